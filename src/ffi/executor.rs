//! `pmc_executor_fn`: a host's thread pool lent to `pmc_extract`.

use std::ffi::c_void;
use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::Executor;

/// One task of a batch handed to a `pmc_executor_fn`: call it with the
/// batch's `task_data` and an index below the batch's `count`. It returns
/// normally whatever happens inside (a failure is reported by
/// `pmc_extract`, not by the task); calls with an index out of range, or a
/// second call with the same index, do nothing.
pub type pmc_task_fn = unsafe extern "C" fn(task_data: *mut c_void, index: u64);

/// A host's executor (see `pmc_options_set_executor`): must call
/// `task(task_data, i)` once for every `i` in `[0, count)`, in any order,
/// on any threads, possibly at once, and return only once every call has
/// returned. Tasks never wait for each other, so running them one after
/// the other on the calling thread is correct too. It must not call `task`
/// after it has returned. `executor_data` is the pointer given to
/// `pmc_options_set_executor`. It is called only on the thread that called
/// `pmc_extract`, a few times per extraction (one batch per parallel
/// step). Like the progress callback, it must return normally: a C++
/// exception thrown out of it aborts the process (catch it inside; a
/// batch it did not finish is reported by `pmc_extract`).
///
/// A task refines cells recursively and needs about 48 KiB of stack at
/// the deepest settings (measured with max level 10, epsilon 1e-6, each
/// rule and reconstruction): run tasks on threads of at least 256 KiB,
/// as for the thread that calls `pmc_extract` (see there).
///
/// With VTK, for instance:
/// `vtkSMPTools::For(0, count, [&](vtkIdType b, vtkIdType e) { for (vtkIdType i = b; i < e; ++i) task(task_data, i); });`
pub type pmc_executor_fn = Option<
    unsafe extern "C" fn(
        executor_data: *mut c_void,
        count: u64,
        task: pmc_task_fn,
        task_data: *mut c_void,
    ),
>;

/// A `pmc_executor_fn` with its data and concurrency, as an [`Executor`].
#[derive(Clone, Copy)]
pub(crate) struct CExecutor {
    pub run: unsafe extern "C" fn(*mut c_void, u64, pmc_task_fn, *mut c_void),
    pub data: *mut c_void,
    pub concurrency: u32,
}

// SAFETY: the extraction calls `run` only from the thread that called
// `pmc_extract` (see `pmc_executor_fn`); the pointer is the caller's and
// only handed back to its own function.
unsafe impl Sync for CExecutor {}

/// Runs the task behind `task_data` (a `&&(dyn Fn(usize) + Sync)`).
unsafe extern "C" fn trampoline(task_data: *mut c_void, index: u64) {
    // SAFETY: `run` below passes a pointer to a live `&dyn Fn`, valid until
    // the executor returns, and the contract forbids calls after that.
    let task = unsafe { &*(task_data as *const &(dyn Fn(usize) + Sync)) };
    if let Ok(i) = usize::try_from(index) {
        // The extraction's tasks catch their own panics; this guard only
        // keeps an unwind from ever crossing into the host's C frames.
        let _ = catch_unwind(AssertUnwindSafe(|| task(i)));
    }
}

impl Executor for CExecutor {
    fn concurrency(&self) -> usize {
        self.concurrency as usize
    }

    fn run(&self, n: usize, task: &(dyn Fn(usize) + Sync)) {
        let task_data = &task as *const &(dyn Fn(usize) + Sync) as *mut c_void;
        // SAFETY: the host's function, called as its contract says; the
        // task data outlives the call.
        unsafe { (self.run)(self.data, n as u64, trampoline, task_data) }
    }
}
