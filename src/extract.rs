//! The extraction driver: validation, the parallel pass over slabs of
//! cells, welding, the triangle cap, progress and cancellation.
//!
//! Determinism: the volume is cut into slabs of cell layers along z, each
//! processed by one worker in cell order (k, j, i). Vertices are numbered
//! in order of first use in that global cell order, and points are welded
//! when their global index coordinates are bit-identical (which is exactly
//! how `vtkMarchingCubes` merges points, samples equal to the isovalue
//! included). Neither depends on the number or size of slabs, so the output
//! is identical for any thread count.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;

use crate::assemble::{assemble, in_grid_plane};
use crate::cubic::{prefilter, BSplineKernel, CatmullRomKernel, Tricubic};
use crate::diagonals::choose_diagonals;
use crate::executor::Executor;
use crate::filter::{ReconstructionFilter, Trilinear};
use crate::flat_map::FlatMap;
use crate::helpers::with_helpers;
use crate::layers::{self, LayerScratch, ScratchPool};
use crate::mc::topology_check::classic_is_trilinear;
use crate::mc::{cell_triangles_borrowed, classic, Patch};
use crate::memory::advise_huge_pages;
use crate::mesh::{Mesh, Stats};
use crate::near_bound;
use crate::normals::{compute_gradients, compute_normals};
use crate::options::{Options, Reconstruction, Topology};
use crate::par::{Exec, OnCaller};
use crate::project::edge_crossing;
use crate::recycle;
use crate::refine::{
    edge_key, faces_like_marching_cubes, shared_fixed_axes, sound_patch, soundly_connected,
    vector_area, Counters, EdgeCache, Refinable, Refiner, Tri,
};
use crate::subcells;
use crate::tables::cube::{on_one_face, CORNERS, CROSSED_EDGES, EDGES, EDGE_AXIS};
use crate::volume::{Grid, Scalar, Volume};
use crate::{Error, HARD_TRIANGLE_CAP, MAX_LEVEL_LIMIT};

/// A small multiplicative hasher for point keys (no DoS concern: keys are
/// our own coordinates).
#[derive(Default)]
pub(crate) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        // Keys arrive as one slice of 24 bytes: mix them a word at a time.
        let mut words = bytes.chunks_exact(8);
        for w in &mut words {
            self.write_u64(u64::from_le_bytes(w.try_into().unwrap()));
        }
        for b in words.remainder() {
            self.write_u64(*b as u64);
        }
    }
    fn write_u64(&mut self, n: u64) {
        self.0 = (self.0.rotate_left(5) ^ n).wrapping_mul(0x51_7c_c1_b7_27_22_0a_95);
    }
}

pub(crate) type KeyMap<V> = HashMap<[u64; 3], V, BuildHasherDefault<KeyHasher>>;

/// The float next to the finite `x` towards +infinity (`up`) or
/// -infinity (`f64::next_up` / `next_down`, newer than the crate's
/// minimum Rust). (Towards the infinity it is, an infinite `x` gives NaN.)
pub(crate) fn next_float(x: f64, up: bool) -> f64 {
    if x == 0.0 {
        let tiny = f64::from_bits(1);
        return if up { tiny } else { -tiny };
    }
    let bits = x.to_bits();
    f64::from_bits(if (x > 0.0) == up { bits + 1 } else { bits - 1 })
}

#[inline]
pub(crate) fn key(p: DVec3) -> [u64; 3] {
    // +0.0 and -0.0 weld together.
    [
        (p.x + 0.0).to_bits(),
        (p.y + 0.0).to_bits(),
        (p.z + 0.0).to_bits(),
    ]
}

/// Extracts the isosurface `isovalue` of `volume`.
///
/// See the crate documentation for the method and [`Options`] for the
/// settings. Returns an error for invalid input; never panics on any input.
pub fn extract(volume: &Volume<'_>, isovalue: f64, options: &Options) -> Result<Mesh, Error> {
    extract_with_progress(
        volume,
        isovalue,
        options,
        &mut |_| ControlFlow::Continue(()),
    )
}

/// Like [`extract`], reporting progress.
///
/// `progress(fraction)` is called on the calling thread, first with 0.0,
/// then while the work runs (the calling thread works too, and reports
/// after each of its cell layers, and within a layer, at most every
/// 20 ms, between refined cells, every few thousand refinement steps, and
/// of steps of meshing a cell again on sub-cells, and while it waits for
/// the helper threads to finish theirs), and last with
/// 1.0 on success. (Plain
/// Marching Cubes of up to 4 Mi cells on one thread, a few milliseconds
/// of work, runs with no call in between.)
/// Returning `ControlFlow::Break(())` stops the extraction once each
/// worker finishes the cell layer it is on (within a few milliseconds for
/// layers of up to about a million cells; a layer of very many cells
/// takes longer); it then returns [`Error::Aborted`], also when that is
/// the answer to the last call, with 1.0 (the mesh is then dropped). Welding the
/// workers' outputs into one mesh (before the call with 0.97) and the
/// normals and gradients (after it) make no calls: on meshes of tens of millions of
/// triangles they take seconds, during which no stop can be asked.
pub fn extract_with_progress(
    volume: &Volume<'_>,
    isovalue: f64,
    options: &Options,
    progress: &mut dyn FnMut(f64) -> ControlFlow<()>,
) -> Result<Mesh, Error> {
    let how = How {
        min_slab_cells: MIN_CELLS_PER_SLAB,
        min_slab_layers: MIN_LAYERS_PER_SLAB,
        min_helper_cells: MIN_CELLS_FOR_HELPERS,
        world_points: true,
        executor: None,
        serial_assembly_triangles: SERIAL_ASSEMBLY_TRIANGLES,
        extreme: None,
        sample_scale: [1.0, 1.0],
    };
    extract_in_slabs(volume, isovalue, options, progress, how)
}

/// Like [`extract_with_progress`], with the parallel steps run as tasks of
/// the host's `executor` instead of on the library's own helper threads
/// (see [`Executor`]); [`Options::threads`] is then not used: the volume is cut
/// for [`Executor::concurrency`] workers. The output is bit-identical to
/// [`extract`]'s.
///
/// `progress` is still called only on the calling thread: while a pass
/// runs, within the tasks the executor happens to run on it (after each
/// cell layer and, at most every 20 ms, between refined cells and
/// refinement steps) and after each such task (a
/// pool that lets the calling thread work, as TBB's does, reports
/// throughout a pass; one that does not reports only between passes).
/// Cancelling takes effect at the next layer of cells of every running
/// task.
pub fn extract_with_executor(
    volume: &Volume<'_>,
    isovalue: f64,
    options: &Options,
    executor: &dyn Executor,
    progress: &mut dyn FnMut(f64) -> ControlFlow<()>,
) -> Result<Mesh, Error> {
    let how = How {
        min_slab_cells: MIN_CELLS_PER_LENT_SLAB,
        min_slab_layers: MIN_LAYERS_PER_SLAB,
        min_helper_cells: MIN_CELLS_FOR_HELPERS,
        world_points: true,
        executor: Some(executor),
        serial_assembly_triangles: SERIAL_ASSEMBLY_TRIANGLES,
        extreme: None,
        sample_scale: [1.0, 1.0],
    };
    extract_in_slabs(volume, isovalue, options, progress, how)
}

/// [`extract_with_progress`] leaving [`Mesh::points`] empty: for callers
/// that map the index points to world themselves (the C API computes them
/// on request), so that an extraction does not write 24 bytes a point that
/// nobody reads. Runs on `executor` when one is given (see
/// [`extract_with_executor`]).
pub(crate) fn extract_index_points(
    volume: &Volume<'_>,
    isovalue: f64,
    options: &Options,
    executor: Option<&dyn Executor>,
    progress: &mut dyn FnMut(f64) -> ControlFlow<()>,
) -> Result<Mesh, Error> {
    let how = How {
        min_slab_cells: if executor.is_some() {
            MIN_CELLS_PER_LENT_SLAB
        } else {
            MIN_CELLS_PER_SLAB
        },
        min_slab_layers: MIN_LAYERS_PER_SLAB,
        min_helper_cells: MIN_CELLS_FOR_HELPERS,
        world_points: false,
        executor,
        serial_assembly_triangles: SERIAL_ASSEMBLY_TRIANGLES,
        extreme: None,
        sample_scale: [1.0, 1.0],
    };
    extract_in_slabs(volume, isovalue, options, progress, how)
}

/// How an extraction runs, beyond its options.
#[derive(Clone, Copy)]
struct How<'e> {
    /// With refinement off, the fewest cells a slab gets (tests use small
    /// slabs on small volumes).
    min_slab_cells: u64,
    /// With refinement off, the fewest layers a slab gets while there are
    /// more slabs than workers (tests use 1).
    min_slab_layers: usize,
    /// With refinement off, the fewest cells for which helper threads
    /// start (not used on an executor, which starts none; tests use 0).
    min_helper_cells: u64,
    /// Whether to fill [`Mesh::points`] (world coordinates).
    world_points: bool,
    /// The host's executor, if it lends one (else the library's helper
    /// threads, or the calling thread).
    executor: Option<&'e dyn Executor>,
    /// Meshes of fewer triangles are assembled on the calling thread
    /// ([`SERIAL_ASSEMBLY_TRIANGLES`]; tests use 0).
    serial_assembly_triangles: usize,
    /// Set when a crossed cell's samples (or the isovalue) are of a
    /// magnitude the products of contouring cannot take (see `magnitude`).
    extreme: Option<&'e AtomicBool>,
    /// The two powers of two whose product the samples were scaled by (see
    /// `magnitude`; `[1, 1]` for the caller's own): gradients are divided
    /// by them, so that they are those of the caller's samples.
    sample_scale: [f64; 2],
}

/// [`extract_with_progress`], run as `how` says.
fn extract_in_slabs(
    volume: &Volume<'_>,
    isovalue: f64,
    options: &Options,
    progress: &mut dyn FnMut(f64) -> ControlFlow<()>,
    how: How<'_>,
) -> Result<Mesh, Error> {
    volume.validate()?;
    if !isovalue.is_finite() {
        return Err(Error::InvalidIsovalue(isovalue));
    }
    if !(options.epsilon.is_finite() && options.epsilon >= 0.0) {
        return Err(Error::InvalidEpsilon(options.epsilon));
    }
    if options.max_level > MAX_LEVEL_LIMIT {
        return Err(Error::InvalidMaxLevel(options.max_level));
    }
    // f64 samples too large or too small for the products of refinement,
    // of an interior vertex's projection and of normals are contoured on a
    // copy scaled by a power of two (see `magnitude`), once a crossed cell
    // met them (reading the whole volume for its range first cost a
    // refined 256^3 volume a third more time).
    let extreme = AtomicBool::new(false);
    let watch = matches!(volume.samples, crate::volume::Samples::F64(_));
    // The second run reports from where the first stopped (progress never
    // goes back), and not at all once the caller asked to stop.
    let (mut last, stopped) = (0.0f64, std::cell::Cell::new(false));
    let mut progress = |f: f64| {
        last = last.max(f);
        let r = progress(last);
        stopped.set(stopped.get() || r.is_break());
        r
    };
    let first = crate::volume::with_grid!(volume, |grid| run(
        grid,
        volume,
        isovalue,
        options,
        &mut progress,
        How {
            extreme: watch.then_some(&extreme),
            ..how
        }
    ));
    if !extreme.load(Ordering::Relaxed) || !matches!(first, Err(Error::Aborted)) {
        return first;
    }
    if stopped.get() {
        return Err(Error::Aborted);
    }
    let Some((samples, iso, factors)) =
        crate::magnitude::scaled_copy(volume, isovalue, &mut progress)?
    else {
        // (Only that cell is extreme, or the samples span too many orders
        // of magnitude for an exact copy: contoured as they are, unscaled.)
        return crate::volume::with_grid!(volume, |grid| run(
            grid,
            volume,
            isovalue,
            options,
            &mut progress,
            how
        ));
    };
    let scaled = Volume {
        samples: crate::volume::Samples::F64(&samples),
        strides: crate::volume::contiguous_strides(volume.dims),
        offset: 0,
        ..*volume
    };
    crate::volume::with_grid!(&scaled, |grid| run(
        grid,
        &scaled,
        iso,
        options,
        &mut progress,
        How {
            sample_scale: factors,
            ..how
        }
    ))
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    /// Produce the mesh; stop when the cap is exceeded.
    Output { cap: u64 },
    /// Only count refinement-tree nodes per level; stop when the leaves
    /// exceed the cap (the level does not fit).
    Count { cap: u64 },
}

struct Shared<'a, T: Scalar, F: ReconstructionFilter> {
    grid: Grid<'a, T>,
    filter: &'a F,
    cell_dims: [usize; 3],
    index_offset: [i64; 3],
    iso: f64,
    options: &'a Options,
    max_level: u32,
    refine: bool,
    cancel: &'a AtomicBool,
    over_cap: &'a AtomicBool,
    emitted: &'a AtomicU64,
    layers_done: &'a AtomicU64,
    scratch: &'a ScratchPool,
    /// See [`How::extreme`].
    extreme: Option<&'a AtomicBool>,
    /// Whether a cell whose refinement stalls is meshed again on sub-cells
    /// (see [`crate::subcells`]).
    subcells: bool,
    /// Reports progress when called on the calling thread (after each
    /// layer; within one, at most every [`PROGRESS_EVERY`]); `None` where
    /// nothing is reported until the end.
    poll: Option<&'a OnCaller<'a>>,
}

/// How many refined cells of a slab are all timed before only one in
/// eight is (see [`SlabOut::refine_time`]).
const TIMED_CELLS: u64 = 64;

/// What one slab of cell layers produced: points (index coordinates,
/// welded within the slab), triangles on them, their levels, counters.
#[derive(Default)]
pub(crate) struct SlabOut {
    pub verts: Vec<DVec3>,
    pub tris: Vec<[u32; 3]>,
    pub levels: Vec<u8>,
    pub mc_tris: u64,
    pub ambiguous: u64,
    pub nonfinite: u64,
    /// Bytes of buffers that could not be allocated (the slab stopped
    /// before its first cell, or before refining a cell; the extraction
    /// fails).
    pub scratch_failed: usize,
    pub counters: Counters,
    /// Time spent refining the timed cells, of `refined_cells` refined
    /// (see [`SlabOut::refine_time`]).
    pub timed_refine: Duration,
    pub timed_cells: u64,
    pub refined_cells: u64,
    pub total_time: Duration,
    /// Indices in `tris` of the triangles lying in a grid plane, the only
    /// ones that can coincide with another cell's (found while their points
    /// are still in cache).
    pub flat_tris: Vec<u32>,
    /// Set when a pass without `weld_all` met an interior point off its
    /// cell's interior (see [`process_slab`]); the output is then discarded.
    pub redo_with_map: bool,
    /// Triangles this pass added to the shared count, and layers it
    /// reported done.
    pub reported: u64,
    pub layers: u64,
    /// The planes `z = k0` and `z = k1` (index space, offset included)
    /// that bound the slab's cell layers `k0..k1`: its points lie between.
    pub z_range: (f64, f64),
    /// Points made while the first cell layer was meshed: every point on
    /// the slab's bottom plane `z = k0` is among them (no other layer's
    /// cells touch that plane), so welding to the slab below looks no
    /// further.
    pub first_layer_verts: usize,
    /// Points made before the last cell layer was meshed: every point on
    /// the top plane `z = k1` comes after them.
    pub before_last_layer_verts: usize,
}

impl SlabOut {
    /// The slab's time spent refining: the timed cells' time scaled to all
    /// refined cells (an estimate once cells are sampled; it feeds only
    /// the statistics' split of the time).
    pub fn refine_time(&self) -> Duration {
        if self.timed_cells == 0 {
            return Duration::ZERO;
        }
        self.timed_refine
            .mul_f64(self.refined_cells as f64 / self.timed_cells as f64)
    }
}

/// Forwards progress to the caller's callback: never decreasing, and never
/// again once the callback asked to stop.
struct Reporter<'p> {
    f: &'p mut dyn FnMut(f64) -> ControlFlow<()>,
    last: f64,
    stopped: bool,
}

impl Reporter<'_> {
    /// Reports `x`; returns false when the caller asked to stop.
    fn report(&mut self, x: f64) -> bool {
        if self.stopped {
            return false;
        }
        self.last = self.last.max(x.clamp(0.0, 1.0));
        if (self.f)(self.last).is_break() {
            self.stopped = true;
        }
        !self.stopped
    }
}

/// Most worker threads one extraction starts (more requested are clamped).
pub const MAX_THREADS: usize = 4096;

/// The least time between two progress reports while the workers run.
const PROGRESS_EVERY: Duration = Duration::from_millis(20);

/// With refinement off, the fewest cells a slab gets. Plain Marching Cubes
/// costs a few nanoseconds a cell, so a smaller slab costs more in its own
/// scratch buffers, a helper thread's start-up and welding at its planes
/// than it gains. (Through VTK with 2 threads, interleaved with
/// vtkFlyingEdges3D: the EPI scan 128x96x24 took 2.2x its time in one
/// slab, 1.6-1.7x in six; the wavy sphere at 64^3 2.1x in one, 1.5x in
/// six; the 48x48x20 tube and the 40^3 atoms, a few thousand triangles,
/// lost 0.05-0.2 ms to a helper thread in two or more. Fortieth session,
/// helpers that watch for work before parking, on its own threads, 2
/// asked, medians of 600 calls: the EPI scan 0.58 ms in 4 slabs against
/// 0.63-0.65 in 6 and 0.82-0.84 in one; the 64^3 sphere 0.32 in 2
/// against 0.35-0.37 in 6 and 0.50 in one.)
const MIN_CELLS_PER_SLAB: u64 = 1 << 16;

/// [`MIN_CELLS_PER_SLAB`] on a host's executor, where no thread starts.
/// It was a quarter of that while a cell cost more (Marschner-Lobb 41^3
/// on TBB with 2 threads, through VTK: 1.56 ms in one slab, 1.13 ms in
/// two), then half (with the cheaper cell loop of the twenty-fourth
/// session two slabs took 0.86 ms against 0.58 in one, and the tube and
/// the atoms 1.3-1.5 times one slab's time). The same as on the library's
/// own threads since the fifty-ninth session: the EPI scan 128x96x24 on
/// TBB with 2 threads, through VTK, alternating with vtkFlyingEdges3D in
/// one process (500 rounds, three runs each), took 0.94-0.96x
/// FlyingEdges' time in 4 slabs against 1.01-1.07x in 6; volumes under
/// 65 536 cells keep one slab, as before.
const MIN_CELLS_PER_LENT_SLAB: u64 = MIN_CELLS_PER_SLAB;

/// Meshes of fewer triangles are assembled on the calling thread: each
/// parallel step of the assembly wakes the workers, which costs more than
/// the step (the 40^3 atoms at ε 0.1 on 2 threads, 16 slabs, 4 290
/// triangles: 0.16 ms in parallel, 0.09 on the calling thread;
/// Marschner-Lobb 41^3, 28 356: 0.75 against 0.63). The output does not
/// depend on it.
const SERIAL_ASSEMBLY_TRIANGLES: usize = 1 << 16;

/// Meshes from this many triangles are assembled in parallel on the
/// library's own helpers, whatever [`SERIAL_ASSEMBLY_TRIANGLES`] says:
/// they still watch for work when the passes end, so a step costs no
/// wake-up (Marschner-Lobb 41^3 on 2 threads, 21 000 triangles in two
/// slabs: assembly 116 -> 93 us, a call 0.330 -> 0.312 ms).
const HOT_HELPERS_ASSEMBLY_TRIANGLES: usize = 1 << 13;

/// The most leaves a refined cell's patch can have (its Marching Cubes
/// triangles times [`crate::options::Rule::most_children`] to the power
/// max_level) for which the slab's buffers are reserved for the whole
/// patch before refining it (fallibly; see `slab_pass`).
const CELL_RESERVE_LIMIT: u64 = 1 << 16;

/// With refinement off, the fewest cell layers a slab gets while there
/// are more slabs than workers.
const MIN_LAYERS_PER_SLAB: usize = 3;

/// With refinement off on the library's own threads, the fewest cells for
/// which helper threads start: below, the calling thread contours the
/// volume alone in one slab; from it on, each worker gets a slab (of at
/// least [`MIN_CELLS_PER_WORKER`] cells). It was 2^19 while starting and
/// waking a helper cost about as much as contouring a few hundred
/// thousand cells on these shared virtual machines (twenty-fourth session: the 64^3 wavy sphere 0.55-1.04
/// ms alone against 1.11-1.92 with a helper). The helpers now stay
/// between calls and watch for work a little before parking
/// ([`crate::helpers`]), and a slab's assembly costs less: 2
/// threads asked, medians of 600 calls, Marschner-Lobb 41^3 (64 000
/// cells) took 0.57-0.58 ms in two slabs against 0.83 alone.
const MIN_CELLS_FOR_HELPERS: u64 = 1 << 15;

/// With refinement off on the library's own threads, the fewest cells of
/// a slab given to a worker so that each has one (see
/// [`MIN_CELLS_FOR_HELPERS`]): helpers beyond that many would wake, and
/// watch for work, for next to nothing.
const MIN_CELLS_PER_WORKER: u64 = 1 << 14;

/// With refinement off and one thread, the most cells an extraction runs
/// on the calling thread without a pool (a few milliseconds of work: no
/// progress is reported in between).
const SERIAL_MAX_CELLS: u64 = 1 << 22;

/// How many slabs (runs of cell layers along z) to cut `nz` layers of
/// `cells` cells into for `threads` workers, with refinement off slabs of
/// at least `min_cells` cells and (while there are more slabs than
/// workers) `min_layers` layers, but a slab for each worker where each can
/// have `min_worker_cells` (`u64::MAX`: no such promise). The output does
/// not depend on it.
fn slab_count(
    nz: usize,
    cells: u64,
    threads: usize,
    refine: bool,
    min_cells: u64,
    min_layers: usize,
    min_worker_cells: u64,
) -> usize {
    // Several slabs a thread, for balance when refinement is uneven. Plain
    // Marching Cubes on one thread needs no balance, and one slab is
    // assembled in place. (Refinement keeps several: its slabs' welding
    // maps stay smaller and faster.)
    let mut n = if threads == 1 && !refine {
        1
    } else {
        nz.min(threads.saturating_mul(8))
    };
    if !refine {
        n = n.min((cells / min_cells.max(1)).min(usize::MAX as u64) as usize);
        // A slab reads one layer of samples more than it contours, and
        // sets up its caches: a few layers each (unless that would leave
        // a worker idle; the scan 128x96x24 on TBB with 2 threads, through
        // VTK: 1.56 ms in 16 slabs, 1.37 in 6).
        n = n.min((nz / min_layers.max(1)).max(threads));
        // Equal shares: three slabs on two threads take as long as four.
        if n > threads {
            n -= n % threads;
        }
        // Helpers started for a small volume each get a slab (the bound on
        // cells a slab would leave it in one), unless a slab each would be
        // too small to be worth waking them (a 40^3 volume on 16 cores
        // takes 3).
        let workers = (cells / min_worker_cells.max(1)).min(usize::MAX as u64) as usize;
        n = n.max(threads.min(nz).min(workers));
    }
    // Grid-edge cache stamps are 32-bit, one per layer of a slab.
    n.max(nz.div_ceil(1 << 31)).max(1)
}

fn run<T: Scalar>(
    grid: Grid<'_, T>,
    volume: &Volume<'_>,
    iso: f64,
    options: &Options,
    progress: &mut dyn FnMut(f64) -> ControlFlow<()>,
    how: How<'_>,
) -> Result<Mesh, Error> {
    let mut reporter = Reporter {
        f: progress,
        last: 0.0,
        stopped: false,
    };
    if !reporter.report(0.0) {
        return Err(Error::Aborted);
    }
    let threads = if let Some(ex) = how.executor {
        ex.concurrency().clamp(1, MAX_THREADS)
    } else if options.threads == 0 {
        std::thread::available_parallelism().map_or(1, |n| n.get())
    } else {
        options.threads.min(MAX_THREADS)
    };
    // No more threads than slabs: a small volume runs on one.
    let nz = grid.dims[2] - 1;
    let refine = options.refines();
    let threads = if how.executor.is_none() && !refine && volume.cell_count() < how.min_helper_cells
    {
        1
    } else {
        threads
    };
    let nslabs = slab_count(
        nz,
        volume.cell_count(),
        threads,
        refine,
        how.min_slab_cells,
        how.min_slab_layers,
        // (On a host's executor no helper starts: no promise.)
        if how.executor.is_none() {
            MIN_CELLS_PER_WORKER
        } else {
            u64::MAX
        },
    );
    let threads = threads.min(nslabs);
    let mut run_on = |exec: Exec<'_>| {
        let r = &mut reporter;
        match options.reconstruction {
            Reconstruction::Trilinear => {
                let f = Trilinear::new(grid);
                run_with(exec, nslabs, grid, &f, volume, iso, options, r, how)
            }
            Reconstruction::CatmullRom => {
                let f = Tricubic::<T, CatmullRomKernel>::new(grid);
                run_with(exec, nslabs, grid, &f, volume, iso, options, r, how)
            }
            Reconstruction::BSpline => {
                let f = Tricubic::<T, BSplineKernel>::new(grid);
                run_with(exec, nslabs, grid, &f, volume, iso, options, r, how)
            }
            Reconstruction::BSplineInterpolating => {
                let coefficients = prefilter(&grid)?;
                let dims = grid.dims.map(|n| n as u64);
                let cv =
                    Volume::new(coefficients.as_slice(), dims).with_index_offset(grid.index_offset);
                let f = Tricubic::<f64, BSplineKernel>::new(Grid::new(&coefficients, &cv));
                run_with(exec, nslabs, grid, &f, volume, iso, options, r, how)
            }
        }
    };
    // Plain Marching Cubes of a volume small enough to take a few
    // milliseconds runs on the calling thread: a pool would cost more than
    // it saves, and progress is reported only before and after.
    if threads == 1 && !refine && volume.cell_count() <= SERIAL_MAX_CELLS {
        return run_on(Exec::Serial);
    }
    if let Some(ex) = how.executor {
        return run_on(Exec::External(ex));
    }
    // The calling thread works next to `threads - 1` helper threads (kept
    // between calls: see `helpers`), and reports progress after each
    // layer of cells it contours.
    with_helpers(threads, |h| run_on(Exec::Helpers(h)))
}

/// One extraction on `exec`: Marching Cubes on `grid`'s samples, then
/// refinement onto the isosurface of `filter`.
#[allow(clippy::too_many_arguments)]
fn run_with<T: Scalar, F: ReconstructionFilter>(
    exec: Exec<'_>,
    nslabs: usize,
    grid: Grid<'_, T>,
    filter: &F,
    volume: &Volume<'_>,
    iso: f64,
    options: &Options,
    reporter: &mut Reporter<'_>,
    how: How<'_>,
) -> Result<Mesh, Error> {
    let start = Instant::now();
    let cell_dims = [grid.dims[0] - 1, grid.dims[1] - 1, grid.dims[2] - 1];
    let nz = cell_dims[2];
    let slabs: Vec<(usize, usize)> = (0..nslabs)
        .map(|s| (s * nz / nslabs, (s + 1) * nz / nslabs))
        .filter(|(a, b)| b > a)
        .collect();

    let refine = options.refines();
    let user_cap = if options.max_triangles == 0 {
        HARD_TRIANGLE_CAP
    } else {
        options.max_triangles.min(HARD_TRIANGLE_CAP)
    };
    let cancel = AtomicBool::new(false);
    let over_cap = AtomicBool::new(false);
    let emitted = AtomicU64::new(0);
    let layers_done = AtomicU64::new(0);
    let scratch = ScratchPool::new(cell_dims[0], cell_dims[1]);
    let mut stats = Stats {
        cells: volume.cell_count(),
        ..Stats::default()
    };

    // Runs one pass over all slabs. The calling thread reports progress
    // (and passes on a stop) after each layer of cells it contours, and
    // after each of its slabs (a host's executor may run none there).
    let mut pass =
        |max_level: u32, mode: Mode, weight: (f64, f64)| -> Result<Vec<SlabOut>, Error> {
            emitted.store(0, Ordering::Relaxed);
            layers_done.store(0, Ordering::Relaxed);
            over_cap.store(false, Ordering::Relaxed);
            let mut report = || {
                let done = layers_done.load(Ordering::Relaxed) as f64 / nz as f64;
                if !reporter.report(weight.0 + weight.1 * done.min(1.0)) {
                    cancel.store(true, Ordering::Relaxed);
                }
            };
            let poll = OnCaller::every(&mut report, PROGRESS_EVERY);
            let serial = matches!(exec, Exec::Serial);
            let shared = Shared {
                grid,
                filter,
                cell_dims,
                index_offset: grid.index_offset,
                iso,
                options,
                max_level,
                refine: refine && max_level > 0,
                cancel: &cancel,
                over_cap: &over_cap,
                emitted: &emitted,
                layers_done: &layers_done,
                scratch: &scratch,
                extreme: how.extreme,
                subcells: refine && subcells::allowed(options),
                poll: (!serial).then_some(&poll),
            };
            if serial {
                let outs: Vec<SlabOut> = slabs
                    .iter()
                    .map(|&(k0, k1)| process_slab(&shared, k0, k1, mode))
                    .collect();
                return finish_pass(outs, &cancel);
            }
            let outs = exec.map_polling(
                slabs.clone(),
                |(k0, k1)| process_slab(&shared, k0, k1, mode),
                &poll,
            )?;
            finish_pass(outs, &cancel)
        };

    let mut max_level = if refine { options.max_level } else { 0 };
    let mut outs = pass(max_level, Mode::Output { cap: user_cap }, (0.0, 0.9))?;
    if over_cap.load(Ordering::Relaxed) {
        // Too many triangles: count refinement trees per level, then redo
        // the pass at the highest level whose output fits the cap.
        drop(outs);
        // Counting all the way to `max_level` can take a very long time
        // when nearly every triangle splits (a tiny epsilon, max level 10):
        // count level by level instead and stop at the first level that
        // does not fit. The total at level l (nodes at l plus leaves above
        // it) never decreases with l, and the counts up to level l do not
        // depend on the deepest level counted, so the chosen level is the
        // same, for at most a few times the cap in work.
        let mut chosen = 0;
        for l in 1..=max_level {
            let w = 0.3 * (l - 1) as f64 / max_level as f64;
            let counts = pass(
                l,
                Mode::Count { cap: user_cap },
                (0.3 + w, 0.3 / max_level as f64),
            )?;
            // A count pass stops once its leaves exceed the cap: the total
            // compared below is exactly those leaves.
            if over_cap.load(Ordering::Relaxed) {
                break;
            }
            let mut nodes = [0u64; 16];
            let mut leaves = [0u64; 16];
            for o in &counts {
                for q in 0..16 {
                    nodes[q] += o.counters.nodes_per_level[q];
                    leaves[q] += o.counters.per_level[q];
                }
            }
            let l = l as usize;
            if nodes[l] + leaves[..l].iter().sum::<u64>() > user_cap {
                break;
            }
            chosen = l;
        }
        max_level = chosen as u32;
        outs = pass(max_level, Mode::Output { cap: u64::MAX }, (0.6, 0.35))?;
        // The count is exact in the usual case, but can fall a few
        // triangles short of the output (seen where a cell is meshed again
        // on sub-cells: `tests/cap.rs`); the cap is a promise, so step
        // down while the output does not fit (level 0 is plain Marching
        // Cubes, kept whatever its size).
        let emitted = |outs: &Vec<SlabOut>| outs.iter().map(|o| o.tris.len() as u64).sum::<u64>();
        while max_level > 0 && emitted(&outs) > user_cap {
            max_level -= 1;
            drop(outs);
            outs = pass(max_level, Mode::Output { cap: u64::MAX }, (0.9, 0.05))?;
        }
    }
    stats.effective_max_level = max_level;
    // The cap lowered the level refinement was asked to reach (with
    // refinement off, a cap below the Marching Cubes count changes
    // nothing: those triangles are always kept).
    stats.budget_reached = refine && max_level < options.max_level;

    let t_asm = Instant::now();
    let passes_wall = (t_asm - start).as_secs_f64();
    let triangles: usize = outs.iter().map(|o| o.tris.len()).sum();
    let assemble_on = match exec {
        // Helpers that just ran the passes still watch for work (see
        // `helpers`): a step handed to them costs little.
        Exec::Helpers(_) if triangles >= HOT_HELPERS_ASSEMBLY_TRIANGLES => exec,
        _ if triangles < how.serial_assembly_triangles => Exec::Serial,
        _ => exec,
    };
    let mut mesh = assemble(
        outs,
        volume,
        passes_wall,
        &mut stats,
        assemble_on,
        how.world_points,
    )?;
    stats.time_assemble = t_asm.elapsed().as_secs_f64();
    if !reporter.report(0.97) {
        return Err(Error::Aborted);
    }
    let t_n = Instant::now();
    // Normals and gradients are those of the trilinear interpolant,
    // whatever the filter.
    let trilinear = Trilinear::new(grid);
    mesh.normals = compute_normals(
        &trilinear,
        volume,
        &mesh.index_points,
        options.normals,
        exec,
    )?;
    mesh.gradients = compute_gradients(
        &trilinear,
        volume,
        &mesh.index_points,
        options.gradients,
        options.normals,
        how.sample_scale,
        exec,
    )?;
    stats.time_normals = t_n.elapsed().as_secs_f64();
    stats.time_total = start.elapsed().as_secs_f64();
    stats.output_triangles = mesh.triangles.len() as u64;
    stats.output_points = mesh.index_points.len() as u64;
    mesh.stats = stats;
    if !reporter.report(1.0) {
        return Err(Error::Aborted);
    }
    Ok(mesh)
}

/// A pass's slab outputs, or why the pass failed (cancelled, or a slab's
/// scratch memory not available).
fn finish_pass(outs: Vec<SlabOut>, cancel: &AtomicBool) -> Result<Vec<SlabOut>, Error> {
    if cancel.load(Ordering::Relaxed) {
        return Err(Error::Aborted);
    }
    if let Some(o) = outs.iter().find(|o| o.scratch_failed > 0) {
        return Err(Error::OutOfMemory(o.scratch_failed));
    }
    Ok(outs)
}

/// Marching Cubes (and refinement) on cell layers `k0..k1`.
///
/// With refinement off, a point strictly inside its grid edge belongs to
/// that edge alone, so the per-layer edge cache welds it and the slab's map
/// only sees points on samples and the interior points of ambiguous cells.
/// That holds while those interior points lie strictly inside their cells;
/// when one does not (a value rounding onto the boundary far from the
/// origin, or degenerate samples), it could coincide with an edge's point,
/// and the slab is redone with every point in the map.
fn process_slab<T: Scalar, F: ReconstructionFilter>(
    sh: &Shared<'_, T, F>,
    k0: usize,
    k1: usize,
    mode: Mode,
) -> SlabOut {
    let mut scratch = match sh.scratch.take() {
        Ok(s) => s,
        Err(bytes) => {
            return SlabOut {
                scratch_failed: bytes,
                ..SlabOut::default()
            }
        }
    };
    // Plain Marching Cubes gets its own instance of the pass, free of the
    // refinement's bookkeeping.
    let pass = |weld_all, scratch: &mut LayerScratch| {
        if sh.refine {
            slab_pass::<T, F, true>(sh, k0, k1, mode, weld_all, scratch)
        } else {
            slab_pass::<T, F, false>(sh, k0, k1, mode, weld_all, scratch)
        }
    };
    let mut out = pass(sh.refine, &mut scratch);
    if out.redo_with_map {
        // Take back what the abandoned pass counted.
        sh.emitted.fetch_sub(out.reported, Ordering::Relaxed);
        sh.layers_done.fetch_sub(out.layers, Ordering::Relaxed);
        out = pass(true, &mut scratch);
    }
    sh.scratch.give(scratch);
    out
}

/// A guess of the Marching Cubes triangles in `layers` cell layers of a
/// grid of `cell_dims` cells: one and a half times those of a surface
/// wrapping the slab's share of the box (two per cell of its faces; the
/// rippled Marschner-Lobb sample has 1.1 times as many), at most 2^22.
fn surface_guess(cell_dims: [usize; 3], layers: usize) -> usize {
    let [nx, ny, nz] = cell_dims.map(|n| n as f64);
    let dz = layers as f64;
    let faces = 2.0 * nx * ny * dz / nz.max(1.0) + 2.0 * dz * (nx + ny);
    (3.0 * faces).min((1 << 22) as f64) as usize
}

/// Squared twice-area (local cell units) below which a refined triangle
/// counts as having no area (see the attempts in [`slab_pass`]); refined
/// triangles of a unit cell are many orders of magnitude larger.
const MIN_DOUBLE_AREA2: f64 = 1e-28;

/// Leaves a refined cell may make beyond what is left under the cap when
/// it may be meshed again on sub-cells (its stalled patch is replaced,
/// often by a smaller one; see [`crate::subcells`]).
const STALL_SLACK: u64 = 1 << 20;

/// Triangles a slab gathers before adding them to the shared count (it
/// reports the rest when it ends).
const REPORT_BATCH: u64 = 1024;

/// One pass of [`process_slab`]; `weld_all` puts every point in the map.
/// `REFINE` is `sh.refine`.
fn slab_pass<T: Scalar, F: ReconstructionFilter, const REFINE: bool>(
    sh: &Shared<'_, T, F>,
    k0: usize,
    k1: usize,
    mode: Mode,
    weld_all: bool,
    scratch: &mut LayerScratch,
) -> SlabOut {
    debug_assert_eq!(REFINE, sh.refine);
    let t0 = Instant::now();
    let mut out = SlabOut::default();
    if !matches!(mode, Mode::Count { .. }) {
        // Room for a generous guess of the Marching Cubes output up front:
        // growing by doubling copies every buffer into fresh memory, and
        // those page faults were two thirds of a small volume's. Pages
        // left unwritten cost nothing; a failed reservation just leaves
        // the growth to the pushes. Buffers kept since an earlier call
        // are already mapped (see crate::recycle).
        let tris = surface_guess(sh.cell_dims, k1 - k0);
        out.tris = recycle::SLAB_TRIS.take(tris);
        out.levels = recycle::LEVELS.take(tris);
        out.verts = recycle::points_as_dvec3(recycle::POINTS.take(tris / 2));
        let _ = out.tris.try_reserve_exact(tris);
        let _ = out.levels.try_reserve_exact(tris);
        let _ = out.verts.try_reserve_exact(tris / 2);
    }
    let mut map: KeyMap<u32> = KeyMap::default();
    let mut local: KeyMap<u32> = KeyMap::default();
    let mut patch = Patch {
        pinch_fans: REFINE,
        ..Patch::default()
    };
    // Scratch for the Classic topology's check (`mc::topology_check`).
    let mut check = Patch::default();
    let mut cache = EdgeCache::default();
    let mut kept: Vec<[u32; 3]> = Vec::with_capacity(16);
    let mut tested = Vec::with_capacity(16);
    let mut pos_of: Vec<DVec3> = Vec::with_capacity(16);
    let mut uses: Vec<(u64, u8)> = Vec::with_capacity(48);
    let mut edges = FlatMap::<u32>::default();
    let mut seen = FlatMap::<()>::default();
    let mut count_leaves: Vec<([u32; 3], [DVec3; 3], u8)> = Vec::new();
    let [nx, ny, _] = sh.cell_dims;
    let count_only = matches!(mode, Mode::Count { .. });
    let (Mode::Output { cap } | Mode::Count { cap }) = mode;
    let mut reported = 0u64;
    let mut grown_to = (0, 0);
    // Whether a point of this pass may sit on a grid point (every point
    // goes through the map, or one edge point rounded onto a sample). Until
    // then, every point lies strictly inside its grid edge or its cell,
    // which settles most triangles' flatness from the case table alone.
    let mut points_on_grid_points = weld_all;
    let opts = sh.options;
    // Inside bits and per-row finiteness of the two sample layers of the
    // current cell layer (by z parity): each layer is read once and serves
    // two cell layers. Then the ids of the points on grid edges: x and y
    // edges of the two sample layers (by z parity), z edges of the current
    // cell layer, each entry stamped with its layer (see `layers`).
    let nxs = nx + 1;
    let first_stamp = scratch.stamps(k1 - k0 + 1);
    let stamp = |z: usize| first_stamp + (z - k0) as u32;
    let LayerScratch {
        insides,
        finite,
        edges: edge_ids,
        cases,
        ..
    } = scratch;
    let (edge_slots, edge_dz) = layers::cell_edge_slots(nxs, (ny + 1) * nxs);
    let read_layer = |z: usize, ins: &mut [u8], fin: &mut [bool]| {
        read_sample_layer(&sh.grid, sh.iso, z, nxs, ins, fin)
    };
    // A cell's point ids and local positions by patch vertex id (see
    // `mc::Patch`). Each cell sets every entry its triangles name before
    // reading it, so they are not cleared from cell to cell.
    let mut ids = [u32::MAX; 16];
    let mut loc = [DVec3::ZERO; 16];
    let plane_z = |k: usize| (sh.index_offset[2] + k as i64) as f64;
    out.z_range = (plane_z(k0), plane_z(k1));
    // Until the layers below say otherwise (a pass cut short): every point.
    out.first_layer_verts = usize::MAX;
    'layers: for k in k0..k1 {
        if k + 1 == k1 {
            out.before_last_layer_verts = out.verts.len();
        }
        let (lo, hi) = (k & 1, (k + 1) & 1);
        if sh.cancel.load(Ordering::Relaxed) || sh.over_cap.load(Ordering::Relaxed) {
            break 'layers;
        }
        if k == k0 {
            read_layer(k, &mut insides[lo], &mut finite[lo]);
        }
        read_layer(k + 1, &mut insides[hi], &mut finite[hi]);
        for j in 0..ny {
            if sh.cancel.load(Ordering::Relaxed) || sh.over_cap.load(Ordering::Relaxed) {
                break 'layers;
            }
            // Reported in batches: an atomic add on a shared counter every
            // row costs more than a row of plain Marching Cubes, and a late
            // report only delays stopping a pass whose output is dropped.
            let n = produced(&out, count_only);
            if n - reported >= REPORT_BATCH && report_emitted(sh, n, &mut reported, cap) {
                break 'layers;
            }
            let caps = (out.verts.capacity(), out.tris.capacity());
            if caps != grown_to {
                // The output grew: large buffers on huge pages.
                grown_to = caps;
                advise_huge_pages(&mut out.verts);
                advise_huge_pages(&mut out.tris);
            }
            // Four sample rows around the current row of cells: (j, k),
            // (j+1, k), (j, k+1), (j+1, k+1).
            fn row<T>(layer: &[T], jj: usize, n: usize) -> &[T] {
                &layer[jj * n..(jj + 1) * n]
            }
            let ins = [
                row(&insides[lo], j, nxs),
                row(&insides[lo], j + 1, nxs),
                row(&insides[hi], j, nxs),
                row(&insides[hi], j + 1, nxs),
            ];
            let fin = [
                finite[lo][j],
                finite[lo][j + 1],
                finite[hi][j],
                finite[hi][j + 1],
            ];
            let all_finite = fin.iter().all(|&x| x);
            case_row(&ins, cases);
            let mut next = 0;
            loop {
                // Most cells are empty: with finite samples, go straight
                // to the next one the surface crosses.
                let i = if all_finite {
                    next_crossed(cases, next)
                } else {
                    next
                };
                if i >= nx {
                    break;
                }
                next = i + 1;
                let case = cases[i];
                // Only cells that the surface crosses (or with a non-finite
                // sample) get here: read their corners from the volume.
                let c = sh.grid.corners([i, j, k]);
                if !all_finite && !c.iter().all(|v| v.is_finite()) {
                    out.nonfinite += 1;
                    continue;
                }
                if case == 0 || case == 255 {
                    continue;
                }
                if let Some(flag) = sh.extreme {
                    if crate::magnitude::extreme(&c, sh.iso) {
                        // The extraction is redone on a scaled copy: stop.
                        flag.store(true, Ordering::Relaxed);
                        sh.cancel.store(true, Ordering::Relaxed);
                        break 'layers;
                    }
                }
                let mut f = [0.0; 8];
                for q in 0..8 {
                    f[q] = c[q] - sh.iso;
                }
                if !f.iter().all(|v| v.is_finite()) {
                    // A sample and the isovalue beyond half of f64::MAX,
                    // of opposite signs: halves, which keep every sign,
                    // crossing and decision of the cell (an infinite
                    // value made the trilinear topology drop the cell).
                    for q in 0..8 {
                        f[q] = 0.5 * c[q] - 0.5 * sh.iso;
                    }
                }
                let (tris, extra, ambiguous) =
                    cell_triangles_borrowed(case, &f, opts.topology, &mut patch);
                if ambiguous {
                    out.ambiguous += 1;
                }
                // With a filter that is not linear on grid edges, the
                // refinement starts from crossings on its own isosurface.
                let edge_filter = if REFINE && !F::LINEAR_ON_EDGES {
                    let Some(fc) = sh.filter.load([i, j, k]) else {
                        // A neighbourhood with a NaN or infinite sample:
                        // the cell is skipped (as below), before it places
                        // any crossing. Placed here, at the linear crossing,
                        // a point would stay there for a neighbour that
                        // refines and moves its crossings onto the filter's
                        // isosurface, depending on which cell came first
                        // (the thread count, the slabs, the pieces).
                        out.nonfinite += 1;
                        continue;
                    };
                    Some(fc)
                } else {
                    None
                };
                let cell_g = [
                    sh.index_offset[0] + i as i64,
                    sh.index_offset[1] + j as i64,
                    sh.index_offset[2] + k as i64,
                ];
                let cell_f = DVec3::new(cell_g[0] as f64, cell_g[1] as f64, cell_g[2] as f64);
                kept.clear();
                pos_of.clear();
                let mc_start = out.tris.len();
                // The point on each grid edge the surface crosses, each edge
                // once (every topology puts one point on each), then the
                // interior points of an ambiguous cell: every id a triangle
                // names is then set, without a test per triangle corner.
                let (crossed, n_crossed) = &CROSSED_EDGES[case as usize];
                let cell_slot = j * nxs + i;
                for &e in &crossed[..*n_crossed as usize] {
                    let e = e as usize;
                    let [a, b] = EDGES[e];
                    let ca = CORNERS[a as usize];
                    let ax = EDGE_AXIS[e] as usize;
                    // The grid edge's slot in the per-layer id cache and
                    // the stamp of its layer (not used when only counting).
                    let at = cell_slot + edge_slots[k & 1][e];
                    let edge_stamp = stamp(k) + edge_dz[e];
                    let cached = layers::lookup(edge_ids[at], edge_stamp);
                    if let (Some(id), false) = (cached, count_only) {
                        // A cell before this one placed the point, with the
                        // coordinates computed below.
                        ids[e] = id;
                        if REFINE {
                            loc[e] = out.verts[id as usize] - cell_f;
                        }
                        continue;
                    }
                    let (sa, sb) = (c[a as usize], c[b as usize]);
                    // vtkMarchingCubes: t from the lower corner.
                    let mut t = (sh.iso - sa) / (sb - sa);
                    if !t.is_finite() || !(sb - sa).is_finite() {
                        // A difference overflowed (samples beyond half of
                        // f64::MAX with opposite signs; with only the
                        // denominator infinite, t came out 0, a point on
                        // the corner): the same ratio of halves.
                        t = ((0.5 * sh.iso - 0.5 * sa) / (0.5 * sb - 0.5 * sa)).clamp(0.0, 1.0);
                    }
                    if let Some(fc) = &edge_filter {
                        let corner = DVec3::new(ca[0] as f64, ca[1] as f64, ca[2] as f64);
                        if let Some(s) = edge_crossing::<F>(fc, sh.iso, corner, ax) {
                            t = s;
                        }
                    }
                    let (x, y, z) = (
                        (cell_g[0] + ca[0] as i64) as f64,
                        (cell_g[1] + ca[1] as i64) as f64,
                        (cell_g[2] + ca[2] as i64) as f64,
                    );
                    // Built in registers: a store of one lane then a load of
                    // the vector stalls store forwarding.
                    let (base, gp) = match ax {
                        0 => (x, DVec3::new(x + t, y, z)),
                        1 => (y, DVec3::new(x, y + t, z)),
                        _ => (z, DVec3::new(x, y, z + t)),
                    };
                    let mut moved = base + t;
                    let mut gp = gp;
                    if edge_filter.is_some() && (moved == base || moved == base + 1.0) {
                        // A cubic's crossing within rounding of a corner
                        // (samples a rounding away from the isovalue) would
                        // weld with the crossings of the corner's other
                        // edges: a polygon visiting two of them apart then
                        // touches itself there, and the patch refined from
                        // it is not a manifold (a crack; a debug assertion).
                        // The point stays on its own edge, one float off
                        // the corner (the offset is exact).
                        moved = next_float(
                            if moved == base { base } else { base + 1.0 },
                            moved == base,
                        );
                        let t = moved - base;
                        gp = match ax {
                            0 => DVec3::new(x + t, y, z),
                            1 => DVec3::new(x, y + t, z),
                            _ => DVec3::new(x, y, z + t),
                        };
                    }
                    if REFINE || count_only {
                        loc[e] = gp - cell_f;
                    }
                    if count_only {
                        ids[e] = e as u32;
                    } else {
                        let next = out.verts.len() as u32;
                        let id = if !weld_all && moved != base && moved != base + 1.0 {
                            // Strictly inside the edge: first seen here.
                            out.verts.push(gp);
                            next
                        } else {
                            points_on_grid_points = true;
                            *map.entry(key(gp)).or_insert_with(|| {
                                out.verts.push(gp);
                                next
                            })
                        };
                        edge_ids[at] = layers::entry(edge_stamp, id);
                        ids[e] = id;
                    }
                }
                for (x, lp) in extra.iter().enumerate() {
                    // An interior point of an ambiguous cell.
                    let e = 12 + x;
                    let lp = DVec3::from_array(*lp);
                    let gp = cell_f + lp;
                    // Refinement sees the point where the output has it:
                    // `lp` a rounding away from a face (2^-54 from x = 0)
                    // lies on it in `gp`, where the neighbour's patch
                    // meets it, and the two cells must classify its edges
                    // alike (else one splits an edge the other keeps
                    // whole: a hole). The difference is exact.
                    loc[e] = gp - cell_f;
                    if !weld_all && !count_only && !strictly_inside(gp, cell_f) {
                        out.redo_with_map = true;
                        break 'layers;
                    }
                    if count_only {
                        ids[e] = e as u32;
                    } else {
                        let next = out.verts.len() as u32;
                        ids[e] = *map.entry(key(gp)).or_insert_with(|| {
                            out.verts.push(gp);
                            next
                        });
                    }
                }
                for tri in tris {
                    debug_assert!(tri.iter().all(|&e| e >= 12 || crossed.contains(&e)));
                    let tid = tri.map(|e| ids[e as usize]);
                    if count_only {
                        // Degeneracy by position when ids are not welded.
                        let p = [
                            loc[tri[0] as usize],
                            loc[tri[1] as usize],
                            loc[tri[2] as usize],
                        ];
                        if p[0] == p[1] || p[1] == p[2] || p[0] == p[2] {
                            continue;
                        }
                    } else if tid[0] == tid[1] || tid[1] == tid[2] || tid[0] == tid[2] {
                        continue;
                    }
                    if !REFINE {
                        // (Their levels, all 0, are written once at the end.)
                        out.tris.push(tid);
                        continue;
                    }
                    kept.push(tid);
                    pos_of.push(loc[tri[0] as usize]);
                    pos_of.push(loc[tri[1] as usize]);
                    pos_of.push(loc[tri[2] as usize]);
                }
                if !REFINE {
                    // The triangles went straight to the output.
                    let n = out.tris.len() - mc_start;
                    if points_on_grid_points {
                        note_flat(&mut out, mc_start);
                    } else {
                        // Every point lies strictly inside its grid edge
                        // or its cell: a triangle is flat exactly when its
                        // three points lie on edges of one face.
                        let flat = if ambiguous {
                            tris.iter().any(|&t| on_one_face(t))
                        } else {
                            classic::HAS_FACE_TRIANGLE[case as usize]
                        };
                        if flat {
                            note_flat(&mut out, mc_start);
                        } else {
                            debug_assert!(
                                out.tris[mc_start..]
                                    .iter()
                                    .all(|t| { !in_grid_plane(t.map(|v| out.verts[v as usize])) }),
                                "a triangle off the cell's faces lies in a grid plane"
                            );
                        }
                    }
                    out.mc_tris += n as u64;
                    out.counters.per_level[0] += n as u64;
                    out.counters.nodes_per_level[0] += n as u64;
                    continue;
                }
                out.mc_tris += kept.len() as u64;
                // Two clock reads cost about 0.1 us on a virtual machine, a
                // few per cent of a lightly refined cell: the first cells
                // of a slab are timed, then one in eight.
                let timed = out.refined_cells < TIMED_CELLS || out.refined_cells % 8 == 0;
                let tr = timed.then(Instant::now);
                let Some(fc) = edge_filter.or_else(|| sh.filter.load([i, j, k])) else {
                    out.nonfinite += 1;
                    continue;
                };
                // Under a cap, the leaves this cell may add before the
                // pass is over it for sure (the other slabs' count lags
                // behind): past it the cell reports at its end, where its
                // final patch decides. The refinement of one attempt stops
                // only past the cap itself (and, for a cell that may be
                // meshed again on sub-cells, room for its stalled patch,
                // which is replaced): an attempt may still be dropped for
                // a smaller one (see the attempts below), and what is left
                // of the cap depends on how far the other slabs have got,
                // so stopping there made the level a cap lowers to depend
                // on the thread count.
                let produced_before = produced(&out, count_only);
                let (remaining, leaf_budget) = if cap == u64::MAX {
                    (u64::MAX, u64::MAX)
                } else {
                    let unreported = produced_before - reported;
                    let r = cap.saturating_sub(sh.emitted.load(Ordering::Relaxed) + unreported);
                    let slack = if sh.subcells { STALL_SLACK } else { 0 };
                    (r, cap.saturating_add(slack))
                };
                let end = CellEnd {
                    t_start: out.tris.len(),
                    timer: tr,
                    produced_before,
                    remaining,
                };
                // Interior edges split only in cells free of ties (a sample
                // at the isovalue is none for the trilinear filter: see
                // `Refinable`).
                let mut refinable = Refinable::of_cell(&f, F::MULTILINEAR && F::LINEAR_ON_EDGES);
                // A table patch that joins the crossings otherwise than
                // `S_K` can never be refined onto it: its faces' edges
                // only (see `mc::topology_check`).
                if opts.topology == Topology::Classic
                    && !classic_is_trilinear(case, &f, &mut check.tris, &mut check.extra)
                {
                    refinable.interior = false;
                    out.counters.unsound_cells += 1;
                }
                // Where the bounds on the interpolant show that every test
                // at level 0 would find its sample near, the cell keeps its
                // Marching Cubes triangles: emit them as refinement would,
                // without running the tests (see `near_bound`).
                let settled = if F::MULTILINEAR
                    && F::LINEAR_ON_EDGES
                    && refinable.interior
                    && refinable.shift[6] == 0.0
                    && !count_only
                    && sh.max_level > 0
                    && extra.is_empty()
                {
                    let far = cell_f.abs().max_element();
                    near_bound::all_near(&c, sh.iso, far, &kept, &pos_of, opts.epsilon, opts.rule)
                        // The patch check the refined patch would face
                        // (unsplit, it fails only when nearly flat).
                        .filter(|_| {
                            let area = pos_of
                                .chunks_exact(3)
                                .fold(DVec3::ZERO, |a, p| a + vector_area([p[0], p[1], p[2]]));
                            faces_like_marching_cubes(area, &pos_of)
                        })
                } else {
                    None
                };
                if let Some(samples) = settled {
                    let n = kept.len() as u64;
                    if n > leaf_budget {
                        sh.over_cap.store(true, Ordering::Relaxed);
                        break 'layers;
                    }
                    out.tris.extend_from_slice(&kept);
                    out.levels.resize(out.levels.len() + kept.len(), 0);
                    out.counters.samples += samples;
                    out.counters.per_level[0] += n;
                    out.counters.nodes_per_level[0] += n;
                    if let Some(p) = sh.poll {
                        p.poll_timed();
                    }
                    if refined_cell_done(sh, &mut out, count_only, end, &mut reported, cap) {
                        break 'layers;
                    }
                    continue;
                }
                // Polygons whose table diagonals refinement cannot follow
                // are re-cut first (see `diagonals`).
                tested.clear();
                if refinable.interior {
                    out.counters.recut_polygons += choose_diagonals::<F>(
                        &fc,
                        refinable.iso(sh.iso, 0, DVec3::ZERO),
                        opts.epsilon,
                        &mut kept,
                        &mut pos_of,
                        &mut tested,
                    ) as u64;
                }
                // Boundary edges of the cell's patch lie on cell faces.
                uses.clear();
                for t in &kept {
                    for e in 0..3 {
                        let key = edge_key(t[e], t[(e + 1) % 3]);
                        match uses.iter_mut().find(|u| u.0 == key) {
                            Some(u) => u.1 += 1,
                            None => uses.push((key, 1)),
                        }
                    }
                }
                let (t_start, v_start) = (out.tris.len(), out.verts.len());
                let before = out.counters.clone();
                local.clear();
                // Room for the cell's whole refined patch, reserved up front
                // where its worst case is modest (4^max_level leaves per
                // Marching Cubes triangle under rules A and A1, 6^max_level
                // under A2 and B: up to level 6-8 or 4-6 by the cell's
                // triangles; the slab's map gets the points its boundary
                // edges can split into): the slab's buffers, the large
                // allocations, then grow here, where a failure is an error,
                // and not while the patch is emitted, where it would abort
                // the process. (`reserved`: the leaves reserved for, which
                // a debug assertion checks the patch against.)
                let mut reserved = usize::MAX;
                if !count_only {
                    let level = sh.max_level.min(31);
                    let worst = (kept.len() as u64)
                        .saturating_mul(opts.rule.most_children().saturating_pow(level));
                    if worst <= CELL_RESERVE_LIMIT {
                        let n = worst as usize;
                        let on_faces = 3 * (kept.len() << level) + 16;
                        let room = try_room(&mut out.tris, n)
                            .and_then(|_| try_room(&mut out.levels, n))
                            .and_then(|_| try_room(&mut out.verts, n + 16))
                            .and_then(|_| {
                                map.try_reserve(on_faces).map_err(|_| {
                                    (map.len() + on_faces).max(2 * map.capacity())
                                        * size_of::<([u64; 3], u32)>()
                                })
                            });
                        if let Err(bytes) = room {
                            out.scratch_failed = bytes;
                            break 'layers;
                        }
                        reserved = n;
                    }
                }
                // Whether refinement merged two of the cell's points (split
                // points that weld onto another point, which straight
                // gradient lines meeting on S_K can cause). Each new point
                // is created once (the edge cache hands its id to the
                // triangle on the other side), so any weld inside the cell,
                // or onto one of its Marching Cubes points, or twice onto
                // the same point of a neighbour, is a merge. Without one,
                // the patch is a subdivision of the Marching Cubes patch
                // and only its facing needs checking.
                // Attempts, each only when the previous one gave an unsound
                // patch: first, interior samples whose gradient line leaves
                // the cell split at the nearest point of S_K inside the cell
                // (see Refiner::interior_fallback); second, they stay
                // unsplit; third, interior edges and centres stay whole.
                // Edges on the cell's faces decide alike in every attempt,
                // so neighbours still match.
                const ATTEMPTS: usize = 3;
                for attempt in 0..ATTEMPTS {
                    cache.clear();
                    count_leaves.clear();
                    let mut merged = false;
                    let mut sliver = false;
                    let grow_failed = std::cell::Cell::new(0usize);
                    let nearest_before = out.counters.nearest_splits;
                    let mut area = DVec3::ZERO;
                    seen.clear();
                    for t in &kept {
                        for &v in t {
                            seen.insert_new(v as u64, ());
                        }
                    }
                    // Distinct ids for new points when counting (the edge
                    // cache is keyed by ids; 0..16 are the cell's own points).
                    let mut next_id = 16u32;
                    let tick = || {
                        if let Some(p) = sh.poll {
                            p.poll_timed();
                        }
                    };
                    let mut refiner = Refiner::<F> {
                        cell: &fc,
                        iso: sh.iso,
                        epsilon: opts.epsilon,
                        max_level: sh.max_level,
                        rule: opts.rule,
                        counters: &mut out.counters,
                        cache: &mut cache,
                        interior_fallback: attempt == 0,
                        leaf_budget,
                        stall_len2: if sh.subcells {
                            subcells::stall_len2(sh.max_level)
                        } else {
                            f64::INFINITY
                        },
                        cancel: sh.cancel,
                        polls: 0,
                        tick: sh.poll.is_some().then_some(&tick as &(dyn Fn() + Sync)),
                        alloc_failed: 0,
                        refinable: if attempt < ATTEMPTS - 1 {
                            refinable
                        } else {
                            Refinable {
                                interior: false,
                                ..refinable
                            }
                        },
                    };
                    if attempt == 0 {
                        // The diagonals' tests, already run to choose them.
                        for (a, b, s) in &tested {
                            refiner.preset(*a, *b, s);
                        }
                    }
                    for (n, t) in kept.iter().enumerate() {
                        let p = [pos_of[3 * n], pos_of[3 * n + 1], pos_of[3 * n + 2]];
                        let mut fixed = [0u8; 3];
                        for e in 0..3 {
                            let key = edge_key(t[e], t[(e + 1) % 3]);
                            let boundary = uses.iter().any(|u| u.0 == key && u.1 == 1);
                            if boundary {
                                fixed[e] = shared_fixed_axes(p[e], p[(e + 1) % 3]);
                            }
                        }
                        let root = Tri {
                            v: *t,
                            p,
                            fixed,
                            level: 0,
                            near: 0,
                        };
                        if count_only {
                            // Leaves are kept only to mesh a stalled cell
                            // again (and count that).
                            let leaves = &mut count_leaves;
                            let within_budget = refiner.run(
                                root,
                                sh.subcells,
                                &mut |t: &Tri| {
                                    if sh.subcells {
                                        leaves.push((t.v, t.p, t.level));
                                    }
                                },
                                &mut |_| {
                                    next_id += 1;
                                    next_id
                                },
                            );
                            if refiner.alloc_failed != 0 {
                                out.scratch_failed = refiner.alloc_failed;
                                break 'layers;
                            }
                            if !within_budget {
                                // More leaves than the cap: the level does
                                // not fit, whatever the rest counts (or
                                // the call was stopped, which wins).
                                sh.over_cap.store(true, Ordering::Relaxed);
                                break 'layers;
                            }
                        } else {
                            let verts = &mut out.verts;
                            let (map, local) = (&mut map, &mut local);
                            let (merged, area, seen) = (&mut merged, &mut area, &mut seen);
                            let sliver = &mut sliver;
                            let tris = &mut out.tris;
                            let levels = &mut out.levels;
                            // Past the cell's reservation (a patch that may
                            // outgrow CELL_RESERVE_LIMIT) the buffers grow
                            // fallibly: an allocation that fails is
                            // recorded, nothing more is stored, and the
                            // pass fails with OutOfMemory after this tree
                            // (an infallible push aborted the host).
                            let within_budget = refiner.run(
                                root,
                                true,
                                &mut |tri: &Tri| {
                                    if grow_failed.get() != 0 {
                                        return;
                                    }
                                    if tris.len() == tris.capacity()
                                        || levels.len() == levels.capacity()
                                    {
                                        let room = try_room(tris, tris.len().max(1024))
                                            .and_then(|_| try_room(levels, levels.len().max(1024)));
                                        if let Err(bytes) = room {
                                            grow_failed.set(bytes);
                                            return;
                                        }
                                    }
                                    tris.push(tri.v);
                                    levels.push(tri.level);
                                    let a = vector_area(tri.p);
                                    *sliver |= a.length_squared() < MIN_DOUBLE_AREA2;
                                    *area += a;
                                },
                                &mut |p: DVec3| {
                                    let gp = cell_f + p;
                                    let next = verts.len() as u32;
                                    // A point inside the open cell belongs to
                                    // no other cell: a small per-cell map
                                    // welds it (same ids, less memory
                                    // traffic than the slab's map). Decided
                                    // on the global coordinates: far from the
                                    // origin, a point just inside the cell
                                    // can round onto its face, where it must
                                    // weld with the face's other points.
                                    let inner = strictly_inside(gp, cell_f);
                                    let m = if inner { &mut *local } else { &mut *map };
                                    if grow_failed.get() != 0 {
                                        return 0;
                                    }
                                    let room =
                                        if verts.len() == verts.capacity() {
                                            try_room(verts, verts.len().max(1024))
                                        } else {
                                            Ok(())
                                        }
                                        .and_then(|_| {
                                            m.try_reserve(1).map_err(|_| {
                                                (2 * m.capacity().max(1024))
                                                    .saturating_mul(size_of::<([u64; 3], u32)>())
                                            })
                                        });
                                    if let Err(bytes) = room {
                                        grow_failed.set(bytes);
                                        return 0;
                                    }
                                    let mut new = false;
                                    let id = *m.entry(key(gp)).or_insert_with(|| {
                                        new = true;
                                        verts.push(gp);
                                        next
                                    });
                                    if !new
                                        && (inner
                                            || id as usize >= v_start
                                            || seen.insert_new(id as u64, ()).is_some())
                                    {
                                        *merged = true;
                                    }
                                    id
                                },
                            );
                            let failed = grow_failed.get().max(refiner.alloc_failed);
                            if failed != 0 {
                                out.scratch_failed = failed;
                                break 'layers;
                            }
                            if !within_budget {
                                // Over the cap (or stopped): this pass's
                                // output is dropped, stop here.
                                sh.over_cap.store(true, Ordering::Relaxed);
                                break 'layers;
                            }
                        }
                    }
                    // Nearest points (of samples near a face, or off the
                    // band along the faces) can land within rounding of
                    // each other without welding: a triangle with no area
                    // means this attempt's nearest splits are undone.
                    let slivered = sliver && out.counters.nearest_splits != nearest_before;
                    // The soundness check's edge map could not grow.
                    let mut check_failed = 0;
                    let accept = count_only
                        || attempt == ATTEMPTS - 1
                        || !refinable.interior
                        || (!slivered
                            && if merged {
                                // A nearest point may weld with another point
                                // into a vertex where the patch touches itself,
                                // which the checks below do not see.
                                out.counters.nearest_splits == nearest_before
                                    && sound_patch(
                                        cell_f,
                                        &out.tris[t_start..],
                                        &out.verts,
                                        &pos_of,
                                        &mut edges,
                                    )
                                    .unwrap_or_else(|bytes| {
                                        check_failed = bytes;
                                        true
                                    })
                            } else {
                                debug_assert!(
                                    soundly_connected(&out.tris[t_start..], &mut edges)
                                        != Ok(false),
                                    "a patch without merged points is a subdivision"
                                );
                                faces_like_marching_cubes(area, &pos_of)
                            });
                    if check_failed != 0 {
                        out.scratch_failed = check_failed;
                        break 'layers;
                    }
                    if accept {
                        break;
                    }
                    drop_patch(&mut out, &mut map, &mut local, t_start, v_start, None);
                    let samples = out.counters.samples;
                    out.counters = before.clone();
                    out.counters.samples = samples;
                    if attempt + 2 == ATTEMPTS {
                        out.counters.unsound_cells += 1;
                    }
                }
                debug_assert!(
                    out.tris.len() - t_start <= reserved,
                    "a patch of {} leaves outgrew its reservation of {reserved}",
                    out.tris.len() - t_start
                );
                // A patch still far from S_K with long edges at the last
                // level: refinement stalled on a fold; mesh the cell again
                // on sub-cells, joined to the outline drawn above.
                if sh.subcells && out.counters.stalled_leaves > before.stalled_leaves {
                    let at = CellAt {
                        f: &f,
                        cell_f,
                        t_start,
                        v_start,
                        above_before: before.above_eps,
                    };
                    // Polled as refinement is: progress and the stop
                    // request (the nested extraction and the outlines of
                    // a large patch take seconds).
                    let tick = || {
                        if let Some(p) = sh.poll {
                            p.poll_timed();
                        }
                    };
                    let poll = subcells::Poll::new(
                        sh.cancel,
                        sh.poll.is_some().then_some(&tick as &(dyn Fn() + Sync)),
                    );
                    if count_only {
                        count_remeshed(&mut out, &count_leaves, &at, opts, sh.max_level, &poll);
                    } else {
                        let (m, l) = (&mut map, &mut local);
                        remesh_cell(&mut out, m, l, &at, opts, sh.max_level, &poll);
                    }
                    if sh.cancel.load(Ordering::Relaxed) {
                        // Stopped (the pass's output is dropped).
                        break 'layers;
                    }
                }
                if let Some(p) = sh.poll {
                    p.poll_timed();
                }
                if refined_cell_done(sh, &mut out, count_only, end, &mut reported, cap) {
                    break 'layers;
                }
            }
        }
        if k == k0 {
            out.first_layer_verts = out.verts.len();
        }
        sh.layers_done.fetch_add(1, Ordering::Relaxed);
        out.layers += 1;
        if let Some(p) = sh.poll {
            p.poll();
        }
    }
    if !REFINE && !count_only {
        // Plain Marching Cubes: every triangle is at level 0.
        out.levels.resize(out.tris.len(), 0);
    }
    // The last rows' triangles count towards the cap too.
    if !out.redo_with_map {
        report_emitted(sh, produced(&out, count_only), &mut reported, cap);
    }
    out.reported = reported;
    out.total_time = t0.elapsed();
    out
}

/// The first cell at or after `from` of a row of case indices whose case
/// is neither 0 nor 255 (one the surface crosses), or the row's length.
/// Eight cases at a time; out of line, so that this loop, which sees
/// nearly every cell of a large volume, keeps its registers whatever the
/// cell code around it does (inlined, its speed changed by 5-15 % with
/// unrelated changes there).
#[inline(never)]
fn next_crossed(cases: &[u8], mut from: usize) -> usize {
    const LOW: u64 = 0x0101_0101_0101_0101;
    let n = cases.len();
    while from + 8 <= n {
        let w = u64::from_le_bytes(cases[from..from + 8].try_into().unwrap());
        // Each byte xor its sign bit spread over the byte: zero exactly
        // for 0 and 255.
        let y = w ^ (((w >> 7) & LOW) * 0xFF);
        if y != 0 {
            return from + (y.trailing_zeros() / 8) as usize;
        }
        from += 8;
    }
    while from < n && matches!(cases[from], 0 | 255) {
        from += 1;
    }
    from
}

/// Reads sample layer `z` (rows of `nxs` samples) into inside bits and
/// per-row finiteness. Kept out of line: inlined into the slab pass's cell
/// loop it measured 8-10 % slower on plain Marching Cubes (the compiler's
/// choice flipped with unrelated changes to the callers).
#[inline(never)]
fn read_sample_layer<T: Scalar>(
    grid: &Grid<'_, T>,
    iso: f64,
    z: usize,
    nxs: usize,
    ins: &mut [u8],
    fin: &mut [bool],
) {
    for (jj, bits) in ins.chunks_exact_mut(nxs).enumerate() {
        fin[jj] = grid.row_inside(jj, z, iso, bits);
    }
}

/// A cell being refined in a slab: corner values less the isovalue, lowest
/// corner (global index coordinates), where its patch starts in the
/// slab's triangles and points, and the slab's count of leaves above
/// epsilon before it.
struct CellAt<'a> {
    f: &'a [f64; 8],
    cell_f: DVec3,
    t_start: usize,
    v_start: usize,
    above_before: u64,
}

/// Reserves room for `n` more items in `v`; on failure, the bytes of the
/// buffer that could not be had (at least double the old one, as `Vec`
/// grows).
fn try_room<T>(v: &mut Vec<T>, n: usize) -> Result<(), usize> {
    v.try_reserve(n).map_err(|_| {
        v.len()
            .saturating_add(n)
            .max(v.capacity().saturating_mul(2))
            .saturating_mul(size_of::<T>())
    })
}

/// Removes a cell's patch from the slab: its triangles (and their levels)
/// from `t_start` on and the points it made, from `v_start` on, with their
/// entries in the welding maps. With `poll`, stops removing map entries
/// once it finds the extraction stopped (the slab's output and its map are
/// then not used again).
fn drop_patch(
    out: &mut SlabOut,
    map: &mut KeyMap<u32>,
    local: &mut KeyMap<u32>,
    t_start: usize,
    v_start: usize,
    poll: Option<&subcells::Poll<'_>>,
) {
    for v in out.verts.drain(v_start..) {
        if poll.is_some_and(|p| p.step().is_none()) {
            break;
        }
        map.remove(&key(v));
    }
    local.clear();
    out.tris.truncate(t_start);
    out.levels.truncate(t_start);
}

/// Numbers the points of a patch `0..` in order of first use: the
/// patch's triangles over those numbers, and the ids in that order;
/// `None` when `poll` finds the extraction stopped.
fn renumber(
    tris: impl Iterator<Item = [u32; 3]>,
    poll: &subcells::Poll<'_>,
) -> Option<(Vec<[u32; 3]>, Vec<u32>)> {
    let mut ids: Vec<u32> = Vec::new();
    let mut index: HashMap<u32, u32> = HashMap::new();
    let tris = tris
        .map(|t| {
            poll.step()?;
            Some(t.map(|v| {
                *index.entry(v).or_insert_with(|| {
                    ids.push(v);
                    ids.len() as u32 - 1
                })
            }))
        })
        .collect::<Option<_>>()?;
    Some((tris, ids))
}

/// Moves a re-meshed cell's output in the per-level counts from the old
/// patch's leaf levels to the new patch's (`level` is the pass's maximum:
/// nodes there are leaves), and its leaves above epsilon to the new
/// patch's.
fn recount(out: &mut SlabOut, old: &[u8], new: &subcells::Remeshed, at: &CellAt<'_>, level: u32) {
    let c = &mut out.counters;
    for (&l, sign) in old
        .iter()
        .map(|l| (l, -1i64))
        .chain(new.levels.iter().map(|l| (l, 1)))
    {
        let l = (l as usize).min(15);
        c.per_level[l] = c.per_level[l].wrapping_add_signed(sign);
        if l == level as usize {
            c.nodes_per_level[l] = c.nodes_per_level[l].wrapping_add_signed(sign);
        }
    }
    c.above_eps = at.above_before + new.above_eps;
    c.cells_on_subcells += 1;
}

/// In a pass that only counts: counts the patch that [`remesh_cell`] would
/// put in place of the cell's stalled one (`leaves`: ids, local
/// positions, levels). Stops early, counting nothing, when `poll` finds
/// the extraction stopped.
fn count_remeshed(
    out: &mut SlabOut,
    leaves: &[([u32; 3], [DVec3; 3], u8)],
    at: &CellAt<'_>,
    options: &Options,
    max_level: u32,
    poll: &subcells::Poll<'_>,
) {
    let Some((old_tris, ids)) = renumber(leaves.iter().map(|l| l.0), poll) else {
        return;
    };
    let mut old_pos = vec![DVec3::ZERO; ids.len()];
    for (t, l) in old_tris.iter().zip(leaves) {
        for e in 0..3 {
            old_pos[t[e] as usize] = l.1[e];
        }
    }
    if let Some(new) = subcells::remesh(at.f, options, max_level, &old_pos, &old_tris, poll) {
        let old: Vec<u8> = leaves.iter().map(|l| l.2).collect();
        recount(out, &old, &new, at, max_level);
    }
}

/// Replaces the cell's refined patch (the slab's triangles from
/// `at.t_start` on) by the one [`subcells::remesh`] makes, when it makes
/// one. Points from `at.v_start` on were made for the old patch: they are
/// dropped, and those on its outline made again (so a neighbour still
/// finds them in `map`); earlier points keep their ids. When `poll` finds
/// the extraction stopped, returns early, the cell's patch then possibly
/// dropped (the pass's output is not used).
fn remesh_cell(
    out: &mut SlabOut,
    map: &mut KeyMap<u32>,
    local: &mut KeyMap<u32>,
    at: &CellAt<'_>,
    options: &Options,
    max_level: u32,
    poll: &subcells::Poll<'_>,
) {
    let Some((old_tris, ids)) = renumber(out.tris[at.t_start..].iter().copied(), poll) else {
        return;
    };
    let old_gp: Vec<DVec3> = ids.iter().map(|&v| out.verts[v as usize]).collect();
    let old_pos: Vec<DVec3> = old_gp.iter().map(|&p| p - at.cell_f).collect();
    let Some(new) = subcells::remesh(at.f, options, max_level, &old_pos, &old_tris, poll) else {
        return;
    };
    let old_levels = out.levels.split_off(at.t_start);
    recount(out, &old_levels, &new, at, max_level);
    drop_patch(out, map, local, at.t_start, at.v_start, Some(poll));
    if poll.now().is_none() {
        return;
    }
    let base = ids.len();
    let mut new_id = vec![u32::MAX; base + new.points.len()];
    for t in &new.tris {
        if poll.step().is_none() {
            out.tris.truncate(at.t_start);
            return;
        }
        let mut tri = [0u32; 3];
        for (x, &v) in t.iter().enumerate() {
            let v = v as usize;
            if new_id[v] == u32::MAX {
                let next = out.verts.len() as u32;
                new_id[v] = if v >= base {
                    let lp = new.points[v - base];
                    let gp = at.cell_f + lp;
                    if subcells::faces(lp) != 0 {
                        // On the new outline, in a face: a neighbour meshed
                        // again too makes the same point (the face's
                        // sub-samples and decisions are alike on both
                        // sides) and must find it, for the two strips
                        // between the outlines to cancel.
                        *map.entry(key(gp)).or_insert_with(|| {
                            out.verts.push(gp);
                            next
                        })
                    } else {
                        // Strictly inside the cell: this cell's alone.
                        out.verts.push(gp);
                        next
                    }
                } else if (ids[v] as usize) < at.v_start {
                    ids[v]
                } else {
                    // A point of the outline made for the old patch: a
                    // neighbour looks it up by position.
                    let gp = old_gp[v];
                    *map.entry(key(gp)).or_insert_with(|| {
                        out.verts.push(gp);
                        next
                    })
                };
            }
            tri[x] = new_id[v];
        }
        out.tris.push(tri);
    }
    out.levels.extend_from_slice(&new.levels);
}

/// Notes which of the slab's triangles from index `from` on lie in a grid
/// plane (checked while their points are in cache).
fn note_flat(out: &mut SlabOut, from: usize) {
    for n in from..out.tris.len() {
        if in_grid_plane(out.tris[n].map(|v| out.verts[v as usize])) {
            out.flat_tris.push(n as u32);
        }
    }
}

/// Where a refined cell's output starts and what the pass had produced
/// and had left under the cap before it (see [`refined_cell_done`]).
struct CellEnd {
    /// The cell's first triangle in the slab's output.
    t_start: usize,
    /// When the cell started, if it is one of the timed cells.
    timer: Option<Instant>,
    produced_before: u64,
    remaining: u64,
}

/// Ends a refined cell: notes its flat triangles, counts it (and its time
/// when timed), and reports the slab's output to the shared count when it
/// grew by many or by more than was left (one row of deeply refined cells
/// can hold far more than the cap). True when the pass is over the cap.
fn refined_cell_done<T: Scalar, F: ReconstructionFilter>(
    sh: &Shared<'_, T, F>,
    out: &mut SlabOut,
    count_only: bool,
    end: CellEnd,
    reported: &mut u64,
    cap: u64,
) -> bool {
    if !count_only {
        note_flat(out, end.t_start);
    }
    out.refined_cells += 1;
    if let Some(start) = end.timer {
        out.timed_refine += start.elapsed();
        out.timed_cells += 1;
    }
    let n = produced(out, count_only);
    (n - *reported >= 4096 || n - end.produced_before > end.remaining)
        && report_emitted(sh, n, reported, cap)
}

/// Whether the point `gp` (global index coordinates) lies in the open cell
/// whose lowest corner is `cell_f`. Decided on the global coordinates: far
/// from the origin a point just inside can round onto the cell's boundary.
#[inline(always)]
fn strictly_inside(gp: DVec3, cell_f: DVec3) -> bool {
    gp.cmpgt(cell_f).all() && gp.cmplt(cell_f + DVec3::ONE).all()
}

/// Case indices of a row of cells from the inside bits of its four sample
/// rows (`ins[0]` = (j, k), `ins[1]` = (j+1, k), `ins[2]` = (j, k+1),
/// `ins[3]` = (j+1, k+1)), in VTK corner order. Slices cut to the row's
/// length let the compiler drop bounds checks and vectorise the loop.
fn case_row(ins: &[&[u8]; 4], cases: &mut [u8]) {
    let n = cases.len();
    let (a0, b0) = (&ins[0][..n], &ins[0][1..=n]);
    let (a1, b1) = (&ins[1][..n], &ins[1][1..=n]);
    let (a2, b2) = (&ins[2][..n], &ins[2][1..=n]);
    let (a3, b3) = (&ins[3][..n], &ins[3][1..=n]);
    for i in 0..n {
        cases[i] = a0[i]
            | (b0[i] << 1)
            | (b1[i] << 2)
            | (a1[i] << 3)
            | (a2[i] << 4)
            | (b2[i] << 5)
            | (b3[i] << 6)
            | (a3[i] << 7);
    }
}

/// The triangles a slab has produced so far: those in its output, or in a
/// count pass the leaves it counted.
fn produced(out: &SlabOut, count_only: bool) -> u64 {
    if count_only {
        out.counters.per_level.iter().sum()
    } else {
        out.tris.len() as u64
    }
}

/// Adds the slab's `n` triangles produced so far (see [`produced`]) to the
/// shared count, less those reported before; returns true (and raises
/// `over_cap`) when the total exceeds `cap`.
fn report_emitted<T: Scalar, F: ReconstructionFilter>(
    sh: &Shared<'_, T, F>,
    n: u64,
    reported: &mut u64,
    cap: u64,
) -> bool {
    if n > *reported {
        let total = sh.emitted.fetch_add(n - *reported, Ordering::Relaxed) + (n - *reported);
        *reported = n;
        if total > cap {
            sh.over_cap.store(true, Ordering::Relaxed);
            return true;
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Rule, Topology};

    #[test]
    fn next_float_steps_one_float() {
        for x in [
            0.0,
            -0.0,
            1.0,
            -1.0,
            7.0,
            -7.0,
            1e300,
            -3.5e-310,
            2f64.powi(52),
        ] {
            let (up, down) = (next_float(x, true), next_float(x, false));
            assert!(up > x && down < x, "{x}");
            // Nothing between: the midpoint rounds to one of the ends.
            for (a, b) in [(x, up), (down, x)] {
                let m = a / 2.0 + b / 2.0;
                assert!(m == a || m == b, "{a} {b}");
            }
        }
        assert_eq!(next_float(1.0, true), 1.0 + f64::EPSILON);
        assert_eq!(next_float(1.0, false), 1.0 - f64::EPSILON / 2.0);
    }

    fn random_values(n: usize, seed: u64, f: impl Fn(f64) -> f64) -> Vec<f64> {
        let mut x = seed;
        (0..n)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                f((x >> 11) as f64 / (1u64 << 53) as f64)
            })
            .collect()
    }

    fn run(v: &Volume<'_>, topology: Topology, threads: usize, min_slab_cells: u64) -> Mesh {
        run_on(v, topology, threads, min_slab_cells, None)
    }

    fn run_on(
        v: &Volume<'_>,
        topology: Topology,
        threads: usize,
        min_slab_cells: u64,
        executor: Option<&dyn Executor>,
    ) -> Mesh {
        run_in_layers(v, topology, threads, min_slab_cells, 1, executor)
    }

    fn run_in_layers(
        v: &Volume<'_>,
        topology: Topology,
        threads: usize,
        min_slab_cells: u64,
        min_slab_layers: usize,
        executor: Option<&dyn Executor>,
    ) -> Mesh {
        let o = Options {
            threads,
            ..Options::marching_cubes(topology)
        };
        let mut go = |_| ControlFlow::Continue(());
        let how = How {
            min_slab_cells,
            min_slab_layers,
            min_helper_cells: 0,
            world_points: true,
            executor,
            serial_assembly_triangles: 0,
            extreme: None,
            sample_scale: [1.0, 1.0],
        };
        extract_in_slabs(v, 0.0, &o, &mut go, how).unwrap()
    }

    fn bits(m: &Mesh) -> (Vec<[u64; 3]>, &[[u64; 3]]) {
        let p = m.index_points.iter().map(|p| p.map(f64::to_bits)).collect();
        (p, &m.triangles)
    }

    #[test]
    fn unrefined_output_is_the_same_for_any_slab_cut() {
        crate::volume::test_offset_limit::raise();
        // Without refinement, points strictly inside grid edges are welded
        // by the edge caches alone (no map): every cut into slabs and every
        // thread count must still give the same mesh, with no two points at
        // the same position. Volumes: values on a few integers (many
        // samples equal to the isovalue, many ambiguous cells), random
        // reals, and the same far from the origin, where interior points of
        // ambiguous cells round onto cell faces (the pass is redone with
        // every point in the map).
        let d = [9u64, 8, 13];
        let n = (d[0] * d[1] * d[2]) as usize;
        let far = [1i64 << 50, 1 << 50, -(1 << 50)];
        let cases: Vec<([u64; 3], Vec<f64>, [i64; 3])> = vec![
            (d, random_values(n, 1, |u| (u * 7.0).floor() - 3.0), [0; 3]),
            (d, random_values(n, 2, |u| 2.0 * u - 1.0), [0; 3]),
            (
                d,
                random_values(n, 3, |u| 2.0 * u - 1.0),
                [-(1 << 50), 5, 1 << 49],
            ),
            (
                d,
                random_values(n, 4, |u| (u * 3.0).floor() - 1.0),
                [1 << 50, 0, -3],
            ),
            // Coordinates in steps of 1/4 on every axis: here an interior
            // point falls onto a grid edge's point (found by a search; a
            // pass that is not redone leaves the two unwelded).
            ([3, 3, 3], random_values(27, 70141, |u| 2.0 * u - 1.0), far),
        ];
        for (dims, values, offset) in &cases {
            let v = Volume::new(values.as_slice(), *dims).with_index_offset(*offset);
            for topology in [Topology::Trilinear, Topology::Classic] {
                let whole = run(&v, topology, 1, MIN_CELLS_PER_SLAB);
                assert!(!whole.triangles.is_empty());
                let (points, _) = bits(&whole);
                let mut sorted = points.clone();
                sorted.sort_unstable();
                sorted.dedup();
                assert_eq!(sorted.len(), points.len(), "{offset:?}: points not welded");
                for threads in [1, 2, 3] {
                    let cut = run(&v, topology, threads, 1);
                    assert!(
                        bits(&cut) == bits(&whole),
                        "{offset:?} {topology:?}: {threads} threads, small slabs"
                    );
                    // Slabs of several layers: points linked across a plane
                    // lie in a slab's first layer only, and the ones above
                    // it are numbered by a shift.
                    let thick = run_in_layers(&v, topology, threads, 1, 3, None);
                    assert!(
                        bits(&thick) == bits(&whole),
                        "{offset:?} {topology:?}: {threads} threads, slabs of 3 layers"
                    );
                    let ex = crate::par::tests::Scrambled {
                        threads,
                        seed: threads as u64,
                    };
                    let lent = run_on(&v, topology, 1, 1, Some(&ex));
                    assert!(
                        bits(&lent) == bits(&whole),
                        "{offset:?} {topology:?}: executor of {threads}, small slabs"
                    );
                }
            }
        }
    }

    #[test]
    fn flat_triangles_are_found_without_looking_at_every_one() {
        crate::volume::test_offset_limit::raise();
        // The unrefined pass looks for triangles lying in a grid plane only
        // in cells whose table triangles have three points on one face, or
        // once a point sat on a grid point; its debug check fails the test
        // if any other triangle is flat. Volumes: reals (no point on a
        // sample), a few integers (many), and both far from the origin.
        let mut flat = 0;
        for seed in 0..200u64 {
            let d = [2 + seed % 5, 2 + seed % 3, 2 + seed % 4];
            let n = (d[0] * d[1] * d[2]) as usize;
            let ties = seed % 2 == 0;
            let values = random_values(n, seed + 11, |u| {
                if ties {
                    (u * 5.0).floor() - 2.0
                } else {
                    2.0 * u - 1.0
                }
            });
            let offset = if seed % 3 == 0 {
                [1 << 50, -(1 << 49), 7]
            } else {
                [0; 3]
            };
            let v = Volume::new(values.as_slice(), d).with_index_offset(offset);
            for topology in [Topology::Trilinear, Topology::Classic] {
                let m = run(&v, topology, 1, 1);
                // In release builds too: the two cells sharing a face both
                // make a triangle lying in it, one of each pair is missed
                // when the search skips it, and the pair stays.
                let mut seen = std::collections::HashSet::new();
                for t in &m.triangles {
                    let p = t.map(|i| m.index_points[i as usize]);
                    let in_plane = (0..3).any(|a| {
                        p[0][a] == p[1][a] && p[1][a] == p[2][a] && p[0][a].fract() == 0.0
                    });
                    flat += in_plane as usize;
                    let mut key = *t;
                    key.sort_unstable();
                    assert!(
                        seen.insert(key),
                        "seed {seed} {topology:?}: triangle {t:?} twice (in a grid plane: {in_plane})"
                    );
                }
            }
        }
        // The volumes do make triangles in grid planes (kept ones: one of
        // a pair, or one alone on the volume's boundary).
        assert!(flat > 0);
    }

    #[test]
    fn the_output_guess_holds_the_rippled_sample_and_stays_bounded() {
        // The rippled Marschner-Lobb sample, about the busiest surface a
        // grid that size carries, fits the up-front reservation (no
        // regrowth); huge grids stay under the cap.
        let ml = crate::samples::marschner_lobb(41);
        let o = Options::marching_cubes(Topology::Trilinear);
        let m = extract(&ml.volume(), ml.isovalue, &o).unwrap();
        let dims = ml.dims.map(|n| n as usize - 1);
        assert!(surface_guess(dims, dims[2]) >= m.triangles.len());
        assert!(surface_guess(dims, dims[2]) < 2 * m.triangles.len());
        assert_eq!(surface_guess([1 << 20; 3], 1 << 20), 1 << 22);
        assert_eq!(surface_guess([5, 5, 0], 0), 0);
    }

    #[test]
    fn threads_that_cannot_start_leave_the_output_unchanged() {
        // A limit on threads (a container's pids limit) makes helper
        // threads fail to start: the extraction and the measure then run
        // on the threads that start (the calling one) instead of failing,
        // with the same result.
        let atoms = crate::samples::atoms(24);
        let v = atoms.volume();
        let o = Options {
            epsilon: 0.01,
            threads: 3,
            ..Options::default()
        };
        let measure = |m: &Mesh| {
            let mo = crate::accuracy::MeasureOptions {
                threads: 3,
                ..Default::default()
            };
            crate::accuracy::measure(&v, atoms.isovalue, &m.index_points, &m.triangles, &mo)
                .unwrap()
        };
        let pooled = extract(&v, atoms.isovalue, &o).unwrap();
        let pooled_distance = measure(&pooled);
        crate::helpers::SPAWN_FAILS.with(|f| f.set(true));
        let fallback = extract(&v, atoms.isovalue, &o);
        let fallback_distance = fallback.as_ref().ok().map(measure);
        crate::helpers::SPAWN_FAILS.with(|f| f.set(false));
        let fallback = fallback.unwrap();
        assert!(pooled.stats.output_triangles > pooled.stats.mc_triangles);
        assert_eq!(pooled.points, fallback.points);
        assert_eq!(pooled.triangles, fallback.triangles);
        assert_eq!(pooled.normals, fallback.normals);
        assert_eq!(
            format!("{pooled_distance:?}"),
            format!("{:?}", fallback_distance.unwrap())
        );
    }

    #[test]
    fn slab_counts() {
        // Refinement off: no slab under the minimum, at least one, and
        // whole shares for the workers (5 slabs' worth on 2: 4).
        assert_eq!(
            slab_count(24, 60_000, 2, false, MIN_CELLS_PER_SLAB, 1, u64::MAX),
            1
        );
        assert_eq!(
            slab_count(24, 340_000, 2, false, MIN_CELLS_PER_SLAB, 1, u64::MAX),
            4
        );
        assert_eq!(
            slab_count(
                255,
                255u64.pow(3),
                2,
                false,
                MIN_CELLS_PER_SLAB,
                1,
                u64::MAX
            ),
            16
        );
        assert_eq!(
            slab_count(0, 0, 2, false, MIN_CELLS_PER_SLAB, 1, u64::MAX),
            1
        );
        // Refinement on: several slabs a thread whatever the size.
        assert_eq!(
            slab_count(24, 294_912, 2, true, MIN_CELLS_PER_SLAB, 1, u64::MAX),
            16
        );
        // One thread: one slab without refinement, several with it.
        assert_eq!(
            slab_count(
                255,
                255u64.pow(3),
                1,
                false,
                MIN_CELLS_PER_SLAB,
                1,
                u64::MAX
            ),
            1
        );
        assert_eq!(
            slab_count(255, 255u64.pow(3), 1, true, MIN_CELLS_PER_SLAB, 1, u64::MAX),
            8
        );
        // A few layers a slab while there are more slabs than workers:
        // 23 layers on 2 workers, 7 slabs, rounded down to 6; 12 layers on
        // 8 workers, one each.
        assert_eq!(slab_count(23, 283_360, 2, false, 1 << 14, 3, u64::MAX), 6);
        assert_eq!(slab_count(23, 283_360, 2, false, 1 << 14, 1, u64::MAX), 16);
        assert_eq!(slab_count(12, 1 << 30, 8, false, 1 << 14, 3, u64::MAX), 8);
        // A slab each for helpers where each gets enough cells: Marschner-
        // Lobb 41^3 on 2 and 16 workers, the 64^3 sphere on 16 (else 1).
        assert_eq!(
            slab_count(40, 64_000, 2, false, MIN_CELLS_PER_SLAB, 3, 1 << 14),
            2
        );
        assert_eq!(
            slab_count(40, 64_000, 16, false, MIN_CELLS_PER_SLAB, 3, 1 << 14),
            3
        );
        assert_eq!(
            slab_count(63, 250_047, 16, false, MIN_CELLS_PER_SLAB, 3, 1 << 14),
            15
        );
        assert_eq!(
            slab_count(40, 64_000, 2, false, MIN_CELLS_PER_SLAB, 3, u64::MAX),
            1
        );
        // Slabs stay under 2^31 layers (32-bit cache stamps).
        assert_eq!(
            slab_count(5 << 31, 5 << 31, 1, false, u64::MAX, 1, u64::MAX),
            5
        );
    }

    /// The word-at-a-time scan finds the same cells as looking at each:
    /// rows of every length around the word size, mostly 0 and 255 with a
    /// few other cases, from every start.
    #[test]
    fn next_crossed_finds_every_crossed_cell_in_order() {
        let mut rng = crate::test_rng::XorShift(0x2545_f491_4f6c_dd1d);
        let mut next = |n: u64| rng.below(n);
        for len in 0..40 {
            for _ in 0..200 {
                let row: Vec<u8> = (0..len)
                    .map(|_| match next(10) {
                        0..=3 => 0,
                        4..=7 => 255,
                        // 1 and 254 differ from 0 and 255 in one bit.
                        8 => [1, 254, 127, 128][next(4) as usize],
                        _ => next(256) as u8,
                    })
                    .collect();
                for from in 0..=len {
                    let want = (from..len)
                        .find(|&i| row[i] != 0 && row[i] != 255)
                        .unwrap_or(len);
                    assert_eq!(next_crossed(&row, from), want, "{row:?} from {from}");
                }
            }
        }
    }

    /// Rules A2 and B split a triangle in six, so a patch can have more
    /// leaves than 4^max_level per Marching Cubes triangle: the room
    /// reserved for a cell's patch must cover that (a debug assertion in
    /// `slab_pass` checks each patch against its reservation; with 4^level
    /// reserved it failed here).
    #[test]
    fn a_cell_reservation_covers_six_way_splits() {
        let level = 4;
        let mut beyond_four = false;
        for seed in 1..=6 {
            let values = random_values(5 * 5 * 5, seed, |u| u - 0.5);
            let v = Volume::new(values.as_slice(), [5, 5, 5]);
            for rule in [Rule::A, Rule::A1, Rule::A2, Rule::B] {
                let o = Options {
                    epsilon: 1e-6,
                    max_level: level,
                    rule,
                    ..Options::default()
                };
                let mesh = crate::extract(&v, 0.0, &o).unwrap();
                let (mc, out) = (mesh.stats.mc_triangles, mesh.stats.output_triangles);
                assert!(mc > 0, "seed {seed}: no surface");
                // The bound itself, over the whole mesh.
                let most = rule.most_children().pow(level);
                assert!(
                    out <= mc * most,
                    "{rule:?} seed {seed}: {out} > {mc} x {most}"
                );
                beyond_four |= out > mc * 4u64.pow(level);
            }
        }
        assert!(
            beyond_four,
            "no patch went past 4^level: the case is not exercised"
        );
    }
}
