//! Status codes returned by every fallible function of the C API.

use std::ffi::c_char;

use super::panic::value_boundary;

/// Outcome of a call. The numeric values are part of the stable ABI and are
/// never renumbered; new codes may be appended.
///
/// In C this is a `uint32_t` typedef with the enumerators as constants, so
/// any integer can be stored; functions taking a status accept unknown
/// values.
#[repr(u32)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PmcStatus {
    /// Success.
    Ok = 0,
    /// A required pointer argument was `NULL`.
    NullArgument = 1,
    /// An argument was out of range, inconsistent or of an unknown
    /// enumeration value; nothing was read out of bounds.
    InvalidArgument = 2,
    /// The progress callback asked to stop; no result was produced.
    Aborted = 3,
    /// A memory reservation failed.
    OutOfMemory = 4,
    /// A bug in the library (a Rust panic caught at the API boundary). The
    /// library remains usable; please report it with the message from
    /// `pmc_last_error_message`.
    InternalError = 5,
}

/// The C representation of [`PmcStatus`]: a `uint32_t` holding one of the
/// `PMC_STATUS_*` values.
pub type pmc_status = u32;

impl PmcStatus {
    /// The status for a raw value, `None` for an unknown one.
    pub fn from_raw(value: pmc_status) -> Option<Self> {
        Some(match value {
            0 => PmcStatus::Ok,
            1 => PmcStatus::NullArgument,
            2 => PmcStatus::InvalidArgument,
            3 => PmcStatus::Aborted,
            4 => PmcStatus::OutOfMemory,
            5 => PmcStatus::InternalError,
            _ => return None,
        })
    }

    /// Static, NUL-terminated description.
    fn description(self) -> &'static [u8] {
        match self {
            PmcStatus::Ok => b"ok\0",
            PmcStatus::NullArgument => b"null argument\0",
            PmcStatus::InvalidArgument => b"invalid argument\0",
            PmcStatus::Aborted => b"aborted by the progress callback\0",
            PmcStatus::OutOfMemory => b"out of memory\0",
            PmcStatus::InternalError => b"internal error\0",
        }
    }
}

/// A short, static, NUL-terminated English description of `status`
/// (for example `"invalid argument"`); `"unknown status"` for a value that
/// is not a `PMC_STATUS_*` constant. Never `NULL`; the string must not be
/// freed or modified. Thread-safe.
///
/// For the details of a failure, see `pmc_last_error_message`.
#[no_mangle]
pub extern "C" fn pmc_status_string(status: pmc_status) -> *const c_char {
    const UNKNOWN: &[u8] = b"unknown status\0";
    value_boundary(UNKNOWN.as_ptr().cast(), || {
        PmcStatus::from_raw(status)
            .map_or(UNKNOWN, PmcStatus::description)
            .as_ptr()
            .cast()
    })
}
