//! Triangulating a cell with the topology of its trilinear interpolant.
//!
//! Instead of the 33 hand-made configurations of Marching Cubes 33, the
//! topology is derived from the function itself, in four steps. Write
//! `P = {F >= iso}` and `N = {F < iso}` inside the cell.
//!
//! 1. **Faces.** On a face `F` is bilinear; an ambiguous face (diagonal
//!    corners agree, adjacent ones differ) joins its inside corners iff its
//!    saddle value is `>= iso` (the asymptotic decider). With `f = s - iso`
//!    and inside diagonal `(p, q)`, outside diagonal `(m, n)`, that is
//!    `f_p f_q >= f_m f_n`: products of the same two numbers, so both cells
//!    sharing the face decide identically. Each face then contributes 0, 1
//!    or 2 segments between its edge crossings; chained, they form closed
//!    *loops* on the cell's boundary.
//! 2. **Regions on the boundary.** A union-find over the 8 corners joins
//!    corners along edges of one sign and across ambiguous faces as decided
//!    in step 1: each class is one region of `P` or `N` on the boundary.
//! 3. **Connections through the interior.** A trilinear function has no
//!    interior extremum, so every component of `P` (or `N`) reaches the
//!    boundary, and within every slice `z = t` every component of the
//!    bilinear slice function reaches the slice's border. Sweeping `t` from
//!    0 to 1, two boundary regions are joined through the interior exactly
//!    when some slice joins them. A slice joins regions not already joined
//!    on the boundary only when it is ambiguous, and its connectivity can
//!    change only where a vertical edge crosses `iso` or where its saddle
//!    value equals `iso` (the roots of a quadratic in `t`, which are the
//!    heights of the body saddles, Natarajan's criterion). One slice
//!    between consecutive events therefore tells everything.
//! 4. **Surface components.** In a ball, each surface component separates
//!    one region of `P` from one region of `N`, and two regions share at
//!    most one component. So loops whose (P region, N region) pair is the
//!    same bound the same component: one loop is a disk (a fan), two loops
//!    are a tube (the tunnels of MC33 cases 4, 6, 7, 10, 12 and 13), which
//!    is stitched between the two loops. Three or more loops cannot occur
//!    for a trilinear function except in degenerate data; each is then
//!    closed as a disk.
//!
//! Loops are oriented so that fans wind like `vtkMarchingCubes` (normals
//! towards lower values); the tube is stitched with the same orientation.

use std::cell::UnsafeCell;
use std::mem::MaybeUninit;
use std::sync::atomic::{AtomicU8, Ordering};

use crate::tables::cube::{
    on_one_face, AMBIGUOUS_FACES, CORNERS, EDGES, FACES, FACE_EDGES, VERTEX_FACES,
};

/// Disjoint sets of `N` small ids (`N <= 256`): a cell's corners here, a
/// patch's points in [`super::topology_check`].
pub(super) struct UnionFind<const N: usize>([u8; N]);

impl<const N: usize> UnionFind<N> {
    pub(super) fn new() -> Self {
        UnionFind(std::array::from_fn(|k| k as u8))
    }
    pub(super) fn find(&mut self, mut a: u8) -> u8 {
        while self.0[a as usize] != a {
            let p = self.0[a as usize];
            self.0[a as usize] = self.0[p as usize];
            a = p;
        }
        a
    }
    pub(super) fn union(&mut self, a: u8, b: u8) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            // Keep the smaller root: deterministic classes.
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.0[hi as usize] = lo;
        }
    }
}

fn edge_midpoint(e: u8) -> [f64; 3] {
    let [a, b] = EDGES[e as usize];
    let (pa, pb) = (CORNERS[a as usize], CORNERS[b as usize]);
    [
        (pa[0] + pb[0]) as f64 * 0.5,
        (pa[1] + pb[1]) as f64 * 0.5,
        (pa[2] + pb[2]) as f64 * 0.5,
    ]
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    let d = sub(a, b);
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// Position of the crossing on edge `e` in local coordinates.
fn crossing(f: &[f64; 8], e: u8) -> [f64; 3] {
    let [a, b] = EDGES[e as usize];
    let (fa, fb) = (f[a as usize], f[b as usize]);
    // (No overflow: `triangles` works on values within 2^1000.)
    let t = if fb != fa { -fa / (fb - fa) } else { 0.5 };
    let (pa, pb) = (CORNERS[a as usize], CORNERS[b as usize]);
    let mut p = [0.0; 3];
    for k in 0..3 {
        p[k] = pa[k] as f64 + t * (pb[k] as f64 - pa[k] as f64);
    }
    p
}

/// Whether the bilinear function with corner values `g` (cyclic order,
/// alternating signs) joins its inside corners. The products are taken of
/// the values brought into [`product_range`] (the signs of the values as
/// given), so that the answer does not change when the data is scaled
/// (taken as given, on values below about 1e-154 both products underflow
/// to 0 and every face joins its inside corners). The scale depends on
/// the face's four values alone: both cells sharing it still agree.
#[inline]
fn joins_inside(g: [f64; 4]) -> bool {
    let s = product_range(g);
    if g[0] >= 0.0 {
        s[0] * s[2] >= s[1] * s[3]
    } else {
        s[1] * s[3] >= s[0] * s[2]
    }
}

/// `v` times a power of two that brings its largest magnitude within
/// 2^-200..2^200, where products of up to four of them (a discriminant)
/// neither overflow nor underflow to 0; `v` itself when it lies there
/// already (then nothing changes), or holds a non-finite value. The
/// scaling is exact, so comparisons and roots of such products keep their
/// answer; a value too small beside the largest one to matter may be
/// flushed to 0 (only magnitudes may be used, not signs).
#[inline]
fn product_range<const N: usize>(v: [f64; N]) -> [f64; N] {
    const UP: f64 = 1.6069380442589903e60; // 2^200
    const DOWN: f64 = 6.223015277861142e-61; // 2^-200
    let mut m = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if !(m > 0.0 && m.is_finite()) || (DOWN..=UP).contains(&m) {
        return v;
    }
    let mut s = 1.0;
    while m < DOWN {
        m *= UP;
        s *= UP;
    }
    while m > UP {
        m *= DOWN;
        s *= DOWN;
    }
    v.map(|x| x * s)
}

/// Per-face result of the asymptotic decider: `Some(true)` when an
/// ambiguous face joins its inside corners, `Some(false)` when it joins
/// its outside corners, `None` for unambiguous faces.
pub fn face_decisions(f: &[f64; 8]) -> [Option<bool>; 6] {
    decisions_of_case(super::case_index(f), f)
}

/// [`face_decisions`] of a cell whose case index the caller has.
#[inline]
fn decisions_of_case(case: u8, f: &[f64; 8]) -> [Option<bool>; 6] {
    let mut out = [None; 6];
    let mut faces = AMBIGUOUS_FACES[case as usize];
    while faces != 0 {
        let k = faces.trailing_zeros() as usize;
        faces &= faces - 1;
        let c = FACES[k].2;
        let g = [
            f[c[0] as usize],
            f[c[1] as usize],
            f[c[2] as usize],
            f[c[3] as usize],
        ];
        out[k] = Some(joins_inside(g));
    }
    out
}

/// A cell's boundary loops: cyclic lists of edges, packed one after the
/// other (each edge is in at most one loop, so twelve slots suffice and
/// there are at most four loops of at least three edges).
#[derive(Debug, Clone, Copy)]
pub struct Loops {
    edges: [u8; 12],
    /// Loop `k` is `edges[ends[k]..ends[k + 1]]`.
    ends: [u8; 5],
    count: u8,
}

impl Loops {
    /// How many loops there are.
    pub fn len(&self) -> usize {
        self.count as usize
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// Loop `k`'s edges in order.
    ///
    /// # Panics
    ///
    /// When `k` is not below [`Loops::len`] (`k` up to 3 may return an
    /// empty slice instead; do not rely on it).
    pub fn get(&self, k: usize) -> &[u8] {
        &self.edges[self.ends[k] as usize..self.ends[k + 1] as usize]
    }
}

/// Boundary loops of the cell's isosurface, as cyclic lists of edges,
/// oriented like `vtkMarchingCubes`'s triangles, for any face decisions
/// (`None`: the face's segments join inside; see [`face_decisions`]).
pub fn loops(f: &[f64; 8], decisions: &[Option<bool>; 6]) -> Loops {
    find_loops(f, decisions)
}

/// What an ambiguous cell's patch needs that depends on its sign pattern
/// and face decisions alone (a face is ambiguous or not by the sign
/// pattern, so one bit a face, "joins inside", tells the decisions apart):
/// worked out when a cell first meets them, then shared (finding the loops
/// alone was a good part of an ambiguous cell's cost).
#[derive(Clone, Copy)]
struct Plan {
    /// The boundary loops ([`loops`]).
    loops: Loops,
    /// Each corner's region on the cell's boundary (step 2), named by its
    /// smallest corner, as [`UnionFind::find`] names classes.
    roots: [u8; 8],
    /// Per loop, where its fan starts ([`fan_start`]).
    fans: [u8; 4],
}

/// A [`Plan`] kept for later cells: `state` says whether `plan` holds it.
struct PlanSlot {
    state: AtomicU8,
    plan: UnsafeCell<MaybeUninit<Plan>>,
}

/// [`PlanSlot::state`]: nothing yet, being written, ready to read.
const EMPTY: u8 = 0;
const WRITING: u8 = 1;
const READY: u8 = 2;

// SAFETY: `plan` is written once, by the one thread that moved `state`
// from EMPTY to WRITING, and read only after that thread stored READY
// (release / acquire); it never changes after.
unsafe impl Sync for PlanSlot {}

/// The plan of each sign pattern and its faces' decisions (bits 0-7 the
/// case index, bit `8 + k` set when face `k` joins its inside corners),
/// kept as cells meet them: about 0.5 MiB of zeroed memory, of which a
/// volume touches the pages of the patterns it holds. Nothing waits on a
/// slot: a cell that finds its slot being written works its plan out
/// itself (the same plan), so a child made by `fork` while another thread
/// wrote one (left WRITING for good) is only slower on that pattern,
/// where a lock or a `OnceLock` would have hung it.
static PLANS: [PlanSlot; 1 << 14] = [const {
    PlanSlot {
        state: AtomicU8::new(EMPTY),
        plan: UnsafeCell::new(MaybeUninit::uninit()),
    }
}; 1 << 14];

/// The slot in [`PLANS`] of a sign pattern and its face decisions.
fn plan_key(case: u8, decisions: &[Option<bool>; 6]) -> usize {
    let mut key = case as usize;
    for (k, d) in decisions.iter().enumerate() {
        if *d == Some(true) {
            key |= 1 << (8 + k);
        }
    }
    key
}

/// The [`Plan`] of a cell, under its own face decisions
/// ([`face_decisions`]). Only these decisions are planned for: others
/// (the public [`loops`] takes any) would share a key with a different
/// answer.
fn planned(case: u8, f: &[f64; 8]) -> Plan {
    let decisions = decisions_of_case(case, f);
    let slot = &PLANS[plan_key(case, &decisions)];
    if slot.state.load(Ordering::Acquire) == READY {
        // SAFETY: READY was stored (release) after the plan was written,
        // and the plan is never written again (see `PlanSlot`).
        return unsafe { (*slot.plan.get()).assume_init() };
    }
    let plan = make_plan(f, &decisions);
    if slot
        .state
        .compare_exchange(EMPTY, WRITING, Ordering::Acquire, Ordering::Relaxed)
        .is_ok()
    {
        // SAFETY: this thread alone moved the slot to WRITING; no reader
        // looks at the plan before READY.
        unsafe { (*slot.plan.get()).write(plan) };
        slot.state.store(READY, Ordering::Release);
    }
    plan
}

/// A cell's [`Plan`] from scratch.
fn make_plan(f: &[f64; 8], decisions: &[Option<bool>; 6]) -> Plan {
    let loops = find_loops(f, decisions);
    let mut uf = boundary_regions(f, decisions);
    let mut fans = [NO_FAN; 4];
    for (k, fan) in fans.iter_mut().enumerate().take(loops.len()) {
        *fan = fan_start(loops.get(k));
    }
    Plan {
        loops,
        roots: std::array::from_fn(|c| uf.find(c as u8)),
        fans,
    }
}

/// [`loops`] from scratch.
fn find_loops(f: &[f64; 8], decisions: &[Option<bool>; 6]) -> Loops {
    let inside = |c: u8| f[c as usize] >= 0.0;
    let mut next = [u8::MAX; 12];
    for (k, (axis, val, c)) in FACES.iter().enumerate() {
        let mut normal = [0.0; 3];
        normal[*axis as usize] = if *val == 0 { -1.0 } else { 1.0 };
        let fe = FACE_EDGES[k];
        // (Fixed arrays: this runs for every ambiguous cell.)
        let mut crossed = [0usize; 4];
        let mut n_crossed = 0;
        for i in 0..4 {
            if inside(c[i]) != inside(c[(i + 1) % 4]) {
                crossed[n_crossed] = i;
                n_crossed += 1;
            }
        }
        let mut segments = [(0u8, 0u8, [0.0f64; 3]); 4];
        let mut n_segments = 0;
        let mut push = |seg: (u8, u8, [f64; 3])| {
            segments[n_segments] = seg;
            n_segments += 1;
        };
        match n_crossed {
            2 => {
                let mut r = [0.0; 3];
                let mut n = 0.0;
                for &cc in c {
                    if inside(cc) {
                        let p = CORNERS[cc as usize];
                        for a in 0..3 {
                            r[a] += p[a] as f64;
                        }
                        n += 1.0;
                    }
                }
                for v in &mut r {
                    *v /= n;
                }
                push((fe[crossed[0]], fe[crossed[1]], r));
            }
            4 => {
                let join_in = decisions[k].unwrap_or(true);
                let mut centre = [0.0; 3];
                for &cc in c {
                    let p = CORNERS[cc as usize];
                    for a in 0..3 {
                        centre[a] += p[a] as f64 * 0.25;
                    }
                }
                for i in 0..4 {
                    // Cut off corner i when it is on the side that is not joined.
                    if inside(c[i]) != join_in {
                        let ea = fe[(i + 3) % 4];
                        let eb = fe[i];
                        let r = if join_in {
                            centre
                        } else {
                            let p = CORNERS[c[i] as usize];
                            [p[0] as f64, p[1] as f64, p[2] as f64]
                        };
                        push((ea, eb, r));
                    }
                }
            }
            _ => {}
        }
        for &(ea, eb, r) in &segments[..n_segments] {
            let (ma, mb) = (edge_midpoint(ea), edge_midpoint(eb));
            let cr = cross(sub(mb, ma), sub(r, ma));
            let d = normal[0] * cr[0] + normal[1] * cr[1] + normal[2] * cr[2];
            // Inside on the right seen from outside: the winding of VTK.
            if d < 0.0 {
                next[ea as usize] = eb;
            } else {
                next[eb as usize] = ea;
            }
        }
    }
    let mut seen = [false; 12];
    let mut out = Loops {
        edges: [0; 12],
        ends: [0; 5],
        count: 0,
    };
    let mut len = 0;
    for start in 0..12u8 {
        if next[start as usize] == u8::MAX || seen[start as usize] {
            continue;
        }
        let first = len;
        let mut e = start;
        while e != u8::MAX && !seen[e as usize] {
            seen[e as usize] = true;
            out.edges[len] = e;
            len += 1;
            e = next[e as usize];
        }
        if len - first >= 3 {
            out.count += 1;
            out.ends[out.count as usize] = len as u8;
        } else {
            // Too short to bound anything (degenerate data): dropped.
            len = first;
        }
    }
    out
}

/// Union-find classes of corners: regions of `P` and `N` joined on the
/// boundary and through the interior (steps 2 and 3).
#[cfg(test)]
fn regions(f: &[f64; 8], decisions: &[Option<bool>; 6]) -> UnionFind<8> {
    let mut uf = boundary_regions(f, decisions);
    join_through_interior(f, &mut uf);
    uf
}

/// The regions of `P` and `N` on the cell's boundary (step 2): corners
/// joined along edges of one sign and across ambiguous faces as decided.
fn boundary_regions(f: &[f64; 8], decisions: &[Option<bool>; 6]) -> UnionFind<8> {
    let inside = |c: usize| f[c] >= 0.0;
    let mut uf = UnionFind::new();
    for [a, b] in EDGES {
        if inside(a as usize) == inside(b as usize) {
            uf.union(a, b);
        }
    }
    for (k, (_, _, c)) in FACES.iter().enumerate() {
        if let Some(join_in) = decisions[k] {
            let (d0, d1) = ((c[0], c[2]), (c[1], c[3]));
            let in_diag = if inside(c[0] as usize) { d0 } else { d1 };
            let out_diag = if inside(c[0] as usize) { d1 } else { d0 };
            let (a, b) = if join_in { in_diag } else { out_diag };
            uf.union(a, b);
        }
    }
    uf
}

/// Joins the boundary regions of `uf` that the cell's interior connects
/// (step 3), by a sweep along z.
fn join_through_interior(f: &[f64; 8], uf: &mut UnionFind<8>) {
    // Sweep z: slice corner j (cyclic 0..4) runs from corner j to j + 4.
    let a = [f[0], f[1], f[2], f[3]];
    let b = [f[4] - f[0], f[5] - f[1], f[6] - f[2], f[7] - f[3]];
    // At most 0, 1, four edge crossings and two saddle heights.
    let mut buf = [0.0f64; 8];
    buf[1] = 1.0;
    let mut n_events = 2;
    for j in 0..4 {
        if (f[j] >= 0.0) != (f[j + 4] >= 0.0) {
            buf[n_events] = f[j] / (f[j] - f[j + 4]);
            n_events += 1;
        }
    }
    let (roots, n_roots) = saddle_heights(a, b);
    for &r in &roots[..n_roots] {
        if r > 0.0 && r < 1.0 {
            buf[n_events] = r;
            n_events += 1;
        }
    }
    // Insertion sort: eight values at most, where a general sort's set-up
    // cost more than the sorting.
    for i in 1..n_events {
        let mut j = i;
        while j > 0 && buf[j - 1].total_cmp(&buf[j]).is_gt() {
            buf.swap(j - 1, j);
            j -= 1;
        }
    }
    let events = &buf[..n_events];
    for w in events.windows(2) {
        if w[1] <= w[0] {
            continue;
        }
        let t = 0.5 * (w[0] + w[1]);
        let g = [
            (1.0 - t) * f[0] + t * f[4],
            (1.0 - t) * f[1] + t * f[5],
            (1.0 - t) * f[2] + t * f[6],
            (1.0 - t) * f[3] + t * f[7],
        ];
        let s = [g[0] >= 0.0, g[1] >= 0.0, g[2] >= 0.0, g[3] >= 0.0];
        if !(s[0] == s[2] && s[1] == s[3] && s[0] != s[1]) {
            continue;
        }
        let join_in = joins_inside(g);
        let (p, q) = if s[0] == join_in {
            (0usize, 2usize)
        } else {
            (1, 3)
        };
        // The slice point on vertical edge j joins, along that edge, the
        // end of the same sign.
        let end = |j: usize| -> u8 {
            if (f[j] >= 0.0) == join_in {
                j as u8
            } else {
                (j + 4) as u8
            }
        };
        uf.union(end(p), end(q));
    }
}

/// Heights `t` along a sweep axis where the slice across it has its
/// saddle on the isovalue: the slice's corner values, in cyclic order, are
/// `a + t b` (a bilinear face's saddle value is zero exactly when its
/// diagonal products agree, `g0 g2 = g1 g3`, a quadratic in `t`). Any real
/// roots; the callers keep those in (0, 1).
fn saddle_heights(a: [f64; 4], b: [f64; 4]) -> ([f64; 2], usize) {
    // Both scaled alike (the roots do not change), so that the products
    // do not underflow on tiny data ([`product_range`]).
    let ab = product_range([a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]]);
    let (a, b) = ([ab[0], ab[1], ab[2], ab[3]], [ab[4], ab[5], ab[6], ab[7]]);
    let qa = b[0] * b[2] - b[1] * b[3];
    let qb = a[0] * b[2] + a[2] * b[0] - a[1] * b[3] - a[3] * b[1];
    let qc = a[0] * a[2] - a[1] * a[3];
    quadratic_roots(qa, qb, qc)
}

/// Real roots of `a t^2 + b t + c` (any that exist; degenerate cases give
/// the linear root or none), and how many there are.
fn quadratic_roots(a: f64, b: f64, c: f64) -> ([f64; 2], usize) {
    let scale = a.abs().max(b.abs()).max(c.abs());
    if scale == 0.0 || !scale.is_finite() {
        return ([0.0; 2], 0);
    }
    if a.abs() <= 1e-14 * scale {
        return if b != 0.0 {
            ([-c / b, 0.0], 1)
        } else {
            ([0.0; 2], 0)
        };
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return ([0.0; 2], 0);
    }
    let s = disc.sqrt();
    // Numerically stable pair.
    let q = -0.5 * (b + b.signum() * s);
    if q != 0.0 {
        ([q / a, c / q], 2)
    } else {
        ([q / a, 0.0], 1)
    }
}

/// Appends the triangles of an ambiguous cell (see the module docs).
///
/// Vertex ids 0..12 are cell edges; id `12 + k` is the interior point
/// `extra[k]` (local coordinates), added where a fan would lay a triangle
/// flat in a cell face. With `pinch`, such a fan may be centred at a pinch
/// point of `S_K` instead (see `fan_centre`; for refinement, which
/// cannot mend a fan laid across the solid). Nothing for a cell with a NaN
/// or infinite corner: the trilinear function means nothing there.
pub fn triangles(f: &[f64; 8], pinch: bool, out: &mut Vec<[u8; 3]>, extra: &mut Vec<[f64; 3]>) {
    if !f.iter().all(|v| v.is_finite()) {
        return;
    }
    let lowered;
    let f = match with_headroom(f) {
        Some(g) => {
            lowered = g;
            &lowered
        }
        None => f,
    };
    let plan = planned(super::case_index(f), f);
    let loops = &plan.loops;
    match loops.len() {
        0 => return,
        // One loop is one disk, whatever the regions.
        1 => return disk(f, loops.get(0), plan.fans[0], pinch, out, extra),
        _ => {}
    }
    let mut uf = UnionFind(plan.roots);
    join_through_interior(f, &mut uf);
    // Group loops by (inside region, outside region). A loop has at least
    // three of the twelve edges, so there are at most four.
    let mut keys = [(0u8, 0u8); 4];
    for (k, key) in keys.iter_mut().enumerate().take(loops.len()) {
        let [a, b] = EDGES[loops.get(k)[0] as usize];
        let (i, o) = if f[a as usize] >= 0.0 { (a, b) } else { (b, a) };
        *key = (uf.find(i), uf.find(o));
    }
    let mut done = [false; 4];
    for i in 0..loops.len() {
        if done[i] {
            continue;
        }
        let mut group = [0usize; 4];
        let mut n = 0;
        for j in i..loops.len() {
            if keys[j] == keys[i] {
                group[n] = j;
                n += 1;
                done[j] = true;
            }
        }
        if n == 2 {
            stitch(f, loops.get(group[0]), loops.get(group[1]), out);
        } else {
            for &j in &group[..n] {
                disk(f, loops.get(j), plan.fans[j], pinch, out, extra);
            }
        }
    }
}

/// Values beyond this magnitude are brought down by [`HEADROOM_SCALE`]
/// before a cell's patch is worked out (see [`with_headroom`]).
const HEADROOM_LIMIT: f64 = 8.98846567431158e299; // 2^1000

/// An exact power of two, 2^-24.
const HEADROOM_SCALE: f64 = 5.960464477539063e-8;

/// `f` times [`HEADROOM_SCALE`] when some value exceeds
/// [`HEADROOM_LIMIT`], else `None`. Differences of values near
/// `f64::MAX` overflow (the slices' value changes of
/// [`join_through_interior`], the edges' [`crossing`]s, the gradients of
/// [`interior_point`]): a cell of
/// such values got the topology of other data. Scaling by a power of two
/// changes no crossing, decision or root; a value that the scaling would
/// round to zero keeps its sign as the least subnormal of that sign (its
/// corner's side must not change).
fn with_headroom(f: &[f64; 8]) -> Option<[f64; 8]> {
    if f.iter().all(|v| v.abs() <= HEADROOM_LIMIT) {
        return None;
    }
    Some(scaled_keeping_signs(f, [HEADROOM_SCALE, 1.0]))
}

/// `f` times the product of `factors` (powers of two), a value the scaling
/// rounds to zero kept as the least subnormal of its sign (its corner's
/// side must not change).
fn scaled_keeping_signs(f: &[f64; 8], [a, b]: [f64; 2]) -> [f64; 8] {
    f.map(|v| {
        let w = v * a * b;
        if w == 0.0 && v != 0.0 {
            f64::from_bits(1).copysign(v)
        } else {
            w
        }
    })
}

/// `f` times a power of two that brings its largest magnitude into
/// `[1, 2)`, when that magnitude lies outside `[2^-256, 2^256]` (and is not
/// 0); else `f` itself. For a fan's interior vertex only, which no other
/// cell shares: squares of values beyond about 1e154 or below about 1e-160
/// overflow or underflow (the gradient's length where [`interior_point`]
/// projects), and the vertex took the fallback's point, a tenth of a cell
/// away. (Not for the patch's decisions: a value the scaling rounds to
/// zero would decide a shared face unlike the cell across it, whose
/// largest value differs.)
fn unit_scaled(f: &[f64; 8]) -> [f64; 8] {
    let m = f.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if !crate::magnitude::out_of_range(m) {
        return *f;
    }
    scaled_keeping_signs(f, crate::magnitude::factors(m))
}

/// Whether two cell edges lie on a common face (a diagonal between their
/// crossings would lie flat in that face, where the neighbouring cell's
/// patch has its boundary).
fn share_face(a: u8, b: u8) -> bool {
    VERTEX_FACES[a as usize] & VERTEX_FACES[b as usize] != 0
}

/// [`fan_start`] when a loop has none.
const NO_FAN: u8 = u8::MAX;

/// The first position of loop `l` whose diagonals to the loop's other
/// vertices all cross the cell's interior (none lies flat in a face, where
/// the neighbouring cell's patch has its boundary), or [`NO_FAN`].
fn fan_start(l: &[u8]) -> u8 {
    let n = l.len();
    (0..n)
        .find(|&s| (2..n - 1).all(|k| !share_face(l[s], l[(s + k) % n])))
        .map_or(NO_FAN, |s| s as u8)
}

/// A disk: a fan from loop position `fan` ([`fan_start`] of `l`), else
/// (`NO_FAN`) a fan around an interior vertex on the surface (with
/// `pinch`, see [`fan_centre`]).
fn disk(
    f: &[f64; 8],
    l: &[u8],
    fan: u8,
    pinch: bool,
    out: &mut Vec<[u8; 3]>,
    extra: &mut Vec<[f64; 3]>,
) {
    let n = l.len();
    if fan != NO_FAN {
        let s = fan as usize;
        for k in 1..n - 1 {
            out.push([l[s], l[(s + k) % n], l[(s + k + 1) % n]]);
        }
        return;
    }
    let c = 12 + extra.len() as u8;
    let g = unit_scaled(f);
    let centre = if pinch {
        fan_centre(&g, l)
    } else {
        interior_point(&g, l)
    };
    // Inside the cell, where it is computed to lie but for rounding: with
    // values of wildly different magnitudes (1e299 beside 1e-301) the
    // projection or its fallback root came out a rounding beyond a face
    // (z = -5.6e-17), a point outside the volume when that face bounds it.
    extra.push(centre.map(|x| x.clamp(0.0, 1.0)));
    for k in 0..n {
        out.push([c, l[k], l[(k + 1) % n]]);
    }
}

/// Where a fan over loop `l` takes its interior vertex: [`interior_point`]
/// unless some triangle of its fan faces against `S_K`, else whichever of
/// the cell's *pinch points* gives the fan that faces best (see
/// [`fan_facing`] and [`pinch_points`]).
///
/// A loop can bound a surface of two sheets joined by a narrow bridge
/// (where the inside region pinches off towards a corner barely above the
/// isovalue): the centroid's projection lands on one sheet and the spokes
/// to the other sheet's crossings cut across the solid. Refinement cannot
/// bring such triangles onto `S_K` (their split points fall on the other
/// sheet at every level, and the middle child stays as large as its
/// parent): on the trefoil tube a level-10 triangle stayed 0.40 cells
/// away. A centre at the bridge's waist makes every spoke follow a sheet.
fn fan_centre(f: &[f64; 8], l: &[u8]) -> [f64; 3] {
    use glam::DVec3;
    let first = DVec3::from_array(interior_point(f, l));
    let (points, n) = pinch_points(f);
    if n == 0 {
        return first.to_array();
    }
    let mut best = (fan_facing(f, first, l), first);
    if best.0 <= 0.0 {
        return first.to_array();
    }
    for &p in &points[..n] {
        let score = fan_facing(f, p, l);
        if score < best.0 {
            best = (score, p);
        }
    }
    best.1.to_array()
}

/// The points of `S_K` strictly inside the cell where a slice across one
/// axis has its saddle on the isovalue: there the slice's section of
/// `S_K` is two crossing lines, the waist of a bridge between two sheets
/// (the same heights as the body-saddle events of the region sweep, here
/// along all three axes). At most two per axis; exact up to rounding.
fn pinch_points(f: &[f64; 8]) -> ([glam::DVec3; 6], usize) {
    use glam::DVec3;
    let value = |p: [u8; 3]| {
        let k = CORNERS.iter().position(|c| *c == p).unwrap();
        f[k]
    };
    let mut out = [DVec3::ZERO; 6];
    let mut n = 0;
    for axis in 0..3 {
        let (ua, va) = ((axis + 1) % 3, (axis + 2) % 3);
        // Slice corners in cyclic order over (u, v): values at the slice's
        // foot (a) and their change across the cell (b).
        let (mut a, mut b) = ([0.0f64; 4], [0.0f64; 4]);
        for (i, (u, v)) in [(0u8, 0u8), (1, 0), (1, 1), (0, 1)].into_iter().enumerate() {
            let mut p = [0u8; 3];
            p[ua] = u;
            p[va] = v;
            a[i] = value(p);
            p[axis] = 1;
            b[i] = value(p) - a[i];
        }
        let (roots, n_roots) = saddle_heights(a, b);
        for &t in &roots[..n_roots] {
            if !(t > 0.0 && t < 1.0) {
                continue;
            }
            let g: [f64; 4] = std::array::from_fn(|i| a[i] + t * b[i]);
            let d = g[0] - g[1] + g[2] - g[3];
            if d == 0.0 {
                continue;
            }
            let (u, v) = ((g[0] - g[3]) / d, (g[0] - g[1]) / d);
            if u > 0.0 && u < 1.0 && v > 0.0 && v < 1.0 {
                let mut p = DVec3::ZERO;
                p[axis] = t;
                p[ua] = u;
                p[va] = v;
                out[n] = p;
                n += 1;
            }
        }
    }
    (out, n)
}

/// How badly the fan around `c` over loop `l` faces: the largest cosine
/// between a fan triangle's normal and the gradient of the interpolant at
/// its corners and centroid. The fan's triangles point their normals
/// against the gradient where they follow `S_K` (-1 at best); a positive
/// value means some triangle crosses to a part of `S_K` facing the other
/// way.
fn fan_facing(f: &[f64; 8], c: glam::DVec3, l: &[u8]) -> f64 {
    use glam::DVec3;
    let mut worst = -1.0f64;
    let n = l.len();
    for k in 0..n {
        let a = DVec3::from_array(crossing(f, l[k]));
        let b = DVec3::from_array(crossing(f, l[(k + 1) % n]));
        let normal = (a - c).cross(b - c);
        let nl = normal.length();
        // A triangle without area (or NaN) faces no way: worst.
        if nl.is_nan() || nl <= 0.0 {
            return 1.0;
        }
        for q in [c, a, b, (a + b + c) / 3.0] {
            let g = crate::filter::trilinear_gradient(f, q);
            let gl = g.length();
            if gl > 0.0 {
                worst = worst.max(normal.dot(g) / (nl * gl));
            }
        }
    }
    worst
}

/// The centroid of a loop's crossings, moved onto the surface: along the
/// gradient line inside the cell when that finds a root, else to the
/// nearest root on the segments from the centroid to the corners of the
/// other sign (one always exists: the loop separates inside corners from
/// outside ones), so the point is always on `S_K`.
fn interior_point(f: &[f64; 8], l: &[u8]) -> [f64; 3] {
    use crate::filter::{trilinear_line_cubic, trilinear_value_gradient, Trilinear};
    use glam::DVec3;
    let mut c = DVec3::ZERO;
    for &e in l {
        c += DVec3::from_array(crossing(f, e)) / l.len() as f64;
    }
    if let Some(pr) = crate::project::project::<Trilinear<'static, f64>>(f, 0.0, c, 0) {
        return pr.point.to_array();
    }
    let (fc, g) = trilinear_value_gradient(f, c);
    let mut best: Option<(f64, DVec3)> = None;
    for (k, corner) in CORNERS.iter().enumerate() {
        if (f[k] >= 0.0) == (fc >= 0.0) {
            continue;
        }
        let q = DVec3::new(corner[0] as f64, corner[1] as f64, corner[2] as f64);
        // F changes sign along the segment c -> corner, where it is a
        // cubic: its root, by the same Illinois iteration as projections
        // (a few values of the polynomial, where a bisection of the
        // filter to adjacent numbers took some fifty).
        let dir = q - c;
        let (a1, (a2, a3)) = (g.dot(dir), trilinear_line_cubic(f, c, dir));
        let along = |s: f64| fc + s * (a1 + s * (a2 + s * a3));
        let s = crate::project::solve(&along, 0.0, fc, 1.0, f[k]);
        let p = c + dir * s;
        let d = (p - c).length();
        if best.map_or(true, |(bd, _)| d < bd) {
            best = Some((d, p));
        }
    }
    best.map_or(c, |(_, p)| p).to_array()
}

/// A tube between two loops: the cheapest closed strip of triangles that
/// walks `a` forwards and `b` backwards.
///
/// Every start diagonal is tried, with a dynamic programme over the strip
/// (at most 12 x 12 states: only ambiguous cells get here). A strip starts
/// by advancing on `a`, ends by advancing on `b` and does not finish `a`
/// before leaving the start vertex of `b`, so no diagonal is used twice (a
/// repeated diagonal would be an edge in four triangles). Costs,
/// in order of weight: a diagonal lying in a face that the neighbour may
/// also take (see below), a triangle lying flat in a cell face (it would
/// overlap the neighbour's patch boundary), a diagonal lying in a face,
/// then the diagonal's length.
///
/// A diagonal in a face joins the two segments of an ambiguous face (in
/// different loops). The cell across that face may stitch a tube there
/// too, and where both took the same diagonal it would be an edge in four
/// triangles; lengths cannot keep them apart (both cells see the same
/// crossings, and near a face saddle at the isovalue the two diagonals
/// across the face tie). So a cell may only join the segments' heads (in
/// its loops' direction, opposite crossings of the face): the neighbour
/// walks each segment of the face the other way (its outside is this
/// cell's inside), so it may only join their tails, the other diagonal.
/// That rests on the signs and the face's decision alone, which both cells
/// share. A strip may cross such a face along either diagonal (mirror
/// images), so this adds no diagonal in a face; a head joined to a tail
/// always closes a flat triangle. The cost is soft like the others, so a
/// strip always exists.
fn stitch(f: &[f64; 8], a: &[u8], b: &[u8], out: &mut Vec<[u8; 3]>) {
    let pa: Vec<[f64; 3]> = a.iter().map(|&e| crossing(f, e)).collect();
    let pb: Vec<[f64; 3]> = b.iter().map(|&e| crossing(f, e)).collect();
    let (m, n) = (a.len(), b.len());
    const FOREIGN: f64 = 1e9;
    const FLAT: f64 = 1e6;
    const IN_FACE: f64 = 1e3;
    // Cost of the triangle closing at diagonal (ia, jb) after advancing.
    let tri_cost = |x: u8, y: u8, z: u8, da: usize, db: usize| {
        let mut c = dist2(pa[da], pb[db]).sqrt();
        let face = VERTEX_FACES[a[da] as usize] & VERTEX_FACES[b[db] as usize];
        if face != 0 {
            // Heads: each end's predecessor in its loop is on that face.
            let (prev_a, prev_b) = (a[(da + m - 1) % m], b[(db + n - 1) % n]);
            let heads = VERTEX_FACES[prev_a as usize] & VERTEX_FACES[prev_b as usize] & face != 0;
            c += if heads { IN_FACE } else { FOREIGN };
        }
        if on_one_face([x, y, z]) {
            c += FLAT;
        }
        c
    };
    let mut best: Option<(f64, usize, usize, Vec<bool>)> = None;
    let w = n + 1;
    let mut cost = vec![f64::INFINITY; (m + 1) * w];
    let mut from_a = vec![false; (m + 1) * w];
    for i0 in 0..m {
        for j0 in 0..n {
            let ai = |i: usize| (i0 + i) % m;
            let bj = |j: usize| (j0 + n - j % n) % n;
            cost.iter_mut().for_each(|c| *c = f64::INFINITY);
            // First step is forced along a: state (1, 0).
            cost[w] = tri_cost(a[ai(0)], a[ai(1)], b[bj(0)], ai(1), bj(0));
            from_a[w] = true;
            for i in 1..=m {
                for j in 0..=n {
                    // (m, 0) would be the start diagonal again.
                    if j == 0 && (i == 1 || i == m) {
                        continue;
                    }
                    let mut c = f64::INFINITY;
                    let mut fa = false;
                    // Advance a: from (i - 1, j); never at j = n (the last
                    // step is along b).
                    if i >= 2 && j < n {
                        let prev = cost[(i - 1) * w + j];
                        let t = tri_cost(a[ai(i - 1)], a[ai(i)], b[bj(j)], ai(i), bj(j));
                        if prev + t < c {
                            c = prev + t;
                            fa = true;
                        }
                    }
                    // Advance b: from (i, j - 1).
                    if j >= 1 {
                        let prev = cost[i * w + j - 1];
                        let t = tri_cost(b[bj(j - 1)], a[ai(i)], b[bj(j)], ai(i), bj(j));
                        if prev + t < c {
                            c = prev + t;
                            fa = false;
                        }
                    }
                    cost[i * w + j] = c;
                    from_a[i * w + j] = fa;
                }
            }
            let total = cost[m * w + n];
            if best.as_ref().map_or(true, |b| total < b.0) {
                // Trace the steps back from (m, n).
                let mut steps = Vec::with_capacity(m + n);
                let (mut i, mut j) = (m, n);
                while i > 0 || j > 0 {
                    let fa = from_a[i * w + j];
                    steps.push(fa);
                    if fa {
                        i -= 1;
                    } else {
                        j -= 1;
                    }
                }
                steps.reverse();
                best = Some((total, i0, j0, steps));
            }
        }
    }
    let Some((_, i0, j0, steps)) = best else {
        return;
    };
    let (mut i, mut j) = (i0, j0);
    for advance_a in steps {
        if advance_a {
            let i1 = (i + 1) % m;
            out.push([a[i], a[i1], b[j]]);
            i = i1;
        } else {
            let j1 = (j + n - 1) % n;
            out.push([b[j], a[i], b[j1]]);
            j = j1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn same(a: &Loops, b: &Loops) -> bool {
        a.len() == b.len() && (0..a.len()).all(|k| a.get(k) == b.get(k))
    }

    #[test]
    fn planned_loops_regions_and_fans_are_found_afresh() {
        // Every sign pattern with random magnitudes (so every decision of
        // its ambiguous faces comes up): the plan, on first and later
        // calls, holds what a fresh search finds.
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        let mut uniform = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            (x >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut loops_seen = 0;
        for case in 1..255u16 {
            for _ in 0..40 {
                let mut f = [0.0; 8];
                for (k, v) in f.iter_mut().enumerate() {
                    let m = 0.01 + uniform();
                    *v = if case >> k & 1 == 1 { m } else { -m };
                }
                let d = face_decisions(&f);
                let fresh = find_loops(&f, &d);
                assert!(!fresh.is_empty());
                let mut uf = boundary_regions(&f, &d);
                let roots: [u8; 8] = std::array::from_fn(|c| uf.find(c as u8));
                // What `planned` decides the key by.
                assert_eq!(decisions_of_case(case as u8, &f), d);
                let check = |plan: Plan| {
                    assert!(same(&plan.loops, &fresh), "case {case}");
                    assert_eq!(plan.roots, roots, "case {case}");
                    for k in 0..4 {
                        let want = if k < fresh.len() {
                            fan_start(fresh.get(k))
                        } else {
                            NO_FAN
                        };
                        assert_eq!(plan.fans[k], want, "case {case} loop {k}");
                    }
                };
                // The public function with other decisions (every face
                // joined inside) must not change what is remembered.
                let _ = loops(&f, &[None; 6]);
                check(planned(case as u8, &f));
                let _ = loops(&f, &[Some(false); 6]);
                check(planned(case as u8, &f));
                loops_seen += fresh.len();
            }
        }
        assert!(loops_seen > 254 * 40);
    }

    #[test]
    fn a_slot_left_being_written_is_worked_around() {
        // As in a child forked while another thread wrote the slot: it
        // stays WRITING for good. Cells of that pattern must still get
        // their plan, their own, without waiting.
        let f = [0.3, -0.2, 0.4, -0.1, -0.5, 0.6, -0.7, 0.2];
        let case = crate::mc::case_index(&f);
        let d = face_decisions(&f);
        let key = plan_key(case, &d);
        let old = PLANS[key].state.swap(WRITING, Ordering::AcqRel);
        let want = make_plan(&f, &d);
        for _ in 0..3 {
            let plan = planned(case, &f);
            assert!(same(&plan.loops, &want.loops));
            assert_eq!((plan.roots, plan.fans), (want.roots, want.fans));
            assert_eq!(PLANS[key].state.load(Ordering::Acquire), WRITING);
        }
        let (mut got, mut extra) = (Vec::new(), Vec::new());
        triangles(&f, false, &mut got, &mut extra);
        assert!(!got.is_empty());
        // Back as it was (READY only over a plan that was written).
        PLANS[key].state.store(old, Ordering::Release);
    }

    #[test]
    fn patches_do_not_change_with_the_scale_of_the_data() {
        // A fan's interior vertex is projected along the gradient, whose
        // length overflowed beyond about 1e154 (and underflowed below
        // about 1e-160): the vertex took the fallback's point instead, a
        // tenth of a cell away. Every patch, interior vertices included,
        // is now the one at scale 1, bit for bit.
        let mut rng = crate::test_rng::XorShift(0xfa25);
        let mut fans = 0;
        for _ in 0..20_000 {
            let f: [f64; 8] = std::array::from_fn(|_| {
                let m = 0.05 + rng.unit();
                if rng.below(2) == 0 {
                    m
                } else {
                    -m
                }
            });
            for pinch in [false, true] {
                let (mut want, mut want_extra) = (Vec::new(), Vec::new());
                triangles(&f, pinch, &mut want, &mut want_extra);
                fans += !want_extra.is_empty() as usize;
                let bits = |x: &Vec<[f64; 3]>| -> Vec<[u64; 3]> {
                    x.iter().map(|p| p.map(f64::to_bits)).collect()
                };
                for e in [-1000, -600, -300, 300, 600, 1000, 1022] {
                    let s = 2f64.powi(e);
                    let g = f.map(|v| v * s);
                    let (mut got, mut got_extra) = (Vec::new(), Vec::new());
                    triangles(&g, pinch, &mut got, &mut got_extra);
                    assert_eq!(got, want, "{f:?} x 2^{e}");
                    assert_eq!(bits(&got_extra), bits(&want_extra), "{f:?} x 2^{e}");
                }
            }
        }
        assert!(fans > 200, "{fans} fans with an interior vertex");
    }

    #[test]
    fn interior_points_lie_in_the_cell() {
        // Cells of a hostile review: values around 1e300, 1e-300 and 1
        // mixed (some 20 in 300 000 such cells had their interior point a
        // rounding outside), led by the one it reported.
        let mut cells = vec![[
            -2.5133482400991705e-301,
            0.4482252024986835,
            1.891773629186082e-301,
            -0.014583868265118038,
            4.1282075394702866e299,
            -1.0920068528904026e-301,
            -0.11231421198135227,
            0.8809142329033226,
        ]];
        let mut rng = crate::test_rng::XorShift(0x1e300);
        for _ in 0..300_000 {
            cells.push(std::array::from_fn(|_| match rng.below(4) {
                0 => (rng.unit() - 0.5) * 1e300,
                1 => (rng.unit() - 0.5) * 1e-300,
                _ => rng.unit() * 2.0 - 1.0,
            }));
        }
        let mut outside = 0;
        for f in &cells {
            for pinch in [false, true] {
                let (mut tris, mut extra) = (Vec::new(), Vec::new());
                triangles(f, pinch, &mut tris, &mut extra);
                outside += extra
                    .iter()
                    .filter(|p| !p.iter().all(|x| (0.0..=1.0).contains(x)))
                    .count();
            }
        }
        assert_eq!(outside, 0);
    }

    #[test]
    fn decisions_and_regions_do_not_change_with_the_scale_of_the_data() {
        // Products of values below about 1e-154 underflowed to 0 (every
        // face then joined its inside corners, and no body saddle was
        // found), and above about 1e154 they overflowed: a tiny or huge
        // volume got another topology than the same volume scaled to 1.
        let mut rng = crate::test_rng::XorShift(0x5ca1e);
        for _ in 0..20_000 {
            let f: [f64; 8] = std::array::from_fn(|_| {
                let m = 0.05 + rng.unit();
                if rng.below(2) == 0 {
                    m
                } else {
                    -m
                }
            });
            let d = face_decisions(&f);
            let mut classes = regions(&f, &d);
            let want: [u8; 8] = std::array::from_fn(|c| classes.find(c as u8));
            for e in [-1000, -700, -600, -520, 520, 600, 1000] {
                let s = 2f64.powi(e);
                let g = f.map(|v| v * s);
                let dg = face_decisions(&g);
                assert_eq!(dg, d, "{f:?} x 2^{e}");
                let mut classes = regions(&g, &dg);
                let got: [u8; 8] = std::array::from_fn(|c| classes.find(c as u8));
                assert_eq!(got, want, "{f:?} x 2^{e}");
            }
        }
    }
}
