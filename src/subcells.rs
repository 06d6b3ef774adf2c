//! Cells whose refinement stalls, meshed again on sub-cells.
//!
//! Where `S_K` folds or pinches inside a cell (a neck near an ambiguous
//! face's saddle, a thin part of the inside hugging a face), the split
//! point of an edge across the fold lands on the far wall, about as far
//! from the midpoint as the edge is long, and the children are no shorter
//! than their parent: at every level the patch keeps triangles that span
//! the fold (on the benchmark's EPI scan, 0.3 cells from `S_K` at every
//! epsilon and level). The trilinear interpolant restricted to a box inside
//! the cell is again trilinear, so such a cell is meshed again as a small
//! volume of [`SUB`]^3 sub-cells sampled from it, by the same pipeline
//! (Marching Cubes with the trilinear topology, then refinement with
//! epsilon in sub-cell units): each sub-cell holds a simpler piece of
//! `S_K`, and refinement converges there.
//!
//! The neighbours are not touched: their patches end on the outline that
//! the cell's own refinement drew on each face (face edges decide alike on
//! both sides). The sub-cell patch ends on its own, finer, outline of the
//! same curves, so each arc of the two outlines between the same two grid
//! edges is joined by a strip of triangles lying in the face, between two
//! polylines inscribed in the same curve. The surface stays closed and
//! consistently oriented; the strip is within the outlines' own distance
//! to `S_K`. Where the neighbour is meshed again too, both make the same
//! fine outline in the face and the same strips, oppositely oriented
//! (see [`zip`]): the strips cancel at assembly and the fine patches meet.

use std::cell::Cell;
use std::collections::HashMap;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};

use glam::DVec3;

use crate::executor::SerialExecutor;
use crate::extract::extract_index_points;
use crate::filter::trilinear_value;
use crate::options::{NormalMode, Options, Reconstruction, Topology};
use crate::volume::Volume;

/// Sub-cells along each axis of a cell meshed again (a power of two, so
/// that sub-cell coordinates divide exactly into the cell's).
pub(crate) const SUB: usize = 4;

/// Levels that one sub-cell edge is below the cell's (`log2 SUB`).
const SUB_LEVELS: u32 = SUB.trailing_zeros();

/// A leaf at the last level with an edge longer than this many times
/// `2^-max_level` cells (what halving from a one-cell edge would leave)
/// shows a stalled refinement; converging refinement leaves edges about
/// an eighth of that.
const STALL_FACTOR: f64 = 8.0;

/// A long edge of a last-level leaf counts as stalled only when its
/// midpoint is farther from `S_K` than this fraction of its length (and
/// than epsilon): across a fold the chord misses `S_K` by a good part of
/// its length (an eighth to several times it on the EPI scan), while a
/// long edge over a smoothly curved sheet, which more levels would bring
/// within epsilon, misses it by a hundredth (Marschner-Lobb at epsilon
/// 0.001: 400 cells meshed again, three times the time, for the same
/// max distance, before this bound).
pub(crate) const STALL_SAG: f64 = 1.0 / 16.0;

/// Squared distance (local units) within which a new outline point is the
/// old one at the same place, rounded differently.
const WELD2: f64 = 1e-18;

/// Twice a strip triangle's area, squared (local units), below which the
/// strip is refused (three points of the outlines on one line).
const MIN_STRIP_AREA2: f64 = 1e-28;

thread_local! {
    /// Set while a cell is meshed on sub-cells: the nested extraction
    /// runs on this thread and must not nest again.
    static NESTED: Cell<bool> = const { Cell::new(false) };
}

/// Steps of a re-meshing (points or triangles through a loop, a few tens
/// of nanoseconds each) between two reads of [`Poll::cancel`].
const POLL_STEPS: u32 = 4096;

/// The extraction's stop request and progress report, as the cell's own
/// refinement polls them (see [`crate::refine::Refiner::cancel`]): a cell
/// meshed again at a high max level spends seconds in the nested
/// extraction and in the outlines of patches of millions of triangles,
/// during which progress is reported and a stop taken, as anywhere else
/// (no call was made for 4-6 s on a 4^3 volume at level 10). Polling reads
/// and changes nothing of the output.
pub(crate) struct Poll<'a> {
    /// The extraction's stop request.
    cancel: &'a AtomicBool,
    /// Reports progress when on the calling thread (at most every 20 ms).
    tick: Option<&'a (dyn Fn() + Sync)>,
    /// Steps since the stop request was last read.
    steps: Cell<u32>,
    /// Set once the stop request was found.
    stopped: Cell<bool>,
}

impl<'a> Poll<'a> {
    pub(crate) fn new(cancel: &'a AtomicBool, tick: Option<&'a (dyn Fn() + Sync)>) -> Self {
        Poll {
            cancel,
            tick,
            steps: Cell::new(0),
            stopped: Cell::new(false),
        }
    }

    /// Counts a step; every [`POLL_STEPS`] steps, [`Poll::now`]. `None`
    /// once the extraction was found stopped.
    #[inline]
    pub(crate) fn step(&self) -> Option<()> {
        let n = self.steps.get() + 1;
        if n < POLL_STEPS {
            self.steps.set(n);
            return (!self.stopped.get()).then_some(());
        }
        self.now()
    }

    /// Reports progress and reads the stop request: `None` once the
    /// extraction is stopped.
    pub(crate) fn now(&self) -> Option<()> {
        self.steps.set(0);
        if !self.stopped.get() {
            if let Some(tick) = self.tick {
                tick();
            }
            self.stopped.set(self.cancel.load(Ordering::Relaxed));
        }
        (!self.stopped.get()).then_some(())
    }
}

/// Marks this thread as inside a re-meshing until dropped (also when the
/// nested extraction unwinds).
struct Nested;

impl Nested {
    fn enter() -> Nested {
        NESTED.with(|n| n.set(true));
        Nested
    }
}

impl Drop for Nested {
    fn drop(&mut self) {
        NESTED.with(|n| n.set(false));
    }
}

/// Whether cells may be meshed on sub-cells in an extraction with
/// `options`: only on the trilinear filter (a sub-cell of a cubic filter's
/// cell is not that filter's cell) and its topology (the sub-cell patch
/// must end where the cell's does), and not inside such a re-meshing.
pub(crate) fn allowed(options: &Options) -> bool {
    options.reconstruction == Reconstruction::Trilinear
        && options.topology == Topology::Trilinear
        && !NESTED.with(|n| n.get())
}

/// [`crate::refine::Refiner::stall_len2`] for refinement to `max_level`
/// with re-meshing allowed: a leaf at the last level with an edge still
/// farther than epsilon (and than [`STALL_SAG`] of its length) and longer
/// than [`STALL_FACTOR`] `2^-max_level` shows a stalled refinement (converging refinement leaves such edges
/// about an eighth of that long; edges kept whole by splits elsewhere are
/// near, not far). Infinite below level 3, where the sub-cells' levels
/// would exceed `max_level`.
pub(crate) fn stall_len2(max_level: u32) -> f64 {
    if max_level < 3 {
        return f64::INFINITY;
    }
    let limit = STALL_FACTOR * 0.5f64.powi(max_level as i32);
    limit * limit
}

/// A cell's new patch: triangles over the old patch's points (indices
/// below the old point count) and `points` (indices from it on).
#[derive(Debug, Default)]
pub(crate) struct Remeshed {
    /// New points, local units.
    pub points: Vec<DVec3>,
    /// Triangles over the old patch's points and then `points`.
    pub tris: Vec<[u32; 3]>,
    /// Refinement level per triangle of `tris`.
    pub levels: Vec<u8>,
    /// Leaves of the sub-cell refinement still above epsilon.
    pub above_eps: u64,
}

/// Meshes the cell with corner values `f` (VTK corner order, less the
/// isovalue) again on sub-cells, keeping the outline of its refined patch
/// (`old_pos` local, `old_tris` indexing them). `None` when the two
/// outlines do not pair up arc by arc (the old patch then stays), and
/// when `poll` finds the extraction stopped (the caller reads that).
pub(crate) fn remesh(
    f: &[f64; 8],
    options: &Options,
    max_level: u32,
    old_pos: &[DVec3],
    old_tris: &[[u32; 3]],
    poll: &Poll<'_>,
) -> Option<Remeshed> {
    let n = SUB + 1;
    let inv = 1.0 / SUB as f64;
    let mut samples = Vec::with_capacity(n * n * n);
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let p = DVec3::new(i as f64, j as f64, k as f64) * inv;
                samples.push(trilinear_value(f, p));
            }
        }
    }
    // A sub-sample on the isovalue (common between integer samples) makes
    // the nested Marching Cubes settle a tie, whose flat triangles can end
    // farther from S_K than the cell's own patch: keep that.
    if samples.contains(&0.0) {
        return None;
    }
    let volume = Volume::new(&samples[..], [n as u64; 3]);
    let sub_options = Options {
        epsilon: options.epsilon * SUB as f64,
        max_level: max_level.saturating_sub(SUB_LEVELS).max(1),
        rule: options.rule,
        topology: Topology::Trilinear,
        normals: NormalMode::None,
        gradients: false,
        max_triangles: 0,
        threads: 1,
        reconstruction: Reconstruction::Trilinear,
    };
    // The nested extraction reports its progress (at most every 20 ms,
    // as refinement does) to the outer one's, and stops with it.
    let mesh = {
        let _nested = Nested::enter();
        extract_index_points(
            &volume,
            0.0,
            &sub_options,
            Some(&SerialExecutor),
            &mut |_| match poll.now() {
                Some(()) => ControlFlow::Continue(()),
                None => ControlFlow::Break(()),
            },
        )
        .ok()?
    };
    poll.now()?;
    let new_pos: Vec<DVec3> = mesh
        .index_points
        .iter()
        .map(|p| poll.step().map(|_| DVec3::from_array(*p) * inv))
        .collect::<Option<_>>()?;
    let new_tris: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .map(|t| poll.step().map(|_| t.map(|v| v as u32)))
        .collect::<Option<_>>()?;
    let old_arcs = outline(old_pos, old_tris, poll)?;
    let new_arcs = outline(&new_pos, &new_tris, poll)?;
    // One arc from each grid edge the surface crosses, in both outlines.
    let froms = |arcs: &[Arc]| {
        let mut f: Vec<u8> = arcs.iter().map(|a| a.from).collect();
        f.sort_unstable();
        f.dedup();
        f
    };
    let old_froms = froms(&old_arcs);
    if old_froms.len() != old_arcs.len() || old_froms != froms(&new_arcs) {
        return None;
    }
    // The old patch's point on each grid edge of the cell.
    let mut on_edge: HashMap<u8, u32> = HashMap::new();
    for a in &old_arcs {
        on_edge.insert(a.from, a.verts[0]);
    }
    // New points on grid edges are the old ones there; a new outline
    // point that is an old one up to rounding (the same face edge split
    // alike at both scales) is welded to it; the rest are numbered after
    // the old points.
    let mut old_of: Vec<Option<u32>> = vec![None; new_pos.len()];
    for (v, p) in new_pos.iter().enumerate() {
        poll.step()?;
        if let Some(e) = grid_edge(*p) {
            old_of[v] = Some(*on_edge.get(&e)?);
        }
    }
    let mut pairs = Vec::with_capacity(old_arcs.len());
    for old in &old_arcs {
        let new = new_arcs.iter().find(|a| a.from == old.from)?;
        if new.to != old.to || new.face != old.face {
            return None;
        }
        for &g in &new.verts[1..new.verts.len() - 1] {
            let q = new_pos[g as usize];
            let mut found = None;
            for &r in &old.verts[1..old.verts.len() - 1] {
                poll.step()?;
                if (old_pos[r as usize] - q).length_squared() <= WELD2 {
                    found = Some(r);
                    break;
                }
            }
            old_of[g as usize] = found;
        }
        pairs.push((old, new));
    }
    let base = old_pos.len() as u32;
    let mut out = Remeshed::default();
    let id: Vec<u32> = old_of
        .iter()
        .zip(&new_pos)
        .map(|(o, p)| {
            poll.step()?;
            Some(o.unwrap_or_else(|| {
                out.points.push(*p);
                base + out.points.len() as u32 - 1
            }))
        })
        .collect::<Option<_>>()?;
    for (t, &l) in new_tris.iter().zip(&mesh.levels) {
        poll.step()?;
        out.tris.push(t.map(|v| id[v as usize]));
        out.levels.push(l.saturating_add(SUB_LEVELS as u8));
    }
    let position = |v: u32| {
        if v < base {
            old_pos[v as usize]
        } else {
            out.points[(v - base) as usize]
        }
    };
    let mut strips = Vec::new();
    for (old, new) in pairs {
        let g: Vec<u32> = new.verts.iter().map(|&v| id[v as usize]).collect();
        zip(&old.verts, &g, &position, &mut strips, poll)?;
    }
    out.levels
        .extend(std::iter::repeat(max_level.min(255) as u8).take(strips.len()));
    out.tris.extend(strips);
    out.above_eps = mesh.stats.faces_above_epsilon;
    Some(out)
}

/// One arc of a patch's outline: boundary points in the patch's boundary
/// order from the point on grid edge `from` to the one on grid edge `to`,
/// all in cell face `face`.
#[derive(Debug)]
struct Arc {
    from: u8,
    to: u8,
    face: u8,
    verts: Vec<u32>,
}

/// The grid edge of the cell that local point `p` lies on (two
/// coordinates 0 or 1), numbered by its axis and those two coordinates.
fn grid_edge(p: DVec3) -> Option<u8> {
    let on = |x: f64| x == 0.0 || x == 1.0;
    let a = p.to_array();
    let fixed = (0..3).filter(|&i| on(a[i])).count();
    if fixed != 2 {
        return None;
    }
    let axis = (0..3).find(|&i| !on(a[i]))?;
    let (u, w) = ((axis + 1) % 3, (axis + 2) % 3);
    Some(axis as u8 * 4 + a[u] as u8 + 2 * a[w] as u8)
}

/// Bit `2 axis + side` for each cell face that local point `p` lies on.
pub(crate) fn faces(p: DVec3) -> u8 {
    let a = p.to_array();
    (0..3).fold(0, |m, i| {
        m | if a[i] == 0.0 {
            1 << (2 * i)
        } else if a[i] == 1.0 {
            1 << (2 * i + 1)
        } else {
            0
        }
    })
}

/// The outline of a patch cut into arcs between grid-edge points; `None`
/// when it is not a set of simple loops through grid edges, each arc in
/// one face (a point on a grid corner, a boundary point with two outgoing
/// boundary edges, a loop inside a face); also when `poll` finds the
/// extraction stopped.
fn outline(pos: &[DVec3], tris: &[[u32; 3]], poll: &Poll<'_>) -> Option<Vec<Arc>> {
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for t in tris {
        poll.step()?;
        for e in 0..3 {
            *directed.entry((t[e], t[(e + 1) % 3])).or_default() += 1;
        }
    }
    let mut next: HashMap<u32, u32> = HashMap::new();
    for (&(a, b), &count) in &directed {
        poll.step()?;
        if count == 1 && !directed.contains_key(&(b, a)) && next.insert(a, b).is_some() {
            return None;
        }
    }
    let mut arcs = Vec::new();
    let mut used = 0;
    let mut starts: Vec<u32> = Vec::new();
    for &v in next.keys() {
        poll.step()?;
        if grid_edge(pos[v as usize]).is_some() {
            starts.push(v);
        }
    }
    starts.sort_unstable();
    for s in starts {
        let mut verts = vec![s];
        let mut face = faces(pos[s as usize]);
        let mut cur = s;
        loop {
            poll.step()?;
            cur = *next.get(&cur)?;
            used += 1;
            verts.push(cur);
            face &= faces(pos[cur as usize]);
            if grid_edge(pos[cur as usize]).is_some() || verts.len() > next.len() + 1 {
                break;
            }
        }
        let to = grid_edge(pos[cur as usize])?;
        if face.count_ones() != 1 {
            return None;
        }
        arcs.push(Arc {
            from: grid_edge(pos[s as usize])?,
            to,
            face,
            verts,
        });
    }
    // Every boundary edge on an arc: no loop without a grid-edge point.
    (used == next.len()).then_some(arcs)
}

/// Triangles joining the old outline arc `r` to the new one `g` (same
/// ends, same direction), appended to `out`: each shortest diagonal
/// first; the old arc's edges keep their direction (the neighbour uses
/// them reversed) and the new arc's are reversed (the new patch uses them
/// forward).
///
/// The walk starts from the arc's end that comes first in coordinate
/// order, whichever way the arc runs: a neighbour meshed again too runs
/// the same two arcs the other way and must build the same strip, with
/// the opposite orientation, for the two strips to cancel (see
/// [`crate::assemble`]) and its fine outline to meet this one.
fn zip(
    r: &[u32],
    g: &[u32],
    pos: &impl Fn(u32) -> DVec3,
    out: &mut Vec<[u32; 3]>,
    poll: &Poll<'_>,
) -> Option<()> {
    let (first, last) = (pos(r[0]), pos(r[r.len() - 1]));
    if last.to_array() < first.to_array() {
        let (rr, gr): (Vec<u32>, Vec<u32>) = (
            r.iter().rev().copied().collect(),
            g.iter().rev().copied().collect(),
        );
        let from = out.len();
        zip_forward(&rr, &gr, pos, out, poll)?;
        for t in &mut out[from..] {
            t.swap(1, 2);
        }
        return Some(());
    }
    zip_forward(r, g, pos, out, poll)
}

/// [`zip`] from `r[0]` and `g[0]` on.
fn zip_forward(
    r: &[u32],
    g: &[u32],
    pos: &impl Fn(u32) -> DVec3,
    out: &mut Vec<[u32; 3]>,
    poll: &Poll<'_>,
) -> Option<()> {
    let (m, n) = (r.len() - 1, g.len() - 1);
    let (mut j, mut i) = (0, 0);
    while j < m || i < n {
        poll.step()?;
        let along_old = i == n
            || (j < m
                && (pos(r[j + 1]) - pos(g[i])).length_squared()
                    <= (pos(r[j]) - pos(g[i + 1])).length_squared());
        let t = if along_old {
            j += 1;
            [r[j - 1], r[j], g[i]]
        } else {
            i += 1;
            [r[j], g[i], g[i - 1]]
        };
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            continue;
        }
        let [a, b, c] = t.map(pos);
        if (b - a).cross(c - a).length_squared() < MIN_STRIP_AREA2 {
            return None;
        }
        out.push(t);
    }
    Some(())
}
