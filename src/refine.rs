//! Adaptive refinement of one cell's Marching Cubes triangles (section 3.1).
//!
//! Crack-freeness without a shared hash table: whether an edge splits, and
//! where its split point goes, is a pure function of the edge's two
//! endpoints (the midpoint `(a + b) / 2` is symmetric in IEEE arithmetic)
//! and of its *fixed axes*: an edge on a cell face (a boundary edge of the
//! cell's patch) is projected within that face, using only values that the
//! two cells sharing the face compute bit-identically (see
//! [`crate::filter`]). Both triangles on either side of an edge therefore
//! make the same decision and create the same point. Edges created by a
//! split at level `l` are tested only by triangles of level `l`, on both
//! sides, so the level cap cuts both sides alike and no T-junction appears.

use glam::DVec3;

use crate::filter::ReconstructionFilter;
use crate::flat_map::FlatMap;
use crate::nearest::{nearest, nearest_within};
use crate::options::Rule;
use crate::project::{seems_far, test_from, Test};
use std::sync::atomic::{AtomicBool, Ordering};

/// Refinement settings and counters for one worker.
pub(crate) struct Refiner<'c, F: ReconstructionFilter> {
    pub cell: &'c F::Cell,
    pub iso: f64,
    pub epsilon: f64,
    pub max_level: u32,
    pub rule: Rule,
    pub counters: &'c mut Counters,
    /// Decisions of the cell's edges so far, keyed by vertex ids: an edge
    /// shared by two triangles of the cell is tested once (the decision is
    /// a pure function of the edge, so this changes nothing but time).
    pub cache: &'c mut EdgeCache,
    /// Which cell faces and whether the interior may be refined (see
    /// [`Refinable`]).
    pub refinable: Refinable,
    /// Whether an interior sample (no fixed axis) whose gradient line
    /// leaves the cell without meeting `S_K` splits at the nearest point of
    /// `S_K` in the cell ([`nearest`]) when that lies strictly inside the
    /// cell. (One on a face would make triangles lying flat in the face,
    /// where the neighbour's patch may lie too.) Samples on faces never
    /// do: the two cells sharing a face decide its edges alike only when
    /// neither decision depends on its own patch, which this fallback is
    /// retried on.
    pub interior_fallback: bool,
    /// Leaves `run` may still emit before it gives up (`u64::MAX`: no
    /// limit). A pass under a triangle cap stops a cell as soon as it
    /// alone would break the cap, instead of refining it to the end.
    pub leaf_budget: u64,
    /// Squared length (local units) above which an edge of a leaf at the
    /// last level that is still farther than epsilon (and than
    /// [`crate::subcells::STALL_SAG`] of its length) counts in
    /// [`Counters::stalled_leaves`]; infinite to not look.
    pub stall_len2: f64,
    /// The extraction's stop request, read every [`CANCEL_POLL`] nodes:
    /// one cell at a high max level refines for seconds.
    pub cancel: &'c AtomicBool,
    /// Nodes visited since the stop request was last read.
    pub polls: u32,
    /// Called with each read of the stop request (the extraction's progress
    /// report, which may ask to stop, when this runs on the calling thread).
    pub tick: Option<&'c (dyn Fn() + Sync)>,
    /// Bytes of the edge cache's growth that could not be allocated (0:
    /// none); `run` then returns false and the extraction fails with
    /// `OutOfMemory` instead of aborting the host.
    pub alloc_failed: usize,
}

/// Nodes between two reads of [`Refiner::cancel`] (a few milliseconds of
/// refinement at most).
const CANCEL_POLL: u32 = 4096;

/// Where a cell may be refined, and against which isovalue. Near a sample
/// within rounding of the isovalue (but not on it), or a face saddle at
/// the isovalue, `S_K` touches itself or contains whole grid segments
/// there; split points projected near such a place from two sides land
/// on the same spot and weld into non-manifold or degenerate triangles.
/// So refinement stays away from them: an edge lying in a cell face
/// splits only when that face is free of such ties (decided from the
/// face's four samples alone, so both cells sharing it agree: no crack),
/// and interior edges and centres only when all six faces are. Such cells
/// keep (part of) their Marching Cubes triangles.
///
/// A sample exactly equal to the isovalue is not such a tie: Marching
/// Cubes counts it inside, and refinement (with the trilinear filter)
/// follows the isosurface of an isovalue lower by [`Refinable::shift`], a
/// relative 2^-32 of the face's (cell's) largest corner value, on which
/// that sample is inside too and `S_K` no longer passes through it.
/// (Integer data contoured at an integer isovalue has many such samples:
/// 8-bit data at 127 or 128 kept its Marching Cubes error, 0.11 cells,
/// everywhere near one.) Some such corners stay frozen:
/// - inside a cell, a corner not joined, through corners at or above the
///   isovalue along the cell's edges, to one above it (a peak or a ridge
///   at the isovalue): the shifted surface there is a cap or a thin tube
///   the size of the shift, which split points cannot follow (Marching
///   Cubes collapses its triangles);
/// - on a face, three corners at the isovalue and the fourth below: the
///   Marching Cubes outline cuts the face along the diagonal between the
///   outer two, while `S_K` runs along its edges and the shifted surface
///   hugs them;
/// - an ambiguous face with a corner at the isovalue: its saddle decides
///   Marching Cubes' topology within rounding of the shift.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Refinable {
    /// Bit `2 * axis + side` set: the face `axis = side` is free of ties.
    pub faces: u8,
    /// The whole cell is free of ties.
    pub interior: bool,
    /// How much lower than the isovalue refinement's isosurface lies on
    /// face `2 * axis + side` (`0..6`) and inside the cell (`6`): zero
    /// unless a corner of that face (cell) equals the isovalue.
    pub shift: [f64; 7],
}

/// Whether a face with corner values `g` (less the isovalue, in cyclic
/// order) is ambiguous: one diagonal's corners above, the other's not.
#[inline]
fn face_ambiguous(g: &[f64; 4]) -> bool {
    let s = g.map(|v| v > 0.0);
    s[0] == s[2] && s[1] == s[3] && s[0] != s[1]
}

/// Whether an ambiguous face's saddle lies within rounding ([`TIE`]) of
/// the isovalue: its diagonals' products are then all but equal.
#[inline]
fn saddle_tie(g: &[f64; 4]) -> bool {
    let (d0, d1) = (g[0] * g[2], g[1] * g[3]);
    (d0 - d1).abs() <= TIE * d0.abs().max(d1.abs())
}

/// The shift of a face (cell) with a corner at the isovalue, relative to
/// its largest corner value: far above rounding (the nearest corner
/// value that is not a tie is at least [`TIE`] of it), far below any
/// epsilon (the surface moves about this fraction of a cell).
const TIE_SHIFT: f64 = 1.0 / (1u64 << 32) as f64;

/// Corner values (less the isovalue) within this fraction of the face's
/// largest one, but not zero, are ties: the crossing lies within rounding
/// of the grid point in global index coordinates.
const TIE: f64 = 1e-10;

impl Refinable {
    /// From the corner values minus the isovalue (VTK corner order);
    /// `shift_ties`: whether corners at the isovalue may be refined around
    /// (the trilinear filter), else they are ties too.
    pub fn of_cell(f: &[f64; 8], shift_ties: bool) -> Self {
        Self::without_ties(f).unwrap_or_else(|| Self::of_cell_with_ties(f, shift_ties))
    }

    /// [`Refinable::of_cell`] for the common cell, where every corner lies
    /// farther from the isovalue than [`TIE`] of the largest (so no face
    /// has a corner at or near it, and nothing shifts): only ambiguous
    /// faces' saddles can then tie. `None` for any other cell (or NaN).
    /// This runs for every refined cell, where the general path (six
    /// faces, several passes over each one's corners) took a tenth of a
    /// smooth volume's refinement at a coarse epsilon.
    #[inline]
    fn without_ties(f: &[f64; 8]) -> Option<Self> {
        use crate::tables::cube::FACES;
        let hi = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        let floor = TIE * hi;
        if !f.iter().all(|v| v.abs() > floor) {
            return None;
        }
        let mut faces = 0b11_1111u8;
        for (bit, (_, _, c)) in FACES.iter().enumerate() {
            let g = c.map(|k| f[k as usize]);
            if face_ambiguous(&g) && saddle_tie(&g) {
                faces &= !(1 << bit);
            }
        }
        Some(Refinable {
            faces,
            interior: faces == 0b11_1111,
            shift: [0.0; 7],
        })
    }

    /// [`Refinable::of_cell`], every case.
    fn of_cell_with_ties(f: &[f64; 8], shift_ties: bool) -> Self {
        use crate::tables::cube::FACES;
        let mut faces = 0u8;
        let mut shift = [0.0; 7];
        for (axis, side, c) in FACES {
            let g = c.map(|k| f[k as usize]);
            let scale = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let zero = g.contains(&0.0);
            let near = g.iter().any(|&v| v != 0.0 && v.abs() <= TIE * scale);
            // Not three corners at the isovalue and the fourth below (see
            // above).
            let crossed = g.iter().filter(|&&v| v == 0.0).count() < 3 || g.iter().any(|&v| v > 0.0);
            let d = if zero && shift_ties && crossed {
                TIE_SHIFT * scale
            } else {
                0.0
            };
            let g = g.map(|v| v + d);
            let ambiguous = face_ambiguous(&g);
            let tie = near || (zero && (d == 0.0 || ambiguous)) || (ambiguous && saddle_tie(&g));
            let bit = 2 * axis as usize + side as usize;
            if !tie {
                faces |= 1 << bit;
                shift[bit] = d;
            }
        }
        let mut interior = faces == 0b11_1111;
        if f.contains(&0.0) {
            // Corners at the isovalue joined, through others at or above
            // it along the cell's edges, to one above it.
            let mut reached = f.map(|v| v > 0.0);
            for _ in 0..7 {
                for [a, b] in crate::tables::cube::EDGES {
                    let (a, b) = (a as usize, b as usize);
                    if f[a] >= 0.0 && f[b] >= 0.0 && reached[a] != reached[b] {
                        reached[a] = true;
                        reached[b] = true;
                    }
                }
            }
            interior &= shift_ties && (0..8).all(|k| f[k] != 0.0 || reached[k]);
            if interior {
                shift[6] = TIE_SHIFT * f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            }
        }
        Refinable {
            faces,
            interior,
            shift,
        }
    }

    /// The isovalue refinement follows for an edge with fixed-axis mask
    /// `fixed` through `mid` (local coordinates): the cell's inside it, a
    /// face's on it. On a grid edge (two fixed axes) the data's own: only
    /// a segment between two corners at the isovalue lies there, near.
    #[inline]
    pub fn iso(&self, iso: f64, fixed: u8, mid: DVec3) -> f64 {
        match fixed {
            0 => iso - self.shift[6],
            1 | 2 | 4 => {
                let k = fixed.trailing_zeros() as usize;
                iso - self.shift[2 * k + (mid[k] == 1.0) as usize]
            }
            _ => iso,
        }
    }

    /// Whether an edge with fixed-axis mask `fixed` through `mid` (local
    /// coordinates) may split.
    fn edge(&self, fixed: u8, mid: DVec3) -> bool {
        if fixed == 0 {
            return self.interior;
        }
        (0..3).all(|k| {
            fixed & (1 << k) == 0 || self.faces & (1 << (2 * k + (mid[k] == 1.0) as usize)) != 0
        })
    }
}

/// Per edge of one cell, keyed by the edge's vertex ids (smaller id in the
/// high half): the split decision, and the id of the split point once a
/// triangle has split the edge (`u32::MAX` before), so that the triangle
/// on the other side reuses the point instead of welding it again.
pub(crate) type EdgeCache = FlatMap<EdgeDecision>;

/// One edge's entry in the [`EdgeCache`] (plain fields rather than an
/// `Option<DVec3>`: copies of those cost store-forwarding stalls).
#[derive(Debug, Clone, Copy)]
pub(crate) struct EdgeDecision {
    /// The split point (local coordinates) when `split`.
    pub point: DVec3,
    /// The split point's id, `u32::MAX` until a triangle creates it.
    pub id: u32,
    /// Whether the edge splits.
    pub split: bool,
}

impl Default for EdgeDecision {
    fn default() -> Self {
        EdgeDecision {
            point: DVec3::ZERO,
            id: u32::MAX,
            split: false,
        }
    }
}

/// Refinement statistics, summed over cells.
#[derive(Debug, Clone, Default)]
pub(crate) struct Counters {
    pub samples: u64,
    pub splits: u64,
    pub failures: u64,
    pub above_eps: u64,
    /// Output triangles per level.
    pub per_level: [u64; 16],
    /// Nodes of the refinement trees per level (for the triangle cap).
    pub nodes_per_level: [u64; 16],
    /// Cells refined on their faces' edges only: their refined patch was
    /// unsound (see [`sound_patch`]), or, with the Classic topology, their
    /// table patch is not the trilinear interpolant's
    /// ([`crate::mc::topology_check`]).
    pub unsound_cells: u64,
    /// Split points placed by the nearest-point fallback
    /// ([`Refiner::interior_fallback`]).
    pub nearest_splits: u64,
    /// Marching Cubes polygons cut along other diagonals before refining
    /// (see [`crate::diagonals`]).
    pub recut_polygons: u64,
    /// Leaves at the last level with a long edge still farther than
    /// epsilon (see [`Refiner::stall_len2`] and [`crate::subcells`]).
    pub stalled_leaves: u64,
    /// Cells meshed again on sub-cells ([`crate::subcells`]).
    pub cells_on_subcells: u64,
}

/// A triangle being refined: vertex ids, local positions, fixed-axis mask
/// of each edge (edge `e` joins vertices `e` and `e + 1`), level.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Tri {
    pub v: [u32; 3],
    pub p: [DVec3; 3],
    pub fixed: [u8; 3],
    pub level: u8,
    /// Bit `e` set: edge `e` was already tested and is within epsilon
    /// (an edge kept whole by a split); a pure function, so not retested.
    pub near: u8,
}

/// Fixed axes shared by two points: those where both have the same
/// coordinate 0 or 1 (they lie on the same cell face or edge).
#[inline]
pub(crate) fn shared_fixed_axes(a: DVec3, b: DVec3) -> u8 {
    let mut m = 0;
    for k in 0..3 {
        if a[k] == b[k] && (a[k] == 0.0 || a[k] == 1.0) {
            m |= 1 << k;
        }
    }
    m
}

/// Whether a cell's refined triangles `tris` (ids into `verts`, global
/// index coordinates) form a sound patch: no corner repeated, no two
/// triangles on the same corners, every edge used at most once in each
/// direction, and, unless the Marching Cubes patch (local positions
/// `mc_pos`, three per triangle) is nearly closed, a vector area pointing
/// the same way as the Marching Cubes patch's. `origin` is the cell's
/// lowest corner in index coordinates; `edges` is scratch. (Counting
/// triangles that face up the filter's gradient as unsound too was tried:
/// it removes the far folds of thin tubes but, refining those cells on
/// their faces only, makes the atoms sample three times less accurate.)
/// Refinement can break these where straight gradient lines from different
/// sample points meet on `S_K`, or where it turns a tiny patch inside out;
/// the caller then refines the cell again without interior splits.
/// `Err(bytes)` when `edges` cannot grow (see [`soundly_connected`]).
pub(crate) fn sound_patch(
    origin: DVec3,
    tris: &[[u32; 3]],
    verts: &[DVec3],
    mc_pos: &[DVec3],
    edges: &mut FlatMap<u32>,
) -> Result<bool, usize> {
    if !soundly_connected(tris, edges)? {
        return Ok(false);
    }
    let mut area = DVec3::ZERO;
    for t in tris {
        area += vector_area(t.map(|v| verts[v as usize] - origin));
    }
    Ok(faces_like_marching_cubes(area, mc_pos))
}

/// The combinatorial half of [`sound_patch`]: no corner repeated, no two
/// triangles on the same corners, every edge used at most once in each
/// direction. `edges` is scratch; `Err(bytes)` when it cannot grow (a
/// patch refined deep holds millions of edges).
pub(crate) fn soundly_connected(
    tris: &[[u32; 3]],
    edges: &mut FlatMap<u32>,
) -> Result<bool, usize> {
    // Each directed edge, packed into a word, maps to the third corner of
    // its triangle: a second triangle on the same corners either repeats a
    // directed edge (same winding) or holds the reverse of one with the
    // same third corner (opposite winding).
    edges.clear();
    for t in tris {
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            return Ok(false);
        }
        for e in 0..3 {
            let (a, b, c) = (t[e] as u64, t[(e + 1) % 3] as u64, t[(e + 2) % 3]);
            if edges.try_insert_new(a << 32 | b, c)?.is_some() || edges.get(b << 32 | a) == Some(c)
            {
                return Ok(false);
            }
        }
    }
    Ok(true)
}

/// Twice the vector area of a triangle.
#[inline]
pub(crate) fn vector_area(p: [DVec3; 3]) -> DVec3 {
    (p[1] - p[0]).cross(p[2] - p[0])
}

/// Whether a refined patch of vector area `area` (twice the area) faces
/// the way of the Marching Cubes patch (`mc_pos`, three local positions
/// per triangle), or that patch is nearly closed (its direction means
/// nothing then). The geometric half of [`sound_patch`]: when refinement
/// merged no two points of a cell (see the caller), its patch is a
/// subdivision of the Marching Cubes patch and this is all that can fail.
pub(crate) fn faces_like_marching_cubes(area: DVec3, mc_pos: &[DVec3]) -> bool {
    let (mut mc_area, mut mc_abs) = (DVec3::ZERO, 0.0);
    for p in mc_pos.chunks_exact(3) {
        let a = vector_area([p[0], p[1], p[2]]);
        mc_area += a;
        mc_abs += a.length();
    }
    mc_area.length() < 0.25 * mc_abs || area.dot(mc_area) > 0.0
}

/// Whether two triangles have the same three corners (in any order).
fn same_corners(a: [DVec3; 3], b: [DVec3; 3]) -> bool {
    a.iter().all(|p| b.contains(p))
}

/// What testing one sample point decides: a pure function of the point,
/// its fixed axes, the cell, the isovalue, epsilon and whether the
/// nearest-point fallback is on (see [`Refiner::interior_fallback`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sample {
    /// Where the sample splits, if it does (local coordinates).
    pub split: Option<DVec3>,
    /// The gradient line left the cell without meeting `S_K`.
    pub failed: bool,
    /// The split point came from the nearest-point fallback.
    pub by_nearest: bool,
    /// The line failed and the nearest point of `S_K` in the cell is
    /// farther than epsilon but not strictly inside the cell (or was not
    /// found): refinement cannot bring this sample onto the surface, only
    /// split it at the nearest point at least [`FACE_BAND`] inside (when
    /// there is one, in `split`).
    pub stuck: bool,
}

/// Width (local units) of the band along the cell faces where a stuck
/// sample's split point may not go (see [`Sample::stuck`]): a point
/// closer to a face would make triangles all but flat in it, where the
/// neighbour's patch has its outline.
pub(crate) const FACE_BAND: f64 = 1.0 / 256.0;

/// Tests the sample point `p` (see [`Sample`]). No split point is taken
/// farther than `reach` from `p` (local units: the length of the edge
/// sampled, or the longest edge of the triangle): such a point lies on
/// another sheet of `S_K` in the cell, and a split there would stretch
/// triangles across the cell. (Where the sheet near `p` hugs a face, the
/// gradient line can cross the cell to a cap around the opposite corner;
/// the line then counts as failed. The nearest point off the band along
/// the faces can lie on such a cap too; the sample is then stuck.)
pub(crate) fn sample<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    p: DVec3,
    fixed: u8,
    epsilon: f64,
    fallback: bool,
    reach: f64,
) -> Sample {
    let vg = F::value_gradient(cell, p);
    sample_from::<F>(cell, iso, p, vg, fixed, epsilon, fallback, reach)
}

/// [`sample`], given the filter's value and gradient at `p`. Always
/// inlined: handed over through memory, the value and gradient were read
/// back wider than written (a store-forwarding stall on every sample).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn sample_from<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    p: DVec3,
    vg: (f64, DVec3),
    fixed: u8,
    epsilon: f64,
    fallback: bool,
    reach: f64,
) -> Sample {
    let mut s = Sample {
        split: None,
        failed: false,
        by_nearest: false,
        stuck: false,
    };
    let within = |q: DVec3| (q - p).length_squared() <= reach * reach;
    match test_from::<F>(cell, iso, p, vg, fixed, epsilon) {
        Test::Far(q) if within(q) => s.split = Some(q),
        Test::Failed | Test::Far(_) => {
            // The gradient line left the cell, or crossed it to another
            // sheet of `S_K`: the nearest point of `S_K` in the cell
            // (face) decides instead.
            s.failed = true;
            if fixed == 0 && fallback {
                match nearest::<F>(cell, iso, p, epsilon) {
                    Test::Far(q) if q.cmpgt(DVec3::ZERO).all() && q.cmplt(DVec3::ONE).all() => {
                        if within(q) {
                            s.split = Some(q);
                            s.by_nearest = true;
                        } else {
                            s.stuck = true;
                        }
                    }
                    Test::Near => {}
                    _ => {
                        // The surface's nearest point lies on a face (where
                        // S_K hugs it; or its foot could not be settled
                        // inside): the best point strictly inside is the
                        // nearest one off the band along the faces.
                        s.stuck = true;
                        match nearest_within::<F>(cell, iso, p, epsilon, FACE_BAND) {
                            Test::Far(q) if within(q) => {
                                s.split = Some(q);
                                s.by_nearest = true;
                            }
                            _ => {}
                        }
                    }
                }
            }
        }
        Test::Near => {}
    }
    s
}

/// Tests the edge between local points `a` and `b` at its midpoint, as
/// [`sample`] does, but, for an interior edge whose midpoint's gradient
/// line misses `S_K`, splits it nearer its middle when it can. The
/// nearest point of `S_K` that then decides can lie far along the edge
/// (more than a quarter of its length from the midpoint, next to one
/// end): the children keep nearly the whole edge, and `S_K` between its
/// ends is never sampled however deep refinement goes (folds and necks of
/// `S_K` that a Marching Cubes triangle spans). There `S_K` is also sought
/// in the plane bisecting the edge ([`bisector_root`]), and the point
/// found is taken unless its longer child is more than
/// [`BISECTOR_SLACK`] times the nearest point's. (Where `S_K` bows far
/// away from the chord between the ends, the bisector's point makes two
/// children of about equal length, each a little longer than half the
/// chord or even than the whole edge, that follow the surface; the
/// nearest point's long child would only span the same bow again.
/// Doing the same where the gradient line does meet `S_K` far along the
/// edge changes nothing for the trilinear filter and folds triangles of
/// the smoothing B-spline.) A pure function of the edge: the ends are put
/// in a fixed order first.
pub(crate) fn sample_edge<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    a: DVec3,
    b: DVec3,
    fixed: u8,
    epsilon: f64,
    fallback: bool,
) -> Sample {
    let m = (a + b) * 0.5;
    let vg = F::value_gradient(cell, m);
    let mut s = sample_from::<F>(cell, iso, m, vg, fixed, epsilon, fallback, (b - a).length());
    if s.split.is_none() && !s.failed && fixed == 0 {
        s.split = bulge::<F>(cell, iso, a, b, vg, epsilon, fallback);
        return s;
    }
    let (Some(q), true, 0) = (s.split, s.failed, fixed) else {
        return s;
    };
    let (a, b) = ordered(a, b);
    let e = b - a;
    if ((q - m).dot(e)).abs() <= 0.25 * e.length_squared() {
        return s;
    }
    if let Some(r) = bisector_root::<F>(cell, iso, m, e) {
        if longer_child(a, b, r) < BISECTOR_SLACK * longer_child(a, b, q)
            && (r - m).length_squared() <= e.length_squared()
        {
            s.split = Some(r);
        }
    }
    s
}

/// The ends of an edge in a fixed order (lexicographic), so that what is
/// computed from them does not depend on the order they came in.
#[inline]
fn ordered(a: DVec3, b: DVec3) -> (DVec3, DVec3) {
    if a.to_array() <= b.to_array() {
        (a, b)
    } else {
        (b, a)
    }
}

/// Where `S_K` bows more than epsilon away from the interior edge `a b`
/// between its ends and its midpoint, which tested near. For a filter that
/// is a cubic along lines ([`ReconstructionFilter::line_cubic`]: the
/// trilinear one) `F - iso` along the edge is known exactly; with both
/// ends on `S_K` and the midpoint near, it can still swing away in an S
/// (a sheet crossing the edge at a slant), which a midpoint never sees
/// however small epsilon is: on the atoms sample of the benchmark such
/// edges, kept whole down to the last level, set the surface's farthest
/// point (0.029 cells at every epsilon from 0.01 to 0.001). The cubic's
/// extreme values between the ends, over the gradient's length there,
/// estimate the distance; a point estimated farther than epsilon is
/// tested like any sample, and the edge splits where that test puts it.
/// (In a face the filter is bilinear, so along an edge in it a quadratic:
/// with both ends on `S_K` its extreme is at the midpoint, already
/// tested.) `None` when the edge stays near or the filter is not a cubic
/// along lines. A pure function of the edge: the ends are put in a fixed
/// order first.
fn bulge<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    a: DVec3,
    b: DVec3,
    (v, g): (f64, DVec3),
    epsilon: f64,
    fallback: bool,
) -> Option<DVec3> {
    let (a, b) = ordered(a, b);
    let m = (a + b) * 0.5;
    let e = b - a;
    let (a2, a3) = F::line_cubic(cell, m, e)?;
    // With t = 0 at the midpoint and the ends (t = +-1/2) on `S_K`, the
    // cubic is (1 - 4 t^2) (q0 - a3 t / 4): beyond the midpoint's own
    // value q0 it swings by at most |a3| / (12 sqrt 3) < 0.05 |a3|. Nearly
    // every edge (all short ones: a3 grows with the cube of the length)
    // swings by less than a tenth of epsilon there and is left to its
    // midpoint's decision, which spares the search below (it made
    // refinement a sixth slower on Marschner-Lobb).
    if 0.05 * a3.abs() <= 0.1 * epsilon * g.length() {
        return None;
    }
    let (q0, q1) = (v - iso, g.dot(e));
    // The critical points of q0 + q1 t + a2 t^2 + a3 t^3 (a3 != 0 here).
    let disc = a2 * a2 - 3.0 * a3 * q1;
    if disc < 0.0 {
        return None;
    }
    let r = disc.sqrt();
    let mut worst: Option<(f64, DVec3)> = None;
    for t in [(-a2 - r) / (3.0 * a3), (-a2 + r) / (3.0 * a3)] {
        if !(t > -0.5 && t < 0.5) {
            continue;
        }
        let x = m + e * t;
        let c = (q0 + t * (q1 + t * (a2 + t * a3))).abs();
        // The gradient there, not at the midpoint: near a saddle of the
        // filter it is far weaker, and the distance far larger.
        let d = c / F::gradient(cell, x).length();
        if d > epsilon && worst.map_or(true, |(wd, _)| d > wd) {
            worst = Some((d, x));
        }
    }
    let x = worst?.1;
    sample::<F>(cell, iso, x, 0, epsilon, fallback, e.length()).split
}

/// How much longer than the nearest point's longer child the bisector's
/// may be and still be taken (see [`sample_edge`]). On Marschner-Lobb
/// (A1, epsilon 0.01) any factor from 1.25 up gave the same surface: the
/// farthest triangle 0.013 cells from `S_K` instead of 0.25 (1.0: only a
/// shorter longer child) and 0.13 (1.05); on the EPI scan of the
/// benchmark the mean distance grew by 2 % (1.05: 0.4 %).
const BISECTOR_SLACK: f64 = 1.25;

/// The length of the longer of the two children of edge `a b` split at `x`.
fn longer_child(a: DVec3, b: DVec3, x: DVec3) -> f64 {
    (x - a).length().max((b - x).length())
}

/// Steps of the grid over the bisecting plane (see [`bisector_root`]).
const BISECTOR_GRID: usize = 24;

/// The point of `S_K` nearest to `m` found in the plane through `m`
/// orthogonal to `e`, strictly inside the cell (a point on a face would
/// make triangles lying flat in it, where the neighbour's patch may lie
/// too): the roots on the segments of a square grid over the plane's part
/// in the cell whose ends' values straddle the isovalue. (A grid, not
/// lines through `m`: the plane meets `S_K` in curves that such lines can
/// all miss.) `None` when there is none.
fn bisector_root<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    m: DVec3,
    e: DVec3,
) -> Option<DVec3> {
    bisector_scan::<F, true>(cell, iso, m, e)
}

/// [`bisector_root`]; with `PRUNE` off every straddling segment's root is
/// computed (the reference the pruned scan must agree with).
fn bisector_scan<F: ReconstructionFilter, const PRUNE: bool>(
    cell: &F::Cell,
    iso: f64,
    m: DVec3,
    e: DVec3,
) -> Option<DVec3> {
    // An orthonormal basis of the plane, across the axis least aligned
    // with e.
    let k = (0..3)
        .min_by(|&i, &j| e[i].abs().total_cmp(&e[j].abs()))
        .unwrap_or(0);
    let u = e.cross(DVec3::AXES[k]).normalize_or_zero();
    let v = e.cross(u).normalize_or_zero();
    if u == DVec3::ZERO || v == DVec3::ZERO {
        return None;
    }
    // The plane's part in the cell lies within the cell corners' shadow.
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for c in crate::tables::cube::CORNERS {
        let corner = DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
        let st = [(corner - m).dot(u), (corner - m).dot(v)];
        for i in 0..2 {
            lo[i] = lo[i].min(st[i]);
            hi[i] = hi[i].max(st[i]);
        }
    }
    const N: usize = BISECTOR_GRID;
    let at = |i: usize, j: usize| {
        let s = lo[0] + (hi[0] - lo[0]) * i as f64 / N as f64;
        let t = lo[1] + (hi[1] - lo[1]) * j as f64 / N as f64;
        m + u * s + v * t
    };
    let inside = |p: DVec3| p.cmpgt(DVec3::ZERO).all() && p.cmplt(DVec3::ONE).all();
    let value = |p: DVec3| {
        if inside(p) {
            F::value(cell, p) - iso
        } else {
            f64::NAN
        }
    };
    let mut grid = [[f64::NAN; N + 1]; N + 1];
    for (j, row) in grid.iter_mut().enumerate() {
        for (i, q) in row.iter_mut().enumerate() {
            *q = value(at(i, j));
        }
    }
    // The segments to the left of and below each grid point whose ends
    // straddle iso, numbered in row order, each with its distance from m
    // (a lower bound for its root's).
    let mut segments: Vec<(f64, usize, [usize; 2], [usize; 2])> = Vec::new();
    for j in 0..=N {
        for i in 0..=N {
            let q = grid[j][i];
            let others = [(i > 0).then(|| [i - 1, j]), (j > 0).then(|| [i, j - 1])];
            for (side, other) in others.into_iter().enumerate() {
                let Some(o) = other else { continue };
                let qo = grid[o[1]][o[0]];
                if q.is_nan() || qo.is_nan() || ((q < 0.0) == (qo < 0.0) && q != 0.0 && qo != 0.0) {
                    continue;
                }
                let (a, b) = (at(o[0], o[1]), at(i, j));
                let t = ((m - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
                let bound = (a + (b - a) * t - m).length();
                segments.push((bound, 2 * (j * (N + 1) + i) + side, o, [i, j]));
            }
        }
    }
    // Nearest first, so that the root of one of the first segments rules
    // out the rest; ties go to the segment first in row order, as a scan
    // in that order would take.
    segments.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
    let mut best: Option<(f64, usize, DVec3)> = None;
    for (bound, index, o, g) in segments {
        // A root is no nearer than its segment (with slack for rounding).
        if PRUNE && best.is_some_and(|(bd, _, _)| bound > bd * (1.0 + 1e-9)) {
            break;
        }
        let (other, p) = (at(o[0], o[1]), at(g[0], g[1]));
        let (qo, q) = (grid[o[1]][o[0]], grid[g[1]][g[0]]);
        let line = |x: f64| F::value(cell, other + (p - other) * x) - iso;
        let x = crate::project::solve(&line, 0.0, qo, 1.0, q);
        let r = other + (p - other) * x;
        let d = (r - m).length();
        if inside(r) && best.map_or(true, |(bd, bi, _)| d < bd || (d == bd && index < bi)) {
            best = Some((d, index, r));
        }
    }
    best.map(|(_, _, r)| r)
}

/// The [`EdgeCache`] key of the edge between points `a` and `b`.
#[inline]
pub(crate) fn edge_key(a: u32, b: u32) -> u64 {
    (a.min(b) as u64) << 32 | a.max(b) as u64
}

impl<F: ReconstructionFilter> Refiner<'_, F> {
    /// Tests the centre `p` of a triangle whose longest edge is `reach`
    /// long; returns the relocated point if it must split. A point on a
    /// cell face is refused: its edges to the triangle's corners on that
    /// face would lie flat in it, where the neighbour's patch can make the
    /// same edges (an edge in four triangles). Rule A2 clamps its
    /// candidate into the cell, onto a face at times, and a smooth
    /// filter's gradient lies in the face there when the data is mirror
    /// symmetric about it, so the projection stays in the face.
    fn test(&mut self, p: DVec3, fixed: u8, reach: f64) -> Option<DVec3> {
        let s = sample::<F>(
            self.cell,
            self.refinable.iso(self.iso, fixed, p),
            p,
            fixed,
            self.epsilon,
            self.interior_fallback,
            reach,
        );
        self.count(&s);
        s.split
            .filter(|q| q.cmpgt(DVec3::ZERO).all() && q.cmplt(DVec3::ONE).all())
    }

    fn count(&mut self, s: &Sample) {
        self.counters.samples += 1;
        self.counters.failures += s.failed as u64;
        self.counters.nearest_splits += s.by_nearest as u64;
    }

    /// Records the decision `s` of the edge between points `a` and `b`,
    /// tested by the caller with this refiner's settings, exactly as
    /// [`Refiner::run`] would have (the test is not run twice).
    pub fn preset(&mut self, a: u32, b: u32, s: &Sample) {
        self.count(s);
        self.cache.insert_new(
            edge_key(a, b),
            EdgeDecision {
                point: s.split.unwrap_or(DVec3::ZERO),
                split: s.split.is_some(),
                ..EdgeDecision::default()
            },
        );
    }

    /// Whether any sample of `t` is above epsilon (for the statistics at the
    /// maximum level), and whether such an edge is longer than
    /// [`Refiner::stall_len2`] allows and sags as a fold does.
    fn above(&mut self, t: &Tri) -> (bool, bool) {
        let mut far = false;
        for e in 0..3 {
            let (a, b) = (t.p[e], t.p[(e + 1) % 3]);
            let long = (b - a).length_squared() > self.stall_len2;
            if (far && !long) || t.near & (1 << e) != 0 {
                continue;
            }
            let m = (a + b) * 0.5;
            let iso = self.refinable.iso(self.iso, t.fixed[e], m);
            if seems_far::<F>(self.cell, iso, m, t.fixed[e], self.epsilon) {
                far = true;
                let sag = crate::subcells::STALL_SAG * (b - a).length();
                if long
                    && (sag <= self.epsilon || seems_far::<F>(self.cell, iso, m, t.fixed[e], sag))
                {
                    return (true, true);
                }
            }
        }
        (far, false)
    }

    /// Emits the output triangle `t` and counts it at its level; false,
    /// emitting nothing, when the leaf budget is spent.
    #[inline(always)]
    fn leaf(&mut self, t: &Tri, emit: &mut impl FnMut(&Tri)) -> bool {
        if self.leaf_budget == 0 {
            return false;
        }
        self.leaf_budget -= 1;
        self.counters.per_level[(t.level as usize).min(15)] += 1;
        emit(t);
        true
    }

    /// Refines `root`; `emit(tri)` receives output triangles in a fixed
    /// order, `vertex(p)` returns the id of a new point (local coordinates).
    /// Returns false, leaving the output partial, when `leaf_budget` ran
    /// out or the extraction was stopped ([`Refiner::cancel`]).
    pub fn run(
        &mut self,
        root: Tri,
        count_above: bool,
        emit: &mut impl FnMut(&Tri),
        vertex: &mut impl FnMut(DVec3) -> u32,
    ) -> bool {
        self.node(&root, count_above, emit, vertex)
    }

    /// Refines `t` and, depth first, its children (the tree is at most
    /// `max_level` deep). Recursion rather than a stack of triangles:
    /// each child is read where it was built, where a copy through a
    /// stack cost store-forwarding stalls on every node.
    fn node(
        &mut self,
        t: &Tri,
        count_above: bool,
        emit: &mut impl FnMut(&Tri),
        vertex: &mut impl FnMut(DVec3) -> u32,
    ) -> bool {
        self.polls += 1;
        if self.polls == CANCEL_POLL {
            self.polls = 0;
            if let Some(tick) = self.tick {
                tick();
            }
            if self.cancel.load(Ordering::Relaxed) {
                return false;
            }
        }
        let lvl = t.level as usize;
        self.counters.nodes_per_level[lvl.min(15)] += 1;
        if t.level as u32 >= self.max_level {
            if count_above {
                let (far, stalled) = self.above(t);
                self.counters.above_eps += far as u64;
                self.counters.stalled_leaves += stalled as u64;
            }
            return self.leaf(t, emit);
        }
        // Bit e of `split`: edge e splits at `mid_p[e]`. (A mask and a
        // plain array: arrays of Option<DVec3> cost store-forwarding
        // stalls on every copy.)
        let mut split = 0u8;
        let mut mid_p = [DVec3::ZERO; 3];
        // The cache slot of each tested edge: room for the three is made
        // first, so the slots stay put until the split points take their
        // ids below (one probe an edge, not three).
        let mut slots = [0usize; 3];
        if let Err(bytes) = self.cache.try_reserve(3) {
            self.alloc_failed = bytes;
            return false;
        }
        // An edge's midpoint, where needed: only an edge in a cell face
        // looks at it before its sample is taken (rule A2 after).
        let midpoint = |e: usize| (t.p[e] + t.p[(e + 1) % 3]) * 0.5;
        for e in 0..3 {
            let fixed = t.fixed[e];
            let mid = if fixed == 0 { DVec3::ZERO } else { midpoint(e) };
            if t.near & (1 << e) == 0 && self.refinable.edge(fixed, mid) {
                let key = edge_key(t.v[e], t.v[(e + 1) % 3]);
                let (slot, found) = self.cache.find(key);
                slots[e] = slot;
                let d = match found {
                    true => self.cache.value(slot),
                    false => {
                        let s = sample_edge::<F>(
                            self.cell,
                            self.refinable.iso(self.iso, fixed, mid),
                            t.p[e],
                            t.p[(e + 1) % 3],
                            fixed,
                            self.epsilon,
                            self.interior_fallback,
                        );
                        self.count(&s);
                        let r = s.split;
                        let d = EdgeDecision {
                            point: r.unwrap_or(DVec3::ZERO),
                            split: r.is_some(),
                            ..EdgeDecision::default()
                        };
                        // Before the next edge's probe: a triangle whose
                        // corners welded into one point has two edges on
                        // the same key.
                        self.cache.fill(slot, key, d);
                        d
                    }
                };
                if d.split {
                    split |= 1 << e;
                    mid_p[e] = d.point;
                }
            }
        }
        let splits = |e: usize| split & (1 << e) != 0;
        let nsplit = split.count_ones() as usize;
        let centroid = || (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        // Only for a centre that is tested (not on Rule A's path).
        let longest = || {
            (0..3)
                .map(|e| (t.p[(e + 1) % 3] - t.p[e]).length_squared())
                .fold(0.0, f64::max)
                .sqrt()
        };
        let centre = match self.rule {
            _ if !self.refinable.interior => None,
            Rule::A => None,
            Rule::A1 => {
                if nsplit == 0 {
                    self.test(centroid(), 0, longest())
                } else {
                    None
                }
            }
            Rule::B => self.test(centroid(), 0, longest()),
            Rule::A2 => {
                let mut shift = DVec3::ZERO;
                for e in 0..3 {
                    if splits(e) {
                        shift += mid_p[e] - midpoint(e);
                    }
                }
                if nsplit > 0 {
                    shift /= nsplit as f64;
                }
                let cand = (centroid() + shift).clamp(DVec3::ZERO, DVec3::ONE);
                self.test(cand, 0, longest())
            }
        };
        if nsplit == 0 && centre.is_none() {
            return self.leaf(t, emit);
        }
        // Ids and positions of the triangle's points by slot: its
        // corners, its edges' split points, its centre.
        let mut ids = [
            t.v[0],
            t.v[1],
            t.v[2],
            u32::MAX,
            u32::MAX,
            u32::MAX,
            u32::MAX,
        ];
        let mut pos = [
            t.p[0],
            t.p[1],
            t.p[2],
            mid_p[0],
            mid_p[1],
            mid_p[2],
            DVec3::ZERO,
        ];
        for e in 0..3 {
            if splits(e) {
                // A split edge was tested, so its slot holds it. The
                // split point of an edge shared by two triangles of the
                // cell is made (and counted) once.
                let entry = self.cache.value_mut(slots[e]);
                if entry.id == u32::MAX {
                    entry.id = vertex(mid_p[e]);
                    self.counters.splits += 1;
                }
                ids[M0 + e] = entry.id;
            }
        }
        if let Some(c) = centre {
            ids[C] = vertex(c);
            pos[C] = c;
            self.counters.splits += 1;
        }
        let mut children = [[C as u8; 3]; 6];
        let mut n = 0;
        if centre.is_some() {
            let mut ring = [C as u8; 6];
            let mut len = 0;
            for e in 0..3 {
                ring[len] = e as u8;
                len += 1;
                if splits(e) {
                    ring[len] = (M0 + e) as u8;
                    len += 1;
                }
            }
            for k in 0..len {
                children[n] = [ring[k], ring[(k + 1) % len], C as u8];
                n += 1;
            }
        } else {
            let (v, m) = (|i: usize| (i % 3) as u8, |e: usize| (M0 + e % 3) as u8);
            match nsplit {
                1 => {
                    let e = (0..3).find(|&e| splits(e)).unwrap();
                    children[0] = [v(e), m(e), v(e + 2)];
                    children[1] = [m(e), v(e + 1), v(e + 2)];
                    n = 2;
                }
                2 => {
                    let u = (0..3).find(|&e| !splits(e)).unwrap();
                    let (e1, e2) = ((u + 1) % 3, (u + 2) % 3);
                    children[0] = [m(e1), v(u + 2), m(e2)];
                    let d1 = (t.p[u] - mid_p[e1]).length_squared();
                    let d2 = (t.p[(u + 1) % 3] - mid_p[e2]).length_squared();
                    if d1 <= d2 {
                        children[1] = [v(u), v(u + 1), m(e1)];
                        children[2] = [v(u), m(e1), m(e2)];
                    } else {
                        children[1] = [v(u), v(u + 1), m(e2)];
                        children[2] = [v(u + 1), m(e1), m(e2)];
                    }
                    n = 3;
                }
                _ => {
                    children[0] = [v(0), m(0), m(2)];
                    children[1] = [m(0), v(1), m(1)];
                    children[2] = [m(2), m(1), v(2)];
                    children[3] = [m(0), m(1), m(2)];
                    n = 4;
                }
            }
        }
        // Split points of different edges may land on the same point of
        // `S_K` (straight gradient lines can meet there). A child with two
        // such corners has no area, and two children on the same corners
        // are the two sides of a pinched-off fold: both are dropped. The
        // edges around them are then shared by the neighbours directly,
        // so the mesh stays closed and manifold. Positions, not ids, are
        // compared so that counting (distinct ids) agrees with output.
        // Element by element, like the children's corners below:
        // `array::map` assembles an array with stores of other widths
        // than the copy that reads it (a store-forwarding stall).
        let corners = |ch: [u8; 3]| {
            [
                pos[ch[0] as usize],
                pos[ch[1] as usize],
                pos[ch[2] as usize],
            ]
        };
        let mut keep = [true; 6];
        // When the new points differ from each other and from the
        // corners, every child has three distinct corners and no two
        // children share them: the checks below are skipped.
        let mut fresh = [DVec3::ZERO; 4];
        let mut nfresh = 0;
        for e in 0..3 {
            if splits(e) {
                fresh[nfresh] = mid_p[e];
                nfresh += 1;
            }
        }
        if let Some(c) = centre {
            fresh[nfresh] = c;
            nfresh += 1;
        }
        let distinct = (0..nfresh)
            .all(|a| !t.p.contains(&fresh[a]) && (a + 1..nfresh).all(|b| fresh[a] != fresh[b]));
        if !distinct {
            for x in 0..n {
                let [a, b, c] = corners(children[x]);
                if a == b || b == c || a == c {
                    keep[x] = false;
                }
            }
            for x in 0..n {
                for y in x + 1..n {
                    if keep[x]
                        && keep[y]
                        && same_corners(corners(children[x]), corners(children[y]))
                    {
                        keep[x] = false;
                        keep[y] = false;
                    }
                }
            }
        }
        // A child edge along a parent edge keeps its fixed axes; one
        // joining two of the parent's corners is that whole, unsplit
        // edge, tested (or known) near. No branch: slots are masked into
        // the 8x8 table, and NO_EDGE reads the zero after the three
        // edges' axes.
        let fixed = [t.fixed[0], t.fixed[1], t.fixed[2], 0];
        let edge_of = |a: u8, b: u8| -> (u8, u8) {
            let whole = ((a < M0 as u8) & (b < M0 as u8)) as u8;
            let (a, b) = (a as usize & 7, b as usize & 7);
            (fixed[PARENT_EDGE[a][b] as usize & 3], whole)
        };
        for x in 0..n {
            if !keep[x] {
                continue;
            }
            let ch = children[x];
            let (f0, n0) = edge_of(ch[0], ch[1]);
            let (f1, n1) = edge_of(ch[1], ch[2]);
            let (f2, n2) = edge_of(ch[2], ch[0]);
            let mut child = Tri {
                v: [
                    ids[ch[0] as usize],
                    ids[ch[1] as usize],
                    ids[ch[2] as usize],
                ],
                p: [DVec3::ZERO; 3],
                fixed: [f0, f1, f2],
                level: t.level + 1,
                near: n0 | n1 << 1 | n2 << 2,
            };
            // Corner by corner into place: a whole array built apart
            // and copied in is read back with loads of other widths
            // than its stores (a store-forwarding stall every child).
            for k in 0..3 {
                child.p[k] = pos[ch[k] as usize];
            }
            if !self.node(&child, count_above, emit, vertex) {
                return false;
            }
        }
        true
    }
}

/// Slots of the points a triangle splits into: its corners `0..3`, the
/// split points of its edges `M0 + e` (edge `e` joins corners `e` and
/// `e + 1`), its centre `C`.
const M0: usize = 3;
const C: usize = 6;
const NO_EDGE: u8 = 3;

/// The parent edge two slots both lie on ([`NO_EDGE`] for none): corners
/// `i` and `i + 1` and the split point between them lie on edge `i`.
/// (Eight by eight, so that a slot masked with 7 needs no bounds check.)
const PARENT_EDGE: [[u8; 8]; 8] = {
    let mut t = [[NO_EDGE; 8]; 8];
    let mut e = 0;
    while e < 3 {
        let (a, b, m) = (e, (e + 1) % 3, M0 + e);
        t[a][b] = e as u8;
        t[b][a] = e as u8;
        t[a][m] = e as u8;
        t[m][a] = e as u8;
        t[b][m] = e as u8;
        t[m][b] = e as u8;
        e += 1;
    }
    t
};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::{trilinear_value, Trilinear};
    use crate::project::test;

    use crate::nearest::tests::uniform;

    type Tri = Trilinear<'static, f64>;

    /// Corner values (VTK order) of `a x + b y + c z + d`.
    fn linear_cell(a: f64, b: f64, c: f64, d: f64) -> [f64; 8] {
        crate::tables::cube::CORNERS.map(|[x, y, z]| a * x as f64 + b * y as f64 + c * z as f64 + d)
    }

    #[test]
    fn samples_at_the_isovalue_shift_the_isovalue_where_the_surface_crosses_them() {
        // Corner 2 = (1, 1, 0) at the isovalue, crossed: neighbours -2, -1, 4.
        let f = linear_cell(1.0, 2.0, 4.0, -3.0);
        assert_eq!(f[2], 0.0);
        let r = Refinable::of_cell(&f, true);
        assert!(r.interior && r.faces == 0b11_1111);
        assert_eq!(r.shift[6], TIE_SHIFT * 4.0);
        // Faces x = 1, y = 1, z = 0 hold corner 2; the others are untouched.
        for (bit, scale) in [(1, 4.0), (3, 4.0), (4, 3.0)] {
            assert_eq!(r.shift[bit], TIE_SHIFT * scale, "face {bit}");
        }
        for bit in [0, 2, 5] {
            assert_eq!(r.shift[bit], 0.0, "face {bit}");
        }
        let mid = DVec3::new(1.0, 0.5, 0.5);
        assert_eq!(r.iso(10.0, 1, mid), 10.0 - r.shift[1]);
        assert_eq!(r.iso(10.0, 0, mid), 10.0 - r.shift[6]);
        assert_eq!(r.iso(10.0, 0b011, mid), 10.0);
        // Corner 6 at the isovalue with no neighbour above it, but joined
        // through corners 2 and 7 (at it) to corner 3 (above): a sheet
        // along the face y = 1, not a ridge (8-bit data at 127).
        let joined = [-2.0, -3.0, 0.0, 1.0, -3.0, -4.0, 0.0, 0.0];
        let j = Refinable::of_cell(&joined, true);
        assert!(j.interior && j.shift[3] > 0.0);
        // Other filters: every face through the corner and the inside freeze.
        let r = Refinable::of_cell(&f, false);
        assert!(!r.interior);
        assert_eq!(r.faces, 0b10_0101);
        assert_eq!(r.shift, [0.0; 7]);
        // A tie that is not exact still freezes its faces.
        let mut g = f;
        g[2] = 1e-13;
        assert_eq!(Refinable::of_cell(&g, true).faces, 0b10_0101);
    }

    /// The tie-free shortcut decides exactly as the general path, on
    /// random cells of small integers (corners at the isovalue, ambiguous
    /// faces whose saddle sits on it), with near-ties and a NaN mixed in.
    #[test]
    fn the_tie_free_shortcut_agrees_with_the_general_path() {
        let mut rng = crate::test_rng::XorShift(0x5eed_cafe);
        let (mut fast, mut ambiguous_ties) = (0, 0);
        for n in 0..200_000 {
            let mut f = [0.0; 8];
            for v in &mut f {
                *v = rng.below(9) as f64 - 4.0;
            }
            match n % 4 {
                1 => f[rng.below(8) as usize] = 1e-12 * (rng.unit() - 0.5),
                2 => f = f.map(|v| v + 0.5 * (rng.unit() - 0.5)),
                3 if n % 1000 == 3 => f[rng.below(8) as usize] = f64::NAN,
                _ => {}
            }
            for shift_ties in [true, false] {
                let general = Refinable::of_cell_with_ties(&f, shift_ties);
                let got = Refinable::of_cell(&f, shift_ties);
                assert_eq!(
                    (got.faces, got.interior, got.shift.map(f64::to_bits)),
                    (
                        general.faces,
                        general.interior,
                        general.shift.map(f64::to_bits)
                    ),
                    "{f:?}"
                );
            }
            if let Some(r) = Refinable::without_ties(&f) {
                fast += 1;
                ambiguous_ties += (r.faces != 0b11_1111) as u32;
            }
        }
        // Both paths ran, and the shortcut met saddles at the isovalue.
        assert!(fast > 50_000 && fast < 190_000, "{fast}");
        assert!(ambiguous_ties > 100, "{ambiguous_ties}");
    }

    #[test]
    fn peaks_ridges_and_flat_faces_at_the_isovalue_stay_frozen() {
        // Corner 6 = (1, 1, 1) a peak at the isovalue: its faces may split
        // (their outline collapsed onto it), the inside may not.
        let peak = linear_cell(1.0, 1.0, 1.0, -3.0);
        let r = Refinable::of_cell(&peak, true);
        assert_eq!(r.faces, 0b11_1111);
        assert!(!r.interior);
        // A ridge: corners 2 and 6 at the isovalue, every other corner below.
        let ridge = linear_cell(1.0, 1.0, 0.0, -2.0);
        assert!(!Refinable::of_cell(&ridge, true).interior);
        // Three corners of face z = 0 at the isovalue, the fourth below.
        let mut flat = linear_cell(0.0, 0.0, 1.0, 0.0);
        flat[0] = -1.0;
        let r = Refinable::of_cell(&flat, true);
        assert_eq!(r.faces & 1 << 4, 0);
        assert!(!r.interior);
        // An ambiguous face with a corner at the isovalue: face z = 0 reads
        // 0, -1, 1, -1 around.
        let amb = [0.0, -1.0, 1.0, -1.0, 2.0, 2.0, 2.0, 2.0];
        let r = Refinable::of_cell(&amb, true);
        assert_eq!(r.faces & 1 << 4, 0);
        assert!(!r.interior);
    }

    /// A random cell (isovalue 0) and a random edge between two points of
    /// `S_K` on its grid edges, as Marching Cubes makes them.
    fn random_edge(rnd: &mut impl FnMut() -> f64) -> Option<([f64; 8], DVec3, DVec3)> {
        use crate::tables::cube::{CORNERS, EDGES};
        let c: [f64; 8] = std::array::from_fn(|_| rnd() * 2.0 - 1.0);
        let crossings: Vec<DVec3> = EDGES
            .iter()
            .filter_map(|&[a, b]| {
                let (fa, fb) = (c[a as usize], c[b as usize]);
                ((fa > 0.0) != (fb > 0.0)).then(|| {
                    let corner = |k: u8| {
                        let k = CORNERS[k as usize];
                        DVec3::new(k[0] as f64, k[1] as f64, k[2] as f64)
                    };
                    corner(a) + (corner(b) - corner(a)) * (fa / (fa - fb))
                })
            })
            .collect();
        if crossings.len() < 2 {
            return None;
        }
        let i = (rnd() * crossings.len() as f64) as usize;
        let j = (i + 1 + (rnd() * (crossings.len() - 1) as f64) as usize) % crossings.len();
        Some((c, crossings[i], crossings[j]))
    }

    #[test]
    fn pruned_bisector_scan_finds_the_root_a_full_scan_finds() {
        // Random cells and edges, and edges through random interior points
        // (planes that may miss S_K): the pruned scan returns the very
        // point the scan of every segment returns, and finds one on S_K
        // in most cases.
        let mut rnd = uniform(4242);
        let mut found = 0;
        for n in 0..3000 {
            let (c, a, b) = if n % 2 == 0 {
                match random_edge(&mut rnd) {
                    Some((c, a, b)) => (c, a, b),
                    None => continue,
                }
            } else {
                let c: [f64; 8] = std::array::from_fn(|_| rnd() * 2.0 - 1.0);
                let p = |rnd: &mut dyn FnMut() -> f64| DVec3::new(rnd(), rnd(), rnd());
                (c, p(&mut rnd), p(&mut rnd))
            };
            let (m, e) = ((a + b) * 0.5, b - a);
            let pruned = bisector_scan::<Tri, true>(&c, 0.0, m, e);
            let full = bisector_scan::<Tri, false>(&c, 0.0, m, e);
            assert_eq!(pruned.map(|r| r.to_array()), full.map(|r| r.to_array()));
            if let Some(r) = pruned {
                found += 1;
                assert!(trilinear_value(&c, r).abs() < 1e-9);
                assert!((r - m).dot(e).abs() <= 1e-9 * e.length());
            }
        }
        assert!(found > 1000, "{found}");
    }

    /// The edges [`random_edge`] makes from `tries` random cells of the
    /// seeded stream, each with the cell and its fixed axes.
    fn random_edges(seed: u64, tries: usize) -> Vec<([f64; 8], DVec3, DVec3, u8)> {
        let mut rnd = uniform(seed);
        (0..tries)
            .filter_map(|_| random_edge(&mut rnd))
            .map(|(c, a, b)| (c, a, b, shared_fixed_axes(a, b)))
            .collect()
    }

    #[test]
    fn edge_decisions_do_not_depend_on_the_order_of_the_ends() {
        // Both triangles on an edge (and both cells on a face) must split
        // it at the same point, bit for bit, or the mesh cracks.
        let mut across = 0;
        for (c, a, b, fixed) in random_edges(99, 12000) {
            let ab = sample_edge::<Tri>(&c, 0.0, a, b, fixed, 1e-3, true);
            let ba = sample_edge::<Tri>(&c, 0.0, b, a, fixed, 1e-3, true);
            assert_eq!(
                ab.split.map(|p| p.to_array().map(f64::to_bits)),
                ba.split.map(|p| p.to_array().map(f64::to_bits)),
                "edge {a} {b} of {c:?}"
            );
            let plain = sample::<Tri>(&c, 0.0, (a + b) * 0.5, fixed, 1e-3, true, (b - a).length());
            across += (plain.split != ab.split) as u32;
        }
        assert!(across > 50, "only {across} edges split across");
    }

    #[test]
    fn edges_split_across_where_the_split_point_runs_along_them() {
        // Interior edges whose gradient line misses S_K and whose nearest
        // point of S_K lies far along the edge: the point chosen instead
        // lies on S_K, strictly inside the cell, in the plane bisecting
        // the edge, and its longer child is at most BISECTOR_SLACK times
        // the nearest point's. Every other decision is the plain one.
        let (mut along, mut across) = (0, 0);
        for (c, a, b, fixed) in random_edges(2024, 20000) {
            let m = (a + b) * 0.5;
            let plain = sample::<Tri>(&c, 0.0, m, fixed, 1e-3, true, (b - a).length());
            let chosen = sample_edge::<Tri>(&c, 0.0, a, b, fixed, 1e-3, true);
            // A near midpoint splits only where the edge bulges (tested
            // below).
            assert!(
                plain.split.is_some() || chosen.split.is_none() || (fixed == 0 && !plain.failed)
            );
            let (Some(q), Some(r)) = (plain.split, chosen.split) else {
                continue;
            };
            let e = b - a;
            if fixed != 0 || !plain.failed || (q - m).dot(e).abs() <= 0.25 * e.length_squared() {
                assert_eq!(q, r, "only a failed line's far point is re-placed");
                continue;
            }
            along += 1;
            if r == q {
                continue;
            }
            across += 1;
            assert!(trilinear_value(&c, r).abs() < 1e-9, "{r} off S_K");
            assert!(longer_child(a, b, r) < BISECTOR_SLACK * longer_child(a, b, q));
            assert!((r - m).dot(e).abs() < 1e-9, "{r} off the bisecting plane");
            assert!(r.cmpgt(DVec3::ZERO).all() && r.cmplt(DVec3::ONE).all());
        }
        assert!(
            along > 30 && across > 10,
            "{along} split far along, {across} re-placed"
        );
    }

    /// The largest distance to `S_K` of the points along the segment
    /// `a b` of the one-cell volume `c`, by the independent measure of
    /// [`crate::accuracy`].
    fn edge_distance(c: &[f64; 8], a: DVec3, b: DVec3) -> f64 {
        // Samples x-fastest; VTK corner order swaps corners 2/3 and 6/7.
        let data = [c[0], c[1], c[3], c[2], c[4], c[5], c[7], c[6]];
        let v = crate::Volume::new(&data[..], [2, 2, 2]);
        let opts = crate::accuracy::MeasureOptions {
            density: 32,
            threads: 1,
            ..Default::default()
        };
        let pts = [a.to_array(), b.to_array()];
        crate::accuracy::measure(&v, 0.0, &pts, &[[0, 1, 1]], &opts)
            .unwrap()
            .max
    }

    #[test]
    fn interior_edges_near_at_the_midpoint_split_where_they_bulge() {
        // Edges between crossings of random cells: an interior edge whose
        // midpoint tests near splits only where S_K swings farther than
        // epsilon from it between the ends (measured independently), at
        // a point of S_K; kept whole, it stays near along its length (at
        // most 1.12 epsilon on these edges: distances along gradient
        // lines, and the measure's 2 % tolerance).
        let eps = 0.01;
        let (mut bulging, mut whole) = (0, 0);
        for (c, a, b, fixed) in random_edges(77, 40000) {
            let m = (a + b) * 0.5;
            let plain = sample::<Tri>(&c, 0.0, m, fixed, eps, true, (b - a).length());
            if plain.split.is_some() || plain.failed || fixed != 0 {
                continue;
            }
            let chosen = sample_edge::<Tri>(&c, 0.0, a, b, fixed, eps, true);
            let far = edge_distance(&c, a, b);
            match chosen.split {
                Some(r) => {
                    bulging += 1;
                    assert!(trilinear_value(&c, r).abs() < 1e-9, "{r} off S_K");
                    assert!(far > eps, "edge {a} {b} of {c:?} split, {far} from S_K");
                }
                None => {
                    whole += 1;
                    assert!(
                        far <= 1.25 * eps,
                        "edge {a} {b} of {c:?} kept, {far} from S_K"
                    );
                }
            }
        }
        assert!(
            bulging > 100 && whole > 100,
            "{bulging} bulging, {whole} whole"
        );
    }

    #[test]
    fn split_points_stay_within_reach_of_their_sample() {
        // Cell (33, 59, 2) of the EPI scan of the benchmark (less its
        // isovalue): one sheet of S_K hugs face x = 0, another caps corner
        // (1, 1, 0). The gradient line from a sample by the first crosses
        // the cell to the cap; splitting there stretched four triangles
        // 0.46 cells off S_K at every level.
        let c = [9.9, -43.1, 18.9, -245.1, 14.9, -130.1, -46.1, 22.9];
        let p = DVec3::new(0.001, 0.180, 0.683);
        let Test::Far(q) = test::<Tri>(&c, 0.0, p, 0, 1e-3) else {
            panic!("the line from {p} should find the far sheet");
        };
        assert!((q - p).length() > 1.0, "{q}");
        let s = sample::<Tri>(&c, 0.0, p, 0, 1e-3, true, 0.1);
        assert!(s.failed);
        assert!(s.split.is_none_or(|r| (r - p).length() <= 0.1));

        // Random cells: edges as Marching Cubes makes them, and interior
        // points with random reaches; no split point lies farther than the
        // reach, and some would have without it.
        let mut rnd = uniform(78);
        let mut beyond = 0;
        for (c, a, b, fixed) in random_edges(77, 20000) {
            let s = sample_edge::<Tri>(&c, 0.0, a, b, fixed, 1e-3, true);
            let reach = (b - a).length();
            if let Some(r) = s.split {
                assert!((r - (a + b) * 0.5).length() <= reach, "{a} {b} -> {r}");
            }
            let p = DVec3::new(rnd(), rnd(), rnd());
            let reach = 0.05 + rnd();
            let s = sample::<Tri>(&c, 0.0, p, 0, 1e-3, true, reach);
            if let Some(r) = s.split {
                assert!((r - p).length() <= reach, "{p} -> {r}, reach {reach}");
            }
            let unbounded = sample::<Tri>(&c, 0.0, p, 0, 1e-3, true, f64::INFINITY);
            beyond += unbounded.split.is_some_and(|r| (r - p).length() > reach) as u32;
        }
        assert!(beyond > 100, "only {beyond} split points beyond reach");
    }
}
