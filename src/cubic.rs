//! Tricubic reconstruction filters: Catmull–Rom and the cubic B-spline
//! (on the samples, or on coefficients prefiltered so that the B-spline
//! interpolates the samples).
//!
//! Each is a tensor product of a 1-D cubic kernel over the 4x4x4 samples
//! around a cell (indices clamped at the volume's border: the border
//! sample is repeated). The paper's refinement only needs a value and a
//! gradient, so these filters plug into it through
//! [`ReconstructionFilter`]; Marching Cubes still takes its topology from
//! the samples (the trilinear decision), its edge vertices move along
//! their grid edge onto the cubic isosurface, and split points follow it.
//!
//! Face consistency (crack-freeness): on a face shared by two cells, the
//! kernel weights across the face are those at `t = 1` in one cell and at
//! `t = 0` in the other. Both kernels are evaluated from integer
//! polynomial coefficients, so these weights are exact, equal as
//! sequences once shifted by one sample, and zero where they differ; the
//! sums run in a fixed order, and adding an exact zero changes nothing, so
//! both cells compute bit-identical values and in-face gradients.
//!
//! The clamped border differs from a piece's border in a distributed run:
//! pieces must carry two extra layers of samples (ghost level 2) for the
//! cubic filters to give identical results on the shared layer (one for
//! the piece's own cells' neighbourhoods, the second so that its ghost
//! cells compute what the serial run does there), and the interpolating
//! B-spline's prefilter needs the whole volume (see the crate docs for what
//! pieces need in general).

use std::marker::PhantomData;

use glam::DVec3;

use crate::filter::ReconstructionFilter;
use crate::volume::{Grid, Scalar};

/// A 1-D cubic kernel: weights of the four samples at offsets -1, 0, 1, 2
/// for a point at `t` in `[0, 1]` between samples 0 and 1.
pub trait Kernel: Sync + Send + 'static {
    /// Weights at `t`.
    fn weights(t: f64) -> [f64; 4];
    /// Derivatives of the weights with respect to `t`.
    fn derivatives(t: f64) -> [f64; 4];
}

/// The Catmull–Rom spline (interpolating, C1, reproduces quadratics).
pub struct CatmullRomKernel;

impl Kernel for CatmullRomKernel {
    #[inline]
    fn weights(t: f64) -> [f64; 4] {
        // (1/2) [-t^3 + 2t^2 - t, 3t^3 - 5t^2 + 2, -3t^3 + 4t^2 + t, t^3 - t^2]
        let t2 = t * t;
        let t3 = t2 * t;
        [
            (-t3 + 2.0 * t2 - t) * 0.5,
            (3.0 * t3 - 5.0 * t2 + 2.0) * 0.5,
            (-3.0 * t3 + 4.0 * t2 + t) * 0.5,
            (t3 - t2) * 0.5,
        ]
    }
    #[inline]
    fn derivatives(t: f64) -> [f64; 4] {
        let t2 = t * t;
        [
            (-3.0 * t2 + 4.0 * t - 1.0) * 0.5,
            (9.0 * t2 - 10.0 * t) * 0.5,
            (-9.0 * t2 + 8.0 * t + 1.0) * 0.5,
            (3.0 * t2 - 2.0 * t) * 0.5,
        ]
    }
}

/// The uniform cubic B-spline (approximating, C2, reproduces linear
/// functions; interpolating after prefiltering).
pub struct BSplineKernel;

impl Kernel for BSplineKernel {
    #[inline]
    fn weights(t: f64) -> [f64; 4] {
        // (1/6) [(1-t)^3, 3t^3 - 6t^2 + 4, -3t^3 + 3t^2 + 3t + 1, t^3]
        let t2 = t * t;
        let t3 = t2 * t;
        let s = 1.0 - t;
        [
            s * s * s / 6.0,
            (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
            (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
            t3 / 6.0,
        ]
    }
    #[inline]
    fn derivatives(t: f64) -> [f64; 4] {
        let t2 = t * t;
        let s = 1.0 - t;
        [
            -3.0 * s * s / 6.0,
            (9.0 * t2 - 12.0 * t) / 6.0,
            (-9.0 * t2 + 6.0 * t + 3.0) / 6.0,
            3.0 * t2 / 6.0,
        ]
    }
}

/// A tricubic filter over a grid of coefficients (the samples themselves,
/// or prefiltered ones) with kernel `K`.
pub struct Tricubic<'a, T: Scalar, K: Kernel> {
    grid: Grid<'a, T>,
    kernel: PhantomData<K>,
}

impl<'a, T: Scalar, K: Kernel> Tricubic<'a, T, K> {
    pub(crate) fn new(grid: Grid<'a, T>) -> Self {
        Tricubic {
            grid,
            kernel: PhantomData,
        }
    }
}

/// The 4x4x4 coefficients around a cell, x fastest (offsets -1..=2).
pub type Neighbourhood = [f64; 64];

#[inline]
fn weighted(cell: &Neighbourhood, wx: [f64; 4], wy: [f64; 4], wz: [f64; 4]) -> f64 {
    // Fixed order: x innermost, then y, then z (see the module docs).
    let mut v = 0.0;
    for (k, &cz) in wz.iter().enumerate() {
        let mut plane = 0.0;
        for (j, &cy) in wy.iter().enumerate() {
            let row = &cell[16 * k + 4 * j..16 * k + 4 * j + 4];
            let r = ((wx[0] * row[0] + wx[1] * row[1]) + wx[2] * row[2]) + wx[3] * row[3];
            plane += cy * r;
        }
        v += cz * plane;
    }
    v
}

impl<T: Scalar, K: Kernel> ReconstructionFilter for Tricubic<'_, T, K> {
    type Cell = Neighbourhood;

    fn load(&self, [i, j, k]: [usize; 3]) -> Option<Neighbourhood> {
        let g = &self.grid;
        let clamp = |c: usize, d: i64, n: usize| (c as i64 + d).clamp(0, n as i64 - 1) as usize;
        let mut out = [0.0; 64];
        for dz in 0..4 {
            let z = clamp(k, dz - 1, g.dims[2]);
            for dy in 0..4 {
                let y = clamp(j, dy - 1, g.dims[1]);
                for dx in 0..4 {
                    let x = clamp(i, dx - 1, g.dims[0]);
                    let v = g.get(x, y, z);
                    if !v.is_finite() {
                        return None;
                    }
                    out[(16 * dz + 4 * dy + dx) as usize] = v;
                }
            }
        }
        Some(out)
    }

    #[inline]
    fn value(cell: &Neighbourhood, p: DVec3) -> f64 {
        weighted(cell, K::weights(p.x), K::weights(p.y), K::weights(p.z))
    }

    #[inline]
    fn gradient(cell: &Neighbourhood, p: DVec3) -> DVec3 {
        let (wx, wy, wz) = (K::weights(p.x), K::weights(p.y), K::weights(p.z));
        let (dx, dy, dz) = (
            K::derivatives(p.x),
            K::derivatives(p.y),
            K::derivatives(p.z),
        );
        DVec3::new(
            weighted(cell, dx, wy, wz),
            weighted(cell, wx, dy, wz),
            weighted(cell, wx, wy, dz),
        )
    }
}

/// Coefficients of the interpolating cubic B-spline of the samples of
/// `grid`, contiguous (x fastest): along each axis in turn, each line
/// `s` is replaced by the `c` solving `(c[k-1] + 4 c[k] + c[k+1]) / 6 =
/// s[k]`, with `c[-1] = c[0]` and `c[n] = c[n-1]` (the clamped border of
/// [`Tricubic`]), by the Thomas algorithm (the system is diagonally
/// dominant). One `f64` per sample: the only copy of the volume the
/// project makes, and only for this filter. A non-finite sample (NaN or
/// infinite) splits its lines: each run of finite samples is solved on its
/// own, with the clamped border at the run's ends, and the non-finite
/// sample stays as it is. Solved whole, one such sample would make every
/// coefficient of its lines non-finite, then, axis after axis, of the
/// whole volume, and every cell would be skipped; this way only the cells
/// whose 4x4x4 neighbourhood reaches it are.
pub(crate) fn prefilter<T: Scalar>(grid: &Grid<'_, T>) -> Result<Vec<f64>, crate::Error> {
    let [nx, ny, nz] = grid.dims;
    let n = nx * ny * nz;
    let mut c = Vec::new();
    crate::memory::reserve(&mut c, n)?;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                c.push(grid.get(i, j, k));
            }
        }
    }
    let mut scratch = vec![0.0f64; nx.max(ny).max(nz)];
    let mut line = vec![0.0f64; nx.max(ny).max(nz)];
    let strides = [1, nx, nx * ny];
    for axis in 0..3 {
        let len = grid.dims[axis];
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for b in 0..grid.dims[v] {
            for a in 0..grid.dims[u] {
                let base = a * strides[u] + b * strides[v];
                for t in 0..len {
                    line[t] = c[base + t * strides[axis]];
                }
                let mut start = 0;
                while start < len {
                    if !line[start].is_finite() {
                        start += 1;
                        continue;
                    }
                    let end = line[start..len]
                        .iter()
                        .position(|v| !v.is_finite())
                        .map_or(len, |r| start + r);
                    solve_line(&mut line[start..end], &mut scratch[start..end]);
                    start = end;
                }
                for t in 0..len {
                    c[base + t * strides[axis]] = line[t];
                }
            }
        }
    }
    Ok(c)
}

/// Coefficients of the cubic B-spline that interpolates the samples of
/// `volume` (the prefilter of [`crate::Reconstruction::BSplineInterpolating`]),
/// one `f64` per sample, contiguous with x fastest, same dims. The plain
/// B-spline ([`crate::Reconstruction::BSpline`]) of a volume made of these
/// coefficients is the interpolating B-spline of `volume`: use it to
/// evaluate that filter many times (e.g. with [`crate::filter::evaluate`])
/// without prefiltering on every call. Errors: invalid volume, or out of
/// memory for the copy.
///
/// ```
/// use precisemc::{cubic::bspline_coefficients, filter::evaluate, Reconstruction, Volume};
/// let data: Vec<f32> = (0..125).map(|n| ((n * 7919) % 13) as f32).collect();
/// let v = Volume::new(&data, [5, 5, 5]);
/// let c = bspline_coefficients(&v).unwrap();
/// let cv = Volume::new(&c, [5, 5, 5]);
/// let a = evaluate(&v, Reconstruction::BSplineInterpolating, [1, 2, 3], [0.3, 0.6, 0.1]);
/// let b = evaluate(&cv, Reconstruction::BSpline, [1, 2, 3], [0.3, 0.6, 0.1]);
/// let (a, b) = (a.unwrap().unwrap(), b.unwrap().unwrap());
/// assert!((a.0 - b.0).abs() < 1e-12);
/// ```
pub fn bspline_coefficients(volume: &crate::Volume<'_>) -> Result<Vec<f64>, crate::Error> {
    volume.validate()?;
    crate::volume::with_grid!(volume, |grid| prefilter(&grid))
}

/// Solves the B-spline interpolation system of one line in place.
fn solve_line(s: &mut [f64], cp: &mut [f64]) {
    let n = s.len();
    if n == 1 {
        return;
    }
    // Rows: diagonal 5/6 at both ends (clamped border), 4/6 inside;
    // off-diagonals 1/6. Forward sweep, then back substitution.
    let off = 1.0 / 6.0;
    let diag = |k: usize| {
        if k == 0 || k == n - 1 {
            5.0 / 6.0
        } else {
            4.0 / 6.0
        }
    };
    let mut m = diag(0);
    cp[0] = off / m;
    s[0] /= m;
    for k in 1..n {
        m = diag(k) - off * cp[k - 1];
        cp[k] = off / m;
        s[k] = (s[k] - off * s[k - 1]) / m;
    }
    for k in (0..n - 1).rev() {
        s[k] -= cp[k] * s[k + 1];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernels_are_partitions_of_unity_and_exact_at_the_ends() {
        for t in [0.0, 0.1, 0.37, 0.5, 0.99, 1.0] {
            for w in [CatmullRomKernel::weights(t), BSplineKernel::weights(t)] {
                assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-15);
            }
            for d in [
                CatmullRomKernel::derivatives(t),
                BSplineKernel::derivatives(t),
            ] {
                assert!(d.iter().sum::<f64>().abs() < 1e-15);
            }
        }
        // Shifted by one sample, the end weights agree bit for bit.
        let (a, b) = (
            CatmullRomKernel::weights(1.0),
            CatmullRomKernel::weights(0.0),
        );
        assert_eq!([a[1], a[2], a[3]], [b[0], b[1], b[2]]);
        assert_eq!((a[0], b[3]), (0.0, 0.0));
        let (a, b) = (BSplineKernel::weights(1.0), BSplineKernel::weights(0.0));
        assert_eq!([a[1], a[2], a[3]], [b[0], b[1], b[2]]);
        assert_eq!((a[0], b[3]), (0.0, 0.0));
    }

    #[test]
    fn prefiltered_line_interpolates() {
        let s: Vec<f64> = (0..9).map(|k| ((k * k) as f64).sin()).collect();
        let mut c = s.clone();
        let mut scratch = vec![0.0; 9];
        solve_line(&mut c, &mut scratch);
        for k in 0..9 {
            let l = c[k.max(1) - 1];
            let r = c[(k + 1).min(8)];
            assert!(((l + 4.0 * c[k] + r) / 6.0 - s[k]).abs() < 1e-12);
        }
    }
}
