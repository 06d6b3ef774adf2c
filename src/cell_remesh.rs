//! Re-meshing a refined cell whose refinement stalled: its patch in the
//! slab's output replaced by the one [`subcells::remesh`] makes on
//! sub-cells (or, in a pass that only counts, counted in its place), and
//! the removal of a cell's patch that an attempt of
//! [`crate::cell_refine`] gives up.

use std::collections::HashMap;

use glam::DVec3;

use crate::options::Options;
use crate::point_key::{key, KeyMap};
use crate::slab_pass::SlabOut;
use crate::subcells;

/// A cell being refined in a slab: corner values less the isovalue, lowest
/// corner (global index coordinates), where its patch starts in the
/// slab's triangles and points, and the slab's count of leaves above
/// epsilon before it.
pub(crate) struct CellAt<'a> {
    pub f: &'a [f64; 8],
    pub cell_f: DVec3,
    pub t_start: usize,
    pub v_start: usize,
    pub above_before: u64,
}

/// Removes a cell's patch from the slab: its triangles (and their levels)
/// from `t_start` on and the points it made, from `v_start` on, with their
/// entries in the welding maps. With `poll`, stops removing map entries
/// once it finds the extraction stopped (the slab's output and its map are
/// then not used again).
pub(crate) fn drop_patch(
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
pub(crate) fn count_remeshed(
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
pub(crate) fn remesh_cell(
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
