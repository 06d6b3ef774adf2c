//! Per-point gradients (`Options::gradients`): off by default, exact in
//! world units on linear fields (also of extreme magnitude, contoured on
//! a scaled copy), the normals' own gradients (each normal the negated,
//! normalised gradient) in both normal modes, and bit-identical for any
//! thread count.

mod common;

use common::*;
use precisemc::{extract, Mesh, NormalMode, Options, Topology, Volume};

const MODES: [NormalMode; 3] = [
    NormalMode::None,
    NormalMode::Gradient,
    NormalMode::CentralDifference,
];

fn opts(normals: NormalMode, refine: bool) -> Options {
    Options {
        normals,
        gradients: true,
        threads: 1,
        ..if refine {
            refine_opts(Topology::Trilinear, precisemc::Rule::A1, 0.01, 3)
        } else {
            mc_opts(Topology::Classic)
        }
    }
}

#[test]
fn gradients_are_off_by_default() {
    assert!(!Options::default().gradients);
    let v = sphere([8, 8, 8], [3.5, 3.4, 3.6], 2.5);
    let m = extract(&Volume::new(&v, [8; 3]), 0.0, &Options::default()).unwrap();
    assert!(!m.points.is_empty());
    assert!(m.gradients.is_empty() && m.normals.is_empty());
    // On, with normals off: gradients alone.
    let m = extract(&Volume::new(&v, [8; 3]), 0.0, &opts(NormalMode::None, true)).unwrap();
    assert_eq!(m.gradients.len(), m.points.len());
    assert!(m.normals.is_empty());
}

/// On `F = a . x + b` (world coordinates, non-unit spacing, an origin) the
/// gradient at every point is `a`, to float rounding, in each mode,
/// refined or not.
#[test]
fn gradients_of_a_linear_field_are_its_slope_in_world_units() {
    let a = [0.7, -1.3, 2.1];
    let origin = [1.0, -2.0, 3.0];
    let spacing = [0.5, 2.0, 0.25];
    let dims = [7usize, 8, 9];
    let values = grid_fn(dims, |i, j, k| {
        let x = [
            origin[0] + spacing[0] * i,
            origin[1] + spacing[1] * j,
            origin[2] + spacing[2] * k,
        ];
        a[0] * x[0] + a[1] * x[1] + a[2] * x[2] + 0.4
    });
    let v = Volume::new(&values, dims_u64(dims))
        .with_origin(origin)
        .with_spacing(spacing);
    let iso = volume_value(&values, dims, [3.2, 3.7, 4.1]);
    for normals in MODES {
        for refine in [false, true] {
            let m = extract(&v, iso, &opts(normals, refine)).unwrap();
            assert!(m.points.len() > 20);
            assert_eq!(m.gradients.len(), m.points.len());
            for g in &m.gradients {
                for c in 0..3 {
                    assert!(
                        (g[c] as f64 - a[c]).abs() <= 1e-6 * a[c].abs(),
                        "{normals:?} refine {refine}: {g:?} != {a:?}"
                    );
                }
            }
        }
    }
}

/// `f64` samples beyond `[2^-256, 2^256]` are contoured on a copy scaled
/// by a power of two: the gradients are still those of the caller's
/// samples. `F = c . x` sampled at `x = 2^e * index` has gradient `c`.
#[test]
fn gradients_of_extreme_samples_are_unscaled() {
    let c = [0.75, -1.5, 1.25];
    let dims = [6usize, 6, 6];
    for e in [-900, 900] {
        let s = 2f64.powi(e);
        let values = grid_fn(dims, |i, j, k| s * (c[0] * i + c[1] * j + c[2] * k));
        let v = Volume::new(&values, dims_u64(dims)).with_spacing([s; 3]);
        for normals in MODES {
            let m = extract(&v, s * 0.3, &opts(normals, false)).unwrap();
            assert!(!m.gradients.is_empty());
            for g in &m.gradients {
                for a in 0..3 {
                    assert!(
                        (g[a] as f64 - c[a]).abs() <= 1e-6,
                        "2^{e} {normals:?}: {g:?} != {c:?}"
                    );
                }
            }
        }
    }
}

/// Where both are requested, each normal is the negated, normalised
/// gradient of its point ((0, 0, 0) where the gradient is), and asking
/// for gradients changes neither the mesh nor the normals; with normals
/// off the gradients are the exact trilinear ones.
#[test]
fn normals_are_negated_normalised_gradients() {
    let mut checked = 0usize;
    for seed in 0..6u64 {
        let dims = [12usize, 11, 13];
        let values = if seed % 2 == 0 {
            blobs(dims, seed, 6)
        } else {
            random_interior(dims, seed, -1.0, 1.0, -1.0)
        };
        let v = Volume::new(&values, dims_u64(dims))
            .with_origin([0.5, -1.0, 2.0])
            .with_spacing([0.6, 1.3, 0.9]);
        let iso = if seed % 2 == 0 { 0.0 } else { 0.1 };
        for refine in [false, true] {
            let exact = extract(&v, iso, &opts(NormalMode::Gradient, refine)).unwrap();
            let alone = extract(&v, iso, &opts(NormalMode::None, refine)).unwrap();
            assert_eq!(alone.gradients, exact.gradients, "seed {seed}");
            for normals in [NormalMode::Gradient, NormalMode::CentralDifference] {
                let m = extract(&v, iso, &opts(normals, refine)).unwrap();
                let plain = extract(
                    &v,
                    iso,
                    &Options {
                        gradients: false,
                        ..opts(normals, refine)
                    },
                )
                .unwrap();
                assert!(plain.gradients.is_empty());
                assert_eq!(
                    Mesh {
                        gradients: Vec::new(),
                        ..m.clone()
                    },
                    plain
                );
                for (n, g) in m.normals.iter().zip(&m.gradients) {
                    let g = g.map(f64::from);
                    let len = norm(g);
                    assert!(len.is_finite(), "{g:?}");
                    if len == 0.0 {
                        assert_eq!(*n, [0.0; 3], "seed {seed} {normals:?}");
                        continue;
                    }
                    for c in 0..3 {
                        assert!(
                            (n[c] as f64 + g[c] / len).abs() < 1e-6,
                            "seed {seed} {normals:?} refine {refine}: normal {n:?}, gradient {g:?}"
                        );
                    }
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 10_000, "{checked}");
}

/// Bit-identical gradients for 1, 2 and 4 threads, on a mesh large enough
/// to be cut into several tasks.
#[test]
fn gradients_do_not_depend_on_the_thread_count() {
    let dims = [32usize, 32, 32];
    let values = random_interior(dims, 7, -1.0, 1.0, -1.0);
    let v = Volume::new(&values, dims_u64(dims)).with_spacing([0.7, 1.1, 0.9]);
    for normals in MODES {
        for refine in [false, true] {
            let run = |threads| {
                let o = Options {
                    threads,
                    ..opts(normals, refine)
                };
                extract(&v, 0.1, &o).unwrap()
            };
            let one = run(1);
            assert!(one.points.len() > 3 * 4096, "{}", one.points.len());
            let bits = |m: &Mesh| -> Vec<[u32; 3]> {
                m.gradients.iter().map(|g| g.map(f32::to_bits)).collect()
            };
            for threads in [2, 4] {
                let m = run(threads);
                assert!(
                    bits(&m) == bits(&one),
                    "{normals:?} refine {refine}: {threads} threads differ"
                );
            }
        }
    }
}

/// A spacing so small that the world gradient leaves float's range gives
/// infinite components, never NaN; a huge one, zeros that keep their sign.
#[test]
fn gradients_of_extreme_spacings_are_not_nan() {
    let values = grid_fn([6, 6, 6], |x, y, z| {
        ((x - 2.5).powi(2) + (y - 2.4).powi(2) + (z - 2.6).powi(2)).sqrt()
    });
    let centre = [2.5, 2.4, 2.6];
    for spacing in [[5e-324, 1.0, 1.0], [1.0, 1e-310, 1e300]] {
        let v = Volume::new(&values, [6, 6, 6]).with_spacing(spacing);
        for normals in MODES {
            let m = extract(&v, 1.7, &opts(normals, false)).unwrap();
            assert!(!m.gradients.is_empty());
            assert!(m
                .gradients
                .iter()
                .all(|g| g.iter().all(|c| !c.is_nan()) && g.iter().any(|c| *c != 0.0)));
            // Along each axis, away from the centre's plane (where the
            // sampled distance field's derivative has a sure sign): a tiny
            // spacing gives an infinite component, a huge one a zero, each
            // with the sign of the distance's derivative; spacing 1 a finite
            // one.
            let mut checked = [0; 3];
            for (g, p) in m.gradients.iter().zip(&m.index_points) {
                for a in 0..3 {
                    let off = p[a] - centre[a];
                    if off.abs() < 0.6 {
                        continue;
                    }
                    checked[a] += 1;
                    let c = g[a];
                    assert_eq!(
                        c.is_sign_negative(),
                        off < 0.0,
                        "{spacing:?} {normals:?}: axis {a} at {p:?}: {g:?}"
                    );
                    match spacing[a] {
                        s if s < 1e-300 => assert!(c.is_infinite(), "{spacing:?}: {g:?}"),
                        s if s > 1e299 => assert_eq!(c, 0.0, "{spacing:?}: {g:?}"),
                        _ => assert!(
                            c.is_finite() && c != 0.0,
                            "{spacing:?} {normals:?} at {p:?}: {g:?}"
                        ),
                    }
                }
            }
            assert!(checked.iter().all(|&n| n > 20), "{checked:?}");
        }
    }
}

/// The exact-gradient mode's gradient is the trilinear interpolant's at the
/// point itself, in the cell that holds it (the floor of its index
/// coordinates, the last cell on the volume's upper faces), on fields
/// whose gradient varies across every cell: on the linear fields above any
/// point of a cell gives the same gradient, and a comparison with
/// vtkFlyingEdges3D's central differences within a few degrees let the
/// gradient at the cell's centre pass. Plain and refined surfaces (split
/// points inside cells), world units with an anisotropic spacing.
#[test]
fn exact_gradients_are_the_interpolants_at_the_point() {
    use precisemc::filter::evaluate;
    use precisemc::Reconstruction;
    let spacing = [0.5, 1.0, 2.0];
    let mut checked = 0;
    for seed in 0..3u64 {
        let dims = [13, 11, 12];
        let values = if seed == 2 {
            random_interior(dims, 5, -1.0, 1.0, -1.0)
        } else {
            blobs(dims, seed, 4)
        };
        let vol = Volume::new(&values, dims_u64(dims)).with_spacing(spacing);
        for refine in [false, true] {
            let m = extract(&vol, 0.0, &opts(NormalMode::Gradient, refine)).unwrap();
            assert!(
                m.points.len() > 50,
                "seed {seed}: {} points",
                m.points.len()
            );
            for (p, g) in m.index_points.iter().zip(&m.gradients) {
                let cell: [u64; 3] =
                    std::array::from_fn(|a| (p[a].floor().max(0.0) as u64).min(dims[a] as u64 - 2));
                let local: [f64; 3] = std::array::from_fn(|a| p[a] - cell[a] as f64);
                let (_, e) = evaluate(&vol, Reconstruction::Trilinear, cell, local)
                    .unwrap()
                    .unwrap();
                let e: [f64; 3] = std::array::from_fn(|a| e[a] / spacing[a]);
                let len = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
                if len == 0.0 {
                    continue; // central differences stand in there
                }
                for a in 0..3 {
                    assert!(
                        (g[a] as f64 - e[a]).abs() <= 1e-6 * len,
                        "seed {seed} refine {refine}: gradient {g:?} at {p:?}, \
                         the interpolant's {e:?}"
                    );
                }
                checked += 1;
            }
        }
    }
    assert!(checked > 1000, "{checked} points checked");
}
