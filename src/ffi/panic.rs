//! The panic boundary: no Rust panic may unwind into C.

use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};

use super::error::set_last_error;
use super::status::PmcStatus;

/// Why a call failed: the status to return and the message stored for
/// `pmc_last_error_message`.
#[derive(Debug)]
pub(crate) struct Failure {
    pub status: PmcStatus,
    pub message: String,
}

impl Failure {
    /// A `PMC_STATUS_NULL_ARGUMENT` failure naming the argument.
    pub fn null(argument: &str) -> Self {
        Failure {
            status: PmcStatus::NullArgument,
            message: format!("{argument} is NULL"),
        }
    }

    /// A `PMC_STATUS_INVALID_ARGUMENT` failure.
    pub fn invalid(message: impl Into<String>) -> Self {
        Failure {
            status: PmcStatus::InvalidArgument,
            message: message.into(),
        }
    }
}

fn panic_text(payload: &(dyn Any + Send)) -> &str {
    if let Some(s) = payload.downcast_ref::<&str>() {
        s
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s
    } else {
        "unknown panic payload"
    }
}

fn record_panic(payload: Box<dyn Any + Send>) {
    set_last_error(&format!(
        "internal error (panic in precisemc): {}",
        panic_text(payload.as_ref())
    ));
    // Dropping a payload could itself panic; leak it instead, a panic at
    // the boundary is a bug and rare.
    std::mem::forget(payload);
}

/// Runs `f` for a function returning a status: `Ok` becomes
/// `PMC_STATUS_OK`, a [`Failure`] its status (with its message stored), a
/// panic `PMC_STATUS_INTERNAL_ERROR`.
pub(crate) fn status_boundary(f: impl FnOnce() -> Result<(), Failure>) -> PmcStatus {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(())) => PmcStatus::Ok,
        Ok(Err(failure)) => {
            set_last_error(&failure.message);
            failure.status
        }
        Err(payload) => {
            record_panic(payload);
            PmcStatus::InternalError
        }
    }
}

/// Runs `f` for a function returning a value: a panic returns `fallback`
/// (with the message stored).
pub(crate) fn value_boundary<T>(fallback: T, f: impl FnOnce() -> T) -> T {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(v) => v,
        Err(payload) => {
            record_panic(payload);
            fallback
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn last_error() -> String {
        let mut buf = [0u8; 256];
        let n =
            unsafe { super::super::error::pmc_last_error_message(buf.as_mut_ptr().cast(), 256) };
        String::from_utf8(buf[..n].to_vec()).unwrap()
    }

    #[test]
    fn panics_become_internal_error() {
        let prev = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let s = status_boundary(|| panic!("boom {}", 42));
        let first = last_error();
        let v = value_boundary(7u64, || -> u64 { panic!("static boom") });
        std::panic::set_hook(prev);
        assert_eq!(s, PmcStatus::InternalError);
        assert_eq!(first, "internal error (panic in precisemc): boom 42");
        assert_eq!(v, 7);
        assert_eq!(
            last_error(),
            "internal error (panic in precisemc): static boom"
        );
    }

    #[test]
    fn failures_store_their_message() {
        assert_eq!(status_boundary(|| Ok(())), PmcStatus::Ok);
        assert_eq!(
            status_boundary(|| Err(Failure::null("thing"))),
            PmcStatus::NullArgument
        );
        assert_eq!(last_error(), "thing is NULL");
        assert_eq!(
            status_boundary(|| Err(Failure::invalid("bad\0value"))),
            PmcStatus::InvalidArgument
        );
        assert_eq!(last_error(), "bad\u{FFFD}value");
    }
}
