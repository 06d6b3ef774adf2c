//! Helper threads started for one call: an [`Executor`] for short
//! parallel steps.
//!
//! Plain Marching Cubes of a small volume takes a millisecond or two. A
//! rayon pool started for it (its threads spawned, the calling thread
//! parked while the work hops to them and back at every step) cost about
//! as much as the work it shared. Here the calling thread works too, next
//! to `threads - 1` helpers that wait between steps on a condition
//! variable, and a step whose tasks the caller has already taken does
//! not wait for a helper to wake. The helpers are scoped threads: all are
//! joined before [`with_helpers`] returns, so none outlives the call.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Condvar, Mutex, MutexGuard};

use crate::executor::Executor;

/// A batch's task with its lifetime erased; see [`Helpers::run`] for why
/// the helpers never call it after the batch returned.
#[derive(Clone, Copy)]
struct Job {
    task: *const (dyn Fn(usize) + Sync + 'static),
    n: usize,
}

// SAFETY: the task is `Sync` (shared by reference between threads), and
// the pointer is dereferenced only while the batch that published it is
// still running (see `Helpers::run`).
unsafe impl Send for Job {}

/// What the helpers and the calling thread share, under one lock.
#[derive(Default)]
struct State {
    /// The batch open to helpers, if any.
    job: Option<Job>,
    /// Counts batches, so that a helper joins each one at most once.
    batch: u64,
    /// Helpers working on the current batch.
    running: usize,
    /// Set when the call is over: the helpers return.
    stop: bool,
}

/// The executor handed to the extraction: the calling thread plus
/// `threads - 1` helpers.
pub(crate) struct Helpers {
    threads: usize,
    state: Mutex<State>,
    /// Signals a new batch (or the stop) to the helpers.
    wake: Condvar,
    /// Signals the calling thread that the last helper left a batch.
    done: Condvar,
    /// The next task index of the current batch not yet taken.
    next: AtomicUsize,
}

impl Helpers {
    fn lock(&self) -> MutexGuard<'_, State> {
        // Tasks never panic (the extraction catches their panics), so the
        // lock is never poisoned; the guard is taken over anyway.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Takes task indices of `job` until none is left.
    fn drain(&self, job: Job) {
        loop {
            let i = self.next.fetch_add(1, Ordering::Relaxed);
            if i >= job.n {
                break;
            }
            // SAFETY: `job` is the open batch's, whose `run` has not
            // returned: it waits for every helper that joined it.
            unsafe { (*job.task)(i) };
        }
    }

    /// A helper's life: join every batch published, until the stop.
    fn serve(&self) {
        let mut seen = 0;
        loop {
            let job = {
                let mut s = self.lock();
                loop {
                    if s.stop {
                        return;
                    }
                    if s.batch != seen {
                        seen = s.batch;
                        if let Some(job) = s.job {
                            s.running += 1;
                            break job;
                        }
                    }
                    s = self.wake.wait(s).unwrap_or_else(|e| e.into_inner());
                }
            };
            self.drain(job);
            let mut s = self.lock();
            s.running -= 1;
            if s.running == 0 {
                self.done.notify_one();
            }
        }
    }
}

impl Executor for Helpers {
    fn concurrency(&self) -> usize {
        self.threads
    }

    fn run(&self, n: usize, task: &(dyn Fn(usize) + Sync)) {
        if n == 0 {
            return;
        }
        // SAFETY (of the erased lifetime): the batch is withdrawn below
        // before this call returns, and the call waits until every helper
        // that joined it has finished, so `task` is never called after it
        // is gone.
        let task: &(dyn Fn(usize) + Sync + 'static) = unsafe { std::mem::transmute(task) };
        let job = Job { task, n };
        self.next.store(0, Ordering::Relaxed);
        if n > 1 {
            let mut s = self.lock();
            s.job = Some(job);
            s.batch += 1;
            drop(s);
            self.wake.notify_all();
        }
        self.drain(job);
        let mut s = self.lock();
        // Helpers that have not woken yet no longer join: every task is
        // taken (by this thread or by a helper that did join).
        s.job = None;
        while s.running > 0 {
            s = self.done.wait(s).unwrap_or_else(|e| e.into_inner());
        }
    }
}

/// Runs `f` with an executor of `threads` workers: the calling thread and
/// `threads - 1` helpers started now and joined before this returns. A
/// helper that cannot be started leaves its share to the others.
pub(crate) fn with_helpers<R>(threads: usize, f: impl FnOnce(&Helpers) -> R) -> R {
    let helpers = Helpers {
        threads: threads.max(1),
        state: Mutex::new(State::default()),
        wake: Condvar::new(),
        done: Condvar::new(),
        next: AtomicUsize::new(0),
    };
    std::thread::scope(|scope| {
        for _ in 1..helpers.threads {
            let h = &helpers;
            if std::thread::Builder::new()
                .name("precisemc-helper".into())
                .spawn_scoped(scope, move || h.serve())
                .is_err()
            {
                break;
            }
        }
        // Stops the helpers however `f` leaves (the scope then joins them;
        // a panic of `f` goes on up after that).
        struct Stop<'a>(&'a Helpers);
        impl Drop for Stop<'_> {
            fn drop(&mut self) {
                self.0.lock().stop = true;
                self.0.wake.notify_all();
            }
        }
        let _stop = Stop(&helpers);
        f(&helpers)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicU64;

    #[test]
    fn every_task_runs_once_in_every_batch() {
        for threads in [1, 2, 3, 8] {
            with_helpers(threads, |h| {
                assert_eq!(h.concurrency(), threads);
                for n in [0, 1, 2, 5, 64, 1000] {
                    let counts: Vec<AtomicU64> = (0..n).map(|_| AtomicU64::new(0)).collect();
                    h.run(n, &|i| {
                        counts[i].fetch_add(1, Ordering::Relaxed);
                    });
                    assert!(counts.iter().all(|c| c.load(Ordering::Relaxed) == 1));
                }
            });
        }
    }

    #[test]
    fn helpers_share_the_work_of_slow_tasks() {
        // Each task waits (up to 5 s, however loaded the machine) until a
        // second thread has run one: with 3 workers a helper joins.
        let ids = Mutex::new(std::collections::HashSet::new());
        let start = std::time::Instant::now();
        with_helpers(3, |h| {
            h.run(12, &|_| {
                ids.lock().unwrap().insert(std::thread::current().id());
                while ids.lock().unwrap().len() < 2 && start.elapsed().as_secs() < 5 {
                    std::thread::sleep(std::time::Duration::from_millis(1));
                }
            });
        });
        assert!(ids.into_inner().unwrap().len() > 1);
    }
}
