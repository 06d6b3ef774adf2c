//! Test 3: closed fields (the border is below the isovalue) give closed
//! meshes, for both topologies, without refinement and with every rule.
//!
//! Generic fields (no sample equals the isovalue): every edge is in
//! exactly two triangles, used once in each direction (consistent
//! orientation), every vertex link is a single cycle (manifold), no
//! triangle is degenerate (repeated index or zero area) or duplicated,
//! every point is used, and the signed volume is positive (normals point
//! to lower values, i.e. out of the enclosed inside set).
//!
//! Integer fields with an integer isovalue (many samples exactly at the
//! isovalue; surfaces touch at such samples): the mesh is a closed,
//! consistently oriented 2-cycle, i.e. for every edge the uses a->b equal
//! the uses b->a (this allows an edge shared by four triangles where two
//! sheets touch, and non-manifold vertices), nothing is degenerate or
//! duplicated, and the signed volume is positive.

mod common;

use common::*;
use precisemc::{extract, Options, Reconstruction, Rule, Topology, Volume};

fn configs() -> Vec<(String, Options)> {
    let mut v = Vec::new();
    for topology in TOPOLOGIES {
        v.push((format!("{topology:?} MC"), mc_opts(topology)));
        for rule in RULES {
            v.push((
                format!("{topology:?} {rule:?}"),
                refine_opts(topology, rule, 0.01, 3),
            ));
        }
    }
    v
}

/// Name, dims, samples, expected (components, Euler characteristic).
type Field = (&'static str, [usize; 3], Vec<f64>, Option<(usize, i64)>);

fn closed_fields() -> Vec<Field> {
    vec![
        (
            "sphere",
            [12, 12, 12],
            sphere([12, 12, 12], [5.55, 5.45, 5.52], 4.0),
            Some((1, 2)),
        ),
        (
            "torus",
            [16, 16, 10],
            torus([16, 16, 10], [7.53, 7.48, 4.51], 4.5, 1.8),
            Some((1, 0)),
        ),
        ("blobs 1", [12, 12, 12], blobs([12, 12, 12], 1, 6), None),
        ("blobs 2", [11, 13, 12], blobs([11, 13, 12], 2, 8), None),
        (
            "random",
            [7, 7, 7],
            random_interior([7, 7, 7], 5, -1.0, 1.0, -1.0),
            None,
        ),
    ]
}

/// What is wrong with `mesh` (checked sane first) when it is not a closed,
/// oriented manifold enclosing a positive volume, with an even Euler
/// characteristic and, where given, the expected (components, Euler
/// characteristic); `None` when it is.
fn not_closed(mesh: &precisemc::Mesh, expect: Option<(usize, i64)>) -> Option<String> {
    assert_sane(mesh);
    let c = check_mesh(mesh);
    let vol_sign = signed_volume(&mesh.index_points, &mesh.triangles);
    let mut bad = !c.is_closed_oriented_manifold()
        || c.unreferenced != 0
        || vol_sign <= 0.0
        || c.triangles == 0
        || c.euler % 2 != 0;
    if let Some((comps, euler)) = expect {
        bad |= c.components != comps || c.euler != euler;
    }
    bad.then(|| format!("volume {vol_sign}, {c:?}"))
}

#[test]
fn closed_fields_give_closed_oriented_manifolds() {
    let mut failures = Vec::new();
    for (name, dims, values, expect) in closed_fields() {
        let vol = Volume::new(&values, dims_u64(dims));
        for (cfg, opts) in configs() {
            let mesh = extract(&vol, 0.0, &opts).unwrap();
            if let Some(what) = not_closed(&mesh, expect) {
                failures.push(format!("{name} / {cfg}: {what}"));
            }
            // Each point refinement adds is a split point, counted once
            // per cell that inserts it: once inside a cell, twice on a
            // face that two cells share (sub-cell meshes make points of
            // their own). Points of Marching Cubes lie on grid edges.
            let s = &mesh.stats;
            if opts.epsilon > 0.0 && s.cells_on_subcells == 0 {
                let on_grid = |p: &[f64; 3]| p.iter().filter(|c| c.fract() == 0.0).count();
                let plain = Options {
                    epsilon: 0.0,
                    max_level: 0,
                    ..opts.clone()
                };
                let mc = extract(&vol, 0.0, &plain).unwrap();
                let count = |m: &precisemc::Mesh, n: usize| {
                    m.index_points.iter().filter(|p| on_grid(p) == n).count()
                };
                // (Trilinear Marching Cubes has points inside some cells.)
                let face = count(&mesh, 1) - count(&mc, 1);
                let inner = count(&mesh, 0) - count(&mc, 0);
                // Within a few: a split point can weld onto another, or
                // replace a fan centre of Marching Cubes (a tenth of the
                // inner points is far below the double count of interior
                // edges' points this caught).
                let (lo, hi) = (
                    (inner + face) as u64,
                    (inner + inner / 10 + 2 * face) as u64,
                );
                if mesh.points.len() != mc.points.len() + face + inner
                    || !(lo..=hi).contains(&s.split_points)
                    || s.split_points > s.samples_evaluated
                {
                    failures.push(format!(
                        "{name} / {cfg}: {inner} points added inside cells and {face} on \
                         faces, {} split points, {} samples",
                        s.split_points, s.samples_evaluated
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The same closed fields refined onto the cubic filters' isosurfaces, with
/// every rule and topology: closed, oriented manifolds of the expected
/// topology (the tests of tests/cubic.rs cover one blob field with rule A1
/// and mirror-symmetric volumes).
#[test]
fn closed_fields_stay_closed_on_the_cubic_filters() {
    let mut failures = Vec::new();
    let mut runs = 0;
    for (name, dims, values, expect) in closed_fields() {
        let vol = Volume::new(&values, dims_u64(dims));
        for reconstruction in [
            Reconstruction::CatmullRom,
            Reconstruction::BSpline,
            Reconstruction::BSplineInterpolating,
        ] {
            for topology in TOPOLOGIES {
                for rule in RULES {
                    let opts = Options {
                        reconstruction,
                        ..refine_opts(topology, rule, 0.01, 3)
                    };
                    let mesh = extract(&vol, 0.0, &opts).unwrap();
                    if let Some(what) = not_closed(&mesh, expect) {
                        failures.push(format!(
                            "{name} / {reconstruction:?} {topology:?} {rule:?}: {what}"
                        ));
                    }
                    runs += 1;
                }
            }
        }
    }
    assert_eq!(runs, 5 * 3 * 2 * 4);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// The enclosed volume of a sphere is close to the ball's, and refinement
/// brings it closer (the trilinear surface of r - |x| is very near the
/// sphere).
#[test]
fn sphere_volume_is_accurate() {
    let dims = [14, 14, 14];
    let r = 5.0;
    let values = sphere(dims, [6.5, 6.5, 6.5], r);
    let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
    let vol = Volume::new(&values, dims_u64(dims));
    for topology in TOPOLOGIES {
        let mc = extract(&vol, 0.0, &mc_opts(topology)).unwrap();
        let refined = extract(&vol, 0.0, &refine_opts(topology, Rule::A1, 0.002, 5)).unwrap();
        let e_mc = (signed_volume(&mc.index_points, &mc.triangles) - exact).abs() / exact;
        let e_ref =
            (signed_volume(&refined.index_points, &refined.triangles) - exact).abs() / exact;
        assert!(e_mc < 0.05, "{topology:?} MC volume error {e_mc}");
        assert!(
            e_ref < e_mc,
            "{topology:?} refinement does not improve the volume: {e_ref} vs {e_mc}"
        );
        // S_K itself lies inside the sphere (the trilinear interpolant of the
        // convex |x| is above it), by about 2% of the volume here.
        assert!(e_ref < 0.03, "{topology:?} refined volume error {e_ref}");
    }
}

/// Integer-valued fields, integer isovalue: many samples equal the isovalue.
fn integer_fields() -> Vec<(String, [usize; 3], Vec<i16>, f64)> {
    let mut cases: Vec<(String, [usize; 3], Vec<i16>, f64)> = Vec::new();
    for seed in 0..6u64 {
        let dims = [7, 6, 7];
        let mut rng = Rng::new(100 + seed);
        let mut v: Vec<i16> = (0..dims[0] * dims[1] * dims[2])
            .map(|_| rng.below(3) as i16)
            .collect();
        set_border(&mut v, dims, 0);
        cases.push((format!("random {{0,1,2}} seed {seed}"), dims, v, 1.0));
    }
    {
        // A quantised sphere: |x| rounded, iso on an integer level.
        let dims = [13, 13, 13];
        let v: Vec<i16> = grid_fn(dims, |x, y, z| {
            let d = ((x - 6.0).powi(2) + (y - 6.0).powi(2) + (z - 6.0).powi(2)).sqrt();
            (8.0 - 2.0 * d).round().max(-4.0)
        })
        .into_iter()
        .map(|x| x as i16)
        .collect();
        cases.push(("quantised sphere".into(), dims, v, 0.0));
    }
    {
        // Two boxes of value 1 touching along an edge and at a corner, iso 1.
        let dims = [8, 8, 8];
        let v: Vec<i16> = grid_fn(dims, |x, y, z| {
            let a =
                (1.0..=3.0).contains(&x) && (1.0..=3.0).contains(&y) && (1.0..=6.0).contains(&z);
            let b =
                (3.0..=6.0).contains(&x) && (3.0..=6.0).contains(&y) && (1.0..=6.0).contains(&z);
            (a || b) as i32 as f64
        })
        .into_iter()
        .map(|x| x as i16)
        .collect();
        cases.push(("touching boxes".into(), dims, v, 1.0));
    }
    cases
}

/// Watertight: a closed, consistently oriented 2-cycle (every edge used as
/// often a->b as b->a, no boundary edge, no edge used twice in the same
/// direction), with positive enclosed volume.
#[test]
fn integer_fields_with_samples_at_the_isovalue_are_watertight() {
    let mut failures = Vec::new();
    for (name, dims, values, iso) in &integer_fields() {
        let vol = Volume::new(values, dims_u64(*dims));
        for (cfg, opts) in configs() {
            let mesh = extract(&vol, *iso, &opts).unwrap();
            assert_sane(&mesh);
            let c = check_mesh(&mesh);
            let vs = signed_volume(&mesh.index_points, &mesh.triangles);
            if c.unbalanced_edges != 0
                || c.boundary_edges != 0
                || c.misoriented_edges != 0
                // Every field has an inside of positive volume: an empty
                // mesh is a failure too.
                || c.triangles == 0
                || vs <= 0.0
            {
                failures.push(format!("{name} / {cfg}: volume {vs}, {c:?}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// No degenerate (repeated index or zero area) and no duplicated triangle
/// (same three points twice), even where sheets touch at samples.
#[test]
fn integer_fields_have_no_degenerate_or_duplicate_triangles() {
    let mut failures = Vec::new();
    for (name, dims, values, iso) in &integer_fields() {
        let vol = Volume::new(values, dims_u64(*dims));
        for (cfg, opts) in configs() {
            let mesh = extract(&vol, *iso, &opts).unwrap();
            assert_sane(&mesh);
            let c = check_mesh(&mesh);
            let vs = signed_volume(&mesh.index_points, &mesh.triangles);
            if c.degenerate != 0 || c.duplicates != 0 {
                failures.push(format!("{name} / {cfg}: volume {vs}, {c:?}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// A field whose isosurface passes exactly through many samples of a
/// smooth (non-integer) field: the plane z = 3.0 exactly on a grid layer.
#[test]
fn plane_through_a_sample_layer() {
    let dims = [6, 6, 8];
    let values = grid_fn(dims, |x, y, z| {
        if x == 0.0 || y == 0.0 || z == 0.0 || x == 5.0 || y == 5.0 || z == 7.0 {
            -1.0
        } else {
            3.0 - z + 0.0 * (x + y)
        }
    });
    let vol = Volume::new(&values, dims_u64(dims));
    for (cfg, opts) in configs() {
        let mesh = extract(&vol, 0.0, &opts).unwrap();
        let c = check_mesh(&mesh);
        assert!(
            c.unbalanced_edges == 0
                && c.boundary_edges == 0
                && c.degenerate == 0
                && c.duplicates == 0,
            "{cfg}: {c:?}"
        );
        assert!(
            signed_volume(&mesh.index_points, &mesh.triangles) > 0.0,
            "{cfg}"
        );
    }
}

/// Minimal reproduction: two coincident triangles of opposite orientation,
/// flat in the plane z = 2, one vertex at the edge crossing (1, 1.5, 2),
/// survive in Classic mode (duplicate removal only considers triangles
/// whose three points are grid points).
#[test]
fn coincident_opposite_triangles_are_removed() {
    let v: Vec<i16> = vec![
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, 1, 0, 0, 0, 0, 1, 0, 1, 0, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 2, 0,
        0, 2, 1, 0, 0, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1, 0,
        0, 2, 2, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0, 0, 0, 0, 0,
    ];
    let mesh = extract(
        &Volume::new(&v, [5, 5, 5]),
        1.0,
        &mc_opts(Topology::Classic),
    )
    .unwrap();
    let c = check_mesh(&mesh);
    assert_eq!(c.unbalanced_edges, 0);
    assert_eq!(c.duplicates, 0, "{c:?}");
}

/// Spheres (radius 3.5-5.7 on 16^3) whose band within one cell of the
/// surface is replaced by k 1e-17 (k in -2..=2, or +-1, +-2: no sample at
/// the isovalue 0), 12 of each.
fn noise_band_volumes() -> Vec<(String, Vec<f64>)> {
    let n = 16;
    let mut volumes = Vec::new();
    for zero in [true, false] {
        let mut rng = Rng::new(7 + zero as u64);
        for trial in 0..12 {
            let c = [
                rng.range(7.0, 8.0),
                rng.range(7.0, 8.0),
                rng.range(7.0, 8.0),
            ];
            let r = 3.5 + 0.2 * trial as f64;
            let values: Vec<f64> = sphere([n; 3], c, r)
                .into_iter()
                .map(|d| {
                    if d.abs() >= 1.0 {
                        return d;
                    }
                    let k = if zero {
                        rng.below(5) as f64 - 2.0
                    } else {
                        [-2.0, -1.0, 1.0, 2.0][rng.below(4) as usize]
                    };
                    k * 1e-17
                })
                .collect();
            volumes.push((format!("zero {zero} trial {trial}"), values));
        }
    }
    volumes
}

/// Each of `noise_band_volumes` under each of `configs` is closed,
/// consistently oriented and not empty.
fn assert_noise_bands_watertight(configs: &[(String, Options)]) {
    let mut failures = Vec::new();
    for (name, values) in noise_band_volumes() {
        let vol = Volume::new(&values, dims_u64([16; 3]));
        for (cfg, opts) in configs {
            let mesh = extract(&vol, 0.0, opts).unwrap();
            let c = check_mesh(&mesh);
            if c.unbalanced_edges != 0
                || c.boundary_edges != 0
                || c.misoriented_edges != 0
                || c.triangles == 0
            {
                failures.push(format!("{name} / {cfg}: {c:?}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Sphere distance fields whose band of width 2 around the surface is
/// rounding noise (see `noise_band_volumes`): Marching Cubes points there
/// lie a rounding away from faces in a cell's coordinates and on them in
/// the output's, and cells once disagreed on which of their edges lie in a
/// shared face (4 and 14 of 23 such volumes had holes). Watertight as the
/// integer fields are.
#[test]
fn rounding_noise_around_the_isovalue_is_watertight() {
    let mut configs = configs();
    configs.push(("default".to_string(), Options::default()));
    assert_noise_bands_watertight(&configs);
}

/// The same volumes refined onto the interpolating cubic filters: their
/// crossings of a grid edge can round onto a corner, where two crossings
/// of one polygon once welded into one point, pinching the patch (176 of
/// 672 configurations of a scan cracked with Catmull-Rom, 404 of 1008 with
/// the interpolating B-spline, and a debug build panicked).
#[test]
fn rounding_noise_around_the_isovalue_is_watertight_on_cubic_filters() {
    let mut configs = Vec::new();
    for reconstruction in [
        Reconstruction::CatmullRom,
        Reconstruction::BSplineInterpolating,
    ] {
        for topology in TOPOLOGIES {
            for rule in [Rule::A, Rule::A1, Rule::B] {
                let opts = Options {
                    reconstruction,
                    ..refine_opts(topology, rule, 0.01, 3)
                };
                configs.push((format!("{reconstruction:?} {topology:?} {rule:?}"), opts));
            }
        }
        let opts = Options {
            reconstruction,
            ..Options::default()
        };
        configs.push((format!("{reconstruction:?} default"), opts));
    }
    assert_noise_bands_watertight(&configs);
}
