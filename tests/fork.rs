//! A process that forks while other threads extract: the child must be able
//! to extract too (Python's `multiprocessing` forks by default on Linux, in
//! the middle of whatever a VTK pipeline's threads are doing).
//!
//! The library keeps process-wide state (buffers kept between calls, the
//! list of arrays handed to C callers, helper threads). A lock of that
//! state held by another thread at the moment of `fork` stays held forever
//! in the child, which has only the forking thread: its next extraction
//! waited on it for good (about one fork in 50 to 270 here before the
//! locks were taken around `fork`).

#![cfg(unix)]

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use precisemc::{extract, samples, Options, Rule};

/// Forks `rounds` times while three threads extract without pause (plain
/// and refined, so that buffers go to and from the kept bins all the time,
/// and through the C API, whose triangle arrays are handed out and freed);
/// each child extracts on one and two threads, and once through the C API,
/// and exits. Fails on a child that does not exit with 0 within 20 s.
/// (Without the locks taken around `fork` this failed within 15-350 forks,
/// on the kept bins; the list of handed-out arrays is held too briefly for
/// a few thousand forks to hit it.)
#[test]
fn a_child_forked_during_extractions_extracts() {
    let vol = Arc::new(samples::atoms(12));
    let stop = Arc::new(AtomicBool::new(false));
    let mut busy: Vec<_> = (0..2)
        .map(|k| {
            let (vol, stop) = (vol.clone(), stop.clone());
            std::thread::spawn(move || {
                let v = vol.volume();
                let refined = Options {
                    epsilon: 0.05,
                    rule: Rule::A1,
                    threads: 2,
                    ..Options::default()
                };
                let plain = Options {
                    threads: 2,
                    ..Options::marching_cubes(precisemc::Topology::Trilinear)
                };
                while !stop.load(Ordering::Relaxed) {
                    let o = if k == 0 { &plain } else { &refined };
                    let m = extract(&v, vol.isovalue, o).unwrap();
                    std::hint::black_box(m);
                    // The kept buffers and threads are let go now and then
                    // too (their locks are taken there as well).
                    if k == 1 {
                        precisemc::release_retained_memory();
                    }
                }
            })
        })
        .collect();
    // Through the C API too: triangle arrays handed to the caller and
    // freed (the list of handed-out arrays has a lock of its own).
    busy.push({
        let (vol, stop) = (vol.clone(), stop.clone());
        std::thread::spawn(move || c_api_until(&vol, &stop))
    });
    let rounds: usize = std::env::var("PMC_FORK_ROUNDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(500);
    let mut failed = None;
    for round in 0..rounds {
        // SAFETY: the child only extracts (allocating, starting threads:
        // glibc makes malloc usable after fork) and leaves with _exit.
        let pid = unsafe { libc::fork() };
        assert!(pid >= 0, "fork failed");
        if pid == 0 {
            let v = vol.volume();
            let mut ok = true;
            for threads in [1, 2] {
                for (epsilon, max_level) in [(0.0, 0), (0.05, 5)] {
                    let o = Options {
                        epsilon,
                        max_level,
                        threads,
                        ..Options::default()
                    };
                    ok &= extract(&v, vol.isovalue, &o).is_ok_and(|m| !m.triangles.is_empty());
                }
            }
            ok &= c_api_once(&vol);
            // SAFETY: leaves the child without running the parent's exit
            // handlers or the test harness.
            unsafe { libc::_exit(if ok { 0 } else { 1 }) };
        }
        let start = Instant::now();
        let status = loop {
            let mut status = 0;
            // SAFETY: waits for our own child.
            let r = unsafe { libc::waitpid(pid, &mut status, libc::WNOHANG) };
            if r == pid {
                break Some(status);
            }
            if start.elapsed() > Duration::from_secs(20) {
                // SAFETY: kills and reaps our own child.
                unsafe {
                    libc::kill(pid, libc::SIGKILL);
                    libc::waitpid(pid, &mut status, 0);
                }
                break None;
            }
            std::thread::sleep(Duration::from_millis(1));
        };
        match status {
            Some(s) if libc::WIFEXITED(s) && libc::WEXITSTATUS(s) == 0 => {}
            Some(s) => {
                failed = Some(format!("child {round} of {rounds} failed (status {s})"));
                break;
            }
            None => {
                failed = Some(format!("child {round} of {rounds} hung for 20 s"));
                break;
            }
        }
    }
    stop.store(true, Ordering::Relaxed);
    for t in busy {
        t.join().unwrap();
    }
    if let Some(f) = failed {
        panic!("{f}");
    }
}

/// Extracts through the C API until `stop` (see [`c_api_once`]).
fn c_api_until(vol: &samples::SampleVolume, stop: &AtomicBool) {
    while !stop.load(Ordering::Relaxed) {
        assert!(c_api_once(vol));
    }
}

/// Extracts through the C API, takes the mesh's triangles (handed out to
/// the caller) and frees them; whether all went well.
fn c_api_once(vol: &samples::SampleVolume) -> bool {
    use precisemc::ffi::*;
    let cv = pmc_volume {
        struct_size: std::mem::size_of::<pmc_volume>() as u64,
        data: vol.data.as_ptr().cast(),
        len: vol.data.len() as u64,
        scalar_type: PmcScalarType::F32 as pmc_scalar_type,
        dims: vol.dims,
        strides: [0; 3],
        origin: [0.0; 3],
        spacing: [1.0; 3],
    };
    let o = pmc_options_new();
    let mut m = std::ptr::null_mut();
    let mut n = 0u64;
    // SAFETY: a valid volume over `vol`'s samples, live options, and the
    // options, mesh and array released once each.
    unsafe {
        let ok = !o.is_null() && pmc_extract(&cv, vol.isovalue, o, &mut m) == PmcStatus::Ok;
        let tris = if ok {
            pmc_mesh_take_triangles(m, &mut n)
        } else {
            std::ptr::null_mut()
        };
        pmc_mesh_free(m);
        pmc_buffer_free(tris.cast());
        pmc_options_free(o);
        ok && n > 0 && !tris.is_null()
    }
}
