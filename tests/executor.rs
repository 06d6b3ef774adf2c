//! A host's executor ([`precisemc::Executor`]): failures of the host's
//! pool become errors, never panics or partial meshes; progress and
//! stopping work as with the library's own threads.

mod common;

use std::ops::ControlFlow;

use common::*;
use precisemc::{extract, extract_with_executor, Error, Executor, Options, Topology, Volume};

/// Runs the tasks of `0..n` that `pick(n)` lists, in that order, on the
/// calling thread.
struct Picky {
    concurrency: usize,
    pick: fn(usize) -> Vec<usize>,
}

impl Executor for Picky {
    fn concurrency(&self) -> usize {
        self.concurrency
    }
    fn run(&self, n: usize, task: &(dyn Fn(usize) + Sync)) {
        for i in (self.pick)(n) {
            task(i);
        }
    }
}

fn settings() -> Vec<Options> {
    vec![
        Options::marching_cubes(Topology::Trilinear),
        refine_opts(Topology::Trilinear, precisemc::Rule::A1, 0.003, 4),
    ]
}

#[test]
fn an_executor_that_skips_tasks_fails_the_extraction_cleanly() {
    // Large enough for several slabs without refinement (small volumes run
    // on the calling thread, without the executor).
    let dims = [56, 52, 60];
    let values = blobs(dims, 5, 7);
    let vol = Volume::new(&values, dims_u64(dims));
    let skips: [fn(usize) -> Vec<usize>; 3] = [
        |_| Vec::new(),
        |n| (1..n).collect(),
        |n| (0..n.saturating_sub(1)).collect(),
    ];
    for opts in settings() {
        for pick in skips {
            let ex = Picky {
                concurrency: 4,
                pick,
            };
            let mut go = |_| ControlFlow::Continue(());
            match extract_with_executor(&vol, 0.0, &opts, &ex, &mut go) {
                Err(Error::Executor { ran, total }) => {
                    assert!(ran < total, "{ran} of {total}");
                    let msg = Error::Executor { ran, total }.to_string();
                    assert!(msg.contains("executor"), "{msg}");
                }
                other => panic!(
                    "expected an executor error, got {:?}",
                    other.map(|m| m.stats)
                ),
            }
        }
        // Repeated and out-of-range indices are ignored.
        let ex = Picky {
            concurrency: 3,
            pick: |n| {
                (0..n)
                    .rev()
                    .chain(0..n)
                    .chain([n, n + 1, usize::MAX])
                    .collect()
            },
        };
        let mut go = |_| ControlFlow::Continue(());
        let lent = extract_with_executor(&vol, 0.0, &opts, &ex, &mut go).unwrap();
        let own = extract(&vol, 0.0, &opts).unwrap();
        assert!(same_mesh(&own, &lent));
    }
}

#[test]
fn progress_and_stopping_on_a_lent_executor() {
    let dims = [30, 30, 30];
    let values = sphere(dims, [14.5, 14.3, 14.7], 11.0);
    let vol = Volume::new(&values, dims_u64(dims));
    let opts = refine_opts(Topology::Trilinear, precisemc::Rule::A1, 0.0005, 5);
    // Tasks on the calling thread: progress within them (at most every
    // 20 ms, the first time at once), rising to 1.
    let ex = Picky {
        concurrency: 2,
        pick: |n| (0..n).collect(),
    };
    let mut seen = Vec::new();
    let mut record = |f: f64| {
        seen.push(f);
        ControlFlow::Continue(())
    };
    extract_with_executor(&vol, 0.0, &opts, &ex, &mut record).unwrap();
    assert!(seen.len() >= 3, "{seen:?}");
    assert!(seen.windows(2).all(|w| w[0] <= w[1]), "{seen:?}");
    assert_eq!(seen.first(), Some(&0.0));
    assert_eq!(seen.last(), Some(&1.0));
    // Stopping at every call in turn, until a run completes first (how
    // many calls come in between depends on time): Aborted, and no call
    // after the stop. The first two calls (0 and the first from within a
    // task) always come.
    let mut aborted = 0;
    for stop in 1.. {
        let mut calls = 0;
        let mut halt = |_| {
            calls += 1;
            if calls >= stop {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        };
        match extract_with_executor(&vol, 0.0, &opts, &ex, &mut halt) {
            Err(Error::Aborted) => {
                assert_eq!(calls, stop);
                aborted += 1;
            }
            Ok(_) => {
                assert!(calls < stop, "stop at call {stop}, {calls} calls");
                break;
            }
            Err(e) => panic!("stop at call {stop}: {e}"),
        }
    }
    assert!(aborted >= 2, "{aborted}");
}
