//! `struct_size`: the first field of every public C struct, so that the
//! structs can grow in later versions without breaking callers built
//! against an older header (the convention of Win32's `cbSize`).
//!
//! The caller sets `struct_size` to `sizeof` of the struct as its header
//! declares it. The library rejects 0 and anything smaller than the first
//! layout it shipped (the "version 1" sizes below), accepts anything
//! larger (a caller built against a newer header), reads only the fields
//! it knows from an input struct, and writes only the fields it knows into
//! an output struct: never a byte at or past the caller's `struct_size`,
//! never `struct_size` itself.
//!
//! When a later version appends a field, the version 1 size stays what it
//! is here (it is the oldest layout still accepted), and the code reading
//! or writing the new field must first check that the caller's
//! `struct_size` reaches past it.

use std::mem::size_of;

use super::measure::pmc_distance;
use super::mesh::pmc_stats;
use super::panic::Failure;
use super::volume::pmc_volume;

// The sizes of the first layouts, the ones this version declares. Frozen:
// when a field is appended to one of these structs, replace its
// `size_of` by the number it gives today on each platform (or the end of
// its last version 1 field), so that callers of version 1 stay accepted.
// Not in the header: C callers set `sizeof`. `tests/c_api.rs` pins
// today's sizes on 64-bit platforms.

/// Size in bytes of the version 1 `pmc_volume` (128 on 64-bit platforms).
pub(crate) const PMC_VOLUME_SIZE_V1: u64 = size_of::<pmc_volume>() as u64;
/// Size in bytes of the version 1 `pmc_stats` (152 on 64-bit platforms).
pub(crate) const PMC_STATS_SIZE_V1: u64 = size_of::<pmc_stats>() as u64;
/// Size in bytes of the version 1 `pmc_distance` (48).
pub(crate) const PMC_DISTANCE_SIZE_V1: u64 = size_of::<pmc_distance>() as u64;

/// The largest `struct_size` accepted (64 KiB, far beyond any layout
/// these structs will have). A caller built against a header without
/// `struct_size` (0.1) passes the struct's first pointer or count in its
/// place, a larger number: rejected instead of taken for a later layout.
pub(crate) const MAX_STRUCT_SIZE: u64 = 1 << 16;

/// Reads the `struct_size` field (the first, a `uint64_t`) of the struct at
/// `p`, with no alignment requirement, and checks it against `v1`, the
/// size of the struct's first layout: 0 and anything below `v1` are
/// `PMC_STATUS_INVALID_ARGUMENT` with a message that names the struct
/// (`name`) and says what to set; so is anything above
/// [`MAX_STRUCT_SIZE`].
///
/// # Safety
///
/// `p` must be non-null and readable for 8 bytes.
pub(crate) unsafe fn check<T>(p: *const T, name: &str, v1: u64) -> Result<(), Failure> {
    // SAFETY: per the contract; the field is the struct's first 8 bytes.
    let size = unsafe { p.cast::<u64>().read_unaligned() };
    if size == 0 {
        return Err(Failure::invalid(format!(
            "{name}.struct_size is 0; set it to sizeof({name}) before the call"
        )));
    }
    if size < v1 {
        return Err(Failure::invalid(format!(
            "{name}.struct_size is {size}, smaller than the {v1} bytes of the smallest \
             {name} this library accepts; set it to sizeof({name}) before the call"
        )));
    }
    if size > MAX_STRUCT_SIZE {
        return Err(Failure::invalid(format!(
            "{name}.struct_size is {size}, larger than any {name} ({MAX_STRUCT_SIZE} bytes \
             at most; a caller built against a header without struct_size?); set it to \
             sizeof({name}) before the call"
        )));
    }
    Ok(())
}

/// Writes the listed fields of `$value` (a struct of type `$ty`) into
/// `*$out` one by one, unaligned: every field but `struct_size`, which is
/// the caller's, and no padding byte. The list must name every field of
/// `$ty` but `struct_size`, which the pattern below checks at compile time.
/// Used for output structs, after [`check`] (so every field listed lies
/// below the caller's `struct_size`).
macro_rules! write_fields {
    ($ty:ident, $out:expr, $value:expr, $($field:ident),+ $(,)?) => {{
        let out: *mut $ty = $out;
        let value: $ty = $value;
        // A field missing from the list fails to compile here.
        let $ty { struct_size: _, $($field: _),+ } = value;
        $(
            // SAFETY: the caller of the macro guarantees that `out` is
            // writable for the version 1 size of `$ty`.
            unsafe { std::ptr::addr_of_mut!((*out).$field).write_unaligned(value.$field) };
        )+
    }};
}
pub(crate) use write_fields;
