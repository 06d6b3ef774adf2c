//! Distance of a triangle mesh to the *analytic* Marschner–Lobb isosurface.
//!
//! The Marschner–Lobb function (`precisemc::samples::marschner_lobb_value`,
//! f_M = 6, alpha = 0.25) is
//! `(1 - sin(pi z / 2) + alpha (1 + rho(r))) / (2 (1 + alpha))` with
//! `rho(r) = cos(2 pi f_M cos(pi r / 2))` and `r = sqrt(x^2 + y^2)`. Its
//! isosurface `ML = c` is therefore, exactly, the surface of revolution
//! `z = g(r)` with `sin(pi g / 2) = 1 + alpha (1 + rho(r)) - 2 (1 + alpha) c`
//! (for c = 0.5: `sin(pi g / 2) = alpha rho(r)`), a height field over
//! the `(x, y)` plane. The nearest point of a surface of revolution to `p`
//! lies in the meridian half-plane of `p`, so the 3-D distance is the 2-D
//! distance from `(r_p, z_p)` to the profile curve `(r, g(r))`, `r >= 0`.
//!
//! [`Revolution::distance`] finds it robustly: the vertical distance
//! `d0 = |z_p - g(r_p)|` bounds it, so the nearest point has
//! `|r - r_p| <= d0`; that window is sampled finely (steps of at most
//! `max_step` and 1/32 of the window), and every local minimum of the
//! squared distance among the samples is polished by golden-section search
//! on its two neighbouring steps; the smallest wins. The surface is the
//! unbounded analytic one (not clipped to the cube `[-1, 1]^3`).
//!
//! [`first_order`] is the usual estimate `|f(p) - c| / |grad f(p)|`, as a
//! cross-check: it agrees with the exact distance where the surface is
//! flat on the scale of the distance.

use std::f64::consts::PI;

/// The Marschner–Lobb parameters of `precisemc::samples`.
pub const FM: f64 = 6.0;
/// See [`FM`].
pub const ALPHA: f64 = 0.25;

/// A surface of revolution about the z axis, `z = g(r)`, `r >= 0`.
pub struct Revolution<G: Fn(f64) -> f64> {
    /// The profile.
    pub g: G,
    /// Largest sampling step of the search window (world units); must be
    /// well below the profile's radius of curvature.
    pub max_step: f64,
}

impl<G: Fn(f64) -> f64> Revolution<G> {
    /// Euclidean distance from `p` (world units) to the surface.
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        let rp = p[0].hypot(p[1]);
        let zp = p[2];
        let d2 = |r: f64| {
            let dz = (self.g)(r) - zp;
            (r - rp) * (r - rp) + dz * dz
        };
        let d0 = ((self.g)(rp) - zp).abs();
        if d0 == 0.0 {
            return 0.0;
        }
        let lo = (rp - d0).max(0.0);
        let hi = rp + d0;
        let steps = (((hi - lo) / self.max_step).ceil() as usize).max(32);
        let h = (hi - lo) / steps as f64;
        let r_at = |i: usize| if i == steps { hi } else { lo + h * i as f64 };
        let values: Vec<f64> = (0..=steps).map(|i| d2(r_at(i))).collect();
        let mut best = d0 * d0;
        for i in 0..=steps {
            let left = if i > 0 { values[i - 1] } else { f64::INFINITY };
            let right = if i < steps {
                values[i + 1]
            } else {
                f64::INFINITY
            };
            if values[i] > left || values[i] > right {
                continue;
            }
            // Golden-section search on [r_(i-1), r_(i+1)].
            let (mut a, mut b) = (r_at(i.saturating_sub(1)), r_at((i + 1).min(steps)));
            let phi = 0.5 * (5f64.sqrt() - 1.0);
            let mut x1 = b - phi * (b - a);
            let mut x2 = a + phi * (b - a);
            let (mut f1, mut f2) = (d2(x1), d2(x2));
            for _ in 0..36 {
                if f1 <= f2 {
                    b = x2;
                    x2 = x1;
                    f2 = f1;
                    x1 = b - phi * (b - a);
                    f1 = d2(x1);
                } else {
                    a = x1;
                    x1 = x2;
                    f1 = f2;
                    x2 = a + phi * (b - a);
                    f2 = d2(x2);
                }
            }
            best = best.min(values[i]).min(f1).min(f2);
        }
        best.sqrt()
    }
}

/// `rho(r)` of the Marschner–Lobb function.
pub fn rho(r: f64) -> f64 {
    (2.0 * PI * FM * (PI * r / 2.0).cos()).cos()
}

/// The profile `g(r)` of the isosurface `ML = iso`. Panics unless the
/// isosurface is a single height field over the whole plane
/// (`|sin(pi g / 2)| < 1` for every `rho`), which holds for isovalues near
/// the standard 0.5.
pub fn ml_profile(iso: f64) -> impl Fn(f64) -> f64 {
    let base = 1.0 + ALPHA - 2.0 * (1.0 + ALPHA) * iso;
    assert!(
        (base - ALPHA).abs() < 1.0 && (base + ALPHA).abs() < 1.0,
        "isovalue {iso}: the Marschner-Lobb isosurface is not a height field"
    );
    move |r| (2.0 / PI) * (base + ALPHA * rho(r)).asin()
}

/// The analytic isosurface `ML = iso` with a search step fine enough for
/// its profile (radius of curvature about 0.018 at the tightest bends).
pub fn ml_surface(iso: f64) -> Revolution<impl Fn(f64) -> f64> {
    Revolution {
        g: ml_profile(iso),
        max_step: 1e-3,
    }
}

/// Value and gradient of the Marschner–Lobb function at `p` (world units).
pub fn ml_value_gradient(p: [f64; 3]) -> (f64, [f64; 3]) {
    let [x, y, z] = p;
    let r = x.hypot(y);
    let k = 2.0 * (1.0 + ALPHA);
    let phase = 2.0 * PI * FM * (PI * r / 2.0).cos();
    let value = (1.0 - (PI * z / 2.0).sin() + ALPHA * (1.0 + phase.cos())) / k;
    // d rho / d r = -sin(phase) * 2 pi f_M * (-sin(pi r / 2) pi / 2).
    let drho = phase.sin() * 2.0 * PI * FM * (PI * r / 2.0).sin() * PI / 2.0;
    let (ux, uy) = if r > 0.0 { (x / r, y / r) } else { (0.0, 0.0) };
    let gz = -(PI / 2.0) * (PI * z / 2.0).cos() / k;
    (value, [ALPHA * drho * ux / k, ALPHA * drho * uy / k, gz])
}

/// First-order distance estimate `|f - iso| / |grad f|` (world units).
pub fn first_order(p: [f64; 3], iso: f64) -> f64 {
    let (f, g) = ml_value_gradient(p);
    let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    if len > 0.0 {
        (f - iso).abs() / len
    } else {
        f64::INFINITY
    }
}

/// Distance statistics of a mesh, in cell units.
#[derive(Debug, Clone, Default)]
pub struct MeshDistance {
    /// Largest exact distance of any sample.
    pub max: f64,
    /// Area-weighted mean exact distance.
    pub mean: f64,
    /// Area-weighted RMS exact distance.
    pub rms: f64,
    /// Largest first-order estimate.
    pub max_first_order: f64,
    /// Area-weighted mean first-order estimate.
    pub mean_first_order: f64,
    /// Samples measured.
    pub samples: u64,
    /// Largest exact distance per triangle.
    pub per_triangle_max: Vec<f64>,
}

/// Measures the distance of a mesh to the analytic isosurface. `points`
/// are in index space; `to_world` maps them to world units and
/// `cell` is the length of one cell in world units (distances are divided
/// by it). Every triangle is sampled on a barycentric grid with `density`
/// subdivisions per edge (vertices, edge points and interior points).
pub fn measure_mesh(
    points: &[[f64; 3]],
    triangles: &[[u64; 3]],
    to_world: impl Fn([f64; 3]) -> [f64; 3] + Sync,
    cell: f64,
    iso: f64,
    density: usize,
) -> MeshDistance {
    use rayon::prelude::*;
    let surface = ml_surface(iso);
    let n = density.max(1);
    let per_tri = (n + 1) * (n + 2) / 2;
    // Per triangle: area, max, sum, sum of squares, first-order max and sum.
    let rows: Vec<[f64; 6]> = triangles
        .par_iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| to_world(points[v as usize]));
            let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
            let ac = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
            let cr = [
                ab[1] * ac[2] - ab[2] * ac[1],
                ab[2] * ac[0] - ab[0] * ac[2],
                ab[0] * ac[1] - ab[1] * ac[0],
            ];
            let area = 0.5 * (cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]).sqrt() / (cell * cell);
            let mut row = [area, 0.0, 0.0, 0.0, 0.0, 0.0];
            for i in 0..=n {
                for j in 0..=n - i {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let p = [0, 1, 2].map(|k| a[k] + ab[k] * u + ac[k] * v);
                    let d = surface.distance(p) / cell;
                    let e = first_order(p, iso) / cell;
                    row[1] = row[1].max(d);
                    row[2] += d;
                    row[3] += d * d;
                    row[4] = row[4].max(e);
                    row[5] += e;
                }
            }
            row
        })
        .collect();
    let mut out = MeshDistance {
        samples: (triangles.len() * per_tri) as u64,
        ..MeshDistance::default()
    };
    let (mut w, mut s, mut sq, mut se) = (0.0, 0.0, 0.0, 0.0);
    for r in &rows {
        let k = r[0] / per_tri as f64;
        w += r[0];
        s += k * r[2];
        sq += k * r[3];
        se += k * r[5];
        out.max = out.max.max(r[1]);
        out.max_first_order = out.max_first_order.max(r[4]);
    }
    if w > 0.0 {
        out.mean = s / w;
        out.rms = (sq / w).sqrt();
        out.mean_first_order = se / w;
    }
    out.per_triangle_max = rows.iter().map(|r| r[1]).collect();
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use precisemc::samples::marschner_lobb_value;

    /// A small deterministic generator (splitmix64).
    struct Rng(u64);
    impl Rng {
        fn f64(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }
        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.f64()
        }
    }

    /// The profile lies on the isosurface of the library's sample function,
    /// and the analytic gradient matches central differences.
    #[test]
    fn profile_and_gradient_match_the_sample_function() {
        let g = ml_profile(0.5);
        let mut rng = Rng(1);
        for _ in 0..2000 {
            let (r, t) = (rng.range(0.0, 1.4), rng.range(0.0, 2.0 * PI));
            let p = [r * t.cos(), r * t.sin(), g(r)];
            let f = marschner_lobb_value(p[0], p[1], p[2]);
            assert!((f - 0.5).abs() < 1e-12, "{p:?}: {f}");
            let q = [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ];
            let (v, grad) = ml_value_gradient(q);
            assert!((v - marschner_lobb_value(q[0], q[1], q[2])).abs() < 1e-14);
            let h = 1e-6;
            for a in 0..3 {
                let (mut lo, mut hi) = (q, q);
                lo[a] -= h;
                hi[a] += h;
                let fd = (marschner_lobb_value(hi[0], hi[1], hi[2])
                    - marschner_lobb_value(lo[0], lo[1], lo[2]))
                    / (2.0 * h);
                assert!((fd - grad[a]).abs() < 1e-6 * (1.0 + fd.abs()), "{q:?} {a}");
            }
        }
        // Another isovalue shifts the surface: still on it.
        let g = ml_profile(0.45);
        let f = marschner_lobb_value(0.3, 0.2, g(0.3f64.hypot(0.2)));
        assert!((f - 0.45).abs() < 1e-12);
    }

    /// A sphere cap `z = sqrt(R^2 - r^2) - c` (points near its top): the
    /// exact distance is `| |p - centre| - R |`.
    #[test]
    fn distance_to_a_sphere_is_exact() {
        let (big_r, c) = (0.7, 0.2);
        let s = Revolution {
            g: move |r: f64| (big_r * big_r - r * r).max(0.0).sqrt() - c,
            max_step: 1e-3,
        };
        let mut rng = Rng(2);
        for _ in 0..3000 {
            let (r, t) = (rng.range(0.0, 0.3), rng.range(0.0, 2.0 * PI));
            let rad = big_r + rng.range(-0.15, 0.15);
            let z = (rad * rad - r * r).sqrt() - c;
            let p = [r * t.cos(), r * t.sin(), z];
            let want = ((p[0] * p[0] + p[1] * p[1] + (p[2] + c).powi(2)).sqrt() - big_r).abs();
            let got = s.distance(p);
            assert!((got - want).abs() < 1e-9, "{p:?}: {got} vs {want}");
        }
    }

    /// A cone `z = a r` has two candidate minima for points near the axis
    /// (the flank and the apex): exact distance known in closed form.
    #[test]
    fn distance_to_a_cone_takes_the_nearest_branch() {
        let a = 1.5f64;
        let s = Revolution {
            g: move |r: f64| a * r,
            max_step: 1e-3,
        };
        let mut rng = Rng(3);
        for _ in 0..3000 {
            let p = [
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 2.0),
            ];
            let (rp, zp) = (p[0].hypot(p[1]), p[2]);
            let foot = (rp + a * zp) / (1.0 + a * a);
            let want = if foot >= 0.0 {
                (zp - a * rp).abs() / (1.0 + a * a).sqrt()
            } else {
                rp.hypot(zp)
            };
            let got = s.distance(p);
            assert!((got - want).abs() < 1e-9, "{p:?}: {got} vs {want}");
        }
    }

    /// Against a brute-force reference on Marschner–Lobb: the minimum over
    /// a dense (x, y) grid of points `(x, y, g(r))` of the surface around
    /// `p`. The exact distance may only be smaller than the reference, by
    /// at most the grid's discretisation error.
    #[test]
    fn distance_to_marschner_lobb_matches_a_dense_reference() {
        let s = ml_surface(0.5);
        let g = ml_profile(0.5);
        let mut rng = Rng(4);
        let mut worst = 0.0f64;
        for _ in 0..60 {
            let (r, t) = (rng.range(0.0, 1.3), rng.range(0.0, 2.0 * PI));
            let off = rng.range(-0.025, 0.025);
            let p = [r * t.cos(), r * t.sin(), g(r) + off];
            let got = s.distance(p);
            assert!(got <= off.abs() + 1e-15, "vertical distance bounds it");
            // Coarse grid around p, then a fine one around its best point.
            let dist = |x: f64, y: f64| {
                let z = g(x.hypot(y));
                ((x - p[0]).powi(2) + (y - p[1]).powi(2) + (z - p[2]).powi(2)).sqrt()
            };
            let grid = |cx: f64, cy: f64, step: f64, m: i64| {
                let mut best = (f64::INFINITY, cx, cy);
                for i in -m..=m {
                    for j in -m..=m {
                        let (x, y) = (cx + i as f64 * step, cy + j as f64 * step);
                        let d = dist(x, y);
                        if d < best.0 {
                            best = (d, x, y);
                        }
                    }
                }
                best
            };
            let coarse = grid(p[0], p[1], 4e-4, ((off.abs() + 1e-3) / 4e-4).ceil() as i64);
            let reference = grid(coarse.1, coarse.2, 1e-5, 60).0;
            assert!(
                got <= reference + 1e-12,
                "{p:?}: {got} > reference {reference}"
            );
            // The grid reference errs by up to a few 1e-6 where the
            // surface is steep (slopes up to about 9): 1e-4 cells.
            assert!(
                reference - got < 5e-6,
                "{p:?}: {got} vs reference {reference}"
            );
            worst = worst.max(reference - got);
        }
        println!("largest gap to the dense reference: {worst:.2e}");
    }

    /// The first-order estimate agrees with the exact distance close to the
    /// surface, and a flat triangle at a known height over a plane
    /// measures that height everywhere.
    #[test]
    fn first_order_agrees_near_the_surface() {
        let s = ml_surface(0.5);
        let g = ml_profile(0.5);
        let mut rng = Rng(5);
        for _ in 0..500 {
            let (r, t) = (rng.range(0.05, 1.3), rng.range(0.0, 2.0 * PI));
            let p = [r * t.cos(), r * t.sin(), g(r) + rng.range(-1e-4, 1e-4)];
            let (d, e) = (s.distance(p), first_order(p, 0.5));
            assert!((d - e).abs() < 0.05 * d + 1e-7, "{p:?}: {d} vs {e}");
        }
    }

    /// The mesh statistics: a triangle on the isosurface's flat top (near
    /// r = 0 the profile is flat to second order) measures about zero; the
    /// same triangle lifted by 0.3 cells measures 0.3.
    #[test]
    fn mesh_statistics_of_a_lifted_triangle() {
        let g0 = ml_profile(0.5)(0.0);
        let cell = 0.05;
        let pts = [
            [0.0, 0.0, g0],
            [1e-3, 0.0, g0],
            [0.0, 1e-3, g0],
            [0.0, 0.0, g0 + 0.3 * cell],
            [1e-3, 0.0, g0 + 0.3 * cell],
            [0.0, 1e-3, g0 + 0.3 * cell],
        ];
        let m = measure_mesh(&pts, &[[0, 1, 2]], |p| p, cell, 0.5, 4);
        assert!(m.max < 1e-3, "{m:?}");
        let m = measure_mesh(&pts, &[[3, 4, 5]], |p| p, cell, 0.5, 4);
        assert!(
            (m.max - 0.3).abs() < 1e-3 && (m.mean - 0.3).abs() < 1e-3,
            "{m:?}"
        );
        assert!((m.rms - 0.3).abs() < 1e-3 && m.samples == 15, "{m:?}");
    }
}
