//! Assembly: the slabs' vertices and triangles welded into one mesh.
//!
//! Each slab numbers its own points; only points on a slab's bottom plane
//! can already exist in the slab before it (its top plane). Every step
//! that touches all points or triangles runs on the executor it is given
//! (the calling thread for small meshes, see `extract`), one slab per
//! task; what stays serial is proportional to the points on the planes
//! between slabs and to the triangles lying in grid planes. Points are
//! numbered slab by slab in order of first use, so the output does not
//! depend on the number of threads.

use std::mem::MaybeUninit;
use std::time::Duration;

use glam::DVec3;

use crate::memory::reserve;
use crate::mesh::{Mesh, Stats};
use crate::par::Exec;
use crate::point_key::{key, KeyMap};
use crate::recycle::{self, Bin};
use crate::refine::Counters;
use crate::slab_pass::SlabOut;
use crate::volume::Volume;
use crate::Error;

/// Welds the slabs' outputs (in slab order) into a mesh and fills the
/// statistics they carry; splits `passes_wall` (seconds) into the Marching
/// Cubes and refinement times. The parallel steps run on `exec`. World
/// coordinates only if `world_points`.
pub(crate) fn assemble(
    mut outs: Vec<SlabOut>,
    volume: &Volume<'_>,
    passes_wall: f64,
    stats: &mut Stats,
    exec: Exec<'_>,
    world_points: bool,
) -> Result<Mesh, Error> {
    sum_counters(&outs, passes_wall, stats);
    let n = outs.len();

    // Points of a slab's bottom plane that the slab before holds on its
    // top plane: (id here, id there), in increasing id here. Only the
    // points made in the slabs' cell layers next to the plane can lie on
    // it (see `SlabOut::first_layer_verts`).
    let links: Vec<Vec<(u32, u32)>> = exec.map((0..n).collect(), |s| {
        if s == 0 || outs[s - 1].z_range.1 != outs[s].z_range.0 {
            return Vec::new();
        }
        let plane = outs[s].z_range.0;
        let below = &outs[s - 1];
        let top = below.before_last_layer_verts.min(below.verts.len());
        let on_top = || {
            below.verts[top..]
                .iter()
                .enumerate()
                .filter(|(_, v)| v.z == plane)
                .map(|(i, v)| (key(*v), (top + i) as u32))
        };
        let here = &outs[s].verts;
        let on_bottom = || {
            here[..outs[s].first_layer_verts.min(here.len())]
                .iter()
                .enumerate()
                .filter(|(_, v)| v.z == plane)
                .map(|(i, v)| (key(*v), i as u32))
        };
        if let Some(links) = link_in_step(on_bottom(), on_top()) {
            return links;
        }
        // Sized up front: growing it rehashed the map several times a
        // plane (a quarter of the linking's time on the EPI scan of the
        // benchmark cut into nine slabs).
        let mut before: KeyMap<u32> =
            KeyMap::with_capacity_and_hasher(on_top().count(), Default::default());
        before.extend(on_top());
        on_bottom()
            .filter_map(|(k, i)| before.get(&k).map(|&j| (i, j)))
            .collect()
    })?;

    // New points: numbered slab after slab, written in parallel. A slab
    // with no point on the plane below keeps its own numbering shifted by
    // its start, and needs no table.
    let fresh: Vec<usize> = (0..n)
        .map(|s| outs[s].verts.len() - links[s].len())
        .collect();
    let starts = offsets(&fresh);
    // The first slab's points are the first of the mesh's, taken over in
    // place (all of them for one slab, below), the others' written after.
    let total_fresh: usize = fresh.iter().sum();
    let mut index_points = if n == 1 {
        Vec::new()
    } else {
        let mut first = recycle::dvec3_as_points(std::mem::take(&mut outs[0].verts));
        let more = total_fresh - first.len();
        reserve(&mut first, more)?;
        first
    };
    // A slab's point ids become the mesh's through its table below the
    // table's length (its first cell layer's points, where those linked to
    // the slab before are), by its shift above (see `global`).
    let mut shifts: Vec<u64> = starts.iter().map(|&s| s as u64).collect();
    let mut remaps: Vec<Vec<u64>> = if n == 1 {
        vec![Vec::new()]
    } else {
        let mut parts = fresh.clone();
        parts[0] = 0;
        let first_len = index_points.len();
        let items = outs
            .iter()
            .zip(&links)
            .zip(split_mut(
                &mut index_points.spare_capacity_mut()[..total_fresh - first_len],
                &parts,
            ))
            .zip(&starts)
            .collect();
        let remaps = exec.map(items, |(((o, link), out), &start)| {
            if link.is_empty() {
                for (w, v) in out.iter_mut().zip(&o.verts) {
                    w.write(v.to_array());
                }
                return Vec::new();
            }
            // Links are made only in the first layer (see `links`).
            let first = o.first_layer_verts.min(o.verts.len());
            let mut table = recycle::REMAPS.take(first);
            table.reserve_exact(first);
            let (mut l, mut w) = (0, 0);
            for (i, v) in o.verts[..first].iter().enumerate() {
                if l < link.len() && link[l].0 as usize == i {
                    // Filled in below, once the slab before is numbered.
                    table.push(u64::MAX);
                    l += 1;
                } else {
                    out[w].write(v.to_array());
                    table.push((start + w) as u64);
                    w += 1;
                }
            }
            assert_eq!(l, link.len(), "a slab's link beyond its first layer");
            // The others in one run, in order.
            for (d, v) in out[w..].iter_mut().zip(&o.verts[first..]) {
                d.write(v.to_array());
            }
            // Every point is either linked or written: the part is full.
            assert_eq!(
                w + (o.verts.len() - first),
                out.len(),
                "a slab's part of the points left unwritten"
            );
            table
        })?;
        // SAFETY: every part of the spare slots up to `total_fresh` points
        // was written in full (`exec.map` returned Ok: every task ran, and
        // each checked its count; the first slab's part is empty, its
        // points already in place).
        unsafe { index_points.set_len(total_fresh) };
        // Above its table, a slab with links has every one of them before
        // each point: point `v` is fresh point `v - links` of the slab.
        for s in 0..n {
            shifts[s] = shifts[s].wrapping_sub(links[s].len() as u64);
        }
        remaps
    };
    for s in 1..n {
        let (done, rest) = remaps.split_at_mut(s);
        for &(i, j) in &links[s] {
            rest[0][i as usize] = global(&done[s - 1], shifts[s - 1], j);
        }
    }

    // Triangles. Welding could give a triangle a repeated point (it does
    // not: points are welded within a slab before their triangles are
    // emitted, and across slabs only onto distinct points; but such a
    // triangle would have no area and its edges would cancel in pairs, so
    // it is dropped below without opening the surface).
    let counts: Vec<usize> = outs.iter().map(|o| o.tris.len()).collect();
    let total_tris = counts.iter().sum();
    // Written in place of the spare capacity, without zeroing it first
    // (a second pass over the largest arrays).
    let mut triangles = room(&recycle::MESH_TRIS, total_tris)?;
    let mut levels = if n == 1 {
        std::mem::take(&mut outs[0].levels)
    } else {
        room(&recycle::LEVELS, total_tris)?
    };
    let tri_starts = offsets(&counts);
    let level_parts = if n == 1 {
        // The slab's levels are the mesh's: nothing to copy.
        vec![Default::default()]
    } else {
        split_mut(&mut levels.spare_capacity_mut()[..total_tris], &counts)
    };
    let items = outs
        .iter()
        .zip(&remaps)
        .zip(&shifts)
        .zip(split_mut(
            &mut triangles.spare_capacity_mut()[..total_tris],
            &counts,
        ))
        .zip(level_parts)
        .zip(&tri_starts)
        .collect();
    let found: Vec<(Vec<Candidate>, Vec<usize>)> =
        exec.map(items, |(((((o, r), &shift), tri_out), level_out), &t0)| {
            let mut degenerate = Vec::new();
            assert_eq!(
                tri_out.len(),
                o.tris.len(),
                "a slab's part of the triangles"
            );
            if r.is_empty() {
                // Numbered by a shift alone (most volumes' slabs, and every
                // single slab): the ids are shifted as flat arrays, which
                // the compiler turns into vector code (not so the triples).
                for (g, &v) in flat_uninit_mut(tri_out).iter_mut().zip(flat(&o.tris)) {
                    g.write(shift + v as u64);
                }
                // A shift keeps distinct ids distinct.
                find_degenerate(&o.tris, t0, &mut degenerate);
            } else {
                let chunks = o.tris.chunks(DEGENERATE_CHUNK);
                for (c, (tris, out)) in chunks.zip(tri_out.chunks_mut(DEGENERATE_CHUNK)).enumerate()
                {
                    let mut any = false;
                    for (w, t) in out.iter_mut().zip(tris) {
                        let g = t.map(|v| global(r, shift, v));
                        any |= is_degenerate(&g);
                        w.write(g);
                    }
                    if any {
                        let g: Vec<_> = tris
                            .iter()
                            .map(|t| t.map(|v| global(r, shift, v)))
                            .collect();
                        note_degenerate(&g, t0 + c * DEGENERATE_CHUNK, &mut degenerate);
                    }
                }
            }
            let cand = o
                .flat_tris
                .iter()
                .map(|&w| {
                    let t = o.tris[w as usize];
                    (t0 + w as usize, t.map(|v| global(r, shift, v)))
                })
                .filter(|&(i, _)| degenerate.binary_search(&i).is_err())
                .map(|(i, g)| Candidate::new(i, g))
                .collect::<Vec<_>>();
            if n > 1 {
                assert_eq!(
                    level_out.len(),
                    o.levels.len(),
                    "a slab's part of the levels"
                );
                for (d, &l) in level_out.iter_mut().zip(&o.levels) {
                    d.write(l);
                }
            }
            (cand, degenerate)
        })?;
    // SAFETY: every slab's part of the first `total_tris` spare slots of
    // `triangles`, and of `levels` for more than one slab, was written in
    // full (`exec.map` returned Ok: every task ran; each checked its
    // part's length against its slab's and wrote every element).
    unsafe {
        triangles.set_len(total_tris);
        if n > 1 {
            levels.set_len(total_tris);
        }
    }
    for r in remaps {
        recycle::REMAPS.give(r);
    }
    if n == 1 {
        // The slab's points become the mesh's, in place.
        index_points = recycle::dvec3_as_points(std::mem::take(&mut outs[0].verts));
    }
    // A large slack (the first slab reserves for a generous guess) is
    // given back.
    if index_points.capacity() > 2 * index_points.len() + (1 << 16) {
        index_points.shrink_to_fit();
    }
    for o in outs {
        recycle::POINTS.give(recycle::dvec3_as_points(o.verts));
        recycle::SLAB_TRIS.give(o.tris);
        recycle::LEVELS.give(o.levels);
    }
    let mut candidates = Vec::new();
    let mut degenerate = Vec::new();
    for (c, d) in found {
        candidates.extend(c);
        degenerate.extend(d);
    }
    remove_duplicate_triangles(candidates, degenerate, &mut triangles, &mut levels);
    if stats.cells_on_subcells > 0 {
        // A cell meshed again on sub-cells drops the Marching Cubes point
        // inside it, made before its refinement.
        drop_unused_points(&mut index_points, &mut triangles, exec)?;
    }

    // World coordinates.
    let mut points = Vec::new();
    if world_points {
        points = recycle::POINTS.take(index_points.len());
        reserve(&mut points, index_points.len())?;
        exec.extend(&mut points, &index_points, |p| volume.world_point(*p))?;
    }
    let (max, sum) = exec
        .map(levels.chunks(1 << 16).collect(), |c| {
            // Two plain reductions, which the compiler turns into vector
            // code (one fold of both ran element by element: 12 us on the
            // 21 000 triangles of Marschner-Lobb 41^3). A chunk's sum fits
            // 32 bits: 2^16 levels of at most 255.
            let max = c.iter().copied().max().unwrap_or(0);
            let sum: u32 = c.iter().map(|&l| u32::from(l)).sum();
            (max, u64::from(sum))
        })?
        .into_iter()
        .fold((0u8, 0u64), |a, b| (a.0.max(b.0), a.1 + b.1));
    stats.max_level = max as u32;
    stats.mean_level = if levels.is_empty() {
        0.0
    } else {
        sum as f64 / levels.len() as f64
    };
    Ok(Mesh {
        points,
        index_points,
        triangles,
        levels,
        ..Mesh::default()
    })
}

/// The links between the points of a plane as two slabs list them
/// (`(key, id)`, each in the order the slab made them), when both lists
/// hold the same keys in the same order: `(id here, id below)` for each.
/// `None` when they differ anywhere (then a map of keys matches them).
/// Without refinement they agree: the cells on either side of the plane
/// make its points in the same order, edge by edge as the layer's cells
/// first touch them; refined points on the plane come in the order of
/// each side's own tree walk. (Keys are unique within a slab, so the pairs
/// are those the map would give.)
fn link_in_step(
    here: impl Iterator<Item = ([u64; 3], u32)>,
    mut below: impl Iterator<Item = ([u64; 3], u32)>,
) -> Option<Vec<(u32, u32)>> {
    let mut links = Vec::with_capacity(here.size_hint().0);
    for (k, i) in here {
        match below.next() {
            Some((kb, j)) if kb == k => links.push((i, j)),
            _ => return None,
        }
    }
    below.next().is_none().then_some(links)
}

/// The ids of `triangles` in one run (`<[T; 3]>::as_flattened`, which is
/// newer than the crate's minimum Rust).
fn flat<T>(triangles: &[[T; 3]]) -> &[T] {
    // SAFETY: an array of arrays is laid out as one array, without padding.
    unsafe { std::slice::from_raw_parts(triangles.as_ptr().cast(), triangles.len() * 3) }
}

/// [`flat`], for triangles not written yet.
fn flat_uninit_mut<T>(triangles: &mut [MaybeUninit<[T; 3]>]) -> &mut [MaybeUninit<T>] {
    // SAFETY: `MaybeUninit<[T; 3]>` is laid out as `[T; 3]`, so as three
    // `MaybeUninit<T>`; the borrow is handed on whole.
    unsafe { std::slice::from_raw_parts_mut(triangles.as_mut_ptr().cast(), triangles.len() * 3) }
}

/// Triangles whose repeated points are looked for together (see
/// [`any_degenerate`]).
const DEGENERATE_CHUNK: usize = 64;

/// Whether triangle `t` repeats a point; without branches.
#[inline(always)]
fn is_degenerate<T: PartialEq>(t: &[T; 3]) -> bool {
    (t[0] == t[1]) | (t[1] == t[2]) | (t[0] == t[2])
}

/// Whether any of `tris` repeats a point: a test without branches (a
/// branch a triangle cost 20 us of a 0.46 ms call on the 21 000 triangles
/// of Marschner-Lobb 41^3, where there is none; this test 10 us).
#[inline]
fn any_degenerate<T: PartialEq>(tris: &[[T; 3]]) -> bool {
    tris.iter().fold(false, |any, t| any | is_degenerate(t))
}

/// Appends to `out`, in increasing order, the indices (from `first`) of
/// the triangles of `tris` that repeat a point: chunk by chunk, looking
/// at each triangle of a chunk only when [`any_degenerate`] finds one.
fn find_degenerate<T: PartialEq>(tris: &[[T; 3]], first: usize, out: &mut Vec<usize>) {
    for (c, chunk) in tris.chunks(DEGENERATE_CHUNK).enumerate() {
        if any_degenerate(chunk) {
            note_degenerate(chunk, first + c * DEGENERATE_CHUNK, out);
        }
    }
}

/// Appends to `out` the indices (from `first`) of the triangles of `tris`
/// that repeat a point.
fn note_degenerate<T: PartialEq>(tris: &[[T; 3]], first: usize, out: &mut Vec<usize>) {
    out.extend(
        tris.iter()
            .enumerate()
            .filter(|(_, t)| is_degenerate(t))
            .map(|(k, _)| first + k),
    );
}

/// Removes the points no triangle uses, keeping the others' order. The
/// passes over the triangles run on `exec`, a chunk a task: one cell meshed
/// again on sub-cells sends a whole mesh through here (on the atoms sample
/// of the throughput table, 750 000 triangles, about 4 % of the call on 2
/// threads when they ran serially).
fn drop_unused_points(
    points: &mut Vec<[f64; 3]>,
    triangles: &mut [[u64; 3]],
    exec: Exec<'_>,
) -> Result<(), Error> {
    use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
    const CHUNK: usize = 1 << 16;
    let used: Vec<AtomicBool> = (0..points.len()).map(|_| AtomicBool::new(false)).collect();
    exec.map(triangles.chunks(CHUNK).collect(), |chunk| {
        for t in chunk {
            for &v in t {
                used[v as usize].store(true, Relaxed);
            }
        }
    })?;
    let mut new_id = Vec::new();
    reserve(&mut new_id, points.len())?;
    let mut next = 0u64;
    for u in &used {
        new_id.push(next);
        next += u64::from(u.load(Relaxed));
    }
    let mut i = 0;
    points.retain(|_| {
        i += 1;
        used[i - 1].load(Relaxed)
    });
    exec.map(triangles.chunks_mut(CHUNK).collect(), |chunk| {
        for t in chunk {
            *t = t.map(|v| new_id[v as usize]);
        }
    })?;
    Ok(())
}

/// Sums the slabs' statistics into `stats`.
fn sum_counters(outs: &[SlabOut], passes_wall: f64, stats: &mut Stats) {
    let mut counters = Counters::default();
    let (mut refine_t, mut total_t) = (Duration::ZERO, Duration::ZERO);
    for o in outs {
        stats.mc_triangles += o.mc_tris;
        stats.ambiguous_cells += o.ambiguous;
        stats.skipped_nonfinite_cells += o.nonfinite;
        counters.samples += o.counters.samples;
        counters.splits += o.counters.splits;
        counters.failures += o.counters.failures;
        counters.above_eps += o.counters.above_eps;
        counters.unsound_cells += o.counters.unsound_cells;
        counters.recut_polygons += o.counters.recut_polygons;
        counters.cells_on_subcells += o.counters.cells_on_subcells;
        refine_t += o.refine_time();
        total_t += o.total_time;
    }
    stats.samples_evaluated = counters.samples;
    stats.split_points = counters.splits;
    stats.projection_failures = counters.failures;
    stats.faces_above_epsilon = counters.above_eps;
    stats.cells_refined_on_faces_only = counters.unsound_cells;
    stats.recut_polygons = counters.recut_polygons;
    stats.cells_on_subcells = counters.cells_on_subcells;
    // The slabs' times are per thread and add up over threads: split the
    // passes' wall time in their proportion.
    let total = total_t.as_secs_f64();
    let share = if total > 0.0 {
        (refine_t.as_secs_f64() / total).min(1.0)
    } else {
        0.0
    };
    stats.time_refine = passes_wall * share;
    stats.time_mc = passes_wall - stats.time_refine;
}

/// Whether a triangle (index coordinates) lies in a grid plane.
#[inline(always)]
pub(crate) fn in_grid_plane(p: [DVec3; 3]) -> bool {
    // The cheap comparisons first: few triangles lie in any axis plane.
    let flat = |a: f64, b: f64, c: f64| b == a && c == a && a.fract() == 0.0;
    flat(p[0].x, p[1].x, p[2].x) || flat(p[0].y, p[1].y, p[2].y) || flat(p[0].z, p[1].z, p[2].z)
}

/// A triangle lying in a grid plane: its index in the output, its points
/// rotated so the smallest id is first and the other two ascending, and
/// whether that reversed its orientation.
struct Candidate {
    index: usize,
    sorted: [u64; 3],
    flipped: bool,
}

impl Candidate {
    fn new(index: usize, t: [u64; 3]) -> Self {
        let mut s = t;
        let r = (0..3).min_by_key(|&k| s[k]).unwrap();
        s.rotate_left(r);
        let flipped = s[1] > s[2];
        if flipped {
            s.swap(1, 2);
        }
        Candidate {
            index,
            sorted: s,
            flipped,
        }
    }
}

/// Samples equal to the isovalue can make two cells emit the same
/// triangle, flat in a shared face: a pair of opposite orientation bounds
/// nothing and is removed (copies of one orientation left over are all
/// kept: removing one would open the surface). Triangles of two
/// cells can coincide only in the grid plane between them, so only the
/// `cand`idates lying in a grid plane are compared. The triangles at the
/// indices in `drop` go too.
fn remove_duplicate_triangles(
    mut cand: Vec<Candidate>,
    mut drop: Vec<usize>,
    triangles: &mut Vec<[u64; 3]>,
    levels: &mut Vec<u8>,
) {
    cand.sort_by(|a, b| a.sorted.cmp(&b.sorted).then(a.index.cmp(&b.index)));
    let mut i = 0;
    while i < cand.len() {
        let mut j = i + 1;
        while j < cand.len() && cand[j].sorted == cand[i].sorted {
            j += 1;
        }
        let group = &cand[i..j];
        i = j;
        if group.len() < 2 {
            continue;
        }
        // Opposite copies cancel in pairs; the surplus stays, every copy
        // of it: each cell's patch needs its own to close (two cells can
        // emit one triangle with the same orientation when it is
        // degenerate, e.g. three points on one grid edge).
        let ups = group.iter().filter(|g| !g.flipped).count();
        let downs = group.len() - ups;
        let (mut drop_up, mut drop_down) = (ups.min(downs), ups.min(downs));
        for g in group {
            let left = if g.flipped {
                &mut drop_down
            } else {
                &mut drop_up
            };
            if *left > 0 {
                *left -= 1;
                drop.push(g.index);
            }
        }
    }
    if drop.is_empty() {
        return;
    }
    drop.sort_unstable();
    let mut d = 0;
    let mut w = 0;
    for r in 0..triangles.len() {
        if d < drop.len() && drop[d] == r {
            d += 1;
            continue;
        }
        triangles[w] = triangles[r];
        levels[w] = levels[r];
        w += 1;
    }
    triangles.truncate(w);
    levels.truncate(w);
}

/// The output id of a slab's point `v`: from the slab's `table` below its
/// length (its first layer's points, when some are linked to the slab
/// before), else `shift + v` (wrapping: a shift less the links can be
/// negative, never the id). The table entry is read whether used or not,
/// so the choice is a select, not a branch: the triangles of the second
/// layer mix points on either side of the table's end, and a branch per
/// corner mispredicted there (26 us on Marschner-Lobb's two slabs).
#[inline(always)]
fn global(table: &[u64], shift: u64, v: u32) -> u64 {
    let shifted = shift.wrapping_add(v as u64);
    let Some(last) = table.len().checked_sub(1) else {
        return shifted;
    };
    let i = v as usize;
    let listed = table[i.min(last)];
    if i <= last {
        listed
    } else {
        shifted
    }
}

/// Start of each part when parts of the given lengths are laid end to end.
fn offsets(lengths: &[usize]) -> Vec<usize> {
    lengths
        .iter()
        .scan(0, |acc, &l| {
            let start = *acc;
            *acc += l;
            Some(start)
        })
        .collect()
}

/// `v` cut into consecutive parts of the given lengths.
fn split_mut<'a, T>(mut v: &'a mut [T], lengths: &[usize]) -> Vec<&'a mut [T]> {
    lengths
        .iter()
        .map(|&l| {
            let (part, rest) = std::mem::take(&mut v).split_at_mut(l);
            v = rest;
            part
        })
        .collect()
}

/// An empty buffer with room for `n` values, from `bin` when it keeps
/// one; an error when the memory is not available. The caller writes the
/// values into its spare capacity (no zeroing first: the assembly writes
/// every value once).
fn room<T: Send + 'static>(bin: &Bin<Vec<T>>, n: usize) -> Result<Vec<T>, Error> {
    let mut v = bin.take(n);
    reserve(&mut v, n)?;
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Signed uses of each undirected edge (0 everywhere: closed).
    fn balance(tris: &[[u64; 3]]) -> HashMap<(u64, u64), i64> {
        let mut uses = HashMap::new();
        for t in tris {
            for c in 0..3 {
                let (a, b) = (t[c], t[(c + 1) % 3]);
                *uses.entry((a.min(b), a.max(b))).or_insert(0) += if a < b { 1 } else { -1 };
            }
        }
        uses.retain(|_, u| *u != 0);
        uses
    }

    /// Two lists of a plane's points link in step only when they hold the
    /// same keys in the same order: then each pair is what a map of keys
    /// gives; any missing, extra or reordered point defers to the map.
    #[test]
    fn plane_points_link_in_step_only_when_the_lists_agree() {
        let mut rng = crate::test_rng::XorShift(0x51_7cc1_b727_220a);
        let mut next = |n: u64| rng.below(n);
        for _ in 0..300 {
            let n = next(12) as usize;
            let keys: Vec<[u64; 3]> = (0..n as u64).map(|k| [k * 7 + 1, k, 3]).collect();
            let below: Vec<([u64; 3], u32)> = keys
                .iter()
                .enumerate()
                .map(|(j, &k)| (k, 100 + 2 * j as u32))
                .collect();
            let mut here: Vec<([u64; 3], u32)> = keys
                .iter()
                .enumerate()
                .map(|(i, &k)| (k, 5 + 3 * i as u32))
                .collect();
            let by_map: Vec<(u32, u32)> = here
                .iter()
                .map(|&(k, i)| (i, below.iter().find(|b| b.0 == k).unwrap().1))
                .collect();
            let linked = link_in_step(here.iter().copied(), below.iter().copied());
            assert_eq!(linked.as_deref(), Some(&by_map[..]));
            match next(3) {
                0 if n > 0 => {
                    here.remove(next(n as u64) as usize);
                }
                1 => here.insert(next(n as u64 + 1) as usize, ([9, 9, 9], 1)),
                _ if n > 1 => {
                    let a = next(n as u64 - 1) as usize;
                    here.swap(a, a + 1);
                }
                _ => continue,
            }
            assert_eq!(
                link_in_step(here.iter().copied(), below.iter().copied()),
                None
            );
        }
    }

    /// The chunked search for triangles with a repeated point finds what a
    /// plain scan finds, wherever they lie (chunk edges, a short last
    /// chunk) and whichever two corners repeat.
    #[test]
    fn degenerate_triangles_are_all_found_in_order() {
        let mut rng = crate::test_rng::XorShift(0x9e37_79b9_7f4a_7c15);
        let mut next = |n: u64| rng.below(n);
        for _ in 0..300 {
            let len = next(4 * DEGENERATE_CHUNK as u64 + 3) as usize;
            let mut tris: Vec<[u32; 3]> = (0..len as u32)
                .map(|i| [3 * i, 3 * i + 1, 3 * i + 2])
                .collect();
            for _ in 0..next(5) {
                if len == 0 {
                    break;
                }
                let t = &mut tris[next(len as u64) as usize];
                let (a, b) = [(0, 1), (1, 2), (0, 2)][next(3) as usize];
                t[b] = t[a];
            }
            let first = next(1000) as usize;
            let mut found = vec![7];
            find_degenerate(&tris, first, &mut found);
            let want: Vec<usize> = std::iter::once(7)
                .chain(
                    (0..len)
                        .filter(|&k| {
                            let t = tris[k];
                            t[0] == t[1] || t[1] == t[2] || t[0] == t[2]
                        })
                        .map(|k| first + k),
                )
                .collect();
            assert_eq!(found, want);
        }
    }

    /// Copies of one triangle in both orientations, spread over a mesh of
    /// other triangles: opposite copies go in pairs, the surplus stays in
    /// full, the edge balance is unchanged and so is everything else.
    #[test]
    fn duplicates_cancel_in_pairs_and_keep_the_balance() {
        let mut rng = crate::test_rng::XorShift(0x2545_f491_4f6c_dd1d);
        let mut next = |n: u64| rng.below(n);
        for _ in 0..500 {
            let (ups, downs) = (next(4) as usize, next(4) as usize);
            let mut tris: Vec<[u64; 3]> = (0..next(6)).map(|i| [10 + i, 20 + i, 30 + i]).collect();
            for k in 0..ups + downs {
                // Rotations of (1, 2, 3) or of its reverse (1, 3, 2).
                let mut t = if k < ups { [1, 2, 3] } else { [1, 3, 2] };
                t.rotate_left(next(3) as usize);
                let at = next(tris.len() as u64 + 1) as usize;
                tris.insert(at, t);
            }
            let before = balance(&tris);
            let others: Vec<_> = tris.iter().copied().filter(|t| t[0] >= 10).collect();
            let cand: Vec<Candidate> = tris
                .iter()
                .enumerate()
                .filter(|(_, t)| t[0] < 10)
                .map(|(i, &t)| Candidate::new(i, t))
                .collect();
            let mut levels = vec![0u8; tris.len()];
            let mut out = tris.clone();
            remove_duplicate_triangles(cand, Vec::new(), &mut out, &mut levels);
            assert_eq!(balance(&out), before, "{tris:?} -> {out:?}");
            let left = out.iter().filter(|t| t[0] < 10 || t[1] < 10).count();
            assert_eq!(left, ups.abs_diff(downs), "{tris:?} -> {out:?}");
            let kept: Vec<_> = out.iter().copied().filter(|t| t[0] >= 10).collect();
            assert_eq!(kept, others);
            assert_eq!(levels.len(), out.len());
        }
    }
}
