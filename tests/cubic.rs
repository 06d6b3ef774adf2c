//! The tricubic reconstruction filters: exact on the polynomials each
//! reproduces, continuous across cells (bit for bit on shared faces), and
//! refinement onto their isosurfaces stays watertight, crack-free and
//! deterministic.

mod common;

use common::*;
use precisemc::filter::evaluate;
use precisemc::{extract, Options, Reconstruction, Rule, Topology, Volume};

const CUBIC: [Reconstruction; 3] = [
    Reconstruction::CatmullRom,
    Reconstruction::BSpline,
    Reconstruction::BSplineInterpolating,
];

fn value(v: &Volume<'_>, r: Reconstruction, cell: [u64; 3], p: [f64; 3]) -> (f64, [f64; 3]) {
    evaluate(v, r, cell, p).unwrap().unwrap()
}

/// Catmull–Rom reproduces polynomials of degree <= 2 per variable and the
/// B-spline on the samples degree <= 1, away from the clamped border (cells whose 4x4x4
/// neighbourhood lies inside the volume); values and gradients.
#[test]
fn polynomial_reproduction() {
    let dims = [8, 7, 9];
    let quad = |x: f64, y: f64, z: f64| 0.3 * x * x - 0.2 * x * y + 0.5 * y * z * z + z - 1.0;
    let quad_grad =
        |x: f64, y: f64, z: f64| [0.6 * x - 0.2 * y, -0.2 * x + 0.5 * z * z, y * z + 1.0];
    let lin = |x: f64, y: f64, z: f64| 0.7 * x - 1.3 * y + 0.4 * z + 2.0;
    let fq = grid_fn(dims, quad);
    let fl = grid_fn(dims, lin);
    let vq = Volume::new(&fq, dims_u64(dims));
    let vl = Volume::new(&fl, dims_u64(dims));
    let mut rng = Rng::new(3);
    for _ in 0..300 {
        let cell = [0, 1, 2].map(|a| 1 + (rng.range(0.0, (dims[a] - 4) as f64) as u64));
        let p = [
            rng.range(0.0, 1.0),
            rng.range(0.0, 1.0),
            rng.range(0.0, 1.0),
        ];
        let x = [0, 1, 2].map(|a| cell[a] as f64 + p[a]);
        let (f, g) = value(&vq, Reconstruction::CatmullRom, cell, p);
        let want = quad(x[0], x[1], x[2]);
        let wg = quad_grad(x[0], x[1], x[2]);
        assert!((f - want).abs() < 1e-11, "CR {x:?}: {f} vs {want}");
        for a in 0..3 {
            assert!(
                (g[a] - wg[a]).abs() < 1e-10,
                "CR gradient {x:?}: {g:?} vs {wg:?}"
            );
        }
        // The prefiltered B-spline's clamped border condition does not
        // keep linear functions linear near the border; it is checked by
        // `interpolation_at_samples` instead.
        for r in [Reconstruction::CatmullRom, Reconstruction::BSpline] {
            let (f, g) = value(&vl, r, cell, p);
            assert!((f - lin(x[0], x[1], x[2])).abs() < 1e-11, "{r:?} {x:?}");
            for (a, w) in [0.7, -1.3, 0.4].into_iter().enumerate() {
                assert!((g[a] - w).abs() < 1e-10, "{r:?} gradient {g:?}");
            }
        }
    }
}

/// The interpolating filters pass through the samples (at cell corners),
/// everywhere including the border; the plain B-spline smooths.
#[test]
fn interpolation_at_samples() {
    let dims = [6, 6, 6];
    let values = random_interior(dims, 5, -1.0, 1.0, 0.5);
    let vol = Volume::new(&values, dims_u64(dims));
    let mut smoothed = 0;
    for k in 0..5u64 {
        for j in 0..5u64 {
            for i in 0..5u64 {
                let s = values[(i + 6 * (j + 6 * k)) as usize];
                for r in [
                    Reconstruction::CatmullRom,
                    Reconstruction::BSplineInterpolating,
                ] {
                    let (f, _) = value(&vol, r, [i, j, k], [0.0, 0.0, 0.0]);
                    assert!((f - s).abs() < 1e-10, "{r:?} at {i},{j},{k}: {f} vs {s}");
                }
                let (f, _) = value(&vol, Reconstruction::BSpline, [i, j, k], [0.0; 3]);
                smoothed += ((f - s).abs() > 1e-3) as usize;
            }
        }
    }
    assert!(smoothed > 50, "the plain B-spline should not interpolate");
}

/// On a face shared by two cells both cells give bit-identical values and
/// in-face gradient components (what crack-free refinement relies on).
#[test]
fn faces_agree_bit_for_bit() {
    let dims = [7, 7, 7];
    let values = random_interior(dims, 8, -2.0, 2.0, -1.0);
    let vol = Volume::new(&values, dims_u64(dims));
    let mut rng = Rng::new(9);
    for r in CUBIC.into_iter().chain([Reconstruction::Trilinear]) {
        for _ in 0..200 {
            let axis = (rng.range(0.0, 3.0) as usize).min(2);
            let mut a = [0, 1, 2].map(|_| rng.range(0.0, 5.0) as u64);
            a[axis] = a[axis].min(4);
            let mut b = a;
            b[axis] += 1;
            let mut pa = [
                rng.range(0.0, 1.0),
                rng.range(0.0, 1.0),
                rng.range(0.0, 1.0),
            ];
            pa[axis] = 1.0;
            let mut pb = pa;
            pb[axis] = 0.0;
            let (fa, ga) = value(&vol, r, a, pa);
            let (fb, gb) = value(&vol, r, b, pb);
            assert_eq!(fa.to_bits(), fb.to_bits(), "{r:?} value across face");
            for c in 0..3 {
                if c != axis {
                    assert_eq!(ga[c].to_bits(), gb[c].to_bits(), "{r:?} gradient {c}");
                }
            }
        }
    }
}

/// Refinement onto each filter's isosurface: closed fields stay
/// watertight, consistently oriented manifolds; output is identical for 1
/// and 2 threads; refined points lie on the filter's isosurface; and the
/// share of folded triangles (normal against the filter's gradient) is
/// measured and small on smooth data.
#[test]
fn refined_surfaces_are_closed_and_on_the_filter_isosurface() {
    let dims = [14, 14, 14];
    let values = blobs(dims, 6, 8);
    let vol = Volume::new(&values, dims_u64(dims));
    for r in CUBIC {
        for rule in [Rule::A1] {
            let opts = Options {
                reconstruction: r,
                threads: 1,
                ..refine_opts(Topology::Trilinear, rule, 0.002, 5)
            };
            let m = extract(&vol, 0.0, &opts).unwrap();
            assert!(
                m.stats.output_triangles > 2 * m.stats.mc_triangles,
                "{r:?} refines"
            );
            assert_sane(&m);
            let c = check_mesh(&m);
            assert!(c.is_closed_oriented_manifold(), "{r:?} {rule:?}: {c:?}");
            let two = extract(
                &vol,
                0.0,
                &Options {
                    threads: 2,
                    ..opts.clone()
                },
            )
            .unwrap();
            assert!(
                same_mesh(&m, &two),
                "{r:?} {rule:?}: thread count changed the output"
            );
            // Points off the grid lines are split points: on the filter's
            // isosurface (to rounding of the value range).
            // Marching Cubes' edge points are moved along their grid edge
            // onto the filter's isosurface where the filter brackets it
            // there: always for the interpolating filters (their values at
            // the samples are the samples, up to the prefilter's rounding).
            let mut on = 0;
            let (mut edge_points, mut edge_on) = (0, 0);
            let mut folded = 0;
            for p in &m.index_points {
                let on_grid_line = p.iter().filter(|c| c.fract() == 0.0).count() >= 2;
                let cell = [0, 1, 2].map(|a| (p[a].floor() as u64).min(dims[a] as u64 - 2));
                let local = [0, 1, 2].map(|a| p[a] - cell[a] as f64);
                let (f, _) = value(&vol, r, cell, local);
                if on_grid_line {
                    edge_points += 1;
                    edge_on += (f.abs() < 1e-9) as usize;
                    continue;
                }
                assert!(f.abs() < 1e-9, "{r:?}: split point {p:?} has F = {f}");
                on += 1;
            }
            assert!(on > 1000, "{r:?}: only {on} split points");
            println!("{r:?}: {edge_on} of {edge_points} edge points on the filter's isosurface");
            if r != Reconstruction::BSpline {
                assert!(
                    edge_on * 1000 >= edge_points * 999,
                    "{r:?}: {edge_on} of {edge_points} edge points on the isosurface"
                );
            }
            for t in &m.triangles {
                let n = tri_normal(&m.index_points, *t);
                let cen = centroid(&m.index_points, *t);
                let cell = [0, 1, 2].map(|a| (cen[a].floor() as u64).min(dims[a] as u64 - 2));
                let local = [0, 1, 2].map(|a| (cen[a] - cell[a] as f64).clamp(0.0, 1.0));
                let (_, g) = value(&vol, r, cell, local);
                // Outward normals point towards lower values: against g.
                folded += (dot(n, g) > 0.0) as usize;
            }
            // Marching Cubes' topology is the trilinear one, and a coarse
            // patch refined onto a curved surface can still turn a few
            // triangles against the cubic gradient (0.7-1 % here; 1.1-1.6 %
            // while edge points stayed at the linear crossings).
            let share = folded as f64 / m.triangles.len() as f64;
            println!(
                "{r:?} {rule:?}: {folded} of {} triangles folded",
                m.triangles.len()
            );
            assert!(
                share < 0.015,
                "{r:?} {rule:?}: {folded} folded triangles ({share})"
            );
        }
    }
}

/// Data mirror-symmetric about a grid plane (any volume three samples
/// thick, with its border below the isovalue) stays a closed manifold with
/// every filter and rule. A smooth filter's gradient lies in the plane of
/// symmetry, so a centre point put on that face (rule A2 clamps its
/// candidate into the cell) stayed in it: both cells made the same edges
/// in the face, each in four triangles (the smoothing B-spline with rule
/// A2, 12 of 300 random such volumes).
#[test]
fn mirror_symmetric_data_stays_a_closed_manifold() {
    let mut rng = Rng::new(0x5eed_3117);
    let mut failures = Vec::new();
    let filters = [Reconstruction::Trilinear, CUBIC[0], CUBIC[1], CUBIC[2]];
    for round in 0..60 {
        let dims = [3, 4 + rng.below(3) as usize, 4 + rng.below(2) as usize];
        let mut v = vec![-1.0f64; dims[0] * dims[1] * dims[2]];
        for k in 1..dims[2] - 1 {
            for j in 1..dims[1] - 1 {
                v[1 + dims[0] * (j + dims[1] * k)] = rng.range(-0.5, 1.0);
            }
        }
        let vol = Volume::new(&v, dims_u64(dims));
        for r in filters {
            for rule in [Rule::A1, Rule::A2, Rule::B] {
                let opts = Options {
                    reconstruction: r,
                    threads: 1,
                    ..refine_opts(Topology::Trilinear, rule, 0.01, 4)
                };
                let m = extract(&vol, 0.0, &opts).unwrap();
                let c = check_mesh(&m);
                if !c.is_closed_oriented_manifold() {
                    failures.push(format!("round {round} {r:?} {rule:?}: {c:?}"));
                }
            }
        }
    }
    // The reviewer's volume, found first.
    let dims = [3usize, 5, 4];
    let mut v = vec![-1.0f64; 60];
    for (j, k, x) in [
        (1, 1, -0.2588486587792489),
        (2, 1, 0.7451877101016711),
        (3, 1, 0.8302026555733331),
        (1, 2, -0.3509593392392478),
        (2, 2, 0.6019841818367995),
        (3, 2, 0.6543558196224188),
    ] {
        v[1 + dims[0] * (j + dims[1] * k)] = x;
    }
    for (eps, level) in [(0.01, 4), (0.003, 5)] {
        let opts = Options {
            reconstruction: Reconstruction::BSpline,
            threads: 1,
            ..refine_opts(Topology::Trilinear, Rule::A2, eps, level)
        };
        let m = extract(&Volume::new(&v, [3, 5, 4]), 0.0, &opts).unwrap();
        let c = check_mesh(&m);
        if !c.is_closed_oriented_manifold() {
            failures.push(format!("found volume, {eps}/{level}: {c:?}"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// A NaN and an infinite sample far from the surface cost only the cells
/// near them, with every filter: the surface stays whole and closed. (The
/// interpolating B-spline's prefilter once spread one NaN over the whole
/// volume: every cell was skipped and the mesh came out empty.) Where a
/// filter's cells do not reach the samples the output is unchanged bit
/// for bit; the interpolating B-spline's coefficients near them move a
/// little (its lines are solved in runs between them), so its surface is
/// only checked to be the same size.
#[test]
fn non_finite_samples_cost_only_the_cells_near_them() {
    let dims = [24, 24, 24];
    let clean = grid_fn(dims, |x, y, z| {
        8.0 - ((x - 12.0).powi(2) + (y - 11.5).powi(2) + (z - 12.5).powi(2)).sqrt()
    });
    let mut dirty = clean.clone();
    let at = |x: usize, y: usize, z: usize| x + dims[0] * (y + dims[1] * z);
    dirty[at(2, 2, 2)] = f64::NAN;
    dirty[at(21, 3, 20)] = f64::INFINITY;
    let (vc, vd) = (
        Volume::new(&clean, dims_u64(dims)),
        Volume::new(&dirty, dims_u64(dims)),
    );
    for r in [Reconstruction::Trilinear].into_iter().chain(CUBIC) {
        let opts = Options {
            reconstruction: r,
            ..refine_opts(Topology::Trilinear, Rule::A1, 0.01, 3)
        };
        let a = extract(&vc, 0.0, &opts).unwrap();
        let b = extract(&vd, 0.0, &opts).unwrap();
        assert_eq!(a.stats.skipped_nonfinite_cells, 0, "{r:?}");
        // A sample touches 8 cells, and a cubic filter's 4x4x4 neighbourhood
        // reaches it from 64.
        let skipped = b.stats.skipped_nonfinite_cells;
        assert!(
            (8..=2 * 64).contains(&skipped),
            "{r:?}: {skipped} cells skipped"
        );
        assert!(
            check_mesh(&b).is_closed_oriented_manifold(),
            "{r:?}: not closed"
        );
        if r == Reconstruction::BSplineInterpolating {
            let (na, nb) = (a.triangles.len() as f64, b.triangles.len() as f64);
            assert!(
                (na - nb).abs() <= 0.02 * na,
                "{r:?}: {na} and {nb} triangles"
            );
        } else {
            assert!(same_mesh(&a, &b), "{r:?}: the surface changed");
        }
    }
}

/// Samples that are NaN or infinite next to the surface. A cell whose 4x4x4
/// neighbourhood holds one is skipped; it still placed the crossings of its
/// grid edges first, at the linear crossing, where a neighbour that refines
/// moves them onto the filter's isosurface, so which cell came first (it
/// changes with the thread count and the slabs) moved points and changed
/// triangles (4 threads: 132067 triangles against 132091 on a wavelet with
/// one NaN). Bit-identical meshes for 1, 2 and 4 threads, with every cubic
/// filter, on volumes with NaN and infinite samples scattered along the
/// surface.
#[test]
fn non_finite_samples_next_to_the_surface_leave_the_mesh_thread_independent() {
    let dims = [44, 40, 42];
    let clean = grid_fn(dims, |x, y, z| {
        let r = ((x - 21.3).powi(2) + (y - 19.6).powi(2) + (z - 20.8).powi(2)).sqrt();
        15.0 - r + 1.5 * (0.4 * x).sin() * (0.3 * z).cos()
    });
    let mut compared = 0;
    for seed in 0..4u64 {
        let mut rng = Rng::new(seed);
        let mut dirty = clean.clone();
        for v in dirty.iter_mut() {
            if v.abs() < 1.5 && rng.f64() < 0.01 {
                *v = if rng.bool() {
                    f64::NAN
                } else {
                    f64::NEG_INFINITY
                };
            }
        }
        let vol = Volume::new(&dirty, dims_u64(dims));
        for r in CUBIC {
            let run = |threads| {
                let opts = Options {
                    reconstruction: r,
                    threads,
                    ..refine_opts(Topology::Trilinear, Rule::A1, 0.02, 2)
                };
                extract(&vol, 0.0, &opts).unwrap()
            };
            let one = run(1);
            assert!(one.stats.skipped_nonfinite_cells > 0, "{r:?}");
            assert!(one.triangles.len() > 1000, "{r:?}");
            for threads in [2, 4] {
                let other = run(threads);
                assert!(
                    same_mesh(&one, &other),
                    "seed {seed} {r:?}: {threads} threads differ from 1 ({} and {} triangles)",
                    other.triangles.len(),
                    one.triangles.len()
                );
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 24);
}

/// The default reconstruction is the trilinear filter: naming it gives the
/// default's mesh, and the option is honoured (a cubic filter refines to
/// a different mesh of the same volume).
#[test]
fn trilinear_is_the_default_filter() {
    assert_eq!(Options::default().reconstruction, Reconstruction::Trilinear);
    let dims = [10, 10, 10];
    let values = blobs(dims, 2, 5);
    let vol = Volume::new(&values, dims_u64(dims));
    let with = |reconstruction| Options {
        reconstruction,
        ..Options::default()
    };
    let a = extract(&vol, 0.0, &Options::default()).unwrap();
    assert!(a.triangles.len() > a.stats.mc_triangles as usize, "refined");
    let b = extract(&vol, 0.0, &with(Reconstruction::Trilinear)).unwrap();
    assert!(same_mesh(&a, &b));
    let c = extract(&vol, 0.0, &with(Reconstruction::CatmullRom)).unwrap();
    assert!(!same_mesh(&a, &c), "Catmull-Rom gave the trilinear mesh");
}

/// Through the C API: the setter rejects unknown values and the extraction
/// equals the Rust one with the same filter.
#[test]
fn c_api_selects_the_filter() {
    use precisemc::ffi::*;
    let dims = [10, 10, 10];
    let values = blobs(dims, 4, 5);
    let vol = Volume::new(&values, dims_u64(dims));
    let cv = pmc_volume {
        struct_size: std::mem::size_of::<pmc_volume>() as u64,
        data: values.as_ptr().cast(),
        len: values.len() as u64,
        scalar_type: PmcScalarType::F64 as u32,
        dims: dims_u64(dims),
        strides: [0; 3],
        origin: [0.0; 3],
        spacing: [1.0; 3],
    };
    for (raw, r) in [
        (0, Reconstruction::Trilinear),
        (1, Reconstruction::CatmullRom),
        (2, Reconstruction::BSpline),
        (3, Reconstruction::BSplineInterpolating),
    ] {
        unsafe {
            let o = pmc_options_new();
            assert_eq!(
                pmc_options_set_reconstruction(o, 4),
                PmcStatus::InvalidArgument
            );
            assert_eq!(pmc_options_set_reconstruction(o, raw), PmcStatus::Ok);
            let mut m = std::ptr::null_mut();
            assert_eq!(pmc_extract(&cv, 0.0, o, &mut m), PmcStatus::Ok);
            let rust = extract(
                &vol,
                0.0,
                &Options {
                    reconstruction: r,
                    ..Options::default()
                },
            )
            .unwrap();
            assert_eq!(
                pmc_mesh_triangle_count(m),
                rust.triangles.len() as u64,
                "{r:?}"
            );
            let pts = std::slice::from_raw_parts(pmc_mesh_index_points(m), 3 * rust.points.len());
            let flat: Vec<f64> = rust.index_points.iter().flatten().copied().collect();
            assert_eq!(pts, flat.as_slice(), "{r:?}");
            pmc_mesh_free(m);
            pmc_options_free(o);
        }
        assert_eq!(
            unsafe { pmc_options_set_reconstruction(std::ptr::null_mut(), raw) },
            PmcStatus::NullArgument
        );
    }
}
