//! The thread-local message of the last failure.

use std::cell::RefCell;
use std::ffi::c_char;

use super::panic::value_boundary;

thread_local! {
    static LAST_ERROR: RefCell<String> = const { RefCell::new(String::new()) };
}

/// Stores `message` as the calling thread's last error (NUL bytes are
/// replaced so that C sees the whole text).
pub(crate) fn set_last_error(message: &str) {
    // `try_with`: during thread teardown the slot may be gone; then the
    // message is dropped rather than panicking.
    let _ = LAST_ERROR.try_with(|slot| {
        if let Ok(mut s) = slot.try_borrow_mut() {
            s.clear();
            s.push_str(&message.replace('\0', "\u{FFFD}"));
        }
    });
}

/// Copies the message of the calling thread's most recent failure into
/// `buf` and returns its full length in bytes, excluding the terminating
/// NUL.
///
/// The message is UTF-8 English text describing the last call on this
/// thread that did not return `PMC_STATUS_OK` (for example which argument
/// was invalid and why). Successful calls do not clear it. It is empty
/// (return value 0) when no call on this thread has failed yet.
///
/// At most `len - 1` bytes are copied, cut at a character boundary, and
/// the copy is always NUL-terminated when `len > 0`. Call with
/// `buf = NULL, len = 0` to query the size: allocate the returned value
/// plus one. Nothing is written when `len == 0` or `buf` is `NULL`.
///
/// # Safety
///
/// `buf` must be `NULL` or valid for writing `len` bytes.
#[no_mangle]
pub unsafe extern "C" fn pmc_last_error_message(buf: *mut c_char, len: usize) -> usize {
    value_boundary(0, || {
        LAST_ERROR
            .try_with(|slot| {
                let Ok(msg) = slot.try_borrow() else { return 0 };
                if !buf.is_null() && len > 0 {
                    let mut n = msg.len().min(len - 1);
                    while !msg.is_char_boundary(n) {
                        n -= 1;
                    }
                    // SAFETY: the caller guarantees `buf` is writable for
                    // `len` bytes and `n < len`; `msg` is a distinct Rust
                    // allocation, so the regions do not overlap.
                    unsafe {
                        std::ptr::copy_nonoverlapping(msg.as_ptr(), buf.cast::<u8>(), n);
                        *buf.add(n) = 0;
                    }
                }
                msg.len()
            })
            .unwrap_or(0)
    })
}
