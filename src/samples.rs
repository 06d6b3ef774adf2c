//! Built-in sample volumes (generated in code, no data files).
//!
//! They show where refinement onto the trilinear isosurface matters: a thin
//! tube (below two cells across, where Marching Cubes turns round sections
//! into flat facets), an electron-density-like map of Gaussian atoms with
//! thin bridges (the paper's SOD example), the Marschner–Lobb test signal,
//! and a large smooth field for throughput measurements. Every sample is a
//! pure function of its size: the same call always gives the same bits.
//!
//! ```
//! use precisemc::{extract, samples, Options};
//! let tube = samples::tube(9);
//! let mesh = extract(&tube.volume(), tube.isovalue, &Options::default()).unwrap();
//! assert!(mesh.stats.output_triangles > mesh.stats.mc_triangles);
//! ```

use std::f64::consts::PI;

use crate::{Samples, Volume};

/// A generated volume: samples (x fastest), dimensions, and the isovalue
/// it is made for. Spacing 1 and origin 0 (index space = world space).
#[derive(Debug, Clone)]
pub struct SampleVolume<T = f32> {
    /// Short name (`"tube"`, `"atoms"`, `"ml"`, `"smooth"`, `"smooth_u8"`).
    pub name: &'static str,
    /// Samples per axis.
    pub dims: [u64; 3],
    /// The isovalue the sample is made for (in sample units).
    pub isovalue: f64,
    /// The samples, `dims[0] * dims[1] * dims[2]` of them, x fastest.
    pub data: Vec<T>,
}

impl<T> SampleVolume<T>
where
    for<'a> &'a [T]: Into<Samples<'a>>,
{
    /// The samples as a [`Volume`] (contiguous, spacing 1, origin 0).
    pub fn volume(&self) -> Volume<'_> {
        Volume::new(self.data.as_slice(), self.dims)
    }

    /// Number of cells, `(nx - 1)(ny - 1)(nz - 1)` (saturating at `u64::MAX`).
    pub fn cell_count(&self) -> u64 {
        self.dims
            .iter()
            .fold(1u64, |c, &n| c.saturating_mul(n.saturating_sub(1)))
    }
}

/// Evaluates `f` at every sample position (index coordinates), x fastest.
fn generate<T>(dims: [u64; 3], mut f: impl FnMut(f64, f64, f64) -> T) -> Vec<T> {
    let n = (dims[0] * dims[1] * dims[2]) as usize;
    let mut data = Vec::with_capacity(n);
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                data.push(f(i as f64, j as f64, k as f64));
            }
        }
    }
    data
}

/// Squared distance from `p` to the segment `[a, b]`.
fn segment_distance2(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    let t = if len2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (0..3).map(|a| (ap[a] - t * ab[a]).powi(2)).sum()
}

/// A thin tube in an `n^3` volume, values 0..255, isovalue 130.5 (the
/// paper's "tube" threshold): a Gaussian profile of width 0.9 cells around
/// a bent curve (a quarter circle rising along z), so the tube is about 1.5
/// cells across and runs obliquely through the lattice. `n` below 4 is taken as 4.
pub fn tube(n: u64) -> SampleVolume {
    let n = n.max(4);
    let s = (n - 1) as f64;
    // The curve as a polyline, off the sample lattice.
    let segments = 64;
    let curve: Vec<[f64; 3]> = (0..=segments)
        .map(|i| {
            let t = i as f64 / segments as f64 * 0.5 * PI;
            [
                0.13 * s + 0.74 * s * t.cos(),
                0.11 * s + 0.74 * s * t.sin(),
                0.17 * s + 0.66 * s * (i as f64 / segments as f64),
            ]
        })
        .collect();
    let width2 = 0.9f64 * 0.9;
    let data = generate([n, n, n], |x, y, z| {
        let d2 = curve
            .windows(2)
            .map(|w| segment_distance2([x, y, z], w[0], w[1]))
            .fold(f64::INFINITY, f64::min);
        (255.0 * (-d2 / width2).exp()) as f32
    });
    SampleVolume {
        name: "tube",
        dims: [n, n, n],
        isovalue: 130.5,
        data,
    }
}

/// An electron-density-like map in an `n^3` volume: a chain of Gaussian
/// atoms (a short helix, 1.6 cells apart, width 1.1 cells) plus a few side
/// atoms, values up to about 130, isovalue 50.5 (the paper's SOD
/// threshold). Neighbouring atoms join through thin necks, where the
/// trilinear topology and refinement change the surface most. `n` below 6 is taken as 6.
pub fn atoms(n: u64) -> SampleVolume {
    let n = n.max(6);
    let s = (n - 1) as f64;
    let c = 0.5 * s;
    let mut centres = Vec::new();
    // Helix backbone: radius 0.3 s, about 1.6 cells between atoms.
    let turns = 2.0;
    let radius = 0.3 * s;
    let length = turns * 2.0 * PI * radius;
    let count = ((length / 1.6).ceil() as usize).max(4);
    for i in 0..count {
        let t = i as f64 / count as f64 * turns * 2.0 * PI;
        centres.push([
            c + radius * t.cos() + 0.07,
            c + radius * t.sin() - 0.13,
            0.15 * s + 0.7 * s * i as f64 / count as f64,
        ]);
    }
    // Side atoms, every fourth backbone atom, pointing outwards.
    for i in (0..count).step_by(4) {
        let t = i as f64 / count as f64 * turns * 2.0 * PI;
        let r = radius + 1.9;
        centres.push([
            c + r * t.cos(),
            c + r * t.sin(),
            0.15 * s + 0.7 * s * i as f64 / count as f64 + 0.4,
        ]);
    }
    let width2 = 1.1f64 * 1.1;
    let data = generate([n, n, n], |x, y, z| {
        let v: f64 = centres
            .iter()
            .map(|a| {
                let d2 = (x - a[0]).powi(2) + (y - a[1]).powi(2) + (z - a[2]).powi(2);
                let e = -d2 / width2;
                // exp is exactly 0 below about -745.13; libm reaches that
                // through its slow underflow path (errno), which was most
                // of the time of a large volume's generation.
                if e < -746.0 {
                    0.0
                } else {
                    e.exp()
                }
            })
            .sum();
        (100.0 * v) as f32
    });
    SampleVolume {
        name: "atoms",
        dims: [n, n, n],
        isovalue: 50.5,
        data,
    }
}

/// The Marschner–Lobb test signal (f_M = 6, alpha = 0.25) over
/// `[-1, 1]^3` sampled on `n^3` points, isovalue 0.5 (the usual test size
/// is `n = 41`). Values lie in `[0, 1]`. `n` below 2 is taken as 2.
pub fn marschner_lobb(n: u64) -> SampleVolume {
    let n = n.max(2);
    let h = 2.0 / (n - 1) as f64;
    let data = generate([n, n, n], |i, j, k| {
        marschner_lobb_value(-1.0 + i * h, -1.0 + j * h, -1.0 + k * h) as f32
    });
    SampleVolume {
        name: "ml",
        dims: [n, n, n],
        isovalue: 0.5,
        data,
    }
}

/// The Marschner–Lobb function at `(x, y, z)` in `[-1, 1]^3`:
/// `(1 - sin(pi z / 2) + a (1 + cos(2 pi f_M cos(pi r / 2)))) / (2 (1 + a))`
/// with `r = sqrt(x^2 + y^2)`, `f_M = 6`, `a = 0.25`.
pub fn marschner_lobb_value(x: f64, y: f64, z: f64) -> f64 {
    const FM: f64 = 6.0;
    const ALPHA: f64 = 0.25;
    let r = (x * x + y * y).sqrt();
    let rho = (2.0 * PI * FM * (PI * r / 2.0).cos()).cos();
    (1.0 - (PI * z / 2.0).sin() + ALPHA * (1.0 + rho)) / (2.0 * (1.0 + ALPHA))
}

/// The smooth field behind [`smooth`] and [`smooth_u8`], in `[0, 1]`: a
/// sphere-like distance field with gentle waves, so the isosurface at 0.5
/// crosses a realistic share of the cells (a few percent).
fn smooth_value(n: u64, x: f64, y: f64, z: f64) -> f64 {
    let s = (n - 1) as f64;
    let (u, v, w) = (x / s - 0.5, y / s - 0.5, z / s - 0.5);
    let r = (u * u + v * v + w * w).sqrt();
    let wave = 0.04 * ((7.0 * u).sin() + (9.0 * v).sin() * (5.0 * w).cos());
    (1.0 - 1.6 * r + wave).clamp(0.0, 1.0)
}

/// A smooth `f32` field on `n^3` samples, values in `[0, 1]`, isovalue 0.5:
/// the throughput benchmark's input (a wavy sphere). `n` below 2 is taken as 2.
pub fn smooth(n: u64) -> SampleVolume {
    let n = n.max(2);
    SampleVolume {
        name: "smooth",
        dims: [n, n, n],
        isovalue: 0.5,
        data: generate([n, n, n], |x, y, z| smooth_value(n, x, y, z) as f32),
    }
}

/// [`smooth`] quantised to `u8` (0..255), isovalue 127.5. `n` below 2 is taken as 2.
pub fn smooth_u8(n: u64) -> SampleVolume<u8> {
    let n = n.max(2);
    SampleVolume {
        name: "smooth_u8",
        dims: [n, n, n],
        isovalue: 127.5,
        data: generate([n, n, n], |x, y, z| {
            (255.0 * smooth_value(n, x, y, z)).round() as u8
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_are_sized_and_cross_their_isovalue() {
        let check = |data: &[f32], dims: [u64; 3], iso: f64| {
            assert_eq!(data.len() as u64, dims.iter().product::<u64>());
            assert!(data.iter().all(|v| v.is_finite()));
            assert!(data.iter().any(|&v| (v as f64) < iso));
            assert!(data.iter().any(|&v| (v as f64) > iso));
        };
        for s in [tube(9), atoms(14), marschner_lobb(41), smooth(32)] {
            check(&s.data, s.dims, s.isovalue);
        }
        let u = smooth_u8(16);
        assert!(u.data.iter().any(|&v| v < 127) && u.data.iter().any(|&v| v > 128));
    }

    #[test]
    fn marschner_lobb_matches_its_formula_at_known_points() {
        // At the origin r = 0: rho = cos(2 pi 6) = 1, so (1 + 0.5) / 2.5.
        assert!((marschner_lobb_value(0.0, 0.0, 0.0) - 0.6).abs() < 1e-12);
        // At z = 1: sin(pi/2) = 1, so only the alpha term remains.
        let v = marschner_lobb_value(0.0, 0.0, 1.0);
        assert!((v - 0.5 / 2.5).abs() < 1e-12);
    }
}
