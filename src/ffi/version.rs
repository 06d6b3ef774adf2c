//! Library version.

use std::ffi::c_char;

const VERSION: &str = concat!(env!("CARGO_PKG_VERSION"), "\0");

/// The version of the library actually loaded, as a static NUL-terminated
/// string `"MAJOR.MINOR.PATCH"` (compare with `PMC_VERSION_STRING`, the
/// version of the header compiled against). Never `NULL`; do not free.
#[no_mangle]
pub extern "C" fn pmc_version_string() -> *const c_char {
    VERSION.as_ptr().cast()
}
