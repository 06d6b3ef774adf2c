//! `pmc_options`: an opaque, heap-allocated set of extraction options.

use std::ffi::{c_int, c_void};

use super::enums::{
    pmc_normals, pmc_reconstruction, pmc_rule, pmc_topology, PmcNormals, PmcReconstruction,
    PmcRule, PmcTopology,
};
use super::executor::{pmc_executor_fn, CExecutor};
use super::panic::{status_boundary, value_boundary, Failure};
use super::status::PmcStatus;
use crate::Options;

/// Highest value accepted by `pmc_options_set_max_level`.
pub const PMC_MAX_LEVEL_LIMIT: u32 = 10;
const _: () = assert!(PMC_MAX_LEVEL_LIMIT == crate::MAX_LEVEL_LIMIT);

/// Highest value accepted by `pmc_options_set_threads`, and for the
/// concurrency of `pmc_options_set_executor`.
pub const PMC_MAX_THREADS: u32 = 4096;

/// A thread count asked through the C API, refused above
/// [`PMC_MAX_THREADS`] (the extraction's and the measure's setters).
pub(crate) fn thread_count(threads: u32) -> Result<usize, Failure> {
    if threads > PMC_MAX_THREADS {
        return Err(Failure::invalid(format!(
            "{threads} threads is above the limit of {PMC_MAX_THREADS}"
        )));
    }
    Ok(threads as usize)
}

/// Largest magnitude of an index offset accepted by `pmc_extract` (2^31):
/// each of the three offsets set with `pmc_options_set_index_offset` must
/// lie in `-PMC_MAX_INDEX_OFFSET ..= PMC_MAX_INDEX_OFFSET`.
pub const PMC_MAX_INDEX_OFFSET: i64 = 2_147_483_648;
const _: () = assert!(PMC_MAX_INDEX_OFFSET == crate::MAX_INDEX_OFFSET);

/// Progress callback: `fraction` goes from 0.0 to 1.0 and never decreases.
/// Called on the thread that called `pmc_extract`, first with 0.0, then
/// after each layer of cells the calling thread finishes and, within a
/// long layer, about every 20 ms (not in between for plain Marching Cubes
/// of up to 4 Mi cells on one thread, a few milliseconds of work done on
/// the calling thread), and last with 1.0 on success. Return 0 to continue,
/// any other value to stop: the callback is not called again, and
/// `pmc_extract` returns `PMC_STATUS_ABORTED` within a few milliseconds
/// and produces no mesh. Welding the workers' outputs into one mesh
/// (before the call with 0.97) and the normals and gradients (after it)
/// make no calls:
/// on meshes of tens of millions of triangles they take seconds, during
/// which no stop can be asked.
/// The callback must not call `pmc_options_*` on the options being used,
/// and must return normally: a C++ exception thrown out of it (or a
/// `longjmp` across the library) cannot pass through the library's Rust
/// frames and aborts the process. Catch inside the callback and return
/// non-zero to stop instead.
pub type pmc_progress_fn =
    Option<unsafe extern "C" fn(user_data: *mut c_void, fraction: f64) -> c_int>;

/// Extraction options (opaque). Create with `pmc_options_new`, change with
/// the `pmc_options_set_*` functions, release with `pmc_options_free`.
///
/// A `pmc_options` may be shared by any number of `pmc_extract` calls,
/// also concurrently from several threads, as long as it is not modified
/// or freed meanwhile (and the progress callback and the executor, if any,
/// tolerate concurrent calls).
pub struct pmc_options {
    _private: [u8; 0],
}

/// What a `pmc_options` handle points to.
#[derive(Clone)]
pub(crate) struct OptionsData {
    pub core: Options,
    pub index_offset: [i64; 3],
    pub progress: pmc_progress_fn,
    pub user_data: *mut c_void,
    /// The host's executor, if set (`pmc_options_set_executor`).
    pub executor: Option<CExecutor>,
}

impl Default for OptionsData {
    fn default() -> Self {
        OptionsData {
            core: Options::default(),
            index_offset: [0; 3],
            progress: None,
            user_data: std::ptr::null_mut(),
            executor: None,
        }
    }
}

impl OptionsData {
    /// The options behind a handle, `None` for `NULL`.
    ///
    /// # Safety
    ///
    /// `p` must be `NULL` or a live handle from `pmc_options_new`.
    pub(crate) unsafe fn from_handle<'a>(p: *const pmc_options) -> Option<&'a OptionsData> {
        // SAFETY: per the contract, a non-null `p` came from `Box::into_raw`
        // of an `OptionsData` in `pmc_options_new` and is still live.
        unsafe { p.cast::<OptionsData>().as_ref() }
    }
}

/// Runs a setter: checks the handle for `NULL`, then applies `f`.
///
/// # Safety
///
/// `p` must be `NULL` or a live, not concurrently used handle.
unsafe fn with_options(
    p: *mut pmc_options,
    f: impl FnOnce(&mut OptionsData) -> Result<(), Failure>,
) -> PmcStatus {
    status_boundary(|| {
        // SAFETY: as for `from_handle`; the caller guarantees exclusivity.
        let o = unsafe { p.cast::<OptionsData>().as_mut() }.ok_or(Failure::null("options"))?;
        f(o)
    })
}

/// Creates options with the defaults: epsilon 0.01, max level 5, rule
/// `PMC_RULE_A1`, topology `PMC_TOPOLOGY_TRILINEAR`, normals
/// `PMC_NORMALS_NONE`, no gradients, reconstruction `PMC_RECONSTRUCTION_TRILINEAR`, no
/// triangle cap, all cores, no progress callback, no executor (threads of
/// its own), index offset (0, 0, 0).
///
/// Returns a new handle owned by the caller, to be released with
/// `pmc_options_free`; `NULL` only if an internal error occurred.
#[no_mangle]
pub extern "C" fn pmc_options_new() -> *mut pmc_options {
    value_boundary(std::ptr::null_mut(), || {
        Box::into_raw(Box::new(OptionsData::default())).cast()
    })
}

/// Releases options created by `pmc_options_new`. `NULL` is accepted and
/// ignored. Meshes extracted with the options stay valid.
///
/// # Safety
///
/// `options` must be `NULL` or a handle from `pmc_options_new` not yet
/// freed; it must not be used afterwards.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_free(options: *mut pmc_options) {
    value_boundary((), || {
        if !options.is_null() {
            // SAFETY: per the contract, `options` came from `Box::into_raw`
            // in `pmc_options_new` and is freed once.
            drop(unsafe { Box::from_raw(options.cast::<OptionsData>()) });
        }
    })
}

/// Sets the largest allowed distance, in cell-edge units of index space,
/// between a tested sample point and the isosurface of the reconstruction
/// filter (`pmc_options_set_reconstruction`; by default the trilinear
/// interpolant's, `S_K`). Default 0.01. `0` turns refinement off (plain
/// Marching Cubes).
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (options unchanged) unless
/// `epsilon` is finite and >= 0; `PMC_STATUS_NULL_ARGUMENT` for `NULL`
/// options.
///
/// # Safety
///
/// `options` must be `NULL` or a live handle from `pmc_options_new`, not
/// used concurrently by another thread.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_epsilon(
    options: *mut pmc_options,
    epsilon: f64,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        if !(epsilon.is_finite() && epsilon >= 0.0) {
            return Err(Failure::invalid(format!(
                "epsilon {} must be finite and >= 0 (cell units)",
                crate::error::Number(epsilon)
            )));
        }
        o.core.epsilon = epsilon;
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Sets the maximum refinement level: each level can split a triangle into
/// up to 4 (rules A and A1) or 6 (rules A2 and B). Default 5. `0` turns
/// refinement off (plain Marching Cubes).
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (options unchanged) above
/// `PMC_MAX_LEVEL_LIMIT`; `PMC_STATUS_NULL_ARGUMENT` for `NULL` options.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_max_level(
    options: *mut pmc_options,
    max_level: u32,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        if max_level > PMC_MAX_LEVEL_LIMIT {
            return Err(Failure::invalid(format!(
                "max level {max_level} is above the limit of {PMC_MAX_LEVEL_LIMIT}"
            )));
        }
        o.core.max_level = max_level;
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Sets the refinement rule, one of the `PMC_RULE_*` values. Default
/// `PMC_RULE_A1`.
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (options unchanged) for any other
/// value; `PMC_STATUS_NULL_ARGUMENT` for `NULL` options.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_rule(
    options: *mut pmc_options,
    rule: pmc_rule,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        let r = PmcRule::from_raw(rule)
            .ok_or_else(|| Failure::invalid(format!("unknown rule {rule}")))?;
        o.core.rule = r.to_core();
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Sets the reconstruction filter whose isosurface refinement follows,
/// one of the `PMC_RECONSTRUCTION_*` values. Default
/// `PMC_RECONSTRUCTION_TRILINEAR`. Marching Cubes' topology always comes
/// from the samples (the trilinear decision); when refining with a cubic
/// filter, its edge vertices first move along their grid edge onto the
/// filter's isosurface (where the filter brackets one there), and split
/// points move onto it too. The cubic filters need two extra layers of
/// samples around a piece for piece-independent output
/// (`PMC_RECONSTRUCTION_BSPLINE_INTERPOLATING`: the whole volume, its
/// prefilter runs along whole lines of samples; see
/// `pmc_options_set_index_offset`), and
/// `PMC_RECONSTRUCTION_BSPLINE_INTERPOLATING` allocates one `double` per
/// sample.
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (options unchanged) for any other
/// value; `PMC_STATUS_NULL_ARGUMENT` for `NULL` options.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_reconstruction(
    options: *mut pmc_options,
    reconstruction: pmc_reconstruction,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        let r = PmcReconstruction::from_raw(reconstruction).ok_or_else(|| {
            Failure::invalid(format!("unknown reconstruction filter {reconstruction}"))
        })?;
        o.core.reconstruction = r.to_core();
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Sets the topology mode, one of the `PMC_TOPOLOGY_*` values. Default
/// `PMC_TOPOLOGY_TRILINEAR`.
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (options unchanged) for any other
/// value; `PMC_STATUS_NULL_ARGUMENT` for `NULL` options.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_topology(
    options: *mut pmc_options,
    topology: pmc_topology,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        let t = PmcTopology::from_raw(topology)
            .ok_or_else(|| Failure::invalid(format!("unknown topology {topology}")))?;
        o.core.topology = t.to_core();
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Sets which per-point normals to compute, one of the `PMC_NORMALS_*`
/// values. Default `PMC_NORMALS_NONE`.
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (options unchanged) for any other
/// value; `PMC_STATUS_NULL_ARGUMENT` for `NULL` options.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_normals(
    options: *mut pmc_options,
    normals: pmc_normals,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        let n = PmcNormals::from_raw(normals)
            .ok_or_else(|| Failure::invalid(format!("unknown normals mode {normals}")))?;
        o.core.normals = n.to_core();
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Sets whether to compute the scalar gradient at each output point
/// (`pmc_mesh_gradients`): `1` on, `0` off (the default). The gradients
/// are computed as the normals of the mode set with
/// `pmc_options_set_normals` are (by the exact trilinear gradient with
/// `PMC_NORMALS_NONE`), so that with both on each normal is its point's
/// negated, normalised gradient.
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (options unchanged) for any other
/// value; `PMC_STATUS_NULL_ARGUMENT` for `NULL` options.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_gradients(
    options: *mut pmc_options,
    gradients: c_int,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        o.core.gradients = match gradients {
            0 => false,
            1 => true,
            _ => {
                return Err(Failure::invalid(format!(
                    "gradients must be 0 (off) or 1 (on), not {gradients}"
                )))
            }
        };
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Caps the number of output triangles: refinement stops at the highest
/// level whose output fits (the mesh's stats then report
/// `budget_reached`). `0` means no cap (the default); an internal safety
/// cap of 250 million triangles always applies. The Marching Cubes
/// triangles themselves are never dropped.
///
/// Returns `PMC_STATUS_NULL_ARGUMENT` for `NULL` options.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_max_triangles(
    options: *mut pmc_options,
    max_triangles: u64,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        o.core.max_triangles = max_triangles;
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Sets the number of worker threads; `0` (the default) uses all cores.
/// The output is identical for any value.
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (options unchanged) above
/// `PMC_MAX_THREADS`; `PMC_STATUS_NULL_ARGUMENT` for `NULL` options.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_threads(
    options: *mut pmc_options,
    threads: u32,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        o.core.threads = thread_count(threads)?;
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Sets (or, with `callback = NULL`, clears) the progress callback and the
/// pointer passed to it unchanged as `user_data`. See `pmc_progress_fn`.
/// Default: none.
///
/// Returns `PMC_STATUS_NULL_ARGUMENT` for `NULL` options.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`; `callback` must be `NULL` or a
/// function safe to call with `user_data` during every later
/// `pmc_extract` using these options.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_progress(
    options: *mut pmc_options,
    callback: pmc_progress_fn,
    user_data: *mut c_void,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        o.progress = callback;
        o.user_data = if callback.is_some() {
            user_data
        } else {
            std::ptr::null_mut()
        };
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Lends the host's thread pool to later extractions with these options
/// (see `pmc_executor_fn`): their parallel steps become tasks of
/// `executor` instead of running on the library's own helper threads,
/// and the thread count (`pmc_options_set_threads`) is not used:
/// the volume is cut for `concurrency` workers, the number of tasks the
/// host runs at once. `executor = NULL` clears it (the default: threads of
/// the extraction's own). The output does not depend on it.
///
/// With an executor, the progress callback is called within the tasks
/// the executor happens to run on the thread that called `pmc_extract`
/// (after each cell layer and, at most every 20 ms, between refined cells
/// and refinement steps) and after each such task (a pool whose calling
/// thread takes part, as TBB's does, reports throughout a pass; others
/// only between passes), and
/// stopping takes effect at the next layer of cells of every running
/// task. An executor that
/// returns without running every task makes `pmc_extract` fail with
/// `PMC_STATUS_INVALID_ARGUMENT`.
///
/// Returns `PMC_STATUS_NULL_ARGUMENT` for `NULL` options,
/// `PMC_STATUS_INVALID_ARGUMENT` for a `concurrency` of 0 or above
/// `PMC_MAX_THREADS` with a non-`NULL` executor (the options are then
/// unchanged).
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`; `executor` must be `NULL` or a
/// function that honours `pmc_executor_fn`'s contract with
/// `executor_data` during every later `pmc_extract` using these options.
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_executor(
    options: *mut pmc_options,
    executor: pmc_executor_fn,
    executor_data: *mut c_void,
    concurrency: u32,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        let Some(run) = executor else {
            o.executor = None;
            return Ok(());
        };
        if concurrency == 0 || concurrency > PMC_MAX_THREADS {
            return Err(Failure::invalid(format!(
                "executor concurrency {concurrency} is outside 1..={PMC_MAX_THREADS}"
            )));
        }
        o.executor = Some(CExecutor {
            run,
            data: executor_data,
            concurrency,
        });
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}

/// Sets the global index of the volume's first sample (VTK's extent start,
/// in samples per axis x, y, z); default (0, 0, 0). With it, the pieces of
/// one volume that share a layer of samples produce bit-identical points
/// where they meet (trilinear filter): set each piece's offset to its
/// extent start and its `pmc_volume::origin` to the world position of
/// global index 0. For the serial run's surface exactly, triangles and
/// normals too, give each piece one more layer of samples beyond each cut
/// (two with the cubic filters; the whole volume, with the offset of its
/// start, for `PMC_RECONSTRUCTION_BSPLINE_INTERPOLATING`) and keep only
/// the triangles of its own cells (a triangle belongs to the cell of the
/// floor of its smallest index coordinates), as the VTK filter does:
/// normals and gradients at a point on a cut take the cell beyond it, a
/// plane of samples equal to the isovalue on a cut leaves flat triangles
/// that only the cell across cancels, and a cell meshed again on sub-cells
/// (trilinear topology, max level 3 up) drops its strip in a face whose
/// neighbour is meshed again too only when the piece holds that neighbour.
///
/// Each offset must lie in `-PMC_MAX_INDEX_OFFSET ..= PMC_MAX_INDEX_OFFSET`
/// (+/-2^31, which holds every VTK extent). Index points are global
/// doubles with the offset included, rounded to at most 2^-21 cells in
/// this range: Marching Cubes gives the mesh of offset 0 moved by the
/// offset, triangle for triangle, and refined meshes are as close to the
/// isosurface as at offset 0 (though a refinement decision near a tie may
/// differ); farther offsets would round points coarsely enough to degrade
/// the refinement. `pmc_extract`
/// rejects an offset outside it with `PMC_STATUS_INVALID_ARGUMENT` and a
/// message naming the axis and value; this setter stores any value.
///
/// Returns `PMC_STATUS_NULL_ARGUMENT` for `NULL` options or offset.
///
/// # Safety
///
/// As for `pmc_options_set_epsilon`; `offset` must be `NULL` or point to 3
/// readable `int64_t`.
/// cbindgen:ptrs-as-arrays=[[offset; 3]]
#[no_mangle]
pub unsafe extern "C" fn pmc_options_set_index_offset(
    options: *mut pmc_options,
    offset: *const i64,
) -> PmcStatus {
    let set = |o: &mut OptionsData| {
        if offset.is_null() {
            return Err(Failure::null("offset"));
        }
        // SAFETY: `offset` is non-null and points to 3 readable values
        // per the contract; read unaligned to tolerate any address.
        let v = unsafe { offset.cast::<[i64; 3]>().read_unaligned() };
        o.index_offset = v;
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_options(options, set) }
}
