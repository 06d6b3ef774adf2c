//! Helper threads for short parallel steps: an [`Executor`] made of the
//! calling thread and `threads - 1` helpers.
//!
//! Plain Marching Cubes of a small volume takes a millisecond or two. A
//! rayon pool started for it (its threads spawned, the calling thread
//! parked while the work hops to them and back at every step) cost about
//! as much as the work it shared. Here the calling thread works too, next
//! to helpers that wait between steps, watching for the next one for
//! [`SPIN`] and then on a condition variable, and a step whose tasks the
//! caller has already taken does not wait for a helper to wake.
//!
//! Starting a thread costs about 0.2 ms on the shared virtual machines
//! this was measured on (spawn and join; waking a parked one, 0.01 ms), so
//! the helpers outlive a call: one process-wide crew serves one call at a
//! time (a call that finds it busy starts helpers of its own, joined
//! before it returns). A crew helper left idle for [`IDLE`] returns;
//! [`stop_crew`] (called by [`crate::release_retained_memory`], and on
//! Linux when the library is unloaded or the process exits) stops and
//! joins them all.

use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, TryLockError};
use std::time::Duration;

use crate::executor::Executor;
use crate::os_thread::OsThread;

/// How long a crew helper waits for work before it returns.
const IDLE: Duration = Duration::from_secs(1);

/// How long a helper with nothing to do watches for the next batch before
/// it parks, and the calling thread for the helpers to finish before it
/// waits on them (as OpenMP's and TBB's workers spin a while): waking a
/// parked thread takes 0.01 ms at the median on the shared virtual
/// machines and far longer now and then, as long as a small volume's step,
/// and calls through VTK come a little more than 0.1 ms apart. Through
/// VTK from Python, 2 threads, medians of 100 calls: the 48x48x20 tube
/// 0.122 ms with 0.3 ms, 0.156 with 0.1, 0.153 alone on the calling
/// thread; Marschner-Lobb 41^3 0.67, 0.66 and 0.91.
const SPIN: Duration = Duration::from_micros(300);

/// A batch's task with its lifetime erased; see [`Lease::run`] for why
/// the helpers never call it after the batch returned.
#[derive(Clone, Copy)]
struct Job {
    task: *const (dyn Fn(usize) + Sync + 'static),
    n: usize,
}

// SAFETY: the task is `Sync` (shared by reference between threads), and
// the pointer is dereferenced only while the batch that published it is
// still running (see `Lease::run`).
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
    /// How many helpers may join a batch (the call's threads less one).
    seats: usize,
    /// Helper threads started and not yet returned.
    alive: usize,
    /// Whether a call is using the crew (its helpers then stay).
    leased: bool,
    /// Set to make every helper return.
    stop: bool,
}

/// A set of helper threads, and the batch they work on.
struct Crew {
    /// How long a helper waits for work before it returns.
    idle: Duration,
    state: Mutex<State>,
    /// Signals a new batch (or the stop) to the helpers.
    wake: Condvar,
    /// Signals the calling thread that the last helper left a batch.
    done: Condvar,
    /// The next task index of the current batch not yet taken.
    next: AtomicUsize,
    /// `State::batch`, readable without the lock (a spinning helper
    /// watches it; bumped at the stop too).
    published: AtomicU64,
    /// `State::running`, readable without the lock (the calling thread
    /// watches it).
    busy: AtomicUsize,
    /// The helpers' threads, joined by [`Crew::stop`].
    handles: Mutex<Vec<OsThread>>,
}

impl Crew {
    fn new(idle: Duration) -> Self {
        Crew {
            idle,
            state: Mutex::default(),
            wake: Condvar::new(),
            done: Condvar::new(),
            next: AtomicUsize::new(0),
            published: AtomicU64::new(0),
            busy: AtomicUsize::new(0),
            handles: Mutex::default(),
        }
    }

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

    /// A helper's life: join the batches published while it has a seat,
    /// until the stop, or until it waited `idle` while no call used the
    /// crew.
    fn serve(&self, mut seen: u64) {
        loop {
            let job = {
                let mut s = self.lock();
                let mut spun = false;
                loop {
                    if s.stop {
                        s.alive -= 1;
                        return;
                    }
                    if s.batch != seen {
                        seen = s.batch;
                        if let Some(job) = s.job.filter(|_| s.running < s.seats) {
                            s.running += 1;
                            self.busy.store(s.running, Ordering::Relaxed);
                            break job;
                        }
                    }
                    if !spun {
                        // Watch for the next batch a little before
                        // parking (looked at again under the lock).
                        spun = true;
                        drop(s);
                        let t = std::time::Instant::now();
                        while self.published.load(Ordering::Acquire) == seen && t.elapsed() < SPIN {
                            std::hint::spin_loop();
                        }
                        s = self.lock();
                        continue;
                    }
                    let (g, wait) = self
                        .wake
                        .wait_timeout(s, self.idle)
                        .unwrap_or_else(|e| e.into_inner());
                    s = g;
                    if wait.timed_out() && !s.leased && s.batch == seen && !s.stop {
                        s.alive -= 1;
                        return;
                    }
                }
            };
            self.drain(job);
            let mut s = self.lock();
            s.running -= 1;
            self.busy.store(s.running, Ordering::Release);
            if s.running == 0 {
                self.done.notify_one();
            }
        }
    }

    /// Makes sure `helpers` helpers are alive (as many as can start) and
    /// marks the crew as used by a call with that many seats.
    fn lease(self: &Arc<Self>, helpers: usize) {
        let mut handles = self.handles.lock().unwrap_or_else(|e| e.into_inner());
        // Helpers that returned while idle, joined rather than detached:
        // past `serve` such a thread still runs this library's code for a
        // few instructions, and nothing else would wait for it before the
        // library is unloaded (`stop_crew` joins only the handles here).
        let mut i = 0;
        while i < handles.len() {
            if handles[i].is_finished() {
                handles.swap_remove(i).join();
            } else {
                i += 1;
            }
        }
        let mut s = self.lock();
        s.leased = true;
        s.seats = helpers;
        while s.alive < helpers {
            let (crew, seen) = (Arc::clone(self), s.batch);
            let started = if spawn_fails() {
                Err(std::io::Error::other("no threads (test)"))
            } else {
                // Not `std::thread`: a child forked while it started or
                // ended a thread could start none (see `os_thread`).
                OsThread::spawn("precisemc-help", move || crew.serve(seen))
            };
            match started {
                Ok(h) => {
                    handles.push(h);
                    s.alive += 1;
                }
                // A helper that cannot start leaves its share to the others.
                Err(_) => break,
            }
        }
    }

    /// Ends a call's use of the crew.
    fn release(&self) {
        let mut s = self.lock();
        s.leased = false;
        s.seats = 0;
    }

    /// Makes every helper return, and joins them.
    fn stop(&self) {
        self.lock().stop = true;
        self.published.fetch_add(1, Ordering::Release);
        self.wake.notify_all();
        let handles = std::mem::take(&mut *self.handles.lock().unwrap_or_else(|e| e.into_inner()));
        for h in handles {
            h.join();
        }
    }
}

/// The executor handed to the extraction: the calling thread plus the
/// crew's helpers, `threads` workers in all.
pub(crate) struct Lease<'a> {
    crew: &'a Crew,
    threads: usize,
}

impl Executor for Lease<'_> {
    fn concurrency(&self) -> usize {
        self.threads
    }

    fn run(&self, n: usize, task: &(dyn Fn(usize) + Sync)) {
        self.run_waiting(n, task, None);
    }
}

/// How often the calling thread, its share of a batch done, calls the
/// `waiting` hook of [`Lease::run_waiting`] while helpers finish theirs.
const WAITING_EVERY: Duration = Duration::from_millis(10);

impl Lease<'_> {
    /// [`Executor::run`], calling `waiting` on this thread about every
    /// [`WAITING_EVERY`] while it waits for helpers to finish their tasks
    /// (the extraction's progress report, which may ask to stop: a helper
    /// can take far longer over one slab than the calling thread over all
    /// of its own). `waiting` must not unwind: the helpers may still be
    /// running `task`.
    pub(crate) fn run_waiting(
        &self,
        n: usize,
        task: &(dyn Fn(usize) + Sync),
        waiting: Option<&dyn Fn()>,
    ) {
        if n == 0 {
            return;
        }
        let crew = self.crew;
        // SAFETY (of the erased lifetime): the batch is withdrawn below
        // before this call returns, and the call waits until every helper
        // that joined it has finished, so `task` is never called after it
        // is gone.
        let task: &(dyn Fn(usize) + Sync + 'static) = unsafe { std::mem::transmute(task) };
        let job = Job { task, n };
        crew.next.store(0, Ordering::Relaxed);
        if n > 1 {
            let mut s = crew.lock();
            s.job = Some(job);
            s.batch += 1;
            crew.published.store(s.batch, Ordering::Release);
            drop(s);
            crew.wake.notify_all();
        }
        crew.drain(job);
        let mut s = crew.lock();
        // Helpers that have not woken yet no longer join: every task is
        // taken (by this thread or by a helper that did join).
        s.job = None;
        if s.running > 0 {
            // Helpers still on their last tasks: watch for them to finish
            // a little before waiting (looked at again under the lock).
            drop(s);
            let t = std::time::Instant::now();
            while crew.busy.load(Ordering::Acquire) > 0 && t.elapsed() < SPIN {
                std::hint::spin_loop();
            }
            s = crew.lock();
        }
        while s.running > 0 {
            s = match waiting {
                None => crew.done.wait(s).unwrap_or_else(|e| e.into_inner()),
                Some(waiting) => {
                    let (g, wait) = crew
                        .done
                        .wait_timeout(s, WAITING_EVERY)
                        .unwrap_or_else(|e| e.into_inner());
                    if wait.timed_out() && g.running > 0 {
                        drop(g);
                        waiting();
                        crew.lock()
                    } else {
                        g
                    }
                }
            };
        }
    }
}

#[cfg(test)]
thread_local! {
    /// Makes this thread's calls start no helper (tests of the fallbacks).
    pub(crate) static SPAWN_FAILS: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Whether helpers fail to start on this thread (tests only).
fn spawn_fails() -> bool {
    #[cfg(test)]
    return SPAWN_FAILS.with(|f| f.get());
    #[cfg(not(test))]
    false
}

/// The process-wide crew, with the id of the process that started it (a
/// child made by `fork` has none of its threads: it starts its own).
static CREW: Mutex<Option<(u32, Arc<Crew>)>> = Mutex::new(None);

/// Runs `f` with an executor of `threads` workers: the calling thread and
/// `threads - 1` helpers, the process's crew when no other call is using
/// it, else helpers started now and joined before this returns. A helper that cannot be started
/// leaves its share to the others (the calling thread at least).
pub(crate) fn with_helpers<R>(threads: usize, f: impl FnOnce(&Lease<'_>) -> R) -> R {
    let threads = threads.max(1);
    let mut slot = match CREW.try_lock() {
        _ if spawn_fails() => None,
        Ok(g) => Some(g),
        Err(TryLockError::Poisoned(e)) => Some(e.into_inner()),
        Err(TryLockError::WouldBlock) => None,
    };
    let crew = match slot.as_deref_mut() {
        Some(slot) => {
            let pid = std::process::id();
            if slot.as_ref().map_or(true, |(p, _)| *p != pid) {
                *slot = Some((pid, Arc::new(Crew::new(IDLE))));
            }
            slot.as_ref().map(|(_, c)| Arc::clone(c))
        }
        None => None,
    };
    let own = crew.is_none();
    let crew = crew.unwrap_or_else(|| Arc::new(Crew::new(IDLE)));
    // Ends the lease (or stops the call's own helpers) however `f` leaves.
    struct End<'a>(&'a Crew, bool);
    impl Drop for End<'_> {
        fn drop(&mut self) {
            if self.1 {
                self.0.stop();
            } else {
                self.0.release();
            }
        }
    }
    crew.lease(threads - 1);
    let _end = End(&crew, own);
    let r = f(&Lease {
        crew: &crew,
        threads,
    });
    drop(_end);
    drop(slot);
    r
}

/// Stops and joins the process's crew of helpers, unless a call is using
/// it. The next call that needs helpers starts them again.
pub(crate) fn stop_crew() {
    // Not waiting for a call using the crew: this may be called from
    // that call's own progress callback. Its helpers return when idle.
    let crew = match CREW.try_lock() {
        Ok(mut g) => g.take(),
        Err(TryLockError::Poisoned(e)) => e.into_inner().take(),
        Err(TryLockError::WouldBlock) => None,
    };
    if let Some((pid, crew)) = crew {
        if pid == std::process::id() {
            crew.stop();
        }
    }
}

/// Stops the crew when the library is unloaded or the process exits, so
/// that no helper runs the library's code after it is gone. Skipped when
/// a call is using the crew then (a process exiting under a running
/// extraction: its threads end with it).
#[cfg(target_os = "linux")]
#[used]
#[link_section = ".fini_array"]
static STOP_AT_UNLOAD: extern "C" fn() = {
    extern "C" fn stop_at_unload() {
        stop_crew();
    }
    stop_at_unload
};

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;
    use std::sync::atomic::AtomicU64;
    use std::thread::ThreadId;

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

    /// Leases `threads - 1` helpers of `crew` for a batch whose tasks wait
    /// (up to 5 s) until `threads` threads have run one; returns the
    /// helpers' thread ids.
    fn busy_helpers(crew: &Arc<Crew>, threads: usize) -> HashSet<ThreadId> {
        let ids = Mutex::new(HashSet::new());
        let start = std::time::Instant::now();
        crew.lease(threads - 1);
        let lease = Lease { crew, threads };
        lease.run(4 * threads, &|_| {
            ids.lock().unwrap().insert(std::thread::current().id());
            while ids.lock().unwrap().len() < threads && start.elapsed().as_secs() < 5 {
                std::thread::sleep(Duration::from_millis(1));
            }
        });
        crew.release();
        let mut ids = ids.into_inner().unwrap();
        ids.remove(&std::thread::current().id());
        ids
    }

    #[test]
    fn a_crew_keeps_its_helpers_between_calls_until_stopped() {
        let crew = Arc::new(Crew::new(Duration::from_secs(600)));
        let first = busy_helpers(&crew, 3);
        let second = busy_helpers(&crew, 3);
        assert_eq!(first.len(), 2);
        assert_eq!(first, second);
        // A call asking for fewer workers seats fewer of them.
        assert_eq!(busy_helpers(&crew, 2).len(), 1);
        assert_eq!(crew.lock().alive, 2);
        crew.stop();
        assert_eq!(crew.lock().alive, 0);
        assert!(crew.handles.lock().unwrap().is_empty());
    }

    #[test]
    fn idle_helpers_return_and_others_start_for_the_next_call() {
        let crew = Arc::new(Crew::new(Duration::from_millis(20)));
        let first = busy_helpers(&crew, 2);
        assert_eq!(first.len(), 1);
        let start = std::time::Instant::now();
        while crew.lock().alive > 0 && start.elapsed().as_secs() < 5 {
            std::thread::sleep(Duration::from_millis(5));
        }
        assert_eq!(crew.lock().alive, 0);
        // Thread ids are never reused: a new thread ran the next batch.
        let second = busy_helpers(&crew, 2);
        assert_eq!(second.len(), 1);
        assert!(first.is_disjoint(&second));
        crew.stop();
        assert!(crew.handles.lock().unwrap().is_empty());
    }

    #[test]
    fn calls_at_once_each_get_helpers_and_run_every_task() {
        // Each call holds its helpers until the other has started (up to
        // 5 s): at most one has the crew, the other starts its own.
        let started = AtomicUsize::new(0);
        let start = std::time::Instant::now();
        std::thread::scope(|scope| {
            for _ in 0..2 {
                scope.spawn(|| {
                    with_helpers(2, |h| {
                        started.fetch_add(1, Ordering::SeqCst);
                        while started.load(Ordering::SeqCst) < 2 && start.elapsed().as_secs() < 5 {
                            std::thread::sleep(Duration::from_millis(1));
                        }
                        let counts: Vec<AtomicU64> = (0..500).map(|_| AtomicU64::new(0)).collect();
                        // Each task waits (up to 5 s) until two threads
                        // have run tasks of this call: a call left without
                        // a helper runs them all on one.
                        let threads = std::sync::Mutex::new(HashSet::new());
                        h.run(500, &|i| {
                            counts[i].fetch_add(1, Ordering::Relaxed);
                            threads.lock().unwrap().insert(std::thread::current().id());
                            while threads.lock().unwrap().len() < 2 && start.elapsed().as_secs() < 5
                            {
                                std::thread::sleep(Duration::from_millis(1));
                            }
                        });
                        assert!(counts.iter().all(|c| c.load(Ordering::Relaxed) == 1));
                        assert_eq!(
                            threads.lock().unwrap().len(),
                            2,
                            "a helper ran this call's tasks"
                        );
                    });
                });
            }
        });
        assert_eq!(started.load(Ordering::SeqCst), 2);
    }

    #[test]
    fn the_calling_thread_reports_while_it_waits_for_helpers() {
        // The calling thread's task waits (up to 5 s) until a helper has
        // started the other, which takes 300 ms: the calling thread waits
        // that long for it, calling `waiting` meanwhile, itself only.
        let crew = Arc::new(Crew::new(Duration::from_secs(600)));
        crew.lease(1);
        let lease = Lease {
            crew: &crew,
            threads: 2,
        };
        let caller = std::thread::current().id();
        let helper_started = std::sync::atomic::AtomicBool::new(false);
        let elsewhere = std::sync::atomic::AtomicBool::new(false);
        let calls = AtomicUsize::new(0);
        let start = std::time::Instant::now();
        lease.run_waiting(
            2,
            &|_| {
                if std::thread::current().id() != caller {
                    helper_started.store(true, Ordering::SeqCst);
                    std::thread::sleep(Duration::from_millis(300));
                }
                while !helper_started.load(Ordering::SeqCst) && start.elapsed().as_secs() < 5 {
                    std::thread::sleep(Duration::from_millis(1));
                }
            },
            Some(&|| {
                if std::thread::current().id() != caller {
                    elsewhere.store(true, Ordering::SeqCst);
                }
                calls.fetch_add(1, Ordering::SeqCst);
            }),
        );
        crew.release();
        crew.stop();
        assert!(helper_started.into_inner());
        assert!(!elsewhere.into_inner());
        // About 30 (every 10 ms of the 300), however loaded the machine.
        assert!(calls.into_inner() >= 3);
    }

    /// Batches of every size on crews of every size, helpers that return
    /// idle (after 0.2 ms) between and during leases, `stop_crew` all the
    /// while, and calls at once: every task runs once, nothing hangs.
    #[test]
    fn batches_survive_idle_returns_stops_and_calls_at_once() {
        let stop = std::sync::atomic::AtomicBool::new(false);
        std::thread::scope(|scope| {
            scope.spawn(|| {
                while !stop.load(Ordering::Relaxed) {
                    stop_crew();
                    std::thread::yield_now();
                }
            });
            let workers: Vec<_> = (0..3)
                .map(|t| {
                    let stop = &stop;
                    scope.spawn(move || {
                        let crew = Arc::new(Crew::new(Duration::from_micros(200)));
                        for round in 0..3000usize {
                            let threads = 1 + (round + t) % 4;
                            let check = |h: &Lease<'_>| {
                                for n in [2usize, 3, 7, 1, 33] {
                                    let counts: Vec<AtomicU64> =
                                        (0..n).map(|_| AtomicU64::new(0)).collect();
                                    h.run(n, &|i| {
                                        counts[i].fetch_add(1, Ordering::Relaxed);
                                    });
                                    assert!(counts.iter().all(|c| c.load(Ordering::Relaxed) == 1));
                                }
                            };
                            if t == 0 {
                                crew.lease(threads - 1);
                                check(&Lease {
                                    crew: &crew,
                                    threads,
                                });
                                crew.release();
                                if round % 7 == 0 {
                                    std::thread::sleep(Duration::from_micros(
                                        150 + (round % 5) as u64 * 20,
                                    ));
                                }
                            } else {
                                with_helpers(threads, check);
                            }
                        }
                        crew.stop();
                        let _ = stop;
                    })
                })
                .collect();
            for w in workers {
                w.join().unwrap();
            }
            stop.store(true, Ordering::Relaxed);
        });
    }
}
