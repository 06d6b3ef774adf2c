//! Test 5: determinism.
//!
//! * Bit-identical meshes (points, index points, triangles, levels,
//!   normals) for 1, 2 and 4 threads, and on a host's executor of any
//!   concurrency that runs the tasks in any order on any threads.
//! * A volume cut into two pieces that share one layer of samples (same
//!   buffer, `with_offset` + `with_index_offset`) gives bit-identical
//!   vertices on the shared layer from both pieces, and the union of the
//!   two pieces' triangles (as position triples with winding) is exactly
//!   the full run's, refined and unrefined, for cuts along z and along x.

mod common;

use common::*;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicUsize, Ordering};

use precisemc::{
    extract, extract_with_executor, Executor, Mesh, NormalMode, Options, Rule, SerialExecutor,
    Volume,
};

/// A host's pool: `threads` scoped threads (the calling thread among them)
/// take the tasks of a batch in a shuffled order; claims `concurrency`.
struct Shuffled {
    threads: usize,
    concurrency: usize,
    seed: u64,
}

impl Executor for Shuffled {
    fn concurrency(&self) -> usize {
        self.concurrency
    }
    fn run(&self, n: usize, task: &(dyn Fn(usize) + Sync)) {
        let mut order: Vec<usize> = (0..n).collect();
        let mut x = self.seed | 1;
        for i in (1..n).rev() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            order.swap(i, (x % (i as u64 + 1)) as usize);
        }
        let next = AtomicUsize::new(0);
        let work = || loop {
            let k = next.fetch_add(1, Ordering::Relaxed);
            if k >= n {
                break;
            }
            task(order[k]);
        };
        std::thread::scope(|s| {
            for _ in 1..self.threads {
                s.spawn(work);
            }
            work();
        });
    }
}

fn volumes() -> Vec<(&'static str, [usize; 3], Vec<f64>)> {
    vec![
        ("blobs", [14, 12, 16], blobs([14, 12, 16], 3, 9)),
        (
            "random",
            [8, 7, 9],
            random_interior([8, 7, 9], 4, -1.0, 1.0, -1.0),
        ),
        (
            "torus",
            [16, 16, 10],
            torus([16, 16, 10], [7.53, 7.48, 4.51], 4.5, 1.8),
        ),
    ]
}

fn configs() -> Vec<(String, Options)> {
    let mut v = Vec::new();
    for topology in TOPOLOGIES {
        v.push((format!("{topology:?} MC"), mc_opts(topology)));
        for rule in [Rule::A1, Rule::B] {
            v.push((
                format!("{topology:?} {rule:?}"),
                refine_opts(topology, rule, 0.005, 4),
            ));
        }
    }
    v
}

#[test]
fn identical_for_any_thread_count() {
    for (name, dims, values) in volumes() {
        let vol = Volume::new(&values, dims_u64(dims)).with_spacing([0.5, 1.0, 2.0]);
        for (cfg, opts) in configs() {
            let modes: &[NormalMode] = if cfg.ends_with("A1") {
                &[NormalMode::Gradient, NormalMode::CentralDifference]
            } else {
                &[NormalMode::None]
            };
            for &normals in modes {
                let run = |threads: usize| {
                    let o = Options {
                        threads,
                        normals,
                        ..opts.clone()
                    };
                    extract(&vol, 0.0, &o).unwrap()
                };
                let one = run(1);
                for t in [2, 4] {
                    let other = run(t);
                    assert!(
                        same_mesh(&one, &other),
                        "{name} {cfg} {normals:?}: {t} threads differ from 1"
                    );
                    // The public equality agrees: it ignores only the
                    // statistics' wall times, so the counters match too.
                    assert!(
                        one == other,
                        "{name} {cfg} {normals:?}: {t} threads: {:?} != {:?}",
                        one.stats,
                        other.stats
                    );
                }
                let o = Options {
                    normals,
                    ..opts.clone()
                };
                let lent = |ex: &dyn Executor| {
                    let mut go = |_| ControlFlow::Continue(());
                    extract_with_executor(&vol, 0.0, &o, ex, &mut go).unwrap()
                };
                assert!(
                    same_mesh(&one, &lent(&SerialExecutor)),
                    "{name} {cfg} {normals:?}: serial executor differs"
                );
                // A host may claim any concurrency, however large.
                for (threads, concurrency) in [
                    (1, 3),
                    (2, 2),
                    (3, 5),
                    (4, 1),
                    (2, 1 << 62),
                    (1, usize::MAX),
                ] {
                    let ex = Shuffled {
                        threads,
                        concurrency,
                        seed: 17 * threads as u64 + (concurrency % 1000) as u64,
                    };
                    let other = lent(&ex);
                    assert!(
                        same_mesh(&one, &other) && one == other,
                        "{name} {cfg} {normals:?}: executor of {threads} threads \
                         claiming {concurrency} differs"
                    );
                }
            }
        }
    }
}

/// `Ok(false)` when the cut does not meet the surface.
fn split_check(
    values: &[f64],
    dims: [usize; 3],
    axis: usize,
    cut: usize,
    opts: &Options,
) -> Result<bool, String> {
    let full = extract(&Volume::new(values, dims_u64(dims)), 0.0, opts).unwrap();
    let strides = [1usize, dims[0], dims[0] * dims[1]];
    let mut lo_dims = dims;
    lo_dims[axis] = cut + 1;
    let mut hi_dims = dims;
    hi_dims[axis] = dims[axis] - cut;
    let s = [strides[0] as i64, strides[1] as i64, strides[2] as i64];
    let lo = Volume::new(values, dims_u64(lo_dims)).with_strides(s);
    let mut off = [0i64; 3];
    off[axis] = cut as i64;
    let hi = Volume::new(values, dims_u64(hi_dims))
        .with_strides(s)
        .with_offset((cut * strides[axis]) as u64)
        .with_index_offset(off);
    let a = extract(&lo, 0.0, opts).map_err(|e| e.to_string())?;
    let b = extract(&hi, 0.0, opts).map_err(|e| e.to_string())?;
    // A cell meshed again on sub-cells next to the cut also has points in
    // the cut that only its own triangles use (its strips, flat in the
    // face, join them to the outline): then the pieces' open edges in the
    // cut, the outline both sides end on, must match instead.
    let remeshed = a.stats.cells_on_subcells + b.stats.cells_on_subcells > 0;
    let layer = |m: &Mesh| -> Vec<[u64; 3]> {
        let on_cut = |v: u64| m.index_points[v as usize][axis] == cut as f64;
        let on: Vec<[f64; 3]> = if remeshed {
            let mut uses = std::collections::HashMap::new();
            for t in &m.triangles {
                for e in 0..3 {
                    let (p, q) = (t[e], t[(e + 1) % 3]);
                    *uses.entry((p.min(q), p.max(q))).or_insert(0) += 1;
                }
            }
            let mut ends: Vec<u64> = uses
                .iter()
                .filter(|&(&(p, q), &n)| n == 1 && on_cut(p) && on_cut(q))
                .flat_map(|(&(p, q), _)| [p, q])
                .collect();
            ends.sort_unstable();
            ends.dedup();
            ends.iter().map(|&v| m.index_points[v as usize]).collect()
        } else {
            m.index_points
                .iter()
                .copied()
                .filter(|p| p[axis] == cut as f64)
                .collect()
        };
        canonical_points(&on)
    };
    let (la, lb) = (layer(&a), layer(&b));
    if la != lb {
        return Err(format!(
            "shared layer: {} vs {} points, or different bits",
            la.len(),
            lb.len()
        ));
    }
    if la.is_empty() {
        return Ok(false);
    }
    let mut union = canonical_triangles(&a.index_points, &a.triangles);
    union.extend(canonical_triangles(&b.index_points, &b.triangles));
    union.sort_unstable();
    if union != canonical_triangles(&full.index_points, &full.triangles) {
        return Err(format!(
            "union of pieces ({} + {} triangles) differs from the full run ({})",
            a.triangles.len(),
            b.triangles.len(),
            full.triangles.len()
        ));
    }
    if a.triangles.len() + b.triangles.len() != full.triangles.len() {
        return Err("triangle counts differ".into());
    }
    Ok(true)
}

#[test]
fn pieces_sharing_a_layer_match_the_full_volume() {
    let mut failures = Vec::new();
    let mut met = 0;
    for (name, dims, values) in volumes() {
        for (cfg, opts) in configs() {
            for (axis, cut) in [
                (2, dims[2] / 2 - 1),
                (0, dims[0] / 2 - 1),
                (1, dims[1] / 2 + 1),
            ] {
                match split_check(&values, dims, axis, cut, &opts) {
                    Ok(true) => met += 1,
                    Ok(false) => {}
                    Err(e) => failures.push(format!("{name} {cfg} axis {axis} cut {cut}: {e}")),
                }
            }
        }
    }
    assert!(met >= 40, "only {met} cuts met the surface");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Repeated runs are identical (no hidden state, no hash-order effects).
#[test]
fn repeated_runs_are_identical() {
    let (_, dims, values) = &volumes()[0];
    let vol = Volume::new(values, dims_u64(*dims));
    let opts = refine_opts(precisemc::Topology::Trilinear, Rule::A2, 0.003, 5);
    let a = extract(&vol, 0.0, &opts).unwrap();
    for _ in 0..3 {
        let b = extract(&vol, 0.0, &opts).unwrap();
        assert!(same_mesh(&a, &b));
        assert_eq!(a, b);
    }
}

/// At the largest accepted index offsets (±2^31 per axis, VTK's extents)
/// Marching Cubes gives the mesh of offset 0 moved by the offset, triangle
/// for triangle, its points within the rounding of global coordinates
/// there (2^-21 cells). Refined meshes are as close to the isosurface as
/// at offset 0, but not always the same triangles: index points are global
/// doubles, and a refinement decision near a tie can go the other way on
/// coordinates rounded to 2^-21 instead of 2^-49 (observed from offsets of
/// 2^24 up, at epsilon 1e-3 and with the defaults; from 2^40 up the
/// refinement degraded: a sphere's largest radius error tripled at 2^50).
#[test]
fn largest_index_offsets_move_the_mesh_of_offset_0() {
    let m = precisemc::MAX_INDEX_OFFSET;
    let offsets = [[m, -m, m], [-m, m, 7], [m, m, -m]];
    let mut named = volumes();
    named.push((
        "sphere",
        [12, 12, 12],
        grid_fn([12, 12, 12], |x, y, z| {
            ((x - 5.3).powi(2) + (y - 5.1).powi(2) + (z - 4.9).powi(2)).sqrt() - 4.0
        }),
    ));
    let measure_opts = precisemc::accuracy::MeasureOptions {
        density: 2,
        ..Default::default()
    };
    for (name, dims, values) in &named {
        let at = |off: [i64; 3], o: &Options| {
            let v = Volume::new(values, dims_u64(*dims)).with_index_offset(off);
            let mesh = extract(&v, 0.0, o).unwrap();
            let d = precisemc::accuracy::measure(
                &v,
                0.0,
                &mesh.index_points,
                &mesh.triangles,
                &measure_opts,
            )
            .unwrap();
            (mesh, d)
        };
        for topology in TOPOLOGIES {
            let o = mc_opts(topology);
            let (base, _) = at([0; 3], &o);
            for off in offsets {
                let (moved, _) = at(off, &o);
                assert_eq!(
                    moved.triangles, base.triangles,
                    "{name} {topology:?} {off:?}"
                );
                for (p, q) in base.index_points.iter().zip(&moved.index_points) {
                    for a in 0..3 {
                        let d = (q[a] - off[a] as f64 - p[a]).abs();
                        assert!(d <= 1.0 / (1u64 << 21) as f64, "{name} {off:?}: {d:e}");
                    }
                }
            }
        }
        for o in [
            Options::default(),
            refine_opts(precisemc::Topology::Trilinear, Rule::A1, 0.001, 5),
        ] {
            let (base, d0) = at([0; 3], &o);
            for off in offsets {
                let (moved, d) = at(off, &o);
                let n = moved.triangles.len() as f64 / base.triangles.len() as f64;
                assert!((0.95..1.05).contains(&n), "{name} {off:?}: {n}");
                // The mean is the same to within a few percent; the
                // maximum, one sample point, moves more with a changed
                // decision (15 % observed on the blobs).
                assert!(
                    d.max <= d0.max * 1.5 + 1e-3 && d.mean <= d0.mean * 1.05 + 1e-6,
                    "{name} {off:?}: max {} mean {} at offset 0, {} {} moved",
                    d0.max,
                    d0.mean,
                    d.max,
                    d.mean
                );
            }
        }
    }
}
