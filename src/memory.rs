//! Fallible allocation of the large output buffers, and the advice that
//! puts them on transparent huge pages.

use crate::Error;

/// Reserves room for `n` more elements (advised onto huge pages when
/// large), or reports the bytes missing.
pub(crate) fn reserve<T>(v: &mut Vec<T>, n: usize) -> Result<(), Error> {
    v.try_reserve_exact(n)
        .map_err(|_| Error::OutOfMemory(n.saturating_mul(std::mem::size_of::<T>())))?;
    advise_huge_pages(v);
    Ok(())
}

/// Asks the kernel for transparent huge pages behind a large buffer's
/// capacity (Linux, where THP is in `madvise` mode): writing fresh output
/// memory otherwise takes one page fault per 4 KiB, which cost a fifth of
/// an unrefined extraction's time. Advice only: nothing changes if the
/// kernel declines or THP is off. Set `PMC_NO_HUGE_PAGES=1` in the
/// environment to skip it (read once per process).
pub(crate) fn advise_huge_pages<T>(v: &mut Vec<T>) {
    #[cfg(target_os = "linux")]
    {
        use std::sync::atomic::{AtomicU8, Ordering};
        // 0 not read yet, 1 advise, 2 off. Not a `OnceLock`: a child
        // forked while another thread ran its initialiser would wait on
        // it forever; racing first readers store the same answer.
        static OFF: AtomicU8 = AtomicU8::new(0);
        let off = || {
            let mut state = OFF.load(Ordering::Relaxed);
            if state == 0 {
                let set = std::env::var_os("PMC_NO_HUGE_PAGES").is_some_and(|v| v != "0");
                state = if set { 2 } else { 1 };
                OFF.store(state, Ordering::Relaxed);
            }
            state == 2
        };
        const HUGE: usize = 2 << 20;
        let start = v.as_mut_ptr() as usize;
        let end = start + v.capacity() * std::mem::size_of::<T>();
        let (lo, hi) = (start.next_multiple_of(HUGE), end & !(HUGE - 1));
        if hi > lo && !off() {
            // SAFETY: [lo, hi) lies within the vector's allocation, which
            // it owns; MADV_HUGEPAGE changes no contents.
            unsafe {
                libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = v;
}
