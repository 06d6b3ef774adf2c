//! Where the parallel steps of one extraction run: on an [`Executor`] (a
//! host's, or the helper threads of `crate::helpers` next to the calling
//! thread), or all on the calling thread. Whichever runs them, the steps
//! produce the same values in the same order, so the output does not
//! depend on the choice.

use std::any::Any;
use std::cell::{Cell, UnsafeCell};
use std::mem::MaybeUninit;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::Mutex;
use std::thread::ThreadId;
use std::time::{Duration, Instant};

use crate::executor::Executor;
use crate::helpers::Lease;
use crate::Error;

/// The executor of an extraction's parallel steps.
#[derive(Clone, Copy)]
pub(crate) enum Exec<'p> {
    /// Every step on the calling thread, in order.
    Serial,
    /// Steps handed to an executor (the host's, or helper threads next to
    /// the calling thread), one task per item or chunk.
    External(&'p dyn Executor),
    /// Steps handed to the library's helper threads next to the calling
    /// thread: as [`Exec::External`], and the calling thread keeps calling
    /// [`Exec::map_polling`]'s `poll` while it waits for the helpers.
    Helpers(&'p Lease<'p>),
}

impl Exec<'_> {
    /// `f` of each item, in the items' order. Fails only on an external
    /// executor that left a task unrun.
    pub(crate) fn map<T, R, F>(self, items: Vec<T>, f: F) -> Result<Vec<R>, Error>
    where
        T: Send,
        R: Send,
        F: Fn(T) -> R + Sync + Send,
    {
        match self {
            Exec::Serial => Ok(items.into_iter().map(f).collect()),
            Exec::External(ex) => run_external(ex, items, &f, None),
            Exec::Helpers(h) => Exec::External(h).map(items, f),
        }
    }

    /// [`Exec::map`], calling `poll` on the calling thread after each item
    /// it ran there (an external executor only: the others report progress
    /// their own way).
    pub(crate) fn map_polling<T, R, F>(
        self,
        items: Vec<T>,
        f: F,
        poll: &OnCaller<'_>,
    ) -> Result<Vec<R>, Error>
    where
        T: Send,
        R: Send,
        F: Fn(T) -> R + Sync + Send,
    {
        match self {
            Exec::External(ex) => run_external(ex, items, &f, Some(poll)),
            Exec::Helpers(h) => run_external(Runner::Helpers(h), items, &f, Some(poll)),
            Exec::Serial => self.map(items, f),
        }
    }

    /// Appends `f` of each element of `src` to `dst`, in order.
    pub(crate) fn extend<T, R, F>(self, dst: &mut Vec<R>, src: &[T], f: F) -> Result<(), Error>
    where
        T: Sync,
        R: Send,
        F: Fn(&T) -> R + Sync + Send,
    {
        match self {
            Exec::Helpers(h) => return Exec::External(h).extend(dst, src, f),
            Exec::Serial => dst.extend(src.iter().map(f)),
            Exec::External(ex) => {
                let len = chunk_len(src.len(), ex);
                fill_spare(ex, dst, src.len(), len, |out, start| {
                    for (w, x) in out.iter_mut().zip(&src[start..]) {
                        w.write(f(x));
                    }
                })?;
            }
        }
        Ok(())
    }
}

/// Items a task of an external executor gets in [`Exec::extend`]: a few
/// chunks a worker, none tiny.
fn chunk_len(n: usize, ex: &dyn Executor) -> usize {
    // The executor's figure is the host's: clamped as the slabs' is (a
    // huge one overflowed the product).
    let workers = ex.concurrency().clamp(1, crate::extract::MAX_THREADS);
    n.div_ceil(4 * workers).max(1 << 12)
}

/// Appends `n` values to `dst`, written by tasks of `ex` in chunks of
/// `len`: `write(chunk, start)` must initialise the whole chunk, which
/// begins at `start` of the `n`.
fn fill_spare<T: Send>(
    ex: &dyn Executor,
    dst: &mut Vec<T>,
    n: usize,
    len: usize,
    write: impl Fn(&mut [MaybeUninit<T>], usize) + Sync,
) -> Result<(), Error> {
    dst.try_reserve(n)
        .map_err(|_| Error::OutOfMemory(n.saturating_mul(std::mem::size_of::<T>())))?;
    let old = dst.len();
    let chunks: Vec<(usize, &mut [MaybeUninit<T>])> = dst.spare_capacity_mut()[..n]
        .chunks_mut(len)
        .enumerate()
        .map(|(c, out)| (c * len, out))
        .collect();
    run_external(ex, chunks, &|(start, out)| write(out, start), None)?;
    // SAFETY: every chunk of the first `n` spare slots ran (`run_external`
    // returned Ok) and `write` initialised all of it.
    unsafe { dst.set_len(old + n) };
    Ok(())
}

/// A callback that only the thread that made it may call (the progress
/// reporter, which is not thread-safe, polled from tasks an external
/// executor happens to run on the calling thread).
pub(crate) struct OnCaller<'a> {
    owner: ThreadId,
    busy: Cell<bool>,
    f: UnsafeCell<&'a mut dyn FnMut()>,
    /// The least time between two calls of `f` (zero: every poll).
    every: Duration,
    /// When `f` was last called.
    last: Cell<Option<Instant>>,
}

// SAFETY: `busy` and `f` are touched only by `poll` on the owner thread
// (checked first), and `busy` keeps a nested call out, so no two accesses
// ever overlap or happen on two threads.
unsafe impl Sync for OnCaller<'_> {}

impl<'a> OnCaller<'a> {
    /// Wraps `f` for the current thread.
    #[cfg(test)]
    pub(crate) fn new(f: &'a mut dyn FnMut()) -> Self {
        Self::every(f, Duration::ZERO)
    }

    /// Wraps `f` for the current thread, to be called by
    /// [`OnCaller::poll_timed`] at most once every `every`.
    pub(crate) fn every(f: &'a mut dyn FnMut(), every: Duration) -> Self {
        OnCaller {
            owner: std::thread::current().id(),
            busy: Cell::new(false),
            f: UnsafeCell::new(f),
            every,
            last: Cell::new(None),
        }
    }

    /// Calls the callback if this is the thread that made it (and it is
    /// not already running); otherwise does nothing.
    pub(crate) fn poll(&self) {
        self.call(false);
    }

    /// [`OnCaller::poll`], unless the callback was called less than
    /// `every` ago (for polls from within a step, which may come often).
    pub(crate) fn poll_timed(&self) {
        self.call(true);
    }

    fn call(&self, timed: bool) {
        if std::thread::current().id() != self.owner || self.busy.get() {
            return;
        }
        if !self.every.is_zero() {
            let now = Instant::now();
            if timed && self.last.get().is_some_and(|t| now - t < self.every) {
                return;
            }
            self.last.set(Some(now));
        }
        self.busy.set(true);
        // SAFETY: on the owner thread and not re-entered (see above).
        unsafe { (*self.f.get())() };
        self.busy.set(false);
    }
}

/// What runs the tasks of [`run_external`].
#[derive(Clone, Copy)]
enum Runner<'e> {
    Any(&'e dyn Executor),
    Helpers(&'e Lease<'e>),
}

impl<'e> From<&'e dyn Executor> for Runner<'e> {
    fn from(ex: &'e dyn Executor) -> Self {
        Runner::Any(ex)
    }
}

/// One item's state in [`run_external`].
enum Slot<T, R> {
    Todo(T),
    Running,
    Done(R),
}

/// Runs `f` on every item through `ex` and returns the results in order.
/// A task's panic is caught in the task (it may run on a foreign thread,
/// or behind a C function) and raised again here, on the calling thread,
/// once the executor has returned.
fn run_external<'e, T: Send, R: Send>(
    ex: impl Into<Runner<'e>>,
    items: Vec<T>,
    f: &(dyn Fn(T) -> R + Sync),
    poll: Option<&OnCaller<'_>>,
) -> Result<Vec<R>, Error> {
    let total = items.len();
    if total == 0 {
        return Ok(Vec::new());
    }
    let slots: Vec<Mutex<Slot<T, R>>> = items
        .into_iter()
        .map(|t| Mutex::new(Slot::Todo(t)))
        .collect();
    let panicked: Mutex<Option<Box<dyn Any + Send>>> = Mutex::new(None);
    let task = |i: usize| {
        let Some(slot) = slots.get(i) else {
            return;
        };
        // No lock is held while `f` runs, so none is ever poisoned; the
        // guard is taken over anyway rather than trusted.
        let item = {
            let mut s = slot.lock().unwrap_or_else(|e| e.into_inner());
            match std::mem::replace(&mut *s, Slot::Running) {
                Slot::Todo(t) => t,
                other => {
                    *s = other;
                    return;
                }
            }
        };
        match catch_unwind(AssertUnwindSafe(|| {
            let r = f(item);
            if let Some(p) = poll {
                p.poll();
            }
            r
        })) {
            Ok(r) => *slot.lock().unwrap_or_else(|e| e.into_inner()) = Slot::Done(r),
            Err(payload) => {
                panicked
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .get_or_insert(payload);
            }
        }
    };
    match (ex.into(), poll) {
        // The calling thread reports while it waits for the helpers too
        // (a helper's slab can take seconds after this thread ran out of
        // work). The report must not unwind while helpers run `task`.
        (Runner::Helpers(h), Some(p)) => {
            let waiting = || {
                if let Err(payload) = catch_unwind(AssertUnwindSafe(|| p.poll_timed())) {
                    panicked
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .get_or_insert(payload);
                }
            };
            h.run_waiting(total, &task, Some(&waiting));
        }
        (Runner::Helpers(h), None) => h.run(total, &task),
        (Runner::Any(ex), _) => ex.run(total, &task),
    }
    if let Some(payload) = panicked.into_inner().unwrap_or_else(|e| e.into_inner()) {
        resume_unwind(payload);
    }
    let mut out = Vec::with_capacity(total);
    let mut ran = 0;
    for s in slots {
        if let Slot::Done(r) = s.into_inner().unwrap_or_else(|e| e.into_inner()) {
            out.push(r);
            ran += 1;
        }
    }
    if ran < total {
        return Err(Error::Executor { ran, total });
    }
    Ok(out)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    #[test]
    fn every_executor_gives_the_same_values_in_order() {
        let src: Vec<u64> = (0..10_000).map(|i| i * 7919 % 10_007).collect();
        let mut out = Vec::new();
        let ex = Scrambled {
            threads: 3,
            seed: 7,
        };
        crate::helpers::with_helpers(3, |helpers| {
            for exec in [Exec::Serial, Exec::External(helpers), Exec::External(&ex)] {
                let mapped = exec.map(src.clone(), |x| x * x + 1).unwrap();
                let mut extended = vec![5u64];
                exec.extend(&mut extended, &src, |&x| x ^ 0x55).unwrap();
                out.push((mapped, extended));
            }
        });
        assert_eq!(out[0], out[1]);
        assert_eq!(out[0], out[2]);
        assert_eq!(out[0].0[3], src[3] * src[3] + 1);
        assert_eq!(out[0].1.len(), 10_001);
        assert_eq!(out[0].1[1], src[0] ^ 0x55);
    }

    /// Runs the tasks on `threads` scoped threads in a shuffled order.
    pub(crate) struct Scrambled {
        pub threads: usize,
        pub seed: u64,
    }

    impl Executor for Scrambled {
        fn concurrency(&self) -> usize {
            self.threads
        }
        fn run(&self, n: usize, task: &(dyn Fn(usize) + Sync)) {
            let mut order: Vec<usize> = (0..n).collect();
            let mut rng = crate::test_rng::XorShift(self.seed | 1);
            for i in (1..n).rev() {
                order.swap(i, rng.below(i as u64 + 1) as usize);
            }
            let next = std::sync::atomic::AtomicUsize::new(0);
            std::thread::scope(|s| {
                for _ in 0..self.threads {
                    s.spawn(|| loop {
                        let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        if k >= n {
                            break;
                        }
                        task(order[k]);
                    });
                }
            });
        }
    }

    /// Calls the tasks of `0..n` given by `indices(n)`, in that order.
    struct Listed(fn(usize) -> Vec<usize>);

    impl Executor for Listed {
        fn concurrency(&self) -> usize {
            2
        }
        fn run(&self, n: usize, task: &(dyn Fn(usize) + Sync)) {
            for i in (self.0)(n) {
                task(i);
            }
        }
    }

    #[test]
    fn an_external_executor_must_run_every_task_once() {
        let items: Vec<u32> = (0..50).collect();
        // Each index twice, and indices out of range: results as usual.
        let twice = Listed(|n| (0..n).chain(0..n).chain([n, n + 7, usize::MAX]).collect());
        let got = Exec::External(&twice)
            .map(items.clone(), |x| x * 3)
            .unwrap();
        assert_eq!(got, items.iter().map(|x| x * 3).collect::<Vec<_>>());
        // An index never called: an error naming the count, not a panic.
        let skip = Listed(|n| (1..n).collect());
        assert_eq!(
            Exec::External(&skip).map(items.clone(), |x| x),
            Err(Error::Executor { ran: 49, total: 50 })
        );
        let none = Listed(|_| Vec::new());
        let mut dst = vec![1u32];
        assert!(Exec::External(&none)
            .extend(&mut dst, &items, |x| *x)
            .is_err());
        // No items: the executor is not needed.
        assert_eq!(
            Exec::External(&none).map(Vec::<u8>::new(), |x| x),
            Ok(vec![])
        );
    }

    #[test]
    fn a_task_panic_is_raised_on_the_calling_thread_after_the_batch() {
        let ex = Scrambled {
            threads: 2,
            seed: 3,
        };
        let ran = std::sync::atomic::AtomicUsize::new(0);
        let r = catch_unwind(AssertUnwindSafe(|| {
            Exec::External(&ex).map((0..20).collect(), |x: u32| {
                ran.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                assert!(x != 11, "item eleven");
                x
            })
        }));
        let payload = r.expect_err("the panic is raised again");
        let msg = payload
            .downcast_ref::<&str>()
            .map(|m| m.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        assert!(msg.contains("item eleven"), "{msg}");
        // Every task ran: one panic does not stop the others.
        assert_eq!(ran.into_inner(), 20);
    }

    #[test]
    fn polls_happen_only_on_the_calling_thread() {
        let ex = Scrambled {
            threads: 3,
            seed: 11,
        };
        let mut calls = 0;
        let mut count = || calls += 1;
        let poll = OnCaller::new(&mut count);
        let caller = std::thread::current().id();
        let on_caller = std::sync::atomic::AtomicUsize::new(0);
        let got = Exec::External(&ex)
            .map_polling(
                (0..200u32).collect(),
                |x| {
                    if std::thread::current().id() == caller {
                        on_caller.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    }
                    x + 1
                },
                &poll,
            )
            .unwrap();
        assert_eq!(got, (1..201).collect::<Vec<_>>());
        // The scoped threads are not the caller: no poll at all.
        assert_eq!(on_caller.into_inner(), 0);
        assert_eq!(calls, 0);
        // A serial executor runs everything on the caller: a poll a task.
        let mut calls = 0;
        let mut count = || calls += 1;
        let poll = OnCaller::new(&mut count);
        Exec::External(&crate::executor::SerialExecutor)
            .map_polling((0..9u32).collect(), |x| x, &poll)
            .unwrap();
        assert_eq!(calls, 9);
    }
}
