//! # PreciseMC
//!
//! Isosurfaces of regular volumes that follow the data more closely than
//! Marching Cubes: the method of Allamandri, Cignoni, Montani and Scopigno,
//! "Adaptively adjusting Marching Cubes output to fit a trilinear
//! reconstruction filter".
//!
//! 1. Marching Cubes runs with ambiguities resolved so that, inside every
//!    cell, the mesh has the topology of the isosurface `S_K` of the
//!    trilinear interpolant ([`Topology::Trilinear`], the default), or with
//!    the table of `vtkMarchingCubes` ([`Topology::Classic`]).
//! 2. Each triangle is then refined adaptively ([`Rule`] A, A1, A2 or B):
//!    sample points farther than `epsilon` (cell units) from `S_K` become
//!    split points, moved onto `S_K` along the gradient line, recursively up
//!    to `max_level`.
//!
//! The mesh is welded, consistently oriented (normals towards lower
//! values), crack-free, and bit-identical for any thread count and any
//! split of the volume into pieces that hold the cells across their cuts
//! (one layer of ghost cells; two with the cubic filters, the whole
//! volume with B-spline Interpolating) and keep their own cells'
//! triangles, as the VTK filter does. Pieces that share only their
//! boundary layer of samples meet with bit-identical points for the
//! trilinear filter, but not always with the serial run's triangles and
//! normals: normals and gradients at a point on a cut take the cell
//! beyond it, a plane of samples equal to the isovalue on a cut leaves
//! flat triangles that only the cell across cancels, and refinement with
//! the trilinear topology from max level 3 up may mesh a cell again on
//! sub-cells, whose strip in a face is dropped only where the neighbour is
//! meshed again too (see docs/how-it-works.md).
//!
//! ```
//! use precisemc::{extract, Options, Volume};
//! // A sphere of radius 5 sampled on a 16^3 grid.
//! let n = 16u64;
//! let mut data = Vec::new();
//! for k in 0..n { for j in 0..n { for i in 0..n {
//!     let (x, y, z) = (i as f32 - 7.5, j as f32 - 7.5, k as f32 - 7.5);
//!     data.push((x * x + y * y + z * z).sqrt());
//! }}}
//! let volume = Volume::new(&data, [n, n, n]);
//! let mesh = extract(&volume, 5.0, &Options::default()).unwrap();
//! // Refinement splits the Marching Cubes triangles (none of this
//! // sphere's samples equals the isovalue, so none cancel in pairs).
//! assert!(mesh.stats.output_triangles >= mesh.stats.mc_triangles);
//! assert_eq!(mesh.triangles.len() as u64, mesh.stats.output_triangles);
//! ```

#![warn(missing_docs)]
// Numeric kernels index several parallel arrays by one loop variable.
#![allow(clippy::needless_range_loop)]

mod error;
mod executor;
mod mesh;
mod options;
mod volume;

pub mod accuracy;
pub mod cubic;
pub mod ffi;
pub mod filter;
pub mod mc;
pub mod project;
pub mod samples;
pub mod tables;

mod assemble;
mod cell_refine;
mod cell_remesh;
mod diagonals;
mod extract;
mod flat_map;
mod fork;
mod helpers;
mod layers;
mod magnitude;
mod memory;
mod near_bound;
mod nearest;
mod normals;
mod os_thread;
mod par;
mod point_key;
mod recycle;
mod refine;
mod slab_pass;
mod slabs;
mod subcells;
#[cfg(test)]
mod test_rng;

pub use error::Error;
pub use executor::{Executor, SerialExecutor};
pub use extract::{extract, extract_with_executor, extract_with_progress, MAX_THREADS};
/// The vector crate of the public signatures that take points
/// (`glam::DVec3`, in local cell coordinates), re-exported so that callers
/// use the same version: `precisemc::glam::DVec3`.
pub use glam;
pub use mesh::{Mesh, Stats};
pub use options::{NormalMode, Options, Reconstruction, Rule, Topology};
pub use recycle::{release_retained_memory, retained_bytes, RETAIN_LIMIT};
pub use volume::{Samples, Scalar, ScalarType, Volume, MAX_DIMENSION, MAX_INDEX_OFFSET};

/// Highest accepted `max_level`. Each level can multiply a triangle by 4
/// (6 under rules A2 and B), and levels beyond 10 only add triangles far
/// below any useful epsilon.
pub const MAX_LEVEL_LIMIT: u32 = 10;

/// Refinement never takes the output past this many triangles, whatever
/// the options, which bounds the memory a tiny epsilon with a high max
/// level can take (about 64 bytes per triangle with its share of points:
/// some 16 GB (15 GiB) at the cap; with less memory, set
/// [`Options::max_triangles`]). Refinement stops at the highest level that
/// fits, like a caller's cap; the Marching Cubes triangles are always
/// kept, so a volume whose plain Marching Cubes surface is larger still
/// gets it whole.
pub const HARD_TRIANGLE_CAP: u64 = 250_000_000;
