//! Fuzz harnesses of PreciseMC: plain functions of a byte string, shared by
//! the libFuzzer targets in `fuzz/fuzz_targets/` and by the stable
//! regression test `tests/fuzz_corpus.rs`, which replays every file of
//! `fuzz/corpus/<target>/` through them (that test includes this file with
//! `#[path]`, so it must only depend on `precisemc` and `std`).
//!
//! The bytes are decoded into a volume (dimensions, scalar type, memory
//! layout, values including NaN, infinities, denormals, type extremes and
//! values exactly at the isovalue), an isovalue, options (extreme epsilon
//! and max level, triangle cap, threads, normals, gradients,
//! reconstruction filter)
//! and a progress callback
//! that may abort at its n-th call. Every decoded input is valid to pass:
//! invalid ones must be rejected with the documented error. The harness
//! panics when a guarantee is violated:
//!
//! - the result is the documented error for invalid input, `Aborted`
//!   exactly when the callback asked to stop, and `Ok` otherwise;
//! - the callback starts at 0.0, never decreases, ends at 1.0 on success
//!   and is not called after it asked to stop;
//! - the mesh is sane: consistent lengths, finite points inside the
//!   volume's box, indices in range, no triangle with a repeated point,
//!   levels and statistics within the options, unit (or zero) normals,
//!   gradients never NaN and, beside normals, their negated direction,
//!   the triangle cap respected;
//! - the output does not depend on the memory layout nor on the thread
//!   count (bit-identical to a contiguous copy run with other threads);
//! - when every sample is finite and the border is below the isovalue,
//!   the mesh is closed and consistently oriented (every edge used as
//!   often in each direction); the one exemption is the open issue of
//!   README, Reliability: with refinement, samples or isovalue beyond
//!   [`EXTREME_RANGE`] (1e30) in magnitude;
//! - through the C API: the same mesh as the core, every status as
//!   documented, handles freed in any order, error messages
//!   NUL-terminated.
#![allow(clippy::too_many_lines)]

use std::collections::HashMap;
use std::ffi::{c_int, c_void};
use std::ops::ControlFlow;

use precisemc::ffi;
use precisemc::{extract, extract_with_progress, Error, Mesh, NormalMode, Options, Rule};
use precisemc::{Reconstruction, Samples, Topology, Volume, MAX_LEVEL_LIMIT};

/// Most samples a decoded volume holds (keeps one run in milliseconds).
pub const MAX_SAMPLES: usize = 4096;

// ---------------------------------------------------------------------------
// Decoding.
// ---------------------------------------------------------------------------

/// Reads the input byte by byte; once it is exhausted, continues with a
/// deterministic pseudo-random stream seeded by the whole input, so that
/// short inputs still describe varied volumes.
pub struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    state: u64,
}

impl<'a> Reader<'a> {
    pub fn new(data: &'a [u8]) -> Self {
        let mut h = 0xcbf2_9ce4_8422_2325u64 ^ data.len() as u64;
        for &b in data {
            h = (h ^ b as u64).wrapping_mul(0x100_0000_01b3);
        }
        Reader {
            data,
            pos: 0,
            state: h | 1,
        }
    }

    pub fn u8(&mut self) -> u8 {
        if let Some(&b) = self.data.get(self.pos) {
            self.pos += 1;
            b
        } else {
            // xorshift64*
            self.state ^= self.state >> 12;
            self.state ^= self.state << 25;
            self.state ^= self.state >> 27;
            (self.state.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 56) as u8
        }
    }

    pub fn u16(&mut self) -> u16 {
        u16::from_le_bytes([self.u8(), self.u8()])
    }

    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }

    pub fn u64(&mut self) -> u64 {
        (self.u32() as u64) | ((self.u32() as u64) << 32)
    }

    pub fn f64_bits(&mut self) -> f64 {
        f64::from_bits(self.u64())
    }

    /// Whether the input proper (not the continuation stream) is used up.
    pub fn exhausted(&self) -> bool {
        self.pos >= self.data.len()
    }
}

/// The ten sample types, by index.
pub const TYPES: [&str; 10] = [
    "i8", "u8", "i16", "u16", "i32", "u32", "i64", "u64", "f32", "f64",
];

/// A typed owned buffer.
#[derive(Clone, Debug)]
pub enum Buffer {
    I8(Vec<i8>),
    U8(Vec<u8>),
    I16(Vec<i16>),
    U16(Vec<u16>),
    I32(Vec<i32>),
    U32(Vec<u32>),
    I64(Vec<i64>),
    U64(Vec<u64>),
    F32(Vec<f32>),
    F64(Vec<f64>),
}

macro_rules! each_buffer {
    ($b:expr, $v:ident => $e:expr) => {
        match $b {
            Buffer::I8($v) => $e,
            Buffer::U8($v) => $e,
            Buffer::I16($v) => $e,
            Buffer::U16($v) => $e,
            Buffer::I32($v) => $e,
            Buffer::U32($v) => $e,
            Buffer::I64($v) => $e,
            Buffer::U64($v) => $e,
            Buffer::F32($v) => $e,
            Buffer::F64($v) => $e,
        }
    };
}

impl Buffer {
    /// A buffer of `n` elements of type `ty` (index into [`TYPES`]) filled
    /// with `fill` (converted with `as`, i.e. saturating).
    pub fn new(ty: u8, n: usize, fill: f64) -> Buffer {
        match ty % 10 {
            0 => Buffer::I8(vec![fill as i8; n]),
            1 => Buffer::U8(vec![fill as u8; n]),
            2 => Buffer::I16(vec![fill as i16; n]),
            3 => Buffer::U16(vec![fill as u16; n]),
            4 => Buffer::I32(vec![fill as i32; n]),
            5 => Buffer::U32(vec![fill as u32; n]),
            6 => Buffer::I64(vec![fill as i64; n]),
            7 => Buffer::U64(vec![fill as u64; n]),
            8 => Buffer::F32(vec![fill as f32; n]),
            _ => Buffer::F64(vec![fill; n]),
        }
    }

    /// Stores `v` (converted with `as`) at `i`; returns the stored value.
    pub fn set(&mut self, i: usize, v: f64) -> f64 {
        match self {
            Buffer::I8(b) => {
                b[i] = v as i8;
                b[i] as f64
            }
            Buffer::U8(b) => {
                b[i] = v as u8;
                b[i] as f64
            }
            Buffer::I16(b) => {
                b[i] = v as i16;
                b[i] as f64
            }
            Buffer::U16(b) => {
                b[i] = v as u16;
                b[i] as f64
            }
            Buffer::I32(b) => {
                b[i] = v as i32;
                b[i] as f64
            }
            Buffer::U32(b) => {
                b[i] = v as u32;
                b[i] as f64
            }
            Buffer::I64(b) => {
                b[i] = v as i64;
                b[i] as f64
            }
            Buffer::U64(b) => {
                b[i] = v as u64;
                b[i] as f64
            }
            Buffer::F32(b) => {
                b[i] = v as f32;
                b[i] as f64
            }
            Buffer::F64(b) => {
                b[i] = v;
                v
            }
        }
    }

    #[allow(clippy::unnecessary_cast)]
    pub fn get(&self, i: usize) -> f64 {
        each_buffer!(self, b => b[i] as f64)
    }

    pub fn len(&self) -> usize {
        each_buffer!(self, b => b.len())
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn is_float(&self) -> bool {
        matches!(self, Buffer::F32(_) | Buffer::F64(_))
    }

    /// Lowest and highest finite value of the type.
    pub fn type_range(&self) -> (f64, f64) {
        match self {
            Buffer::I8(_) => (i8::MIN as f64, i8::MAX as f64),
            Buffer::U8(_) => (0.0, u8::MAX as f64),
            Buffer::I16(_) => (i16::MIN as f64, i16::MAX as f64),
            Buffer::U16(_) => (0.0, u16::MAX as f64),
            Buffer::I32(_) => (i32::MIN as f64, i32::MAX as f64),
            Buffer::U32(_) => (0.0, u32::MAX as f64),
            Buffer::I64(_) => (i64::MIN as f64, i64::MAX as f64),
            Buffer::U64(_) => (0.0, u64::MAX as f64),
            Buffer::F32(_) => (f32::MIN as f64, f32::MAX as f64),
            Buffer::F64(_) => (f64::MIN, f64::MAX),
        }
    }

    /// The smallest positive subnormal of a float type (1 for integers).
    pub fn denormal(&self) -> f64 {
        match self {
            Buffer::F32(_) => f32::from_bits(1) as f64,
            Buffer::F64(_) => f64::from_bits(1),
            _ => 1.0,
        }
    }

    pub fn samples(&self) -> Samples<'_> {
        each_buffer!(self, b => Samples::from(b))
    }

    /// Pointer to element `skip` (for the C API) and the scalar type code.
    pub fn raw(&self) -> (*const c_void, u32) {
        let code = match self {
            Buffer::I8(_) => 0,
            Buffer::U8(_) => 1,
            Buffer::I16(_) => 2,
            Buffer::U16(_) => 3,
            Buffer::I32(_) => 4,
            Buffer::U32(_) => 5,
            Buffer::I64(_) => 6,
            Buffer::U64(_) => 7,
            Buffer::F32(_) => 8,
            Buffer::F64(_) => 9,
        };
        (each_buffer!(self, b => b.as_ptr().cast()), code)
    }
}

/// A decoded volume: logical values (as stored, read back as f64), dims,
/// and one memory layout of them.
#[derive(Clone, Debug)]
pub struct Case {
    pub dims: [usize; 3],
    /// Logical samples, x fastest (what the library should see).
    pub contiguous: Buffer,
    /// The same samples in the layout below (padding holds NaN or junk).
    pub laid_out: Buffer,
    pub strides: [i64; 3],
    pub offset: u64,
    pub iso: f64,
    /// Whether every sample is finite and the border lies below `iso`.
    pub closed: bool,
    pub origin: [f64; 3],
    pub spacing: [f64; 3],
    pub index_offset: [i64; 3],
}

/// Above this magnitude of samples (or of the isovalue), refinement is not
/// required to keep the surface closed: the one open issue of README,
/// Reliability ("samples span more than about 1e30"). Every other
/// guarantee, the closed surface included, is checked on every input.
pub const EXTREME_RANGE: f64 = 1e30;

impl Case {
    /// Largest magnitude of a finite sample or of the isovalue.
    pub fn max_abs(&self) -> f64 {
        (0..self.contiguous.len())
            .map(|i| self.contiguous.get(i).abs())
            .filter(|v| v.is_finite())
            .fold(self.iso.abs(), f64::max)
    }

    pub fn dims_u64(&self) -> [u64; 3] {
        [
            self.dims[0] as u64,
            self.dims[1] as u64,
            self.dims[2] as u64,
        ]
    }

    pub fn contiguous_volume(&self) -> Volume<'_> {
        Volume::new(self.contiguous.samples(), self.dims_u64())
            .with_origin(self.origin)
            .with_spacing(self.spacing)
            .with_index_offset(self.index_offset)
    }

    pub fn laid_out_volume(&self) -> Volume<'_> {
        Volume::new(self.laid_out.samples(), self.dims_u64())
            .with_strides(self.strides)
            .with_offset(self.offset)
            .with_origin(self.origin)
            .with_spacing(self.spacing)
            .with_index_offset(self.index_offset)
    }
}

/// One sample value from a palette of awkward values.
fn value(r: &mut Reader<'_>, buf: &Buffer, iso_hint: f64) -> f64 {
    let b = r.u8();
    let hi = (b >> 4) as f64;
    let (lo, hi_t) = buf.type_range();
    match b & 15 {
        0..=6 => hi - 8.0,
        7 => hi * 0.25 - 2.0,
        8 => iso_hint,
        9 => f64::NAN,
        10 => {
            if b & 16 == 0 {
                f64::INFINITY
            } else {
                f64::NEG_INFINITY
            }
        }
        11 => buf.denormal() * (hi - 8.0),
        12 => {
            if b & 16 == 0 {
                lo
            } else {
                hi_t
            }
        }
        13 => r.f64_bits(),
        14 => (r.u16() as f64 - 32768.0) * 10f64.powi((hi as i32) * 20 - 150),
        _ => {
            if b & 16 == 0 {
                next_up(iso_hint)
            } else {
                next_down(iso_hint)
            }
        }
    }
}

fn next_up(x: f64) -> f64 {
    if !x.is_finite() {
        return x;
    }
    if x == 0.0 {
        return f64::from_bits(1);
    }
    let b = x.to_bits();
    f64::from_bits(if x > 0.0 { b + 1 } else { b - 1 })
}

fn next_down(x: f64) -> f64 {
    -next_up(-x)
}

/// Decodes a volume and isovalue. `c_layout`: only layouts the C API can
/// express (positive strides, no offset).
pub fn decode_case(r: &mut Reader<'_>, c_layout: bool) -> Case {
    let shape = r.u8();
    let ty = r.u8() % 10;
    let mut dims = [0usize; 3];
    if shape & 3 == 3 {
        // Extreme aspect ratio: one long axis.
        let long = (shape >> 2) as usize % 3;
        for (a, d) in dims.iter_mut().enumerate() {
            *d = if a == long {
                2 + r.u8() as usize * 2
            } else {
                2 + (r.u8() & 1) as usize
            };
        }
    } else {
        for d in &mut dims {
            *d = 2 + (r.u8() % 10) as usize;
        }
    }
    while dims[0] * dims[1] * dims[2] > MAX_SAMPLES {
        let a = (0..3).max_by_key(|&a| dims[a]).unwrap();
        dims[a] = dims[a].div_ceil(2).max(2);
    }
    let n = dims[0] * dims[1] * dims[2];
    let mut contiguous = Buffer::new(ty, n, 0.0);

    // Isovalue hint, used by the palette before the samples exist.
    let iso_mode = r.u8();
    let hint = match iso_mode % 4 {
        0 => (r.u8() as f64 - 128.0) / 16.0,
        1 => r.u8() as f64 - 128.0,
        2 => value(r, &contiguous, 0.5),
        _ => 0.5,
    };
    let mut finite = true;
    for i in 0..n {
        let v = value(r, &contiguous, hint);
        let s = contiguous.set(i, v);
        finite &= s.is_finite();
    }
    let iso = match (iso_mode >> 2) % 4 {
        // Exactly a sample's value.
        0 | 1 => contiguous.get(r.u16() as usize % n),
        2 => hint,
        _ => value(r, &contiguous, hint),
    };
    // A border below the isovalue: the surface is closed.
    let closed_wanted = iso_mode & 0x40 != 0;
    let mut closed = false;
    if closed_wanted && iso.is_finite() {
        let (lo, _) = contiguous.type_range();
        let below = if iso_mode & 0x80 != 0 { lo } else { iso - 1.0 };
        let b = contiguous.set(0, below);
        if b < iso {
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        let border = i == 0
                            || j == 0
                            || k == 0
                            || i + 1 == dims[0]
                            || j + 1 == dims[1]
                            || k + 1 == dims[2];
                        let idx = i + dims[0] * (j + dims[1] * k);
                        if border {
                            contiguous.set(idx, b);
                        } else if !contiguous.get(idx).is_finite() {
                            contiguous.set(idx, iso);
                        }
                    }
                }
            }
            closed = true;
        }
    }
    let _ = finite;

    // Memory layout: axis order, gaps, reversed axes (core only).
    let lay = r.u8();
    const PERMS: [[usize; 3]; 6] = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    let perm = PERMS[(lay % 6) as usize];
    let gaps = r.u8();
    let mut strides = [0i64; 3];
    let mut step = 1i64 + (gaps & 1) as i64;
    for (q, &a) in perm.iter().enumerate() {
        strides[a] = step;
        step = step * dims[a] as i64 + ((gaps >> (1 + 2 * q)) & 3) as i64;
    }
    let len = step as usize + (gaps >> 7) as usize;
    let mut offset = 0i64;
    if !c_layout {
        let flips = r.u8() & 7;
        for a in 0..3 {
            if flips & (1 << a) != 0 {
                offset += (dims[a] as i64 - 1) * strides[a];
                strides[a] = -strides[a];
            }
        }
    }
    let junk = if lay & 0x80 != 0 { f64::NAN } else { 3.0 };
    let mut laid_out = Buffer::new(ty, len, junk);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                let e =
                    offset + i as i64 * strides[0] + j as i64 * strides[1] + k as i64 * strides[2];
                laid_out.set(e as usize, contiguous.get(i + dims[0] * (j + dims[1] * k)));
            }
        }
    }

    // World placement.
    let place = r.u8();
    let mut origin = [0.0; 3];
    let mut spacing = [1.0; 3];
    let mut index_offset = [0i64; 3];
    if place & 1 != 0 {
        for a in 0..3 {
            origin[a] = (r.u8() as f64 - 128.0) * 0.37;
            spacing[a] = 0.05 + r.u8() as f64 * 0.1;
        }
    }
    if place & 2 != 0 {
        for o in &mut index_offset {
            *o = r.u16() as i16 as i64;
        }
    }
    if place & 4 != 0 {
        // Large but representable placements.
        let e = (r.u8() % 40) as i32;
        for a in 0..3 {
            origin[a] = 10f64.powi(e) * (a as f64 - 1.0);
            spacing[a] = 10f64.powi(-e / 2);
        }
    }
    Case {
        dims,
        contiguous,
        laid_out,
        strides,
        offset: offset as u64,
        iso,
        closed,
        origin,
        spacing,
        index_offset,
    }
}

/// Decodes options. Returns the options and the expected validation error
/// (`Some` when the options are invalid).
pub fn decode_options(r: &mut Reader<'_>) -> (Options, Option<Error>) {
    let a = r.u8();
    let epsilon = match r.u8() % 16 {
        0 => 0.0,
        1 => f64::from_bits(1),
        2 => 1e-300,
        3 => 1e-12,
        4 => 1e-4,
        5 | 6 => 0.01,
        7 => 0.05,
        8 => 0.3,
        9 => 1.0,
        10 => 1e300,
        11 => f64::MAX,
        12 => -0.0,
        13 => r.f64_bits(),
        14 => r.u8() as f64 / 256.0,
        _ => 0.002,
    };
    let max_level = match r.u8() % 16 {
        0 => 0,
        l @ 1..=10 => l as u32,
        11 => MAX_LEVEL_LIMIT,
        12 => MAX_LEVEL_LIMIT + 1,
        13 => u32::MAX,
        _ => 3,
    };
    let rule = [Rule::A, Rule::A1, Rule::A2, Rule::B][(a & 3) as usize];
    let topology = if a & 4 != 0 {
        Topology::Classic
    } else {
        Topology::Trilinear
    };
    let normals = [
        NormalMode::None,
        NormalMode::Gradient,
        NormalMode::CentralDifference,
        NormalMode::None,
    ][((a >> 3) & 3) as usize];
    // From bits already read (inputs keep their meaning): gradients alone
    // with the second code of no normals, beside normals with rules A1, B.
    let gradients = (a >> 3) & 3 == 3 || (a & 1 != 0 && normals != NormalMode::None);
    let max_triangles = match (a >> 5) & 7 {
        0..=2 => 0,
        3 => 1,
        4 => r.u8() as u64,
        5 => r.u16() as u64,
        6 => 5_000,
        _ => u64::MAX,
    };
    let threads = (r.u8() % 4) as usize;
    let mut o = Options {
        epsilon,
        max_level,
        rule,
        topology,
        normals,
        gradients,
        max_triangles,
        threads,
        // Decoded last, by `decode_reconstruction`.
        reconstruction: Reconstruction::Trilinear,
    };
    let err = if !(epsilon.is_finite() && epsilon >= 0.0) {
        Some(Error::InvalidEpsilon(epsilon))
    } else if max_level > MAX_LEVEL_LIMIT {
        Some(Error::InvalidMaxLevel(max_level))
    } else {
        None
    };
    // Bound the work (a triangle refined to level 10 everywhere is a
    // million leaves): deep levels only with a coarser epsilon, and a cap.
    if err.is_none() && o.refines() && o.epsilon < 0.05 && o.max_level > 6 {
        o.max_level = 6;
    }
    if o.refines() && o.max_level >= 5 && (o.max_triangles == 0 || o.max_triangles > 20_000) {
        o.max_triangles = 20_000;
    }
    (o, err)
}

/// Decodes the reconstruction filter, read after everything else so that
/// inputs written before the filter was decoded keep their meaning: when
/// the input proper is used up (the reader continues with its
/// pseudo-random stream), the filter is `None` (the default, trilinear,
/// and the C harness does not call the setter). Otherwise one byte gives
/// the filter and the raw value the C harness passes to
/// `pmc_options_set_reconstruction`: a valid code, or now and then an
/// invalid one (the setter must reject it and leave the default).
pub fn decode_reconstruction(r: &mut Reader<'_>) -> Option<(Reconstruction, u32)> {
    if r.exhausted() {
        return None;
    }
    let b = r.u8();
    const FILTERS: [Reconstruction; 4] = [
        Reconstruction::Trilinear,
        Reconstruction::CatmullRom,
        Reconstruction::BSpline,
        Reconstruction::BSplineInterpolating,
    ];
    let code = (b & 3) as u32;
    let raw = match (b >> 2) & 7 {
        6 => 4 + ((b >> 5) as u32),
        7 => [u32::MAX, 0x8000_0000, 0x100, 5][(b >> 5) as usize & 3],
        _ => code,
    };
    Some((FILTERS[code as usize], raw))
}

// ---------------------------------------------------------------------------
// Checks.
// ---------------------------------------------------------------------------

/// Progress recorded by the callback.
#[derive(Debug, Default)]
pub struct ProgressLog {
    pub calls: u32,
    pub stop_at: u32,
    pub values: Vec<f64>,
    pub stopped: bool,
    pub called_after_stop: bool,
}

impl ProgressLog {
    pub fn new(stop_at: u32) -> Self {
        ProgressLog {
            stop_at,
            ..ProgressLog::default()
        }
    }

    /// Records a call; returns true to stop.
    pub fn call(&mut self, f: f64) -> bool {
        if self.stopped {
            self.called_after_stop = true;
        }
        self.calls += 1;
        self.values.push(f);
        if self.stop_at != 0 && self.calls >= self.stop_at {
            self.stopped = true;
        }
        self.stopped
    }

    /// Checks the sequence of calls against the outcome.
    pub fn check(&self, ok: bool) {
        assert!(!self.called_after_stop, "callback called after stop");
        if let Some(&f) = self.values.first() {
            assert_eq!(f, 0.0, "first progress value {f}");
        }
        for w in self.values.windows(2) {
            assert!(w[1] >= w[0], "progress decreased: {:?}", self.values);
        }
        for &v in &self.values {
            assert!((0.0..=1.0).contains(&v), "progress {v} out of [0, 1]");
        }
        if ok {
            assert!(!self.stopped, "success after the callback asked to stop");
            assert_eq!(self.values.last(), Some(&1.0), "{:?}", self.values);
        } else {
            assert!(self.stopped, "aborted without being asked");
        }
    }
}

/// Checks the guarantees every mesh satisfies.
pub fn check_mesh(m: &Mesh, case: &Case, o: &Options) {
    let np = m.points.len();
    assert_eq!(m.index_points.len(), np);
    assert_eq!(m.levels.len(), m.triangles.len());
    assert_eq!(m.stats.output_points, np as u64);
    assert_eq!(m.stats.output_triangles, m.triangles.len() as u64);
    let cells = (case.dims[0] as u64 - 1) * (case.dims[1] as u64 - 1) * (case.dims[2] as u64 - 1);
    assert_eq!(m.stats.cells, cells);
    let level_cap = if o.refines() { o.max_level } else { 0 };
    assert!(m.stats.max_level <= level_cap, "{:?}", m.stats);
    assert!(m.stats.effective_max_level <= level_cap, "{:?}", m.stats);
    assert!(
        m.stats.max_level <= m.stats.effective_max_level,
        "{:?}",
        m.stats
    );
    for &l in &m.levels {
        assert!(l as u32 <= m.stats.max_level);
    }
    // The triangle cap, exactly (a mesh of plain Marching Cubes larger than
    // the cap is kept whole: the cap never removes that surface).
    if o.max_triangles > 0 {
        assert!(
            m.stats.output_triangles <= o.max_triangles.max(m.stats.mc_triangles),
            "cap {} exceeded: {:?}",
            o.max_triangles,
            m.stats
        );
    }
    if !o.refines() {
        assert!(m.levels.iter().all(|&l| l == 0));
    }
    for (a, ip) in m.points.iter().zip(&m.index_points) {
        for ax in 0..3 {
            assert!(a[ax].is_finite() && ip[ax].is_finite(), "{a:?} {ip:?}");
            let lo = case.index_offset[ax] as f64;
            let hi = lo + (case.dims[ax] - 1) as f64;
            let tol = 1e-9 * (1.0 + hi.abs());
            assert!(
                ip[ax] >= lo - tol && ip[ax] <= hi + tol,
                "index point {ip:?} outside the volume (axis {ax}: {lo}..{hi})"
            );
            let w = case.origin[ax] + case.spacing[ax] * ip[ax];
            assert!(
                (a[ax] - w).abs() <= 1e-9 * (1.0 + w.abs()),
                "point {a:?} is not origin + spacing * {ip:?}"
            );
        }
    }
    for t in &m.triangles {
        assert!(t.iter().all(|&v| (v as usize) < np), "{t:?} / {np}");
        assert!(
            t[0] != t[1] && t[1] != t[2] && t[0] != t[2],
            "triangle with a repeated point {t:?}"
        );
    }
    if o.normals == NormalMode::None {
        assert!(m.normals.is_empty());
    } else {
        assert_eq!(m.normals.len(), np);
        for n in &m.normals {
            let l = (n[0] as f64).hypot(n[1] as f64).hypot(n[2] as f64);
            assert!(l == 0.0 || (l - 1.0).abs() < 1e-3, "normal {n:?}");
        }
    }
    if !o.gradients {
        assert!(m.gradients.is_empty());
    } else {
        assert_eq!(m.gradients.len(), np);
        // Never NaN; where normals are on too, each normal is the negated,
        // normalised gradient (where that is a normal float32 of finite
        // length: beyond, the float32 gradient lost its direction).
        assert!(m.gradients.iter().flatten().all(|c| !c.is_nan()));
        for (n, g) in m.normals.iter().zip(&m.gradients) {
            let g = g.map(f64::from);
            let l = g[0].hypot(g[1]).hypot(g[2]);
            if l.is_finite() && l > f64::from(f32::MIN_POSITIVE) {
                let far = (0..3).any(|c| (f64::from(n[c]) + g[c] / l).abs() > 1e-3);
                assert!(!far, "normal {n:?}, gradient {g:?}");
            }
        }
    }
    // Known open issue (README, Reliability): refinement may open the
    // surface when samples span more than about 1e30; only there is the
    // closed check skipped, and only with refinement.
    let exempt = o.refines() && case.max_abs() > EXTREME_RANGE;
    if case.closed && !exempt {
        check_closed(m);
    }
}

/// Every undirected edge is used as often in each direction (a closed,
/// consistently oriented surface, possibly touching itself at samples).
pub fn check_closed(m: &Mesh) {
    let mut uses: HashMap<(u64, u64), i64> = HashMap::new();
    for t in &m.triangles {
        for c in 0..3 {
            let (a, b) = (t[c], t[(c + 1) % 3]);
            let key = (a.min(b), a.max(b));
            *uses.entry(key).or_default() += if a < b { 1 } else { -1 };
        }
    }
    let bad: Vec<_> = uses.iter().filter(|(_, &u)| u != 0).take(4).collect();
    assert!(
        bad.is_empty(),
        "mesh not closed: unbalanced edges {bad:?} (of {} triangles)",
        m.triangles.len()
    );
}

type Bits = (Vec<[u64; 3]>, Vec<[u64; 3]>, Vec<[u32; 3]>, Vec<[u32; 3]>);

fn bits(m: &Mesh) -> Bits {
    (
        m.points.iter().map(|p| p.map(f64::to_bits)).collect(),
        m.index_points.iter().map(|p| p.map(f64::to_bits)).collect(),
        m.normals.iter().map(|p| p.map(f32::to_bits)).collect(),
        m.gradients.iter().map(|p| p.map(f32::to_bits)).collect(),
    )
}

/// Whether two meshes are bit-identical (statistics except timings).
pub fn assert_same(a: &Mesh, b: &Mesh, what: &str) {
    assert!(
        bits(a) == bits(b),
        "{what}: points, normals or gradients differ"
    );
    assert!(a.triangles == b.triangles, "{what}: triangles differ");
    assert!(a.levels == b.levels, "{what}: levels differ");
    let strip = |m: &Mesh| {
        let mut s = m.stats.clone();
        s.time_mc = 0.0;
        s.time_refine = 0.0;
        s.time_assemble = 0.0;
        s.time_normals = 0.0;
        s.time_total = 0.0;
        s
    };
    assert_eq!(strip(a), strip(b), "{what}: statistics differ");
}

// ---------------------------------------------------------------------------
// Core harness.
// ---------------------------------------------------------------------------

/// The core harness: `extract_with_progress` on a decoded input.
pub fn fuzz_core(data: &[u8]) {
    let mut r = Reader::new(data);
    let case = decode_case(&mut r, false);
    let (mut opts, opt_err) = decode_options(&mut r);
    let stop_at = match r.u8() % 8 {
        s @ 1..=4 => s as u32,
        _ => 0,
    };
    if let Some((filter, _)) = decode_reconstruction(&mut r) {
        opts.reconstruction = filter;
    }
    let vol = case.laid_out_volume();
    let mut log = ProgressLog::new(stop_at);
    let res = extract_with_progress(&vol, case.iso, &opts, &mut |f| {
        if log.call(f) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    if !case.iso.is_finite() {
        assert!(
            matches!(res, Err(Error::InvalidIsovalue(x)) if x.to_bits() == case.iso.to_bits()),
            "{res:?}"
        );
        assert_eq!(log.calls, 0);
        return;
    }
    if let Some(e) = opt_err {
        match (&res, &e) {
            (Err(Error::InvalidEpsilon(x)), Error::InvalidEpsilon(y)) => {
                assert!(x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()))
            }
            _ => assert_eq!(res.as_ref().err(), Some(&e)),
        }
        assert_eq!(log.calls, 0);
        return;
    }
    match &res {
        Ok(m) => {
            log.check(true);
            check_mesh(m, &case, &opts);
            // Layout- and thread-independence.
            let other = Options {
                threads: if opts.threads == 1 { 3 } else { 1 },
                ..opts.clone()
            };
            let m2 = extract(&case.contiguous_volume(), case.iso, &other)
                .expect("contiguous copy failed where the strided volume succeeded");
            assert_same(m, &m2, "contiguous copy, other thread count");
        }
        Err(Error::Aborted) => log.check(false),
        Err(e) => panic!("unexpected error {e:?} for a valid input"),
    }
}

// ---------------------------------------------------------------------------
// C API harness.
// ---------------------------------------------------------------------------

unsafe extern "C" fn progress_cb(user: *mut c_void, f: f64) -> c_int {
    // SAFETY: `user` is the `ProgressLog` passed with the callback, alive
    // during the extraction and only touched from this thread.
    let log = unsafe { &mut *user.cast::<ProgressLog>() };
    log.call(f) as c_int
}

fn last_error() -> String {
    // SAFETY: a NULL buffer of length 0 only queries the size.
    let n = unsafe { ffi::pmc_last_error_message(std::ptr::null_mut(), 0) };
    let mut buf = vec![0x55u8; n + 1];
    // SAFETY: `buf` is writable for its length.
    let m = unsafe { ffi::pmc_last_error_message(buf.as_mut_ptr().cast(), buf.len()) };
    assert_eq!(m, n);
    assert_eq!(buf[n], 0, "message not NUL-terminated");
    String::from_utf8(buf[..n].to_vec()).expect("message not UTF-8")
}

/// Checks a truncated copy of the last error message.
fn check_truncated_message(len: usize) {
    let full = last_error();
    let mut buf = vec![0x55u8; len + 1];
    // SAFETY: `buf` is writable for `len` bytes.
    let n = unsafe { ffi::pmc_last_error_message(buf.as_mut_ptr().cast(), len) };
    assert_eq!(n, full.len());
    assert_eq!(buf[len], 0x55, "wrote past len");
    if len > 0 {
        let end = buf.iter().position(|&b| b == 0).expect("no NUL");
        assert!(end < len);
        let s = std::str::from_utf8(&buf[..end]).expect("truncated message not UTF-8");
        assert!(full.starts_with(s));
        assert!(full.len() - s.len() <= 3 || s.len() == len - 1);
    }
}

/// The C API harness: `pmc_extract` through the exported functions, with
/// the same volume given to the core for comparison.
pub fn fuzz_c_api(data: &[u8]) {
    let mut r = Reader::new(data);
    let case = decode_case(&mut r, true);
    let (opts, _) = decode_options(&mut r);
    let stop_at = match r.u8() % 8 {
        s @ 1..=4 => s as u32,
        _ => 0,
    };
    let hostile = r.u8();
    let extra = r.u64();
    let filter = decode_reconstruction(&mut r);

    let (ptr, code) = case.laid_out.raw();
    let mut vol = ffi::pmc_volume {
        struct_size: std::mem::size_of::<ffi::pmc_volume>() as u64,
        data: ptr,
        len: case.laid_out.len() as u64,
        scalar_type: code,
        dims: case.dims_u64(),
        strides: case.strides,
        origin: case.origin,
        spacing: case.spacing,
    };
    // What the call must return; `None`: OK or ABORTED.
    let mut expect: Option<u32> = None;
    let mut null_volume = false;
    let mut null_out = false;
    let elem = code_size(code);
    match hostile % 16 {
        1 => {
            let needed: i64 = (0..3)
                .map(|a| (case.dims[a] as i64 - 1) * case.strides[a])
                .sum::<i64>()
                + 1;
            vol.len = (needed as u64).saturating_sub(1 + extra % 4);
            expect = Some(2);
        }
        2 => {
            vol.scalar_type = 10 + (extra as u32 % 1000);
            expect = Some(2);
        }
        3 => {
            vol.data = std::ptr::null();
            expect = Some(1);
        }
        4 => null_volume = true,
        5 => null_out = true,
        6 => {
            vol.dims[(extra % 3) as usize] = extra >> 63;
            expect = Some(2);
        }
        7 => {
            vol.strides[(extra % 3) as usize] = -((extra >> 8) as i64 & 7) - 1;
            expect = Some(2);
        }
        8 => {
            vol.spacing[(extra % 3) as usize] =
                [0.0, -1.0, f64::NAN, f64::INFINITY][(extra >> 8) as usize % 4];
            expect = Some(2);
        }
        9 => {
            vol.origin[(extra % 3) as usize] =
                [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][(extra >> 8) as usize % 3];
            expect = Some(2);
        }
        10 if elem > 1 => {
            // Misaligned data.
            vol.data = ptr.cast::<u8>().wrapping_add(1).cast();
            vol.len -= 1;
            expect = Some(2);
        }
        11 => {
            vol.dims[(extra % 3) as usize] = u64::MAX - (extra >> 32);
            expect = Some(2);
        }
        12 => {
            // Contiguous shorthand, valid when the layout is contiguous.
            vol.strides = [0, 0, 0];
            let contiguous =
                case.strides == [1, case.dims[0] as i64, (case.dims[0] * case.dims[1]) as i64];
            if !contiguous && case.laid_out.len() < case.dims.iter().product() {
                expect = Some(2);
            } else if !contiguous {
                expect = Some(u32::MAX); // valid, different values
            }
        }
        13 => {
            vol.strides[(extra % 3) as usize] = 0;
            expect = Some(2);
        }
        14 => {
            // A struct_size of 0 or below the first layout's (a caller
            // built against an older header): rejected before any other
            // field is read.
            let size = std::mem::size_of::<ffi::pmc_volume>() as u64;
            vol.struct_size = [0, 1, 8, size - 1][(extra % 4) as usize];
            expect = Some(2);
        }
        _ => {}
    }
    let iso = if hostile & 0x10 != 0 && hostile & 15 == 0 {
        expect = Some(2);
        [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][(extra % 3) as usize]
    } else {
        case.iso
    };
    if !iso.is_finite() && matches!(expect, None | Some(u32::MAX)) {
        expect = Some(2);
    }
    if null_volume || null_out {
        expect = Some(1);
    }

    // Options through the setters, with hostile raw values now and then.
    let use_null_options = hostile & 0x20 != 0 && case.contiguous.len() <= 1000;
    let o = if use_null_options {
        std::ptr::null_mut()
    } else {
        ffi::pmc_options_new()
    };
    let mut core_opts = Options::default();
    let mut index_offset = [0i64; 3];
    if !o.is_null() {
        // SAFETY: `o` is a live handle, used by this thread only.
        unsafe {
            let st = ffi::pmc_options_set_epsilon(o, opts.epsilon);
            if opts.epsilon.is_finite() && opts.epsilon >= 0.0 {
                assert_eq!(st as u32, 0);
                core_opts.epsilon = opts.epsilon;
            } else {
                assert_eq!(st as u32, 2);
            }
            let st = ffi::pmc_options_set_max_level(o, opts.max_level);
            if opts.max_level <= MAX_LEVEL_LIMIT {
                assert_eq!(st as u32, 0);
                core_opts.max_level = opts.max_level;
            } else {
                assert_eq!(st as u32, 2);
            }
            let raw = |x: u32| if hostile & 0x40 != 0 { x + 4 } else { x };
            let rule = opts.rule as u32;
            assert_eq!(
                ffi::pmc_options_set_rule(o, raw(rule)) as u32,
                if hostile & 0x40 != 0 { 2 } else { 0 }
            );
            let top = match opts.topology {
                Topology::Trilinear => 0,
                Topology::Classic => 1,
            };
            assert_eq!(
                ffi::pmc_options_set_topology(o, raw(top)) as u32,
                if hostile & 0x40 != 0 { 2 } else { 0 }
            );
            let nm = match opts.normals {
                NormalMode::None => 0,
                NormalMode::Gradient => 1,
                NormalMode::CentralDifference => 2,
            };
            assert_eq!(
                ffi::pmc_options_set_normals(o, raw(nm) + (hostile & 0x40 != 0) as u32) as u32,
                if hostile & 0x40 != 0 { 2 } else { 0 }
            );
            if hostile & 0x40 == 0 {
                core_opts.rule = opts.rule;
                core_opts.topology = opts.topology;
                core_opts.normals = opts.normals;
            }
            // A hostile flag (neither 0 nor 1) is rejected, leaving it off.
            let gv = if hostile & 0x40 != 0 {
                2 + opts.gradients as std::ffi::c_int
            } else {
                opts.gradients as std::ffi::c_int
            };
            assert_eq!(
                ffi::pmc_options_set_gradients(o, gv) as u32,
                if hostile & 0x40 != 0 { 2 } else { 0 }
            );
            if hostile & 0x40 == 0 {
                core_opts.gradients = opts.gradients;
            }
            assert_eq!(
                ffi::pmc_options_set_max_triangles(o, opts.max_triangles) as u32,
                0
            );
            core_opts.max_triangles = opts.max_triangles;
            let threads = if hostile & 0x80 != 0 {
                (extra >> 16) as u32
            } else {
                opts.threads as u32
            };
            let st = ffi::pmc_options_set_threads(o, threads);
            if threads <= ffi::PMC_MAX_THREADS {
                assert_eq!(st as u32, 0);
            } else {
                assert_eq!(st as u32, 2);
            }
            if case.index_offset != [0; 3] {
                let st = ffi::pmc_options_set_index_offset(o, case.index_offset.as_ptr());
                assert_eq!(st as u32, 0);
                index_offset = case.index_offset;
            }
            assert_eq!(
                ffi::pmc_options_set_index_offset(o, std::ptr::null()) as u32,
                1
            );
            if let Some((f, raw)) = filter {
                let st = ffi::pmc_options_set_reconstruction(o, raw);
                if raw < 4 {
                    assert_eq!(st as u32, 0);
                    core_opts.reconstruction = f;
                } else {
                    assert_eq!(st as u32, 2, "reconstruction {raw} accepted");
                    assert!(last_error().contains("reconstruction"), "{}", last_error());
                }
            }
        }
    }
    // Keep it cheap: no more than 2 threads, the harness bounds the work.
    if !o.is_null() {
        // SAFETY: as above.
        unsafe { ffi::pmc_options_set_threads(o, 1 + (extra as u32 & 1)) };
    }
    if !o.is_null() && core_opts.refines() && core_opts.max_level >= 5 {
        let cap = if core_opts.max_triangles == 0 || core_opts.max_triangles > 20_000 {
            20_000
        } else {
            core_opts.max_triangles
        };
        // SAFETY: as above.
        unsafe { ffi::pmc_options_set_max_triangles(o, cap) };
        core_opts.max_triangles = cap;
    }
    if o.is_null() {
        core_opts = Options::default();
    }
    let stop_at = if o.is_null() { 0 } else { stop_at };
    let mut log = ProgressLog::new(stop_at);
    if stop_at != 0 {
        // SAFETY: `log` outlives every extraction with these options.
        let st = unsafe {
            ffi::pmc_options_set_progress(
                o,
                Some(progress_cb),
                (&mut log as *mut ProgressLog).cast(),
            )
        };
        assert_eq!(st as u32, 0);
    }

    let mut mesh: *mut ffi::pmc_mesh = 0x10 as *mut ffi::pmc_mesh;
    let vp: *const ffi::pmc_volume = if null_volume { std::ptr::null() } else { &vol };
    let out: *mut *mut ffi::pmc_mesh = if null_out {
        std::ptr::null_mut()
    } else {
        &mut mesh
    };
    // SAFETY: every pointer is NULL or valid; `vol.data` is readable for
    // `vol.len` elements of its type (or misaligned, which is rejected
    // before any read).
    let st = unsafe { ffi::pmc_extract(vp, iso, o, out) } as u32;
    if !null_out && st != 0 {
        assert!(mesh.is_null(), "failure left a mesh");
    }
    match expect {
        Some(e) if e != u32::MAX => {
            assert_eq!(st, e, "status; message: {}", last_error());
            assert!(!last_error().is_empty());
            check_truncated_message((extra % 24) as usize);
            assert_eq!(log.calls, 0);
        }
        _ => {
            if st == 3 {
                log.check(false);
                assert!(last_error().contains("abort"));
            } else {
                assert_eq!(st, 0, "status; message: {}", last_error());
                if stop_at != 0 {
                    log.check(true);
                }
            }
        }
    }
    // Free the options first or last.
    if hostile & 0x08 != 0 {
        // SAFETY: `o` is NULL or live; not used again.
        unsafe { ffi::pmc_options_free(o) };
    }
    if st == 0 && !null_out {
        // SAFETY: `mesh` is a live handle from a successful extraction.
        let m = unsafe { mesh_from_handle(mesh) };
        if expect.is_none() {
            let vol_core = Volume::new(case.laid_out.samples(), case.dims_u64())
                .with_strides(case.strides)
                .with_origin(case.origin)
                .with_spacing(case.spacing)
                .with_index_offset(index_offset);
            let core = extract(&vol_core, iso, &core_opts).expect("core failed");
            assert_same(&m, &core, "C API vs core");
            let mut c2 = case.clone();
            c2.index_offset = index_offset;
            check_mesh(&m, &c2, &core_opts);
        }
        // SAFETY: live handle, freed once.
        unsafe { ffi::pmc_mesh_free(mesh) };
    }
    if hostile & 0x08 == 0 {
        // SAFETY: `o` is NULL or live; not used again.
        unsafe { ffi::pmc_options_free(o) };
    }
    // NULL is accepted everywhere.
    // SAFETY: NULL handles.
    unsafe {
        ffi::pmc_mesh_free(std::ptr::null_mut());
        ffi::pmc_options_free(std::ptr::null_mut());
        assert_eq!(ffi::pmc_mesh_point_count(std::ptr::null()), 0);
        assert!(ffi::pmc_mesh_points(std::ptr::null()).is_null());
    }
}

fn code_size(code: u32) -> usize {
    [1, 1, 2, 2, 4, 4, 8, 8, 4, 8][code as usize % 10]
}

/// Reads a mesh back through the accessors.
///
/// # Safety
///
/// `mesh` must be a live handle.
unsafe fn mesh_from_handle(mesh: *const ffi::pmc_mesh) -> Mesh {
    // SAFETY: forwarded contract; the arrays have the documented lengths.
    unsafe {
        let np = ffi::pmc_mesh_point_count(mesh) as usize;
        let nt = ffi::pmc_mesh_triangle_count(mesh) as usize;
        let slice3 = |p: *const f64| -> Vec<[f64; 3]> {
            if np == 0 {
                assert!(p.is_null());
                return Vec::new();
            }
            std::slice::from_raw_parts(p, 3 * np)
                .chunks(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect()
        };
        let points = slice3(ffi::pmc_mesh_points(mesh));
        let index_points = slice3(ffi::pmc_mesh_index_points(mesh));
        let tp = ffi::pmc_mesh_triangles(mesh);
        let lp = ffi::pmc_mesh_triangle_levels(mesh);
        let (triangles, levels) = if nt == 0 {
            assert!(tp.is_null() && lp.is_null());
            (Vec::new(), Vec::new())
        } else {
            (
                std::slice::from_raw_parts(tp, 3 * nt)
                    .chunks(3)
                    .map(|c| [c[0] as u64, c[1] as u64, c[2] as u64])
                    .collect(),
                std::slice::from_raw_parts(lp, nt).to_vec(),
            )
        };
        let np_ = ffi::pmc_mesh_normals(mesh);
        let normals = if np_.is_null() {
            Vec::new()
        } else {
            std::slice::from_raw_parts(np_, 3 * np)
                .chunks(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect()
        };
        let gp = ffi::pmc_mesh_gradients(mesh);
        let gradients = if gp.is_null() {
            Vec::new()
        } else {
            std::slice::from_raw_parts(gp, 3 * np)
                .chunks(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect()
        };
        // `Default` sets `struct_size`.
        let mut s = ffi::pmc_stats::default();
        assert_eq!(ffi::pmc_mesh_stats(mesh, &mut s) as u32, 0);
        let stats = precisemc::Stats {
            cells: s.cells,
            mc_triangles: s.mc_triangles,
            output_triangles: s.output_triangles,
            output_points: s.output_points,
            ambiguous_cells: s.ambiguous_cells,
            skipped_nonfinite_cells: s.skipped_nonfinite_cells,
            max_level: s.max_level,
            mean_level: s.mean_level,
            samples_evaluated: s.samples_evaluated,
            split_points: s.split_points,
            projection_failures: s.projection_failures,
            faces_above_epsilon: s.faces_above_epsilon,
            cells_refined_on_faces_only: ffi::pmc_mesh_cells_refined_on_faces_only(mesh),
            recut_polygons: ffi::pmc_mesh_recut_polygons(mesh),
            cells_on_subcells: ffi::pmc_mesh_cells_on_subcells(mesh),
            budget_reached: s.budget_reached != 0,
            effective_max_level: s.effective_max_level,
            ..precisemc::Stats::default()
        };
        Mesh {
            points,
            index_points,
            triangles,
            normals,
            gradients,
            levels,
            stats,
        }
    }
}
