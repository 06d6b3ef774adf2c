//! Keeping the library's process-wide locks usable in a child made by
//! `fork`.
//!
//! Why: the buffers kept between calls ([`crate::recycle`]) and the list
//! of arrays handed to C callers (`ffi::buffer`) sit behind process-wide
//! locks, each held for a few instructions at a time. A child made by
//! `fork` has only the thread that forked: a lock that another thread held
//! at that instant stays held in the child for good, and the child's next
//! extraction waited on it forever (Python's `multiprocessing` forks by
//! default on Linux, whatever the parent's threads are doing; one fork in
//! about 50 to 270 under steady extractions hung). Handlers registered
//! with `pthread_atfork` take every such lock just before `fork` and let
//! go of them just after, in the parent and in the child, so the child
//! starts with all of them free and the contents whole.
//!
//! The helper threads' crew ([`crate::helpers`]) is not among them: a call
//! holds it for its whole run, which may be the one forking (from a
//! progress callback). A child finds it either free, and starts a crew of
//! its own (the crew records its process id), or held, and starts helpers
//! for each call. (A child forked from a progress callback must not
//! return into that extraction: the helpers it waits for are not there.)
//! A lock the standard library takes as a `std::thread` starts or ends is
//! out of reach here: the helpers' threads are started without it
//! ([`crate::os_thread`]).

use std::any::Any;
use std::cell::RefCell;
use std::mem::ManuallyDrop;
use std::sync::atomic::{AtomicBool, Ordering};

thread_local! {
    /// The locks' guards, held by the forking thread from the `prepare`
    /// handler to the `parent` / `child` one, which empties it again.
    ///
    /// `ManuallyDrop`: a thread-local that needs dropping has its
    /// destructor registered with glibc (`__cxa_thread_atexit_impl`) on
    /// its first use by a thread, which (a) counts against this library's
    /// image until that thread exits, so a host that forked once from its
    /// main thread could never unmap the library with `dlclose` any more,
    /// and (b) takes the dynamic loader's lock inside `fork`, while glibc
    /// before 2.36 holds its fork-handler lock there, which `dlopen` and
    /// `dlclose` of other libraries take under the loader's lock. Nothing
    /// is left to drop: the handlers free the vector along with the guards.
    static HELD: RefCell<ManuallyDrop<Vec<Box<dyn Any>>>> =
        const { RefCell::new(ManuallyDrop::new(Vec::new())) };
}

/// Whether the handlers are registered (once per process).
static REGISTERED: AtomicBool = AtomicBool::new(false);

/// Registers the fork handlers unless done. Called when the library is
/// loaded (Linux, below) and, in case that did not run, before each use
/// of the locks it covers (one relaxed load when registered).
#[inline]
pub(crate) fn ensure_handlers() {
    if !REGISTERED.load(Ordering::Relaxed) {
        register();
    }
}

#[cold]
fn register() {
    if REGISTERED.swap(true, Ordering::AcqRel) {
        return;
    }
    #[cfg(unix)]
    // SAFETY: the handlers are plain functions that never unwind (below).
    // glibc ties the registration to this library's image and drops it
    // when the library is unloaded.
    unsafe {
        libc::pthread_atfork(Some(before_fork), Some(after_fork), Some(after_fork));
    }
}

/// Takes every covered lock (always in the same order; none is ever held
/// while taking another, so this cannot deadlock).
#[cfg_attr(not(unix), allow(dead_code))]
extern "C" fn before_fork() {
    let _ = std::panic::catch_unwind(|| {
        let _ = HELD.try_with(|held| {
            let mut held = held.borrow_mut();
            crate::recycle::hold_all(&mut held);
            crate::ffi::hold_all(&mut held);
        });
    });
}

/// Lets go of the locks taken by [`before_fork`].
#[cfg_attr(not(unix), allow(dead_code))]
extern "C" fn after_fork() {
    let _ = std::panic::catch_unwind(|| {
        let _ = HELD.try_with(|held| drop(std::mem::take(&mut **held.borrow_mut())));
    });
}

/// Registers the handlers when the library is loaded, before any thread
/// can take one of the locks (a later registration could miss a fork that
/// races with the first extraction).
#[cfg(target_os = "linux")]
#[used]
#[link_section = ".init_array"]
static REGISTER_AT_LOAD: extern "C" fn() = {
    extern "C" fn register_at_load() {
        ensure_handlers();
    }
    register_at_load
};
