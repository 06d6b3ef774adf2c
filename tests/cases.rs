//! Test 1: every one of the 256 sign patterns of a single cell, in both
//! topology modes, with many corner magnitudes (so that ambiguous faces
//! and the cell interior are decided both ways), unrefined and refined.
//!
//! For each cell patch we check that
//! * it is a consistently oriented manifold patch without degenerate or
//!   duplicate triangles;
//! * (unrefined) its vertices are exactly the crossing points of the
//!   sign-changing cell edges, at the VTK interpolation parameter;
//! * its boundary lies on the cell faces: every boundary edge joins two
//!   vertices on a common face, and (unrefined) there is one boundary edge
//!   per face segment (one per face with two crossings, two per face with
//!   four);
//! * (Trilinear mode) on every ambiguous face the boundary segments follow
//!   the asymptotic decider, recomputed here from the bilinear saddle value;
//! * it separates the inside corners from the outside corners with normals
//!   towards the outside. The check is a signed ray-crossing count: for a
//!   fixed interior point `o` let `psi(c)` be the number of triangles the
//!   segment `o -> c` crosses along their normal minus the number it
//!   crosses against it. The patch is a properly embedded surface in the
//!   cube (boundary on the cube's surface), and any closed path in the
//!   cube has intersection number 0 with such a surface, so `psi(b) -
//!   psi(a)` is the signed crossing count of *any* path from `a` to `b`
//!   inside the cube. Correct separation and orientation mean exactly:
//!   `psi` is one constant on inside corners and that constant plus 1 on
//!   outside corners (crossing from inside to outside goes along the
//!   normal). Segments that pass near an edge or vertex of a triangle are
//!   avoided by trying several points `o`.

mod common;

use common::*;
use precisemc::mc::{case_index, trilinear::face_decisions};
use precisemc::tables::cube::{CORNERS, EDGES, EDGE_AXIS, FACES, FACE_EDGES};
use precisemc::{extract, Mesh, Options, Rule, Topology, Volume};

fn run_cell(f: &[f64; 8], opts: &Options) -> Mesh {
    let data = cell_volume(f);
    let v = Volume::new(&data, [2, 2, 2]);
    let mesh = extract(&v, 0.0, opts).expect("extract");
    assert_sane(&mesh);
    mesh
}

/// Crossing point of cell edge `e` (VTK interpolation from the lower corner).
fn crossing(f: &[f64; 8], e: usize) -> [f64; 3] {
    let [a, b] = EDGES[e];
    let (sa, sb) = (f[a as usize], f[b as usize]);
    let t = (0.0 - sa) / (sb - sa);
    let ca = CORNERS[a as usize];
    let mut p = [ca[0] as f64, ca[1] as f64, ca[2] as f64];
    p[EDGE_AXIS[e] as usize] += t;
    p
}

/// Signed crossing count of segment `o -> t` with the triangles, or `None`
/// when the segment passes too close to a triangle's edge or vertex (or an
/// endpoint lies too close to a triangle).
fn signed_crossings(
    points: &[[f64; 3]],
    tris: &[[u64; 3]],
    o: [f64; 3],
    t: [f64; 3],
) -> Option<i32> {
    let tol = 1e-12;
    let mut psi = 0;
    for tri in tris {
        let (a, b, c) = (
            points[tri[0] as usize],
            points[tri[1] as usize],
            points[tri[2] as usize],
        );
        let n = cross(sub(b, a), sub(c, a));
        let nl = norm(n);
        let d0 = dot(sub(o, a), n) / nl;
        let d1 = dot(sub(t, a), n) / nl;
        if (d0 > tol && d1 > tol) || (d0 < -tol && d1 < -tol) {
            continue;
        }
        // The segment reaches the triangle's plane: on which side of the
        // three edges does it pass?
        let dir = sub(t, o);
        let s = [
            dot(cross(sub(a, o), sub(b, o)), dir),
            dot(cross(sub(b, o), sub(c, o)), dir),
            dot(cross(sub(c, o), sub(a, o)), dir),
        ];
        // Normalised, s[i] is about the distance between the segment's line
        // and the triangle's edge i.
        let len = [norm(sub(b, a)), norm(sub(c, b)), norm(sub(a, c))];
        if (0..3).any(|i| s[i].abs() <= 1e-11 * len[i] * norm(dir)) {
            // Near an edge line of the triangle.
            if d0.abs() <= tol || d1.abs() <= tol || (d0 < 0.0) != (d1 < 0.0) {
                return None;
            }
            continue;
        }
        let inside =
            (s[0] > 0.0 && s[1] > 0.0 && s[2] > 0.0) || (s[0] < 0.0 && s[1] < 0.0 && s[2] < 0.0);
        if !inside {
            continue;
        }
        if d0.abs() <= tol || d1.abs() <= tol {
            return None;
        }
        psi += if d0 < 0.0 && d1 > 0.0 { 1 } else { -1 };
    }
    Some(psi)
}

/// The separation check described in the module docs. Returns an error
/// message on failure.
fn check_separation(f: &[f64; 8], points: &[[f64; 3]], tris: &[[u64; 3]]) -> Result<(), String> {
    let origins = [
        [0.5123, 0.4731, 0.5317],
        [0.3141, 0.6279, 0.4471],
        [0.7072, 0.2719, 0.5773],
        [0.2236, 0.3606, 0.7937],
        [0.6932, 0.7392, 0.1415],
        [0.1618, 0.8414, 0.6180],
    ];
    for o in origins {
        let mut psi = [0i32; 8];
        let mut ok = true;
        for c in 0..8 {
            let p = CORNERS[c];
            match signed_crossings(points, tris, o, [p[0] as f64, p[1] as f64, p[2] as f64]) {
                Some(v) => psi[c] = v,
                None => {
                    ok = false;
                    break;
                }
            }
        }
        if !ok {
            continue;
        }
        let ins: Vec<i32> = (0..8).filter(|&c| f[c] >= 0.0).map(|c| psi[c]).collect();
        let outs: Vec<i32> = (0..8).filter(|&c| f[c] < 0.0).map(|c| psi[c]).collect();
        let pin = ins[0];
        let pout = outs[0];
        if ins.iter().any(|&v| v != pin) || outs.iter().any(|&v| v != pout) || pout - pin != 1 {
            return Err(format!(
                "signed crossing counts per corner {psi:?} (inside {ins:?}, outside {outs:?})"
            ));
        }
        return Ok(());
    }
    Err("every test origin gave a degenerate ray".into())
}

/// Whether two local points lie on a common face of the cell.
fn on_common_face(a: [f64; 3], b: [f64; 3]) -> bool {
    (0..3).any(|k| a[k] == b[k] && (a[k] == 0.0 || a[k] == 1.0))
}

/// Bilinear saddle value of a face with cyclic corner values g.
fn face_saddle(g: [f64; 4]) -> Option<f64> {
    let den = g[0] + g[2] - g[1] - g[3];
    if den == 0.0 {
        None
    } else {
        Some((g[0] * g[2] - g[1] * g[3]) / den)
    }
}

struct Coverage {
    joined_inside: usize,
    joined_outside: usize,
}

fn check_cell(
    f: &[f64; 8],
    topology: Topology,
    refined: bool,
    cov: &mut Coverage,
) -> Result<(), String> {
    let opts = if refined {
        refine_opts(topology, Rule::A1, 0.01, 3)
    } else {
        mc_opts(topology)
    };
    let mesh = run_cell(f, &opts);
    let pts = &mesh.index_points;
    let c = check_mesh(&mesh);
    if c.triangles == 0 {
        return Err("empty patch".into());
    }
    if c.degenerate != 0
        || c.duplicates != 0
        || c.nonmanifold_edges != 0
        || c.misoriented_edges != 0
    {
        return Err(format!("bad patch: {c:?}"));
    }
    if c.nonmanifold_vertices != 0 {
        return Err(format!("non-manifold vertex: {c:?}"));
    }
    if c.unreferenced != 0 {
        return Err(format!("unreferenced points: {c:?}"));
    }
    for p in pts {
        if p.iter().any(|x| !(0.0..=1.0).contains(x)) {
            return Err(format!("point {p:?} outside the cell"));
        }
    }
    // Trilinear mode: no triangle lies flat in a cell face (where the
    // neighbouring cell has its boundary), except the strips that join a
    // cell meshed again on sub-cells to its own outline there.
    if topology == Topology::Trilinear && mesh.stats.cells_on_subcells == 0 {
        for t in &mesh.triangles {
            let p = t.map(|v| pts[v as usize]);
            if on_common_face(p[0], p[1])
                && on_common_face(p[1], p[2])
                && on_common_face(p[0], p[2])
            {
                let common = (0..3).any(|k| {
                    p[0][k] == p[1][k] && p[1][k] == p[2][k] && (p[0][k] == 0.0 || p[0][k] == 1.0)
                });
                if common {
                    return Err(format!("triangle {p:?} flat in a cell face"));
                }
            }
        }
    }
    // Boundary edges on faces.
    let mut uses = std::collections::HashMap::<(u64, u64), u32>::new();
    for t in &mesh.triangles {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            *uses.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let boundary: Vec<(u64, u64)> = uses
        .iter()
        .filter(|(_, &n)| n == 1)
        .map(|(&k, _)| k)
        .collect();
    for &(a, b) in &boundary {
        if !on_common_face(pts[a as usize], pts[b as usize]) {
            return Err(format!(
                "boundary edge {:?}-{:?} not on a face",
                pts[a as usize], pts[b as usize]
            ));
        }
    }
    let inside = |c: u8| f[c as usize] >= 0.0;
    let crossed: Vec<usize> = (0..12)
        .filter(|&e| inside(EDGES[e][0]) != inside(EDGES[e][1]))
        .collect();
    if !refined {
        // Vertices = crossings, one each, plus (Trilinear mode) interior
        // points on the surface.
        let mut vert_of_edge = [usize::MAX; 12];
        if pts.len() < crossed.len() {
            return Err(format!(
                "{} points for {} crossed edges",
                pts.len(),
                crossed.len()
            ));
        }
        for &e in &crossed {
            let q = crossing(f, e);
            let m: Vec<usize> = (0..pts.len())
                .filter(|&i| dist(pts[i], q) <= 1e-12)
                .collect();
            if m.len() != 1 {
                return Err(format!(
                    "crossing of edge {e} at {q:?} matched {} points",
                    m.len()
                ));
            }
            vert_of_edge[e] = m[0];
        }
        let scale = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for (i, p) in pts.iter().enumerate() {
            if vert_of_edge.contains(&i) {
                continue;
            }
            if topology == Topology::Classic {
                return Err(format!("Classic mode point {p:?} not on a cell edge"));
            }
            let v = tri_value(f, *p);
            if v.abs() > 1e-9 * scale || p.iter().any(|x| *x <= 0.0 || *x >= 1.0) {
                return Err(format!(
                    "extra point {p:?} not on the surface inside the cell (F = {v})"
                ));
            }
        }
        let mut segments = 0;
        for (k, (_, _, fc)) in FACES.iter().enumerate() {
            let n = (0..4)
                .filter(|&i| inside(fc[i]) != inside(fc[(i + 1) % 4]))
                .count();
            segments += n / 2;
            if n == 4 && topology == Topology::Trilinear {
                let g = [
                    f[fc[0] as usize],
                    f[fc[1] as usize],
                    f[fc[2] as usize],
                    f[fc[3] as usize],
                ];
                let Some(s) = face_saddle(g) else { continue };
                if s.abs() <= 1e-9 * g.iter().fold(0.0f64, |m, v| m.max(v.abs())) {
                    continue; // a tie: either decision is acceptable
                }
                let join_in = s > 0.0;
                if face_decisions(f)[k] != Some(join_in) {
                    return Err(format!(
                        "face {k}: face_decisions disagrees with the saddle value {s}"
                    ));
                }
                if join_in {
                    cov.joined_inside += 1;
                } else {
                    cov.joined_outside += 1;
                }
                // The corners that are cut off: those on the side not joined.
                for i in 0..4 {
                    if inside(fc[i]) != join_in {
                        let ea = FACE_EDGES[k][(i + 3) % 4] as usize;
                        let eb = FACE_EDGES[k][i] as usize;
                        let (va, vb) = (vert_of_edge[ea] as u64, vert_of_edge[eb] as u64);
                        if uses.get(&(va.min(vb), va.max(vb))) != Some(&1) {
                            return Err(format!(
                                "face {k} (saddle {s}): no boundary segment cutting off corner {}",
                                fc[i]
                            ));
                        }
                    }
                }
            }
        }
        if boundary.len() != segments {
            return Err(format!(
                "{} boundary edges for {} face segments",
                boundary.len(),
                segments
            ));
        }
    }
    check_separation(f, pts, &mesh.triangles)
}

/// Corner values for `case` in trial `t`.
fn values_for(case: u8, t: usize, rng: &mut Rng) -> [f64; 8] {
    let mut f = [0.0; 8];
    for (c, v) in f.iter_mut().enumerate() {
        let inside = (case >> c) & 1 == 1;
        let mag = match t {
            0 => 1.0,
            1 => 1.0 + c as f64 / 8.0,
            2..=9 => rng.range(0.05, 1.0),
            _ => rng.log_uniform(1e-3, 1e3),
        };
        *v = if inside { mag } else { -mag };
    }
    f
}

fn run_cases(topology: Topology, refined: bool, trials: &[usize], seed: u64) {
    let mut rng = Rng::new(seed);
    let mut cov = Coverage {
        joined_inside: 0,
        joined_outside: 0,
    };
    let mut failures = Vec::new();
    let mut count = 0;
    for case in 1..=254u8 {
        for &t in trials {
            let f = values_for(case, t, &mut rng);
            assert_eq!(case_index(&f), case);
            count += 1;
            if let Err(e) = check_cell(&f, topology, refined, &mut cov) {
                failures.push(format!("case {case} trial {t} f = {f:?}: {e}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{topology:?} refined={refined}: {} of {count} cells fail:\n{}",
        failures.len(),
        failures.join("\n")
    );
    if topology == Topology::Trilinear && !refined && trials.len() > 10 {
        assert!(
            cov.joined_inside > 1000 && cov.joined_outside > 1000,
            "face decision coverage"
        );
    }
}

const ALL_TRIALS: [usize; 28] = [
    0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25,
    26, 27,
];
/// Trials without exact ties (every ambiguous face and body saddle is
/// generically away from the isovalue).
const GENERIC_TRIALS: [usize; 5] = [1, 2, 3, 10, 11];

#[test]
fn all_256_cases_classic() {
    run_cases(Topology::Classic, false, &ALL_TRIALS, 1);
}

#[test]
fn all_256_cases_trilinear() {
    run_cases(Topology::Trilinear, false, &ALL_TRIALS, 1);
}

#[test]
fn all_256_cases_classic_refined() {
    run_cases(Topology::Classic, true, &GENERIC_TRIALS, 2);
}

#[test]
fn all_256_cases_trilinear_refined() {
    run_cases(Topology::Trilinear, true, &GENERIC_TRIALS, 2);
}

/// Corner values of +-1 exactly: every ambiguous face has its saddle
/// exactly at the isovalue (the surface pinches there). The patch must
/// still be a consistently oriented manifold after refinement.
#[test]
fn all_256_cases_with_ties_refined() {
    for topology in TOPOLOGIES {
        run_cases(topology, true, &[0], 3);
    }
}

#[test]
fn empty_and_full_cells_give_nothing() {
    for f in [[1.0; 8], [-1.0; 8], [0.0; 8]] {
        for topology in TOPOLOGIES {
            let m = run_cell(&f, &mc_opts(topology));
            assert!(m.triangles.is_empty() && m.points.is_empty());
        }
    }
}

/// The public table-level API agrees with extraction: the triangles of
/// `cell_triangles` are, edge for edge, those of the extracted patch.
#[test]
fn cell_triangles_matches_extract() {
    let mut rng = Rng::new(3);
    for case in 1..=254u8 {
        for t in [0, 5, 12] {
            let f = values_for(case, t, &mut rng);
            for topology in TOPOLOGIES {
                let mut patch = precisemc::mc::Patch::default();
                precisemc::mc::cell_triangles(&f, topology, &mut patch);
                let mut pts: Vec<[f64; 3]> = (0..12).map(|e| crossing(&f, e)).collect();
                pts.extend_from_slice(&patch.extra);
                let tris: Vec<[u64; 3]> = patch.tris.iter().map(|t| t.map(|e| e as u64)).collect();
                let mesh = run_cell(&f, &mc_opts(topology));
                assert_eq!(
                    canonical_triangles(&pts, &tris),
                    canonical_triangles(&mesh.index_points, &mesh.triangles),
                    "case {case} {topology:?}"
                );
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Minimal reproductions of defects found by the tests above (kept as
// regression tests).
// ---------------------------------------------------------------------------

fn patch_of(f: &[f64; 8]) -> Mesh {
    run_cell(f, &mc_opts(Topology::Trilinear))
}

/// A tube between loops [1, 11, 10, 3] and [4, 8, 7]: the stitch must not
/// walk all the way around one loop while staying at one vertex of the
/// other (that repeats a diagonal: an edge in four triangles).
#[test]
fn tube_stitch_never_repeats_a_diagonal() {
    let f = [
        -0.09995732273590074,
        -0.16474112566363266,
        37.05928876841618,
        0.001001507965003159,
        0.059772251929350755,
        -0.06012122068119459,
        -10.413177429645632,
        -0.03134194122892819,
    ];
    let c = check_mesh(&patch_of(&f));
    assert_eq!(c.nonmanifold_edges, 0, "{c:?}");
    assert_eq!(c.loops_per_component, vec![2], "{c:?}");
    assert_eq!(c.euler, 0, "an annulus: {c:?}");
}

/// A tube between [0, 8, 3] (around corner 0) and a hexagon: triangle
/// (edges 0, 8, 9) lies flat in face y = 0 although a stitch without flat
/// triangles exists.
#[test]
fn trilinear_patch_has_no_triangle_flat_in_a_face() {
    let f = [-1.0, 1.125, -1.25, 1.375, 1.5, -1.625, -1.75, -1.875];
    let mesh = patch_of(&f);
    for t in &mesh.triangles {
        let p = t.map(|v| mesh.index_points[v as usize]);
        let flat = (0..3).any(|k| {
            p[0][k] == p[1][k] && p[1][k] == p[2][k] && (p[0][k] == 0.0 || p[0][k] == 1.0)
        });
        assert!(!flat, "triangle {p:?} lies in a cell face");
    }
}

/// A disk whose 8-vertex loop needs an interior vertex: the vertex must be
/// on the surface (it is the loop centroid, F = -0.0319, when the gradient
/// line through the centroid has no root in the cell).
#[test]
fn interior_patch_vertex_is_on_the_surface() {
    let f = [
        -0.9053508287849475,
        -0.47279245596459585,
        0.6782785428991671,
        0.33800342151045726,
        0.2595858809253941,
        0.5965390163156555,
        -0.687610605982395,
        -0.12559990599207355,
    ];
    let mesh = patch_of(&f);
    for p in &mesh.index_points {
        let v = tri_value(&f, *p);
        assert!(v.abs() <= 1e-9, "vertex {p:?} has F = {v}");
    }
}

/// The public cell functions take any corner values: a NaN or infinite
/// corner gets the table's triangles (or none from the trilinear test
/// itself), never a panic (the tube's stitching ran past its table on
/// NaN costs).
#[test]
fn cells_with_non_finite_corners_do_not_panic() {
    use precisemc::mc::{cell_triangles, trilinear, Patch};
    let mut rng = Rng::new(77);
    let bad = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY];
    for n in 0..60_000 {
        let mut f = [0.0; 8];
        for v in f.iter_mut() {
            *v = rng.f64() * 2.0 - 1.0;
        }
        f[n % 8] = bad[n % 3];
        if n % 5 == 0 {
            // A subnormal at another corner.
            f[(n % 8 + 1 + (n / 8) % 7) % 8] = 1e-310;
        }
        let mut patch = Patch::default();
        let tested = cell_triangles(&f, Topology::Trilinear, &mut patch);
        assert!(!tested, "{f:?}");
        assert_eq!(
            patch.tris,
            precisemc::mc::classic::case_triangles(case_index(&f))
        );
        let (mut tris, mut extra) = (Vec::new(), Vec::new());
        trilinear::triangles(&f, true, &mut tris, &mut extra);
        assert!(tris.is_empty() && extra.is_empty(), "{f:?}");
    }
}
