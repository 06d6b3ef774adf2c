//! Test 9: progress, cancellation and the triangle cap.
//!
//! * The callback gets 0.0 first and 1.0 last, all values in [0, 1] and
//!   non-decreasing, also when the triangle cap makes the extraction run
//!   extra passes.
//! * `Break` at the first call, at a later call, or at the last call gives
//!   `Err(Error::Aborted)`.
//! * `max_triangles` is respected, `stats.budget_reached` is set, the
//!   effective level is reduced, and the capped mesh is still watertight.

mod common;

use std::ops::ControlFlow;

use common::*;
use precisemc::{extract, extract_with_progress, Error, Options, Rule, Topology, Volume};

/// A volume large enough for refinement to take well over 20 ms in a
/// debug build (so that intermediate progress is reported).
fn big() -> ([usize; 3], Vec<f64>) {
    let dims = [40, 40, 40];
    (dims, blobs(dims, 9, 40))
}

fn heavy_opts(threads: usize) -> Options {
    Options {
        threads,
        ..refine_opts(Topology::Trilinear, Rule::A1, 0.001, 5)
    }
}

fn record(vol: &Volume<'_>, opts: &Options) -> (Result<precisemc::Mesh, Error>, Vec<f64>) {
    let mut calls = Vec::new();
    let r = extract_with_progress(vol, 0.0, opts, &mut |p| {
        calls.push(p);
        ControlFlow::Continue(())
    });
    (r, calls)
}

fn assert_progress(calls: &[f64]) {
    assert!(calls.len() >= 2, "{calls:?}");
    assert_eq!(calls[0], 0.0, "{calls:?}");
    assert_eq!(*calls.last().unwrap(), 1.0, "{calls:?}");
    assert!(calls.iter().all(|p| (0.0..=1.0).contains(p)), "{calls:?}");
    assert!(
        calls.windows(2).all(|w| w[1] >= w[0]),
        "not monotone: {calls:?}"
    );
}

#[test]
fn progress_runs_from_zero_to_one() {
    let (dims, v) = big();
    let vol = Volume::new(&v, dims_u64(dims));
    let (r, calls) = record(&vol, &heavy_opts(2));
    assert!(r.is_ok());
    assert_progress(&calls);
    assert!(
        calls.len() > 2,
        "no intermediate progress reported: {calls:?}"
    );
    // Tiny volumes too.
    let small = sphere([4, 4, 4], [1.5, 1.5, 1.5], 1.0);
    let (r, calls) = record(&Volume::new(&small, [4, 4, 4]), &Options::default());
    assert!(r.is_ok());
    assert_progress(&calls);
}

#[test]
fn progress_is_monotone_when_the_cap_is_reached() {
    let (dims, v) = big();
    let vol = Volume::new(&v, dims_u64(dims));
    let full = extract(&vol, 0.0, &heavy_opts(2)).unwrap();
    // A cap most of the way through the first pass.
    let cap = full.triangles.len() as u64 * 9 / 10;
    let opts = Options {
        max_triangles: cap,
        ..heavy_opts(2)
    };
    let (r, calls) = record(&vol, &opts);
    let m = r.unwrap();
    assert!(m.stats.budget_reached);
    assert_progress(&calls);
}

/// A heavy extraction whose progress callback asks to stop at its second
/// call (during the work).
fn break_at_second_call(vol: &Volume<'_>) -> Result<precisemc::Mesh, Error> {
    let mut n = 0;
    extract_with_progress(vol, 0.0, &heavy_opts(2), &mut |_| {
        n += 1;
        if n >= 2 {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    })
}

#[test]
fn break_aborts() {
    let (dims, v) = big();
    let vol = Volume::new(&v, dims_u64(dims));
    // At the first call.
    let r = extract_with_progress(&vol, 0.0, &heavy_opts(2), &mut |_| ControlFlow::Break(()));
    assert_eq!(r, Err(Error::Aborted));
    // At the second call (during the work).
    assert_eq!(break_at_second_call(&vol), Err(Error::Aborted));
    // At the final 1.0.
    let small = sphere([6, 6, 6], [2.5, 2.5, 2.5], 2.0);
    let r = extract_with_progress(
        &Volume::new(&small, [6, 6, 6]),
        0.0,
        &Options::default(),
        &mut |p| {
            if p >= 1.0 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        },
    );
    assert_eq!(r, Err(Error::Aborted));
}

/// Cancelling during the work returns quickly (well before the full run).
#[test]
fn break_is_prompt() {
    let (dims, v) = big();
    let vol = Volume::new(&v, dims_u64(dims));
    let t = std::time::Instant::now();
    extract(&vol, 0.0, &heavy_opts(2)).unwrap();
    let full = t.elapsed();
    // The quickest of three cancelled runs: on a shared machine a single
    // run can be held up by other work.
    let mut cancelled = std::time::Duration::MAX;
    for _ in 0..3 {
        let t = std::time::Instant::now();
        assert_eq!(break_at_second_call(&vol), Err(Error::Aborted));
        cancelled = cancelled.min(t.elapsed());
    }
    assert!(
        cancelled < full,
        "cancel took {cancelled:?}, the full run {full:?}"
    );
}

/// A stop asked for while one cell refines deep (max level 10, where a
/// single cell of noise takes seconds to minutes) takes effect within that
/// cell: refinement reads the stop request every few thousand nodes. (It
/// was read before each row of cells only: 11.5 s after the stop on a 6^3
/// volume in a release build.)
#[test]
fn break_is_prompt_inside_a_deeply_refined_cell() {
    let dims = [6usize, 6, 6];
    let mut x = 1u64;
    let v: Vec<f64> = (0..dims.iter().product::<usize>())
        .map(|_| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        })
        .collect();
    let vol = Volume::new(&v, dims_u64(dims));
    for threads in [1, 2] {
        let opts = Options {
            epsilon: 1e-7,
            max_level: 10,
            threads,
            ..Options::default()
        };
        let mut calls = 0;
        let mut stopped = None;
        let r = extract_with_progress(&vol, 0.5, &opts, &mut |_| {
            calls += 1;
            if calls < 2 {
                return ControlFlow::Continue(());
            }
            stopped.get_or_insert_with(std::time::Instant::now);
            ControlFlow::Break(())
        });
        assert_eq!(r, Err(Error::Aborted));
        let after = stopped.expect("no second progress call").elapsed();
        assert!(
            after < std::time::Duration::from_secs(3),
            "{threads} threads: returned {after:?} after the stop"
        );
    }
}

#[test]
fn triangle_cap_is_respected_and_watertight() {
    let dims = [16, 16, 16];
    let v = blobs(dims, 4, 10);
    let vol = Volume::new(&v, dims_u64(dims));
    for topology in TOPOLOGIES {
        for rule in RULES {
            let opts = refine_opts(topology, rule, 0.0005, 6);
            let full = extract(&vol, 0.0, &opts).unwrap();
            assert!(!full.stats.budget_reached);
            let mc = full.stats.mc_triangles;
            for cap in [
                mc,
                mc + 1,
                (mc + full.stats.output_triangles) / 2,
                full.stats.output_triangles - 1,
            ] {
                let o = Options {
                    max_triangles: cap,
                    ..opts.clone()
                };
                let m = extract(&vol, 0.0, &o).unwrap();
                assert_sane(&m);
                assert!(
                    m.triangles.len() as u64 <= cap,
                    "{topology:?} {rule:?}: {} > cap {cap}",
                    m.triangles.len()
                );
                assert!(m.stats.budget_reached, "{topology:?} {rule:?} cap {cap}");
                assert!(m.stats.effective_max_level < 6);
                assert!(m
                    .levels
                    .iter()
                    .all(|&l| (l as u32) <= m.stats.effective_max_level));
                let c = check_mesh(&m);
                assert!(
                    c.is_closed_oriented_manifold(),
                    "{topology:?} {rule:?} cap {cap}: {c:?}"
                );
            }
            // A cap at or above the output changes nothing. (Cells meshed
            // again on sub-cells on both sides of a face can emit flat
            // triangles there that cancel in pairs when the mesh is
            // assembled; the cap counts them before, so allow for them.)
            let slack = if full.stats.cells_on_subcells > 0 {
                full.stats.output_triangles / 8
            } else {
                0
            };
            let o = Options {
                max_triangles: full.stats.output_triangles + slack,
                ..opts.clone()
            };
            let m = extract(&vol, 0.0, &o).unwrap();
            assert!(!m.stats.budget_reached);
            assert!(same_mesh(&m, &full));
        }
    }
    // A cap below the Marching Cubes count: refinement is off, the mesh is
    // the plain Marching Cubes mesh (the cap limits refinement only).
    let opts = refine_opts(Topology::Trilinear, Rule::A1, 0.001, 4);
    let mc = extract(&vol, 0.0, &mc_opts(Topology::Trilinear)).unwrap();
    let o = Options {
        max_triangles: 10,
        ..opts
    };
    let m = extract(&vol, 0.0, &o).unwrap();
    assert!(m.stats.budget_reached);
    assert_eq!(m.stats.effective_max_level, 0);
    assert_eq!(m.triangles.len(), mc.triangles.len());
}

/// The phase times are wall times that add up to at most the total, with
/// 1 and 2 threads (the slabs' per-thread times are scaled to the wall
/// time of the passes, so two threads do not count twice).
#[test]
fn phase_times_fit_in_the_total() {
    let (dims, v) = big();
    let vol = Volume::new(&v, dims_u64(dims));
    for threads in [1, 2] {
        let m = extract(&vol, 0.0, &heavy_opts(threads)).unwrap();
        let s = &m.stats;
        let parts = [s.time_mc, s.time_refine, s.time_assemble, s.time_normals];
        assert!(
            parts.iter().all(|t| *t >= 0.0),
            "{threads} threads: {parts:?}"
        );
        assert!(
            s.time_refine > 0.0,
            "{threads} threads: refinement not timed"
        );
        assert!(
            parts.iter().sum::<f64>() <= s.time_total * (1.0 + 1e-9),
            "{threads} threads: {parts:?} add up to more than {}",
            s.time_total
        );
    }
}

/// Noise on sample plane `k` within `[1, 1 + side)` in x and y (values in
/// [0, 1), isovalue 0.5), 1.0 elsewhere.
fn noise_planes(dims: [usize; 3], planes: &[(usize, usize)], seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let mut v = vec![1.0; dims[0] * dims[1] * dims[2]];
    for &(k, side) in planes {
        for j in 1..1 + side {
            for i in 1..1 + side {
                v[(k * dims[1] + j) * dims[0] + i] = rng.f64();
            }
        }
    }
    v
}

/// A stop asked for while a helper thread refines a slab and the calling
/// thread has no work left takes effect promptly: the calling thread keeps
/// reporting while it waits for the helpers. (It reported only between
/// its own cells: here, on 2 threads, the callback was not called for the
/// 13 s a helper refined the heavy slab, and the stop waited for it.)
#[test]
fn break_is_prompt_while_a_helper_finishes_a_slab() {
    // 16 slabs of 2 layers on 2 threads: layer 0 (noise on sample plane
    // 0, 3x3 samples) is the lighter, taken by the calling thread first;
    // layers 2 and 3 (noise on plane 3, 8x8 samples) are heavy, and
    // both in slab 1, which a helper takes meanwhile; the other slabs
    // have no surface.
    let dims = [12usize, 12, 33];
    let v = noise_planes(dims, &[(0, 3), (3, 8)], 5);
    let vol = Volume::new(&v, dims_u64(dims));
    let opts = Options {
        epsilon: 1e-7,
        max_level: 8,
        threads: 2,
        ..Options::default()
    };
    let start = std::time::Instant::now();
    // After the calling thread's slab 0 (0.6 s here), long before the
    // helper's slab 1 (13 s).
    let wish = std::time::Duration::from_secs(2);
    let mut last = start;
    let mut gap = std::time::Duration::ZERO;
    let r = extract_with_progress(&vol, 0.5, &opts, &mut |_| {
        let now = std::time::Instant::now();
        gap = gap.max(now - last);
        last = now;
        if now - start >= wish {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    });
    let took = start.elapsed();
    assert_eq!(r, Err(Error::Aborted));
    assert!(
        took < wish + std::time::Duration::from_secs(2),
        "returned {took:?} after the start, the stop asked for after {wish:?} (longest gap between calls {gap:?})"
    );
}

/// A cell of the benchmark's EPI scan where refinement stalls on a neck
/// of `S_K` (see tests/subcells.rs), corner values less the isovalue:
/// at epsilon 1e-5, max level 7 and rule B it is meshed again on
/// sub-cells, which takes most of the extraction's time (the nested
/// extraction and the outlines of a patch of some 10^5 triangles).
const FOLD: [f64; 8] = [
    -7.102, 20.898, -106.102, -87.102, 33.898, -77.102, -49.102, 161.898,
];

fn fold_opts() -> Options {
    Options {
        epsilon: 1e-5,
        max_level: 7,
        rule: Rule::B,
        threads: 1,
        ..Options::default()
    }
}

/// While a cell is meshed again on sub-cells, progress is reported as
/// during refinement, and a stop asked for then is honoured at once. (No
/// call was made while the cell was meshed again: on this cell, 0.9 s of
/// the 1.3 s of the extraction went by without one, on a 4^3 volume at
/// max level 10 more than 5 s.)
#[test]
fn progress_is_reported_while_a_cell_is_meshed_on_subcells() {
    let vol = Volume::new(&FOLD[..], [2, 2, 2]);
    let opts = fold_opts();
    let m = extract(&vol, 0.0, &opts).unwrap();
    assert_eq!(m.stats.cells_on_subcells, 1);
    // The longest time between two calls, against the whole run (up to the
    // call with 0.97: welding and normals make none), the best of three
    // runs (on a shared machine one run can be held up by other work).
    let mut best = f64::INFINITY;
    let mut total = f64::INFINITY;
    for _ in 0..3 {
        let start = std::time::Instant::now();
        let mut times = Vec::new();
        let r = extract_with_progress(&vol, 0.0, &opts, &mut |f| {
            if f < 0.97 {
                times.push(start.elapsed().as_secs_f64());
            }
            ControlFlow::Continue(())
        });
        let run = r.unwrap();
        assert_eq!(run.triangles, m.triangles, "progress changed the output");
        let gap = times.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
        let t = *times.last().unwrap();
        total = total.min(t);
        best = best.min(gap / t);
    }
    assert!(
        best < 0.25,
        "a gap of {:.0} % of the run between two progress calls",
        100.0 * best
    );
    // A stop asked for at the first call after 30 % of the quickest run
    // (about where the cell starts to be meshed again) ends the extraction
    // at once.
    let wish = 0.3 * total;
    let start = std::time::Instant::now();
    let mut asked = None;
    let r = extract_with_progress(&vol, 0.0, &opts, &mut |_| {
        let now = start.elapsed().as_secs_f64();
        if now < wish {
            return ControlFlow::Continue(());
        }
        asked.get_or_insert(now);
        ControlFlow::Break(())
    });
    let took = start.elapsed().as_secs_f64();
    assert_eq!(r, Err(Error::Aborted));
    let asked = asked.unwrap();
    assert!(
        took - asked < 0.5 * total,
        "stopped {asked:.3} s after the start, returned at {took:.3}, of {total:.3} s"
    );
}
