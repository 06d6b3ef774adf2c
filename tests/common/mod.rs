//! Helpers shared by the integration tests: a deterministic RNG, volume
//! builders, mesh checks (edges, manifoldness, orientation, components,
//! Euler characteristic, boundary loops, degenerate and duplicate
//! triangles, signed volume) and dense references of the trilinear
//! interpolant computed independently of the library (flood fills of the
//! inside and outside sets on a fine sampling).
//!
//! Every integration test binary includes this module and uses a different
//! subset of it.
#![allow(dead_code)]

use std::collections::{HashMap, HashSet};

use precisemc::{Mesh, Options, Rule, Topology};

// ---------------------------------------------------------------------------
// Random numbers (splitmix64: tiny, deterministic, no dependency).
// ---------------------------------------------------------------------------

/// A deterministic pseudo-random generator.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 0x9E37_79B9_7F4A_7C15)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.f64()
    }
    /// Uniform integer in 0..n.
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }
    /// Log-uniform in [lo, hi) (lo > 0).
    pub fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        (lo.ln() + (hi.ln() - lo.ln()) * self.f64()).exp()
    }
    pub fn bool(&mut self) -> bool {
        self.next_u64() & 1 == 1
    }
}

// ---------------------------------------------------------------------------
// Options and volumes.
// ---------------------------------------------------------------------------

pub const RULES: [Rule; 4] = [Rule::A, Rule::A1, Rule::A2, Rule::B];
pub const TOPOLOGIES: [Topology; 2] = [Topology::Classic, Topology::Trilinear];

pub fn refine_opts(topology: Topology, rule: Rule, epsilon: f64, max_level: u32) -> Options {
    Options {
        epsilon,
        max_level,
        rule,
        topology,
        threads: 1,
        ..Options::default()
    }
}

pub fn mc_opts(topology: Topology) -> Options {
    Options {
        threads: 1,
        ..Options::marching_cubes(topology)
    }
}

/// Samples `f(i, j, k)` (index coordinates) on a contiguous grid, x fastest.
pub fn grid_fn(dims: [usize; 3], f: impl Fn(f64, f64, f64) -> f64) -> Vec<f64> {
    let mut v = Vec::with_capacity(dims[0] * dims[1] * dims[2]);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                v.push(f(i as f64, j as f64, k as f64));
            }
        }
    }
    v
}

/// `r - |p - c|`: positive inside a ball of radius `r`.
pub fn sphere(dims: [usize; 3], c: [f64; 3], r: f64) -> Vec<f64> {
    grid_fn(dims, |x, y, z| {
        r - ((x - c[0]).powi(2) + (y - c[1]).powi(2) + (z - c[2]).powi(2)).sqrt()
    })
}

/// Positive inside a torus around the z axis through `c`.
pub fn torus(dims: [usize; 3], c: [f64; 3], big_r: f64, small_r: f64) -> Vec<f64> {
    grid_fn(dims, |x, y, z| {
        let (dx, dy, dz) = (x - c[0], y - c[1], z - c[2]);
        let q = (dx * dx + dy * dy).sqrt() - big_r;
        small_r - (q * q + dz * dz).sqrt()
    })
}

/// A sum of random Gaussian bumps minus 0.5, with the border set to -1
/// (so that the isosurface 0 is closed).
pub fn blobs(dims: [usize; 3], seed: u64, count: usize) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let bumps: Vec<([f64; 3], f64, f64)> = (0..count)
        .map(|_| {
            let c = [
                rng.range(1.5, dims[0] as f64 - 2.5),
                rng.range(1.5, dims[1] as f64 - 2.5),
                rng.range(1.5, dims[2] as f64 - 2.5),
            ];
            (c, rng.range(0.8, 2.5), rng.range(0.6, 1.4))
        })
        .collect();
    let mut v = grid_fn(dims, |x, y, z| {
        let mut s = -0.5;
        for (c, w, a) in &bumps {
            let d2 = (x - c[0]).powi(2) + (y - c[1]).powi(2) + (z - c[2]).powi(2);
            s += a * (-d2 / (w * w)).exp();
        }
        s
    });
    set_border(&mut v, dims, -1.0);
    v
}

/// Random values in [lo, hi) with the border set to `border`.
pub fn random_interior(dims: [usize; 3], seed: u64, lo: f64, hi: f64, border: f64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    let mut v: Vec<f64> = (0..dims[0] * dims[1] * dims[2])
        .map(|_| rng.range(lo, hi))
        .collect();
    set_border(&mut v, dims, border);
    v
}

pub fn set_border<T: Copy>(v: &mut [T], dims: [usize; 3], value: T) {
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                if i == 0
                    || j == 0
                    || k == 0
                    || i + 1 == dims[0]
                    || j + 1 == dims[1]
                    || k + 1 == dims[2]
                {
                    v[i + dims[0] * (j + dims[1] * k)] = value;
                }
            }
        }
    }
}

pub fn dims_u64(d: [usize; 3]) -> [u64; 3] {
    [d[0] as u64, d[1] as u64, d[2] as u64]
}

/// Corner `i` of a cell in VTK order (see `precisemc::tables::cube`).
pub const CORNER: [[usize; 3]; 8] = [
    [0, 0, 0],
    [1, 0, 0],
    [1, 1, 0],
    [0, 1, 0],
    [0, 0, 1],
    [1, 0, 1],
    [1, 1, 1],
    [0, 1, 1],
];

/// A 2x2x2 contiguous volume holding one cell with corner values `f`
/// (VTK corner order).
pub fn cell_volume(f: &[f64; 8]) -> Vec<f64> {
    let mut v = vec![0.0; 8];
    for (c, p) in CORNER.iter().enumerate() {
        v[p[0] + 2 * p[1] + 4 * p[2]] = f[c];
    }
    v
}

/// The eight corner values of a cell, in VTK order.
pub fn corners_of(values: &[f64], dims: [usize; 3], cell: [usize; 3]) -> [f64; 8] {
    let mut c = [0.0; 8];
    for (q, p) in CORNER.iter().enumerate() {
        let (i, j, k) = (cell[0] + p[0], cell[1] + p[1], cell[2] + p[2]);
        c[q] = values[i + dims[0] * (j + dims[1] * k)];
    }
    c
}

// ---------------------------------------------------------------------------
// The trilinear interpolant, written independently of the library.
// ---------------------------------------------------------------------------

/// Trilinear interpolant of corner values `f` (VTK order) at local `p`.
pub fn tri_value(f: &[f64; 8], p: [f64; 3]) -> f64 {
    let mut s = 0.0;
    for (c, q) in CORNER.iter().enumerate() {
        let mut w = 1.0;
        for a in 0..3 {
            w *= if q[a] == 1 { p[a] } else { 1.0 - p[a] };
        }
        s += w * f[c];
    }
    s
}

/// Gradient of the trilinear interpolant (local coordinates).
pub fn tri_gradient(f: &[f64; 8], p: [f64; 3]) -> [f64; 3] {
    let mut g = [0.0; 3];
    for (c, q) in CORNER.iter().enumerate() {
        for (a, ga) in g.iter_mut().enumerate() {
            let mut w = if q[a] == 1 { 1.0 } else { -1.0 };
            for b in 0..3 {
                if b != a {
                    w *= if q[b] == 1 { p[b] } else { 1.0 - p[b] };
                }
            }
            *ga += w * f[c];
        }
    }
    g
}

/// Hessian of the trilinear interpolant (zero diagonal).
fn tri_hessian(f: &[f64; 8], p: [f64; 3]) -> [[f64; 3]; 3] {
    let mut h = [[0.0; 3]; 3];
    for (c, q) in CORNER.iter().enumerate() {
        for a in 0..3 {
            for b in 0..3 {
                if a == b {
                    continue;
                }
                let o = 3 - a - b;
                let mut w = if q[a] == 1 { 1.0 } else { -1.0 };
                w *= if q[b] == 1 { 1.0 } else { -1.0 };
                w *= if q[o] == 1 { p[o] } else { 1.0 - p[o] };
                h[a][b] += w * f[c];
            }
        }
    }
    h
}

fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if det.abs() < 1e-300 {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut mk = m;
        for row in 0..3 {
            mk[row][k] = r[row];
        }
        let dk = mk[0][0] * (mk[1][1] * mk[2][2] - mk[1][2] * mk[2][1])
            - mk[0][1] * (mk[1][0] * mk[2][2] - mk[1][2] * mk[2][0])
            + mk[0][2] * (mk[1][0] * mk[2][1] - mk[1][1] * mk[2][0]);
        *o = dk / det;
    }
    Some(out)
}

/// Values of the trilinear interpolant at its critical points: interior
/// critical points (found by Newton's method from a grid of starts) and
/// the saddles of the bilinear restrictions to the six faces.
pub fn critical_values(f: &[f64; 8]) -> Vec<f64> {
    let mut out = Vec::new();
    let scale = f.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
    // Faces.
    for axis in 0..3 {
        for side in 0..2 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let g = |a: f64, b: f64| {
                let mut p = [0.0; 3];
                p[axis] = side as f64;
                p[u] = a;
                p[v] = b;
                tri_value(f, p)
            };
            // g(a, b) = c0 + c1 a + c2 b + c3 a b.
            let c0 = g(0.0, 0.0);
            let c1 = g(1.0, 0.0) - c0;
            let c2 = g(0.0, 1.0) - c0;
            let c3 = g(1.0, 1.0) - c0 - c1 - c2;
            if c3.abs() > 1e-14 * scale {
                let (a, b) = (-c2 / c3, -c1 / c3);
                if a > 0.0 && a < 1.0 && b > 0.0 && b < 1.0 {
                    out.push(g(a, b));
                }
            }
        }
    }
    // Interior.
    let mut found: Vec<[f64; 3]> = Vec::new();
    for sx in 0..4 {
        for sy in 0..4 {
            for sz in 0..4 {
                let mut p = [
                    (sx as f64 + 0.5) / 4.0,
                    (sy as f64 + 0.5) / 4.0,
                    (sz as f64 + 0.5) / 4.0,
                ];
                let mut ok = false;
                for _ in 0..60 {
                    let g = tri_gradient(f, p);
                    let gl = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
                    if gl < 1e-13 * scale {
                        ok = true;
                        break;
                    }
                    let Some(d) = solve3(tri_hessian(f, p), g) else {
                        break;
                    };
                    for a in 0..3 {
                        p[a] -= d[a];
                    }
                    if p.iter().any(|c| !(-0.5..=1.5).contains(c)) {
                        break;
                    }
                }
                if ok
                    && p.iter().all(|c| *c > 0.0 && *c < 1.0)
                    && !found.iter().any(|q| dist(*q, p) < 1e-7)
                {
                    found.push(p);
                    out.push(tri_value(f, p));
                }
            }
        }
    }
    out
}

/// Smallest distance of a corner value or critical value to `iso`,
/// relative to the largest |corner value - iso|.
pub fn relative_margin(f: &[f64; 8], iso: f64) -> f64 {
    let g: [f64; 8] = std::array::from_fn(|i| f[i] - iso);
    let scale = g.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut m = g.iter().fold(f64::INFINITY, |m, v| m.min(v.abs()));
    for c in critical_values(&g) {
        m = m.min(c.abs());
    }
    m / scale
}

/// Value of the piecewise trilinear interpolant of a contiguous volume at
/// index point `p` (cell = floor(p), clamped to the volume).
pub fn volume_value(values: &[f64], dims: [usize; 3], p: [f64; 3]) -> f64 {
    let (cell, local) = locate(dims, p);
    tri_value(&corners_of(values, dims, cell), local)
}

/// Cell containing index point `p` (floor, clamped) and local coordinates.
pub fn locate(dims: [usize; 3], p: [f64; 3]) -> ([usize; 3], [f64; 3]) {
    let mut cell = [0usize; 3];
    let mut local = [0.0; 3];
    for a in 0..3 {
        let c = (p[a].floor().max(0.0) as usize).min(dims[a] - 2);
        cell[a] = c;
        local[a] = p[a] - c as f64;
    }
    (cell, local)
}

// ---------------------------------------------------------------------------
// Small vector helpers.
// ---------------------------------------------------------------------------

pub fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
pub fn add(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
pub fn scale(a: [f64; 3], s: f64) -> [f64; 3] {
    [a[0] * s, a[1] * s, a[2] * s]
}
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
pub fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}
pub fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm(sub(a, b))
}

/// `(p1 - p0) x (p2 - p0)` of a triangle.
pub fn tri_normal(points: &[[f64; 3]], t: [u64; 3]) -> [f64; 3] {
    let (p0, p1, p2) = (
        points[t[0] as usize],
        points[t[1] as usize],
        points[t[2] as usize],
    );
    cross(sub(p1, p0), sub(p2, p0))
}

pub fn centroid(points: &[[f64; 3]], t: [u64; 3]) -> [f64; 3] {
    let (p0, p1, p2) = (
        points[t[0] as usize],
        points[t[1] as usize],
        points[t[2] as usize],
    );
    scale(add(add(p0, p1), p2), 1.0 / 3.0)
}

// ---------------------------------------------------------------------------
// Mesh checks.
// ---------------------------------------------------------------------------

struct Dsu(Vec<usize>);

impl Dsu {
    fn new(n: usize) -> Self {
        Dsu((0..n).collect())
    }
    fn find(&mut self, mut a: usize) -> usize {
        while self.0[a] != a {
            self.0[a] = self.0[self.0[a]];
            a = self.0[a];
        }
        a
    }
    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.0[ra.max(rb)] = ra.min(rb);
        }
    }
}

/// Everything the tests want to know about a triangle soup with shared
/// vertices.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct MeshCheck {
    pub triangles: usize,
    /// Points referenced by at least one triangle.
    pub vertices: usize,
    /// Points referenced by no triangle.
    pub unreferenced: usize,
    /// Distinct undirected edges.
    pub edges: usize,
    /// Edges used by exactly one triangle.
    pub boundary_edges: usize,
    /// Edges used by more than two triangles.
    pub nonmanifold_edges: usize,
    /// Edges used by exactly two triangles in the same direction.
    pub misoriented_edges: usize,
    /// Edges whose uses a->b and b->a differ in number (0 for a closed,
    /// consistently oriented 2-cycle, manifold or not).
    pub unbalanced_edges: usize,
    /// Vertices whose link (the opposite edges of their triangles) is not a
    /// single cycle or path.
    pub nonmanifold_vertices: usize,
    /// Connected components (triangles sharing a vertex).
    pub components: usize,
    /// Components of the graph of boundary edges.
    pub boundary_loops: usize,
    /// Boundary loops per component, sorted descending (one entry per component).
    pub loops_per_component: Vec<usize>,
    /// V - E + F over referenced vertices.
    pub euler: i64,
    /// Triangles with a repeated index or exactly zero area.
    pub degenerate: usize,
    /// Triangles whose vertex set repeats an earlier triangle's.
    pub duplicates: usize,
    /// Triangles with an index outside the point array.
    pub out_of_range: usize,
    /// Smallest triangle area (twice the area, actually: |cross|).
    pub min_double_area: f64,
}

impl MeshCheck {
    /// Every edge in exactly two triangles, used once in each direction,
    /// every vertex manifold, nothing degenerate or duplicated.
    pub fn is_closed_oriented_manifold(&self) -> bool {
        self.out_of_range == 0
            && self.boundary_edges == 0
            && self.nonmanifold_edges == 0
            && self.misoriented_edges == 0
            && self.unbalanced_edges == 0
            && self.nonmanifold_vertices == 0
            && self.degenerate == 0
            && self.duplicates == 0
    }
}

pub fn check_mesh(mesh: &Mesh) -> MeshCheck {
    check_tris(&mesh.index_points, &mesh.triangles)
}

pub fn check_tris(points: &[[f64; 3]], tris: &[[u64; 3]]) -> MeshCheck {
    let mut c = MeshCheck {
        triangles: tris.len(),
        min_double_area: f64::INFINITY,
        ..MeshCheck::default()
    };
    let n = points.len();
    c.out_of_range = tris
        .iter()
        .filter(|t| t.iter().any(|&v| v as usize >= n))
        .count();
    if c.out_of_range > 0 {
        return c;
    }
    // Edges: (lo, hi) -> [uses lo->hi, uses hi->lo].
    let mut edges: HashMap<(u64, u64), [u32; 2]> = HashMap::new();
    let mut used = vec![false; n];
    let mut dsu = Dsu::new(n);
    let mut seen: HashSet<[u64; 3]> = HashSet::new();
    let mut incident: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (ti, t) in tris.iter().enumerate() {
        for v in t {
            used[*v as usize] = true;
            incident[*v as usize].push(ti);
        }
        dsu.union(t[0] as usize, t[1] as usize);
        dsu.union(t[0] as usize, t[2] as usize);
        let mut s = *t;
        s.sort_unstable();
        if !seen.insert(s) {
            c.duplicates += 1;
        }
        let area = norm(tri_normal(points, *t));
        c.min_double_area = c.min_double_area.min(area);
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] || area == 0.0 {
            c.degenerate += 1;
        }
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            if a == b {
                continue;
            }
            let entry = edges.entry((a.min(b), a.max(b))).or_insert([0, 0]);
            entry[(a > b) as usize] += 1;
        }
    }
    c.vertices = used.iter().filter(|u| **u).count();
    c.unreferenced = n - c.vertices;
    c.edges = edges.len();
    let mut bdsu = Dsu::new(n);
    let mut on_boundary = vec![false; n];
    for (&(a, b), u) in &edges {
        let total = u[0] + u[1];
        if total == 1 {
            c.boundary_edges += 1;
            bdsu.union(a as usize, b as usize);
            on_boundary[a as usize] = true;
            on_boundary[b as usize] = true;
        }
        if total > 2 {
            c.nonmanifold_edges += 1;
        }
        if total == 2 && u[0] != 1 {
            c.misoriented_edges += 1;
        }
        if u[0] != u[1] && total != 1 {
            c.unbalanced_edges += 1;
        }
    }
    // Components and loops per component.
    let mut comp_loops: HashMap<usize, usize> = HashMap::new();
    for (v, &u) in used.iter().enumerate() {
        if u && dsu.find(v) == v {
            comp_loops.insert(v, 0);
        }
    }
    c.components = comp_loops.len();
    for (v, &b) in on_boundary.iter().enumerate() {
        if b && bdsu.find(v) == v {
            c.boundary_loops += 1;
            let root = dsu.find(v);
            *comp_loops.get_mut(&root).unwrap() += 1;
        }
    }
    let mut lpc: Vec<usize> = comp_loops.values().copied().collect();
    lpc.sort_unstable_by(|a, b| b.cmp(a));
    c.loops_per_component = lpc;
    c.euler = c.vertices as i64 - c.edges as i64 + tris.len() as i64;
    // Vertex links.
    for (v, inc) in incident.iter().enumerate() {
        if inc.is_empty() {
            continue;
        }
        let mut link: Vec<(u64, u64)> = Vec::with_capacity(inc.len());
        for &ti in inc {
            let t = tris[ti];
            let others: Vec<u64> = t.iter().copied().filter(|&w| w != v as u64).collect();
            if others.len() == 2 {
                link.push((others[0], others[1]));
            }
        }
        let mut deg: HashMap<u64, usize> = HashMap::new();
        for &(a, b) in &link {
            *deg.entry(a).or_insert(0) += 1;
            *deg.entry(b).or_insert(0) += 1;
        }
        let ids: Vec<u64> = deg.keys().copied().collect();
        let index: HashMap<u64, usize> = ids.iter().enumerate().map(|(i, &w)| (w, i)).collect();
        let mut ld = Dsu::new(ids.len());
        for &(a, b) in &link {
            ld.union(index[&a], index[&b]);
        }
        let comps = (0..ids.len()).filter(|&i| ld.find(i) == i).count();
        if comps != 1 || deg.values().any(|&d| d > 2) {
            c.nonmanifold_vertices += 1;
        }
    }
    c
}

/// Signed volume enclosed by the triangles (positive when normals point
/// away from the enclosed region). Summed about a point of the surface
/// (the same volume for a closed mesh) rather than the origin, so that
/// rounding scales with the surface's size, not with its distance from
/// the origin: a closed surface 1e-5 cells across, two cells from the
/// origin, came out at -6e-18 summed about the origin.
pub fn signed_volume(points: &[[f64; 3]], tris: &[[u64; 3]]) -> f64 {
    let Some(first) = tris.first() else {
        return 0.0;
    };
    let o = points[first[0] as usize];
    let rel = |i: u64| {
        let p = points[i as usize];
        [p[0] - o[0], p[1] - o[1], p[2] - o[2]]
    };
    tris.iter()
        .map(|t| {
            let (a, b, c) = (rel(t[0]), rel(t[1]), rel(t[2]));
            dot(a, cross(b, c)) / 6.0
        })
        .sum()
}

/// Triangles as position triples (bit patterns), rotated so that the
/// smallest comes first (winding preserved), sorted: equal for two meshes
/// that differ only in point numbering and triangle order.
pub fn canonical_triangles(points: &[[f64; 3]], tris: &[[u64; 3]]) -> Vec<[[u64; 3]; 3]> {
    let bits = |p: [f64; 3]| {
        [
            (p[0] + 0.0).to_bits(),
            (p[1] + 0.0).to_bits(),
            (p[2] + 0.0).to_bits(),
        ]
    };
    let mut out: Vec<[[u64; 3]; 3]> = tris
        .iter()
        .map(|t| {
            let mut k = [
                bits(points[t[0] as usize]),
                bits(points[t[1] as usize]),
                bits(points[t[2] as usize]),
            ];
            let r = (0..3).min_by_key(|&i| k[i]).unwrap();
            k.rotate_left(r);
            k
        })
        .collect();
    out.sort_unstable();
    out
}

/// Sorted bit patterns of points.
pub fn canonical_points(points: &[[f64; 3]]) -> Vec<[u64; 3]> {
    let mut v: Vec<[u64; 3]> = points
        .iter()
        .map(|p| {
            [
                (p[0] + 0.0).to_bits(),
                (p[1] + 0.0).to_bits(),
                (p[2] + 0.0).to_bits(),
            ]
        })
        .collect();
    v.sort_unstable();
    v
}

/// Whether two meshes are bit-identical (points, triangles, levels, normals).
pub fn same_mesh(a: &Mesh, b: &Mesh) -> bool {
    let bits = |v: &Vec<[f64; 3]>| v.iter().map(|p| p.map(f64::to_bits)).collect::<Vec<_>>();
    let nbits = |v: &Vec<[f32; 3]>| v.iter().map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
    bits(&a.points) == bits(&b.points)
        && bits(&a.index_points) == bits(&b.index_points)
        && a.triangles == b.triangles
        && a.levels == b.levels
        && nbits(&a.normals) == nbits(&b.normals)
        && nbits(&a.gradients) == nbits(&b.gradients)
}

/// Asserts that no coordinate of the mesh is NaN or infinite and that the
/// arrays have consistent lengths.
pub fn assert_sane(mesh: &Mesh) {
    assert_eq!(mesh.points.len(), mesh.index_points.len());
    assert_eq!(mesh.levels.len(), mesh.triangles.len());
    assert_eq!(mesh.stats.output_triangles, mesh.triangles.len() as u64);
    assert_eq!(mesh.stats.output_points, mesh.points.len() as u64);
    for p in mesh.points.iter().chain(&mesh.index_points) {
        assert!(p.iter().all(|c| c.is_finite()), "non-finite point {p:?}");
    }
    let n = mesh.points.len() as u64;
    for t in &mesh.triangles {
        assert!(
            t.iter().all(|&v| v < n),
            "index out of range {t:?} ({n} points)"
        );
    }
    for nn in &mesh.normals {
        assert!(nn.iter().all(|c| c.is_finite()), "non-finite normal {nn:?}");
    }
}

// ---------------------------------------------------------------------------
// Dense references.
// ---------------------------------------------------------------------------

/// Labels the 6-connected components of the grid points of each sign
/// (`inside[i]` true or false). Returns labels and the number of inside
/// and outside components.
pub fn flood(n: [usize; 3], inside: &[bool]) -> (Vec<u32>, usize, usize) {
    let total = n[0] * n[1] * n[2];
    let mut label = vec![u32::MAX; total];
    let (mut nin, mut nout) = (0, 0);
    let mut next = 0u32;
    let mut stack = Vec::new();
    for start in 0..total {
        if label[start] != u32::MAX {
            continue;
        }
        let s = inside[start];
        if s {
            nin += 1;
        } else {
            nout += 1;
        }
        label[start] = next;
        stack.push(start);
        while let Some(p) = stack.pop() {
            let (i, j, k) = (p % n[0], (p / n[0]) % n[1], p / (n[0] * n[1]));
            let mut visit = |q: usize| {
                if label[q] == u32::MAX && inside[q] == s {
                    label[q] = next;
                    stack.push(q);
                }
            };
            if i > 0 {
                visit(p - 1);
            }
            if i + 1 < n[0] {
                visit(p + 1);
            }
            if j > 0 {
                visit(p - n[0]);
            }
            if j + 1 < n[1] {
                visit(p + n[0]);
            }
            if k > 0 {
                visit(p - n[0] * n[1]);
            }
            if k + 1 < n[2] {
                visit(p + n[0] * n[1]);
            }
        }
        next += 1;
    }
    (label, nin, nout)
}

/// Topology of the isosurface `F = 0` of the trilinear interpolant of one
/// cell, measured on an `(n+1)^3` sampling.
#[derive(Debug, Clone, PartialEq)]
pub struct CellReference {
    pub inside_regions: usize,
    pub outside_regions: usize,
    /// Surface components: each separates two regions and, in a ball, the
    /// region adjacency graph is a tree, so this is `regions - 1`.
    pub components: usize,
    /// Loops of the curve `F = 0` on the cube's surface: each separates two
    /// regions of the (sphere-like) surface, so `surface regions - 1`.
    pub boundary_loops: usize,
    /// Loops per surface component, sorted descending.
    pub loops_per_component: Vec<usize>,
    /// Euler characteristic if every component has genus 0 (true for the
    /// trilinear interpolant in a cell): sum of `2 - loops`.
    pub euler: i64,
}

/// Dense reference for one cell with corner values `f` (iso 0, inside is
/// `F >= 0`). `Err` when the sampling is inconsistent (the region
/// adjacency graphs are not trees), i.e. the sampling is too coarse for
/// this cell.
pub fn cell_reference(f: &[f64; 8], n: usize) -> Result<CellReference, String> {
    let m = n + 1;
    let dims = [m, m, m];
    let mut inside = vec![false; m * m * m];
    for k in 0..m {
        for j in 0..m {
            for i in 0..m {
                let p = [
                    i as f64 / n as f64,
                    j as f64 / n as f64,
                    k as f64 / n as f64,
                ];
                inside[i + m * (j + m * k)] = tri_value(f, p) >= 0.0;
            }
        }
    }
    let (label, nin, nout) = flood(dims, &inside);
    // Adjacent pairs of 3D regions of opposite sign.
    let mut pairs3: HashSet<(u32, u32)> = HashSet::new();
    let idx = |i: usize, j: usize, k: usize| i + m * (j + m * k);
    for k in 0..m {
        for j in 0..m {
            for i in 0..m {
                let p = idx(i, j, k);
                for q in [
                    if i + 1 < m {
                        Some(idx(i + 1, j, k))
                    } else {
                        None
                    },
                    if j + 1 < m {
                        Some(idx(i, j + 1, k))
                    } else {
                        None
                    },
                    if k + 1 < m {
                        Some(idx(i, j, k + 1))
                    } else {
                        None
                    },
                ]
                .into_iter()
                .flatten()
                {
                    if label[p] != label[q] {
                        pairs3.insert((label[p].min(label[q]), label[p].max(label[q])));
                    }
                }
            }
        }
    }
    let regions = nin + nout;
    if pairs3.len() + 1 != regions {
        return Err(format!(
            "3D region graph is not a tree: {} regions, {} adjacencies",
            regions,
            pairs3.len()
        ));
    }
    // Surface of the cube: flood fill over boundary points, adjacency by
    // grid neighbours that are boundary points too (two such neighbours
    // always share a face).
    let on_b =
        |i: usize, j: usize, k: usize| i == 0 || j == 0 || k == 0 || i == n || j == n || k == n;
    let mut slabel: HashMap<usize, u32> = HashMap::new();
    let mut nsurf = 0u32;
    let mut stack = Vec::new();
    for k in 0..m {
        for j in 0..m {
            for i in 0..m {
                if !on_b(i, j, k) || slabel.contains_key(&idx(i, j, k)) {
                    continue;
                }
                let s = inside[idx(i, j, k)];
                slabel.insert(idx(i, j, k), nsurf);
                stack.push((i, j, k));
                while let Some((a, b, c)) = stack.pop() {
                    let nb = [
                        (a.wrapping_sub(1), b, c),
                        (a + 1, b, c),
                        (a, b.wrapping_sub(1), c),
                        (a, b + 1, c),
                        (a, b, c.wrapping_sub(1)),
                        (a, b, c + 1),
                    ];
                    for (x, y, z) in nb {
                        if x >= m || y >= m || z >= m || !on_b(x, y, z) {
                            continue;
                        }
                        let q = idx(x, y, z);
                        if inside[q] == s && !slabel.contains_key(&q) {
                            slabel.insert(q, nsurf);
                            stack.push((x, y, z));
                        }
                    }
                }
                nsurf += 1;
            }
        }
    }
    // Loops: adjacent surface regions of opposite sign.
    let mut loops: HashSet<(u32, u32)> = HashSet::new();
    let mut surf_to_3d: HashMap<u32, u32> = HashMap::new();
    for (&p, &s) in &slabel {
        surf_to_3d.insert(s, label[p]);
        let (i, j, k) = (p % m, (p / m) % m, p / (m * m));
        for (x, y, z) in [(i + 1, j, k), (i, j + 1, k), (i, j, k + 1)] {
            if x < m && y < m && z < m && on_b(x, y, z) {
                let t = slabel[&idx(x, y, z)];
                if t != s {
                    loops.insert((s.min(t), s.max(t)));
                }
            }
        }
    }
    if nsurf > 0 && loops.len() + 1 != nsurf as usize {
        return Err(format!(
            "surface region graph is not a tree: {} regions, {} adjacencies",
            nsurf,
            loops.len()
        ));
    }
    let mut per_comp: HashMap<(u32, u32), usize> = pairs3.iter().map(|&p| (p, 0)).collect();
    for (a, b) in &loops {
        let (x, y) = (surf_to_3d[a], surf_to_3d[b]);
        let key = (x.min(y), x.max(y));
        match per_comp.get_mut(&key) {
            Some(c) => *c += 1,
            None => return Err(format!("loop between non-adjacent regions {key:?}")),
        }
    }
    let mut lpc: Vec<usize> = per_comp.values().copied().collect();
    lpc.sort_unstable_by(|a, b| b.cmp(a));
    let euler = lpc.iter().map(|&l| 2 - l as i64).sum();
    Ok(CellReference {
        inside_regions: nin,
        outside_regions: nout,
        components: regions - 1,
        boundary_loops: loops.len(),
        loops_per_component: lpc,
        euler,
    })
}

/// Dense reference for a whole volume (piecewise trilinear, `F >= iso`
/// inside), sampled `per_cell` times per cell edge: the number of inside
/// and outside components and the Euler characteristic of the inside set
/// (as the cubical complex of inside samples: vertices - edges + squares -
/// cubes whose corners are all inside).
pub struct VolumeReference {
    pub inside_components: usize,
    pub outside_components: usize,
    pub inside_euler: i64,
}

pub fn volume_reference(
    values: &[f64],
    dims: [usize; 3],
    iso: f64,
    per_cell: usize,
) -> VolumeReference {
    let n = [
        (dims[0] - 1) * per_cell + 1,
        (dims[1] - 1) * per_cell + 1,
        (dims[2] - 1) * per_cell + 1,
    ];
    let h = 1.0 / per_cell as f64;
    let mut inside = vec![false; n[0] * n[1] * n[2]];
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let p = [i as f64 * h, j as f64 * h, k as f64 * h];
                inside[i + n[0] * (j + n[1] * k)] = volume_value(values, dims, p) >= iso;
            }
        }
    }
    let (_, nin, nout) = flood(n, &inside);
    // Cubical Euler characteristic of the inside samples.
    let at = |i: usize, j: usize, k: usize| inside[i + n[0] * (j + n[1] * k)];
    let mut chi: i64 = 0;
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                // Cells of dimension d anchored at (i, j, k) spanning the axes in `mask`.
                for mask in 0u8..8 {
                    let ext = [mask & 1 != 0, mask & 2 != 0, mask & 4 != 0];
                    if (ext[0] && i + 1 >= n[0])
                        || (ext[1] && j + 1 >= n[1])
                        || (ext[2] && k + 1 >= n[2])
                    {
                        continue;
                    }
                    let mut all = true;
                    for c in 0u8..8 {
                        if c & !mask != 0 {
                            continue;
                        }
                        let (x, y, z) = (
                            i + (c & 1) as usize,
                            j + ((c >> 1) & 1) as usize,
                            k + ((c >> 2) & 1) as usize,
                        );
                        if !at(x, y, z) {
                            all = false;
                            break;
                        }
                    }
                    if all {
                        chi += if mask.count_ones() % 2 == 0 { 1 } else { -1 };
                    }
                }
            }
        }
    }
    VolumeReference {
        inside_components: nin,
        outside_components: nout,
        inside_euler: chi,
    }
}

/// Smallest relative margin over all cells of a volume (see
/// [`relative_margin`]), relative to the whole volume's value range.
pub fn volume_margin(values: &[f64], dims: [usize; 3], iso: f64) -> f64 {
    let range = values.iter().fold(0.0f64, |m, v| m.max((v - iso).abs()));
    let mut m = f64::INFINITY;
    for k in 0..dims[2] - 1 {
        for j in 0..dims[1] - 1 {
            for i in 0..dims[0] - 1 {
                let c = corners_of(values, dims, [i, j, k]);
                let g: [f64; 8] = std::array::from_fn(|q| c[q] - iso);
                for v in g {
                    m = m.min(v.abs());
                }
                for v in critical_values(&g) {
                    m = m.min(v.abs());
                }
            }
        }
    }
    m / range
}
