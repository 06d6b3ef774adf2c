//! Finding the point `p'` of the ideal surface `S_K` that corresponds to a
//! sample point `p` (section 3.2 of the paper).
//!
//! The paper walks along the gradient line through `p` in small steps. For
//! the trilinear filter the restriction of `F` to a line inside one cell is
//! a cubic polynomial, so we can do better and find the root nearest to
//! `p` exactly: the cubic is recovered from four evaluations spread over
//! the part of the line inside the cell, its critical points split that
//! part into monotone pieces, and the nearest piece with a sign change is
//! solved on the true function by a safeguarded Illinois (regula falsi)
//! iteration. Only evaluations of the filter are used, so the answer is a
//! pure function of `p` and the direction: on a face shared by two cells
//! both cells compute the same bits. The search never leaves the cell (so
//! the refined surface stays inside the cell of its Marching Cubes
//! triangle and cannot cross a neighbour's) and is reported as a failure
//! when the line meets no root there.

use glam::DVec3;

use crate::filter::ReconstructionFilter;

/// Result of projecting a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Projection {
    /// The point on `S_K`, in local cell coordinates.
    pub point: DVec3,
    /// Its distance to the sample point, in cell (index) units.
    pub distance: f64,
}

/// Parameter interval of the line `p + t d` inside `[0, 1]^3`.
fn clip_to_cell(p: DVec3, d: DVec3) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for a in 0..3 {
        if d[a] != 0.0 {
            let t0 = (0.0 - p[a]) / d[a];
            let t1 = (1.0 - p[a]) / d[a];
            lo = lo.max(t0.min(t1));
            hi = hi.min(t0.max(t1));
        } else if p[a] < 0.0 || p[a] > 1.0 {
            return None;
        }
    }
    if lo.is_finite() && hi.is_finite() && lo <= hi {
        Some((lo.min(0.0), hi.max(0.0)))
    } else {
        None
    }
}

/// `g` with the components of the axes set in `fixed` zeroed (bit `a`:
/// coordinate `a` is held, as for points on a cell face).
#[inline]
fn without_fixed(mut g: DVec3, fixed: u8) -> DVec3 {
    for a in 0..3 {
        if fixed & (1 << a) != 0 {
            g[a] = 0.0;
        }
    }
    g
}

/// Projects `p` (local coordinates of a cell) onto `F = iso` along the
/// gradient line, restricted to the axes not set in `fixed` (bit `a` set:
/// the coordinate `a` is held, as for points on a cell face). Returns
/// `None` when the gradient vanishes or the line has no root in the cell.
pub fn project<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    p: DVec3,
    fixed: u8,
) -> Option<Projection> {
    let g = without_fixed(F::gradient(cell, p), fixed);
    let len = g.length();
    if !(len > 0.0 && len.is_finite()) {
        return None;
    }
    let d = g / len;
    let (lo, hi) = clip_to_cell(p, d)?;
    // Where the filter is a cubic along lines, its polynomial stands in for
    // it: a few operations a value, where the filter's own evaluation took
    // several times that (the search below takes a dozen or more).
    let cubic = F::line_cubic(cell, p, d);
    let q0 = F::value(cell, p) - iso;
    let q = |t: f64| match cubic {
        Some((a2, a3)) => q0 + t * (len + t * (a2 + t * a3)),
        None => F::value(cell, p + d * t) - iso,
    };
    if q0 == 0.0 {
        return Some(Projection {
            point: p,
            distance: 0.0,
        });
    }
    // Cubic through four evaluations (Newton form on s in [0, 1]).
    let w = hi - lo;
    if w <= 0.0 {
        return None;
    }
    let y = [q(lo), q(lo + w / 3.0), q(lo + 2.0 * w / 3.0), q(hi)];
    // Divided differences with nodes 0, 1/3, 2/3, 1.
    let d1 = [
        (y[1] - y[0]) * 3.0,
        (y[2] - y[1]) * 3.0,
        (y[3] - y[2]) * 3.0,
    ];
    let d2 = [(d1[1] - d1[0]) * 1.5, (d1[2] - d1[1]) * 1.5];
    let d3 = d2[1] - d2[0];
    // Monomial coefficients of c0 + c1 s + c2 s^2 + c3 s^3.
    // N(s) = y0 + d1_0 s + d2_0 s (s - 1/3) + d3 s (s - 1/3)(s - 2/3)
    let c3 = d3;
    let c2 = d2[0] - d3;
    let c1 = d1[0] - d2[0] / 3.0 + d3 * (2.0 / 9.0);
    // Critical points of the cubic split [0, 1] into monotone pieces.
    let mut cuts = [0.0f64; 6];
    let mut ncuts = 2;
    cuts[1] = 1.0;
    let (a, b, c) = (3.0 * c3, 2.0 * c2, c1);
    let scale = a.abs().max(b.abs()).max(c.abs());
    if scale > 0.0 {
        if a.abs() > 1e-12 * scale {
            let disc = b * b - 4.0 * a * c;
            if disc >= 0.0 {
                let s = disc.sqrt();
                let qq = -0.5 * (b + if b < 0.0 { -s } else { s });
                for r in [qq / a, if qq != 0.0 { c / qq } else { f64::NAN }] {
                    if r > 0.0 && r < 1.0 {
                        cuts[ncuts] = r;
                        ncuts += 1;
                    }
                }
            }
        } else if b != 0.0 {
            let r = -c / b;
            if r > 0.0 && r < 1.0 {
                cuts[ncuts] = r;
                ncuts += 1;
            }
        }
    }
    // The point p itself (t = 0) is a cut too, so pieces lie on one side.
    let s0 = -lo / w;
    if s0 > 0.0 && s0 < 1.0 {
        cuts[ncuts] = s0;
        ncuts += 1;
    }
    let cuts = &mut cuts[..ncuts];
    cuts.sort_by(|x, y| x.total_cmp(y));
    // Pieces ordered by their distance from t = 0.
    let mut pieces = [(0.0f64, 0.0f64, 0.0f64); 5];
    let mut npieces = 0;
    for wnd in cuts.windows(2) {
        if wnd[1] <= wnd[0] {
            continue;
        }
        // t = 0 must be an exact piece end so q(0) is reused bit-exactly.
        let ta = if wnd[0] == s0 { 0.0 } else { lo + wnd[0] * w };
        let tb = if wnd[1] == s0 { 0.0 } else { lo + wnd[1] * w };
        let near = if ta <= 0.0 && tb >= 0.0 {
            0.0
        } else {
            ta.abs().min(tb.abs())
        };
        pieces[npieces] = (near, ta, tb);
        npieces += 1;
    }
    let pieces = &mut pieces[..npieces];
    pieces.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.total_cmp(&y.1)));
    let mut best: Option<f64> = None;
    for &mut (near, ta, tb) in pieces {
        if let Some(bt) = best {
            if near >= bt.abs() {
                break;
            }
        }
        let (qa, qb) = (
            if ta == 0.0 { q0 } else { q(ta) },
            if tb == 0.0 { q0 } else { q(tb) },
        );
        if qa == 0.0 || qb == 0.0 || (qa < 0.0) != (qb < 0.0) {
            let t = solve(&q, ta, qa, tb, qb);
            if best.map_or(true, |bt| t.abs() < bt.abs()) {
                best = Some(t);
            }
        }
    }
    let t = best?;
    let point = p + d * t;
    Some(Projection {
        point,
        distance: t.abs(),
    })
}

/// Outcome of testing a sample point against epsilon.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Test {
    /// `S_K` is within epsilon of the point.
    Near,
    /// The nearest point of `S_K` is farther than epsilon: split there.
    Far(DVec3),
    /// No point of `S_K` on the gradient line inside the cell.
    Failed,
}

/// Decides whether `p` is within `epsilon` of `S_K` along the gradient line
/// (with the same fixed axes as [`project`]). Usually settled without
/// [`project`]: a near sample by one value at `epsilon` in the Newton
/// direction, a far one by a walk that brackets the root. When the filter
/// is a cubic along lines ([`ReconstructionFilter::line_cubic`]) the walk
/// runs on that polynomial (Halley steps) instead of evaluating the filter.
/// On the polynomial the line is parametrised by the gradient itself,
/// `p + s ∇F`, which keeps divisions off the common path. A pure function of its arguments,
/// like [`project`].
pub fn test<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    p: DVec3,
    fixed: u8,
    epsilon: f64,
) -> Test {
    test_from::<F>(cell, iso, p, F::value_gradient(cell, p), fixed, epsilon)
}

/// [`test()`], given the filter's value and gradient at `p` (as
/// [`ReconstructionFilter::value_gradient`] returns them). Always inlined,
/// for the reason [`crate::refine`]'s `sample_from` is.
#[inline(always)]
pub(crate) fn test_from<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    p: DVec3,
    (v0, g0): (f64, DVec3),
    fixed: u8,
    epsilon: f64,
) -> Test {
    let mask = |g: DVec3| without_fixed(g, fixed);
    let g = mask(g0);
    let len2 = g.length_squared();
    if len2 > 0.0 && len2.is_finite() {
        let q0 = v0 - iso;
        if q0 == 0.0 {
            return Test::Near;
        }
        let found = match F::line_cubic(cell, p, g) {
            // On the polynomial the line is parametrised by the gradient
            // itself, p + s g: no normalisation, and epsilon is compared
            // without a division.
            Some((a2, a3)) => {
                let line = Line {
                    p,
                    g,
                    q0,
                    slope0: len2,
                    reach: epsilon / len2.sqrt(),
                };
                let q = |s: f64| q0 + s * (len2 + s * (a2 + s * a3));
                let halley = |s: f64| {
                    let q = q(s);
                    let q1 = len2 + s * (2.0 * a2 + 3.0 * a3 * s);
                    let q2 = 2.0 * a2 + 6.0 * a3 * s;
                    (q, -2.0 * q * q1 / (2.0 * q1 * q1 - q * q2))
                };
                line.walk(q, || halley(0.0).1, halley)
                    .map(|r| r.map(|s| p + g * s))
            }
            // On the filter, by distance along the unit direction.
            None => {
                let len = len2.sqrt();
                let d = g / len;
                let line = Line {
                    p,
                    g: d,
                    q0,
                    slope0: len,
                    reach: epsilon,
                };
                line.walk(
                    |t| F::value(cell, p + d * t) - iso,
                    || -q0 / len,
                    |t| {
                        let (v, gt) = F::value_gradient(cell, p + d * t);
                        let q = v - iso;
                        (q, -q / mask(gt).dot(d))
                    },
                )
                .map(|r| r.map(|t| p + d * t))
            }
        };
        match found {
            Some(None) => return Test::Near,
            Some(Some(q)) => return Test::Far(q),
            None => {}
        }
    }
    match project::<F>(cell, iso, p, fixed) {
        None => Test::Failed,
        Some(pr) if pr.distance > epsilon => Test::Far(pr.point),
        Some(_) => Test::Near,
    }
}

/// A gradient line through a sample point, for [`test()`]: `q(s) = F - iso`
/// at `p + s g` (`g` the gradient or its unit direction), with `q(0) = q0`
/// and `q'(0) = slope0`; `reach` is epsilon in units of `s`.
struct Line {
    p: DVec3,
    g: DVec3,
    q0: f64,
    slope0: f64,
    reach: f64,
}

impl Line {
    /// `Some(None)`: a root within epsilon; `Some(Some(s))`: the root the
    /// walk brackets, farther than epsilon; `None`: undecided. `q(s)` gives
    /// the value, `q_step(s)` the value and the step to take from `s` (a
    /// Newton or Halley step), `step0()` the step from 0.
    #[inline(always)]
    fn walk(
        &self,
        q: impl Fn(f64) -> f64,
        step0: impl FnOnce() -> f64,
        q_step: impl Fn(f64) -> (f64, f64),
    ) -> Option<Option<f64>> {
        let &Line {
            p,
            g,
            q0,
            slope0,
            reach,
        } = self;
        let inside = |s: f64| {
            let x = p + g * s;
            x.cmpge(DVec3::ZERO).all() && x.cmple(DVec3::ONE).all()
        };
        // Most samples are near: when the first Newton step (-q0 / slope0)
        // stays within epsilon, one value at epsilon in its direction
        // (inside the cell) settles it if the sign changes there. The
        // cell's bounds on the line cost six divisions: they are computed
        // only when the point at epsilon lies outside the cell.
        if q0.abs() <= reach * slope0 {
            let mut se = if q0 > 0.0 { -reach } else { reach };
            if !inside(se) {
                let (lo, hi) = clip_to_cell(p, g)?;
                se = se.clamp(lo, hi);
            }
            let qe = q(se);
            if qe == 0.0 || (qe < 0.0) != (q0 < 0.0) {
                return Some(None);
            }
        }
        let tol = 1e-13 * q0.abs();
        // Walk along the line until it brackets a root.
        let (mut s, mut qs, mut step) = (0.0, q0, step0());
        for _ in 0..6 {
            let sn = s + step;
            if !(sn.is_finite() && inside(sn)) {
                return None;
            }
            let (qn, stepn) = q_step(sn);
            if qn.abs() > tol && (qn < 0.0) == (q0 < 0.0) {
                s = sn;
                qs = qn;
                step = stepn;
                continue;
            }
            // A root lies between s and sn (both on one side of 0).
            if s.abs().max(sn.abs()) <= reach {
                return Some(None);
            }
            let r = if qn.abs() <= tol {
                sn
            } else {
                solve(&q, s, qs, sn, qn)
            };
            return Some((r.abs() > reach).then_some(r));
        }
        None
    }
}

/// Quick estimate of whether `p` is farther than `epsilon` from `S_K`: no
/// sign change of `F - iso` between `p` and the two points `epsilon` away
/// along the gradient line (clamped to the cell). Used only for
/// statistics. The Newton direction is tried first: for a near sample
/// that usually settles it with one more value.
pub fn seems_far<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    p: DVec3,
    fixed: u8,
    epsilon: f64,
) -> bool {
    let (v0, g) = F::value_gradient(cell, p);
    let g = without_fixed(g, fixed);
    let len = g.length();
    let q0 = v0 - iso;
    if !(len > 0.0 && len.is_finite()) || q0 == 0.0 {
        return false;
    }
    let d = g / len * epsilon;
    let toward = if q0 > 0.0 { -d } else { d };
    [toward, -toward].into_iter().all(|s| {
        let q = F::value(cell, (p + s).clamp(DVec3::ZERO, DVec3::ONE)) - iso;
        q != 0.0 && (q < 0.0) == (q0 < 0.0)
    })
}

/// Where the filter crosses `iso` on the grid edge of `cell` from the
/// local corner `corner` along `axis`, as a parameter in `[0, 1]`; `None`
/// when its values at the two ends do not bracket `iso`, or `axis` is not
/// 0, 1 or 2. Evaluates the filter on the edge only, so every cell around
/// the edge finds the same bits (face consistency, see [`crate::filter`]).
pub fn edge_crossing<F: ReconstructionFilter>(
    cell: &F::Cell,
    iso: f64,
    corner: DVec3,
    axis: usize,
) -> Option<f64> {
    if axis > 2 {
        return None;
    }
    let mut dir = DVec3::ZERO;
    dir[axis] = 1.0;
    let q = |s: f64| F::value(cell, corner + dir * s) - iso;
    let (q0, q1) = (q(0.0), q(1.0));
    if !(q0.is_finite() && q1.is_finite()) || (q0 > 0.0 && q1 > 0.0) || (q0 < 0.0 && q1 < 0.0) {
        return None;
    }
    Some(solve(&q, 0.0, q0, 1.0, q1))
}

/// Root of `q` in `[a, b]` with `q(a)`, `q(b)` of opposite signs (or zero):
/// Illinois iteration, falling back to bisection when it stalls.
pub(crate) fn solve(
    q: &impl Fn(f64) -> f64,
    mut a: f64,
    mut qa: f64,
    mut b: f64,
    mut qb: f64,
) -> f64 {
    if qa == 0.0 {
        return a;
    }
    if qb == 0.0 {
        return b;
    }
    // Residual small enough for any use (values are f64 samples).
    let tol = 1e-14 * qa.abs().max(qb.abs());
    // The bracket is narrow enough relative to itself and to its ends, not
    // to 1: a line parametrised by the gradient (see `test_from`) brackets
    // roots within 1e-9 of 0 on data of magnitude 1e9, and a width absolute
    // in that parameter ended the search after one step, 4.5e-4 cells
    // off `S_K` (from 1e18 up).
    let w0 = (b - a).abs();
    let mut side = 0i8;
    for it in 0..200 {
        let width = (b - a).abs();
        if width <= 1e-15 * (w0 + a.abs().max(b.abs())) {
            break;
        }
        let mut t = (a * qb - b * qa) / (qb - qa);
        if !(t > a.min(b) && t < a.max(b)) || it % 8 == 7 {
            t = 0.5 * (a + b);
        }
        let qt = q(t);
        if qt.abs() <= tol {
            return t;
        }
        if (qt < 0.0) == (qb < 0.0) {
            b = t;
            qb = qt;
            if side == -1 {
                qa *= 0.5;
            }
            side = -1;
        } else {
            a = t;
            qa = qt;
            if side == 1 {
                qb *= 0.5;
            }
            side = 1;
        }
    }
    if qa.abs() <= qb.abs() {
        a
    } else {
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::{trilinear_value, Trilinear};
    use crate::volume::Grid;

    type Tri = Trilinear<'static, f64>;

    #[test]
    fn lands_on_the_surface_within_the_cell() {
        let c = [-1.0, 0.5, 2.0, 0.2, 0.3, 1.5, -0.4, 0.9];
        for &(x, y, z) in &[(0.2, 0.2, 0.2), (0.5, 0.5, 0.5), (0.8, 0.1, 0.6)] {
            let p = DVec3::new(x, y, z);
            // Each point's gradient line meets S_K inside the cell.
            let pr =
                project::<Tri>(&c, 0.1, p, 0).unwrap_or_else(|| panic!("no projection from {p}"));
            let v = trilinear_value(&c, pr.point);
            assert!((v - 0.1).abs() < 1e-12, "{v}");
            assert!(pr.point.min_element() >= 0.0 && pr.point.max_element() <= 1.0);
            assert!(((pr.point - p).length() - pr.distance).abs() < 1e-12);
        }
        let _ = Grid::<f64>::new; // keep the type in scope for the alias
    }

    /// Uniform numbers in [0, 1) from a seed (a linear congruential
    /// generator: reproducible, no dependency).
    fn uniform(mut x: u64) -> impl FnMut() -> f64 {
        move || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The trilinear filter without its line polynomial: `test` then
    /// evaluates the filter along the line.
    struct Evaluated;
    impl ReconstructionFilter for Evaluated {
        type Cell = [f64; 8];
        fn load(&self, _: [usize; 3]) -> Option<[f64; 8]> {
            None
        }
        fn value(c: &[f64; 8], p: DVec3) -> f64 {
            trilinear_value(c, p)
        }
        fn gradient(c: &[f64; 8], p: DVec3) -> DVec3 {
            crate::filter::trilinear_gradient(c, p)
        }
    }

    #[test]
    fn the_line_polynomial_decides_like_the_filter() {
        // Random cells, sample points at distances around epsilon from
        // S_K: the walk on the polynomial must reach the same decisions
        // and the same split points as the walk on filter values.
        let mut rnd = uniform(7);
        let (mut near, mut far) = (0, 0);
        for n in 0..20000 {
            let c: [f64; 8] = std::array::from_fn(|_| rnd() * 2.0 - 1.0);
            let p = DVec3::new(rnd(), rnd(), rnd());
            let g = crate::filter::trilinear_gradient(&c, p);
            let dist = [0.0003, 0.0009, 0.0011, 0.004, 0.03, 0.2][n % 6];
            let iso =
                trilinear_value(&c, p) + g.length() * dist * if n % 2 == 0 { 1.0 } else { -1.0 };
            let eps = 0.001;
            let a = test::<Tri>(&c, iso, p, 0, eps);
            let b = test::<Evaluated>(&c, iso, p, 0, eps);
            match (a, b) {
                (Test::Near, Test::Near) => near += 1,
                (Test::Failed, Test::Failed) => {}
                (Test::Far(qa), Test::Far(qb)) => {
                    far += 1;
                    assert!((qa - qb).length() < 1e-12, "{qa} vs {qb}");
                    assert!((trilinear_value(&c, qa) - iso).abs() < 1e-13);
                }
                _ => panic!("cell {c:?}, p {p}, iso {iso}: {a:?} vs {b:?}"),
            }
        }
        assert!(near > 5000 && far > 5000, "{near} near, {far} far");
    }

    #[test]
    fn shared_faces_decide_bit_identically() {
        // Two cells sharing a face, for each axis: a sample point on the
        // face, tested with that axis fixed, must give the same decision
        // and the same split point (up to the fixed coordinate) from both.
        use crate::tables::cube::CORNERS;
        let mut rnd = uniform(99);
        let mut far = 0;
        for n in 0..6000 {
            let axis = n % 3;
            // Samples of a 2-cell block along `axis`: 12 values.
            let vals: Vec<f64> = (0..12).map(|_| rnd() * 2.0 - 1.0).collect();
            let at = |cell: usize, k: usize| {
                let c = CORNERS[k];
                let mut q = [c[0] as usize, c[1] as usize, c[2] as usize];
                q[axis] += cell;
                let (u, v) = match axis {
                    0 => (q[1], q[2]),
                    1 => (q[0], q[2]),
                    _ => (q[0], q[1]),
                };
                vals[q[axis] * 4 + v * 2 + u]
            };
            let a: [f64; 8] = std::array::from_fn(|k| at(0, k));
            let b: [f64; 8] = std::array::from_fn(|k| at(1, k));
            let mut pa = DVec3::new(rnd(), rnd(), rnd());
            pa[axis] = 1.0;
            let mut pb = pa;
            pb[axis] = 0.0;
            let iso = trilinear_value(&a, pa) + (rnd() - 0.5) * 0.05;
            let fixed = 1u8 << axis;
            match (
                test::<Tri>(&a, iso, pa, fixed, 0.001),
                test::<Tri>(&b, iso, pb, fixed, 0.001),
            ) {
                (Test::Far(qa), Test::Far(qb)) => {
                    far += 1;
                    assert_eq!((qa[axis], qb[axis]), (1.0, 0.0));
                    for k in (0..3).filter(|&k| k != axis) {
                        assert_eq!(qa[k].to_bits(), qb[k].to_bits(), "{qa} vs {qb}");
                    }
                }
                (ra, rb) => assert_eq!(ra == Test::Near, rb == Test::Near, "{ra:?} vs {rb:?}"),
            }
        }
        assert!(far > 1000, "{far} far samples");
    }

    #[test]
    fn face_points_stay_on_the_face() {
        let c = [-1.0, 0.5, 2.0, 0.2, 0.3, 1.5, -0.4, 0.9];
        let p = DVec3::new(0.0, 0.4, 0.5);
        let pr = project::<Tri>(&c, 0.1, p, 1).unwrap();
        assert_eq!(pr.point.x, 0.0);
        assert!((trilinear_value(&c, pr.point) - 0.1).abs() < 1e-12);
    }
}
