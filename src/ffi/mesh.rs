//! `pmc_mesh`: the opaque result of an extraction, and its statistics.

use std::sync::OnceLock;

use super::buffer::hand_out;
use super::panic::{status_boundary, value_boundary, Failure};
use super::status::PmcStatus;
use super::struct_size::{self, write_fields};
use crate::volume::index_to_world;
use crate::{Mesh, Stats};

/// An extracted triangle mesh (opaque), owned by the caller from a
/// successful `pmc_extract` until `pmc_mesh_free`.
///
/// The mesh is welded (shared points appear once) and consistently
/// oriented: the normal of triangle `(p0, p1, p2)`, `(p1 - p0) x (p2 - p0)`,
/// points towards lower sample values, as in `vtkMarchingCubes`.
///
/// Arrays returned by the accessors are owned by the mesh: valid until
/// `pmc_mesh_free`, read-only, and `NULL` when empty. Apart from
/// `pmc_mesh_take_triangles`, no call changes a mesh, so any number of
/// threads may read it concurrently.
pub struct pmc_mesh {
    _private: [u8; 0],
}

/// What a handle points to: the core mesh, extracted without world
/// coordinates, and the mapping that gives them on first request (most
/// callers, such as the VTK filter, map the index points themselves, and
/// an extraction need not write 24 bytes a point that nobody reads).
struct Handle {
    mesh: Mesh,
    origin: [f64; 3],
    spacing: [f64; 3],
    world: OnceLock<Vec<[f64; 3]>>,
}

/// Wraps a core mesh, extracted from a volume with this origin and
/// spacing, into a new handle owned by the caller.
pub(crate) fn into_handle(mesh: Mesh, origin: [f64; 3], spacing: [f64; 3]) -> *mut pmc_mesh {
    let handle = Handle {
        mesh,
        origin,
        spacing,
        world: OnceLock::new(),
    };
    Box::into_raw(Box::new(handle)).cast()
}

/// The handle's contents, `None` for `NULL`.
///
/// # Safety
///
/// `p` must be `NULL` or a live handle from `pmc_extract`.
unsafe fn handle<'a>(p: *const pmc_mesh) -> Option<&'a Handle> {
    // SAFETY: a non-null handle came from `into_handle` and is live.
    unsafe { p.cast::<Handle>().as_ref() }
}

/// The mesh behind a handle, `None` for `NULL`.
///
/// # Safety
///
/// `p` must be `NULL` or a live handle from `pmc_extract`.
unsafe fn mesh<'a>(p: *const pmc_mesh) -> Option<&'a Mesh> {
    // SAFETY: forwarded contract.
    unsafe { handle(p) }.map(|h| &h.mesh)
}

/// `NULL` for an empty slice, else its first element.
fn ptr_or_null<T, U>(v: &[T]) -> *const U {
    if v.is_empty() {
        std::ptr::null()
    } else {
        v.as_ptr().cast()
    }
}

/// Counters and timings of one extraction, filled by `pmc_mesh_stats`.
/// Counts are exact; times are wall-clock seconds.
///
/// Set `struct_size` to `sizeof(pmc_stats)` before the call; the library
/// fills the other fields. (In Rust, `Default` sets it.)
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct pmc_stats {
    /// Size in bytes of the caller's struct, set by the caller to
    /// `sizeof(pmc_stats)` and never written by the library. No default:
    /// 0, or less than the size of the first `pmc_stats` layout (152 bytes
    /// on 64-bit platforms), is `PMC_STATUS_INVALID_ARGUMENT` with nothing
    /// written. A larger value up to 65536 (a caller built against a later
    /// header) is accepted: the library writes the fields it knows and no
    /// byte past them; above 65536 it is rejected (likely a pointer).
    pub struct_size: u64,
    /// Cells in the volume, `(dims[0]-1)(dims[1]-1)(dims[2]-1)`.
    pub cells: u64,
    /// Triangles produced by Marching Cubes, before refinement, counted
    /// before the flat triangles that cancel in pairs across a plane of
    /// samples equal to the isovalue are dropped (the output can hold
    /// fewer).
    pub mc_triangles: u64,
    /// Triangles in the output (= `pmc_mesh_triangle_count` until
    /// `pmc_mesh_take_triangles` takes them).
    pub output_triangles: u64,
    /// Points in the output (= `pmc_mesh_point_count`).
    pub output_points: u64,
    /// Cells whose topology was decided by the trilinear test; 0 with
    /// `PMC_TOPOLOGY_CLASSIC`.
    pub ambiguous_cells: u64,
    /// Cells skipped because a corner sample is NaN or infinite (with a
    /// cubic reconstruction filter, also cells whose 4x4x4 neighbourhood of
    /// samples holds one).
    pub skipped_nonfinite_cells: u64,
    /// Sample points tested against the ideal surface.
    pub samples_evaluated: u64,
    /// Split points inserted, each once per cell that inserts it (a point
    /// on a cell face, which both cells sharing the face insert and weld,
    /// counts in both).
    pub split_points: u64,
    /// Sample points whose gradient line left the cell without meeting the
    /// ideal surface, or met it farther away than the edge (triangle)
    /// sampled, on another sheet (interior ones are then decided by the
    /// nearest point of the surface in the cell).
    pub projection_failures: u64,
    /// Output triangles at the maximum level that still had a sample point
    /// farther than epsilon.
    pub faces_above_epsilon: u64,
    /// Highest refinement level of an output triangle.
    pub max_level: u32,
    /// The refinement level actually used (below the requested max level
    /// when the triangle cap was reached).
    pub effective_max_level: u32,
    /// Mean refinement level over output triangles.
    pub mean_level: f64,
    /// 1 if the triangle cap stopped refinement below the requested max
    /// level (`effective_max_level` below it), else 0. Always 0 with
    /// refinement off (epsilon or max level 0): the Marching Cubes
    /// triangles are kept whatever the cap, and no level is lowered.
    pub budget_reached: u8,
    /// Wall time spent in Marching Cubes, seconds: the rest of the
    /// passes over the cells once `time_refine` is taken.
    pub time_mc: f64,
    /// Wall time spent in refinement, seconds: the passes' wall time in
    /// the proportion measured on the refined cells (all of a slab's
    /// first 64, then one in eight; an estimate).
    pub time_refine: f64,
    /// Wall time spent welding and assembling the output, seconds.
    pub time_assemble: f64,
    /// Wall time spent on normals and gradients, seconds.
    pub time_normals: f64,
    /// Total wall time of the extraction, seconds.
    pub time_total: f64,
}

impl Default for pmc_stats {
    /// All zero but `struct_size`, `size_of::<pmc_stats>()`.
    fn default() -> Self {
        pmc_stats {
            struct_size: std::mem::size_of::<pmc_stats>() as u64,
            cells: 0,
            mc_triangles: 0,
            output_triangles: 0,
            output_points: 0,
            ambiguous_cells: 0,
            skipped_nonfinite_cells: 0,
            samples_evaluated: 0,
            split_points: 0,
            projection_failures: 0,
            faces_above_epsilon: 0,
            max_level: 0,
            effective_max_level: 0,
            mean_level: 0.0,
            budget_reached: 0,
            time_mc: 0.0,
            time_refine: 0.0,
            time_assemble: 0.0,
            time_normals: 0.0,
            time_total: 0.0,
        }
    }
}

impl From<&Stats> for pmc_stats {
    fn from(s: &Stats) -> Self {
        // Destructured so that a new core field fails to compile here.
        let Stats {
            cells,
            mc_triangles,
            output_triangles,
            output_points,
            ambiguous_cells,
            skipped_nonfinite_cells,
            max_level,
            mean_level,
            samples_evaluated,
            split_points,
            projection_failures,
            faces_above_epsilon,
            budget_reached,
            effective_max_level,
            time_mc,
            time_refine,
            time_assemble,
            time_normals,
            time_total,
            // Have their own accessors, not fields of `pmc_stats` (which may
            // grow, see `struct_size`, but keeps its first layout's fields).
            cells_refined_on_faces_only: _,
            recut_polygons: _,
            cells_on_subcells: _,
        } = s.clone();
        pmc_stats {
            struct_size: std::mem::size_of::<pmc_stats>() as u64,
            cells,
            mc_triangles,
            output_triangles,
            output_points,
            ambiguous_cells,
            skipped_nonfinite_cells,
            samples_evaluated,
            split_points,
            projection_failures,
            faces_above_epsilon,
            max_level,
            effective_max_level,
            mean_level,
            budget_reached: budget_reached as u8,
            time_mc,
            time_refine,
            time_assemble,
            time_normals,
            time_total,
        }
    }
}

/// Number of points; 0 for `NULL`.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_point_count(mesh: *const pmc_mesh) -> u64 {
    // SAFETY: forwarded contract.
    value_boundary(0, || {
        unsafe { self::mesh(mesh) }.map_or(0, |m| m.index_points.len() as u64)
    })
}

/// Number of triangles; 0 for `NULL`.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_triangle_count(mesh: *const pmc_mesh) -> u64 {
    // SAFETY: forwarded contract.
    value_boundary(0, || {
        unsafe { self::mesh(mesh) }.map_or(0, |m| m.triangles.len() as u64)
    })
}

/// Point positions in world coordinates: `3 * pmc_mesh_point_count`
/// doubles, x, y, z per point, `origin + spacing * index point` per axis
/// (bit-identical to the core's `Mesh::points`). Computed on the first
/// call (24 bytes a point; thread-safe), so a caller that maps
/// `pmc_mesh_index_points` itself never pays for them. `NULL` for a
/// `NULL` or empty mesh, and if their memory cannot be allocated.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_points(mesh: *const pmc_mesh) -> *const f64 {
    value_boundary(std::ptr::null(), || {
        // SAFETY: forwarded contract.
        let Some(h) = (unsafe { handle(mesh) }) else {
            return std::ptr::null();
        };
        if let Some(world) = h.world.get() {
            return ptr_or_null(world);
        }
        let index = &h.mesh.index_points;
        let mut world = Vec::new();
        if world.try_reserve_exact(index.len()).is_err() {
            return std::ptr::null();
        }
        world.extend(
            index
                .iter()
                .map(|&p| index_to_world(h.origin, h.spacing, p)),
        );
        // Two threads racing here computed the same values; one is kept.
        let _ = h.world.set(world);
        h.world.get().map_or(std::ptr::null(), |w| ptr_or_null(w))
    })
}

/// The same points in continuous global index space (sample units, the
/// index offset included): `3 * pmc_mesh_point_count` doubles. Useful to
/// interpolate other point data of the volume trilinearly. `NULL` for a
/// `NULL` or empty mesh.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_index_points(mesh: *const pmc_mesh) -> *const f64 {
    value_boundary(std::ptr::null(), || {
        // SAFETY: forwarded contract.
        unsafe { self::mesh(mesh) }.map_or(std::ptr::null(), |m| ptr_or_null(&m.index_points))
    })
}

/// Triangles: `3 * pmc_mesh_triangle_count` zero-based point indices, each
/// in `[0, pmc_mesh_point_count)`. `NULL` for a `NULL` or empty mesh.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_triangles(mesh: *const pmc_mesh) -> *const i64 {
    value_boundary(std::ptr::null(), || {
        // SAFETY: forwarded contract. The core stores `u64` indices below
        // the point count (< 2^63), which read the same as `i64`.
        unsafe { self::mesh(mesh) }.map_or(std::ptr::null(), |m| ptr_or_null(&m.triangles))
    })
}

/// Moves the triangles out of `mesh` to the caller, without a copy (to be
/// adopted, say, as the connectivity of a `vtkCellArray`): returns the
/// array `pmc_mesh_triangles` returned, `3 * n` point indices, and stores
/// `n` in `*out_count` (when `out_count` is not `NULL`). The caller owns
/// the array and releases it with `pmc_buffer_free`. Afterwards the mesh
/// has no triangles (`pmc_mesh_triangles` gives `NULL` and
/// `pmc_mesh_triangle_count` 0); its points, per-triangle levels (still
/// `n` bytes) and statistics stay. Returns `NULL` (and 0) for a `NULL`
/// mesh or one without triangles.
///
/// The one call that changes a mesh: it must not run concurrently with
/// other calls on the same mesh.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`, not used by
/// another thread during the call; `out_count` must be `NULL` or writable.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_take_triangles(
    mesh: *mut pmc_mesh,
    out_count: *mut u64,
) -> *mut i64 {
    value_boundary(std::ptr::null_mut(), || {
        // SAFETY: per the contract, a non-null handle came from
        // `into_handle`, is live and used by no one else during the call.
        let h = unsafe { mesh.cast::<Handle>().as_mut() };
        let taken = h.map_or_else(Vec::new, |h| std::mem::take(&mut h.mesh.triangles));
        if !out_count.is_null() {
            // SAFETY: non-null and writable per the contract.
            unsafe { out_count.write_unaligned(taken.len() as u64) };
        }
        // The core's `u64` indices are below the point count (< 2^63) and
        // read the same as `i64`.
        hand_out(taken)
    })
}

/// Unit normals per point, pointing towards lower sample values:
/// `3 * pmc_mesh_point_count` floats; (0, 0, 0) where the gradient
/// vanishes (in gradient mode, the central differences too) or is not
/// finite in either mode (next to NaN or infinite samples: gradient mode
/// takes a cell around the point whose samples are finite, central
/// differences leave such samples out, and each mode falls back on the
/// other). `NULL`
/// when normals were not requested
/// (`PMC_NORMALS_NONE`) and for a `NULL` or empty mesh.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_normals(mesh: *const pmc_mesh) -> *const f32 {
    value_boundary(std::ptr::null(), || {
        // SAFETY: forwarded contract.
        unsafe { self::mesh(mesh) }.map_or(std::ptr::null(), |m| ptr_or_null(&m.normals))
    })
}

/// The scalar gradient at each point, in sample value per world length
/// unit (the index-space gradient divided by the volume's spacing per
/// axis), pointing towards higher sample values and not normalised, as
/// `vtkFlyingEdges3D`'s "Gradients": `3 * pmc_mesh_point_count` floats.
/// Computed as the normals of the mode set with `pmc_options_set_normals`
/// are (the exact trilinear gradient with `PMC_NORMALS_NONE`): each normal
/// is its point's negated, normalised gradient, and (0, 0, 0) where the
/// normal is; a component beyond float's range is infinite. `NULL` when
/// gradients were not requested (`pmc_options_set_gradients`) and for a
/// `NULL` or empty mesh.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_gradients(mesh: *const pmc_mesh) -> *const f32 {
    value_boundary(std::ptr::null(), || {
        // SAFETY: forwarded contract.
        unsafe { self::mesh(mesh) }.map_or(std::ptr::null(), |m| ptr_or_null(&m.gradients))
    })
}

/// Refinement level per triangle (0 = a Marching Cubes triangle): one
/// byte per output triangle (`pmc_stats.output_triangles`; still there
/// after `pmc_mesh_take_triangles`). `NULL` for a `NULL` mesh or one that
/// never had triangles.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_triangle_levels(mesh: *const pmc_mesh) -> *const u8 {
    value_boundary(std::ptr::null(), || {
        // SAFETY: forwarded contract.
        unsafe { self::mesh(mesh) }.map_or(std::ptr::null(), |m| ptr_or_null(&m.levels))
    })
}

/// Copies the statistics of the extraction that produced `mesh` into
/// `*out`: every field but `struct_size`, which the caller sets to
/// `sizeof(pmc_stats)` before the call.
///
/// Returns, with nothing written, `PMC_STATUS_NULL_ARGUMENT` if `mesh` or
/// `out` is `NULL`, and `PMC_STATUS_INVALID_ARGUMENT` if
/// `out->struct_size` is 0 or smaller than the first `pmc_stats` layout.
/// `out` need not be aligned.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`; `out` must
/// be `NULL` or valid for reading and writing its `struct_size` bytes.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_stats(mesh: *const pmc_mesh, out: *mut pmc_stats) -> PmcStatus {
    status_boundary(|| {
        // SAFETY: forwarded contract.
        let m = unsafe { self::mesh(mesh) }.ok_or(Failure::null("mesh"))?;
        if out.is_null() {
            return Err(Failure::null("out"));
        }
        // SAFETY: `out` is non-null and readable for its first 8 bytes per
        // the contract.
        unsafe {
            struct_size::check(
                out.cast_const(),
                "pmc_stats",
                struct_size::PMC_STATS_SIZE_V1,
            )?
        };
        // SAFETY: `out` is writable for the version 1 size, just checked;
        // the fields are written unaligned.
        write_fields!(
            pmc_stats,
            out,
            pmc_stats::from(&m.stats),
            cells,
            mc_triangles,
            output_triangles,
            output_points,
            ambiguous_cells,
            skipped_nonfinite_cells,
            samples_evaluated,
            split_points,
            projection_failures,
            faces_above_epsilon,
            max_level,
            effective_max_level,
            mean_level,
            budget_reached,
            time_mc,
            time_refine,
            time_assemble,
            time_normals,
            time_total,
        );
        Ok(())
    })
}

/// Cells refined splitting only the edges on their faces: their refined
/// patch was unsound (two split points on one spot, a non-manifold edge,
/// or a patch turned inside out), or, with the Classic topology, their
/// table patch is not the trilinear interpolant's (see `cells_refined_on_faces_only` in the
/// README). 0 for a `NULL` mesh. Not a field of `pmc_stats`.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_cells_refined_on_faces_only(mesh: *const pmc_mesh) -> u64 {
    value_boundary(0, || {
        // SAFETY: forwarded contract.
        unsafe { self::mesh(mesh) }.map_or(0, |m| m.stats.cells_refined_on_faces_only)
    })
}

/// Cells where refinement stalled on a fold or neck of the ideal surface
/// and that were meshed again on 4x4x4 sub-cells (see `cells_on_subcells`
/// in the README). 0 for a `NULL` mesh and with refinement off. Not a
/// field of `pmc_stats`.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_cells_on_subcells(mesh: *const pmc_mesh) -> u64 {
    value_boundary(0, || {
        // SAFETY: forwarded contract.
        unsafe { self::mesh(mesh) }.map_or(0, |m| m.stats.cells_on_subcells)
    })
}

/// Marching Cubes polygons cut along other diagonals before refinement,
/// because refinement could not bring a diagonal of the case table's onto
/// the ideal surface (see `recut_polygons` in the README). 0 for a `NULL`
/// mesh and with refinement off. Not a field of `pmc_stats`.
///
/// # Safety
///
/// `mesh` must be `NULL` or a live handle from `pmc_extract`.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_recut_polygons(mesh: *const pmc_mesh) -> u64 {
    value_boundary(0, || {
        // SAFETY: forwarded contract.
        unsafe { self::mesh(mesh) }.map_or(0, |m| m.stats.recut_polygons)
    })
}

/// Releases a mesh and all its arrays. `NULL` is accepted and ignored.
///
/// # Safety
///
/// `mesh` must be `NULL` or a handle from `pmc_extract` not yet freed; it
/// and every array obtained from it must not be used afterwards.
#[no_mangle]
pub unsafe extern "C" fn pmc_mesh_free(mesh: *mut pmc_mesh) {
    value_boundary((), || {
        if !mesh.is_null() {
            // SAFETY: per the contract, `mesh` came from `into_handle` and
            // is freed once.
            let h = unsafe { Box::from_raw(mesh.cast::<Handle>()) };
            // Its arrays are kept for the next extraction (see
            // `pmc_release_memory`).
            let Handle { mesh, world, .. } = *h;
            crate::recycle::give_mesh(mesh);
            if let Some(w) = world.into_inner() {
                crate::recycle::POINTS.give(w);
            }
        }
    })
}
