//! Cells whose refinement would split nothing, told from bounds on the
//! trilinear interpolant instead of by running their tests.
//!
//! Where the data is smooth, nearly every refined cell keeps its Marching
//! Cubes triangles: every level-0 test (edge midpoints, the diagonals'
//! check, the centres) finds `S_K` within epsilon, and those tests cost
//! several times the cell's plain Marching Cubes work. A test of a point
//! `p` (see `project::test_from`) steps from `p` along the gradient line,
//! towards the isovalue, by epsilon (or to the cell's boundary when that is
//! nearer), and calls `p` near when `F - iso` has changed sign there.
//! Along that line the interpolant is a cubic whose quadratic and cubic
//! coefficients are bounded by the cell's face twists and its body twist,
//! and `|F(p) - iso|` at a midpoint or centre of points on `S_K` is bounded
//! by the twists and the distances to those points (Taylor's theorem): when
//! these bounds leave the sign change certain at every sample, with room
//! for rounding, each test would return "near" and the cell's output is
//! its Marching Cubes triangles, bit for bit. [`all_near`] decides that;
//! it errs only towards running the tests. Edges in cell faces are decided
//! the same way by both neighbours either way, because the bound only
//! predicts the test's result.

use glam::DVec3;

use crate::options::Rule;
use crate::refine::shared_fixed_axes;

/// Bounds on the trilinear interpolant of one cell (local coordinates).
#[derive(Debug, Clone, Copy)]
struct CellBounds {
    /// Largest |second mixed derivative| over the cell (the face twists:
    /// each mixed derivative interpolates linearly between two of them).
    twist: f64,
    /// |third mixed derivative| / (3 sqrt 3): bounds the cubic coefficient
    /// along any unit direction.
    body: f64,
    /// By fixed-axis mask (none, or one axis: the masks of the tests run
    /// inside the cell and in its faces), a lower bound over the cell of
    /// the length of the gradient with those axes zeroed; 0 for the other
    /// masks.
    least: [f64; 8],
    /// Absolute allowance (value units) for rounding: of the Marching
    /// Cubes points' positions and of the tests' own arithmetic.
    slack: f64,
}

/// What the cheap first check of a cell needs (see [`all_near`]).
struct Rough {
    /// [`CellBounds::twist`].
    twist: f64,
    /// The largest |edge difference|: the gradient is never longer than
    /// sqrt 3 times it.
    steepest: f64,
    /// The body twist (the third mixed derivative).
    hxyz: f64,
    /// The edge differences by axis (each axis's four edges in the order
    /// of `CellBounds::of_cell`'s table).
    edges: [[f64; 4]; 3],
}

impl Rough {
    fn of_cell(c: &[f64; 8]) -> Self {
        // The six face twists, then the body twist.
        let twists = crate::filter::twists(c);
        let edges = [
            crate::filter::x_steps(c),
            [c[3] - c[0], c[2] - c[1], c[7] - c[4], c[6] - c[5]],
            [c[4] - c[0], c[5] - c[1], c[6] - c[2], c[7] - c[3]],
        ];
        let abs_max = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        Rough {
            twist: abs_max(&twists[..6]),
            hxyz: twists[6],
            steepest: edges.iter().fold(0.0, |m, d| f64::max(m, abs_max(d))),
            edges,
        }
    }
}

impl CellBounds {
    /// From the corner values (VTK corner order), for a cell whose lowest
    /// corner lies `far` index units from the origin along its largest
    /// coordinate.
    fn of_cell(c: &[f64; 8], iso: f64, far: f64, rough: &Rough) -> Self {
        let &Rough {
            twist,
            steepest,
            hxyz,
            ref edges,
        } = rough;
        // Two lower bounds of the gradient's length, the better one kept:
        // per axis, |dF/dx_axis| is bilinear in the two other coordinates,
        // so its extremes are the axis's four edge differences; and the
        // component along the mean corner gradient, a sum of such terms,
        // is multilinear over the cell, so its least value is at a corner
        // (each corner's gradient is its three edge differences).
        let slope = edges.map(|d| {
            if d.iter().all(|&v| v > 0.0) || d.iter().all(|&v| v < 0.0) {
                d.iter().fold(f64::INFINITY, |m, v| m.min(v.abs()))
            } else {
                0.0
            }
        });
        // Corner k's gradient: per axis, the index in `edges[axis]` of
        // the edge of that axis through k.
        const AT: [[usize; 3]; 8] = [
            [0, 0, 0],
            [0, 1, 1],
            [1, 1, 2],
            [1, 0, 3],
            [2, 2, 0],
            [2, 3, 1],
            [3, 3, 2],
            [3, 2, 3],
        ];
        let corner = AT.map(|[x, y, z]| [edges[0][x], edges[1][y], edges[2][z]]);
        let mut mean = [0.0; 3];
        for g in &corner {
            for a in 0..3 {
                mean[a] += g[a];
            }
        }
        let n = DVec3::from_array(mean).normalize_or_zero().to_array();
        // Per corner and axis, the gradient's term along `n`; then per
        // mask the least sum over the free axes (plain comparisons, the
        // masks unrolled, each sum in the order of its axes: this runs for
        // every refined cell).
        let terms = corner.map(|g| [g[0] * n[0], g[1] * n[1], g[2] * n[2]]);
        let mut along = [f64::INFINITY; 4];
        for t in &terms {
            let sums = [t[0] + t[1] + t[2], t[1] + t[2], t[0] + t[2], t[0] + t[1]];
            for (m, v) in along.iter_mut().zip(sums) {
                if v < *m {
                    *m = v;
                }
            }
        }
        let sq = slope.map(|s| s * s);
        let nn = n.map(|v| v * v);
        let mut least = [0.0; 8];
        for (i, fixed) in [0usize, 1, 2, 4].into_iter().enumerate() {
            let (m2, n2) = match fixed {
                0 => (sq[0] + sq[1] + sq[2], nn[0] + nn[1] + nn[2]),
                1 => (sq[1] + sq[2], nn[1] + nn[2]),
                2 => (sq[0] + sq[2], nn[0] + nn[2]),
                _ => (sq[0] + sq[1], nn[0] + nn[1]),
            };
            let along = if n2 > 0.0 { along[i] / n2.sqrt() } else { 0.0 };
            least[fixed] = f64::sqrt(m2).max(along);
        }
        let scale = c.iter().fold(iso.abs(), |m, v| m.max(v.abs()));
        // Points are placed in global coordinates and brought back to the
        // cell by a subtraction: each coordinate is off by up to a few ulps
        // of the global one, so `F - iso` at a Marching Cubes point is off
        // by the steepest slope times that (twice, for the three axes).
        // Generous factors: the allowance only makes the bound stricter.
        const ULP: f64 = f64::EPSILON;
        let slack = 16.0 * ULP * (far + 2.0) * 2.0 * steepest + 64.0 * ULP * scale;
        CellBounds {
            twist,
            body: hxyz.abs() / (3.0 * 3f64.sqrt()) + 8.0 * ULP * scale,
            least,
            slack,
        }
    }

    /// Whether the test of the point `x` (fixed-axis mask `fixed`), which
    /// lies within distances whose largest square is `reach2` of points
    /// of the cell's patch on `S_K` with `x` in their convex hull, finds
    /// `S_K` within `epsilon` on its first step.
    fn near(&self, x: DVec3, fixed: u8, reach2: f64, epsilon: f64) -> bool {
        // Room to step inside the cell along the free axes.
        let mut room = f64::INFINITY;
        for a in 0..3 {
            if fixed & (1 << a) == 0 {
                room = room.min(x[a].min(1.0 - x[a]));
            }
        }
        let m = self.least[fixed as usize & 7];
        // The step the test takes: epsilon, or less where the cell's
        // boundary cuts it; it is at least `delta`.
        let delta = epsilon.min(room);
        if !(delta >= 1e-6 * epsilon && delta > 0.0 && m > 0.0) {
            return false;
        }
        // |F(x) - iso| is at most twist * reach2 (the remainders of the
        // Taylor expansions at x of the values at the hull's points, which
        // are iso). After a step of length d along the gradient, F - iso
        // has moved towards zero by at least d * |g| - twist d^2 - body
        // d^3: a sign change when that exceeds |F(x) - iso|. That lower
        // bound grows with d up to epsilon when its derivative stays
        // positive, so the shortest step decides.
        let (h, b) = (self.twist, self.body);
        let grows = m > 2.0 * h * epsilon + 3.0 * b * epsilon * epsilon;
        let moved = delta * m - h * delta * delta - b * delta * delta * delta;
        grows && h * reach2 + self.slack < moved * (1.0 - 1e-6)
    }
}

/// Whether every test refinement would run on the Marching Cubes patch
/// `tris` (point ids) of a cell free of ties, with corners' local
/// positions `pos` (three per triangle, in order), finds its sample near:
/// the diagonals' check (`crate::diagonals`), each edge's midpoint with
/// its check along the edge (`refine::sample_edge`), and each triangle's
/// centre under `rule`. `c` are the cell's corner values, `iso` the
/// isovalue, `far` the largest coordinate of the cell's lowest corner
/// (index units). Every point of the patch must lie on `S_K` (up to
/// rounding): no interior points of ambiguous cells. `false` when the
/// bounds cannot tell, or when an interior edge of the patch lies in a
/// cell face (the diagonals' check treats it apart). Otherwise the number
/// of tests refinement would have run (each edge once, each centre).
#[allow(clippy::too_many_arguments)]
pub(crate) fn all_near(
    c: &[f64; 8],
    iso: f64,
    far: f64,
    tris: &[[u32; 3]],
    pos: &[DVec3],
    epsilon: f64,
    rule: Rule,
) -> Option<u64> {
    #[cfg(test)]
    if tests::OFF.load(std::sync::atomic::Ordering::Relaxed) {
        return None;
    }
    if epsilon.is_nan() || epsilon <= 0.0 {
        return None;
    }
    // First a necessary condition that costs little (most cells the
    // bound cannot settle fail it): the gradient is nowhere longer than
    // sqrt 3 times the steepest edge difference, so no sample passes
    // `CellBounds::near` unless twist * reach2 is below epsilon times that.
    let rough = Rough::of_cell(c);
    let ceiling = epsilon * 3f64.sqrt() * rough.steepest;
    for p in pos.chunks_exact(3) {
        for e in 0..3 {
            if rough.twist * 0.25 * (p[(e + 1) % 3] - p[e]).length_squared() >= ceiling {
                return None;
            }
        }
    }
    let mut tests = 0;
    let b = CellBounds::of_cell(c, iso, far, &rough);
    // The check along an interior edge (`refine::bulge`) stops at once when
    // 0.05 |a3| <= 0.1 epsilon |g(midpoint)|, a3 = e_x e_y e_z F_xyz.
    let m_all = b.least[0];
    let body3 = b.body * 3.0 * 3f64.sqrt();
    for (n, t) in tris.iter().enumerate() {
        let p = [pos[3 * n], pos[3 * n + 1], pos[3 * n + 2]];
        for e in 0..3 {
            let (a, z) = (p[e], p[(e + 1) % 3]);
            let fixed = shared_fixed_axes(a, z);
            let (ia, iz) = (t[e], t[(e + 1) % 3]);
            let interior = tris
                .iter()
                .any(|u| (0..3).any(|f| u[f] == iz && u[(f + 1) % 3] == ia));
            if interior {
                if fixed != 0 {
                    // A diagonal flat in a face: the diagonals' check
                    // re-cuts its polygon.
                    return None;
                }
                let d = z - a;
                if 0.05 * (d.x * d.y * d.z).abs() * body3 > 0.1 * epsilon * m_all * (1.0 - 1e-6) {
                    return None;
                }
            }
            // An interior edge is tested once, from either side.
            tests += u64::from(!interior || ia < iz);
            let mid = (a + z) * 0.5;
            if !b.near(mid, fixed, (z - a).length_squared() * 0.25, epsilon) {
                return None;
            }
        }
        if rule != Rule::A {
            let centre = (p[0] + p[1] + p[2]) / 3.0;
            let reach2 = p
                .iter()
                .fold(0.0f64, |r, q| r.max((*q - centre).length_squared()));
            if !b.near(centre, 0, reach2, epsilon) {
                return None;
            }
            tests += 1;
        }
    }
    #[cfg(test)]
    tests::PROVEN.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    Some(tests)
}

#[cfg(test)]
pub(crate) mod tests {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::Mutex;

    use super::*;
    use crate::filter::Trilinear;
    use crate::mc::cell_triangles_of_case;
    use crate::refine::{sample, sample_edge};
    use crate::test_rng::XorShift;
    use crate::Topology;

    type F = Trilinear<'static, f64>;

    /// Turns [`all_near`] off (for the test that compares the output with
    /// and without it; the output must not change, so other tests running
    /// meanwhile are unaffected).
    pub(crate) static OFF: AtomicBool = AtomicBool::new(false);
    /// Held by this module's tests, which count what [`all_near`] proves.
    static ONE_AT_A_TIME: Mutex<()> = Mutex::new(());
    /// Cells [`all_near`] has proven near, in this test process.
    pub(crate) static PROVEN: AtomicU64 = AtomicU64::new(0);

    /// A cell's Marching Cubes patch (ids, local positions), when every
    /// point lies on a grid edge.
    fn patch(c: &[f64; 8], iso: f64, topology: Topology) -> Option<(Vec<[u32; 3]>, Vec<DVec3>)> {
        use crate::tables::cube::{CORNERS, EDGES};
        let f = c.map(|v| v - iso);
        let case = (0..8).fold(0u8, |k, i| k | ((f[i] >= 0.0) as u8) << i);
        let mut p = crate::mc::Patch::default();
        cell_triangles_of_case(case, &f, topology, &mut p);
        let mut pos = Vec::new();
        for t in &p.tris {
            for &e in t {
                let e = e as usize;
                if e >= 12 {
                    return None;
                }
                let [a, b] = EDGES[e];
                let (ca, cb) = (CORNERS[a as usize], CORNERS[b as usize]);
                let s = (iso - c[a as usize]) / (c[b as usize] - c[a as usize]);
                let pa = DVec3::new(ca[0] as f64, ca[1] as f64, ca[2] as f64);
                let pb = DVec3::new(cb[0] as f64, cb[1] as f64, cb[2] as f64);
                pos.push(pa + (pb - pa) * s);
            }
        }
        Some((p.tris.iter().map(|t| t.map(|e| e as u32)).collect(), pos))
    }

    fn range(rng: &mut XorShift, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * rng.unit()
    }

    /// Corner values of a gently curved field: a plane in a random
    /// direction plus small random twists, scaled and shifted at random.
    fn smooth_cell(rng: &mut XorShift, curl: f64) -> [f64; 8] {
        let n = DVec3::new(
            range(rng, -1.0, 1.0),
            range(rng, -1.0, 1.0),
            range(rng, -1.0, 1.0),
        );
        let off = range(rng, -1.5, 0.5);
        let (scale, shift) = (10f64.powf(range(rng, -3.0, 3.0)), range(rng, -100.0, 100.0));
        let mut c = [0.0; 8];
        for (k, q) in crate::tables::cube::CORNERS.iter().enumerate() {
            let x = DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64);
            c[k] = shift + scale * (n.dot(x) + off + curl * range(rng, -1.0, 1.0));
        }
        if rng.below(4) == 0 {
            // Quantised, as integer samples are: steps of a few per cent
            // of the values' range across the cell.
            let step = scale * 0.05;
            c = c.map(|v| (v / step).round() * step + 0.5 * step);
        }
        c
    }

    #[test]
    fn a_cell_found_near_is_near_in_every_test() {
        let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
        let mut rng = XorShift(7);
        let (mut proven, mut tried) = (0, 0);
        for round in 0..200_000 {
            let curl = [0.0, 0.001, 0.01, 0.05, 0.2][round % 5];
            let c = smooth_cell(&mut rng, curl);
            let iso =
                c.iter().sum::<f64>() / 8.0 + range(&mut rng, -0.3, 0.3) * (c[6] - c[0]).abs();
            let topology = if round % 2 == 0 {
                Topology::Trilinear
            } else {
                Topology::Classic
            };
            let Some((tris, pos)) = patch(&c, iso, topology) else {
                continue;
            };
            if tris.is_empty() {
                continue;
            }
            let epsilon = 10f64.powf(range(&mut rng, -3.0, -0.5));
            let rule = [Rule::A, Rule::A1, Rule::A2, Rule::B][round % 4];
            tried += 1;
            if all_near(&c, iso, 0.0, &tris, &pos, epsilon, rule).is_none() {
                continue;
            }
            proven += 1;
            for (n, t) in tris.iter().enumerate() {
                let p = [pos[3 * n], pos[3 * n + 1], pos[3 * n + 2]];
                for e in 0..3 {
                    let (a, b) = (p[e], p[(e + 1) % 3]);
                    let s = sample_edge::<F>(&c, iso, a, b, shared_fixed_axes(a, b), epsilon, true);
                    assert!(
                        s.split.is_none() && !s.failed,
                        "edge {a} {b} of {c:?} at {iso} splits ({epsilon})"
                    );
                    let _ = t;
                }
                let centre = (p[0] + p[1] + p[2]) / 3.0;
                let s = sample::<F>(&c, iso, centre, 0, epsilon, true, 1.0);
                assert!(
                    s.split.is_none() && !s.failed,
                    "centre of {c:?} at {iso} splits"
                );
            }
        }
        // The bound must also be useful: most gently curved cells pass.
        assert!(
            tried > 100_000 && proven * 4 > tried,
            "{proven} of {tried} proven near"
        );
    }

    /// Points (bits), triangles, counts and the mean level (bits).
    type Outcome = (Vec<[u64; 3]>, Vec<[u64; 3]>, [u64; 8], u64);

    /// Output and statistics that must not depend on [`all_near`].
    fn outcome(m: &crate::Mesh) -> Outcome {
        let s = &m.stats;
        (
            m.index_points.iter().map(|p| p.map(f64::to_bits)).collect(),
            m.triangles.clone(),
            [
                s.output_triangles,
                s.samples_evaluated,
                s.split_points,
                s.projection_failures,
                s.faces_above_epsilon,
                s.cells_refined_on_faces_only,
                s.recut_polygons,
                s.max_level as u64,
            ],
            s.mean_level.to_bits(),
        )
    }

    #[test]
    fn the_output_is_the_same_with_and_without_the_bound() {
        let _one = ONE_AT_A_TIME.lock().unwrap_or_else(|e| e.into_inner());
        use crate::samples;
        let smooth = samples::smooth(40);
        let quantised = samples::smooth_u8(40);
        let ml = samples::marschner_lobb(24);
        let atoms = samples::atoms(20);
        let volumes = [
            (smooth.volume(), smooth.isovalue),
            (quantised.volume(), quantised.isovalue),
            (ml.volume(), ml.isovalue),
            (atoms.volume(), atoms.isovalue),
        ];
        let proven_before = PROVEN.load(Ordering::Relaxed);
        for (n, (volume, iso)) in volumes.iter().enumerate() {
            for (k, rule) in [Rule::A, Rule::A1, Rule::A2, Rule::B]
                .into_iter()
                .enumerate()
            {
                let options = crate::Options {
                    epsilon: [0.1, 0.01, 0.003][(n + k) % 3],
                    rule,
                    threads: 1 + (n + k) % 2,
                    ..crate::Options::default()
                };
                OFF.store(true, Ordering::Relaxed);
                let without = crate::extract(volume, *iso, &options).unwrap();
                OFF.store(false, Ordering::Relaxed);
                let with = crate::extract(volume, *iso, &options).unwrap();
                assert!(
                    outcome(&with) == outcome(&without),
                    "volume {n}, rule {rule:?}: the bound changed the output"
                );
            }
        }
        // Not vacuous: the smooth volumes have cells the bound settles.
        assert!(PROVEN.load(Ordering::Relaxed) > proven_before + 1000);
    }
}
