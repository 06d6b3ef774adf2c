//! Buffers kept between extractions, so that repeated calls reuse memory
//! that is already mapped instead of faulting fresh pages in.
//!
//! Why: glibc returns a large freed block at the top of its heap to the
//! kernel (and unmaps very large ones), so each call of a small or medium
//! extraction used to write most of its buffers into fresh pages: through
//! the VTK filter, 300 page faults a call on the 128 x 96 x 24 EPI scan of
//! the benchmark, about a third of the call's time. The buffers that take
//! part (slab points, triangles and levels, the edge caches, the mesh's
//! arrays, normals and gradients included, once the caller releases them) go back to process-wide bins
//! here instead, up to [`RETAIN_LIMIT`] bytes in all, and the next call
//! takes them. Contents are never read before being written, so the
//! output does not depend on what a bin hands out.
//! [`release_retained_memory`] (C: `pmc_release_memory`) empties the bins.

use std::any::Any;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

use glam::DVec3;

use crate::layers::LayerScratch;

/// Most bytes the bins keep together: 64 MiB. A buffer that would take the
/// total beyond it is freed as usual.
pub const RETAIN_LIMIT: usize = 64 << 20;

/// Most buffers one bin keeps (a call uses one per slab, slabs at most a
/// few per thread on small volumes).
const PER_BIN: usize = 16;

/// Bytes held by all bins.
static RETAINED: AtomicUsize = AtomicUsize::new(0);

/// Frees every buffer kept for reuse between extractions (see the module
/// documentation), and stops the helper threads kept between extractions
/// while no extraction uses them; returns the bytes of buffers released.
/// Thread-safe; extractions running meanwhile are not affected. Useful
/// after a burst of extractions, before a long phase that needs the
/// memory elsewhere.
pub fn release_retained_memory() -> usize {
    crate::helpers::stop_crew();
    POINTS.release()
        + SLAB_TRIS.release()
        + LEVELS.release()
        + MESH_TRIS.release()
        + REMAPS.release()
        + VECTORS.release()
        + SCRATCH.release()
}

/// Takes every bin's lock until `held` is cleared (see [`crate::fork`]).
pub(crate) fn hold_all(held: &mut Vec<Box<dyn Any>>) {
    POINTS.hold(held);
    SLAB_TRIS.hold(held);
    LEVELS.hold(held);
    MESH_TRIS.hold(held);
    REMAPS.hold(held);
    VECTORS.hold(held);
    SCRATCH.hold(held);
}

/// Bytes currently kept for reuse by all bins.
pub fn retained_bytes() -> usize {
    RETAINED.load(Ordering::Relaxed)
}

/// Something a bin can hold: its size in bytes, and how to clear it.
pub(crate) trait Held: Send + 'static {
    fn bytes(&self) -> usize;
    /// Drops the contents that must not outlive a call (none are read).
    fn reset(&mut self) {}
}

impl<T: Send + 'static> Held for Vec<T> {
    fn bytes(&self) -> usize {
        self.capacity() * std::mem::size_of::<T>()
    }
    fn reset(&mut self) {
        self.clear();
    }
}

/// A bin of retained buffers of one kind.
pub(crate) struct Bin<H> {
    free: Mutex<Vec<H>>,
}

impl<H: Held> Bin<H> {
    pub(crate) const fn new() -> Self {
        Bin {
            free: Mutex::new(Vec::new()),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<H>> {
        crate::fork::ensure_handlers();
        self.free.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Takes the bin's lock until `held` is cleared (around `fork`, see
    /// [`crate::fork`]).
    fn hold(&'static self, held: &mut Vec<Box<dyn Any>>) {
        held.push(Box::new(
            self.free.lock().unwrap_or_else(|e| e.into_inner()),
        ));
    }

    /// The first kept buffer that `fits`, taken out of the bin.
    pub(crate) fn take_where(&self, fits: impl Fn(&H) -> bool) -> Option<H> {
        let mut free = self.lock();
        let i = free.iter().position(fits)?;
        Some(Self::remove(&mut free, i))
    }

    /// Takes the `i`th kept buffer out of `free`, the bin's locked list,
    /// and out of the retained count.
    fn remove(free: &mut Vec<H>, i: usize) -> H {
        let h = free.swap_remove(i);
        RETAINED.fetch_sub(h.bytes(), Ordering::Relaxed);
        h
    }

    /// Keeps `h` for a later call if the bin and the budget have room;
    /// frees it otherwise.
    pub(crate) fn give(&self, mut h: H) {
        let b = h.bytes();
        if b == 0 {
            return;
        }
        h.reset();
        let mut free = self.lock();
        if free.len() >= PER_BIN {
            return;
        }
        if RETAINED.fetch_add(b, Ordering::Relaxed) + b > RETAIN_LIMIT {
            RETAINED.fetch_sub(b, Ordering::Relaxed);
            return;
        }
        free.push(h);
    }

    /// Frees everything kept; returns the bytes.
    fn release(&self) -> usize {
        let taken = std::mem::take(&mut *self.lock());
        let b = taken.iter().map(Held::bytes).sum();
        RETAINED.fetch_sub(b, Ordering::Relaxed);
        b
    }
}

impl<T: Send + 'static> Bin<Vec<T>> {
    /// An empty vector, with the capacity of a kept one: the smallest
    /// holding `n` elements, else the largest (the caller reserves the
    /// rest); a new one when the bin is empty.
    pub(crate) fn take(&self, n: usize) -> Vec<T> {
        let mut free = self.lock();
        let best = (0..free.len())
            .filter(|&i| free[i].capacity() >= n)
            .min_by_key(|&i| free[i].capacity())
            .or_else(|| (0..free.len()).max_by_key(|&i| free[i].capacity()));
        best.map_or_else(Vec::new, |i| Self::remove(&mut free, i))
    }
}

/// Points: the slabs' (as [`DVec3`], see [`points_as_dvec3`]) and the
/// mesh's index and world points.
pub(crate) static POINTS: Bin<Vec<[f64; 3]>> = Bin::new();
/// The slabs' triangles (slab-local ids).
pub(crate) static SLAB_TRIS: Bin<Vec<[u32; 3]>> = Bin::new();
/// Refinement levels per triangle, of slabs and meshes.
pub(crate) static LEVELS: Bin<Vec<u8>> = Bin::new();
/// The mesh's triangles (global ids).
pub(crate) static MESH_TRIS: Bin<Vec<[u64; 3]>> = Bin::new();
/// Slab-to-mesh point numbering while assembling.
pub(crate) static REMAPS: Bin<Vec<u64>> = Bin::new();
/// The mesh's normals and gradients.
pub(crate) static VECTORS: Bin<Vec<[f32; 3]>> = Bin::new();
/// Edge caches and inside bits of the slab workers.
pub(crate) static SCRATCH: Bin<LayerScratch> = Bin::new();

/// Keeps a mesh's arrays for later extractions (the C API's
/// `pmc_mesh_free`).
pub(crate) fn give_mesh(m: crate::Mesh) {
    POINTS.give(m.points);
    POINTS.give(m.index_points);
    MESH_TRIS.give(m.triangles);
    LEVELS.give(m.levels);
    VECTORS.give(m.normals);
    VECTORS.give(m.gradients);
}

/// The same allocation as `DVec3`s (same size and alignment: the in-place
/// collection keeps it).
pub(crate) fn points_as_dvec3(v: Vec<[f64; 3]>) -> Vec<DVec3> {
    v.into_iter().map(DVec3::from_array).collect()
}

/// The same allocation as `[f64; 3]`s.
pub(crate) fn dvec3_as_points(v: Vec<DVec3>) -> Vec<[f64; 3]> {
    v.into_iter().map(|p| p.to_array()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_change_type_in_place() {
        let mut v: Vec<[f64; 3]> = Vec::with_capacity(1000);
        v.push([1.0, 2.0, 3.0]);
        let (ptr, cap) = (v.as_ptr() as usize, v.capacity());
        let d = points_as_dvec3(v);
        assert_eq!((d.as_ptr() as usize, d.capacity()), (ptr, cap));
        assert_eq!(d[0], DVec3::new(1.0, 2.0, 3.0));
        let back = dvec3_as_points(d);
        assert_eq!((back.as_ptr() as usize, back.capacity()), (ptr, cap));
    }

    #[test]
    fn kept_buffers_do_not_change_the_output() {
        // Buffers dirtied by other extractions (other values, isovalues,
        // sizes, thread counts; refined or not) give the same mesh, bit
        // for bit, as an extraction after the bins were emptied.
        use crate::{extract, Options, Volume};
        let dims = [23u64, 19, 17];
        let field = |a: f64, b: f64| -> Vec<f32> {
            let mut v = Vec::new();
            for k in 0..dims[2] {
                for j in 0..dims[1] {
                    for i in 0..dims[0] {
                        let (x, y, z) = (i as f64, j as f64, k as f64);
                        v.push(((a * x).sin() + (b * y).cos() * (0.3 * z).sin()) as f32);
                    }
                }
            }
            v
        };
        let (mine, other) = (field(0.41, 0.37), field(0.23, 0.61));
        // Normals and gradients too: they fill vectors kept from
        // earlier meshes.
        let options = |eps: f64, threads: usize| Options {
            epsilon: eps,
            threads,
            normals: crate::NormalMode::Gradient,
            gradients: true,
            ..Options::default()
        };
        for (eps, threads) in [(0.0, 1), (0.0, 2), (0.01, 2)] {
            let run = || extract(&Volume::new(&mine[..], dims), 0.2, &options(eps, threads));
            release_retained_memory();
            let fresh = run().unwrap();
            for (odims, iso, oeps, othreads) in [
                (dims, -0.3, 0.0, 2),
                (dims, 0.5, 0.005, 1),
                ([19, 23, 17], 0.1, 0.0, 1),
            ] {
                let m = extract(
                    &Volume::new(&other[..], odims),
                    iso,
                    &options(oeps, othreads),
                );
                give_mesh(m.unwrap());
                assert!(retained_bytes() > 0);
                let again = run().unwrap();
                assert_eq!(again.index_points, fresh.index_points);
                assert_eq!(again.triangles, fresh.triangles);
                assert_eq!(again.levels, fresh.levels);
                assert_eq!(again.normals, fresh.normals);
                assert_eq!(again.gradients, fresh.gradients);
                assert!(!again.normals.is_empty() && !again.gradients.is_empty());
                give_mesh(again);
            }
        }
    }

    #[test]
    fn bins_hand_back_kept_buffers_within_the_budget() {
        // A private bin: the statics are shared with other tests.
        static BIN: Bin<Vec<u16>> = Bin::new();
        let mut v = Vec::with_capacity(4096);
        v.extend(0..100u16);
        let ptr = v.as_ptr() as usize;
        BIN.give(v);
        let w = BIN.take(10);
        assert_eq!(w.as_ptr() as usize, ptr, "the kept buffer is reused");
        assert!(w.is_empty() && w.capacity() >= 4096);
        assert!(BIN.take(10).capacity() == 0, "taken once");
        // The smallest that fits is preferred, else the largest.
        BIN.give(Vec::with_capacity(100));
        BIN.give(Vec::with_capacity(5000));
        BIN.give(Vec::with_capacity(1000));
        assert_eq!(BIN.take(900).capacity(), 1000);
        assert_eq!(BIN.take(9000).capacity(), 5000);
        // Beyond the budget a buffer is freed, not kept.
        BIN.give(Vec::with_capacity(RETAIN_LIMIT));
        assert!(BIN.take(RETAIN_LIMIT).capacity() < RETAIN_LIMIT);
        // At most PER_BIN buffers.
        for _ in 0..PER_BIN + 5 {
            BIN.give(Vec::with_capacity(10));
        }
        assert!(BIN.lock().len() <= PER_BIN);
        BIN.release();
        assert!(BIN.lock().is_empty());
    }
}
