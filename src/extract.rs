//! The extraction driver: validation, the passes over slabs of cells
//! (each slab's pass in [`crate::slab_pass`], their number in
//! [`crate::slabs`]), the triangle cap, progress and cancellation, then
//! the assembly ([`crate::assemble`]) and the normals.
//!
//! Determinism: the volume is cut into slabs of cell layers along z, each
//! processed by one worker in cell order (k, j, i). Vertices are numbered
//! in order of first use in that global cell order, and points are welded
//! when their global index coordinates are bit-identical (which is exactly
//! how `vtkMarchingCubes` merges points, samples equal to the isovalue
//! included). Neither depends on the number or size of slabs, so the output
//! is identical for any thread count.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use crate::assemble::assemble;
use crate::cubic::{prefilter, BSplineKernel, CatmullRomKernel, Tricubic};
use crate::executor::Executor;
use crate::filter::{ReconstructionFilter, Trilinear, TrilinearFast};
use crate::helpers::with_helpers;
use crate::layers::ScratchPool;
use crate::mesh::{Mesh, Stats};
use crate::normals::{compute_gradients, compute_normals};
use crate::options::{Options, Reconstruction};
use crate::par::{Exec, OnCaller};
use crate::slab_pass::{process_slab, Mode, Shared, SlabOut};
use crate::slabs::{
    slab_count, MIN_CELLS_FOR_HELPERS, MIN_CELLS_PER_LENT_SLAB, MIN_CELLS_PER_SLAB,
    MIN_CELLS_PER_WORKER, MIN_LAYERS_PER_SLAB, SERIAL_MAX_CELLS,
};
use crate::subcells;
use crate::volume::{Grid, Scalar, Volume};
use crate::{Error, HARD_TRIANGLE_CAP, MAX_LEVEL_LIMIT};

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
                let f = TrilinearFast(Trilinear::new(grid));
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Rule, Topology};

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

    /// Rules A2 and B split a triangle in six, so a patch can have more
    /// leaves than 4^max_level per Marching Cubes triangle: the room
    /// reserved for a cell's patch must cover that (a debug assertion in
    /// `cell_refine` checks each patch against its reservation; with 4^level
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
