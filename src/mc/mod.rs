//! Marching Cubes inside one cell: which cell edges carry vertices and how
//! they form triangles. Vertex positions, welding and refinement live
//! elsewhere (`extract`, `refine`).
//!
//! A cell is described by `f[i] = sample[i] - isovalue` at its eight
//! corners (VTK order, [`crate::tables::cube`]). A corner is *inside* when
//! `f >= 0`, exactly as `vtkMarchingCubes` builds its case index, so a
//! sample equal to the isovalue counts as inside and its edge vertices sit
//! on the sample itself (they are merged there, see `slab_pass`).

pub mod classic;
pub mod topology_check;
pub mod trilinear;

use crate::options::Topology;
use crate::tables::cube::NEEDS_TOPOLOGY_TEST;

/// The patch of one cell: triangles as triples of vertex ids, where ids
/// 0..12 are cell edges and `12 + k` is the interior point `extra[k]`
/// (local coordinates, on the surface).
#[derive(Debug, Clone, Default)]
pub struct Patch {
    /// Triangles.
    pub tris: Vec<[u8; 3]>,
    /// Interior points.
    pub extra: Vec<[f64; 3]>,
    /// Whether a fan around an interior point may be centred at a pinch
    /// point of `S_K` (set for refinement; default off: plain Marching
    /// Cubes keeps the centroid's projection, which costs less).
    pub pinch_fans: bool,
}

impl Patch {
    /// Empties the patch, keeping its memory.
    pub fn clear(&mut self) {
        self.tris.clear();
        self.extra.clear();
    }
}

/// Case index: bit `i` set when corner `i` is inside (`f >= 0`).
#[inline(always)]
pub fn case_index(f: &[f64; 8]) -> u8 {
    let mut c = 0u8;
    for (i, v) in f.iter().enumerate() {
        c |= ((*v >= 0.0) as u8) << i;
    }
    c
}

/// Appends the triangles of one cell to `out`; returns whether the
/// trilinear topology test ran (the cell was ambiguous, with finite
/// corners; a NaN or infinite corner gets the table's triangles).
#[inline]
pub fn cell_triangles(f: &[f64; 8], topology: Topology, out: &mut Patch) -> bool {
    cell_triangles_of_case(case_index(f), f, topology, out)
}

/// [`cell_triangles`] for a cell whose case index the caller already has
/// (`case == case_index(f)`): the extraction reads it from its case row,
/// and recomputing it took a tenth of plain Marching Cubes' cell loop.
///
/// # Panics
///
/// With debug assertions on, when `case` is not `case_index(f)` (in a
/// release build the triangles are those of `case`).
#[inline]
pub fn cell_triangles_of_case(case: u8, f: &[f64; 8], topology: Topology, out: &mut Patch) -> bool {
    debug_assert_eq!(case, case_index(f));
    if case == 0 || case == 255 {
        return false;
    }
    if topology_decides(case, f, topology) {
        trilinear::triangles(f, out.pinch_fans, &mut out.tris, &mut out.extra);
        true
    } else {
        classic::triangles(case, &mut out.tris);
        false
    }
}

/// The triangles of one cell (`case == case_index(f)`), its interior
/// points, and whether the trilinear topology test ran: the triangles are
/// borrowed from the fixed table, without a copy, unless the test decides
/// them into `out` (emptied first).
///
/// # Panics
///
/// As [`cell_triangles_of_case`], when `case` is not `case_index(f)`.
#[inline]
pub fn cell_triangles_borrowed<'a>(
    case: u8,
    f: &[f64; 8],
    topology: Topology,
    out: &'a mut Patch,
) -> (&'a [[u8; 3]], &'a [[f64; 3]], bool) {
    debug_assert_eq!(case, case_index(f));
    out.clear();
    if topology_decides(case, f, topology) {
        trilinear::triangles(f, out.pinch_fans, &mut out.tris, &mut out.extra);
        (&out.tris, &out.extra, true)
    } else {
        (classic::case_triangles(case), &out.extra, false)
    }
}

/// Whether the cell's triangles come from the trilinear topology test
/// rather than the fixed table. Not for a cell with a NaN or infinite
/// corner (the extraction skips those; the test's arithmetic would have
/// no meaning there): the table's triangles then.
#[inline(always)]
fn topology_decides(case: u8, f: &[f64; 8], topology: Topology) -> bool {
    topology == Topology::Trilinear
        && NEEDS_TOPOLOGY_TEST[case as usize]
        && f.iter().all(|v| v.is_finite())
}
