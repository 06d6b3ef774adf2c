//! How a volume is cut into slabs of cell layers along z, one a task,
//! and when helper threads start. None of it changes the output (see
//! `extract`), only how the work is shared.

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
pub(crate) const MIN_CELLS_PER_SLAB: u64 = 1 << 16;

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
pub(crate) const MIN_CELLS_PER_LENT_SLAB: u64 = MIN_CELLS_PER_SLAB;

/// With refinement off, the fewest cell layers a slab gets while there
/// are more slabs than workers.
pub(crate) const MIN_LAYERS_PER_SLAB: usize = 3;

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
pub(crate) const MIN_CELLS_FOR_HELPERS: u64 = 1 << 15;

/// With refinement off on the library's own threads, the fewest cells of
/// a slab given to a worker so that each has one (see
/// [`MIN_CELLS_FOR_HELPERS`]): helpers beyond that many would wake, and
/// watch for work, for next to nothing.
pub(crate) const MIN_CELLS_PER_WORKER: u64 = 1 << 14;

/// With refinement off and one thread, the most cells an extraction runs
/// on the calling thread without a pool (a few milliseconds of work: no
/// progress is reported in between).
pub(crate) const SERIAL_MAX_CELLS: u64 = 1 << 22;

/// How many slabs (runs of cell layers along z) to cut `nz` layers of
/// `cells` cells into for `threads` workers, with refinement off slabs of
/// at least `min_cells` cells and (while there are more slabs than
/// workers) `min_layers` layers, but a slab for each worker where each can
/// have `min_worker_cells` (`u64::MAX`: no such promise). The output does
/// not depend on it.
pub(crate) fn slab_count(
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slab_counts() {
        const M: u64 = MIN_CELLS_PER_SLAB;
        const ANY: u64 = u64::MAX;
        let n255 = 255u64.pow(3);
        // (layers, cells, threads, refine, min cells, min layers, cells a
        // worker, slabs)
        type Case = (usize, u64, usize, bool, u64, usize, u64, usize);
        let cases: &[Case] = &[
            // Refinement off: no slab under the minimum, at least one, and
            // whole shares for the workers (5 slabs' worth on 2: 4).
            (24, 60_000, 2, false, M, 1, ANY, 1),
            (24, 340_000, 2, false, M, 1, ANY, 4),
            (255, n255, 2, false, M, 1, ANY, 16),
            (0, 0, 2, false, M, 1, ANY, 1),
            // Refinement on: several slabs a thread whatever the size.
            (24, 294_912, 2, true, M, 1, ANY, 16),
            // One thread: one slab without refinement, several with it.
            (255, n255, 1, false, M, 1, ANY, 1),
            (255, n255, 1, true, M, 1, ANY, 8),
            // A few layers a slab while there are more slabs than workers:
            // 23 layers on 2 workers, 7 slabs, rounded down to 6; 12 layers
            // on 8 workers, one each.
            (23, 283_360, 2, false, 1 << 14, 3, ANY, 6),
            (23, 283_360, 2, false, 1 << 14, 1, ANY, 16),
            (12, 1 << 30, 8, false, 1 << 14, 3, ANY, 8),
            // A slab each for helpers where each gets enough cells:
            // Marschner-Lobb 41^3 on 2 and 16 workers, the 64^3 sphere on
            // 16 (else 1).
            (40, 64_000, 2, false, M, 3, 1 << 14, 2),
            (40, 64_000, 16, false, M, 3, 1 << 14, 3),
            (63, 250_047, 16, false, M, 3, 1 << 14, 15),
            (40, 64_000, 2, false, M, 3, ANY, 1),
            // Slabs stay under 2^31 layers (32-bit cache stamps).
            (5 << 31, 5 << 31, 1, false, ANY, 1, ANY, 5),
        ];
        for &(nz, cells, threads, refine, min_cells, min_layers, per_worker, want) in cases {
            assert_eq!(
                slab_count(nz, cells, threads, refine, min_cells, min_layers, per_worker),
                want,
                "{nz} layers, {cells} cells, {threads} threads, refine {refine}"
            );
        }
    }
}
