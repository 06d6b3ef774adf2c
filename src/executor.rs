//! Running an extraction's parallel steps on the host's threads.
//!
//! By default an extraction runs on the calling thread and the library's
//! own helper threads (`crate::helpers`: kept between calls, parked, each
//! returning after a second without work). A host that already keeps a
//! thread pool (VTK's
//! `vtkSMPTools`, TBB, OpenMP, a game engine's job system) can lend it
//! instead through an [`Executor`]: no thread is started per call, and
//! the extraction shares the cores with the host's other work the way the
//! host schedules it. The output does not depend on the executor.

/// A host's way of running a batch of independent tasks, possibly at once.
///
/// [`crate::extract_with_executor`] hands its parallel steps (one task per
/// slab of cell layers, or per chunk of points) to [`Executor::run`].
/// Tasks never block on each other, never start nested batches, and catch
/// their own panics, so any scheduling is correct, serial included.
pub trait Executor: Sync {
    /// How many tasks may run at once (the host's worker count, at least
    /// 1): the volume is cut for that many workers. `0` counts as 1, and a
    /// value above [`crate::MAX_THREADS`] as that limit. (The C API's
    /// `pmc_options_set_executor` refuses such values instead.)
    fn concurrency(&self) -> usize;

    /// Calls `task(i)` once for every `i` in `0..n`, in any order, on any
    /// threads, and returns when every call has returned. A task called
    /// twice or with an index out of range does nothing; an index never
    /// called makes the extraction fail with [`crate::Error::Executor`].
    fn run(&self, n: usize, task: &(dyn Fn(usize) + Sync));
}

/// Runs every task on the calling thread, in order: the same output as any
/// other executor, without parallelism (for tests and hosts without a
/// pool).
#[derive(Debug, Clone, Copy, Default)]
pub struct SerialExecutor;

impl Executor for SerialExecutor {
    fn concurrency(&self) -> usize {
        1
    }

    fn run(&self, n: usize, task: &(dyn Fn(usize) + Sync)) {
        (0..n).for_each(task);
    }
}
