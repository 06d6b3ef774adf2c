//! Test 7: property-based tests over random small volumes (dims 2..6),
//! every scalar type, random strides and offsets (the samples embedded in
//! a bigger buffer, axes possibly flipped), random isovalues and options.
//!
//! * No panic, no NaN or infinite coordinate, indices in range, arrays of
//!   consistent length.
//! * The strided, embedded volume gives a mesh bit-identical to the same
//!   samples stored contiguously (except for axis flips, which only permute
//!   storage: the mesh is also identical since it depends on the logical
//!   samples only).
//! * When the border is below the isovalue the mesh is a closed, oriented
//!   2-cycle (uses a->b equal uses b->a for every edge, no boundary edge).
//! * Arbitrary (mostly invalid) parameters give `Ok` or `Err`, never a
//!   panic; `Ok` exactly when `Volume::validate` and the option checks pass.

mod common;

use common::*;
use precisemc::{extract, Mesh, Options, Rule, Samples, Topology, Volume};
use proptest::prelude::*;

#[derive(Debug, Clone)]
struct Case {
    dims: [usize; 3],
    ty: usize,
    raw: Vec<i64>,
    nan_at: Option<usize>,
    pad: [usize; 3],
    flip: [bool; 3],
    lead: usize,
    closed: bool,
    iso_frac: f64,
    topology: bool,
    rule: usize,
    eps: usize,
    max_level: u32,
    threads: usize,
}

fn case_strategy() -> impl Strategy<Value = Case> {
    (
        (2usize..=6, 2usize..=6, 2usize..=6),
        0usize..10,
        prop::collection::vec(-1000i64..1000, 216),
        prop::option::weighted(0.15, 0usize..216),
        (0usize..3, 0usize..3, 0usize..3),
        (any::<bool>(), any::<bool>(), any::<bool>()),
        0usize..7,
        any::<bool>(),
        0.0f64..1.0,
        (any::<bool>(), 0usize..4, 0usize..3, 0u32..4, 1usize..3),
    )
        .prop_map(
            |(
                d,
                ty,
                raw,
                nan_at,
                pad,
                flip,
                lead,
                closed,
                iso_frac,
                (topology, rule, eps, max_level, threads),
            )| Case {
                // A closed case's border is set below the isovalue: with a
                // dimension of 2 every sample is on it and there would be no
                // surface to check.
                dims: [d.0, d.1, d.2].map(|n| if closed { n.max(3) } else { n }),
                ty,
                raw,
                nan_at,
                pad: [pad.0, pad.1, pad.2],
                flip: [flip.0, flip.1, flip.2],
                lead,
                closed,
                iso_frac,
                topology,
                rule,
                eps,
                max_level,
                threads,
            },
        )
}

/// Logical sample values (as i64 before conversion to the type).
fn logical(c: &Case) -> Vec<i64> {
    let n = c.dims[0] * c.dims[1] * c.dims[2];
    let mut v: Vec<i64> = c.raw[..n].to_vec();
    if c.closed {
        set_border(&mut v, c.dims, -1000);
    }
    v
}

/// Buffer layout: returns (buffer length, offset, strides).
fn layout(c: &Case) -> (usize, u64, [i64; 3]) {
    let ext = [
        c.dims[0] + c.pad[0],
        c.dims[1] + c.pad[1],
        c.dims[2] + c.pad[2],
    ];
    let base = [1i64, ext[0] as i64, (ext[0] * ext[1]) as i64];
    let mut strides = base;
    let mut offset = c.lead as i64;
    for a in 0..3 {
        if c.flip[a] {
            strides[a] = -base[a];
            offset += (c.dims[a] as i64 - 1) * base[a];
        }
    }
    (
        c.lead + ext[0] * ext[1] * ext[2] + 3,
        offset as u64,
        strides,
    )
}

fn embed<T: Copy>(c: &Case, vals: &[T], filler: T) -> Vec<T> {
    let (len, offset, strides) = layout(c);
    let mut buf = vec![filler; len];
    for k in 0..c.dims[2] {
        for j in 0..c.dims[1] {
            for i in 0..c.dims[0] {
                let idx = offset as i64
                    + i as i64 * strides[0]
                    + j as i64 * strides[1]
                    + k as i64 * strides[2];
                buf[idx as usize] = vals[i + c.dims[0] * (j + c.dims[1] * k)];
            }
        }
    }
    buf
}

fn options(c: &Case) -> Options {
    Options {
        epsilon: [0.0, 0.05, 0.01][c.eps],
        max_level: c.max_level,
        rule: [Rule::A, Rule::A1, Rule::A2, Rule::B][c.rule],
        topology: if c.topology {
            Topology::Trilinear
        } else {
            Topology::Classic
        },
        threads: c.threads,
        ..Options::default()
    }
}

fn run_pair(c: &Case, contiguous: Samples<'_>, embedded: Samples<'_>, iso: f64) -> (Mesh, Mesh) {
    let d = dims_u64(c.dims);
    let (_, offset, strides) = layout(c);
    let opts = options(c);
    let a = extract(&Volume::new(contiguous, d), iso, &opts).expect("contiguous");
    let b = extract(
        &Volume::new(embedded, d)
            .with_strides(strides)
            .with_offset(offset),
        iso,
        &opts,
    )
    .expect("embedded");
    (a, b)
}

macro_rules! typed {
    ($c:expr, $t:ty, $conv:expr, $filler:expr) => {{
        let conv = $conv;
        let vals: Vec<$t> = logical($c).iter().map(|&x| conv(x)).collect();
        let lo = vals.iter().map(|&x| x as f64).fold(f64::INFINITY, f64::min);
        let hi = vals
            .iter()
            .map(|&x| x as f64)
            .fold(f64::NEG_INFINITY, f64::max);
        let iso = if hi > lo {
            lo + (hi - lo) * (0.02 + 0.96 * $c.iso_frac)
        } else {
            lo + 0.5
        };
        let emb = embed($c, &vals, $filler);
        run_pair($c, Samples::from(&vals), Samples::from(&emb), iso)
    }};
}

fn float_vals(c: &Case) -> Vec<f64> {
    let mut v: Vec<f64> = logical(c).iter().map(|&x| x as f64 / 37.0).collect();
    if let Some(at) = c.nan_at {
        let n = v.len();
        v[at % n] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][at % 3];
    }
    v
}

fn run_case(c: &Case) -> (Mesh, Mesh, bool) {
    let fv = float_vals(c);
    let has_nonfinite = c.ty >= 8 && fv.iter().any(|x| !x.is_finite());
    let (a, b) = match c.ty {
        0 => typed!(c, i8, |x: i64| (x / 8) as i8, 77i8),
        1 => typed!(c, u8, |x: i64| ((x + 1000) / 8) as u8, 77u8),
        2 => typed!(c, i16, |x: i64| (x * 30) as i16, 77i16),
        3 => typed!(c, u16, |x: i64| ((x + 1000) * 30) as u16, 77u16),
        4 => typed!(c, i32, |x: i64| (x * 1_000_000) as i32, 77i32),
        5 => typed!(c, u32, |x: i64| ((x + 1000) * 1_000_000) as u32, 77u32),
        6 => typed!(c, i64, |x: i64| x * 1_000_000_007, 77i64),
        7 => typed!(c, u64, |x: i64| (x + 1000) as u64 * 3, 77u64),
        8 => {
            let v32: Vec<f32> = fv.iter().map(|&x| x as f32).collect();
            let finite: Vec<f64> = v32
                .iter()
                .filter(|x| x.is_finite())
                .map(|&x| x as f64)
                .collect();
            let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let iso = if hi > lo {
                lo + (hi - lo) * (0.02 + 0.96 * c.iso_frac)
            } else {
                0.5
            };
            let emb = embed(c, &v32, f32::NAN);
            run_pair(c, Samples::from(&v32), Samples::from(&emb), iso)
        }
        _ => {
            let finite: Vec<f64> = fv.iter().copied().filter(|x| x.is_finite()).collect();
            let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let iso = if hi > lo {
                lo + (hi - lo) * (0.02 + 0.96 * c.iso_frac)
            } else {
                0.5
            };
            let emb = embed(c, &fv, f64::NAN);
            run_pair(c, Samples::from(&fv), Samples::from(&emb), iso)
        }
    };
    (a, b, has_nonfinite)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn random_volumes_are_sane_closed_and_layout_independent(c in case_strategy()) {
        let (a, b, nonfinite) = run_case(&c);
        assert_sane(&a);
        assert_sane(&b);
        prop_assert!(same_mesh(&a, &b), "embedded volume gives a different mesh");
        prop_assert_eq!(a.stats.cells, ((c.dims[0] - 1) * (c.dims[1] - 1) * (c.dims[2] - 1)) as u64);
        if c.closed && !nonfinite {
            let k = check_mesh(&a);
            prop_assert_eq!(k.boundary_edges, 0, "{:?}", k);
            prop_assert_eq!(k.unbalanced_edges, 0, "{:?}", k);
            prop_assert_eq!(k.misoriented_edges, 0, "{:?}", k);
        }
        if nonfinite {
            prop_assert!(a.stats.skipped_nonfinite_cells >= 1);
        }
    }

    /// Any parameters: an error exactly when they are invalid (decided here
    /// from the documented rules, not by the library's own validation),
    /// never a panic; valid ones give a sane mesh. Half the cases are laid
    /// out consistently (contiguous strides, some axes reversed, the
    /// buffer just long enough), so that valid volumes are common.
    #[test]
    fn arbitrary_parameters_never_panic(
        dims in (0u64..5, 0u64..5, 0u64..5),
        strides in (-30i64..30, -30i64..30, -30i64..30),
        offset in 0u64..80,
        len in 0usize..100,
        consistent in any::<bool>(),
        spacing in prop::sample::select(vec![1.0, 0.5, 0.0, -1.0, f64::NAN, f64::INFINITY]),
        iso in prop::sample::select(vec![0.0, 0.5, f64::NAN, f64::INFINITY, -3.0]),
        eps in prop::sample::select(vec![0.0, 0.01, -0.01, f64::NAN, 1e300]),
        max_level in 0u32..13,
        seed in any::<u64>(),
    ) {
        let mut rng = common::Rng::new(seed);
        let (mut dims, mut strides, mut offset, mut len, mut spacing) =
            ([dims.0, dims.1, dims.2], [strides.0, strides.1, strides.2], offset, len, spacing);
        if consistent {
            dims = dims.map(|d| d.max(2));
            strides = [1, dims[0] as i64, (dims[0] * dims[1]) as i64];
            offset = 0;
            for (a, s) in strides.iter_mut().enumerate() {
                if seed >> a & 1 == 1 {
                    offset += (dims[a] - 1) * *s as u64;
                    *s = -*s;
                }
            }
            len = (dims[0] * dims[1] * dims[2]) as usize + (seed >> 3) as usize % 3;
            if !(spacing > 0.0 && spacing.is_finite()) {
                spacing = 1.0;
            }
        }
        // The element indices the box reaches: its corners bound them.
        let (mut lo, mut hi) = (offset as i128, offset as i128);
        for a in 0..3 {
            let span = (dims[a] as i128 - 1) * strides[a] as i128;
            if span < 0 { lo += span } else { hi += span }
        }
        let layout_ok = dims.iter().all(|&d| d >= 2)
            && !strides.contains(&0)
            && lo >= 0
            && hi < len as i128;
        let valid = layout_ok
            && spacing.is_finite()
            && spacing > 0.0
            && iso.is_finite()
            && eps.is_finite()
            && eps >= 0.0
            && max_level <= precisemc::MAX_LEVEL_LIMIT;
        let data: Vec<f32> = (0..len).map(|_| rng.range(-1.0, 1.0) as f32).collect();
        let vol = Volume::new(&data, dims)
            .with_strides(strides)
            .with_offset(offset)
            .with_spacing([1.0, spacing, 1.0]);
        let opts = Options { epsilon: eps, max_level, threads: 1, ..Options::default() };
        let r = extract(&vol, iso, &opts);
        prop_assert_eq!(r.is_ok(), valid, "{:?}", r.as_ref().err());
        if let Ok(m) = r {
            assert_sane(&m);
            prop_assert_eq!(
                m.stats.cells,
                (dims[0] - 1) * (dims[1] - 1) * (dims[2] - 1)
            );
        }
    }
}
