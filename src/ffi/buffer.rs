//! Arrays moved out of a mesh to the caller (no copy), and their release.
//!
//! A Rust allocation can only be given back with its length and capacity,
//! which a C caller's free callback (such as VTK's `SetArrayFreeFunction`)
//! does not pass: the library keeps them here, by address, until
//! `pmc_buffer_free`.

use std::sync::Mutex;

use super::panic::value_boundary;

/// Address, length and capacity (in triangles) of each buffer handed out
/// and not yet freed. Few live at once, so a list serves.
static HANDED_OUT: Mutex<Vec<(usize, usize, usize)>> = Mutex::new(Vec::new());

/// Takes the list's lock until `held` is cleared (around `fork`, see
/// [`crate::fork`]).
pub(crate) fn hold(held: &mut Vec<Box<dyn std::any::Any>>) {
    held.push(Box::new(
        HANDED_OUT.lock().unwrap_or_else(|e| e.into_inner()),
    ));
}

/// Hands `v` over to the caller: its first element, or `NULL` when empty
/// (an empty vector is simply dropped).
pub(crate) fn hand_out(v: Vec<[u64; 3]>) -> *mut i64 {
    if v.is_empty() {
        return std::ptr::null_mut();
    }
    let mut v = std::mem::ManuallyDrop::new(v);
    let entry = (v.as_mut_ptr() as usize, v.len(), v.capacity());
    crate::fork::ensure_handlers();
    HANDED_OUT
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(entry);
    entry.0 as *mut i64
}

/// Releases an array obtained from `pmc_mesh_take_triangles`. `NULL` is
/// accepted and ignored, and so is an address this library did not hand
/// out. Releasing an array twice is the caller's error, which is caught
/// only while no later array was handed out at that address: released
/// arrays are kept for the next extraction, so the next
/// `pmc_mesh_take_triangles` may return the same address, and a late
/// second release would then free that new array under its owner.
/// Thread-safe. Its signature is that of a C
/// `free`, so that it can be given as the free function of an array that
/// adopts the buffer (VTK: `SetArray(..., VTK_DATA_ARRAY_USER_DEFINED)`
/// then `SetArrayFreeFunction(pmc_buffer_free)`).
///
/// # Safety
///
/// `buffer` must be `NULL` or not used after this call.
#[no_mangle]
pub unsafe extern "C" fn pmc_buffer_free(buffer: *mut std::ffi::c_void) {
    value_boundary((), || {
        if buffer.is_null() {
            return;
        }
        crate::fork::ensure_handlers();
        let entry = {
            let mut list = HANDED_OUT.lock().unwrap_or_else(|e| e.into_inner());
            let at = list.iter().position(|e| e.0 == buffer as usize);
            at.map(|i| list.swap_remove(i))
        };
        if let Some((ptr, len, cap)) = entry {
            // SAFETY: the entry was recorded by `hand_out` from a live
            // vector that was not dropped, and is removed here, once.
            let v = unsafe { Vec::from_raw_parts(ptr as *mut [u64; 3], len, cap) };
            // Kept for the next extraction (see `pmc_release_memory`).
            crate::recycle::MESH_TRIS.give(v);
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn handed_out_buffers_are_released_once() {
        let v: Vec<[u64; 3]> = (0..1000).map(|i| [i, i + 1, i + 2]).collect();
        let p = hand_out(v);
        // SAFETY: p points to 3000 readable values.
        assert_eq!(unsafe { *p.add(2999) }, 1001);
        let live = |p: *mut i64| HANDED_OUT.lock().unwrap().iter().any(|e| e.0 == p as usize);
        assert!(live(p));
        // SAFETY: p came from hand_out; unknown and repeated addresses are
        // ignored.
        unsafe {
            pmc_buffer_free(p.cast());
            pmc_buffer_free(p.cast());
            pmc_buffer_free(std::ptr::null_mut());
        }
        assert!(!live(p));
        assert!(hand_out(Vec::new()).is_null());
    }
}
