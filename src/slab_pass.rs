//! One pass over a slab of cell layers: the cells' Marching Cubes
//! patches (the trilinear topology or the classic table), each refined
//! onto `S_K` when refinement is on, their points welded within the
//! slab; the extraction (`extract`) runs one a slab and welds the slabs.

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;

use crate::assemble::in_grid_plane;
use crate::diagonals::choose_diagonals;
use crate::filter::ReconstructionFilter;
use crate::flat_map::FlatMap;
use crate::layers::{self, LayerScratch, ScratchPool};
use crate::mc::topology_check::classic_is_trilinear;
use crate::mc::{cell_triangles_borrowed, classic, Patch};
use crate::memory::advise_huge_pages;
use crate::near_bound;
use crate::options::{Options, Topology};
use crate::par::OnCaller;
use crate::point_key::{key, next_float, KeyMap};
use crate::project::edge_crossing;
use crate::recycle;
use crate::refine::{
    edge_key, faces_like_marching_cubes, shared_fixed_axes, sound_patch, soundly_connected,
    vector_area, Counters, EdgeCache, Refinable, Refiner, Tri,
};
use crate::subcells;
use crate::tables::cube::{on_one_face, CORNERS, CROSSED_EDGES, EDGES, EDGE_AXIS};
use crate::volume::{Grid, Scalar};

#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Mode {
    /// Produce the mesh; stop when the cap is exceeded.
    Output { cap: u64 },
    /// Only count refinement-tree nodes per level; stop when the leaves
    /// exceed the cap (the level does not fit).
    Count { cap: u64 },
}

pub(crate) struct Shared<'a, T: Scalar, F: ReconstructionFilter> {
    pub(crate) grid: Grid<'a, T>,
    pub(crate) filter: &'a F,
    pub(crate) cell_dims: [usize; 3],
    pub(crate) index_offset: [i64; 3],
    pub(crate) iso: f64,
    pub(crate) options: &'a Options,
    pub(crate) max_level: u32,
    pub(crate) refine: bool,
    pub(crate) cancel: &'a AtomicBool,
    pub(crate) over_cap: &'a AtomicBool,
    pub(crate) emitted: &'a AtomicU64,
    pub(crate) layers_done: &'a AtomicU64,
    pub(crate) scratch: &'a ScratchPool,
    /// See `How::extreme` in `extract`.
    pub(crate) extreme: Option<&'a AtomicBool>,
    /// Whether a cell whose refinement stalls is meshed again on sub-cells
    /// (see [`crate::subcells`]).
    pub(crate) subcells: bool,
    /// Reports progress when called on the calling thread (after each
    /// layer; within one, at most every `PROGRESS_EVERY` of `extract`);
    /// `None` where
    /// nothing is reported until the end.
    pub(crate) poll: Option<&'a OnCaller<'a>>,
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

/// The most leaves a refined cell's patch can have (its Marching Cubes
/// triangles times [`crate::options::Rule::most_children`] to the power
/// max_level) for which the slab's buffers are reserved for the whole
/// patch before refining it (fallibly; see `slab_pass`).
const CELL_RESERVE_LIMIT: u64 = 1 << 16;

/// Marching Cubes (and refinement) on cell layers `k0..k1`.
///
/// With refinement off, a point strictly inside its grid edge belongs to
/// that edge alone, so the per-layer edge cache welds it and the slab's map
/// only sees points on samples and the interior points of ambiguous cells.
/// That holds while those interior points lie strictly inside their cells;
/// when one does not (a value rounding onto the boundary far from the
/// origin, or degenerate samples), it could coincide with an edge's point,
/// and the slab is redone with every point in the map.
pub(crate) fn process_slab<T: Scalar, F: ReconstructionFilter>(
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
    use crate::{extract, Options, Topology};

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
}
