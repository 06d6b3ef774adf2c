//! `pmc_measure_options`: an opaque set of settings of the accuracy
//! measure (`pmc_measure`), as `pmc_options` is of the extraction.

use super::options::{thread_count, PMC_MAX_INDEX_OFFSET};
use super::panic::{status_boundary, value_boundary, Failure};
use super::status::PmcStatus;
use crate::accuracy::{MeasureOptions, MIN_TOLERANCE};

/// Highest value accepted by `pmc_measure_options_set_density`.
pub const PMC_MAX_MEASURE_DENSITY: u32 = 1024;

/// Smallest absolute tolerance accepted by
/// `pmc_measure_options_set_tolerance`, in cell units (1e-8): below it
/// the search's cost grows past hours for a mesh.
pub const PMC_MIN_MEASURE_TOLERANCE: f64 = 1e-8;
const _: () = assert!(PMC_MIN_MEASURE_TOLERANCE == MIN_TOLERANCE);

/// Settings of the accuracy measure (opaque). Create with
/// `pmc_measure_options_new`, change with the `pmc_measure_options_set_*`
/// functions, pass to `pmc_measure`, release with
/// `pmc_measure_options_free`. May be shared by concurrent `pmc_measure`
/// calls as long as it is not modified or freed meanwhile. Since 0.2.1,
/// with the functions below.
pub struct pmc_measure_options {
    _private: [u8; 0],
}

/// What a `pmc_measure_options` handle holds.
#[derive(Debug, Clone, Default)]
pub(crate) struct Settings {
    /// The core's settings.
    pub measure: MeasureOptions,
    /// `Some(offset)`: the points are index points in global index space,
    /// of a mesh extracted with this index offset
    /// (`pmc_measure_options_set_index_points`); `None`: world points.
    pub index_offset: Option<[i64; 3]>,
}

/// The settings behind a handle, the defaults for `NULL`.
///
/// # Safety
///
/// `p` must be `NULL` or a live handle from `pmc_measure_options_new`.
pub(crate) unsafe fn settings(p: *const pmc_measure_options) -> Settings {
    // SAFETY: per the contract, a non-null `p` came from `Box::into_raw` of
    // a `Settings` in `pmc_measure_options_new` and is still live.
    unsafe { p.cast::<Settings>().as_ref() }
        .cloned()
        .unwrap_or_default()
}

/// Runs a setter: checks the handle for `NULL`, then applies `f`.
///
/// # Safety
///
/// `p` must be `NULL` or a live, not concurrently used handle.
unsafe fn with_settings(
    p: *mut pmc_measure_options,
    f: impl FnOnce(&mut Settings) -> Result<(), Failure>,
) -> PmcStatus {
    status_boundary(|| {
        // SAFETY: as for `settings`; the caller guarantees exclusivity.
        let o = unsafe { p.cast::<Settings>().as_mut() }.ok_or(Failure::null("options"))?;
        f(o)
    })
}

/// Creates measure settings with the defaults: density 4, absolute
/// tolerance 1e-5 cells, relative tolerance 0.02, all cores.
///
/// Returns a new handle owned by the caller, to be released with
/// `pmc_measure_options_free`; `NULL` only if an internal error occurred.
#[no_mangle]
pub extern "C" fn pmc_measure_options_new() -> *mut pmc_measure_options {
    value_boundary(std::ptr::null_mut(), || {
        Box::into_raw(Box::new(Settings::default())).cast()
    })
}

/// Releases settings created by `pmc_measure_options_new`. `NULL` is
/// accepted and ignored.
///
/// # Safety
///
/// `options` must be `NULL` or a live handle from
/// `pmc_measure_options_new`, not used by another thread during the call
/// nor afterwards.
#[no_mangle]
pub unsafe extern "C" fn pmc_measure_options_free(options: *mut pmc_measure_options) {
    value_boundary((), || {
        if !options.is_null() {
            // SAFETY: per the contract, a live handle freed once.
            drop(unsafe { Box::from_raw(options.cast::<Settings>()) });
        }
    })
}

/// Sets the subdivisions of each triangle edge for the barycentric sample
/// grid: `(density + 1)(density + 2) / 2` sample points per triangle (1:
/// the vertices only). Default 4.
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (settings unchanged) unless
/// `density` is in `1..=PMC_MAX_MEASURE_DENSITY`;
/// `PMC_STATUS_NULL_ARGUMENT` for `NULL` settings.
///
/// # Safety
///
/// `options` must be `NULL` or a live handle from
/// `pmc_measure_options_new`, not used concurrently by another thread.
#[no_mangle]
pub unsafe extern "C" fn pmc_measure_options_set_density(
    options: *mut pmc_measure_options,
    density: u32,
) -> PmcStatus {
    let set = |o: &mut Settings| {
        if !(1..=PMC_MAX_MEASURE_DENSITY).contains(&density) {
            return Err(Failure::invalid(format!(
                "measure density {density} is outside 1..={PMC_MAX_MEASURE_DENSITY}"
            )));
        }
        o.measure.density = density;
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_settings(options, set) }
}

/// Sets how closely each sample's distance is certified: to within
/// `absolute + relative * d` for a distance `d`, `absolute` in cell units.
/// Defaults 1e-5 and 0.02. Tighter tolerances cost more: several times
/// for every decade of `absolute` below the default, and with `relative`
/// 0 a sample's search may stop at its box limit where the surface curves
/// around it (see `precisemc::accuracy::MeasureOptions`).
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (settings unchanged) unless
/// `absolute` is finite and at least `PMC_MIN_MEASURE_TOLERANCE` and
/// `relative` lies in `[0, 1)`; `PMC_STATUS_NULL_ARGUMENT` for `NULL`
/// settings.
///
/// # Safety
///
/// As for `pmc_measure_options_set_density`.
#[no_mangle]
pub unsafe extern "C" fn pmc_measure_options_set_tolerance(
    options: *mut pmc_measure_options,
    absolute: f64,
    relative: f64,
) -> PmcStatus {
    let set = |o: &mut Settings| {
        if !(absolute.is_finite() && absolute >= PMC_MIN_MEASURE_TOLERANCE) {
            return Err(Failure::invalid(format!(
                "measure tolerance {} must be finite and at least 1e-8 cells",
                crate::error::Number(absolute)
            )));
        }
        if !(relative.is_finite() && (0.0..1.0).contains(&relative)) {
            return Err(Failure::invalid(format!(
                "relative measure tolerance {} must be in [0, 1)",
                crate::error::Number(relative)
            )));
        }
        o.measure.tolerance = absolute;
        o.measure.relative_tolerance = relative;
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_settings(options, set) }
}

/// Sets the number of threads measuring; `0` (the default) uses all
/// cores. The calling thread works beside the extraction's helper threads
/// (see `pmc_options_set_threads`). The result is identical for any
/// value.
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (settings unchanged) above
/// `PMC_MAX_THREADS`; `PMC_STATUS_NULL_ARGUMENT` for `NULL` settings.
///
/// # Safety
///
/// As for `pmc_measure_options_set_density`.
#[no_mangle]
pub unsafe extern "C" fn pmc_measure_options_set_threads(
    options: *mut pmc_measure_options,
    threads: u32,
) -> PmcStatus {
    let set = |o: &mut Settings| {
        o.measure.threads = thread_count(threads)?;
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_settings(options, set) }
}

/// Makes `pmc_measure` take its points in continuous global index space,
/// as `pmc_mesh_index_points` gives them for a mesh extracted with the
/// index offset `offset` (`pmc_options_set_index_offset`; `{0, 0, 0}` for
/// a mesh extracted without one), instead of world coordinates. `NULL`
/// goes back to world coordinates, the default. Index points are measured
/// as given, as the Rust API measures them: world points are turned into
/// index points by `(point - origin) / spacing`, which loses what the
/// world coordinates could not hold (far from the origin, where a double
/// is coarser than a cell: world points 1e15 units from it are rounded to
/// 1/8 of a unit, and measured up to several cells off). Since 0.2.2.
///
/// Returns `PMC_STATUS_INVALID_ARGUMENT` (settings unchanged) when an
/// offset lies outside `-PMC_MAX_INDEX_OFFSET ..= PMC_MAX_INDEX_OFFSET`
/// (the message names the axis and value); `PMC_STATUS_NULL_ARGUMENT` for
/// `NULL` settings.
///
/// # Safety
///
/// As for `pmc_measure_options_set_density`; `offset` must be `NULL` or
/// point to 3 readable `int64_t`.
/// cbindgen:ptrs-as-arrays=[[offset; 3]]
#[no_mangle]
pub unsafe extern "C" fn pmc_measure_options_set_index_points(
    options: *mut pmc_measure_options,
    offset: *const i64,
) -> PmcStatus {
    let set = |o: &mut Settings| {
        if offset.is_null() {
            o.index_offset = None;
            return Ok(());
        }
        // SAFETY: `offset` is non-null and points to 3 readable values per
        // the contract; read unaligned to tolerate any address.
        let v = unsafe { offset.cast::<[i64; 3]>().read_unaligned() };
        if let Some(axis) = (0..3).find(|&a| v[a].unsigned_abs() > PMC_MAX_INDEX_OFFSET as u64) {
            let e = crate::Error::InvalidIndexOffset {
                axis,
                value: v[axis],
            };
            return Err(Failure::invalid(format!("invalid measure options: {e}")));
        }
        o.index_offset = Some(v);
        Ok(())
    };
    // SAFETY: forwarded contract.
    unsafe { with_settings(options, set) }
}
