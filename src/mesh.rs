//! The output: a welded triangle mesh with per-triangle levels and statistics.

/// Counters and timings of one extraction.
///
/// Equality (`==`) compares the counters and levels and ignores the wall
/// times (`time_*`), which differ from run to run: two extractions of the
/// same input with the same options compare equal, whatever the thread
/// count or executor.
#[derive(Debug, Clone, Default)]
pub struct Stats {
    /// Cells in the volume.
    pub cells: u64,
    /// Triangles produced by Marching Cubes, before refinement: counted
    /// cell by cell, before the flat triangles that cancel in pairs across
    /// a grid plane of samples equal to the isovalue are dropped, so the
    /// output can hold fewer (a 2x2x3 volume whose middle plane of samples
    /// equals the isovalue, the others below it: 4 Marching Cubes
    /// triangles, an empty output).
    pub mc_triangles: u64,
    /// Triangles in the output.
    pub output_triangles: u64,
    /// Points in the output.
    pub output_points: u64,
    /// Cells whose topology was decided by the trilinear test (ambiguous
    /// faces or body-diagonal cases); 0 in `Classic` mode.
    pub ambiguous_cells: u64,
    /// Cells skipped because a corner sample is NaN or infinite (with a
    /// cubic reconstruction filter, also cells whose 4x4x4 neighbourhood of
    /// samples holds one).
    pub skipped_nonfinite_cells: u64,
    /// Highest refinement level of an output triangle (the paper's maxL).
    pub max_level: u32,
    /// Mean refinement level over output triangles (the paper's meanL).
    pub mean_level: f64,
    /// Sample points tested against the ideal surface.
    pub samples_evaluated: u64,
    /// Split points inserted, each once per cell that inserts it (a point
    /// on a cell face, which both cells sharing the face insert and weld,
    /// counts in both).
    pub split_points: u64,
    /// Sample points whose gradient line left the cell without meeting
    /// the ideal surface, or met it farther away than the edge (triangle)
    /// sampled, on another sheet (interior ones are then decided by the
    /// nearest point of the surface in the cell).
    pub projection_failures: u64,
    /// Output triangles at the maximum level that still had a sample point
    /// farther than epsilon.
    pub faces_above_epsilon: u64,
    /// Cells refined splitting only the edges on their faces: their
    /// refined patch was unsound (two split points on one spot, a
    /// non-manifold edge, or a patch turned inside out), or, with the
    /// Classic topology, their table patch is not the trilinear
    /// interpolant's. Their interior edges and centres may stay farther
    /// than epsilon.
    pub cells_refined_on_faces_only: u64,
    /// Marching Cubes polygons cut along other diagonals before refining,
    /// because refinement could not bring a diagonal of the case table's
    /// onto the ideal surface (it crossed a part of the cell the surface
    /// never enters); 0 with refinement off.
    pub recut_polygons: u64,
    /// Cells where refinement stalled (a fold or neck of the surface
    /// narrower than the cell: edges still long and farther than epsilon
    /// at the last level) and that were meshed again on 4x4x4 sub-cells,
    /// joined to their neighbours by strips of triangles lying in the
    /// cell's faces; 0 with refinement off, below max level 3, with
    /// classic topology or a cubic filter.
    pub cells_on_subcells: u64,
    /// Whether the triangle cap stopped refinement below `max_level`
    /// (`effective_max_level < max_level`). Never with refinement off
    /// (`epsilon` or `max_level` 0): the Marching Cubes triangles are
    /// always kept, whatever the cap, and no level is lowered.
    pub budget_reached: bool,
    /// The refinement level actually used (below `max_level` when the cap
    /// was reached).
    pub effective_max_level: u32,
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
    /// Total wall time, seconds.
    pub time_total: f64,
}

impl PartialEq for Stats {
    fn eq(&self, o: &Self) -> bool {
        // Every field but the times, spelled out so that a new counter
        // cannot be left out unnoticed (the destructuring fails to compile).
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
            cells_refined_on_faces_only,
            recut_polygons,
            cells_on_subcells,
            budget_reached,
            effective_max_level,
            time_mc: _,
            time_refine: _,
            time_assemble: _,
            time_normals: _,
            time_total: _,
        } = self;
        *cells == o.cells
            && *mc_triangles == o.mc_triangles
            && *output_triangles == o.output_triangles
            && *output_points == o.output_points
            && *ambiguous_cells == o.ambiguous_cells
            && *skipped_nonfinite_cells == o.skipped_nonfinite_cells
            && *max_level == o.max_level
            && mean_level.to_bits() == o.mean_level.to_bits()
            && *samples_evaluated == o.samples_evaluated
            && *split_points == o.split_points
            && *projection_failures == o.projection_failures
            && *faces_above_epsilon == o.faces_above_epsilon
            && *cells_refined_on_faces_only == o.cells_refined_on_faces_only
            && *recut_polygons == o.recut_polygons
            && *cells_on_subcells == o.cells_on_subcells
            && *budget_reached == o.budget_reached
            && *effective_max_level == o.effective_max_level
    }
}

/// A welded, consistently oriented triangle mesh.
///
/// Normals of triangles `(p1 - p0) x (p2 - p0)` point towards lower values,
/// as in `vtkMarchingCubes`.
///
/// Equality (`==`) compares the arrays by value and the statistics without
/// their wall times (see [`Stats`]): the output is deterministic, so two
/// extractions of the same input with the same options compare equal
/// whatever the thread count.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Point positions in world coordinates.
    pub points: Vec<[f64; 3]>,
    /// The same points in continuous global index space (for interpolating
    /// other point arrays trilinearly).
    pub index_points: Vec<[f64; 3]>,
    /// Three point indices per triangle.
    pub triangles: Vec<[u64; 3]>,
    /// Unit normals per point, in world space, pointing towards lower
    /// values (empty when not requested); (0, 0, 0) where the data gives no
    /// direction (see [`crate::NormalMode`]).
    pub normals: Vec<[f32; 3]>,
    /// Scalar gradient per point, in sample value per world length unit,
    /// pointing towards higher values (empty unless
    /// [`crate::Options::gradients`]); (0, 0, 0) where the normal is, a
    /// component beyond float32's range infinite.
    pub gradients: Vec<[f32; 3]>,
    /// Refinement level per triangle (0 = Marching Cubes triangle).
    pub levels: Vec<u8>,
    /// Statistics of the extraction.
    pub stats: Stats,
}

impl Mesh {
    /// Gives the mesh's arrays back to the library for later extractions
    /// (as the C API's `pmc_mesh_free` does), instead of freeing them. A
    /// program that extracts again and again (a slider over the isovalue,
    /// a time series) then writes into memory that is already mapped: on a
    /// small volume, faulting the output's pages in afresh can take as long
    /// as contouring it. At most [`crate::RETAIN_LIMIT`] bytes are kept in
    /// all; [`crate::release_retained_memory`] frees them.
    pub fn recycle(self) {
        crate::recycle::give_mesh(self);
    }
}
