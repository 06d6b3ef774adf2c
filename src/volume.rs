//! The input: a regular grid of samples borrowed from the caller.
//!
//! Samples are read in place, whatever their type and strides; nothing is
//! copied. Every element index the extraction can touch is checked against
//! the buffer once, in [`Volume::validate`], before any read.

use crate::Error;

/// The element type of a volume's samples (VTK's scalar types).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ScalarType {
    /// `i8` / `signed char`.
    I8,
    /// `u8` / `unsigned char`.
    U8,
    /// `i16` / `short`.
    I16,
    /// `u16` / `unsigned short`.
    U16,
    /// `i32` / `int`.
    I32,
    /// `u32` / `unsigned int`.
    U32,
    /// `i64` / `long long`.
    I64,
    /// `u64` / `unsigned long long`.
    U64,
    /// `f32` / `float`.
    F32,
    /// `f64` / `double`.
    F64,
}

/// A borrowed, typed buffer of samples.
#[derive(Debug, Clone, Copy)]
pub enum Samples<'a> {
    /// `i8` samples.
    I8(&'a [i8]),
    /// `u8` samples.
    U8(&'a [u8]),
    /// `i16` samples.
    I16(&'a [i16]),
    /// `u16` samples.
    U16(&'a [u16]),
    /// `i32` samples.
    I32(&'a [i32]),
    /// `u32` samples.
    U32(&'a [u32]),
    /// `i64` samples.
    I64(&'a [i64]),
    /// `u64` samples.
    U64(&'a [u64]),
    /// `f32` samples.
    F32(&'a [f32]),
    /// `f64` samples.
    F64(&'a [f64]),
}

impl Samples<'_> {
    /// Number of elements in the buffer.
    pub fn len(&self) -> usize {
        match self {
            Samples::I8(s) => s.len(),
            Samples::U8(s) => s.len(),
            Samples::I16(s) => s.len(),
            Samples::U16(s) => s.len(),
            Samples::I32(s) => s.len(),
            Samples::U32(s) => s.len(),
            Samples::I64(s) => s.len(),
            Samples::U64(s) => s.len(),
            Samples::F32(s) => s.len(),
            Samples::F64(s) => s.len(),
        }
    }

    /// Whether the buffer is empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The element type.
    pub fn scalar_type(&self) -> ScalarType {
        match self {
            Samples::I8(_) => ScalarType::I8,
            Samples::U8(_) => ScalarType::U8,
            Samples::I16(_) => ScalarType::I16,
            Samples::U16(_) => ScalarType::U16,
            Samples::I32(_) => ScalarType::I32,
            Samples::U32(_) => ScalarType::U32,
            Samples::I64(_) => ScalarType::I64,
            Samples::U64(_) => ScalarType::U64,
            Samples::F32(_) => ScalarType::F32,
            Samples::F64(_) => ScalarType::F64,
        }
    }
}

macro_rules! impl_from_slice {
    ($($t:ty => $v:ident),*) => {$(
        impl<'a> From<&'a [$t]> for Samples<'a> {
            fn from(s: &'a [$t]) -> Self { Samples::$v(s) }
        }
        impl<'a> From<&'a Vec<$t>> for Samples<'a> {
            fn from(s: &'a Vec<$t>) -> Self { Samples::$v(s.as_slice()) }
        }
    )*};
}
impl_from_slice!(i8 => I8, u8 => U8, i16 => I16, u16 => U16, i32 => I32, u32 => U32,
    i64 => I64, u64 => U64, f32 => F32, f64 => F64);

/// A regular volume: `dims[0] x dims[1] x dims[2]` samples, x fastest.
///
/// Sample `(i, j, k)` (local indices, `0 <= i < dims[0]`, ...) is element
/// `offset + i * strides[0] + j * strides[1] + k * strides[2]` of the
/// buffer. Its world position is `origin + spacing * (index_offset + (i, j, k))`
/// per axis: `origin` is the world position of *global* index 0, as for a
/// VTK image whose extent does not start at 0, so that pieces of one volume
/// produce bit-identical vertices where they meet.
///
/// ```
/// use precisemc::Volume;
/// let data = vec![0.0f32; 4 * 4 * 4];
/// let v = Volume::new(&data, [4, 4, 4]).with_spacing([0.5, 0.5, 2.0]);
/// assert!(v.validate().is_ok());
/// ```
#[derive(Debug, Clone, Copy)]
pub struct Volume<'a> {
    /// The samples.
    pub samples: Samples<'a>,
    /// Number of samples per axis (each in `2..=`[`MAX_DIMENSION`]).
    pub dims: [u64; 3],
    /// Element strides per axis (may be negative with a matching offset).
    /// Default (from [`Volume::new`]): contiguous, x fastest.
    pub strides: [i64; 3],
    /// Element index of local sample (0, 0, 0). Default 0.
    pub offset: u64,
    /// Global index of local sample (0, 0, 0) (VTK's extent start), in
    /// samples; each within ±[`MAX_INDEX_OFFSET`]. Default 0.
    pub index_offset: [i64; 3],
    /// World position of global index (0, 0, 0). Default 0.
    pub origin: [f64; 3],
    /// World distance between samples per axis (> 0). Default 1.
    pub spacing: [f64; 3],
}

/// `origin + spacing * p` per axis: world coordinates of a point in
/// global index space (the one mapping every entry point uses, so that
/// world points computed now or later are bit-identical).
pub(crate) fn index_to_world(origin: [f64; 3], spacing: [f64; 3], p: [f64; 3]) -> [f64; 3] {
    [
        origin[0] + spacing[0] * p[0],
        origin[1] + spacing[1] * p[1],
        origin[2] + spacing[2] * p[2],
    ]
}

/// Largest accepted number of samples per axis (2^40).
pub const MAX_DIMENSION: u64 = 1 << 40;

/// Largest accepted magnitude of an index offset per axis (2^31): offsets
/// lie in `-MAX_INDEX_OFFSET..=MAX_INDEX_OFFSET`, which holds every VTK
/// extent (32-bit integers).
///
/// Index points are global `f64` coordinates with the offset included (so
/// that pieces of one volume give bit-identical points where they meet):
/// the farther from 0, the coarser they are rounded, up to 2^-21 cells at
/// 2^31. Within this range Marching Cubes gives the mesh of offset 0 moved
/// by the offset, triangle for triangle, and refined meshes are as close
/// to the isosurface as at offset 0; they are not always the same
/// triangles, since a refinement decision near a tie can go the other way
/// on the coarser coordinates. Beyond, the rounding degrades refinement
/// (at 2^50 a sphere's largest radius error tripled).
pub const MAX_INDEX_OFFSET: i64 = 1 << 31;

/// The accepted magnitude of an index offset: [`MAX_INDEX_OFFSET`], but
/// unit tests of the paths that handle coarsely rounded points (points of
/// distinct cells that round together, reachable at offset 0 only with
/// dims near 2^40) raise it on their thread to reach them with small
/// volumes far out.
fn offset_limit() -> u64 {
    #[cfg(test)]
    if let Some(l) = test_offset_limit::LIMIT.with(|l| l.get()) {
        return l;
    }
    MAX_INDEX_OFFSET as u64
}

#[cfg(test)]
pub(crate) mod test_offset_limit {
    thread_local! {
        /// This thread's override of the index offset limit.
        pub(crate) static LIMIT: std::cell::Cell<Option<u64>> = const { std::cell::Cell::new(None) };
    }

    /// Accepts index offsets up to 2^50 on this thread (the limit before
    /// offsets were capped at 2^31).
    pub(crate) fn raise() {
        LIMIT.with(|l| l.set(Some(1 << 50)));
    }
}

/// Contiguous strides (x fastest) for `dims`. When they overflow `i64`,
/// `i64::MAX` stands in for the stride that overflows (not 0, which would
/// read as aliasing): such dims hold more samples than `isize::MAX`, which
/// [`Volume::validate`] reports before it looks at strides.
pub(crate) fn contiguous_strides(dims: [u64; 3]) -> [i64; 3] {
    let dx = i64::try_from(dims[0]).ok();
    let dxy = dx.and_then(|dx| dx.checked_mul(i64::try_from(dims[1]).ok()?));
    [1, dx.unwrap_or(i64::MAX), dxy.unwrap_or(i64::MAX)]
}

impl<'a> Volume<'a> {
    /// A contiguous volume (x fastest) with origin 0 and spacing 1.
    pub fn new(samples: impl Into<Samples<'a>>, dims: [u64; 3]) -> Self {
        Volume {
            samples: samples.into(),
            dims,
            strides: contiguous_strides(dims),
            offset: 0,
            index_offset: [0; 3],
            origin: [0.0; 3],
            spacing: [1.0; 3],
        }
    }

    /// Sets element strides (all zero = contiguous, x fastest). A zero
    /// stride on some axes only is rejected by [`Volume::validate`].
    pub fn with_strides(mut self, strides: [i64; 3]) -> Self {
        if strides == [0, 0, 0] {
            self.strides = contiguous_strides(self.dims);
        } else {
            self.strides = strides;
        }
        self
    }

    /// Sets the element index of local sample (0, 0, 0).
    pub fn with_offset(mut self, offset: u64) -> Self {
        self.offset = offset;
        self
    }

    /// Sets the global index of local sample (0, 0, 0), in samples per
    /// axis (VTK's extent start); default 0. Each must lie within
    /// `-MAX_INDEX_OFFSET..=MAX_INDEX_OFFSET` (±2^31, see
    /// [`MAX_INDEX_OFFSET`]), else [`Volume::validate`] fails with
    /// [`Error::InvalidIndexOffset`].
    pub fn with_index_offset(mut self, index_offset: [i64; 3]) -> Self {
        self.index_offset = index_offset;
        self
    }

    /// Sets the world position of global index (0, 0, 0).
    pub fn with_origin(mut self, origin: [f64; 3]) -> Self {
        self.origin = origin;
        self
    }

    /// Sets the world spacing per axis.
    pub fn with_spacing(mut self, spacing: [f64; 3]) -> Self {
        self.spacing = spacing;
        self
    }

    /// World coordinates of a point in global index space.
    pub(crate) fn world_point(&self, p: [f64; 3]) -> [f64; 3] {
        index_to_world(self.origin, self.spacing, p)
    }

    /// Number of cells, `(nx-1)(ny-1)(nz-1)` (0 for invalid dims).
    pub fn cell_count(&self) -> u64 {
        let [x, y, z] = self.dims;
        x.saturating_sub(1)
            .saturating_mul(y.saturating_sub(1))
            .saturating_mul(z.saturating_sub(1))
    }

    /// Checks dims, spacing, origin, index offset, that the world box is
    /// finite and that every addressed element lies in the buffer.
    pub fn validate(&self) -> Result<(), Error> {
        for a in 0..3 {
            if self.dims[a] < 2 {
                return Err(Error::DimensionTooSmall {
                    axis: a,
                    value: self.dims[a],
                });
            }
            let s = self.spacing[a];
            if !(s.is_finite() && s > 0.0) {
                return Err(Error::InvalidSpacing { axis: a, value: s });
            }
            if !self.origin[a].is_finite() {
                return Err(Error::InvalidOrigin {
                    axis: a,
                    value: self.origin[a],
                });
            }
            if self.dims[a] > MAX_DIMENSION {
                return Err(Error::DimensionTooLarge {
                    axis: a,
                    value: self.dims[a],
                });
            }
            if self.index_offset[a].unsigned_abs() > offset_limit() {
                return Err(Error::InvalidIndexOffset {
                    axis: a,
                    value: self.index_offset[a],
                });
            }
        }
        // Before the strides: contiguous strides of dims this large have
        // overflowed (see `contiguous_strides`).
        let total = (self.dims[0] as u128) * (self.dims[1] as u128) * (self.dims[2] as u128);
        if total > (isize::MAX as u128) {
            return Err(Error::DimensionOverflow(self.dims));
        }
        // Every point of the mesh lies in the box of global indices
        // `index_offset ..= index_offset + dims - 1`, and its world
        // coordinate `origin + spacing * p` grows with `p`: finite at both
        // ends means finite everywhere.
        for a in 0..3 {
            let first = self.index_offset[a];
            // No overflow: |first| <= 2^31 and dims <= 2^40.
            let last = first + (self.dims[a] - 1) as i64;
            for index in [first, last] {
                // As `index_to_world` computes it.
                if !(self.origin[a] + self.spacing[a] * index as f64).is_finite() {
                    return Err(Error::WorldOverflow {
                        axis: a,
                        index,
                        origin: self.origin[a],
                        spacing: self.spacing[a],
                    });
                }
            }
        }
        // A zero stride would read one sample for a whole axis.
        if self.strides.contains(&0) {
            return Err(Error::InvalidStrides(self.strides));
        }
        // Smallest and largest element index over the box: the extremes are
        // at corners, per axis independently.
        let mut lo = self.offset as i128;
        let mut hi = self.offset as i128;
        for a in 0..3 {
            let span = (self.dims[a] as i128 - 1) * self.strides[a] as i128;
            if span < 0 {
                lo += span;
            } else {
                hi += span;
            }
        }
        let len = self.samples.len() as u64;
        if lo < 0 {
            return Err(Error::OutOfBounds { index: lo, len });
        }
        if hi >= len as i128 {
            return Err(Error::OutOfBounds { index: hi, len });
        }
        Ok(())
    }
}

/// A sample type the extraction reads in place.
pub trait Scalar: Copy + Send + Sync + 'static {
    /// Whether the type can hold NaN or infinities.
    const FLOAT: bool;
    /// The value as `f64` (exact for every type but 64-bit integers beyond 2^53).
    fn to_f64(self) -> f64;
    /// Sets `bits[i]` to 1 where `run[i].to_f64() >= iso`, else 0, and
    /// returns whether every value is finite. `iso` is not NaN; `bits`
    /// and `run` have the same length. The default compares in `f64`;
    /// types exact in `f64` compare against an integer threshold instead
    /// (same result, and the loop vectorises on the narrow type).
    #[inline]
    fn inside_run(run: &[Self], iso: f64, bits: &mut [u8]) -> bool {
        let mut finite = true;
        for (b, v) in bits.iter_mut().zip(run) {
            let v = v.to_f64();
            if Self::FLOAT {
                finite &= v.is_finite();
            }
            *b = (v >= iso) as u8;
        }
        finite
    }
}

macro_rules! impl_scalar {
    ($($t:ty: $f:expr),*) => {$(
        impl Scalar for $t {
            const FLOAT: bool = $f;
            #[inline(always)]
            fn to_f64(self) -> f64 { self as f64 }
        }
    )*};
}
impl_scalar!(i64: false, u64: false, f64: true);

impl Scalar for f32 {
    const FLOAT: bool = true;
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self as f64
    }
    /// Compares in `f32` against the least `f32` not below `iso` (the same
    /// result as in `f64`, for every value, NaN included): widening each
    /// sample halved the loop's vector width (a third of plain Marching
    /// Cubes' time on a large float volume went to this loop).
    #[inline]
    fn inside_run(run: &[Self], iso: f64, bits: &mut [u8]) -> bool {
        let th = f32_at_least(iso);
        // Exponent bits all set: infinite or NaN.
        const EXP: u32 = 0x7f80_0000;
        let mut nonfinite = 0u8;
        for (b, &v) in bits.iter_mut().zip(run) {
            *b = (v >= th) as u8;
            nonfinite |= (v.to_bits() & EXP == EXP) as u8;
        }
        nonfinite == 0
    }
}

/// The least `f32` whose value is at least `x` (`x` not NaN; +inf above
/// the largest `f32`): for every `f32` `v`, `v as f64 >= x` exactly when
/// `v >= f32_at_least(x)`.
fn f32_at_least(x: f64) -> f32 {
    let t = x as f32; // nearest, ties to even
    if (t as f64) >= x {
        return t;
    }
    // Rounded down: the next f32 up (t is finite here, below x).
    if t == 0.0 {
        return f32::from_bits(1);
    }
    let bits = t.to_bits();
    f32::from_bits(if t > 0.0 { bits + 1 } else { bits - 1 })
}

// Integers of up to 32 bits are exact in f64: `v >= iso` is
// `v >= ceil(iso)` with the ceiling in the type's range.
macro_rules! impl_scalar_narrow {
    ($($t:ty),*) => {$(
        impl Scalar for $t {
            const FLOAT: bool = false;
            #[inline(always)]
            fn to_f64(self) -> f64 { self as f64 }
            #[inline]
            fn inside_run(run: &[Self], iso: f64, bits: &mut [u8]) -> bool {
                if iso > <$t>::MAX as f64 {
                    bits.fill(0);
                } else if iso <= <$t>::MIN as f64 {
                    bits.fill(1);
                } else {
                    let th = iso.ceil() as $t;
                    for (b, &v) in bits.iter_mut().zip(run) {
                        *b = (v >= th) as u8;
                    }
                }
                true
            }
        }
    )*};
}
impl_scalar_narrow!(i8, u8, i16, u16, i32, u32);

/// Runs `$body` with `$g` bound to the volume's typed [`Grid`], whatever
/// its scalar type (one monomorphised copy per type, no conversion copy).
/// The volume must have been validated.
macro_rules! with_grid {
    ($volume:expr, |$g:ident| $body:expr) => {{
        use $crate::volume::{Grid, Samples};
        let v = $volume;
        match v.samples {
            Samples::I8(s) => {
                let $g = Grid::new(s, v);
                $body
            }
            Samples::U8(s) => {
                let $g = Grid::new(s, v);
                $body
            }
            Samples::I16(s) => {
                let $g = Grid::new(s, v);
                $body
            }
            Samples::U16(s) => {
                let $g = Grid::new(s, v);
                $body
            }
            Samples::I32(s) => {
                let $g = Grid::new(s, v);
                $body
            }
            Samples::U32(s) => {
                let $g = Grid::new(s, v);
                $body
            }
            Samples::I64(s) => {
                let $g = Grid::new(s, v);
                $body
            }
            Samples::U64(s) => {
                let $g = Grid::new(s, v);
                $body
            }
            Samples::F32(s) => {
                let $g = Grid::new(s, v);
                $body
            }
            Samples::F64(s) => {
                let $g = Grid::new(s, v);
                $body
            }
        }
    }};
}
pub(crate) use with_grid;

/// Typed, validated read access to a volume (local indices).
#[derive(Clone, Copy)]
pub(crate) struct Grid<'a, T: Scalar> {
    data: &'a [T],
    offset: isize,
    strides: [isize; 3],
    pub dims: [usize; 3],
    pub index_offset: [i64; 3],
}

impl<'a, T: Scalar> Grid<'a, T> {
    /// Wraps a buffer. The caller must have run [`Volume::validate`].
    pub(crate) fn new(data: &'a [T], v: &Volume<'_>) -> Self {
        Grid {
            data,
            offset: v.offset as isize,
            strides: [
                v.strides[0] as isize,
                v.strides[1] as isize,
                v.strides[2] as isize,
            ],
            dims: [v.dims[0] as usize, v.dims[1] as usize, v.dims[2] as usize],
            index_offset: v.index_offset,
        }
    }

    /// Inside bits of row `(j, k)` (`bits[i]` = 1 where the sample is at
    /// or above `iso`; `bits` has length `dims[0]`), returning whether every
    /// value is finite.
    #[inline]
    pub(crate) fn row_inside(&self, j: usize, k: usize, iso: f64, bits: &mut [u8]) -> bool {
        assert!(j < self.dims[1] && k < self.dims[2] && bits.len() == self.dims[0]);
        let base = self.offset + j as isize * self.strides[1] + k as isize * self.strides[2];
        let s0 = self.strides[0];
        if s0 == 1 {
            // SAFETY: as below, for the indices base .. base + dims[0].
            let run = unsafe {
                self.data
                    .get_unchecked(base as usize..base as usize + bits.len())
            };
            return T::inside_run(run, iso, bits);
        }
        let mut finite = true;
        for (i, b) in bits.iter_mut().enumerate() {
            // SAFETY: `Volume::validate` proved every in-range index lies in
            // the buffer; j and k are asserted above and i < dims[0].
            let v = unsafe {
                self.data
                    .get_unchecked((base + i as isize * s0) as usize)
                    .to_f64()
            };
            if T::FLOAT {
                finite &= v.is_finite();
            }
            *b = (v >= iso) as u8;
        }
        finite
    }

    /// The eight corner samples of cell `[i, j, k]` (local indices), as
    /// f64, in VTK corner order.
    #[inline(always)]
    pub(crate) fn corners(&self, [i, j, k]: [usize; 3]) -> [f64; 8] {
        [
            self.get(i, j, k),
            self.get(i + 1, j, k),
            self.get(i + 1, j + 1, k),
            self.get(i, j + 1, k),
            self.get(i, j, k + 1),
            self.get(i + 1, j, k + 1),
            self.get(i + 1, j + 1, k + 1),
            self.get(i, j + 1, k + 1),
        ]
    }

    /// Sample at local indices, as f64.
    #[inline(always)]
    pub(crate) fn get(&self, i: usize, j: usize, k: usize) -> f64 {
        debug_assert!(i < self.dims[0] && j < self.dims[1] && k < self.dims[2]);
        let idx = self.offset
            + i as isize * self.strides[0]
            + j as isize * self.strides[1]
            + k as isize * self.strides[2];
        // SAFETY: `Volume::validate` proved that every index reachable with
        // in-range (i, j, k) lies in 0..data.len(), and callers only pass
        // in-range indices (checked in debug builds above).
        unsafe { self.data.get_unchecked(idx as usize).to_f64() }
    }
}

#[cfg(test)]
mod tests {
    use super::Scalar;
    use crate::point_key::next_float;

    /// The comparison in `f64`, as the default `inside_run` makes it.
    fn reference<T: Scalar>(run: &[T], iso: f64) -> Vec<u8> {
        run.iter().map(|v| (v.to_f64() >= iso) as u8).collect()
    }

    /// Narrow integers compare against a threshold in their own type:
    /// the same bits as in `f64` for every isovalue, in range or not.
    #[test]
    fn integer_thresholds_match_the_f64_comparison() {
        fn check<T: Scalar + TryFrom<i64>>(lo: i64, hi: i64) {
            let vals: Vec<T> = [lo, lo + 1, -1, 0, 1, 2, 7, hi - 1, hi]
                .iter()
                .filter_map(|&v| T::try_from(v).ok())
                .collect();
            let (lo, hi) = (lo as f64, hi as f64);
            for iso in [
                lo - 1e12,
                lo - 1.0,
                lo - 0.5,
                lo,
                lo + 0.25,
                -1.5,
                -1.0,
                -0.0,
                0.0,
                1e-300,
                0.5,
                1.0,
                1.999,
                2.0,
                6.5,
                7.0,
                hi - 0.5,
                hi,
                hi + 0.5,
                hi + 1e12,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ] {
                let mut bits = vec![9u8; vals.len()];
                assert!(T::inside_run(&vals, iso, &mut bits));
                assert_eq!(bits, reference(&vals, iso), "iso {iso}");
            }
        }
        check::<i8>(i8::MIN as i64, i8::MAX as i64);
        check::<u8>(0, u8::MAX as i64);
        check::<i16>(i16::MIN as i64, i16::MAX as i64);
        check::<u16>(0, u16::MAX as i64);
        check::<i32>(i32::MIN as i64, i32::MAX as i64);
        check::<u32>(0, u32::MAX as i64);
    }

    /// float32 compares in its own type against a rounded threshold: the
    /// same bits and finiteness as in `f64`, on values from every part of
    /// the type (zeros, subnormals, the extremes, infinities, NaNs) and
    /// isovalues on, next to and between them.
    #[test]
    fn float32_threshold_matches_the_f64_comparison() {
        let mut rng = crate::test_rng::XorShift(0x9e37_79b9_7f4a_7c15);
        let mut next = || rng.bits();
        let mut vals: Vec<f32> = [
            0.0,
            -0.0,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MIN_POSITIVE,
            1.0,
            -1.0,
            0.1,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ]
        .to_vec();
        vals.extend((0..2000).map(|_| f32::from_bits(next() as u32)));
        vals.extend((0..2000).map(|_| (next() % 2001) as f32 / 7.0 - 140.0));
        let mut isos: Vec<f64> = vec![f64::INFINITY, f64::NEG_INFINITY, f64::MAX, f64::MIN];
        for &v in vals.iter().take(600).chain(&vals[2013..2400]) {
            if v.is_nan() {
                continue;
            }
            let x = v as f64;
            let up = f32::from_bits(if v >= 0.0 {
                v.to_bits() + 1
            } else {
                v.to_bits() - 1
            });
            // (An infinite `x` steps to NaN, dropped below, or to the
            // largest finite value.)
            isos.extend([
                x,
                next_float(x, true),
                next_float(x, false),
                (x + up as f64) / 2.0,
            ]);
        }
        for iso in isos.into_iter().filter(|x| !x.is_nan()) {
            for chunk in vals.chunks(97) {
                let mut bits = vec![9u8; chunk.len()];
                let finite = f32::inside_run(chunk, iso, &mut bits);
                assert_eq!(bits, reference(chunk, iso), "iso {iso:e}");
                assert_eq!(finite, chunk.iter().all(|v| v.is_finite()));
            }
        }
    }

    /// Floats keep the `f64` comparison and report non-finite values.
    #[test]
    fn float_runs_report_non_finite_values() {
        let vals = [0.5f32, -1.0, 3.0];
        let mut bits = [0u8; 3];
        assert!(f32::inside_run(&vals, 0.5, &mut bits));
        assert_eq!(bits, [1, 0, 1]);
        let vals = [0.5f64, f64::NAN, 3.0];
        assert!(!f64::inside_run(&vals, 0.5, &mut bits));
        assert_eq!(bits, [1, 0, 1]);
    }
}
