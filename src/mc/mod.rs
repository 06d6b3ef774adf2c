//! Marching Cubes inside one cell: which cell edges carry vertices and how
//! they form triangles. Vertex positions, welding and refinement live
//! elsewhere (`extract`, `refine`).
//!
//! A cell is described by `f[i] = sample[i] - isovalue` at its eight
//! corners (VTK order, [`crate::tables::cube`]). A corner is *inside* when
//! `f >= 0`, exactly as `vtkMarchingCubes` builds its case index, so a
//! sample equal to the isovalue counts as inside and its edge vertices sit
//! on the sample itself (they are merged there, see `extract`).

pub mod classic;
pub mod trilinear;

use crate::options::Topology;
use crate::tables::cube::NEEDS_TOPOLOGY_TEST;

/// Triangles of one cell, as triples of cell edge indices (0..12).
pub type EdgeTriangles = Vec<[u8; 3]>;

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
/// trilinear topology test ran (the cell was ambiguous).
#[inline]
pub fn cell_triangles(f: &[f64; 8], topology: Topology, out: &mut EdgeTriangles) -> bool {
    let case = case_index(f);
    if case == 0 || case == 255 {
        return false;
    }
    if topology == Topology::Trilinear && NEEDS_TOPOLOGY_TEST[case as usize] {
        trilinear::triangles(f, out);
        true
    } else {
        classic::triangles(case, out);
        false
    }
}
