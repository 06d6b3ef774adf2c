//! The reconstruction filters compared on the Marschner–Lobb signal (and,
//! briefly, on the other built-in samples).
//!
//! Marschner–Lobb (f_M = 6, alpha = 0.25) is sampled on 41^3 points over
//! `[-1, 1]^3` (`samples::marschner_lobb(41)`) and extracted at 0.5 with
//! refinement onto each filter's isosurface (trilinear, Catmull–Rom, cubic
//! B-spline, interpolating cubic B-spline). Each surface is measured
//! against the **analytic** isosurface `ML = 0.5` (`analytic.rs`: every
//! triangle sampled on a barycentric grid, exact nearest-point distance,
//! plus the first-order estimate `|f - c| / |grad f|` as a cross-check),
//! in cell units (one cell = 0.05). Folded triangles are those whose normal
//! (towards lower values) points along the gradient of the filter refined
//! onto, or of the analytic function, at the triangle's centroid.
//!
//! Printed (Markdown): an epsilon sweep per filter; the comparison at equal
//! triangle counts (epsilon bisected per filter to hit 2x, 4x and 8x the
//! Marching Cubes count within 2 %); and, on `tube` and `atoms` (no
//! analytic surface), triangles, folds and the distance to the trilinear
//! `S_K` (`precisemc::accuracy`) at 4x the Marching Cubes count.
//!
//! The surfaces at 4x go to `target/filters/*.vtk` (legacy VTK, world
//! coordinates, cell scalar `dist` = largest distance of the triangle's
//! samples in cells) for `bench/filters_pictures.py`.
//!
//! ```text
//! cargo run --release --example filters [-- OUTPUT_DIR]
//! cargo test --example filters      # tests of the analytic distance
//! ```

mod analytic;

use std::io::Write;

use precisemc::filter::evaluate;
use precisemc::samples::{self, SampleVolume};
use precisemc::{accuracy, extract, Mesh, Options, Reconstruction, Volume};

/// The filters: enum, name in the tables, key in file names.
const FILTERS: [(Reconstruction, &str, &str); 4] = [
    (Reconstruction::Trilinear, "trilinear", "trilinear"),
    (Reconstruction::CatmullRom, "Catmull-Rom", "catmull_rom"),
    (Reconstruction::BSpline, "B-spline", "bspline"),
    (
        Reconstruction::BSplineInterpolating,
        "B-spline interp.",
        "bspline_interpolating",
    ),
];

/// Barycentric subdivisions per triangle edge of the distance samples.
const DENSITY: usize = 4;
/// Maximum refinement level of every refined run.
const LEVEL: u32 = 5;
/// The epsilon sweep measures every k-th triangle of larger meshes, so
/// that at most this many are measured (the max is then a lower bound).
const SWEEP_LIMIT: usize = 100_000;

/// Coefficients of the interpolating cubic B-spline of a sample: the
/// plain B-spline of these is the library's `BSplineInterpolating`.
fn prefilter(data: &[f32], dims: [u64; 3]) -> Vec<f64> {
    precisemc::cubic::bspline_coefficients(&Volume::new(data, dims))
        .expect("prefilter of a valid sample")
}

/// Evaluates a filter's value and gradient at index point `p`, with the
/// interpolating B-spline through prefiltered coefficients (`evaluate`
/// itself would prefilter on every call).
struct FilterEval<'a> {
    volume: Volume<'a>,
    coefficients: Volume<'a>,
}

impl FilterEval<'_> {
    fn gradient(&self, r: Reconstruction, p: [f64; 3]) -> Option<[f64; 3]> {
        let (vol, r) = match r {
            Reconstruction::BSplineInterpolating => (&self.coefficients, Reconstruction::BSpline),
            other => (&self.volume, other),
        };
        let cell = [0, 1, 2].map(|a| (p[a].floor().max(0.0) as u64).min(vol.dims[a] - 2));
        let local = [0, 1, 2].map(|a| (p[a] - cell[a] as f64).clamp(0.0, 1.0));
        evaluate(vol, r, cell, local).ok().flatten().map(|(_, g)| g)
    }
}

fn normal(points: &[[f64; 3]], t: [u64; 3]) -> ([f64; 3], [f64; 3]) {
    let [a, b, c] = t.map(|v| points[v as usize]);
    let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
    let n = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    let centroid = [0, 1, 2].map(|k| (a[k] + b[k] + c[k]) / 3.0);
    (n, centroid)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Share of triangles whose normal (towards lower values) points along the
/// gradient `grad` at their centroid (index space).
fn fold_share(mesh: &Mesh, grad: impl Fn([f64; 3]) -> Option<[f64; 3]> + Sync) -> f64 {
    use rayon::prelude::*;
    let folded: usize = mesh
        .triangles
        .par_iter()
        .filter(|t| {
            let (n, c) = normal(&mesh.index_points, **t);
            grad(c).is_some_and(|g| dot(n, g) > 0.0)
        })
        .count();
    folded as f64 / mesh.triangles.len().max(1) as f64
}

fn run(s: &SampleVolume, options: &Options) -> Mesh {
    extract(&s.volume(), s.isovalue, options).expect("extraction")
}

fn refine(r: Reconstruction, epsilon: f64, max_level: u32) -> Options {
    Options {
        epsilon,
        max_level,
        reconstruction: r,
        ..Options::default()
    }
}

/// The epsilon (bisected on a log scale) whose triangle count is within
/// 2 % of `target` at max level [`LEVEL`] (else at the highest lower level
/// that hits it), and its max level and mesh; the closest one found when
/// none does.
fn at_count(s: &SampleVolume, r: Reconstruction, target: u64) -> (f64, u32, Mesh) {
    let miss = |k: usize| (k as f64 / target as f64 - 1.0).abs();
    let mut best: Option<(f64, u32, Mesh)> = None;
    for level in (1..=LEVEL).rev() {
        let (mut lo, mut hi) = (1e-6f64.ln(), 2f64.ln());
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            let m = run(s, &refine(r, mid.exp(), level));
            let n = m.triangles.len();
            let better = match &best {
                None => true,
                Some((_, _, b)) => miss(n) < miss(b.triangles.len()),
            };
            if better {
                best = Some((mid.exp(), level, m));
            }
            if miss(n) <= 0.02 || hi - lo < 1e-4 {
                break;
            }
            // Smaller epsilon, more triangles.
            if n as u64 > target {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        if best
            .as_ref()
            .is_some_and(|b| miss(b.2.triangles.len()) <= 0.02)
        {
            break;
        }
    }
    best.expect("at least one run")
}

/// One measured Marschner–Lobb surface.
struct Row {
    label: String,
    epsilon: f64,
    level: u32,
    mesh: Mesh,
    /// Triangles measured (every k-th one when the mesh is large).
    measured: usize,
    /// Mean distance of the split points (points off the grid lines: on
    /// the filter's isosurface), cells; and their number.
    split_mean: (f64, usize),
    distance: analytic::MeshDistance,
    folds_filter: f64,
    folds_analytic: f64,
}

struct Ml<'a> {
    sample: &'a SampleVolume,
    eval: FilterEval<'a>,
    h: f64,
}

impl Ml<'_> {
    fn to_world(&self) -> impl Fn([f64; 3]) -> [f64; 3] + Sync {
        let h = self.h;
        move |p| p.map(|c| -1.0 + c * h)
    }

    fn measure(
        &self,
        label: String,
        r: Reconstruction,
        (epsilon, level): (f64, u32),
        mesh: Mesh,
        limit: usize,
    ) -> Row {
        let t = std::time::Instant::now();
        let stride = mesh.triangles.len().div_ceil(limit.max(1)).max(1);
        let subset: Vec<[u64; 3]> = mesh.triangles.iter().step_by(stride).copied().collect();
        let distance = analytic::measure_mesh(
            &mesh.index_points,
            &subset,
            self.to_world(),
            self.h,
            self.sample.isovalue,
            DENSITY,
        );
        eprintln!(
            "{label}: {} triangles, {} measured, {:.1} s",
            mesh.triangles.len(),
            subset.len(),
            t.elapsed().as_secs_f64()
        );
        let split_mean = {
            use rayon::prelude::*;
            let surface = analytic::ml_surface(self.sample.isovalue);
            let w = self.to_world();
            let d: Vec<f64> = mesh
                .index_points
                .par_iter()
                .filter(|p| p.iter().filter(|c| c.fract() == 0.0).count() < 2)
                .map(|p| surface.distance(w(*p)) / self.h)
                .collect();
            (d.iter().sum::<f64>() / d.len().max(1) as f64, d.len())
        };
        let folds_filter = fold_share(&mesh, |c| self.eval.gradient(r, c));
        let w = self.to_world();
        let folds_analytic = fold_share(&mesh, |c| Some(analytic::ml_value_gradient(w(c)).1));
        Row {
            label,
            epsilon,
            level,
            measured: subset.len(),
            split_mean,
            mesh,
            distance,
            folds_filter,
            folds_analytic,
        }
    }
}

fn print_rows(rows: &[Row], mc: u64) {
    println!("| surface | ε | max level | triangles | × MC | measured | max | mean | RMS | 1st-order max / mean | split points: mean | folded (filter) | folded (analytic) |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|---:|---:|---:|");
    for r in rows {
        let d = &r.distance;
        let eps = if r.epsilon > 0.0 {
            format!("{:.2e}", r.epsilon)
        } else {
            "–".into()
        };
        println!(
            "| {} | {} | {} | {} | {:.2} | {} | {:.4} | {:.5} | {:.5} | {:.4} / {:.5} | {} | {:.2} % | {:.2} % |",
            r.label,
            eps,
            r.level,
            r.mesh.triangles.len(),
            r.mesh.triangles.len() as f64 / mc as f64,
            if r.measured == r.mesh.triangles.len() {
                "all".to_string()
            } else {
                format!("1 in {}", r.mesh.triangles.len().div_ceil(r.measured))
            },
            d.max,
            d.mean,
            d.rms,
            d.max_first_order,
            d.mean_first_order,
            if r.level > 0 && r.split_mean.1 > 0 {
                format!("{:.5}", r.split_mean.0)
            } else {
                "–".into()
            },
            100.0 * r.folds_filter,
            100.0 * r.folds_analytic,
        );
    }
    println!();
}

/// Writes a legacy VTK polydata file: world points, triangles, cell scalar
/// `dist` (largest sample distance of each triangle, cells).
fn write_vtk(path: &std::path::Path, row: &Row, to_world: impl Fn([f64; 3]) -> [f64; 3]) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).expect("create vtk file"));
    let m = &row.mesh;
    writeln!(
        f,
        "# vtk DataFile Version 3.0\n{} ({} triangles)\nASCII\nDATASET POLYDATA",
        row.label.replace('×', "x"),
        m.triangles.len()
    )
    .unwrap();
    writeln!(f, "POINTS {} double", m.index_points.len()).unwrap();
    for p in &m.index_points {
        let w = to_world(*p);
        writeln!(f, "{} {} {}", w[0], w[1], w[2]).unwrap();
    }
    writeln!(
        f,
        "POLYGONS {} {}",
        m.triangles.len(),
        4 * m.triangles.len()
    )
    .unwrap();
    for t in &m.triangles {
        writeln!(f, "3 {} {} {}", t[0], t[1], t[2]).unwrap();
    }
    writeln!(
        f,
        "CELL_DATA {}\nSCALARS dist float 1\nLOOKUP_TABLE default",
        m.triangles.len()
    )
    .unwrap();
    for d in &row.distance.per_triangle_max {
        writeln!(f, "{}", *d as f32).unwrap();
    }
}

fn marschner_lobb(out: &std::path::Path) {
    let sample = samples::marschner_lobb(41);
    let coefficients = prefilter(&sample.data, sample.dims);
    let ml = Ml {
        sample: &sample,
        eval: FilterEval {
            volume: sample.volume(),
            coefficients: Volume::new(coefficients.as_slice(), sample.dims),
        },
        h: 2.0 / (sample.dims[0] - 1) as f64,
    };
    let mc_mesh = run(&sample, &Options::marching_cubes(Default::default()));
    let mc = mc_mesh.triangles.len() as u64;
    let baseline = ml.measure(
        "Marching Cubes".into(),
        Reconstruction::Trilinear,
        (0.0, 0),
        mc_mesh,
        usize::MAX,
    );

    println!("## Marschner–Lobb 41^3, isovalue 0.5: distance to the analytic isosurface (cells)\n");
    println!(
        "Rule A1, max level {LEVEL}; {} distance samples per triangle; \
         folds: share of triangles facing along the gradient.\n",
        (DENSITY + 1) * (DENSITY + 2) / 2
    );
    println!("### Epsilon sweep\n");
    let mut rows = vec![];
    for (r, name, _) in FILTERS {
        for eps in [0.1, 0.03, 0.01, 0.003] {
            let m = run(&sample, &refine(r, eps, LEVEL));
            rows.push(ml.measure(name.into(), r, (eps, LEVEL), m, SWEEP_LIMIT));
        }
    }
    let mut all = vec![baseline];
    all.extend(rows);
    print_rows(&all, mc);
    eprintln!(
        "sweep: {} distance samples in all",
        all.iter().map(|r| r.distance.samples).sum::<u64>()
    );
    let baseline = all.swap_remove(0);

    println!("### Equal triangle counts (ε bisected per filter, within 2 %)\n");
    let mut rows = vec![baseline];
    for factor in [2u64, 4, 8] {
        for (r, name, key) in FILTERS {
            let (eps, level, m) = at_count(&sample, r, factor * mc);
            let row = ml.measure(format!("{name} ×{factor}"), r, (eps, level), m, usize::MAX);
            if factor == 4 {
                let file = out.join(format!("ml_{key}.vtk"));
                write_vtk(&file, &row, ml.to_world());
            }
            rows.push(row);
        }
    }
    write_vtk(&out.join("ml_mc.vtk"), &rows[0], ml.to_world());
    print_rows(&rows, mc);
}

/// Samples without an analytic surface: triangles, folds against the
/// filter's own gradient, and distance to the trilinear `S_K`.
fn other_samples() {
    println!(
        "## Other samples at 4× the Marching Cubes count: distance to the trilinear S_K (cells)\n"
    );
    println!("| sample | surface | ε | triangles | folded (filter) | max | mean |");
    println!("|---|---|---:|---:|---:|---:|---:|");
    for s in [samples::tube(9), samples::atoms(14)] {
        let coefficients = prefilter(&s.data, s.dims);
        let eval = FilterEval {
            volume: s.volume(),
            coefficients: Volume::new(coefficients.as_slice(), s.dims),
        };
        let opts = accuracy::MeasureOptions::default();
        let mc_mesh = run(&s, &Options::marching_cubes(Default::default()));
        let mc = mc_mesh.triangles.len() as u64;
        let mut list = vec![(
            "Marching Cubes".to_string(),
            Reconstruction::Trilinear,
            0.0,
            mc_mesh,
        )];
        for (r, name, _) in FILTERS {
            let (eps, _, m) = at_count(&s, r, 4 * mc);
            list.push((name.to_string(), r, eps, m));
        }
        for (name, r, eps, m) in list {
            let d = accuracy::measure(
                &s.volume(),
                s.isovalue,
                &m.index_points,
                &m.triangles,
                &opts,
            )
            .expect("measure");
            let eps = if eps > 0.0 {
                format!("{eps:.2e}")
            } else {
                "–".into()
            };
            println!(
                "| {} {}^3 | {} | {} | {} | {:.2} % | {:.4} | {:.5} |",
                s.name,
                s.dims[0],
                name,
                eps,
                m.triangles.len(),
                100.0 * fold_share(&m, |c| eval.gradient(r, c)),
                d.max,
                d.mean
            );
        }
    }
    println!();
}

fn main() {
    let out = std::path::PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "target/filters".into()),
    );
    std::fs::create_dir_all(&out).expect("create output directory");
    marschner_lobb(&out);
    other_samples();
    eprintln!("surfaces written to {}", out.display());
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The example's prefilter gives the library's interpolating B-spline
    /// (values and gradients), so folds are counted against the right
    /// filter.
    #[test]
    fn prefilter_matches_the_library() {
        let s = samples::marschner_lobb(12);
        let c = prefilter(&s.data, s.dims);
        let coefficients = Volume::new(c.as_slice(), s.dims);
        let volume = s.volume();
        for (i, cell) in [[0, 0, 0], [3, 5, 7], [10, 10, 10], [10, 0, 4]]
            .into_iter()
            .enumerate()
        {
            let p = [0.1 + 0.2 * i as f64, 0.7, 0.35];
            let (fa, ga) = evaluate(&volume, Reconstruction::BSplineInterpolating, cell, p)
                .unwrap()
                .unwrap();
            let (fb, gb) = evaluate(&coefficients, Reconstruction::BSpline, cell, p)
                .unwrap()
                .unwrap();
            assert!((fa - fb).abs() < 1e-12, "{cell:?}: {fa} vs {fb}");
            for a in 0..3 {
                assert!((ga[a] - gb[a]).abs() < 1e-11, "{cell:?}: {ga:?} vs {gb:?}");
            }
        }
    }

    /// Folds are counted: a triangle facing along the gradient is folded,
    /// its mirror image is not.
    #[test]
    fn fold_share_counts_triangles_facing_the_gradient() {
        let mesh = Mesh {
            index_points: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            triangles: vec![[0, 1, 2], [0, 2, 1]],
            ..Mesh::default()
        };
        // Normal of [0, 1, 2] is +z; a gradient along +z folds it.
        assert_eq!(fold_share(&mesh, |_| Some([0.0, 0.0, 1.0])), 0.5);
        assert_eq!(fold_share(&mesh, |_| None), 0.0);
    }
}
