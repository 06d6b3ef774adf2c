//! `pmc_measure_distance` and `pmc_measure`: the independent accuracy
//! measure over C.

use super::extract::failure;
use super::measure_options::{pmc_measure_options, settings, Settings};
use super::panic::{status_boundary, Failure};
use super::status::PmcStatus;
use super::struct_size::{self, write_fields};
use super::volume::{core_volume, pmc_volume, volume_ref};
use crate::accuracy::{measure, MeasureOptions};

/// Distance of a mesh to the trilinear isosurface, in cell units (index
/// space), as returned by `pmc_measure_distance`.
///
/// Set `struct_size` to `sizeof(pmc_distance)` before the call; the
/// library fills the other fields. (In Rust, `Default` sets it.)
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct pmc_distance {
    /// Size in bytes of the caller's struct, set by the caller to
    /// `sizeof(pmc_distance)` and never written by the library. No
    /// default: 0, or less than the size of the first `pmc_distance`
    /// layout (48 bytes), is `PMC_STATUS_INVALID_ARGUMENT` with nothing
    /// written. A larger value up to 65536 (a caller built against a later
    /// header) is accepted: the library writes the fields it knows and no
    /// byte past them; above 65536 it is rejected (likely a pointer).
    pub struct_size: u64,
    /// Largest distance of any sample point.
    pub max: f64,
    /// Mean distance, weighted by triangle area (the plain mean of the
    /// sample points when the triangles measured have no area).
    pub mean: f64,
    /// Root mean square distance, weighted likewise.
    pub rms: f64,
    /// Sample points measured.
    pub samples: u64,
    /// Sample points with no isosurface anywhere in the volume (left out).
    pub unresolved: u64,
}

impl Default for pmc_distance {
    /// All zero but `struct_size`, `size_of::<pmc_distance>()`.
    fn default() -> Self {
        pmc_distance {
            struct_size: std::mem::size_of::<pmc_distance>() as u64,
            max: 0.0,
            mean: 0.0,
            rms: 0.0,
            samples: 0,
            unresolved: 0,
        }
    }
}

/// Writes `d` into `*out`, all fields but `struct_size`.
///
/// # Safety
///
/// `out` must be writable for `PMC_DISTANCE_SIZE_V1` bytes (checked with
/// `struct_size::check`).
unsafe fn write(out: *mut pmc_distance, d: pmc_distance) {
    write_fields!(pmc_distance, out, d, max, mean, rms, samples, unresolved);
}

/// Measures how far a triangle mesh lies from the isosurface `isovalue`
/// of the trilinear interpolant of `volume`, independently of how the
/// mesh was made (any contour filter's output can be measured).
///
/// Each triangle is sampled on a barycentric grid with `density`
/// subdivisions per edge (`(density + 1)(density + 2) / 2` points: the
/// vertices, points along the edges and inside; 0 means the default, 4),
/// and each sample's distance to the isosurface is found by a certified
/// nearest-first search over boxes (to within 1e-5 cells plus 2 % of the
/// distance), not by the refinement's own projection.
///
/// `points` holds `point_count` xyz triples in world coordinates, where
/// sample `(i, j, k)` of `volume` lies at `origin + spacing * (i, j, k)`:
/// this function takes no index offset (`pmc_options_set_index_offset`),
/// it measures in the volume's own frame. The points of a mesh extracted
/// with an index offset `o` lie at `origin + spacing * (o + (i, j, k))`:
/// measure them against a copy of the volume whose `origin` is moved to
/// `origin + spacing * o` per axis (with the unmoved origin they would be
/// measured `o` samples away from their surface). `triangles` holds
/// `triangle_count` triples of point ids. On success stores the
/// statistics in `*out` and returns `PMC_STATUS_OK`. `out` is checked
/// first (not `NULL`, then its `struct_size`), then `volume` (not `NULL`,
/// then its `struct_size`): when `out` is `NULL` or its `struct_size` is
/// invalid nothing is written; on any later failure every field of `*out`
/// but `struct_size` is zeroed. Errors:
/// `PMC_STATUS_NULL_ARGUMENT` for a `NULL` `volume`, `volume->data` or
/// `out` (or `points`/`triangles` with a non-zero count);
/// `PMC_STATUS_INVALID_ARGUMENT` for an `out->struct_size` or a
/// `volume->struct_size` that is 0 or smaller than the struct's first
/// layout (see `pmc_distance` and `pmc_volume`), an invalid volume, a
/// non-finite isovalue or point, a point outside the volume's
/// representable index range (`(p - origin) / spacing` overflows) or
/// more than 1e60 cells outside the volume
/// (`precisemc::accuracy::MAX_MEASURE_REACH`), a point id negative or not below `point_count` (the message names the first
/// such triangle, its id and the point count), or `density > 1024`;
/// `PMC_STATUS_OUT_OF_MEMORY` when the copies of the arrays cannot be
/// made. Uses all cores, on the extraction's helper threads beside the
/// calling thread (where a limit on threads lets only some start, those,
/// the calling thread at least); the result does not depend on their
/// number (`pmc_measure` takes settings with a thread count and the
/// tolerances). The calling thread needs about 40 KiB of stack: give it
/// at least 256 KiB, as for `pmc_extract`.
///
/// # Safety
///
/// `volume` as for `pmc_extract`; `points` must be readable for
/// `3 * point_count` doubles and `triangles` for `3 * triangle_count`
/// integers (either may be `NULL` when its count is 0); `out` must be
/// `NULL` or valid for reading and writing its `struct_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn pmc_measure_distance(
    volume: *const pmc_volume,
    isovalue: f64,
    points: *const f64,
    point_count: u64,
    triangles: *const i64,
    triangle_count: u64,
    density: u32,
    out: *mut pmc_distance,
) -> PmcStatus {
    let options = Settings {
        measure: MeasureOptions {
            density: if density == 0 { 4 } else { density },
            ..MeasureOptions::default()
        },
        index_offset: None,
    };
    // SAFETY: forwarded contract.
    unsafe {
        measure_into(
            volume,
            isovalue,
            points,
            point_count,
            triangles,
            triangle_count,
            options,
            out,
        )
    }
}

/// `pmc_measure_distance` with the settings of `options` (`NULL`: the
/// defaults, those of `pmc_measure_options_new`): the density, the
/// tolerances each distance is certified to, the number of threads and,
/// since 0.2.2, whether `points` are index points with an index offset
/// (see the `pmc_measure_options_set_*` functions). Arguments, results
/// and errors otherwise as there (with index points, no check of
/// `(p - origin) / spacing`: the points are used as given). Since 0.2.1.
///
/// # Safety
///
/// As for `pmc_measure_distance`; `options` must be `NULL` or a live
/// handle from `pmc_measure_options_new`, not modified during the call.
#[no_mangle]
pub unsafe extern "C" fn pmc_measure(
    volume: *const pmc_volume,
    isovalue: f64,
    points: *const f64,
    point_count: u64,
    triangles: *const i64,
    triangle_count: u64,
    options: *const pmc_measure_options,
    out: *mut pmc_distance,
) -> PmcStatus {
    // SAFETY: forwarded contract.
    let options = unsafe { settings(options) };
    // SAFETY: forwarded contract.
    unsafe {
        measure_into(
            volume,
            isovalue,
            points,
            point_count,
            triangles,
            triangle_count,
            options,
            out,
        )
    }
}

/// The body of `pmc_measure_distance` and `pmc_measure`.
///
/// # Safety
///
/// As for `pmc_measure_distance`.
#[allow(clippy::too_many_arguments)]
unsafe fn measure_into(
    volume: *const pmc_volume,
    isovalue: f64,
    points: *const f64,
    point_count: u64,
    triangles: *const i64,
    triangle_count: u64,
    options: Settings,
    out: *mut pmc_distance,
) -> PmcStatus {
    status_boundary(|| {
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        // SAFETY: `out` is non-null and readable and writable for its `struct_size`
        // bytes per the contract, hence readable for the first 8.
        unsafe {
            struct_size::check(
                out.cast_const(),
                "pmc_distance",
                struct_size::PMC_DISTANCE_SIZE_V1,
            )?
        };
        // Zeroed, in case of a failure below.
        // SAFETY: `out` is writable for the version 1 size, just checked.
        unsafe { write(out, pmc_distance::default()) };
        // SAFETY: per the contract, `volume` is NULL or points to a volume.
        let v = unsafe { volume_ref(volume)? };
        // SAFETY: as for pmc_extract.
        let volume = unsafe { core_volume(v, options.index_offset.unwrap_or([0; 3]))? };
        // SAFETY: `points` is readable for 3 * point_count doubles.
        let pts = unsafe { array(points, point_count, "points")? };
        // SAFETY: `triangles` is readable for 3 * triangle_count integers.
        let ids = unsafe { array(triangles, triangle_count, "triangles")? };
        let mut index_points = Vec::new();
        index_points
            .try_reserve_exact(pts.len() / 3)
            .map_err(|_| failure(crate::Error::OutOfMemory(pts.len() * 8)))?;
        for (i, p) in pts.chunks_exact(3).enumerate() {
            if p.iter().any(|c| !c.is_finite()) {
                return Err(failure(crate::Error::InvalidMeasure(
                    "points must be finite",
                )));
            }
            if options.index_offset.is_some() {
                index_points.push([p[0], p[1], p[2]]);
                continue;
            }
            let q = [0, 1, 2].map(|a| (p[a] - v.origin[a]) / v.spacing[a]);
            // A finite point far outside the volume can overflow in index
            // space (a tiny spacing): not a NaN or infinite input.
            if q.iter().any(|c| !c.is_finite()) {
                return Err(Failure::invalid(format!(
                    "point {i} ({}, {}, {}) is outside the volume's representable index \
                     range: (point - origin) / spacing overflows",
                    crate::error::Number(p[0]),
                    crate::error::Number(p[1]),
                    crate::error::Number(p[2])
                )));
            }
            index_points.push(q);
        }
        let mut tris = Vec::new();
        tris.try_reserve_exact(ids.len() / 3)
            .map_err(|_| failure(crate::Error::OutOfMemory(ids.len() * 8)))?;
        for (n, t) in ids.chunks_exact(3).enumerate() {
            if let Some(&id) = t.iter().find(|&&id| id < 0) {
                return Err(Failure::invalid(format!(
                    "invalid mesh for the distance measure: triangle {n} has point id {id}; \
                     point ids must be >= 0"
                )));
            }
            tris.push([t[0] as u64, t[1] as u64, t[2] as u64]);
        }
        let d =
            measure(&volume, isovalue, &index_points, &tris, &options.measure).map_err(failure)?;
        // SAFETY: as above.
        unsafe {
            write(
                out,
                pmc_distance {
                    struct_size: 0, // not written
                    max: d.max,
                    mean: d.mean,
                    rms: d.rms,
                    samples: d.samples,
                    unresolved: d.unresolved,
                },
            )
        };
        Ok(())
    })
}

/// `3 * count` elements at `data` (`data` may be NULL when `count` is 0).
///
/// # Safety
///
/// `data` must be readable for `3 * count` elements when non-null.
unsafe fn array<'a, T>(data: *const T, count: u64, name: &str) -> Result<&'a [T], Failure> {
    if count == 0 {
        return Ok(&[]);
    }
    if data.is_null() {
        return Err(Failure::null(name));
    }
    let n = count
        .checked_mul(3)
        .filter(|&n| n as u128 * std::mem::size_of::<T>() as u128 <= isize::MAX as u128)
        .ok_or_else(|| Failure::invalid(format!("{name}: count {count} is too large")))?;
    if (data as usize) % std::mem::align_of::<T>() != 0 {
        return Err(Failure::invalid(format!("{name} is not aligned")));
    }
    // SAFETY: non-null, aligned, size fits isize; readable per the contract.
    Ok(unsafe { std::slice::from_raw_parts(data, n as usize) })
}
