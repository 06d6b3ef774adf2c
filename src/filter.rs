//! Reconstruction filters: the continuous function whose isosurface `S_K`
//! the mesh approximates.
//!
//! Marching Cubes and refinement only ever ask a filter for a value and a
//! gradient at a point of one cell, so new filters plug in here without
//! touching either. That is an extension point of the crate itself:
//! [`crate::extract()`] takes one of the filters
//! [`crate::Reconstruction`] names, and a filter implemented outside the
//! crate serves [`crate::project`]'s functions (projection, the epsilon
//! test, edge crossings), not an extraction. A filter must be
//! *face-consistent*: on a face shared by two cells, both cells must return
//! bit-identical values and bit-identical gradient components along the
//! face, so that split points on shared faces are identical from both sides
//! (crack-free, piece-independent).

use glam::DVec3;

use crate::volume::{Grid, Scalar};

/// A continuous reconstruction of the samples, evaluated cell by cell.
pub trait ReconstructionFilter: Sync {
    /// What one cell needs for evaluation (e.g. its corner samples).
    type Cell: Copy + Send;

    /// Whether the filter is linear along grid edges between the two
    /// samples (trilinear), so that Marching Cubes' edge crossings already
    /// lie on its isosurface. Otherwise refinement first moves each
    /// crossing along its grid edge onto the filter's isosurface, where the
    /// filter brackets one there. Default: `false`.
    const LINEAR_ON_EDGES: bool = false;

    /// Whether the filter is multilinear over each whole cell (trilinear):
    /// then, on any axis-aligned box in a cell, its value at the midpoint
    /// of an edge, of a face or of the box is the mean of the two, four
    /// or eight corner values around it, and searches that halve boxes
    /// need not evaluate it there. Default: `false`.
    const MULTILINEAR: bool = false;

    /// Loads cell `(i, j, k)` (local cell indices). `None` when a sample
    /// the cell needs is not finite.
    fn load(&self, cell: [usize; 3]) -> Option<Self::Cell>;

    /// Value at local coordinates `p` in `[0, 1]^3` of the cell.
    fn value(cell: &Self::Cell, p: DVec3) -> f64;

    /// Gradient with respect to local (index-space) coordinates.
    fn gradient(cell: &Self::Cell, p: DVec3) -> DVec3;

    /// Value and gradient together (filters override it to share work).
    #[inline]
    fn value_gradient(cell: &Self::Cell, p: DVec3) -> (f64, DVec3) {
        (Self::value(cell, p), Self::gradient(cell, p))
    }

    /// The filter along the line `p + t d` inside one cell, when it is a
    /// cubic polynomial in `t` there: the coefficients `(a2, a3)` such
    /// that `F(p + t d) = F(p) + t ∇F(p)·d + a2 t² + a3 t³` exactly. Lets
    /// refinement search a line for `S_K` without evaluating the filter
    /// again. Face-consistent like the rest of the filter: for `p` on a
    /// shared face and `d` along it, both cells must return coefficients
    /// that give bit-identical polynomial values. Default: `None` (not a
    /// cubic along lines).
    #[inline]
    fn line_cubic(_cell: &Self::Cell, _p: DVec3, _d: DVec3) -> Option<(f64, f64)> {
        None
    }
}

#[inline(always)]
fn lerp(a: f64, b: f64, t: f64) -> f64 {
    // (1 - t) a + t b returns a exactly at t = 0 and b exactly at t = 1,
    // which makes face values bit-identical between neighbouring cells.
    (1.0 - t) * a + t * b
}

/// Value of the trilinear interpolant of corner values `c` (VTK corner
/// order, see [`crate::tables::cube`]) at local point `p`.
///
/// ```
/// let c = [0.0, 1.0, 2.0, 1.0, 1.0, 2.0, 3.0, 2.0]; // x + y + z
/// let v = precisemc::filter::trilinear_value(&c, precisemc::glam::DVec3::new(0.25, 0.5, 0.5));
/// assert!((v - 1.25).abs() < 1e-15);
/// ```
#[inline]
pub fn trilinear_value(c: &[f64; 8], p: DVec3) -> f64 {
    let r00 = lerp(c[0], c[1], p.x);
    let r10 = lerp(c[3], c[2], p.x);
    let r01 = lerp(c[4], c[5], p.x);
    let r11 = lerp(c[7], c[6], p.x);
    let s0 = lerp(r00, r10, p.y);
    let s1 = lerp(r01, r11, p.y);
    lerp(s0, s1, p.z)
}

/// Gradient (local coordinates) of the trilinear interpolant at `p`.
#[inline]
pub fn trilinear_gradient(c: &[f64; 8], p: DVec3) -> DVec3 {
    value_gradient_with(c, &x_steps(c), p).1
}

/// Value and gradient of the trilinear interpolant, sharing the work; the
/// same bits as [`trilinear_value`] and [`trilinear_gradient`].
#[inline]
pub fn trilinear_value_gradient(c: &[f64; 8], p: DVec3) -> (f64, DVec3) {
    value_gradient_with(c, &x_steps(c), p)
}

/// The changes along the cell's four x edges (`c1 - c0`, `c2 - c3`,
/// `c5 - c4`, `c6 - c7`), which the gradient's x component interpolates.
#[inline(always)]
pub(crate) fn x_steps(c: &[f64; 8]) -> [f64; 4] {
    [c[1] - c[0], c[2] - c[3], c[5] - c[4], c[6] - c[7]]
}

/// [`trilinear_value_gradient`] given the cell's [`x_steps`]: one
/// expression for both the public functions and [`TrilinearCell`], whose
/// steps are computed once a cell (so the same bits either way).
#[inline(always)]
fn value_gradient_with(c: &[f64; 8], dx: &[f64; 4], p: DVec3) -> (f64, DVec3) {
    let r00 = lerp(c[0], c[1], p.x);
    let r10 = lerp(c[3], c[2], p.x);
    let r01 = lerp(c[4], c[5], p.x);
    let r11 = lerp(c[7], c[6], p.x);
    let s0 = lerp(r00, r10, p.y);
    let s1 = lerp(r01, r11, p.y);
    let gx = lerp(lerp(dx[0], dx[1], p.y), lerp(dx[2], dx[3], p.y), p.z);
    let gy = lerp(r10 - r00, r11 - r01, p.z);
    (lerp(s0, s1, p.z), DVec3::new(gx, gy, s1 - s0))
}

/// The trilinear filter of the paper: the interpolant of each cell's eight
/// corner samples.
pub struct Trilinear<'a, T: Scalar> {
    pub(crate) grid: Grid<'a, T>,
}

impl<'a, T: Scalar> Trilinear<'a, T> {
    pub(crate) fn new(grid: Grid<'a, T>) -> Self {
        Trilinear { grid }
    }

    /// The eight corner samples of a cell, in VTK corner order.
    #[inline(always)]
    pub(crate) fn corners(&self, cell: [usize; 3]) -> [f64; 8] {
        self.grid.corners(cell)
    }
}

impl<T: Scalar> ReconstructionFilter for Trilinear<'_, T> {
    type Cell = [f64; 8];
    const LINEAR_ON_EDGES: bool = true;
    const MULTILINEAR: bool = true;

    fn load(&self, cell: [usize; 3]) -> Option<[f64; 8]> {
        let c = self.corners(cell);
        if T::FLOAT && !c.iter().all(|v| v.is_finite()) {
            return None;
        }
        Some(c)
    }

    #[inline]
    fn value(cell: &[f64; 8], p: DVec3) -> f64 {
        trilinear_value(cell, p)
    }

    #[inline]
    fn gradient(cell: &[f64; 8], p: DVec3) -> DVec3 {
        trilinear_gradient(cell, p)
    }

    #[inline]
    fn value_gradient(cell: &[f64; 8], p: DVec3) -> (f64, DVec3) {
        trilinear_value_gradient(cell, p)
    }

    #[inline]
    fn line_cubic(c: &[f64; 8], p: DVec3, d: DVec3) -> Option<(f64, f64)> {
        Some(trilinear_line_cubic(c, p, d))
    }
}

/// Coefficients `(a2, a3)` of `t²` and `t³` of the trilinear interpolant
/// along the line `p + t d`. The interpolant has degree one in each
/// coordinate, so its Hessian has a zero diagonal and its Taylor series
/// ends with the mixed third derivative: `a2 = Σ_{i<j} d_i d_j H_ij(p)`,
/// `a3 = d_x d_y d_z ∂³F/∂x∂y∂z`.
///
/// Face-consistent: on a face `x = 1` of one cell and `x = 0` of the next,
/// with `d_x = 0`, the only term that is not a signed zero is
/// `d_y d_z H_yz`, and `H_yz` there is the twist of the shared face,
/// computed from its four samples in the same order by both cells (the
/// interpolation across the cell returns its end exactly). Signed zeros differ at most in sign,
/// which leaves the polynomial's values unchanged.
///
/// ```
/// use precisemc::glam::DVec3;
/// use precisemc::filter::{trilinear_gradient, trilinear_line_cubic, trilinear_value};
/// let c = [0.3, -1.0, 2.0, 0.5, 1.5, -0.2, 0.7, 1.1];
/// let (p, d) = (DVec3::new(0.2, 0.6, 0.3), DVec3::new(0.48, -0.6, 0.64));
/// let (a2, a3) = trilinear_line_cubic(&c, p, d);
/// let t = 0.4;
/// let poly = trilinear_value(&c, p) + t * trilinear_gradient(&c, p).dot(d) + a2 * t * t + a3 * t * t * t;
/// assert!((poly - trilinear_value(&c, p + d * t)).abs() < 1e-14);
/// ```
#[inline]
pub fn trilinear_line_cubic(c: &[f64; 8], p: DVec3, d: DVec3) -> (f64, f64) {
    line_cubic_with(&twists(c), p, d)
}

/// The twists of the cell's opposite faces (xy at z = 0 and 1, xz at
/// y = 0 and 1, yz at x = 0 and 1) and its body twist, for
/// [`line_cubic_with`].
#[inline(always)]
pub(crate) fn twists(c: &[f64; 8]) -> [f64; 7] {
    [
        c[0] - c[1] + c[2] - c[3],
        c[4] - c[5] + c[6] - c[7],
        c[0] - c[1] - c[4] + c[5],
        c[3] - c[2] - c[7] + c[6],
        c[0] - c[3] - c[4] + c[7],
        c[1] - c[2] - c[5] + c[6],
        (c[1] - c[0]) + (c[3] - c[2]) + (c[4] - c[5]) + (c[6] - c[7]),
    ]
}

/// [`trilinear_line_cubic`] given the cell's [`twists`] (see
/// [`value_gradient_with`] for why one expression serves both).
#[inline(always)]
fn line_cubic_with(tw: &[f64; 7], p: DVec3, d: DVec3) -> (f64, f64) {
    // Twists of the opposite faces, interpolated across the cell.
    let hxy = lerp(tw[0], tw[1], p.z);
    let hxz = lerp(tw[2], tw[3], p.y);
    let hyz = lerp(tw[4], tw[5], p.x);
    (
        d.x * d.y * hxy + d.x * d.z * hxz + d.y * d.z * hyz,
        d.x * d.y * d.z * tw[6],
    )
}

/// A trilinear cell as refinement evaluates it, again and again: its
/// corner samples with the differences of them that every gradient and
/// every cubic along a line would otherwise compute anew (about 7 % of a
/// refined extraction's instructions: atoms 64^3, ε 0.001, level 5).
/// The same bits as the functions on
/// corner arrays ([`trilinear_value_gradient`], [`trilinear_line_cubic`]).
#[derive(Debug, Clone, Copy)]
pub(crate) struct TrilinearCell {
    c: [f64; 8],
    dx: [f64; 4],
    tw: [f64; 7],
}

impl TrilinearCell {
    #[inline]
    pub(crate) fn new(c: [f64; 8]) -> Self {
        TrilinearCell {
            c,
            dx: x_steps(&c),
            tw: twists(&c),
        }
    }
}

/// The trilinear filter with its cells as [`TrilinearCell`]s: what the
/// extraction refines with (the public [`Trilinear`] keeps corner arrays
/// as its cells). Same values, gradients and cubics to the bit.
pub(crate) struct TrilinearFast<'a, T: Scalar>(pub(crate) Trilinear<'a, T>);

impl<T: Scalar> ReconstructionFilter for TrilinearFast<'_, T> {
    type Cell = TrilinearCell;
    const LINEAR_ON_EDGES: bool = true;
    const MULTILINEAR: bool = true;

    fn load(&self, cell: [usize; 3]) -> Option<TrilinearCell> {
        self.0.load(cell).map(TrilinearCell::new)
    }

    #[inline]
    fn value(cell: &TrilinearCell, p: DVec3) -> f64 {
        trilinear_value(&cell.c, p)
    }

    #[inline]
    fn gradient(cell: &TrilinearCell, p: DVec3) -> DVec3 {
        value_gradient_with(&cell.c, &cell.dx, p).1
    }

    #[inline]
    fn value_gradient(cell: &TrilinearCell, p: DVec3) -> (f64, DVec3) {
        value_gradient_with(&cell.c, &cell.dx, p)
    }

    #[inline]
    fn line_cubic(cell: &TrilinearCell, p: DVec3, d: DVec3) -> Option<(f64, f64)> {
        Some(line_cubic_with(&cell.tw, p, d))
    }
}

/// Value and gradient (index space) of the reconstruction `filter` of
/// `volume`, evaluated in cell `cell` (local cell indices) at local
/// coordinates `local` in `[0, 1]^3`: the function refinement follows.
/// `Ok(None)` when a sample the cell needs is not finite;
/// `Err(Error::OutOfVolume)` for a cell not in the volume (each index
/// below its dimension less one) or a local coordinate outside `[0, 1]`.
/// Meant for checks and small queries: the interpolating B-spline
/// prefilters the whole volume on every call.
///
/// ```
/// use precisemc::{filter::evaluate, Reconstruction, Volume};
/// // f = x^2 on a 6^3 grid: Catmull-Rom reproduces quadratics.
/// let data: Vec<f64> = (0..216).map(|n| ((n % 6) as f64).powi(2)).collect();
/// let v = Volume::new(&data, [6, 6, 6]);
/// let (f, g) = evaluate(&v, Reconstruction::CatmullRom, [2, 2, 2], [0.25, 0.5, 0.5])
///     .unwrap()
///     .unwrap();
/// assert!((f - 2.25f64.powi(2)).abs() < 1e-12 && (g[0] - 4.5).abs() < 1e-12);
/// ```
pub fn evaluate(
    volume: &crate::Volume<'_>,
    filter: crate::Reconstruction,
    cell: [u64; 3],
    local: [f64; 3],
) -> Result<Option<(f64, [f64; 3])>, crate::Error> {
    use crate::cubic::{prefilter, BSplineKernel, CatmullRomKernel, Tricubic};
    use crate::Reconstruction as R;
    volume.validate()?;
    // (`cell[a] + 1` would wrap for u64::MAX; dims are at least 2.)
    if (0..3).any(|a| cell[a] >= volume.dims[a] - 1)
        || local.iter().any(|c| !(0.0..=1.0).contains(c))
    {
        return Err(crate::Error::OutOfVolume { cell, local });
    }
    fn at<F: ReconstructionFilter>(f: &F, cell: [u64; 3], p: DVec3) -> Option<(f64, [f64; 3])> {
        let c = f.load(cell.map(|c| c as usize))?;
        let (v, g) = F::value_gradient(&c, p);
        Some((v, g.to_array()))
    }
    let p = DVec3::from_array(local);
    Ok(crate::volume::with_grid!(volume, |grid| match filter {
        R::Trilinear => Ok(at(&Trilinear::new(grid), cell, p)),
        R::CatmullRom => Ok(at(&Tricubic::<_, CatmullRomKernel>::new(grid), cell, p)),
        R::BSpline => Ok(at(&Tricubic::<_, BSplineKernel>::new(grid), cell, p)),
        R::BSplineInterpolating => prefilter(&grid).map(|c| {
            let cv = crate::Volume::new(c.as_slice(), volume.dims);
            at(
                &Tricubic::<f64, BSplineKernel>::new(Grid::new(&c, &cv)),
                cell,
                p,
            )
        }),
    })?)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn corners_of(f: impl Fn(f64, f64, f64) -> f64) -> [f64; 8] {
        let mut c = [0.0; 8];
        for (i, p) in crate::tables::cube::CORNERS.iter().enumerate() {
            c[i] = f(p[0] as f64, p[1] as f64, p[2] as f64);
        }
        c
    }

    #[test]
    fn reproduces_trilinear_polynomials_and_gradients() {
        let f = |x: f64, y: f64, z: f64| {
            1.0 + 2.0 * x - y + 0.5 * z + 3.0 * x * y - x * z + 0.25 * y * z - 2.0 * x * y * z
        };
        let c = corners_of(f);
        for &(x, y, z) in &[(0.1, 0.2, 0.3), (0.9, 0.5, 0.01), (0.5, 0.5, 0.5)] {
            let p = DVec3::new(x, y, z);
            assert!((trilinear_value(&c, p) - f(x, y, z)).abs() < 1e-12);
            let h = 1e-6;
            let g = trilinear_gradient(&c, p);
            for a in 0..3 {
                let mut q = p;
                q[a] += h;
                let mut r = p;
                r[a] -= h;
                let num = (trilinear_value(&c, q) - trilinear_value(&c, r)) / (2.0 * h);
                assert!((g[a] - num).abs() < 1e-6);
            }
        }
    }

    #[test]
    fn shared_faces_evaluate_bit_identically() {
        // Two cells side by side along x share the face x = 1 / x = 0.
        let a = [0.3, 1.7, -2.1, 0.9, 4.4, -0.7, 1.1, 2.3];
        // b's left face (corners 0, 3, 7, 4) equals a's right face (1, 2, 6, 5).
        let b = [a[1], 5.5, -3.3, a[2], a[5], 0.1, 9.9, a[6]];
        for &(y, z) in &[(0.1234, 0.987), (0.5, 0.5), (0.333, 0.0), (1.0, 0.7)] {
            let pa = DVec3::new(1.0, y, z);
            let pb = DVec3::new(0.0, y, z);
            assert_eq!(
                trilinear_value(&a, pa).to_bits(),
                trilinear_value(&b, pb).to_bits()
            );
            let ga = trilinear_gradient(&a, pa);
            let gb = trilinear_gradient(&b, pb);
            assert_eq!(ga.y.to_bits(), gb.y.to_bits());
            assert_eq!(ga.z.to_bits(), gb.z.to_bits());
        }
    }

    #[test]
    fn cells_with_their_differences_evaluate_as_corner_arrays_do() {
        // Refinement's cells (`TrilinearCell`, differences computed once)
        // must give the bits of the public functions on corner arrays,
        // which crack-freeness and determinism rest on; and the cubic along
        // a line must reproduce the interpolant along it.
        type Fast = TrilinearFast<'static, f64>;
        let mut rng = crate::test_rng::XorShift(0x7e1f_ce11);
        let mixed = |rng: &mut crate::test_rng::XorShift| {
            // Values of very different magnitudes, signs and zeros.
            let v = (rng.unit() - 0.5) * 10f64.powi(rng.below(13) as i32 - 6);
            if rng.below(16) == 0 {
                0.0
            } else {
                v
            }
        };
        for _ in 0..2000 {
            let c: [f64; 8] = std::array::from_fn(|_| mixed(&mut rng));
            let cell = TrilinearCell::new(c);
            for _ in 0..8 {
                // Points inside, on faces and on corners.
                let p = DVec3::from_array(std::array::from_fn(|_| match rng.below(5) {
                    0 => 0.0,
                    1 => 1.0,
                    _ => rng.unit(),
                }));
                let d = DVec3::from_array(std::array::from_fn(|_| rng.unit() - 0.5));
                let (v, g) = trilinear_value_gradient(&c, p);
                let (fv, fg) = Fast::value_gradient(&cell, p);
                assert_eq!(fv.to_bits(), v.to_bits(), "{c:?} {p}");
                assert_eq!(
                    fg.to_array().map(f64::to_bits),
                    g.to_array().map(f64::to_bits)
                );
                assert_eq!(
                    Fast::value(&cell, p).to_bits(),
                    trilinear_value(&c, p).to_bits()
                );
                let fg2 = Fast::gradient(&cell, p).to_array();
                assert_eq!(
                    fg2.map(f64::to_bits),
                    trilinear_gradient(&c, p).to_array().map(f64::to_bits)
                );
                let (a2, a3) = trilinear_line_cubic(&c, p, d);
                let (fa2, fa3) = Fast::line_cubic(&cell, p, d).unwrap();
                assert_eq!((fa2.to_bits(), fa3.to_bits()), (a2.to_bits(), a3.to_bits()));
                let scale = c.iter().fold(0.0f64, |m, x| m.max(x.abs())).max(1e-300);
                for t in [-0.7, -0.2, 0.3, 0.9] {
                    let poly = v + t * g.dot(d) + a2 * t * t + a3 * t * t * t;
                    let exact = trilinear_value(&c, p + d * t);
                    assert!((poly - exact).abs() <= 1e-12 * scale, "{c:?} {p} {d} {t}");
                }
            }
        }
    }
}
