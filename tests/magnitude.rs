//! Refined surfaces do not depend on the magnitude of the data: the same
//! field times any factor puts its split points on `S_K` as closely, and
//! times a power of two (within the range where nothing is rescaled or
//! rounded differently) gives the same mesh, bit for bit. Split points
//! are found by a root search along the gradient line, parametrised by the
//! gradient itself for the trilinear filter: its step shrinks as the
//! values grow, and a stopping width absolute in that parameter (as the
//! search had) ended it after one step on values above about 1e9.

mod common;

use common::{blobs, corners_of, tri_gradient, tri_value, Rng};
use precisemc::{extract, Mesh, Options, Reconstruction, Rule, Volume};

/// The largest distance of a mesh point to `S_K`, to first order
/// (|F - iso| / |grad F| of the trilinear interpolant of its cell), in
/// cells.
fn farthest_from_sk(values: &[f64], dims: [usize; 3], mesh: &Mesh) -> f64 {
    mesh.index_points
        .iter()
        .map(|p| {
            let cell = [0, 1, 2].map(|a| (p[a].floor() as usize).min(dims[a] - 2));
            let f = corners_of(values, dims, cell);
            let l = [0, 1, 2].map(|a| p[a] - cell[a] as f64);
            let g = tri_gradient(&f, l);
            tri_value(&f, l).abs() / (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt()
        })
        .fold(0.0, f64::max)
}

#[test]
fn split_points_stay_on_sk_whatever_the_magnitude() {
    let dims = [14usize; 3];
    let mut rng = Rng::new(0x6d61676e);
    for seed in 0..4u64 {
        let base = blobs(dims, 100 + seed, 6);
        let rule = [Rule::A, Rule::A1, Rule::A2, Rule::B][seed as usize];
        let options = Options {
            epsilon: 0.001,
            rule,
            ..Options::default()
        };
        let run = |scale: f64| {
            let v: Vec<f64> = base.iter().map(|x| x * scale).collect();
            let mesh = extract(&Volume::new(&v, [14; 3]), 0.0, &options).unwrap();
            (farthest_from_sk(&v, dims, &mesh), mesh)
        };
        let (d1, reference) = run(1.0);
        assert!(
            reference.stats.split_points > 100,
            "seed {seed}: too little refined"
        );
        assert!(d1 < 1e-10, "seed {seed}: {d1}");
        // Any factor: as close to S_K (the old search left points 4.5e-4
        // cells off from 1e18 up).
        let mut factors = vec![1e6, 1e9, 1e12, 1e18, 1e30, 1e60, 1e-6, 1e-30];
        factors.push(rng.log_uniform(1e3, 1e70));
        for s in factors {
            let (d, mesh) = run(s);
            assert!(
                d < 1e-10,
                "seed {seed} {rule:?}, values x {s:e}: {d} cells off S_K"
            );
            assert_eq!(
                mesh.triangles.len(),
                reference.triangles.len(),
                "values x {s:e}"
            );
        }
        // Powers of two: the same mesh.
        for k in [10, 30, 60, 100, 200, -10, -100] {
            let (_, mesh) = run(2f64.powi(k));
            assert_eq!(mesh.index_points, reference.index_points, "values x 2^{k}");
            assert_eq!(mesh.triangles, reference.triangles, "values x 2^{k}");
        }
    }
}

#[test]
fn cubic_filters_split_points_do_not_depend_on_a_power_of_two() {
    // The cubic filters search by distance, not by the gradient's
    // parameter: they were already exact; kept so.
    let dims = [12usize; 3];
    let base = blobs(dims, 7, 5);
    for reconstruction in [Reconstruction::CatmullRom, Reconstruction::BSpline] {
        let options = Options {
            epsilon: 0.002,
            reconstruction,
            ..Options::default()
        };
        let run = |scale: f64| {
            let v: Vec<f64> = base.iter().map(|x| x * scale).collect();
            extract(&Volume::new(&v, [12; 3]), 0.0, &options).unwrap()
        };
        let reference = run(1.0);
        for k in [40, 100] {
            let mesh = run(2f64.powi(k));
            assert_eq!(
                mesh.index_points, reference.index_points,
                "{reconstruction:?} 2^{k}"
            );
        }
    }
}
