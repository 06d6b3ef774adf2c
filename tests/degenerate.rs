//! Degenerate data, for both topologies, with refinement off and on
//! (every rule, several epsilons and maximum levels; no triangle cap, which
//! `tests/cap.rs` and `tests/memory.rs` cover):
//!
//! * constant volumes (no triangle at all);
//! * integer fields with the isovalue on sample values (many ties);
//! * planes exactly through grid points (`f = z - 3` on an integer lattice,
//!   iso 0, and oblique planes), and closed polyhedra whose faces pass
//!   through grid points;
//! * checkerboards of ±1 with the isovalue exactly 0 (every face saddle at
//!   the isovalue) and slightly off;
//! * two cells, and 3x3x3 volumes, with a shared ambiguous face's saddle
//!   within 1e-15..1e-3 of the isovalue (tunnels through both cells);
//! * single-voxel spikes (one sample above the isovalue in a field below
//!   it, and one below in a field above), of magnitudes down to the
//!   smallest subnormal;
//! * every one of the 256 sign patterns of a 2x2x2 volume, with random
//!   magnitudes, equal magnitudes (saddles exactly at the isovalue) and
//!   magnitudes spread over six decades, alone and padded;
//! * volumes of extreme aspect ratio (1000x2x2, 2x1000x2, 2x2x1000, and
//!   tubes in 1000x3x3, 3x1000x3, 3x3x1000 padded by a border below the
//!   isovalue).
//!
//! Properties checked for every case and configuration:
//!
//! * points finite and inside the volume's box, indices in range, every
//!   point used by a triangle;
//! * no degenerate triangle (repeated index or exactly zero area in index
//!   space) and no duplicate triangle (same three points twice);
//! * consistent orientation: no edge used twice in the same direction, and
//!   every interior edge used as often in one direction as in the other;
//! * watertight: boundary edges only on the faces of the volume's box, and
//!   none at all where the surface is closed (the field is padded by a
//!   border below the isovalue), where the enclosed signed volume is also
//!   positive (normals towards lower values), and the surface exists
//!   exactly where plain Marching Cubes of the same topology has one (on
//!   the integer fields also enclosing within a factor 2 of its volume);
//! * determinism: 1 and 2 threads give bit-identical meshes.
//!
//! Where no sample equals the isovalue (generic data) the mesh is also a
//! 2-manifold (every edge in at most two triangles, every vertex link a
//! single fan or cycle). Where samples equal the isovalue the surface may
//! touch itself at such a sample (a non-manifold vertex, and possibly an
//! edge shared by four triangles between two grid points at the isovalue):
//! this is allowed and documented in the README ("Samples equal to the
//! isovalue"); the mesh is still a closed, consistently oriented 2-cycle.
//! The same holds for the ±1 checkerboard with iso 0 and the 2x2x2 patterns
//! of equal magnitudes, where face saddles lie exactly at the isovalue and
//! `S_K` itself touches itself at the saddle.

mod common;

use std::collections::HashMap;

use common::*;
use std::ops::ControlFlow;

use precisemc::{extract, extract_with_progress, Mesh, Options, Rule, Topology, Volume};

// ---------------------------------------------------------------------------
// Configurations.
// ---------------------------------------------------------------------------

/// Both topologies: plain MC, every rule at (0.01, 3), a fine epsilon at
/// level 4 and a coarse epsilon at level 1. (A tiny epsilon at level 10
/// held by a triangle cap is exercised by tests/memory.rs: here it would
/// cost seconds per case.)
fn configs() -> Vec<(String, Options)> {
    let mut v = Vec::new();
    for topology in TOPOLOGIES {
        v.push((format!("{topology:?} MC"), mc_opts(topology)));
        for rule in RULES {
            v.push((
                format!("{topology:?} {rule:?} 0.01/3"),
                refine_opts(topology, rule, 0.01, 3),
            ));
        }
        v.push((
            format!("{topology:?} A1 1e-3/4"),
            refine_opts(topology, Rule::A1, 1e-3, 4),
        ));
        v.push((
            format!("{topology:?} B 0.1/1"),
            refine_opts(topology, Rule::B, 0.1, 1),
        ));
    }
    v
}

/// A smaller set for the many tiny cases (2x2x2 patterns).
fn quick_configs() -> Vec<(String, Options)> {
    let mut v = Vec::new();
    for topology in TOPOLOGIES {
        v.push((format!("{topology:?} MC"), mc_opts(topology)));
        v.push((
            format!("{topology:?} A1 0.01/3"),
            refine_opts(topology, Rule::A1, 0.01, 3),
        ));
        v.push((
            format!("{topology:?} B 0.01/2"),
            refine_opts(topology, Rule::B, 0.01, 2),
        ));
    }
    v
}

// ---------------------------------------------------------------------------
// Checks.
// ---------------------------------------------------------------------------

/// What a case must satisfy beyond the common properties.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Expect {
    /// No triangle at all.
    Empty,
    /// The surface may reach the volume's box (boundary edges there only).
    Open,
    /// No boundary edge; positive enclosed volume unless empty.
    Closed,
}

#[derive(Clone, Copy, Debug)]
struct Case {
    expect: Expect,
    /// Generic data (no sample, no saddle at the isovalue): the mesh must
    /// also be a 2-manifold and use every point. (Where triangles collapse
    /// onto a sample at the isovalue, or within rounding of it, their
    /// point may stay in the point array unused: observed and allowed.)
    manifold: bool,
    /// Closed surfaces only: the enclosed volume lies within
    /// [`VOLUME_FACTOR`] of plain Marching Cubes' (fields whose surface
    /// refinement moves little; thin slabs, spikes and checkerboards,
    /// where `S_K` encloses far more or less than the table's patches, do
    /// not ask it).
    volume_like_mc: bool,
}

const OPEN: Case = Case {
    expect: Expect::Open,
    manifold: false,
    volume_like_mc: false,
};
const OPEN_MANIFOLD: Case = Case {
    expect: Expect::Open,
    manifold: true,
    volume_like_mc: false,
};
const CLOSED: Case = Case {
    expect: Expect::Closed,
    manifold: false,
    volume_like_mc: false,
};
const CLOSED_MANIFOLD: Case = Case {
    expect: Expect::Closed,
    manifold: true,
    volume_like_mc: false,
};
/// Closed, and enclosing about the volume of plain Marching Cubes.
const CLOSED_LIKE_MC: Case = Case {
    expect: Expect::Closed,
    manifold: false,
    volume_like_mc: true,
};
/// No triangle; a point may remain where every triangle collapsed onto a
/// sample at the isovalue (observed: one unused point for a lone sample at
/// the isovalue).
const EMPTY: Case = Case {
    expect: Expect::Empty,
    manifold: false,
    volume_like_mc: false,
};

/// Boundary edges (used by one triangle) whose end points do not lie on a
/// common face of the volume's box.
fn boundary_edges_off_box(mesh: &Mesh, dims: [usize; 3]) -> usize {
    let mut edges: HashMap<(u64, u64), u32> = HashMap::new();
    for t in &mesh.triangles {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            *edges.entry((a.min(b), a.max(b))).or_insert(0) += 1;
        }
    }
    let on_face = |p: [f64; 3], q: [f64; 3]| {
        (0..3).any(|a| {
            let hi = (dims[a] - 1) as f64;
            (p[a] == 0.0 && q[a] == 0.0) || (p[a] == hi && q[a] == hi)
        })
    };
    edges
        .iter()
        .filter(|(&(a, b), &n)| {
            n == 1 && !on_face(mesh.index_points[a as usize], mesh.index_points[b as usize])
        })
        .count()
}

/// Problems of one mesh (empty when it satisfies everything).
fn problems(mesh: &Mesh, dims: [usize; 3], case: Case, opts: &Options) -> Vec<String> {
    let mut p = Vec::new();
    if mesh.points.len() != mesh.index_points.len()
        || mesh.levels.len() != mesh.triangles.len()
        || mesh.stats.output_triangles != mesh.triangles.len() as u64
        || mesh.stats.output_points != mesh.points.len() as u64
    {
        p.push("inconsistent array lengths or stats".into());
    }
    for q in mesh.points.iter().chain(&mesh.index_points) {
        if !q.iter().all(|c| c.is_finite()) {
            p.push(format!("non-finite point {q:?}"));
            return p;
        }
    }
    for q in &mesh.index_points {
        if (0..3).any(|a| q[a] < 0.0 || q[a] > (dims[a] - 1) as f64) {
            p.push(format!("point outside the box {q:?}"));
            return p;
        }
    }
    if mesh.levels.iter().any(|&l| l as u32 > opts.max_level) {
        p.push("level above max_level".into());
    }
    let c = check_mesh(mesh);
    if c.out_of_range > 0 {
        p.push(format!(
            "{} triangles with an index out of range",
            c.out_of_range
        ));
        return p;
    }
    if c.degenerate > 0 {
        p.push(format!("{} degenerate triangles", c.degenerate));
    }
    if c.duplicates > 0 {
        p.push(format!("{} duplicate triangles", c.duplicates));
    }
    if case.manifold && c.unreferenced > 0 {
        p.push(format!("{} unreferenced points", c.unreferenced));
    }
    if c.misoriented_edges > 0 || c.unbalanced_edges > 0 {
        p.push(format!(
            "orientation: {} misoriented, {} unbalanced edges",
            c.misoriented_edges, c.unbalanced_edges
        ));
    }
    let off = boundary_edges_off_box(mesh, dims);
    if off > 0 {
        p.push(format!("{off} boundary edges inside the volume"));
    }
    if case.manifold && (c.nonmanifold_edges > 0 || c.nonmanifold_vertices > 0) {
        p.push(format!(
            "generic data but {} non-manifold edges, {} non-manifold vertices",
            c.nonmanifold_edges, c.nonmanifold_vertices
        ));
    }
    match case.expect {
        Expect::Empty => {
            if !mesh.triangles.is_empty() {
                p.push(format!("{} triangles, expected none", mesh.triangles.len()));
            }
        }
        Expect::Open => {}
        Expect::Closed => {
            if c.boundary_edges > 0 {
                p.push(format!(
                    "closed surface with {} boundary edges",
                    c.boundary_edges
                ));
            }
            let v = signed_volume(&mesh.index_points, &mesh.triangles);
            if !mesh.triangles.is_empty() && v <= 0.0 {
                p.push(format!("enclosed volume {v} not positive"));
            }
        }
    }
    p
}

/// Most a closed refined surface's enclosed volume may differ from that of
/// plain Marching Cubes of the same topology, as a factor either way, where
/// the case asks it (`Case::volume_like_mc`). Measured on the integer
/// fields that ask it (2026-11-29): 0.63 to 1.13.
const VOLUME_FACTOR: f64 = 2.0;

/// A closed surface exists exactly where plain Marching Cubes of the same
/// topology finds one: when that mesh is empty (every sample at or below
/// the isovalue, a peak exactly at it collapsing onto its sample) so is
/// the refined one, and otherwise the refined mesh is not empty (and, if
/// `volume_like_mc`, encloses a volume within [`VOLUME_FACTOR`] of Marching
/// Cubes').
fn compare_with_marching_cubes(mesh: &Mesh, mc: &Mesh, volume_like_mc: bool) -> Option<String> {
    match (mc.triangles.is_empty(), mesh.triangles.is_empty()) {
        (true, true) => None,
        (true, false) => Some(format!(
            "{} triangles where Marching Cubes has none",
            mesh.triangles.len()
        )),
        (false, true) => Some(format!(
            "no triangle where Marching Cubes has {}",
            mc.triangles.len()
        )),
        (false, false) if volume_like_mc => {
            let v = signed_volume(&mesh.index_points, &mesh.triangles);
            let v_mc = signed_volume(&mc.index_points, &mc.triangles);
            (!(v_mc > 0.0 && v >= v_mc / VOLUME_FACTOR && v <= v_mc * VOLUME_FACTOR))
                .then(|| format!("enclosed volume {v}, Marching Cubes {v_mc}"))
        }
        (false, false) => None,
    }
}

/// Where a sample lies above the isovalue of a field whose border is below
/// it, plain Marching Cubes finds a surface (which the refined meshes must
/// then have too: `compare_with_marching_cubes`).
fn require_marching_cubes_surface(
    name: &str,
    meshes: &[Mesh],
    configs: &[(String, Options)],
    failures: &mut Vec<String>,
) {
    for (m, (cfg, o)) in meshes.iter().zip(configs) {
        if !o.refines() && m.triangles.is_empty() {
            failures.push(format!(
                "{name} / {cfg}: no triangle though samples lie above the isovalue"
            ));
        }
    }
}

/// Runs every configuration with 1 and 2 threads on one volume and records
/// problems in `failures`. Returns the total triangle count (of the
/// 1-thread runs) for sanity checks by the caller.
fn run(
    name: &str,
    vol: &Volume<'_>,
    dims: [usize; 3],
    iso: f64,
    case: Case,
    configs: &[(String, Options)],
    failures: &mut Vec<String>,
) -> Vec<Mesh> {
    let mut meshes = Vec::new();
    // Plain Marching Cubes of each topology, the reference of a closed
    // surface's existence and size.
    let mut mc_meshes: Vec<(Topology, Mesh)> = Vec::new();
    for (cfg, opts) in configs {
        let one = Options {
            threads: 1,
            ..opts.clone()
        };
        let two = Options {
            threads: 2,
            ..opts.clone()
        };
        let t0 = std::time::Instant::now();
        let m1 = match extract(vol, iso, &one) {
            Ok(m) => m,
            Err(e) => {
                failures.push(format!("{name} / {cfg}: error {e}"));
                continue;
            }
        };
        if std::env::var_os("DEGENERATE_TIMES").is_some() {
            eprintln!(
                "{name} / {cfg}: {} triangles, {:.3} s",
                m1.triangles.len(),
                t0.elapsed().as_secs_f64()
            );
        }
        for p in problems(&m1, dims, case, opts) {
            failures.push(format!("{name} / {cfg}: {p}"));
        }
        if case.expect == Expect::Closed {
            let t = opts.topology;
            if !mc_meshes.iter().any(|(u, _)| *u == t) {
                let mc = extract(vol, iso, &mc_opts(t)).expect("Marching Cubes");
                mc_meshes.push((t, mc));
            }
            let (_, mc) = mc_meshes.iter().find(|(u, _)| *u == t).unwrap();
            if let Some(p) = compare_with_marching_cubes(&m1, mc, case.volume_like_mc) {
                failures.push(format!("{name} / {cfg}: {p}"));
            }
        }
        match extract(vol, iso, &two) {
            Ok(m2) if same_mesh(&m1, &m2) => {}
            Ok(_) => failures.push(format!("{name} / {cfg}: 1 and 2 threads differ")),
            Err(e) => failures.push(format!("{name} / {cfg}: error {e} with 2 threads")),
        }
        meshes.push(m1);
    }
    meshes
}

fn report(failures: Vec<String>) {
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures
            .iter()
            .take(40)
            .cloned()
            .collect::<Vec<_>>()
            .join("\n")
    );
}

fn area(mesh: &Mesh) -> f64 {
    mesh.triangles
        .iter()
        .map(|t| norm(tri_normal(&mesh.index_points, *t)) / 2.0)
        .sum()
}

fn idx(dims: [usize; 3], i: usize, j: usize, k: usize) -> usize {
    i + dims[0] * (j + dims[1] * k)
}

// ---------------------------------------------------------------------------
// Constant volumes.
// ---------------------------------------------------------------------------

/// A constant volume has no surface whatever the isovalue (equal to the
/// constant: every sample inside; above: every sample outside).
#[test]
fn constant_volumes_have_no_triangles() {
    let dims = [5, 6, 7];
    let n = dims[0] * dims[1] * dims[2];
    let cfgs = configs();
    let mut failures = Vec::new();
    for c in [-1.0, 0.0, 1.0, 1e-300, -f64::MAX] {
        let v = vec![c; n];
        let vol = Volume::new(&v, dims_u64(dims));
        for iso in [c, -1.0, 0.0, 0.5, 1.0, 1e300] {
            run(
                &format!("f64 {c} iso {iso}"),
                &vol,
                dims,
                iso,
                EMPTY,
                &cfgs,
                &mut failures,
            );
        }
    }
    for c in [0u8, 128, 255] {
        let v = vec![c; n];
        let vol = Volume::new(&v, dims_u64(dims));
        for iso in [0.0, 127.5, 128.0, 255.0] {
            run(
                &format!("u8 {c} iso {iso}"),
                &vol,
                dims,
                iso,
                EMPTY,
                &cfgs,
                &mut failures,
            );
        }
    }
    {
        let v = vec![0.25f32; n];
        let vol = Volume::new(&v, dims_u64(dims));
        for iso in [0.25, 0.0, 1.0] {
            run(
                &format!("f32 0.25 iso {iso}"),
                &vol,
                dims,
                iso,
                EMPTY,
                &cfgs,
                &mut failures,
            );
        }
    }
    {
        let v = vec![i16::MIN; n];
        let vol = Volume::new(&v, dims_u64(dims));
        for iso in [i16::MIN as f64, 0.0] {
            run(
                &format!("i16 MIN iso {iso}"),
                &vol,
                dims,
                iso,
                EMPTY,
                &cfgs,
                &mut failures,
            );
        }
    }
    report(failures);
}

// ---------------------------------------------------------------------------
// Isovalue on sample values.
// ---------------------------------------------------------------------------

/// Integer data contoured at an integer isovalue, where the surface
/// crosses samples equal to it (wavy spheres, a few tens of units a cell):
/// refinement follows `S_K` there as anywhere else (README, "Samples
/// equal to the isovalue"). It used to keep the Marching Cubes triangles
/// of every cell around such a sample: their distance, measured by
/// `accuracy::measure`, stayed at Marching Cubes' (here 0.025-0.041
/// cells, 13-20 times epsilon). The meshes stay closed and oriented.
#[test]
fn refinement_reaches_epsilon_around_samples_at_the_isovalue() {
    use precisemc::accuracy::{measure, MeasureOptions};
    let eps = 0.002;
    let opts = refine_opts(Topology::Trilinear, Rule::A1, eps, 5);
    let mo = MeasureOptions {
        density: 3,
        ..Default::default()
    };
    let dims = [22, 21, 20];
    let mut ties_seen = 0;
    let mut failures = Vec::new();
    for seed in 0..4u64 {
        let mut rng = Rng::new(900 + seed);
        let c = [10.0 + rng.f64(), 10.0 + rng.f64(), 9.5 + rng.f64()];
        let (r, gain) = (6.0 + 2.0 * rng.f64(), 20.0 + 30.0 * rng.f64());
        let f = grid_fn(dims, |x, y, z| {
            let d = ((x - c[0]).powi(2) + (y - c[1]).powi(2) + (z - c[2]).powi(2)).sqrt();
            1000.0 + gain * (r - d + 0.3 * (0.7 * x).sin() * (0.5 * y).cos())
        });
        let v: Vec<i16> = f.iter().map(|x| x.round() as i16).collect();
        let vol = Volume::new(&v, dims_u64(dims));
        for iso in [995.0, 1000.0, 1003.0] {
            let ties = v.iter().filter(|&&x| x as f64 == iso).count();
            ties_seen += ties;
            let mesh = extract(&vol, iso, &opts).unwrap();
            let d = measure(&vol, iso, &mesh.index_points, &mesh.triangles, &mo).unwrap();
            let check = check_mesh(&mesh);
            let closed = !mesh.triangles.is_empty()
                && check.out_of_range == 0
                && check.boundary_edges == 0
                && check.misoriented_edges == 0
                && check.unbalanced_edges == 0
                && check.degenerate == 0
                && check.duplicates == 0;
            if d.max > 1.5 * eps || !closed {
                failures.push(format!(
                    "seed {seed} iso {iso} ({ties} samples at it): max distance {:.5}, {check:?}",
                    d.max
                ));
            }
        }
    }
    assert!(ties_seen > 20, "only {ties_seen} samples at the isovalues");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Rounded wavy spheres of many gains (1 to 30 units a cell, some with
/// noise of a unit or two), closed by a low border, at integer isovalues:
/// samples at the isovalue on peaks, ridges, plateaus and slopes, where
/// refinement runs on a shifted isovalue or stays frozen (README,
/// "Samples equal to the isovalue"); every configuration must give a
/// closed, consistently oriented surface enclosing a positive volume.
#[test]
fn integer_spheres_at_integer_isovalues() {
    let cfgs = configs();
    let mut failures = Vec::new();
    let mut cases = 0;
    for seed in 0..16u64 {
        let mut rng = Rng::new(5000 + seed);
        let dims = [
            10 + rng.below(6) as usize,
            9 + rng.below(6) as usize,
            8 + rng.below(6) as usize,
        ];
        let gain = [1.0, 2.0, 3.0, 5.0, 10.0, 30.0][rng.below(6) as usize];
        let noise = [0.0, 0.5, 1.5][rng.below(3) as usize];
        let c = dims.map(|n| n as f64 / 2.0 + rng.f64());
        let r = 2.5 + 2.0 * rng.f64();
        let mut v: Vec<i16> = grid_fn(dims, |x, y, z| {
            let d = ((x - c[0]).powi(2) + (y - c[1]).powi(2) + (z - c[2]).powi(2)).sqrt();
            (20.0 + gain * (r - d + 0.4 * (0.9 * x).sin() * (0.7 * y).cos())).round()
        })
        .into_iter()
        .map(|x| x as i16)
        .collect();
        for x in v.iter_mut() {
            *x += (noise * (rng.f64() * 2.0 - 1.0)).round() as i16;
        }
        let low = (15 - (gain * 3.0) as i16).min(0);
        set_border(&mut v, dims, low);
        let vol = Volume::new(&v, dims_u64(dims));
        // Four levels through the sphere's wall, and its top (peaks).
        let top = *v.iter().max().unwrap() as f64;
        let levels = (0..4).map(|k| (20.0 + gain * (k as f64 - 1.5)).round());
        for iso in levels.chain([top]) {
            if iso > low as f64 {
                cases += 1;
                let name = format!("sphere {seed} gain {gain} noise {noise} iso {iso}");
                let meshes = run(&name, &vol, dims, iso, CLOSED_LIKE_MC, &cfgs, &mut failures);
                if iso < top {
                    require_marching_cubes_surface(&name, &meshes, &cfgs, &mut failures);
                }
            }
        }
    }
    assert!(cases >= 50, "{cases} cases");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Gradient normals are unit vectors on label data contoured at a label's
/// value: a point on a sample whose upper cell is flat (all its samples
/// equal the point's) took that cell's zero gradient (a quarter of a
/// binary sphere's points had (0, 0, 0) at isovalue 1).
#[test]
fn gradient_normals_on_label_volumes_are_unit_vectors() {
    use precisemc::NormalMode;
    for (seed, top) in [(1u64, 1i16), (2, 1), (3, 3), (4, 5)] {
        let mut rng = Rng::new(9000 + seed);
        let dims = [18 + rng.below(4) as usize, 17 + rng.below(4) as usize, 16];
        let c = dims.map(|n| n as f64 / 2.0 + rng.f64() - 0.5);
        let r = 6.0 + 1.5 * rng.f64();
        // Nested shells labelled 1..=top inside, 0 outside.
        let v: Vec<i16> = grid_fn(dims, |x, y, z| {
            let d = ((x - c[0]).powi(2) + (y - c[1]).powi(2) + (z - c[2]).powi(2)).sqrt();
            (r - d + 1.0).floor().clamp(0.0, top as f64)
        })
        .into_iter()
        .map(|x| x as i16)
        .collect();
        let vol = Volume::new(&v, dims_u64(dims));
        for label in 1..=top {
            for eps in [0.0, 0.01] {
                let opts = Options {
                    epsilon: eps,
                    normals: NormalMode::Gradient,
                    ..Options::default()
                };
                let mesh = extract(&vol, label as f64, &opts).unwrap();
                assert!(!mesh.triangles.is_empty(), "seed {seed} label {label}");
                assert_eq!(mesh.normals.len(), mesh.points.len());
                for (n, p) in mesh.normals.iter().zip(&mesh.index_points) {
                    let len = n.iter().map(|c| (*c as f64).powi(2)).sum::<f64>().sqrt();
                    assert!(
                        (len - 1.0).abs() < 1e-5,
                        "seed {seed} label {label} eps {eps}: normal {n:?} at {p:?}"
                    );
                }
            }
        }
    }
}

/// Normals are unit vectors next to NaN and infinite samples, in both
/// modes: the surface's cells are finite, but a point on their faces was
/// located in a neighbouring cell with a NaN corner (gradient mode), and
/// central differences took NaN from a neighbour, or 0 x NaN from corners
/// of no weight (about 100 and 470 zero normals of 5 500 triangles on the
/// Wavelet with 60 NaN samples).
#[test]
fn normals_next_to_non_finite_samples_are_unit_vectors() {
    use precisemc::NormalMode;
    let mut checked = 0;
    for seed in 0..6u64 {
        let mut rng = Rng::new(4200 + seed);
        let dims = [20, 19, 18];
        let c = dims.map(|n| n as f64 / 2.0 + rng.f64() - 0.5);
        let mut v = grid_fn(dims, |x, y, z| {
            7.0 - ((x - c[0]).powi(2) + (y - c[1]).powi(2) + (z - c[2]).powi(2)).sqrt()
                + 0.3 * (x * 0.9 + y * 0.4).sin()
        });
        // Non-finite samples scattered near the surface.
        for n in 0..40 {
            let i = rng.below(v.len() as u64) as usize;
            if v[i].abs() < 2.5 {
                v[i] = [f64::NAN, f64::INFINITY, f64::NEG_INFINITY][n % 3];
            }
        }
        let vol = Volume::new(&v, dims_u64(dims));
        for normals in [NormalMode::Gradient, NormalMode::CentralDifference] {
            for eps in [0.0, 0.01] {
                let opts = Options {
                    epsilon: eps,
                    normals,
                    ..Options::default()
                };
                let mesh = extract(&vol, 0.0, &opts).unwrap();
                assert!(mesh.stats.skipped_nonfinite_cells > 0, "seed {seed}");
                for (n, p) in mesh.normals.iter().zip(&mesh.index_points) {
                    let len = n.iter().map(|c| (*c as f64).powi(2)).sum::<f64>().sqrt();
                    assert!(
                        (len - 1.0).abs() < 1e-5,
                        "seed {seed} {normals:?} eps {eps}: normal {n:?} at {p:?}"
                    );
                    checked += 1;
                }
            }
        }
    }
    assert!(checked > 10_000, "{checked} normals");
}

/// Random integers in `0..=top` on `dims`, with a border of 0.
fn random_integers(rng: &mut Rng, dims: [usize; 3], top: u64) -> Vec<i16> {
    let mut v: Vec<i16> = (0..dims[0] * dims[1] * dims[2])
        .map(|_| rng.below(top + 1) as i16)
        .collect();
    set_border(&mut v, dims, 0);
    v
}

/// Random integers in 0..=top (top 3 to 6) with a border of 0, at every
/// integer isovalue: plateaus, ridges and three-sample faces at the
/// isovalue everywhere. (Refining faces with three samples at the
/// isovalue and the fourth below, which README "Samples equal to the
/// isovalue" keeps frozen, made surfaces of negative volume here.)
#[test]
fn random_integers_at_every_integer_isovalue() {
    let cfgs = configs();
    let mut failures = Vec::new();
    for seed in 0..12u64 {
        let mut rng = Rng::new(9100 + seed);
        let dims = [9, 8, 7];
        let top = 3 + rng.below(4);
        let v = random_integers(&mut rng, dims, top);
        let vol = Volume::new(&v, dims_u64(dims));
        let max = *v.iter().max().unwrap() as u64;
        for iso in 1..=top {
            let name = format!("random {seed} top {top} iso {iso}");
            let iso_f = iso as f64;
            let meshes = run(
                &name,
                &vol,
                dims,
                iso_f,
                CLOSED_LIKE_MC,
                &cfgs,
                &mut failures,
            );
            if iso < max {
                require_marching_cubes_surface(&name, &meshes, &cfgs, &mut failures);
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Random integers in 0..=4 with a border of 0; the isovalue on every
/// integer level. Iso 0 puts every sample inside (no surface); iso 4 is
/// the maximum (the surface shrinks onto the samples equal to 4: isolated
/// samples give nothing, since their triangles collapse onto the sample).
#[test]
fn isovalue_on_integer_samples() {
    let cfgs = configs();
    let mut failures = Vec::new();
    for seed in 0..3u64 {
        let dims = [9, 8, 7];
        let mut rng = Rng::new(700 + seed);
        let v = random_integers(&mut rng, dims, 4);
        let vol = Volume::new(&v, dims_u64(dims));
        run(
            &format!("seed {seed} iso 0"),
            &vol,
            dims,
            0.0,
            EMPTY,
            &cfgs,
            &mut failures,
        );
        let max = *v.iter().max().unwrap() as f64;
        for iso in [1.0, 2.0, 3.0, 4.0] {
            let name = format!("seed {seed} iso {iso}");
            let meshes = run(&name, &vol, dims, iso, CLOSED_LIKE_MC, &cfgs, &mut failures);
            if iso < max {
                require_marching_cubes_surface(&name, &meshes, &cfgs, &mut failures);
            }
        }
        // The same data as f64, isovalue just off an integer (generic).
        let f: Vec<f64> = v.iter().map(|&x| x as f64).collect();
        let volf = Volume::new(&f, dims_u64(dims));
        // (Iso 1.5 puts face saddles such as that of 2 1 / 1 2 exactly at the
        // isovalue, and the case of
        // `centroid_rules_keep_a_generic_cell_manifold` in some cell.)
        for iso in [1.5, 2.0 + 1e-9, 3.0 - 1e-9] {
            let name = format!("seed {seed} f64 iso {iso}");
            let meshes = run(
                &name,
                &volf,
                dims,
                iso,
                CLOSED_LIKE_MC,
                &cfgs,
                &mut failures,
            );
            if iso < max {
                require_marching_cubes_surface(&name, &meshes, &cfgs, &mut failures);
            }
        }
    }
    // Terraces: floor((x + y + z) / 2), open, iso on every level.
    let dims = [8, 7, 9];
    let t: Vec<u8> = grid_fn(dims, |x, y, z| ((x + y + z) / 2.0).floor())
        .into_iter()
        .map(|x| x as u8)
        .collect();
    let vol = Volume::new(&t, dims_u64(dims));
    for iso in [1.0, 3.0, 5.0, 10.0] {
        run(
            &format!("terraces iso {iso}"),
            &vol,
            dims,
            iso,
            OPEN,
            &cfgs,
            &mut failures,
        );
    }
    report(failures);
}

// ---------------------------------------------------------------------------
// Planes through grid points.
// ---------------------------------------------------------------------------

/// Linear fields are reproduced exactly by the trilinear interpolant, so
/// `S_K` is the plane: with or without refinement the mesh is flat and its
/// area is the area of the plane's section of the box (to rounding). With
/// the isovalue exactly on a lattice plane the surface runs through the
/// samples at the isovalue (they are inside: the cells above them have no
/// surface, the cells below have a flat quad on their top face).
#[test]
fn planes_through_grid_points() {
    let dims = [8, 8, 8];
    let s2 = 2f64.sqrt();
    let s3 = 3f64.sqrt();
    // Name, field, area of the section {f = 0} of [0, 7]^3.
    type Plane = (&'static str, fn(f64, f64, f64) -> f64, f64);
    let planes: [Plane; 7] = [
        ("z - 3", |_, _, z| z - 3.0, 49.0),
        ("3 - z", |_, _, z| 3.0 - z, 49.0),
        ("x - 3", |x, _, _| x - 3.0, 49.0),
        ("y - 6", |_, y, _| y - 6.0, 49.0),
        ("x + y - 5", |x, y, _| x + y - 5.0, 35.0 * s2),
        ("x - y", |x, y, _| x - y, 49.0 * s2),
        ("x + y + z - 6", |x, y, z| x + y + z - 6.0, 18.0 * s3),
    ];
    let cfgs = configs();
    let mut failures = Vec::new();
    for (name, f, expected_area) in planes {
        let v = grid_fn(dims, f);
        let vol = Volume::new(&v, dims_u64(dims));
        for iso in [0.0, 1e-12, -1e-12, 1e-6, -1e-6] {
            let case_name = format!("plane {name} iso {iso}");
            let generic = iso != 0.0;
            let case = if generic { OPEN_MANIFOLD } else { OPEN };
            let meshes = run(&case_name, &vol, dims, iso, case, &cfgs, &mut failures);
            for (m, (cfg, _)) in meshes.iter().zip(&cfgs) {
                let a = area(m);
                // Shifting the plane by 1e-6 changes the area by about
                // that much; the section stays flat.
                if (a - expected_area).abs() > 1e-4 * expected_area {
                    failures.push(format!(
                        "{case_name} / {cfg}: area {a}, expected {expected_area}"
                    ));
                }
            }
        }
    }
    report(failures);
}

/// Closed polyhedra whose faces pass through grid points: a cube
/// `3 - max|x - c|` and an octahedron `4 - |x - c|_1` on an integer
/// lattice, iso 0 (and a little above).
#[test]
fn polyhedra_through_grid_points_are_closed() {
    let dims = [11, 11, 11];
    let cfgs = configs();
    let mut failures = Vec::new();
    let cube = grid_fn(dims, |x, y, z| {
        3.0 - (x - 5.0).abs().max((y - 5.0).abs()).max((z - 5.0).abs())
    });
    let octa = grid_fn(dims, |x, y, z| {
        4.0 - (x - 5.0).abs() - (y - 5.0).abs() - (z - 5.0).abs()
    });
    for (name, v) in [("cube", &cube), ("octahedron", &octa)] {
        let vol = Volume::new(v, dims_u64(dims));
        for iso in [0.0, 1.0, 0.5, 1e-12] {
            let case = if iso == 0.0 || iso == 1.0 {
                CLOSED
            } else {
                CLOSED_MANIFOLD
            };
            let meshes = run(
                &format!("{name} iso {iso}"),
                &vol,
                dims,
                iso,
                case,
                &cfgs,
                &mut failures,
            );
            if meshes.iter().any(|m| m.triangles.is_empty()) {
                failures.push(format!("{name} iso {iso}: empty mesh"));
            }
        }
    }
    report(failures);
}

// ---------------------------------------------------------------------------
// Checkerboards.
// ---------------------------------------------------------------------------

fn checker(dims: [usize; 3]) -> Vec<f64> {
    grid_fn(dims, |x, y, z| {
        if (x + y + z) as i64 % 2 == 0 {
            1.0
        } else {
            -1.0
        }
    })
}

/// With the Classic topology, a cell whose table patch joins the
/// crossings otherwise than `S_K` (an ambiguous face cut the other way,
/// caps where `S_K` has a tunnel) is refined on its faces' edges only:
/// its interior samples could never reach `S_K`, and refining them kept
/// splitting to the last level (one ±1 checkerboard cell at iso -0.5, rule
/// B, epsilon 0.1: 3.2 M triangles at level 9 where the Trilinear topology
/// keeps its 4; on random 4x4x4 fields up to 100 times the Trilinear
/// topology's count). Checked on random fields and checkerboards: the
/// Classic topology's refined output stays within a small factor of the
/// Trilinear topology's (or of its own Marching Cubes triangles).
#[test]
fn classic_refinement_stays_bounded_where_the_table_is_not_s_k() {
    let mut failures = Vec::new();
    let mut cases: Vec<(String, [usize; 3], Vec<f64>, f64)> = Vec::new();
    let level = 6;
    for seed in 0..60u64 {
        let mut rng = Rng::new(seed);
        let v: Vec<f64> = (0..64).map(|_| rng.range(-1.0, 1.0)).collect();
        for iso in [-0.5, 0.0, 0.3] {
            cases.push((format!("random seed {seed}"), [4, 4, 4], v.clone(), iso));
        }
    }
    for n in [2, 3, 5] {
        for iso in [-0.8, -0.5, -0.2, 0.2, 0.5, 0.8] {
            cases.push((format!("checker {n}^3"), [n; 3], checker([n; 3]), iso));
        }
    }
    for (name, dims, v, iso) in &cases {
        let vol = Volume::new(v, dims_u64(*dims));
        for rule in [Rule::B, Rule::A1] {
            let run = |topology| {
                extract(&vol, *iso, &refine_opts(topology, rule, 0.1, level))
                    .unwrap()
                    .stats
            };
            let (classic, trilinear) = (run(Topology::Classic), run(Topology::Trilinear));
            let bound = 8 * trilinear.output_triangles.max(classic.mc_triangles);
            if classic.output_triangles > bound {
                failures.push(format!(
                    "{name} iso {iso} {rule:?} level {level}: Classic gave {} triangles \
                     (its Marching Cubes {}), Trilinear {}",
                    classic.output_triangles, classic.mc_triangles, trilinear.output_triangles
                ));
            }
        }
    }
    report(failures);
}

/// Alternating ±1. With iso exactly 0 every face of every cell is
/// ambiguous with its saddle exactly at the isovalue (and the body saddle
/// too): `S_K` touches itself at every face centre, so non-manifold vertices
/// are allowed there; slightly off 0 the data is generic.
#[test]
fn checkerboards() {
    let cfgs = configs();
    let mut failures = Vec::new();
    let dims = [6, 5, 7];
    let v = checker(dims);
    let vol = Volume::new(&v, dims_u64(dims));
    for iso in [0.0, 1e-12, -1e-12, 1e-6, -1e-6, 0.5, -0.5] {
        let case = if iso == 0.0 { OPEN } else { OPEN_MANIFOLD };
        let meshes = run(
            &format!("checker iso {iso}"),
            &vol,
            dims,
            iso,
            case,
            &cfgs,
            &mut failures,
        );
        if meshes.iter().any(|m| m.triangles.is_empty()) {
            failures.push(format!("checker iso {iso}: empty mesh"));
        }
    }
    // Padded by a border of -1 (below every isovalue tried): closed.
    let dims = [8, 7, 9];
    let mut v = checker(dims);
    set_border(&mut v, dims, -1.0);
    let vol = Volume::new(&v, dims_u64(dims));
    for iso in [0.0, 1e-12, -1e-12, 1e-6, -1e-6, 0.5, -0.5] {
        let case = if iso == 0.0 { CLOSED } else { CLOSED_MANIFOLD };
        run(
            &format!("padded checker iso {iso}"),
            &vol,
            dims,
            iso,
            case,
            &cfgs,
            &mut failures,
        );
    }
    // The same as i8 (the integer path of the sample reader).
    let vi: Vec<i8> = v.iter().map(|&x| x as i8).collect();
    let vol = Volume::new(&vi, dims_u64(dims));
    run(
        "padded i8 checker iso 0",
        &vol,
        dims,
        0.0,
        CLOSED,
        &cfgs,
        &mut failures,
    );
    report(failures);
}

// ---------------------------------------------------------------------------
// Face saddles near the isovalue.
// ---------------------------------------------------------------------------

/// Whether some sample is at the isovalue or some ambiguous cell face has
/// its saddle exactly there (the asymptotic decider's products tie, as the
/// library computes them from `sample - iso`): `S_K` may touch itself
/// there, so the mesh need not be a 2-manifold.
fn touches(v: &[f64], dims: [usize; 3], iso: f64) -> bool {
    if v.contains(&iso) {
        return true;
    }
    let f = |i: usize, j: usize, k: usize| v[idx(dims, i, j, k)] - iso;
    for axis in 0..3 {
        let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut lo = [0usize; 3];
        lo[u] = dims[u] - 1;
        lo[w] = dims[w] - 1;
        lo[axis] = dims[axis];
        for i in 0..lo[0] {
            for j in 0..lo[1] {
                for k in 0..lo[2] {
                    let corner = |du: usize, dw: usize| {
                        let mut p = [i, j, k];
                        p[u] += du;
                        p[w] += dw;
                        f(p[0], p[1], p[2])
                    };
                    let g = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                    let s = g.map(|x| x >= 0.0);
                    if s[0] == s[2] && s[1] == s[3] && s[0] != s[1] && g[0] * g[2] == g[1] * g[3] {
                        return true;
                    }
                }
            }
        }
    }
    false
}

/// Sets the sample at `face[2]` so that the face with corners `face` (in
/// cyclic order) has its bilinear saddle at `iso + t`.
fn put_saddle(v: &mut [f64], face: [usize; 4], iso: f64, t: f64) {
    let (f0, f1, f3) = (v[face[0]] - iso, v[face[1]] - iso, v[face[3]] - iso);
    // (f0 f2 - f1 f3) / (f0 + f2 - f1 - f3) = t, solved for f2.
    v[face[2]] = iso + (f1 * f3 + t * (f0 - f1 - f3)) / (f0 - t);
}

/// Regression (was a bug of the Trilinear topology): two cells sharing an
/// ambiguous face, each with a tube (`stitch` in `src/mc/trilinear.rs`)
/// that needs a diagonal lying in that face, took the same one, an edge
/// in four triangles. Both cells see the same two diagonals across the
/// face, and near a face saddle at the isovalue their costs tie (the
/// 3x2x2 volume below gave it at iso 1e-9, not at 1e-6); random ±1-ish
/// data gave it too, well away from ties. Checked here: that volume at
/// isovalues 1e-12..1e-3 on both sides of its saddle (0), and random
/// two-cell volumes (along each axis) and 3x3x3 volumes with values of
/// magnitude 1..1.3 whose shared face (or one interior face) has its
/// saddle within 1e-15..1e-6 of the isovalue: every mesh a 2-manifold,
/// except where the rounded data puts a saddle exactly on the isovalue.
#[test]
fn face_saddles_near_the_isovalue_keep_the_mesh_manifold() {
    let cfgs: Vec<(String, Options)> = quick_configs()
        .into_iter()
        .filter(|(_, o)| o.topology == Topology::Trilinear)
        .collect();
    let mut failures = Vec::new();
    let data = [1., 1., -1., 1., -1., 1., 1., -1., 1., -1., 1., 1.];
    let dims = [3, 2, 2];
    let vol = Volume::new(&data[..], dims_u64(dims));
    for e in 3..=12 {
        for sign in [1.0, -1.0] {
            let iso = sign * 10f64.powi(-e);
            let name = format!("3x2x2 iso {iso:e}");
            run(&name, &vol, dims, iso, OPEN_MANIFOLD, &cfgs, &mut failures);
        }
    }
    let mut rng = Rng::new(4444);
    let mut ties = 0;
    let mut volumes = 0;
    // Shape 0..3: two cells along that axis; 3: 3x3x3.
    for shape in 0..4 {
        for _ in 0..150 {
            let dims = if shape == 3 {
                [3, 3, 3]
            } else {
                let mut d = [2, 2, 2];
                d[shape] = 3;
                d
            };
            let iso = if rng.bool() {
                0.0
            } else {
                rng.range(-0.05, 0.05)
            };
            let mut v: Vec<f64> = (0..dims.iter().product::<usize>())
                .map(|_| {
                    let m = rng.range(1.0, 1.3);
                    iso + if rng.bool() { m } else { -m }
                })
                .collect();
            // The face: normal `axis` at 1, from (a, b) in the other two.
            let axis = if shape == 3 {
                rng.below(3) as usize
            } else {
                shape
            };
            let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
            let (a, b) = if shape == 3 {
                (rng.below(2) as usize, rng.below(2) as usize)
            } else {
                (0, 0)
            };
            let face: [usize; 4] = std::array::from_fn(|k| {
                let mut p = [0; 3];
                p[axis] = 1;
                p[u] = a + [0, 1, 1, 0][k];
                p[w] = b + [0, 0, 1, 1][k];
                idx(dims, p[0], p[1], p[2])
            });
            // Ambiguous: alternating signs around the face.
            let s = if rng.bool() { 1.0 } else { -1.0 };
            for (k, &c) in face.iter().enumerate() {
                let m = (v[c] - iso).abs();
                v[c] = iso + if k % 2 == 0 { s * m } else { -s * m };
            }
            let t = rng.log_uniform(1e-15, 1e-6);
            put_saddle(&mut v, face, iso, if rng.bool() { t } else { -t });
            let case = if touches(&v, dims, iso) {
                ties += 1;
                OPEN
            } else {
                OPEN_MANIFOLD
            };
            let name = format!("{dims:?} iso {iso:e} saddle {t:e} off {v:?}");
            let vol = Volume::new(&v, dims_u64(dims));
            run(&name, &vol, dims, iso, case, &cfgs, &mut failures);
            volumes += 1;
        }
    }
    // Exact ties of the rounded data are rare: the check is not vacuous.
    assert!(ties * 20 < volumes, "{ties} of {volumes} volumes tie");
    report(failures);
}

// ---------------------------------------------------------------------------
// Single-voxel spikes.
// ---------------------------------------------------------------------------

/// One sample above the isovalue in a field below it: a small closed
/// surface around the sample (an octahedron-like patch), for magnitudes
/// down to the smallest subnormal, where every vertex lies within rounding
/// of the sample. A spike exactly at the isovalue is inside but encloses
/// nothing: its triangles collapse onto the sample and are dropped.
#[test]
fn single_sample_above_the_isovalue() {
    let dims = [7, 7, 7];
    let cfgs = configs();
    let mut failures = Vec::new();
    for mag in [1.0, 1e-3, 1e-9, 1e-17, 1e-300, 5e-324] {
        for (where_, at) in [
            ("centre", [3, 3, 3]),
            ("near border", [1, 1, 5]),
            ("corner", [0, 0, 0]),
            ("edge", [0, 3, 6]),
            ("face", [3, 0, 3]),
        ] {
            let on_border = at.iter().zip(dims).any(|(&a, d)| a == 0 || a + 1 == d);
            if on_border && mag < 1e-17 {
                // Next to coordinate 0 the vertices stay distinct (1e-300 is
                // representable) but the cross product underflows, so the
                // checker's area is exactly 0: not a mesh defect.
                continue;
            }
            let mut v = vec![-1.0; dims[0] * dims[1] * dims[2]];
            v[idx(dims, at[0], at[1], at[2])] = mag;
            let vol = Volume::new(&v, dims_u64(dims));
            // Below about 1e-16 relative the vertices round onto the sample:
            // the triangles collapse and are dropped (a rounding tie),
            // possibly leaving the unused point.
            let tie = mag < 1e-9;
            let case = Case {
                expect: if on_border {
                    Expect::Open
                } else {
                    Expect::Closed
                },
                manifold: !tie,
                volume_like_mc: false,
            };
            let name = format!("spike +{mag} at {where_}");
            let meshes = run(&name, &vol, dims, 0.0, case, &cfgs, &mut failures);
            if mag >= 1e-9 && meshes.iter().any(|m| m.triangles.is_empty()) {
                failures.push(format!("{name}: empty mesh"));
            }
        }
    }
    // Exactly at the isovalue, and the same spike in a field of -1 scaled.
    let mut v = vec![-1.0; dims[0] * dims[1] * dims[2]];
    v[idx(dims, 3, 3, 3)] = 0.0;
    let vol = Volume::new(&v, dims_u64(dims));
    run("spike at iso", &vol, dims, 0.0, EMPTY, &cfgs, &mut failures);
    // u8: one 255 in zeros, iso 1 and iso 255.
    let mut u = vec![0u8; dims[0] * dims[1] * dims[2]];
    u[idx(dims, 2, 4, 3)] = 255;
    let vol = Volume::new(&u, dims_u64(dims));
    run(
        "u8 spike iso 1",
        &vol,
        dims,
        1.0,
        CLOSED_MANIFOLD,
        &cfgs,
        &mut failures,
    );
    run(
        "u8 spike iso 255",
        &vol,
        dims,
        255.0,
        EMPTY,
        &cfgs,
        &mut failures,
    );
    report(failures);
}

/// One sample below the isovalue in a field above it, padded by a border
/// below the isovalue: two closed components (the box-like outer surface
/// and a small inverted one around the sample, which encloses negative
/// volume, the total staying positive).
#[test]
fn single_sample_below_the_isovalue() {
    let dims = [7, 8, 7];
    let cfgs = configs();
    let mut failures = Vec::new();
    for mag in [1.0, 1e-3, 1e-9, 1e-17, 1e-300, 5e-324] {
        for at in [[3, 3, 3], [1, 1, 1], [2, 6, 5]] {
            let mut v = vec![1.0; dims[0] * dims[1] * dims[2]];
            set_border(&mut v, dims, -1.0);
            v[idx(dims, at[0], at[1], at[2])] = -mag;
            let vol = Volume::new(&v, dims_u64(dims));
            let name = format!("hole -{mag} at {at:?}");
            // Tiny holes: a rounding tie (see the spikes above).
            let case = Case {
                expect: Expect::Closed,
                manifold: mag >= 1e-9,
                volume_like_mc: false,
            };
            let meshes = run(&name, &vol, dims, 0.0, case, &cfgs, &mut failures);
            for (m, (cfg, _)) in meshes.iter().zip(&cfgs) {
                let c = check_mesh(m);
                // The hole's surface exists when its vertices do not all
                // round onto the sample; adjacent to the border it merges
                // with the outer surface.
                let interior = at.iter().zip(dims).all(|(&a, d)| a >= 2 && a + 3 <= d);
                if mag >= 1e-9 && interior && c.components != 2 {
                    failures.push(format!("{name} / {cfg}: {} components", c.components));
                }
            }
        }
    }
    // A hole exactly at the isovalue is inside: the same mesh as no hole.
    let mut v = vec![1.0; dims[0] * dims[1] * dims[2]];
    set_border(&mut v, dims, -1.0);
    let plain = v.clone();
    v[idx(dims, 3, 3, 3)] = 0.0;
    let vol = Volume::new(&v, dims_u64(dims));
    let with = run("hole at iso", &vol, dims, 0.0, CLOSED, &cfgs, &mut failures);
    let vol = Volume::new(&plain, dims_u64(dims));
    let without = run(
        "no hole",
        &vol,
        dims,
        0.0,
        CLOSED_MANIFOLD,
        &cfgs,
        &mut failures,
    );
    for ((a, b), (cfg, _)) in with.iter().zip(&without).zip(&cfgs) {
        if a.triangles.len() != b.triangles.len() {
            failures.push(format!(
                "hole at iso / {cfg}: {} triangles, {} without the hole",
                a.triangles.len(),
                b.triangles.len()
            ));
        }
    }
    report(failures);
}

// ---------------------------------------------------------------------------
// 2x2x2 volumes.
// ---------------------------------------------------------------------------

/// Corner values of sign pattern `pattern` (bit c set: corner c inside)
/// with magnitudes from `mag`.
fn pattern_values(pattern: u32, mut mag: impl FnMut() -> f64) -> [f64; 8] {
    std::array::from_fn(|c| {
        let m = mag();
        if pattern >> c & 1 == 1 {
            m
        } else {
            -m
        }
    })
}

/// The cell embedded in a 4x4x4 volume with a border of -1: closed.
fn padded_cell(f: &[f64; 8]) -> Vec<f64> {
    let dims = [4, 4, 4];
    let mut v = vec![-1.0; 64];
    for (c, p) in CORNER.iter().enumerate() {
        v[idx(dims, p[0] + 1, p[1] + 1, p[2] + 1)] = f[c];
    }
    v
}

/// [`run`] on the cell `f` embedded by [`padded_cell`], at isovalue 0.
fn run_padded(
    name: &str,
    f: &[f64; 8],
    case: Case,
    configs: &[(String, Options)],
    failures: &mut Vec<String>,
) -> Vec<Mesh> {
    let p = padded_cell(f);
    let vol = Volume::new(&p, [4, 4, 4]);
    run(name, &vol, [4, 4, 4], 0.0, case, configs, failures)
}

/// Every sign pattern of a single cell: random magnitudes (generic), equal
/// magnitudes (ambiguous faces then have their saddle exactly at 0: `S_K`
/// touches itself there), and magnitudes spread over six decades; alone
/// (open) and padded by a border of -1 (closed).
#[test]
fn all_sign_patterns_of_a_cell() {
    let cfgs = quick_configs();
    let mut failures = Vec::new();
    let mut rng = Rng::new(2222);
    let mut total = 0usize;
    for pattern in 0u32..256 {
        let mut variants: Vec<(String, [f64; 8], bool)> = Vec::new();
        for d in 0..2 {
            variants.push((
                format!("random {d}"),
                pattern_values(pattern, || rng.range(0.05, 1.0)),
                true,
            ));
        }
        variants.push(("equal".into(), pattern_values(pattern, || 1.0), false));
        for (vname, f, generic) in variants {
            let name = format!("pattern {pattern:#010b} {vname} {f:?}");
            let v = cell_volume(&f);
            let vol = Volume::new(&v, [2, 2, 2]);
            let case = if generic { OPEN_MANIFOLD } else { OPEN };
            let meshes = run(&name, &vol, [2, 2, 2], 0.0, case, &cfgs, &mut failures);
            let empty = pattern == 0 || pattern == 255;
            for m in &meshes {
                total += m.triangles.len();
                if empty != m.triangles.is_empty() {
                    failures.push(format!("{name}: {} triangles", m.triangles.len()));
                }
            }
            let case = if generic { CLOSED_MANIFOLD } else { CLOSED };
            run_padded(&format!("padded {name}"), &f, case, &cfgs, &mut failures);
        }
    }
    assert!(total > 0);
    report(failures);
}

// ---------------------------------------------------------------------------
// Extreme aspect ratios.
// ---------------------------------------------------------------------------

/// Permutes a field defined on (long, a, b) to put the long axis at `axis`.
fn along(
    axis: usize,
    n: usize,
    m: usize,
    f: impl Fn(f64, f64, f64) -> f64,
) -> ([usize; 3], Vec<f64>) {
    let mut dims = [m, m, m];
    dims[axis] = n;
    let v = grid_fn(dims, |x, y, z| {
        let p = [x, y, z];
        let (a, b) = match axis {
            0 => (p[1], p[2]),
            1 => (p[2], p[0]),
            _ => (p[0], p[1]),
        };
        f(p[axis], a, b)
    });
    (dims, v)
}

/// 1000x2x2 and its permutations: a smooth field, and random ±1 (many
/// ambiguous cells); everything is border, so the surface is open.
#[test]
fn thin_slabs_of_extreme_aspect() {
    let cfgs = configs();
    let mut failures = Vec::new();
    for axis in 0..3 {
        let (dims, v) = along(axis, 1000, 2, |t, a, b| {
            (0.037 * t).sin() + 0.6 * (a - 0.5) - 0.45 * (b - 0.5) + 0.2 * (0.11 * t).cos()
        });
        let vol = Volume::new(&v, dims_u64(dims));
        let meshes = run(
            &format!("smooth {dims:?}"),
            &vol,
            dims,
            0.0,
            OPEN_MANIFOLD,
            &cfgs,
            &mut failures,
        );
        if meshes.iter().any(|m| m.triangles.is_empty()) {
            failures.push(format!("smooth {dims:?}: empty mesh"));
        }
        let mut rng = Rng::new(31 + axis as u64);
        let r: Vec<f64> = (0..v.len())
            .map(|_| if rng.bool() { 1.0 } else { -1.0 } * rng.range(0.1, 1.0))
            .collect();
        let vol = Volume::new(&r, dims_u64(dims));
        run(
            &format!("random {dims:?}"),
            &vol,
            dims,
            0.0,
            OPEN_MANIFOLD,
            &cfgs,
            &mut failures,
        );
        // Integer ±1 with iso 0: saddles exactly at the isovalue.
        let s: Vec<i8> = r.iter().map(|&x| if x > 0.0 { 1 } else { -1 }).collect();
        let vol = Volume::new(&s, dims_u64(dims));
        run(
            &format!("random ±1 {dims:?}"),
            &vol,
            dims,
            0.0,
            OPEN,
            &cfgs,
            &mut failures,
        );
    }
    report(failures);
}

/// 1000x3x3 and its permutations with a tube along the middle line (the
/// only samples above the isovalue), padded by the border: closed. A
/// continuous tube is one component of genus 0; a tube broken by samples
/// below the isovalue falls into several closed components.
#[test]
fn tubes_of_extreme_aspect_are_closed() {
    let cfgs = configs();
    let mut failures = Vec::new();
    for axis in 0..3 {
        let mut rng = Rng::new(77 + axis as u64);
        let heights: Vec<f64> = (0..1000).map(|_| rng.range(0.1, 1.0)).collect();
        let line = |t: f64, a: f64, b: f64, h: &[f64]| {
            let t = t as usize;
            if a == 1.0 && b == 1.0 && t > 0 && t < 999 {
                h[t]
            } else {
                -1.0
            }
        };
        let (dims, v) = along(axis, 1000, 3, |t, a, b| line(t, a, b, &heights));
        let vol = Volume::new(&v, dims_u64(dims));
        let meshes = run(
            &format!("tube {dims:?}"),
            &vol,
            dims,
            0.0,
            CLOSED_MANIFOLD,
            &cfgs,
            &mut failures,
        );
        for (m, (cfg, _)) in meshes.iter().zip(&cfgs) {
            let c = check_mesh(m);
            if c.components != 1 || c.euler != 2 {
                failures.push(format!(
                    "tube {dims:?} / {cfg}: {} components, Euler {}",
                    c.components, c.euler
                ));
            }
        }
        // Break the tube at 50, 150, ..., 950: 11 pieces.
        let broken: Vec<f64> = heights
            .iter()
            .enumerate()
            .map(|(t, &h)| if t % 100 == 50 { -0.5 } else { h })
            .collect();
        let (dims, v) = along(axis, 1000, 3, |t, a, b| line(t, a, b, &broken));
        let vol = Volume::new(&v, dims_u64(dims));
        let meshes = run(
            &format!("broken tube {dims:?}"),
            &vol,
            dims,
            0.0,
            CLOSED_MANIFOLD,
            &cfgs,
            &mut failures,
        );
        for (m, (cfg, _)) in meshes.iter().zip(&cfgs) {
            let c = check_mesh(m);
            if c.components != 11 || c.euler != 22 {
                failures.push(format!(
                    "broken tube {dims:?} / {cfg}: {} components, Euler {}",
                    c.components, c.euler
                ));
            }
        }
        // Integer tube with iso on the tube's value (1): the tube shrinks
        // onto the middle line of samples at the isovalue, a
        // zero-thickness sheet that is removed.
        let (dims, v) = along(axis, 1000, 3, |t, a, b| line(t, a, b, &[1.0; 1000]));
        let u: Vec<i16> = v.iter().map(|&x| x as i16).collect();
        let vol = Volume::new(&u, dims_u64(dims));
        run(
            &format!("i16 tube iso 1 {dims:?}"),
            &vol,
            dims,
            1.0,
            CLOSED,
            &cfgs,
            &mut failures,
        );
    }
    report(failures);
}

/// Regression (was a bug of refinement with the Trilinear topology, from
/// 2026-11-23): in padded single cells whose magnitudes span six decades
/// (tiny positive corners in a field of -1), rule A1 at (0.01, 3) and rule
/// B at (0.01, 2) gave a closed, consistently oriented mesh whose enclosed
/// volume was negative (down to -0.13 cell volumes while the inside set is
/// ~1e-6): refined points landed far from the Marching Cubes patch and
/// the surface folded over itself, in a few of these 254 patterns (for
/// instance the 4x4x4 volume of -1 whose inner cell has VTK-order corner
/// values [1.1984390145765349e-5, 1.9055151805487956e-6,
/// -0.939794328404909, 2.447138897398763e-5, -0.004613839019859177,
/// -0.002197328390480045, -0.01203402196193081, -8.565772919685186e-5],
/// iso 0, A1, epsilon 0.01, max level 3). The inside region of such a cell
/// is a slab far thinner than epsilon and the Marching Cubes patch cuts
/// across the cell: a split point on a face edge moved along the face past
/// the patch's diagonal, or a gradient line crossed the slab to another
/// part of `S_K`. This draw of the patterns was found passing on
/// 2026-11-26, after the checks refined patches have gained since (which
/// one fixed it was not traced); the few cells that still fold are in
/// [`six_decade_cells_that_still_fold`].
#[test]
fn sign_patterns_with_magnitudes_over_six_decades() {
    let cfgs = quick_configs();
    let mut failures = Vec::new();
    let mut rng = Rng::new(2223);
    for pattern in 1u32..255 {
        let f = pattern_values(pattern, || rng.log_uniform(1e-6, 1.0));
        let name = format!("pattern {pattern:#010b} log {f:?}");
        let v = cell_volume(&f);
        let vol = Volume::new(&v, [2, 2, 2]);
        run(
            &name,
            &vol,
            [2, 2, 2],
            0.0,
            OPEN_MANIFOLD,
            &cfgs,
            &mut failures,
        );
        let padded = format!("padded {name}");
        run_padded(&padded, &f, CLOSED_MANIFOLD, &cfgs, &mut failures);
    }
    report(failures);
}

/// A mesh's shape, to compare meshes whose points may differ by rounding:
/// its triangles, components, Euler characteristic, edges in more than
/// two triangles and duplicate triangles.
fn shape_of(m: &Mesh) -> (usize, usize, i64, usize, usize) {
    let c = check_mesh(m);
    (
        m.triangles.len(),
        c.components,
        c.euler,
        c.nonmanifold_edges,
        c.duplicates,
    )
}

/// Every sign pattern of a cell (random magnitudes, and magnitudes 1 and
/// 2 with zeros) scaled by powers of two down to 2^-1000 and up to 2^1000:
/// the Marching Cubes mesh of the unscaled cell (as many triangles, as
/// many components, the same Euler characteristic, as many non-manifold
/// edges and duplicate triangles). The asymptotic decider and
/// the body saddles multiplied corner values: below about 1e-154 the
/// products underflowed to 0, every ambiguous face joined its inside
/// corners, and the Trilinear topology's mesh changed (a 5x5x5 volume of
/// values 1e-300 gave a triangle twice, once each way, where the same
/// volume times 1e300 gave a 2-manifold); the Classic topology's
/// refinement then found other cells' tables wrong.
#[test]
fn tiny_and_huge_magnitudes_give_the_topology_of_the_unscaled_data() {
    let mut failures = Vec::new();
    let mut rng = Rng::new(2224);
    let mut compared = 0;
    for pattern in 1u32..255 {
        for variant in 0..3 {
            let f = if variant < 2 {
                pattern_values(pattern, || rng.range(0.05, 1.0))
            } else {
                // Zeros on some inside corners (samples at the isovalue).
                let mut f = pattern_values(pattern, || [1.0, 2.0][rng.below(2) as usize]);
                for v in f.iter_mut() {
                    if *v > 0.0 && rng.bool() {
                        *v = 0.0;
                    }
                }
                f
            };
            let topology = Topology::Trilinear;
            let at = |s: f64| {
                let v: Vec<f64> = padded_cell(&f).iter().map(|x| x * s).collect();
                let vol = Volume::new(&v, [4, 4, 4]);
                // (Interior points are projections, which may round
                // otherwise: compared by the mesh's shape.)
                shape_of(&extract(&vol, 0.0, &mc_opts(topology)).unwrap())
            };
            let want = at(1.0);
            for e in [-1000, -600, -520, 520, 600, 1000] {
                if at(2f64.powi(e)) != want {
                    failures.push(format!("pattern {pattern:#010b} {f:?} x 2^{e}"));
                }
                compared += 1;
            }
        }
    }
    assert!(compared > 4000);
    report(failures);
}

/// Refinement of `f64` data of extreme magnitude: values past about 1e154
/// (or below about 1e-160) overflowed (underflowed) refinement's products,
/// every projection failed and the Marching Cubes triangles stayed; such a
/// volume is now refined on a copy scaled by a power of two, which gives
/// the mesh of the data at an ordinary scale, bit for bit (points and
/// triangles), on either topology.
#[test]
fn extreme_magnitudes_are_refined_like_ordinary_ones() {
    let n = 9usize;
    let v = grid_fn([n; 3], |x, y, z| {
        (0.9 * x).sin() + (0.7 * y).cos() * (0.4 * z).sin() - 0.3 * (1.1 * z).cos()
    });
    let mut failures = Vec::new();
    for topology in [Topology::Trilinear, Topology::Classic] {
        for rule in [Rule::A1, Rule::B] {
            let opts = Options {
                epsilon: 0.01,
                max_level: 3,
                rule,
                topology,
                ..Options::default()
            };
            let at = |e: i32| {
                let s: Vec<f64> = v.iter().map(|x| x * 2f64.powi(e)).collect();
                extract(&Volume::new(&s, [n as u64; 3]), 0.1 * 2f64.powi(e), &opts).unwrap()
            };
            // 2^0: not scaled; 2^-1: scaled to the same binade as 2^600.
            let plain = at(-1);
            assert!(
                plain.stats.output_triangles > plain.stats.mc_triangles,
                "{topology:?} {rule:?}: not refined at an ordinary scale"
            );
            for e in [-1000, -600, 600, 1000, 0] {
                let m = at(e);
                let same = m.triangles == plain.triangles
                    && m.points.len() == plain.points.len()
                    && m.points
                        .iter()
                        .zip(&plain.points)
                        .all(|(a, b)| (0..3).all(|c| a[c].to_bits() == b[c].to_bits()));
                if !same {
                    failures.push(format!(
                        "{topology:?} {rule:?} x 2^{e}: {} triangles ({} MC, {} projection failures), want {}",
                        m.stats.output_triangles,
                        m.stats.mc_triangles,
                        m.stats.projection_failures,
                        plain.stats.output_triangles
                    ));
                }
            }
        }
    }
    // The first run stops at the first extreme cell and the extraction is
    // redone on the copy: the progress reported never goes back, and a stop
    // asked during the first run is honoured.
    let s: Vec<f64> = v.iter().map(|x| x * 2f64.powi(600)).collect();
    let vol = Volume::new(&s, [n as u64; 3]);
    let mut seen = Vec::new();
    let mut record = |f: f64| {
        seen.push(f);
        ControlFlow::Continue(())
    };
    extract_with_progress(&vol, 0.0, &Options::default(), &mut record).unwrap();
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
    assert_eq!(seen.last(), Some(&1.0));
    let mut stop = |_: f64| ControlFlow::Break(());
    assert!(matches!(
        extract_with_progress(&vol, 0.0, &Options::default(), &mut stop),
        Err(precisemc::Error::Aborted)
    ));
    report(failures);
}

/// Samples (and isovalues) up to +-f64::MAX: the difference of two
/// values of opposite signs beyond half of it overflows. Where only the
/// denominator of an edge's crossing ratio overflowed, the ratio came out
/// 0 and the point sat on the grid point (the check caught only a NaN or
/// infinite ratio): crossings of several edges met there, and random
/// volumes of values times f64::MAX had edges in three or four triangles
/// (564 of 3600 meshes, both topologies); where a sample less the
/// isovalue overflowed, the trilinear topology dropped the cell. Each mesh
/// must have the shape of the same data and isovalue times 2^-8, and
/// refined ones (refined on a scaled copy, see
/// `extreme_magnitudes_are_refined_like_ordinary_ones`) no edge in more
/// than two triangles.
#[test]
fn samples_near_f64_max_give_the_mesh_of_the_scaled_data() {
    let mut failures = Vec::new();
    let mut rng = Rng::new(4711);
    let dims = [6usize, 5, 4];
    let n = dims[0] * dims[1] * dims[2];
    for round in 0..150 {
        let v: Vec<f64> = (0..n)
            .map(|_| {
                let m = rng.range(0.0, 1.0);
                if rng.bool() {
                    m
                } else {
                    -m
                }
            })
            .collect();
        // The isovalue 0, or half of the largest value (times the scale):
        // samples and isovalue of opposite signs then differ by more than
        // f64::MAX.
        let iso = [0.0, -0.5, 0.5][round % 3];
        for topology in [Topology::Trilinear, Topology::Classic] {
            let shape = |scale: f64, opts: &Options| {
                let s: Vec<f64> = v.iter().map(|x| x * scale).collect();
                let vol = Volume::new(&s, dims.map(|d| d as u64));
                shape_of(&extract(&vol, iso * scale, opts).unwrap())
            };
            let off = mc_opts(topology);
            let want = shape(2f64.powi(-8), &off);
            let got = shape(f64::MAX, &off);
            if got != want {
                failures.push(format!(
                    "round {round} {topology:?} off: {got:?}, want {want:?}"
                ));
            }
            let refined = Options {
                epsilon: 0.1,
                max_level: 3,
                topology,
                threads: 1,
                ..Options::default()
            };
            let (_, _, _, nonmanifold, duplicates) = shape(f64::MAX, &refined);
            if nonmanifold + duplicates > 0 {
                failures.push(format!(
                    "round {round} {topology:?} refined: {nonmanifold} edges in more than two triangles, {duplicates} duplicates"
                ));
            }
        }
    }
    report(failures);
}

/// BUG (refinement, Trilinear topology; open): the six-decade cells of
/// [`sign_patterns_with_magnitudes_over_six_decades`] that still fold.
/// Sixteen more draws of the 254 patterns (4064 padded cells, the six
/// configurations of `quick_configs` each, 2026-11-26) gave these four
/// closed, consistently oriented meshes with a negative enclosed volume:
/// one with rule A1 at (0.01, 3), -0.0016 cell volumes, and three with
/// rule B at (0.01, 2), -0.0065, -0.00087 and -0.38; every other
/// configuration of these cells, and every configuration of the other
/// 4060, encloses a positive volume. (The draws also gave a negative
/// volume of -6e-18 for plain Marching Cubes: rounding of a surface 1e-5
/// cells across summed about the origin; `signed_volume` now sums about a
/// point of the surface.)
///
/// What is known (2026-11-27): in the first three the inside region is a
/// sheet thinner than `FACE_BAND` along two or three faces, and the
/// Marching Cubes patch cuts straight across the cell. From the midpoint
/// of a diagonal (or a centre) the gradient, set by the large corner
/// values across the cell, meets the sheet at a slant, and the line
/// slides along it (0.71 cells in the A1 cell, where the nearest point of
/// `S_K` lies about 0.5 cells straight across) past the outline where the
/// triangle's face edges split, so the children fold over that outline
/// (the middle child of a 4-way split faces its parent at cosine -0.95).
/// Letting the nearest point decide for an interior sample whose line
/// ends in that band (retrying the cell the old way where the patch is
/// then unsound) mended those three, but not the fourth (a ring of sheets
/// along the faces, where refining the face edges alone folds it), and on
/// sixteen fresh draws (seeds 3000-3015) gave 9 negative volumes against
/// 7 without it; with every such line it also cost 7.5 % of the atoms
/// sample's refinement time. Not adopted.
#[test]
#[ignore = "bug: refinement folds the surface of a few tiny inside regions (negative enclosed volume)"]
fn six_decade_cells_that_still_fold() {
    let cells: [([f64; 8], Rule, u32); 4] = [
        (
            [
                2.395756182788412e-5,
                4.806082130591921e-6,
                1.42369329036778e-6,
                -0.5696246049080944,
                -0.3414630432776189,
                -6.823006378849875e-6,
                -6.818097112384749e-5,
                -0.00023371700381525384,
            ],
            Rule::A1,
            3,
        ),
        (
            [
                -0.5844893091638395,
                1.2196167471448446e-6,
                -0.260707781002923,
                0.00023050008643412236,
                2.727041677106737e-5,
                1.6642104428726323e-6,
                7.191609108721424e-5,
                1.0618179559916998e-6,
            ],
            Rule::B,
            2,
        ),
        (
            [
                0.0004552638131331494,
                -0.8880306485443248,
                0.00011202796645566661,
                5.842205837881773e-5,
                -0.2456003724672143,
                -0.1092240433778961,
                -7.549776203330828e-6,
                0.0002050366293367202,
            ],
            Rule::B,
            2,
        ),
        (
            [
                -3.289553696850793e-6,
                -0.18690829451026725,
                0.0013457272838687676,
                0.0002650875233664228,
                0.02938135966518216,
                0.00017091872049299162,
                5.835277224087686e-6,
                -0.1882265473318724,
            ],
            Rule::B,
            2,
        ),
    ];
    let mut failures = Vec::new();
    for (f, rule, level) in cells {
        let cfgs = vec![(
            format!("Trilinear {rule:?} 0.01/{level}"),
            refine_opts(precisemc::Topology::Trilinear, rule, 0.01, level),
        )];
        let name = format!("padded cell {f:?}");
        run_padded(&name, &f, CLOSED_MANIFOLD, &cfgs, &mut failures);
    }
    report(failures);
}

/// Regression (was a bug of rules A2 and B, which sample the centroid): one
/// generic cell (no sample, face saddle or interior critical value near
/// the isovalue: critical values 0.5 and -1.5) with VTK-order corner
/// values [-1, -3, -1, 1, 5, 3, -3, -1] gave non-manifold edges at max
/// level 2 with iso 1e-9, and pairs of duplicate triangles of opposite
/// orientation with iso exactly 0: the straight gradient lines of two
/// edges' midpoints meet on `S_K` at the cell centre, so two split points
/// coincide. Fixed by dropping children on repeated corners and by
/// refining unsound cells on their faces only (`src/refine.rs`). Same cell
/// as [1, 0, 1, 2, 4, 3, 0, 1] at iso 1.5, found in a random integer
/// field.
#[test]
fn centroid_rules_keep_a_generic_cell_manifold() {
    let f = [-1.0, -3.0, -1.0, 1.0, 5.0, 3.0, -3.0, -1.0];
    let mut failures = Vec::new();
    let v = cell_volume(&f);
    let vol = Volume::new(&v, [2, 2, 2]);
    let p = padded_cell(&f);
    let pvol = Volume::new(&p, [4, 4, 4]);
    let mut cfgs = Vec::new();
    for rule in [Rule::A2, Rule::B] {
        for level in 1..=3 {
            cfgs.push((
                format!("Trilinear {rule:?} 0.01/{level}"),
                refine_opts(precisemc::Topology::Trilinear, rule, 0.01, level),
            ));
        }
    }
    // The fix is exercised: some configurations here need the second,
    // faces-only attempt (the others are fixed by dropping children).
    let fallbacks: u64 = cfgs
        .iter()
        .map(|(_, o)| {
            extract(&pvol, 1e-9, o)
                .unwrap()
                .stats
                .cells_refined_on_faces_only
        })
        .sum();
    assert!(fallbacks > 0, "no cell was refined on its faces only");
    for iso in [0.0, 1e-9] {
        run(
            &format!("cell iso {iso}"),
            &vol,
            [2, 2, 2],
            iso,
            OPEN_MANIFOLD,
            &cfgs,
            &mut failures,
        );
        run(
            &format!("padded cell iso {iso}"),
            &pvol,
            [4, 4, 4],
            iso,
            CLOSED_MANIFOLD,
            &cfgs,
            &mut failures,
        );
    }
    report(failures);
}

/// An `f64` volume whose magnitudes span too many binary orders for one
/// exact scaling (a huge sample beside tiny ones) is contoured as it is.
/// The scaled copy made for its extreme cells rounded the tiny samples to
/// subnormals or -0, which counted as above an isovalue of 0 (the whole
/// surface vanished), and a piece of the volume holding the huge sample
/// put points on the layer it shares with its neighbour unlike that
/// neighbour. Plain Marching Cubes: a small bump's surface is the one it
/// has alone, bit for bit, whatever huge bump lies elsewhere, and two
/// pieces agree on their shared layer. Refined: the mesh stays a closed
/// manifold with the small bump's surface in it (one scale cannot suit
/// both bumps: see Limitations in the README).
#[test]
fn samples_spanning_too_many_magnitudes_are_not_rounded_by_a_scaled_copy() {
    let dims = [8usize, 4, 4];
    let idx = |i: usize, j: usize, k: usize| i + dims[0] * (j + dims[1] * k);
    let mut failures = Vec::new();
    for tiny in [1e-300, 1e-200, 1e-20, 1e-10] {
        for huge in [1e300, 1e200, 1e100] {
            let mut small_only = vec![-tiny; 128];
            // A small bump across x = 3 of values about `tiny`.
            for k in 1..3 {
                for j in 1..3 {
                    for i in 2..5 {
                        small_only[idx(i, j, k)] = (1.0 + 0.1 * (i + 2 * j + 3 * k) as f64) * tiny;
                    }
                }
            }
            let mut both = small_only.clone();
            both[idx(6, 2, 2)] = huge;
            for max_level in [0, 3] {
                let opts = Options {
                    threads: 1,
                    ..refine_opts(Topology::Trilinear, Rule::A1, 0.01, max_level)
                };
                let alone = extract(&Volume::new(&small_only, [8, 4, 4]), 0.0, &opts).unwrap();
                let whole = extract(&Volume::new(&both, [8, 4, 4]), 0.0, &opts).unwrap();
                let bits = |m: &Mesh| {
                    let mut p: Vec<[u64; 3]> = m
                        .index_points
                        .iter()
                        .filter(|p| p[0] < 5.0)
                        .map(|p| p.map(|c| (c + 0.0).to_bits()))
                        .collect();
                    p.sort_unstable();
                    p
                };
                let c = check_mesh(&whole);
                let same = max_level > 0 || bits(&alone) == bits(&whole);
                if alone.triangles.is_empty()
                    || bits(&whole).is_empty()
                    || !same
                    || !c.is_closed_oriented_manifold()
                {
                    failures.push(format!(
                        "tiny {tiny:e} huge {huge:e} level {max_level}: {} triangles alone, {} \
                         with the huge bump, same small bump {}, {c:?}",
                        alone.triangles.len(),
                        whole.triangles.len(),
                        bits(&alone) == bits(&whole)
                    ));
                }
                // Two pieces sharing the layer x = 3, the huge sample in
                // the upper one only.
                let s = [1i64, dims[0] as i64, (dims[0] * dims[1]) as i64];
                let lo = Volume::new(&both, [4, 4, 4]).with_strides(s);
                let hi = Volume::new(&both, [5, 4, 4])
                    .with_strides(s)
                    .with_offset(3)
                    .with_index_offset([3, 0, 0]);
                let layer = |m: &Mesh| {
                    let mut p: Vec<[u64; 3]> = m
                        .index_points
                        .iter()
                        .filter(|p| p[0] == 3.0)
                        .map(|p| p.map(|c| (c + 0.0).to_bits()))
                        .collect();
                    p.sort_unstable();
                    p
                };
                let (a, b) = (
                    extract(&lo, 0.0, &opts).unwrap(),
                    extract(&hi, 0.0, &opts).unwrap(),
                );
                if max_level == 0 && (layer(&a).is_empty() || layer(&a) != layer(&b)) {
                    failures.push(format!(
                        "tiny {tiny:e} huge {huge:e} level {max_level}: pieces' shared layer \
                         {} / {} points, equal {}",
                        layer(&a).len(),
                        layer(&b).len(),
                        layer(&a) == layer(&b)
                    ));
                }
            }
        }
    }
    report(failures);
}

/// Normals do not depend on the scale of the data. Samples near float64's
/// largest values overflowed the gradient's differences (1e308 - -1e308),
/// which left every normal (0, 0, 0); the direction is now the one of the
/// data at an ordinary scale, bit for bit, in both normal modes, refined
/// or not, from 2^-1000 to values whose differences pass f64::MAX.
/// Plain Marching Cubes and normals do not depend on the scale of the
/// data either: the mesh and normals of an `f64` volume times 2^e are
/// those at an ordinary scale, bit for bit, in both normal modes and
/// topologies, refined or not, from 2^-1000 to samples whose differences
/// pass f64::MAX. Before, samples beyond about 1e154 left an interior
/// vertex off its projection (its gradient's length overflowed: 0.12
/// cells away here), and near f64::MAX the gradients' differences
/// overflowed (half the normals (0, 0, 0)).
#[test]
fn plain_meshes_and_normals_do_not_depend_on_the_scale_of_the_data() {
    use precisemc::NormalMode;
    let n = 9usize;
    let v = grid_fn([n; 3], |x, y, z| {
        1.9 * (2.3 * x + 1.7 * y + 1.1 * z).sin() * (0.5 + 0.5 * (0.3 * y).cos())
    });
    // At 2^1023 the samples stay below f64::MAX but the differences
    // between neighbours of opposite signs overflow.
    let big = |x: f64| x * 2f64.powi(1023);
    assert!(v.iter().all(|x| big(*x).is_finite()));
    assert!(v.windows(2).any(|w| (big(w[1]) - big(w[0])).is_infinite()));
    let mut failures = Vec::new();
    let modes = [NormalMode::Gradient, NormalMode::CentralDifference];
    for (normals, topology) in modes
        .into_iter()
        .zip([Topology::Trilinear, Topology::Classic])
    {
        for max_level in [0, 3] {
            let opts = Options {
                epsilon: 0.01,
                max_level,
                normals,
                topology,
                ..Options::default()
            };
            let at = |e: i32| {
                let s: Vec<f64> = v.iter().map(|x| x * 2f64.powi(e)).collect();
                extract(&Volume::new(&s, [n as u64; 3]), 0.1 * 2f64.powi(e), &opts).unwrap()
            };
            let plain = at(0);
            assert!(plain.normals.len() == plain.points.len() && !plain.points.is_empty());
            assert!(plain.normals.iter().all(|m| m.iter().any(|c| *c != 0.0)));
            for e in [-1000, 600, 1000, 1023] {
                let m = at(e);
                let bits = |p: &[f32; 3]| p.map(f32::to_bits);
                let same_points = m.triangles == plain.triangles
                    && m.points.len() == plain.points.len()
                    && m.points
                        .iter()
                        .zip(&plain.points)
                        .all(|(a, b)| (0..3).all(|c| a[c].to_bits() == b[c].to_bits()));
                let same_normals = m
                    .normals
                    .iter()
                    .map(bits)
                    .eq(plain.normals.iter().map(bits));
                if !(same_points && same_normals) {
                    let zero = m
                        .normals
                        .iter()
                        .filter(|m| m.iter().all(|c| *c == 0.0))
                        .count();
                    failures.push(format!(
                        "{normals:?} {topology:?} level {max_level} x 2^{e}: same points and \
                         triangles {same_points}, same normals {same_normals} ({zero} of {} zero)",
                        m.normals.len()
                    ));
                }
            }
        }
    }
    report(failures);
}
