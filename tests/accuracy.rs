//! Test 4: accuracy.
//!
//! * Every output vertex lies on S_K: |F(p) - iso| <= 1e-9 * (value range),
//!   with F the piecewise trilinear interpolant evaluated independently at
//!   `index_points` (cell = floor(p) clamped to the volume).
//! * Refinement stopped for a reason: every triangle whose level is below
//!   the effective maximum level has its rule's sample points (the three
//!   edge midpoints; for A1, A2 and B also the centroid, which is what A2's
//!   candidate is when no edge splits) within epsilon of S_K, measured
//!   with `precisemc::project::project` in the triangle's cell (an edge on
//!   the cell patch's boundary is projected within its face, as the
//!   library does; a sample whose gradient line finds no root in the cell
//!   is decided by the nearest-point fallback, which is not checked here:
//!   `thin_features_refine_where_gradient_lines_miss` measures its effect;
//!   nor is a sample whose projection lies farther away than its edge, or
//!   for the centroid the triangle's longest edge: such a point lies on
//!   another sheet of S_K, and the library does not split there).
//! * The distance of the mesh to S_K shrinks as epsilon shrinks, measured
//!   by the first-order distance |F - iso| / |grad F| at the midpoints and
//!   centroids of all output triangles (independent of `project`).

mod common;

use std::collections::HashMap;

use common::*;
use glam::DVec3;
use precisemc::filter::Trilinear;
use precisemc::project::project;
use precisemc::{extract, Mesh, Options, Rule, Topology, Volume};

type Filter = Trilinear<'static, f64>;

fn fields() -> Vec<(&'static str, [usize; 3], Vec<f64>)> {
    vec![
        (
            "sphere",
            [12, 12, 12],
            sphere([12, 12, 12], [5.55, 5.45, 5.52], 4.2),
        ),
        ("blobs", [12, 12, 12], blobs([12, 12, 12], 7, 7)),
        (
            "random",
            [7, 7, 7],
            random_interior([7, 7, 7], 11, -1.0, 1.0, -1.0),
        ),
    ]
}

fn vertex_errors(
    mesh: &Mesh,
    values: &[f64],
    dims: [usize; 3],
    off: [i64; 3],
    iso: f64,
) -> Vec<String> {
    let range = values.iter().fold(0.0f64, |m, v| m.max((v - iso).abs()));
    let mut out = Vec::new();
    for p in &mesh.index_points {
        let local = [
            p[0] - off[0] as f64,
            p[1] - off[1] as f64,
            p[2] - off[2] as f64,
        ];
        let v = volume_value(values, dims, local);
        if (v - iso).abs() > 1e-9 * range {
            out.push(format!("vertex {p:?}: F - iso = {}", v - iso));
        }
    }
    out
}

#[test]
fn every_vertex_is_on_the_trilinear_surface() {
    let mut failures = Vec::new();
    for (name, dims, values) in fields() {
        // A non-trivial placement: index offset, origin, anisotropic spacing.
        let off = [3, -2, 7];
        let vol = Volume::new(&values, dims_u64(dims))
            .with_index_offset(off)
            .with_origin([0.5, -1.0, 2.0])
            .with_spacing([0.7, 1.3, 0.9]);
        for topology in TOPOLOGIES {
            let mut cfgs: Vec<(String, Options)> = vec![("MC".into(), mc_opts(topology))];
            for rule in RULES {
                cfgs.push((format!("{rule:?}"), refine_opts(topology, rule, 0.005, 4)));
            }
            for (cfg, opts) in cfgs {
                let mesh = extract(&vol, 0.0, &opts).unwrap();
                // World points follow from index points.
                for (w, p) in mesh.points.iter().zip(&mesh.index_points) {
                    let want = [0.5 + 0.7 * p[0], -1.0 + 1.3 * p[1], 2.0 + 0.9 * p[2]];
                    assert!(
                        dist(*w, want) <= 1e-12 * (1.0 + norm(want)),
                        "{w:?} vs {want:?}"
                    );
                }
                let errs = vertex_errors(&mesh, &values, dims, off, 0.0);
                if !errs.is_empty() {
                    failures.push(format!(
                        "{name} {topology:?} {cfg}: {} vertices off S_K, e.g. {}",
                        errs.len(),
                        errs[0]
                    ));
                }
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Checks the "stopped for a reason" property; returns failures and the
/// number of sample points checked.
fn check_unsplit(
    mesh: &Mesh,
    values: &[f64],
    dims: [usize; 3],
    rule: Rule,
    eps: f64,
) -> (Vec<String>, usize) {
    let pts = &mesh.index_points;
    let maxl = mesh.stats.effective_max_level;
    // Group triangles by cell.
    let mut by_cell: HashMap<[usize; 3], Vec<usize>> = HashMap::new();
    for (n, t) in mesh.triangles.iter().enumerate() {
        let c = centroid(pts, *t);
        if c.iter().any(|x| x.fract() == 0.0) {
            continue; // flat in a cell face: the cell is ambiguous
        }
        by_cell.entry(locate(dims, c).0).or_default().push(n);
    }
    let mut failures = Vec::new();
    let mut interior: HashMap<[usize; 3], String> = HashMap::new();
    let mut checked = 0;
    for (cell, tris) in &by_cell {
        let corners = corners_of(values, dims, *cell);
        let cf = [cell[0] as f64, cell[1] as f64, cell[2] as f64];
        let mut uses: HashMap<(u64, u64), u32> = HashMap::new();
        for &n in tris {
            let t = mesh.triangles[n];
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        for &n in tris {
            if mesh.levels[n] as u32 >= maxl {
                continue;
            }
            let t = mesh.triangles[n];
            let local = t.map(|v| {
                let p = pts[v as usize];
                DVec3::new(p[0] - cf[0], p[1] - cf[1], p[2] - cf[2])
            });
            // A split point farther from its sample than the edge (or, for
            // the centre, the longest edge) is not taken: it lies on
            // another sheet of S_K.
            let mut samples: Vec<(DVec3, u8, f64)> = Vec::new();
            let longest = (0..3)
                .map(|e| (local[(e + 1) % 3] - local[e]).length())
                .fold(0.0, f64::max);
            for e in 0..3 {
                let (a, b) = (t[e], t[(e + 1) % 3]);
                let (pa, pb) = (local[e], local[(e + 1) % 3]);
                let mut fixed = 0u8;
                if uses[&(a.min(b), a.max(b))] == 1 {
                    for k in 0..3 {
                        if pa[k] == pb[k] && (pa[k] == 0.0 || pa[k] == 1.0) {
                            fixed |= 1 << k;
                        }
                    }
                }
                samples.push(((pa + pb) * 0.5, fixed, (pb - pa).length()));
            }
            if rule != Rule::A {
                samples.push(((local[0] + local[1] + local[2]) / 3.0, 0, longest));
            }
            for (s, fixed, reach) in samples {
                // Only samples whose distance the projection settles count
                // towards the total the test requires.
                if let Some(pr) = project::<Filter>(&corners, 0.0, s, fixed) {
                    checked += 1;
                    if pr.distance > eps * (1.0 + 1e-9) + 1e-12 && pr.distance <= reach {
                        let msg = format!(
                            "cell {cell:?} level {} sample {s:?} (fixed {fixed}) is {} from S_K",
                            mesh.levels[n], pr.distance
                        );
                        if fixed == 0 {
                            interior.entry(*cell).or_insert(msg);
                        } else {
                            failures.push(msg);
                        }
                    }
                }
            }
        }
    }
    // A cell whose refined patch was unsound is refined again on its faces'
    // edges only (`cells_refined_on_faces_only`): its interior samples may
    // stay above epsilon, but no more cells than counted.
    if interior.len() as u64 > mesh.stats.cells_refined_on_faces_only {
        failures.extend(interior.into_values());
    }
    (failures, checked)
}

#[test]
fn unsplit_triangles_are_within_epsilon() {
    let mut failures = Vec::new();
    let mut total = 0;
    for (name, dims, values) in fields() {
        let vol = Volume::new(&values, dims_u64(dims));
        for topology in TOPOLOGIES {
            for rule in RULES {
                for (eps, maxl) in [(0.02, 3), (0.004, 4)] {
                    let mesh = extract(&vol, 0.0, &refine_opts(topology, rule, eps, maxl)).unwrap();
                    assert_eq!(mesh.stats.effective_max_level, maxl);
                    assert!(mesh.levels.iter().all(|&l| l as u32 <= maxl));
                    let (f, n) = check_unsplit(&mesh, &values, dims, rule, eps);
                    total += n;
                    if !f.is_empty() {
                        failures.push(format!(
                            "{name} {topology:?} {rule:?} eps {eps}: {} samples, e.g. {}",
                            f.len(),
                            f[0]
                        ));
                    }
                }
            }
        }
    }
    assert!(total > 10_000, "only {total} samples checked");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// First-order distance of the mesh's triangle midpoints and centroids to
/// S_K: (max, mean).
fn mesh_distance(mesh: &Mesh, values: &[f64], dims: [usize; 3]) -> (f64, f64) {
    let pts = &mesh.index_points;
    let (mut max, mut sum, mut n) = (0.0f64, 0.0, 0usize);
    for t in &mesh.triangles {
        let p = t.map(|v| pts[v as usize]);
        let samples = [
            scale(add(p[0], p[1]), 0.5),
            scale(add(p[1], p[2]), 0.5),
            scale(add(p[2], p[0]), 0.5),
            centroid(pts, *t),
        ];
        for s in samples {
            let (cell, local) = locate(dims, s);
            let c = corners_of(values, dims, cell);
            let g = tri_gradient(&c, local);
            let d = tri_value(&c, local).abs() / norm(g);
            max = max.max(d);
            sum += d;
            n += 1;
        }
    }
    (max, sum / n as f64)
}

#[test]
fn distance_to_the_surface_shrinks_with_epsilon() {
    let dims = [12, 12, 12];
    let values = sphere(dims, [5.55, 5.45, 5.52], 4.2);
    let vol = Volume::new(&values, dims_u64(dims));
    for topology in TOPOLOGIES {
        for rule in RULES {
            let mut prev: Option<(f64, f64, f64)> = None;
            let mut mc_mean = 0.0;
            for eps in [0.0, 0.05, 0.01, 0.002] {
                let opts = if eps == 0.0 {
                    mc_opts(topology)
                } else {
                    refine_opts(topology, rule, eps, 6)
                };
                let mesh = extract(&vol, 0.0, &opts).unwrap();
                let (max, mean) = mesh_distance(&mesh, &values, dims);
                if let Some((pe, pmax, pmean)) = prev {
                    // Equal when no sample is above the larger epsilon.
                    assert!(
                        mean <= pmean,
                        "{topology:?} {rule:?}: mean distance {mean} at eps {eps} not below {pmean} at eps {pe}"
                    );
                    assert!(max <= pmax * 1.05, "{topology:?} {rule:?}: max distance {max} at eps {eps} above {pmax} at {pe}");
                }
                if eps == 0.002 {
                    // Every sample of an output triangle, tested or not, is
                    // close to S_K (0.0020-0.0027 measured over the rules
                    // and topologies in the fifty-first session).
                    assert!(
                        max < 2.0 * eps,
                        "{topology:?} {rule:?}: max distance {max} at eps {eps}"
                    );
                    assert!(
                        mean < 0.5 * mc_mean,
                        "{topology:?} {rule:?}: mean {mean} vs Marching Cubes {mc_mean}"
                    );
                }
                if eps == 0.0 {
                    mc_mean = mean;
                }
                prev = Some((eps, max, mean));
            }
        }
    }
}

#[test]
fn thin_features_refine_where_gradient_lines_miss() {
    // In thin tubes and in the tunnels of Marschner-Lobb the gradient line
    // of a sample often leaves its cell before meeting S_K; the nearest
    // point of S_K in the cell then decides. Measured independently
    // (`accuracy::measure`, a certified distance to S_K), the refined
    // surface must come close where plain gradient lines leave triangles
    // 0.4 cells away (tube: max 0.41, mean 0.0050; ml: mean 0.0060 at
    // epsilon 0.001 without the fallback). Where that nearest point lies
    // on a cell face (S_K hugging it), the sample splits at the nearest
    // point just inside instead of staying put: without that, atoms kept
    // triangles 0.053 cells away and the mean of Marschner-Lobb was twice
    // as large (at density 3: max 0.053 -> 0.015, mean 0.0010 -> 0.0005).
    // Where that nearest point lies far along the sample's edge, the edge
    // splits across it instead (in the plane bisecting it): otherwise the
    // children keep nearly the whole edge at every level (at density 2:
    // tube max 0.028 -> 0.013, Marschner-Lobb mean 0.00039 -> 0.00027),
    // and it does so even where the bisector's point leaves children a
    // little longer than the edge, as where S_K bows far from the chord:
    // taking it only when the longer child got shorter, Marschner-Lobb
    // kept triangles of its tunnels folded over such edges 0.25 cells
    // away at every epsilon (now 0.013).
    use precisemc::samples;
    // (Measured in the fifty-first session: max 0.0047, 0.0035 and 0.015,
    // mean about 0.00022 on the tube and the atoms.)
    for (s, max_bound, mean_bound) in [
        (samples::tube(48), 0.008, 0.0004),
        (samples::atoms(40), 0.006, 0.0004),
        (samples::marschner_lobb(41), 0.022, 0.00033),
    ] {
        let (mesh, m) = refined_at_a_thousandth(&s, 2);
        assert!(
            mesh.stats.projection_failures > 0,
            "{}: nothing to rescue",
            s.name
        );
        assert!(
            m.max < max_bound && m.mean < mean_bound,
            "{}: max {} mean {}",
            s.name,
            m.max,
            m.mean
        );
    }
}

#[test]
fn polygons_are_recut_where_table_diagonals_cannot_reach_the_surface() {
    // Where S_K hugs a cell face, a diagonal of the case table can cross
    // the part of the cell S_K never enters: its midpoint's nearest point
    // of S_K lies on the cell's boundary, so refinement cannot move it and
    // its triangles stay far away at any epsilon (atoms: 0.18 cells, tube:
    // 0.10 without re-cutting, measured independently when it was added).
    // Re-cut along diagonals refinement can follow, the max distance fell
    // below 0.07 (0.053 and 0.036 then). Since then edges checked along
    // their length and cells meshed again on sub-cells bring those
    // triangles close too (0.0032 and 0.0042 with or without the re-cut,
    // fifty-first session): the bound guards the combination.
    use precisemc::samples;
    for s in [samples::atoms(40), samples::tube(48)] {
        let (mesh, m) = refined_at_a_thousandth(&s, 3);
        assert!(mesh.stats.recut_polygons > 0, "{}: nothing re-cut", s.name);
        let vol = s.volume();
        assert!(m.max < 0.007, "{}: max {} mean {}", s.name, m.max, m.mean);
        // Plain Marching Cubes is the case table's, untouched.
        let mc = extract(
            &vol,
            s.isovalue,
            &Options::marching_cubes(Topology::Trilinear),
        )
        .unwrap();
        assert_eq!(mc.stats.recut_polygons, 0);
    }
}

/// A sample refined with rule A1 at epsilon 0.001, and its distance to
/// S_K measured independently (`accuracy::measure` at `density`).
fn refined_at_a_thousandth(
    s: &precisemc::samples::SampleVolume,
    density: u32,
) -> (Mesh, precisemc::accuracy::Distance) {
    let vol = s.volume();
    let opts = Options {
        epsilon: 0.001,
        rule: Rule::A1,
        ..Options::default()
    };
    let mesh = extract(&vol, s.isovalue, &opts).unwrap();
    let m = precisemc::accuracy::measure(
        &vol,
        s.isovalue,
        &mesh.index_points,
        &mesh.triangles,
        &precisemc::accuracy::MeasureOptions {
            density,
            ..Default::default()
        },
    )
    .unwrap();
    (mesh, m)
}

#[test]
fn fans_bridge_two_sheets_of_a_pinched_cell() {
    // A cell whose inside region pinches off towards a corner barely above
    // the isovalue (the trefoil tube's cell (42, 29, 5), corner (1, 0, 0)
    // 1.5 above it): its one loop bounds a surface of two sheets joined by
    // a narrow bridge. A fan around the centroid's projection laid spokes
    // across the solid to the other sheet, which no split could bring
    // onto S_K (0.40 cells away at every epsilon and level, and 0.32-0.45
    // in 92 % of the cells below). The fan centre now sits where every
    // spoke follows a sheet. Checked on the cell and on 200 neighbours of
    // it (the weak corner from 0.5 to 6, the others scaled by 0.85-1.15),
    // measured independently; about 4 % of them kept a triangle over 0.3
    // cells away when this was added, none over 0.05 in the fifty-first
    // session, where the tube's cell measured 0.0095).
    let base = [87.5, 1.5, -31.5, -21.5, -14.5, -24.5, 7.5, 95.5];
    let mut rng = Rng::new(0x9e37_79b9_7f4a_7c15);
    let mut far = 0;
    const TRIALS: usize = 200;
    for trial in 0..TRIALS {
        let mut f = base;
        if trial > 0 {
            for v in f.iter_mut() {
                *v *= rng.range(0.85, 1.15);
            }
            f[1] = rng.range(0.5, 6.0);
        }
        let vol = Volume::new(&f[..], [2, 2, 2]);
        let opts = Options {
            epsilon: 0.01,
            rule: Rule::A1,
            max_level: 8,
            threads: 1,
            ..Options::default()
        };
        let mesh = extract(&vol, 0.0, &opts).unwrap();
        let m = precisemc::accuracy::measure(
            &vol,
            0.0,
            &mesh.index_points,
            &mesh.triangles,
            &precisemc::accuracy::MeasureOptions {
                density: 3,
                ..Default::default()
            },
        )
        .unwrap();
        if trial == 0 {
            assert!(m.max < 0.015, "the tube's cell: max {} cells", m.max);
        }
        far += usize::from(m.max > 0.05);
    }
    assert!(
        far * 100 <= TRIALS,
        "{far} of {TRIALS} cells keep far triangles"
    );
}
