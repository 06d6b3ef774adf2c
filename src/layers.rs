//! Per-worker scratch of the Marching Cubes pass over a slab: the inside
//! bits of two sample layers and the ids of the points on their grid edges.
//!
//! The edge caches take about 40 bytes per sample of a layer (2.6 MB for a
//! 256 x 256 layer). Allocating, clearing and faulting them in again for
//! every slab cost more than Marching Cubes itself on small volumes, so a
//! [`ScratchPool`] hands the same buffers from slab to slab. Cache entries
//! carry a stamp that is unique to one sample layer (or cell layer, for the
//! z edges) of one slab, so nothing needs clearing between slabs and an
//! entry left by an earlier slab never matches.

use std::sync::Mutex;

use crate::recycle::SCRATCH;
use crate::tables::cube::{CORNERS, EDGES, EDGE_AXIS};

/// An empty cache entry (its stamp, `u32::MAX`, is never handed out).
pub(crate) const EMPTY: u64 = u64::MAX;

/// A cache entry: the point `id` placed on a grid edge of the layer
/// stamped `stamp`.
#[inline(always)]
pub(crate) fn entry(stamp: u32, id: u32) -> u64 {
    (stamp as u64) << 32 | id as u64
}

/// The id in `entry` if it was placed under `stamp`.
#[inline(always)]
pub(crate) fn lookup(entry: u64, stamp: u32) -> Option<u32> {
    (entry >> 32 == stamp as u64).then_some(entry as u32)
}

/// Scratch buffers for one slab worker, sized for cell layers of
/// `nx` x `ny` cells.
pub(crate) struct LayerScratch {
    /// Inside bits of the two sample layers of the current cell layer (by
    /// z parity), `(nx + 1) * (ny + 1)` each.
    pub insides: [Vec<u8>; 2],
    /// Whether each sample row of those layers is all finite.
    pub finite: [Vec<bool>; 2],
    /// Ids on grid edges, five regions of one sample layer's length
    /// (`(nx + 1) * (ny + 1)`, rows of `nx + 1`, an edge at its lower
    /// sample): the x edges of the two sample layers (by z parity), their
    /// y edges, then the z edges of the current cell layer. One buffer, so
    /// that a cell's edge finds its slot by a fixed offset from the cell
    /// ([`cell_edge_slots`]) rather than by a branch on its axis.
    pub edges: Vec<u64>,
    /// Case indices of one row of cells.
    pub cases: Vec<u8>,
    /// The first stamp not handed out yet.
    next_stamp: u32,
    /// The cell layer size the buffers are laid out for.
    dims: (usize, usize),
}

/// Bytes of the buffers of a [`LayerScratch`] for layers of `nx` x `ny`
/// cells (the inside bits and the edge caches; the per-row flags and case
/// indices are a few bytes a row).
/// Saturating, so that the message of a failed reservation of a huge
/// layer tells a size beyond the address space rather than a wrapped one.
fn scratch_bytes(nx: usize, ny: usize) -> usize {
    let layer = (ny.saturating_add(1)).saturating_mul(nx.saturating_add(1));
    layer.saturating_mul(2 + 8 * 5)
}

/// For a cell layer of z parity `p`, each cell edge's slot in
/// [`LayerScratch::edges`] less the cell's index `j * nxs + i`
/// (`[p][e]`), and the layer above the cell layer's own (0 or 1) that
/// stamps it (`.1[e]`, the z offset of its lower corner), for rows of
/// `nxs` samples and layers of `len` samples.
pub(crate) fn cell_edge_slots(nxs: usize, len: usize) -> ([[usize; 12]; 2], [u32; 12]) {
    let mut at = [[0; 12]; 2];
    let mut dz = [0; 12];
    for e in 0..12 {
        let ca = CORNERS[EDGES[e][0] as usize].map(|c| c as usize);
        dz[e] = ca[2] as u32;
        for (p, slots) in at.iter_mut().enumerate() {
            let parity = (p + ca[2]) & 1;
            let region = match EDGE_AXIS[e] {
                0 => parity,
                1 => 2 + parity,
                _ => 4,
            };
            slots[e] = region * len + ca[1] * nxs + ca[0];
        }
    }
    (at, dz)
}

impl crate::recycle::Held for LayerScratch {
    fn bytes(&self) -> usize {
        scratch_bytes(self.dims.0, self.dims.1)
    }
    // Nothing to clear: entries of earlier calls carry stamps that never
    // match again (the stamps go on from call to call).
}

impl LayerScratch {
    /// Buffers for layers of `nx` x `ny` cells, or the bytes that could
    /// not be allocated.
    fn new(nx: usize, ny: usize) -> Result<Self, usize> {
        let s = (|| {
            // Checked: a layer too large to address cannot be allocated.
            let layer = (ny + 1).checked_mul(nx + 1)?;
            Some(LayerScratch {
                insides: [filled(layer, 0)?, filled(layer, 0)?],
                finite: [filled(ny + 1, true)?, filled(ny + 1, true)?],
                edges: filled(layer.checked_mul(5)?, EMPTY)?,
                cases: filled(nx, 0)?,
                next_stamp: 0,
                dims: (nx, ny),
            })
        })();
        s.ok_or(scratch_bytes(nx, ny))
    }

    /// Reserves `n` consecutive stamps (`n < u32::MAX`) and returns the
    /// first; the caches are cleared when the stamps run out.
    pub fn stamps(&mut self, n: usize) -> u32 {
        debug_assert!((n as u64) < u32::MAX as u64);
        if self.next_stamp as u64 + n as u64 >= u32::MAX as u64 {
            self.edges.fill(EMPTY);
            self.next_stamp = 0;
        }
        let first = self.next_stamp;
        self.next_stamp += n as u32;
        first
    }
}

/// The scratch buffers of one extraction's workers: at most one set per
/// worker running at a time is ever allocated, or taken from those kept
/// since earlier calls ([`crate::recycle`]), to which they return when the
/// pool is dropped.
pub(crate) struct ScratchPool {
    nx: usize,
    ny: usize,
    free: Mutex<Vec<LayerScratch>>,
}

impl ScratchPool {
    /// A pool for cell layers of `nx` x `ny` cells.
    pub fn new(nx: usize, ny: usize) -> Self {
        ScratchPool {
            nx,
            ny,
            free: Mutex::new(Vec::new()),
        }
    }

    /// A set of buffers (reused when one is free), or the bytes that could
    /// not be allocated.
    pub fn take(&self) -> Result<LayerScratch, usize> {
        let reused = self.free.lock().unwrap_or_else(|e| e.into_inner()).pop();
        let dims = (self.nx, self.ny);
        match reused.or_else(|| SCRATCH.take_where(|s| s.dims == dims)) {
            Some(s) => Ok(s),
            None => LayerScratch::new(self.nx, self.ny),
        }
    }

    /// Returns buffers to the pool.
    pub fn give(&self, s: LayerScratch) {
        self.free.lock().unwrap_or_else(|e| e.into_inner()).push(s);
    }
}

impl Drop for ScratchPool {
    fn drop(&mut self) {
        let free = std::mem::take(self.free.get_mut().unwrap_or_else(|e| e.into_inner()));
        for s in free {
            SCRATCH.give(s);
        }
    }
}

/// A vector of `n` copies of `value`, or `None` when the allocation fails.
fn filled<T: Clone>(n: usize, value: T) -> Option<Vec<T>> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).ok()?;
    v.resize(n, value);
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A layer too large to address reports a saturated size, not a
    /// wrapped one (2^30 x 2^30 cells once read as about 1.15e19 bytes).
    #[test]
    fn huge_layers_saturate_their_size() {
        assert_eq!(scratch_bytes(3, 1), 42 * 8);
        let n = (1usize << 30) - 1;
        assert_eq!(scratch_bytes(n, n), usize::MAX);
        assert_eq!(LayerScratch::new(n, n).err(), Some(usize::MAX));
    }

    #[test]
    fn entries_match_only_their_stamp() {
        let e = entry(7, 42);
        assert_eq!(lookup(e, 7), Some(42));
        assert_eq!(lookup(e, 8), None);
        assert_eq!(lookup(EMPTY, 0), None);
        assert_eq!(lookup(EMPTY, u32::MAX - 1), None);
    }

    #[test]
    fn stamps_are_fresh_until_they_run_out_then_caches_clear() {
        let pool = ScratchPool::new(3, 2);
        let mut s = pool.take().unwrap();
        // (The set may come from an earlier extraction, its stamps gone on.)
        let first = s.stamps(5);
        assert_eq!(s.stamps(4), first + 5);
        s.edges[1] = entry(6, 3);
        pool.give(s);
        // The pool hands the same buffers back, entries and stamps kept.
        let mut s = pool.take().unwrap();
        assert_eq!(lookup(s.edges[1], 6), Some(3));
        s.next_stamp = u32::MAX - 3;
        // Not enough stamps left: everything is cleared and they restart.
        assert_eq!(s.stamps(3), 0);
        assert!(s.edges.iter().all(|&e| e == EMPTY));
        assert_eq!(s.stamps(1), 3);
    }

    #[test]
    fn each_grid_edge_has_one_slot_shared_by_its_cells() {
        // Every (cell, edge) of a 3 x 2 x 2 block of cells, keyed by the
        // grid edge it is: slot and stamp layer (z of the sample layer for
        // x and y edges, of the cell layer for z edges) agree exactly when
        // the grid edge is the same one.
        let (nx, ny) = (3usize, 2usize);
        let (nxs, len) = (nx + 1, (nx + 1) * (ny + 1));
        let (at, dz) = cell_edge_slots(nxs, len);
        let mut seen = std::collections::HashMap::new();
        for k in 0..2usize {
            for j in 0..ny {
                for i in 0..nx {
                    for e in 0..12 {
                        let ca = CORNERS[EDGES[e][0] as usize].map(|c| c as usize);
                        let grid_edge = (i + ca[0], j + ca[1], k + ca[2], EDGE_AXIS[e]);
                        let slot = j * nxs + i + at[k & 1][e];
                        assert!(slot < 5 * len);
                        let key = (slot, k + dz[e] as usize);
                        if let Some(g) = seen.insert(key, grid_edge) {
                            assert_eq!(g, grid_edge, "cell ({i}, {j}, {k}) edge {e}");
                        }
                    }
                }
            }
        }
        // Distinct grid edges of the block: x 3*3*3, y 4*2*3, z 4*3*2.
        let edges: std::collections::HashSet<_> = seen.values().collect();
        assert_eq!(edges.len(), 27 + 24 + 24);
        assert_eq!(seen.len(), edges.len());
    }
}
