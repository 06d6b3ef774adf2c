//! The fallback of the sample test for interior samples: when the gradient
//! line through a sample point leaves its cell without meeting `S_K` (thin
//! tubes and necks, tunnels of ambiguous cells: where the surface bends
//! within one cell), the point of `S_K` in the cell nearest to the sample
//! decides instead.
//!
//! The search is a branch and bound over boxes. Starting from the cell, the
//! nearest box whose corner values straddle the isovalue is halved along
//! each axis, until the nearest such box is farther than epsilon and small
//! ([`COARSE`]) — the sample is far, and splits at a point of `S_K` found
//! there — or a point of `S_K` within epsilon turns up. For the trilinear
//! filter the straddling test is exact (a multilinear function takes its
//! extremes over a box at the box's corners, so a box that does not
//! straddle holds no point of `S_K`); for the cubic filters it is a good
//! heuristic. The point found in the last box (a root on one of its
//! edges) is then moved to the foot of the sample on `S_K` by a few
//! Gauss-Newton steps, so that nearby samples do not share it.

use std::cell::Cell;

use glam::DVec3;

use crate::filter::ReconstructionFilter;
use crate::project::{solve, Test};
use crate::tables::cube::{CORNERS, EDGES};

/// Box edge (cell units) from which a box farther than epsilon is tried
/// as the place to split: a point of `S_K` found on its edges is moved to
/// the sample's foot ([`polish`]). Where that fails (the iteration can
/// wander off to a farther sheet from a coarse box) the search halves on
/// down to [`FINE`], as every far search did until the fifty-seventh
/// session: there, on Marschner-Lobb at epsilon 0.1, a far search opened
/// about 32 boxes against 8 now, and its refinement took 137 M
/// instructions a call against 126 M (callgrind), while the distances
/// measured on Marschner-Lobb, the atoms and the tube at epsilon 0.1, 0.01
/// and 0.001 stayed as they were (max within 1e-8 cells, mean within
/// 0.1 %). From 1/4 the farthest triangle of Marschner-Lobb at 0.01 went
/// from 0.0128 to 0.0179 cells.
pub const COARSE: f64 = 1.0 / 8.0;

/// Box edge (cell units) at which a far search whose point does not move
/// to the foot gives up; also how much farther from the sample than the
/// box's point the foot may end ([`polish`]).
pub const FINE: f64 = 1.0 / 32.0;

/// Boxes examined at most per search (a safeguard; a few dozen are
/// usual).
const MAX_BOXES: usize = 4096;

/// A box of the search: lowest corner, edge length, the filter minus the
/// isovalue at its corners (VTK order, [`CORNERS`]), distance from the
/// sample.
#[derive(Clone, Copy)]
struct Cube {
    lo: DVec3,
    size: f64,
    f: [f64; 8],
    lower: f64,
}

impl Cube {
    /// Distance from `p` to the box (0 inside).
    fn distance(lo: DVec3, size: f64, p: DVec3) -> f64 {
        (lo - p)
            .max(p - (lo + DVec3::splat(size)))
            .max(DVec3::ZERO)
            .length()
    }

    fn corner(&self, k: usize) -> DVec3 {
        let c = CORNERS[k];
        self.lo + DVec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * self.size
    }
}

/// For each point `g` of a box's 3x3x3 halving grid (digits `g % 3`,
/// `g / 3 % 3`, `g / 9` in half edges), the box corner it is, if any.
const GRID_CORNER: [Option<u8>; 27] = {
    let mut t = [None; 27];
    let mut k = 0;
    while k < 8 {
        let c = CORNERS[k];
        t[2 * c[0] as usize + 6 * c[1] as usize + 18 * c[2] as usize] = Some(k as u8);
        k += 1;
    }
    t
};

/// The points of a box's 3x3x3 halving grid that are not box corners, in an
/// order where each is the midpoint of two points before it (or corners):
/// `(point, a, b)`. Points with one middle digit (edge midpoints) come
/// first, then those with two (face centres), then the centre; each is
/// halfway between its neighbours along its first middle digit's axis.
const GRID_MIDPOINTS: [(u8, u8, u8); 19] = {
    let mut t = [(0u8, 0u8, 0u8); 19];
    let mut n = 0;
    let mut middles = 1;
    while middles <= 3 {
        let mut g = 0;
        while g < 27 {
            let d = [g % 3, g / 3 % 3, g / 9];
            let count = (d[0] == 1) as usize + (d[1] == 1) as usize + (d[2] == 1) as usize;
            if count == middles {
                let axis = if d[0] == 1 {
                    0
                } else if d[1] == 1 {
                    1
                } else {
                    2
                };
                let step = [1, 3, 9][axis];
                t[n] = (g as u8, (g - step) as u8, (g + step) as u8);
                n += 1;
            }
            g += 1;
        }
        middles += 1;
    }
    t
};

/// A box's 3x3x3 halving grid of values (see [`GRID_CORNER`]) for a
/// multilinear filter, from the box's corner values `f` (VTK order): the
/// other points by means (see [`ReconstructionFilter::MULTILINEAR`]).
fn halving_grid_of_multilinear(f: &[f64; 8]) -> [f64; 27] {
    let mut grid = [0.0; 27];
    for (k, c) in CORNERS.iter().enumerate() {
        grid[2 * c[0] as usize + 6 * c[1] as usize + 18 * c[2] as usize] = f[k];
    }
    // Unrolled with constant indices (a loop over the table kept them in
    // memory and took four times as long; this runs for every box).
    macro_rules! means {
        ($($i:literal)*) => {$({
            const M: (u8, u8, u8) = GRID_MIDPOINTS[$i];
            grid[M.0 as usize] = 0.5 * (grid[M.1 as usize] + grid[M.2 as usize]);
        })*};
    }
    means!(0 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18);
    grid
}

/// For each child box (by its corner of the parent) and each of its
/// corners, the point of the parent's halving grid it is.
const CHILD_GRID: [[u8; 8]; 8] = {
    let mut t = [[0u8; 8]; 8];
    let mut child = 0;
    while child < 8 {
        let o = CORNERS[child];
        let mut k = 0;
        while k < 8 {
            let d = CORNERS[k];
            t[child][k] = (o[0] + d[0]) + 3 * (o[1] + d[1]) + 9 * (o[2] + d[2]);
            k += 1;
        }
        child += 1;
    }
    t
};

/// Whether box `b` comes before box `c` in the search: the nearer first,
/// ties broken by size (larger first) and position. A total order (no
/// two boxes of a search are equal in all of these), so the search does
/// not depend on the order boxes were queued.
#[inline]
fn before(b: &Cube, c: &Cube) -> bool {
    b.lower
        .total_cmp(&c.lower)
        .then_with(|| c.size.total_cmp(&b.size))
        .then_with(|| b.lo.x.total_cmp(&c.lo.x))
        .then_with(|| b.lo.y.total_cmp(&c.lo.y))
        .then_with(|| b.lo.z.total_cmp(&c.lo.z))
        .is_lt()
}

/// The open boxes of a search, first ([`before`]) on top: a binary heap
/// of indices into every box queued (searches that open thousands of
/// boxes, in cells where `S_K` folds tightly, stay n log n). Sifting four
/// byte indices, where a heap of the boxes' keys moved forty bytes a
/// step, took a third of the search's time.
#[derive(Default)]
struct Queue {
    heap: Vec<u32>,
    boxes: Vec<Cube>,
}

impl Queue {
    fn clear(&mut self) {
        self.heap.clear();
        self.boxes.clear();
    }

    fn push(&mut self, c: Cube) {
        let (heap, boxes) = (&mut self.heap, &mut self.boxes);
        let id = boxes.len() as u32;
        boxes.push(c);
        let mut i = heap.len();
        heap.push(id);
        while i > 0 {
            let parent = (i - 1) / 2;
            if !before(&boxes[id as usize], &boxes[heap[parent] as usize]) {
                break;
            }
            heap[i] = heap[parent];
            i = parent;
        }
        heap[i] = id;
    }

    fn pop(&mut self) -> Option<Cube> {
        let (heap, boxes) = (&mut self.heap, &self.boxes);
        let top = *heap.first()?;
        let last = heap.pop()?;
        let n = heap.len();
        if n > 0 {
            let mut i = 0;
            loop {
                let mut child = 2 * i + 1;
                if child >= n {
                    break;
                }
                if child + 1 < n
                    && before(
                        &boxes[heap[child + 1] as usize],
                        &boxes[heap[child] as usize],
                    )
                {
                    child += 1;
                }
                if !before(&boxes[heap[child] as usize], &boxes[last as usize]) {
                    break;
                }
                heap[i] = heap[child];
                i = child;
            }
            heap[i] = last;
        }
        Some(boxes[top as usize])
    }
}

/// Room for the open boxes and their values reserved up front: most
/// searches open a few dozen boxes and then never grow the buffers.
const QUEUE_CAPACITY: usize = 256;

#[inline(always)]
fn straddles(f: &[f64; 8]) -> bool {
    // The least and largest value (NaN ignored, as by the comparisons it
    // stands for): branch-free, where the early exits of `any` and its
    // sixteen tests cost twice as much.
    let (mut least, mut most) = (f64::INFINITY, f64::NEG_INFINITY);
    for &v in f {
        least = if v < least { v } else { least };
        most = if v > most { v } else { most };
    }
    least <= 0.0 && most >= 0.0
}

/// Decides the interior sample `p` (local coordinates of the cell) by the
/// nearest point of `S_K` in the cell: [`Test::Near`] when one lies within
/// `epsilon`, [`Test::Far`] with a point of `S_K` near the nearest one
/// otherwise, [`Test::Failed`] when the cell holds no point of `S_K` (by
/// the straddling test) or the search gives up. A pure function of its
/// arguments.
pub fn nearest<F: ReconstructionFilter>(cell: &F::Cell, iso: f64, p: DVec3, epsilon: f64) -> Test {
    nearest_within::<F>(cell, iso, p, epsilon, 0.0)
}

/// [`nearest`] over the cell shrunk by `margin` on every side (the box
/// `[margin, 1 - margin]^3`, local units, `0 <= margin < 0.5`): points of
/// `S_K` closer than that to a cell face are not looked at.
pub fn nearest_within<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    p: DVec3,
    epsilon: f64,
    margin: f64,
) -> Test {
    let f = |x: DVec3| F::value(cell, x) - iso;
    let (lo, size) = (DVec3::splat(margin), 1.0 - 2.0 * margin);
    let mut root = Cube {
        lo,
        size,
        f: [0.0; 8],
        lower: Cube::distance(lo, size, p),
    };
    for k in 0..8 {
        root.f[k] = f(root.corner(k));
    }
    if root.f.iter().any(|v| !v.is_finite()) || !straddles(&root.f) {
        return Test::Failed;
    }
    let mut open = QUEUE.with(|q| q.take()).unwrap_or_else(|| Queue {
        heap: Vec::with_capacity(QUEUE_CAPACITY),
        boxes: Vec::with_capacity(QUEUE_CAPACITY),
    });
    open.clear();
    let found = search::<F>(cell, iso, p, epsilon, margin, root, &mut open);
    // Kept unless a search in a tight fold grew it large.
    if open.boxes.capacity() <= 16 * QUEUE_CAPACITY {
        QUEUE.with(|q| q.set(Some(open)));
    }
    found
}

thread_local! {
    /// The last search's queue, for the next one on this thread:
    /// allocating it afresh cost as much as a few boxes.
    static QUEUE: Cell<Option<Queue>> = const { Cell::new(None) };
}

/// The branch and bound of [`nearest_within`] from its `root` box, on the
/// empty queue `open`.
#[allow(clippy::too_many_arguments)]
fn search<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    p: DVec3,
    epsilon: f64,
    margin: f64,
    root: Cube,
    open: &mut Queue,
) -> Test {
    let f = |x: DVec3| F::value(cell, x) - iso;
    open.push(root);
    let mut tried_coarse = false;
    for _ in 0..MAX_BOXES {
        let Some(b) = open.pop() else {
            break;
        };
        if b.lower > epsilon {
            // One try from a coarse box; where the iteration wanders off
            // from there (a fold of `S_K` between the box and the foot),
            // the boxes are halved on to the fine ones, as before the
            // coarse try was made.
            let fine = b.size <= FINE;
            if fine || (b.size <= COARSE && !tried_coarse) {
                tried_coarse = true;
                match edge_root::<F>(&f, &b, p).and_then(|q| polish::<F>(cell, iso, p, q, margin)) {
                    Some(x) => return Test::Far(x),
                    None if fine => return Test::Failed,
                    None => {}
                }
            }
        } else if let Some(q) = edge_root::<F>(&f, &b, p) {
            let d = (q - p).length();
            if d <= epsilon {
                return Test::Near;
            }
            // Too small to tell apart from epsilon: far, but barely.
            if b.size <= epsilon * 0.125 {
                return match polish::<F>(cell, iso, p, q, margin) {
                    Some(x) => Test::Far(x),
                    None => Test::Failed,
                };
            }
        }
        // Halve along each axis: a 3x3x3 grid of values, of which the
        // eight corners are known.
        let half = b.size * 0.5;
        let mut grid = [0.0f64; 27];
        if F::MULTILINEAR {
            grid = halving_grid_of_multilinear(&b.f);
        } else {
            for (g, value) in grid.iter_mut().enumerate() {
                *value = match GRID_CORNER[g] {
                    Some(k) => b.f[k as usize],
                    None => {
                        let d = [g % 3, g / 3 % 3, g / 9];
                        f(b.lo + DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64) * half)
                    }
                };
            }
        }
        // The children in order, unrolled with constant indices (a loop
        // over the table read them from memory, at twice the cost); most
        // do not straddle and are placed only if they do.
        macro_rules! children {
            ($($child:literal)*) => {$({
                const AT: [u8; 8] = CHILD_GRID[$child];
                const O: [u8; 3] = CORNERS[$child];
                let f = [
                    grid[AT[0] as usize],
                    grid[AT[1] as usize],
                    grid[AT[2] as usize],
                    grid[AT[3] as usize],
                    grid[AT[4] as usize],
                    grid[AT[5] as usize],
                    grid[AT[6] as usize],
                    grid[AT[7] as usize],
                ];
                if straddles(&f) {
                    let lo = b.lo + DVec3::new(O[0] as f64, O[1] as f64, O[2] as f64) * half;
                    let c = Cube {
                        lo,
                        size: half,
                        f,
                        lower: Cube::distance(lo, half, p),
                    };
                    open.push(c);
                }
            })*};
        }
        children!(0 1 2 3 4 5 6 7);
    }
    Test::Failed
}

/// Moves `q`, a point of `S_K` found by the search, to the foot of `p` on
/// `S_K` nearby: repeatedly the point nearest to `p` of the plane where the
/// filter's linearisation at the current point is zero (Gauss-Newton on
/// the distance; it converges fast where `S_K` is smooth). `None` when the
/// iteration leaves the cell, does not settle on `S_K`, or ends farther
/// from `p` than `q`: the box's edge root itself is no split point, since
/// nearby samples whose searches stop in the same box would share it (and
/// weld), and its place on a box edge can line it up exactly with other
/// points.
fn polish<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    p: DVec3,
    q: DVec3,
    margin: f64,
) -> Option<DVec3> {
    let (lo, hi) = (DVec3::splat(margin), DVec3::splat(1.0 - margin));
    let inside = |y: DVec3| y.cmpge(lo).all() && y.cmple(hi).all();
    // Within a margin the foot may lie beyond the box (on the band it
    // leaves out): steps that leave the box are clamped onto it and the
    // axes they hit held there, so the iteration finds the foot on the
    // box's face instead. (On the whole cell such a foot is on the
    // neighbour's side; those searches give up, as the doc says.)
    let clamp = margin > 0.0;
    let mut held = DVec3::ONE;
    let mut x = q;
    for _ in 0..24 {
        let (v, g) = F::value_gradient(cell, x);
        let g = g * held;
        let len2 = g.length_squared();
        if !(len2 > 0.0 && len2.is_finite()) {
            return None;
        }
        // The sample seen in the plane of the held axes.
        let target = x + (p - x) * held;
        // Half steps: where the distance is near S_K's radius of
        // curvature, full steps oscillate about the foot (and diverge
        // beyond it); half steps damp that for any ratio below 3.
        let mut y = (x + target - g * ((v - iso + g.dot(target - x)) / len2)) * 0.5;
        if clamp && !inside(y) {
            let c = y.clamp(lo, hi);
            held *= DVec3::select(c.cmpne(y), DVec3::ZERO, DVec3::ONE);
            y = c;
        }
        // A step out of the cell is shortened (the foot may lie inside
        // though a full step overshoots); one that stays out gives up.
        for _ in 0..4 {
            if inside(y) {
                break;
            }
            y = (x + y) * 0.5;
        }
        if !inside(y) {
            return None;
        }
        let step = (y - x).length();
        x = y;
        if step <= 1e-14 {
            break;
        }
    }
    // Where S_K curves strongly (radius near the distance) the iteration
    // converges slowly along S_K; the point need not be the exact foot, but
    // it must lie on S_K: Newton steps along the gradient finish.
    for _ in 0..4 {
        let (v, g) = F::value_gradient(cell, x);
        let g = g * held;
        let len2 = g.length_squared();
        if (v - iso).abs() <= 1e-12 * len2.sqrt() {
            return (inside(x) && (x - p).length() <= (q - p).length() + FINE).then_some(x);
        }
        if !(len2 > 0.0 && len2.is_finite()) {
            return None;
        }
        x -= g * ((v - iso) / len2);
    }
    None
}

/// The root of `f` nearest to `p` on the edges of box `b` whose ends
/// differ in sign (or are zero).
fn edge_root<F: ReconstructionFilter>(
    f: &impl Fn(DVec3) -> f64,
    b: &Cube,
    p: DVec3,
) -> Option<DVec3> {
    let mut best: Option<(f64, DVec3)> = None;
    for [i, j] in EDGES.map(|e| e.map(usize::from)) {
        let (fa, fb) = (b.f[i], b.f[j]);
        if (fa > 0.0 && fb > 0.0) || (fa < 0.0 && fb < 0.0) {
            continue;
        }
        let (start, end) = (b.corner(i), b.corner(j));
        let t = if F::MULTILINEAR {
            // Linear along an edge: the root is the secant's, the first
            // step of `solve` (where it stops but for rounding), without
            // evaluating the filter there.
            if fa == 0.0 {
                0.0
            } else if fb == 0.0 {
                1.0
            } else {
                -fa / (fb - fa)
            }
        } else {
            solve(&|t: f64| f(start + (end - start) * t), 0.0, fa, 1.0, fb)
        };
        let q = start + (end - start) * t;
        let d = (q - p).length_squared();
        if best.map_or(true, |(bd, _)| d < bd) {
            best = Some((d, q));
        }
    }
    best.map(|(_, q)| q)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::filter::{trilinear_value, Trilinear};

    type Tri = Trilinear<'static, f64>;

    /// A seeded stream of uniform numbers in [0, 1) (a linear
    /// congruential generator; the refinement tests use it too).
    pub(crate) fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut x = seed;
        move || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// Distance from `p` to `S_K` of the cell `c` (isovalue 0) and the
    /// point, from a dense grid of z-segments (within about 1/n).
    fn dense_nearest(c: &[f64; 8], p: DVec3, n: usize) -> (f64, DVec3) {
        dense_nearest_within(c, p, n, 0.0)
    }

    /// [`dense_nearest`] over the box `[margin, 1 - margin]^3`.
    fn dense_nearest_within(c: &[f64; 8], p: DVec3, n: usize, margin: f64) -> (f64, DVec3) {
        let mut best = (f64::INFINITY, DVec3::ZERO);
        let size = 1.0 - 2.0 * margin;
        for i in 0..=n {
            for j in 0..=n {
                for k in 0..n {
                    let a = DVec3::splat(margin)
                        + DVec3::new(i as f64, j as f64, k as f64) * (size / n as f64);
                    let b = a + DVec3::new(0.0, 0.0, size / n as f64);
                    let (fa, fb) = (trilinear_value(c, a), trilinear_value(c, b));
                    if (fa > 0.0) != (fb > 0.0) {
                        let q = a + (b - a) * (fa / (fa - fb));
                        if (q - p).length() < best.0 {
                            best = ((q - p).length(), q);
                        }
                    }
                }
            }
        }
        best
    }

    #[test]
    fn halving_grid_means_are_the_trilinear_values() {
        // Random cells and boxes: every point of the halving grid gets the
        // trilinear interpolant's value there, to rounding.
        let mut rnd = uniform(2718);
        for _ in 0..500 {
            let c: [f64; 8] = std::array::from_fn(|_| rnd() * 2.0 - 1.0);
            let size = 0.5 * rnd();
            let lo = DVec3::new(rnd(), rnd(), rnd()) * (1.0 - size);
            let at = |d: [usize; 3]| {
                lo + DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64) * (0.5 * size)
            };
            let f = std::array::from_fn(|k| {
                let q = CORNERS[k];
                trilinear_value(
                    &c,
                    at([2 * q[0] as usize, 2 * q[1] as usize, 2 * q[2] as usize]),
                )
            });
            let grid = halving_grid_of_multilinear(&f);
            for (g, v) in grid.iter().enumerate() {
                let exact = trilinear_value(&c, at([g % 3, g / 3 % 3, g / 9]));
                assert!((v - exact).abs() <= 1e-14, "point {g}: {v} vs {exact}");
            }
        }
    }

    #[test]
    fn agrees_with_a_dense_search_on_random_cells() {
        // Random cells and samples: a far answer lies on S_K, inside the
        // cell, not much farther than the nearest point of S_K; a near
        // answer has S_K within epsilon (up to the dense search's
        // resolution). Some samples whose gradient line misses S_K must be
        // rescued (the point of the fallback).
        let mut rnd = uniform(12345);
        let (mut near, mut far, mut failed, mut rescued) = (0, 0, 0, 0);
        let mut off_foot = 0;
        for _ in 0..600 {
            let c: [f64; 8] = std::array::from_fn(|_| rnd() * 2.0 - 1.0);
            let p = DVec3::new(rnd(), rnd(), rnd());
            let eps = [0.001, 0.05][(rnd() * 2.0) as usize];
            let n = 48;
            let (best, foot) = dense_nearest(&c, p, n);
            let line = crate::project::project::<Tri>(&c, 0.0, p, 0);
            match nearest::<Tri>(&c, 0.0, p, eps) {
                Test::Far(q) => {
                    far += 1;
                    rescued += line.is_none() as u32;
                    assert!(trilinear_value(&c, q).abs() < 1e-9);
                    assert!(q.cmpge(DVec3::ZERO).all() && q.cmple(DVec3::ONE).all());
                    let d = (q - p).length();
                    assert!(d > eps, "{d} <= {eps}");
                    // Within what a coarse box and the slack of `polish`
                    // allow, and mostly at the foot itself (below).
                    assert!(d <= best + COARSE * 3f64.sqrt() + FINE, "{d} vs {best}");
                    off_foot += (d > best + FINE * 3f64.sqrt()) as u32;
                    assert!(best + 1.0 / n as f64 >= eps, "{best} vs eps {eps}");
                }
                Test::Near => {
                    near += 1;
                    assert!(best <= eps + 2.0 / n as f64, "{best} vs eps {eps}");
                }
                Test::Failed => {
                    // No S_K in the cell, or its nearest point is on the
                    // cell's boundary (the foot of `p` lies outside).
                    failed += 1;
                    let edge = foot.min_element().min(1.0 - foot.max_element());
                    assert!(
                        best.is_infinite() || edge < 0.1,
                        "failed at {foot}, {best} from p"
                    );
                }
            }
        }
        assert!(
            near > 20 && far > 300 && rescued > 5,
            "{near} near, {far} far, {failed} failed, {rescued} rescued"
        );
        assert!(
            off_foot * 50 <= far,
            "{off_foot} of {far} far answers off the foot"
        );
    }

    #[test]
    fn within_a_margin_finds_the_nearest_point_off_the_faces() {
        // Samples whose nearest point of S_K lies on (or next to) a cell
        // face: with a margin the answer stays in the shrunken box, on
        // S_K, and is about as near as the box's nearest point of S_K (a
        // dense search over the box) — also where the foot in the whole
        // cell lies on a face and the plain search gives up.
        let mut rnd = uniform(777);
        let margin = 1.0 / 64.0;
        let (lo, hi) = (DVec3::splat(margin), DVec3::splat(1.0 - margin));
        let (mut far, mut on_band, mut rescued) = (0, 0, 0);
        for _ in 0..600 {
            // S_K hugging the face z = 0: the upper corners well outside.
            let mut c: [f64; 8] = std::array::from_fn(|_| rnd() * 2.0 - 1.0);
            for v in &mut c[4..] {
                *v = -1.0 - rnd();
            }
            let p = DVec3::new(rnd(), rnd(), 0.2 + 0.6 * rnd());
            let (best, _) = dense_nearest_within(&c, p, 48, margin);
            if let Test::Far(q) = nearest_within::<Tri>(&c, 0.0, p, 1e-3, margin) {
                far += 1;
                assert!(trilinear_value(&c, q).abs() < 1e-9, "{q} off S_K");
                assert!(q.cmpge(lo).all() && q.cmple(hi).all(), "{q} in the band");
                let d = (q - p).length();
                assert!(d <= best + FINE * 3f64.sqrt(), "{d} vs {best}");
                on_band += (q.z - margin < 1e-12) as u32;
                rescued += matches!(nearest::<Tri>(&c, 0.0, p, 1e-3), Test::Failed) as u32;
            }
        }
        assert!(
            far > 200 && on_band > 20 && rescued > 20,
            "{far} far, {on_band} on the band's face, {rescued} rescued"
        );
    }
}
