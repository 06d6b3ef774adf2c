//! Fixed data: the cube's numbering and the Marching Cubes case table.
//!
//! Kept apart from the case logic (`crate::mc`) so that the data can be
//! checked on its own, against VTK on the VTK side.

pub mod cube;
pub mod vtk_cases;

pub use vtk_cases::VTK_TRIANGLE_CASES;
