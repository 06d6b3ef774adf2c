//! `pmc_extract`: the one entry point that runs an extraction.

use std::ops::ControlFlow;

use super::mesh::{into_handle, pmc_mesh};
use super::options::{pmc_options, OptionsData};
use super::panic::{status_boundary, Failure};
use super::status::PmcStatus;
use super::volume::{core_volume, pmc_volume, volume_ref};
use crate::Error;

/// The C status and message of a core error.
pub(super) fn failure(e: Error) -> Failure {
    let status = match e {
        Error::Aborted => PmcStatus::Aborted,
        // Worker threads fail to start for want of memory for their stacks
        // or of the process's thread allowance: a resource, not an
        // argument, is short.
        Error::OutOfMemory(_) | Error::ThreadPool(_) => PmcStatus::OutOfMemory,
        _ => PmcStatus::InvalidArgument,
    };
    Failure {
        status,
        message: e.to_string(),
    }
}

/// Extracts the isosurface `isovalue` of `volume`: Marching Cubes with the
/// chosen topology, then adaptive refinement of every triangle onto the
/// trilinear isosurface (see `pmc_options`).
///
/// `options` may be `NULL` for the defaults (see `pmc_options_new`). On
/// success returns `PMC_STATUS_OK` and stores in `*out_mesh` a new mesh
/// owned by the caller (release it with `pmc_mesh_free`). On failure
/// stores `NULL` in `*out_mesh` (when `out_mesh` is not `NULL`), records a
/// message for `pmc_last_error_message`, and returns:
///
/// - `PMC_STATUS_NULL_ARGUMENT` if `volume`, `volume->data` or `out_mesh`
///   is `NULL`;
/// - `PMC_STATUS_INVALID_ARGUMENT` for a `volume->struct_size` that is 0
///   or smaller than the first `pmc_volume` layout (checked before any
///   other field of the volume), an invalid volume (see
///   `pmc_volume`), an isovalue that is NaN or infinite, or an index
///   offset out of range, or when the options' executor returned without
///   running every task (see `pmc_options_set_executor`);
/// - `PMC_STATUS_ABORTED` if the progress callback asked to stop;
/// - `PMC_STATUS_OUT_OF_MEMORY` if a memory reservation failed (the
///   output's, a slab's buffers as refinement fills them, a cell's patch,
///   its edge decisions and its soundness check however deep it refines).
///   A few smaller allocations (a stalled cell's sub-cells, small buffers)
///   still abort the process when they fail (README, Limitations). Cap the
///   output with
///   `pmc_options_set_max_triangles` where memory is tight. (Worker
///   threads that cannot be started, for a process's limit on threads,
///   are no error: their share runs on the threads that did start, the
///   calling thread at least, with the same output.)
///
/// The samples are read only during the call. The output does not depend
/// on the thread count, and pieces of a volume that share a layer of
/// samples give bit-identical points on it (see
/// `pmc_options_set_index_offset`). Samples that are NaN or infinite skip
/// their cells (with a cubic reconstruction filter, every cell whose 4x4x4
/// neighbourhood holds one). Thread-safe: concurrent calls may share `volume` and
/// `options`.
///
/// Stack: the calling thread refines cells itself, recursively (one
/// level per recursion, up to max level 10), and needs about 56 KiB of
/// stack at the deepest settings (measured with max level 10, epsilon
/// 1e-6, each rule and reconstruction; a thread of 48 KiB crashed, 58
/// KiB was the least that worked). Give a thread that calls it at least
/// 256 KiB (`pthread_attr_setstacksize`); a process's main thread and
/// default threads have more on Linux (8 MiB), macOS (512 KiB) and
/// Windows (1 MiB). The library's own helper threads have 8 MiB; for an
/// executor's threads see `pmc_executor_fn`.
///
/// # Safety
///
/// `volume` must be `NULL` or point to a `pmc_volume` readable for its
/// `struct_size` bytes, whose `data` is `NULL` or readable for `len`
/// elements of `scalar_type`, not written during the call; `options`
/// must be `NULL` or a live handle from `pmc_options_new`; `out_mesh`
/// must be `NULL` or writable.
#[no_mangle]
pub unsafe extern "C" fn pmc_extract(
    volume: *const pmc_volume,
    isovalue: f64,
    options: *const pmc_options,
    out_mesh: *mut *mut pmc_mesh,
) -> PmcStatus {
    status_boundary(|| {
        if out_mesh.is_null() {
            return Err(Failure::null("out_mesh"));
        }
        // SAFETY: `out_mesh` is non-null and writable per the contract.
        unsafe { out_mesh.write(std::ptr::null_mut()) };
        // SAFETY: per the contract, `volume` is NULL or points to a volume.
        let v = unsafe { volume_ref(volume)? };
        let defaults;
        // SAFETY: per the contract, `options` is NULL or a live handle.
        let opts = match unsafe { OptionsData::from_handle(options) } {
            Some(o) => o,
            None => {
                defaults = OptionsData::default();
                &defaults
            }
        };
        // SAFETY: per the contract, `data` is NULL or readable for `len`
        // elements during this call.
        let volume = unsafe { core_volume(v, opts.index_offset)? };
        let mut last = 0.0f64;
        let mut stopped = false;
        let mut progress = |fraction: f64| {
            let Some(cb) = opts.progress else {
                return ControlFlow::Continue(());
            };
            // Once the callback asked to stop it is not called again.
            if stopped {
                return ControlFlow::Break(());
            }
            // Reported values never decrease, whatever the passes do.
            last = fraction.clamp(last, 1.0);
            // SAFETY: the caller guarantees the callback may be called
            // with its user data during extractions.
            stopped = unsafe { cb(opts.user_data, last) } != 0;
            if stopped {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        };
        let mesh = crate::extract::extract_index_points(
            &volume,
            isovalue,
            &opts.core,
            opts.executor.as_ref().map(|e| e as &dyn crate::Executor),
            &mut progress,
        )
        .map_err(failure)?;
        let handle = into_handle(mesh, volume.origin, volume.spacing);
        // SAFETY: as above.
        unsafe { out_mesh.write(handle) };
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Worker threads that cannot start are a resource shortage, like
    /// memory, not a caller's mistake.
    #[test]
    fn thread_failures_are_out_of_memory() {
        let f = failure(Error::ThreadPool("Resource temporarily unavailable".into()));
        assert_eq!(f.status, PmcStatus::OutOfMemory);
        assert!(f.message.contains("cannot start worker threads"));
        assert_eq!(
            failure(Error::InvalidIsovalue(f64::NAN)).status,
            PmcStatus::InvalidArgument
        );
    }
}
