//! The library's threads (the helpers of the extraction and the distance
//! measure), started with `pthread_create` itself on Unix rather than
//! through `std::thread`.
//!
//! Why: `std::thread` records each thread it starts, and forgets it when
//! the thread ends, under a lock of the standard library's own (for its
//! stack overflow message). A process that forks while one of its threads
//! holds that lock leaves it held for good in the child, whose first
//! thread started through `std::thread` then waits on it forever: in
//! `tests/fork.rs`, where threads extract (starting and ending helpers)
//! while the test forks, about one child in 2 000 hung in starting its
//! helpers. A thread started here takes no lock at its start or end, so a
//! child can always start its own. Elsewhere, `std::thread`.

use std::io;

/// A started thread: join it, or drop it to let it end on its own.
pub(crate) struct OsThread {
    inner: imp::Inner,
}

impl OsThread {
    /// Starts a thread named `name` (at most 15 bytes, no NUL) that runs
    /// `main`; a panic in `main` ends the thread only.
    pub(crate) fn spawn(
        name: &'static str,
        main: impl FnOnce() + Send + 'static,
    ) -> io::Result<Self> {
        let main = move || {
            let _ = std::panic::catch_unwind(std::panic::AssertUnwindSafe(main));
        };
        Ok(OsThread {
            inner: imp::spawn(name, Box::new(main))?,
        })
    }

    /// Whether `main` has returned (the thread is ending or gone).
    pub(crate) fn is_finished(&self) -> bool {
        self.inner.is_finished()
    }

    /// Waits for the thread to end.
    pub(crate) fn join(self) {
        self.inner.join();
    }
}

#[cfg(unix)]
mod imp {
    use std::ffi::c_void;
    use std::io;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;

    type Main = Box<dyn FnOnce() + Send + 'static>;

    /// Stack of a helper (virtual memory only until used; `std::thread`
    /// gave them 2 MiB).
    const STACK: usize = 8 << 20;

    pub(super) struct Inner {
        id: libc::pthread_t,
        done: Arc<AtomicBool>,
        joined: bool,
        /// The process that started the thread: in a child made by `fork`
        /// the thread does not exist and its id means nothing (glibc gives
        /// its stack and descriptor to the child's next threads), so it is
        /// neither joined nor detached there.
        pid: libc::pid_t,
    }

    // SAFETY: a `pthread_t` is only an id (a pointer on musl), used by
    // whichever thread joins or drops the handle.
    unsafe impl Send for Inner {}
    unsafe impl Sync for Inner {}

    fn ours(pid: libc::pid_t) -> bool {
        // SAFETY: no preconditions.
        unsafe { libc::getpid() == pid }
    }

    extern "C" fn start(arg: *mut c_void) -> *mut c_void {
        // SAFETY: `arg` is the box that `spawn` leaked for this thread
        // alone.
        let main = unsafe { Box::from_raw(arg.cast::<Main>()) };
        // `main` catches its own panics (`OsThread::spawn`): nothing
        // unwinds out of this function.
        main();
        std::ptr::null_mut()
    }

    pub(super) fn spawn(name: &'static str, main: Main) -> io::Result<Inner> {
        let done = Arc::new(AtomicBool::new(false));
        let flag = Arc::clone(&done);
        let main: Main = Box::new(move || {
            main();
            flag.store(true, Ordering::Release);
        });
        let arg = Box::into_raw(Box::new(main));
        let mut id = std::mem::MaybeUninit::<libc::pthread_t>::uninit();
        // SAFETY: plain calls on a local attribute object, initialised
        // before use and destroyed after; `start` takes over `arg` when
        // the thread starts, and it is freed here when it does not.
        unsafe {
            let mut attr = std::mem::MaybeUninit::<libc::pthread_attr_t>::uninit();
            let r = libc::pthread_attr_init(attr.as_mut_ptr());
            if r != 0 {
                drop(Box::from_raw(arg));
                return Err(io::Error::from_raw_os_error(r));
            }
            let mut attr = attr.assume_init();
            libc::pthread_attr_setstacksize(&mut attr, STACK);
            let r = libc::pthread_create(id.as_mut_ptr(), &attr, start, arg.cast());
            libc::pthread_attr_destroy(&mut attr);
            if r != 0 {
                drop(Box::from_raw(arg));
                return Err(io::Error::from_raw_os_error(r));
            }
            #[cfg(target_os = "linux")]
            {
                let mut buf = [0u8; 16];
                let n = name.len().min(15);
                buf[..n].copy_from_slice(&name.as_bytes()[..n]);
                libc::pthread_setname_np(id.assume_init(), buf.as_ptr().cast());
            }
        }
        #[cfg(not(target_os = "linux"))]
        let _ = name;
        Ok(Inner {
            // SAFETY: `pthread_create` succeeded and set it.
            id: unsafe { id.assume_init() },
            done,
            joined: false,
            // SAFETY: no preconditions.
            pid: unsafe { libc::getpid() },
        })
    }

    impl Inner {
        pub(super) fn is_finished(&self) -> bool {
            self.done.load(Ordering::Acquire)
        }

        pub(super) fn join(mut self) {
            self.joined = true;
            if !ours(self.pid) {
                return;
            }
            // SAFETY: a thread of ours, neither joined nor detached yet.
            unsafe {
                libc::pthread_join(self.id, std::ptr::null_mut());
            }
        }
    }

    impl Drop for Inner {
        fn drop(&mut self) {
            if !self.joined && ours(self.pid) {
                // SAFETY: as in `join`; the thread then ends on its own.
                unsafe {
                    libc::pthread_detach(self.id);
                }
            }
        }
    }
}

#[cfg(not(unix))]
mod imp {
    use std::io;

    pub(super) struct Inner(std::thread::JoinHandle<()>);

    pub(super) fn spawn(name: &'static str, main: Box<dyn FnOnce() + Send>) -> io::Result<Inner> {
        std::thread::Builder::new()
            .name(name.into())
            .spawn(main)
            .map(Inner)
    }

    impl Inner {
        pub(super) fn is_finished(&self) -> bool {
            self.0.is_finished()
        }

        pub(super) fn join(self) {
            let _ = self.0.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::Arc;

    #[test]
    fn threads_run_their_work_and_survive_its_panics() {
        let runs = Arc::new(AtomicUsize::new(0));
        let threads: Vec<OsThread> = (0..8)
            .map(|i| {
                let runs = Arc::clone(&runs);
                OsThread::spawn("pmc-test", move || {
                    runs.fetch_add(1, Ordering::Relaxed);
                    assert!(i % 2 == 0, "a panic ends this thread only");
                })
                .unwrap()
            })
            .collect();
        for t in threads {
            t.join();
        }
        assert_eq!(runs.load(Ordering::Relaxed), 8);
    }

    #[test]
    fn a_finished_thread_says_so_and_a_dropped_one_ends_on_its_own() {
        let t = OsThread::spawn("pmc-test", || {}).unwrap();
        let start = std::time::Instant::now();
        while !t.is_finished() {
            assert!(start.elapsed().as_secs() < 10, "the thread never finished");
            std::thread::yield_now();
        }
        drop(t);
        let gone = Arc::new(AtomicUsize::new(0));
        let g = Arc::clone(&gone);
        drop(
            OsThread::spawn("pmc-test", move || {
                g.fetch_add(1, Ordering::Relaxed);
            })
            .unwrap(),
        );
        while gone.load(Ordering::Relaxed) == 0 {
            assert!(
                start.elapsed().as_secs() < 10,
                "the detached thread never ran"
            );
            std::thread::yield_now();
        }
    }

    /// The process's virtual memory size (KiB).
    fn vm_size_kib() -> u64 {
        let status = std::fs::read_to_string("/proc/self/status").unwrap();
        let line = status.lines().find(|l| l.starts_with("VmSize:")).unwrap();
        line.split_whitespace().nth(1).unwrap().parse().unwrap()
    }

    /// Run alone in a process of its own by
    /// `dropped_threads_give_back_their_stacks` (other tests' memory would
    /// blur the count).
    #[test]
    #[ignore = "run in a process of its own by dropped_threads_give_back_their_stacks"]
    fn dropped_threads_give_back_their_stacks_alone() {
        // A finished thread whose handle is dropped (detached) gives its
        // stack back (glibc keeps a few for reuse); one never detached
        // keeps its stack mapped for ever: 64 of them, 512 MiB.
        let start = std::time::Instant::now();
        let mut before = 0;
        for i in 0..65 {
            let t = OsThread::spawn("pmc-test", || {}).unwrap();
            while !t.is_finished() {
                assert!(start.elapsed().as_secs() < 30, "a thread never finished");
                std::thread::yield_now();
            }
            drop(t);
            if i == 0 {
                before = vm_size_kib();
            }
        }
        let grown = vm_size_kib().saturating_sub(before);
        assert!(
            grown < 128 << 10,
            "64 dropped threads left {grown} KiB mapped"
        );
    }

    #[test]
    #[cfg(target_os = "linux")]
    fn dropped_threads_give_back_their_stacks() {
        let name = "os_thread::tests::dropped_threads_give_back_their_stacks_alone";
        let out = std::process::Command::new(std::env::current_exe().unwrap())
            .args(["--ignored", "--exact", name, "--test-threads=1"])
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && stdout.contains("1 passed"),
            "{stdout}\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
