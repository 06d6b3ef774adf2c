//! A child made by `fork` must not touch the parent's helper threads: their
//! thread ids mean nothing in the child (POSIX), and glibc hands their
//! stacks, thread descriptors included, to the child's next threads.

#![cfg(target_os = "linux")]

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use precisemc::{extract, samples, Options, Topology};

static GO: AtomicBool = AtomicBool::new(false);

extern "C" fn wait_for_go(_: *mut libc::c_void) -> *mut libc::c_void {
    while !GO.load(Ordering::Acquire) {
        std::thread::sleep(Duration::from_millis(1));
    }
    std::ptr::null_mut()
}

/// The parent's crew keeps the handle of a helper that returned idle; the
/// child's first call replaces the crew. The child's own thread, started
/// before that call on the stack glibc cached from that helper, must stay
/// joinable.
#[test]
fn a_child_does_not_detach_its_own_threads_through_the_parents_crew() {
    let vol = samples::atoms(40);
    let v = vol.volume();
    let o = Options {
        threads: 2,
        ..Options::marching_cubes(Topology::Trilinear)
    };
    assert!(!extract(&v, vol.isovalue, &o).unwrap().triangles.is_empty());
    // The helper returns after 1 s without work; its handle stays in the
    // crew until the next call.
    std::thread::sleep(Duration::from_millis(1500));
    // SAFETY: the child starts a thread, extracts, joins and `_exit`s.
    let pid = unsafe { libc::fork() };
    assert!(pid >= 0);
    if pid == 0 {
        let code = unsafe {
            let mut attr = std::mem::MaybeUninit::<libc::pthread_attr_t>::uninit();
            libc::pthread_attr_init(attr.as_mut_ptr());
            let mut attr = attr.assume_init();
            libc::pthread_attr_setstacksize(&mut attr, 8 << 20);
            let mut t: libc::pthread_t = 0;
            let r = libc::pthread_create(&mut t, &attr, wait_for_go, std::ptr::null_mut());
            libc::pthread_attr_destroy(&mut attr);
            if r != 0 {
                libc::_exit(3);
            }
            let ok = extract(&v, vol.isovalue, &o).is_ok();
            GO.store(true, Ordering::Release);
            let j = libc::pthread_join(t, std::ptr::null_mut());
            if !ok {
                2
            } else if j != 0 {
                // EINVAL: the thread was detached behind the child's back.
                100 + j
            } else {
                0
            }
        };
        unsafe { libc::_exit(code) };
    }
    let mut status = 0;
    // SAFETY: waits for our own child.
    unsafe { libc::waitpid(pid, &mut status, 0) };
    assert!(libc::WIFEXITED(status), "child died: status {status}");
    assert_eq!(libc::WEXITSTATUS(status), 0, "child exit code");
}
