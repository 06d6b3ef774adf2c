//! One pass over a slab of cell layers: the cells' Marching Cubes
//! patches (the trilinear topology or the classic table), each refined
//! onto `S_K` when refinement is on, their points welded within the
//! slab; the extraction (`extract`) runs one a slab and welds the slabs.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use glam::DVec3;

use crate::assemble::in_grid_plane;
use crate::cell_refine::{refine_cell, CellInput, CellScratch};
use crate::filter::ReconstructionFilter;
use crate::layers::{self, LayerScratch, ScratchPool};
use crate::mc::{cell_triangles_borrowed, classic, Patch};
use crate::memory::advise_huge_pages;
use crate::options::Options;
use crate::par::OnCaller;
use crate::point_key::{key, next_float, KeyMap};
use crate::project::edge_crossing;
use crate::recycle;
use crate::refine::Counters;
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

impl<T: Scalar, F: ReconstructionFilter> Shared<'_, T, F> {
    /// Reports progress through [`Shared::poll`] unless it was reported
    /// lately ([`OnCaller::poll_timed`]): between refined cells and within
    /// their refinement.
    pub(crate) fn poll_timed(&self) {
        if let Some(p) = self.poll {
            p.poll_timed();
        }
    }
}

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
    let mut patch = Patch {
        pinch_fans: REFINE,
        ..Patch::default()
    };
    // The cell's Marching Cubes triangles and their corners' positions
    // (in `rs.kept` and `rs.pos_of`), and what refining it needs.
    let mut rs = CellScratch::new();
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
                rs.kept.clear();
                rs.pos_of.clear();
                let mc_start = out.tris.len();
                // The point on each grid edge the surface crosses, each edge
                // once (every topology puts one point on each), then the
                // interior points of an ambiguous cell: every id a triangle
                // names is then set, without a test per triangle corner.
                let (crossed, n_crossed) = &CROSSED_EDGES[case as usize];
                let cell_slot = j * nxs + i;
                for &e in &crossed[..*n_crossed as usize] {
                    let e = e as usize;
                    // The grid edge's slot in the per-layer id cache and
                    // the stamp of its layer (not used when only counting).
                    let at = cell_slot + edge_slots[k & 1][e];
                    let edge_stamp = stamp(k) + edge_dz[e];
                    let cached = layers::lookup(edge_ids[at], edge_stamp);
                    if let (Some(id), false) = (cached, count_only) {
                        // A cell before this one placed the point, with the
                        // coordinates `edge_point` gives.
                        ids[e] = id;
                        if REFINE {
                            loc[e] = out.verts[id as usize] - cell_f;
                        }
                        continue;
                    }
                    let (gp, inside_edge) =
                        edge_point::<F>(&c, e, sh.iso, edge_filter.as_ref(), cell_g);
                    if REFINE || count_only {
                        loc[e] = gp - cell_f;
                    }
                    if count_only {
                        ids[e] = e as u32;
                    } else {
                        let next = out.verts.len() as u32;
                        let id = if !weld_all && inside_edge {
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
                    rs.kept.push(tid);
                    rs.pos_of.push(loc[tri[0] as usize]);
                    rs.pos_of.push(loc[tri[1] as usize]);
                    rs.pos_of.push(loc[tri[2] as usize]);
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
                let cell = CellInput {
                    corners: &c,
                    f: &f,
                    case,
                    interior_points: !extra.is_empty(),
                    ijk: [i, j, k],
                    cell_f,
                    filter: edge_filter,
                };
                let flow = refine_cell(sh, &mut out, &mut map, &mut reported, mode, cell, &mut rs);
                if flow.is_break() {
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

/// The point (global index coordinates) where the surface crosses grid
/// edge `e` of the cell whose lowest corner is `cell_g`, from the cell's
/// corner samples `c`: where the samples' linear interpolation meets
/// `iso`, as vtkMarchingCubes places it, or, given the filter's cell
/// (`filter`: a filter not linear on grid edges), where the filter's own
/// isosurface crosses the edge. With it, whether the point lies strictly
/// inside the edge (it can round onto a sample).
#[inline(always)]
fn edge_point<F: ReconstructionFilter>(
    c: &[f64; 8],
    e: usize,
    iso: f64,
    filter: Option<&F::Cell>,
    cell_g: [i64; 3],
) -> (DVec3, bool) {
    let [a, b] = EDGES[e];
    let ca = CORNERS[a as usize];
    let ax = EDGE_AXIS[e] as usize;
    let (sa, sb) = (c[a as usize], c[b as usize]);
    // vtkMarchingCubes: t from the lower corner.
    let mut t = (iso - sa) / (sb - sa);
    if !t.is_finite() || !(sb - sa).is_finite() {
        // A difference overflowed (samples beyond half of f64::MAX with
        // opposite signs; with only the denominator infinite, t came out
        // 0, a point on the corner): the same ratio of halves.
        t = ((0.5 * iso - 0.5 * sa) / (0.5 * sb - 0.5 * sa)).clamp(0.0, 1.0);
    }
    if let Some(fc) = filter {
        let corner = DVec3::new(ca[0] as f64, ca[1] as f64, ca[2] as f64);
        if let Some(s) = edge_crossing::<F>(fc, iso, corner, ax) {
            t = s;
        }
    }
    let (x, y, z) = (
        (cell_g[0] + ca[0] as i64) as f64,
        (cell_g[1] + ca[1] as i64) as f64,
        (cell_g[2] + ca[2] as i64) as f64,
    );
    // Built in registers: a store of one lane then a load of the vector
    // stalls store forwarding.
    let (base, gp) = match ax {
        0 => (x, DVec3::new(x + t, y, z)),
        1 => (y, DVec3::new(x, y + t, z)),
        _ => (z, DVec3::new(x, y, z + t)),
    };
    let mut moved = base + t;
    let mut gp = gp;
    if filter.is_some() && (moved == base || moved == base + 1.0) {
        // A cubic's crossing within rounding of a corner (samples a
        // rounding away from the isovalue) would weld with the crossings
        // of the corner's other edges: a polygon visiting two of them
        // apart then touches itself there, and the patch refined from it
        // is not a manifold (a crack; a debug assertion). The point stays
        // on its own edge, one float off the corner (the offset is
        // exact).
        moved = next_float(if moved == base { base } else { base + 1.0 }, moved == base);
        let t = moved - base;
        gp = match ax {
            0 => DVec3::new(x + t, y, z),
            1 => DVec3::new(x, y + t, z),
            _ => DVec3::new(x, y, z + t),
        };
    }
    (gp, moved != base && moved != base + 1.0)
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

/// Notes which of the slab's triangles from index `from` on lie in a grid
/// plane (checked while their points are in cache).
pub(crate) fn note_flat(out: &mut SlabOut, from: usize) {
    for n in from..out.tris.len() {
        if in_grid_plane(out.tris[n].map(|v| out.verts[v as usize])) {
            out.flat_tris.push(n as u32);
        }
    }
}

/// Whether the point `gp` (global index coordinates) lies in the open cell
/// whose lowest corner is `cell_f`. Decided on the global coordinates: far
/// from the origin a point just inside can round onto the cell's boundary.
#[inline(always)]
pub(crate) fn strictly_inside(gp: DVec3, cell_f: DVec3) -> bool {
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
pub(crate) fn produced(out: &SlabOut, count_only: bool) -> u64 {
    if count_only {
        out.counters.per_level.iter().sum()
    } else {
        out.tris.len() as u64
    }
}

/// Adds the slab's `n` triangles produced so far (see [`produced`]) to the
/// shared count, less those reported before; returns true (and raises
/// `over_cap`) when the total exceeds `cap`.
pub(crate) fn report_emitted<T: Scalar, F: ReconstructionFilter>(
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
