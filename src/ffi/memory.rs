//! Releasing the buffers the library keeps between extractions.

use super::panic::value_boundary;

/// Frees the buffers the library keeps between extractions for reuse and
/// returns their size in bytes. Repeated extractions write into memory
/// that earlier ones used (the slabs' points and triangles, the edge
/// caches, and the arrays of meshes passed to `pmc_mesh_free` or
/// `pmc_buffer_free`) rather than into fresh pages; at most 64 MiB is
/// kept, process-wide. Call this after a burst of extractions when the
/// memory is wanted elsewhere. Also stops the helper threads the library
/// keeps between extractions (parked; each returns by itself after 1 s
/// without work) unless an extraction is using them. Thread-safe;
/// extractions running meanwhile are not affected.
#[no_mangle]
pub extern "C" fn pmc_release_memory() -> usize {
    value_boundary(0, crate::recycle::release_retained_memory)
}
