//! Quick throughput figures for the README: cells per second of plain
//! Marching Cubes (refinement off) on the smooth 256^3 `f32` sample, and
//! output triangles per second with refinement on (atoms 128^3, epsilon
//! 0.001, max level 5), with 1 and 2 threads, median of 5 runs.
//!
//! ```text
//! cargo run --release --example throughput
//! ```

use std::time::Instant;

use precisemc::samples::{self, SampleVolume};
use precisemc::{extract, Mesh, Options, Rule, Topology};

const RUNS: usize = 5;

/// Median wall time (s) of `RUNS` extractions, and the last mesh.
fn measure<T>(s: &SampleVolume<T>, options: &Options) -> (Mesh, f64)
where
    for<'a> &'a [T]: Into<precisemc::Samples<'a>>,
{
    let volume = s.volume();
    let mut times = Vec::with_capacity(RUNS);
    let mut mesh = None;
    for _ in 0..RUNS {
        let t = Instant::now();
        let m = extract(&volume, s.isovalue, options).expect("extraction failed");
        times.push(t.elapsed().as_secs_f64());
        mesh = Some(m);
    }
    times.sort_by(f64::total_cmp);
    (mesh.unwrap(), times[RUNS / 2])
}

fn cpu_model() -> String {
    std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string())
}

fn mc_row<T>(s: &SampleVolume<T>, label: &str, topology: Topology, threads: usize)
where
    for<'a> &'a [T]: Into<precisemc::Samples<'a>>,
{
    let options = Options {
        threads,
        ..Options::marching_cubes(topology)
    };
    let (m, t) = measure(s, &options);
    let cells = s.cell_count() as f64;
    println!(
        "| {label} | {topology:?} | {threads} | {} | {:.1} | {:.1} | {:.2} |",
        m.stats.output_triangles,
        t * 1e3,
        cells / t / 1e6,
        m.stats.output_triangles as f64 / t / 1e6
    );
}

fn main() {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "CPU: {}, nproc = {cores}; median of {RUNS} runs\n",
        cpu_model()
    );

    let smooth = samples::smooth(256);
    println!(
        "Marching Cubes, refinement off, {}^3 samples ({} cells), isovalue {}:\n",
        smooth.dims[0],
        smooth.cell_count(),
        smooth.isovalue
    );
    println!("| sample | topology | threads | triangles | time (ms) | Mcells/s | Mtris/s |");
    println!("|---|---|---:|---:|---:|---:|---:|");
    for topology in [Topology::Trilinear, Topology::Classic] {
        for threads in [1, 2] {
            mc_row(&smooth, "smooth f32", topology, threads);
        }
    }
    drop(smooth);
    let smooth_u8 = samples::smooth_u8(256);
    for threads in [1, 2] {
        mc_row(&smooth_u8, "smooth u8", Topology::Trilinear, threads);
    }
    drop(smooth_u8);

    let atoms = samples::atoms(128);
    println!(
        "\nRefinement on: atoms {}x{}x{}, isovalue {}, epsilon 0.001, max level 5:\n",
        atoms.dims[0], atoms.dims[1], atoms.dims[2], atoms.isovalue
    );
    println!(
        "| rule | threads | MC triangles | output triangles | meanL | time (ms) | output Mtris/s | refine share |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for rule in [Rule::A1] {
        for threads in [1, 2] {
            let options = Options {
                epsilon: 0.001,
                max_level: 5,
                rule,
                threads,
                ..Options::default()
            };
            let (m, t) = measure(&atoms, &options);
            let st = &m.stats;
            println!(
                "| {rule:?} | {threads} | {} | {} | {:.3} | {:.1} | {:.2} | {:.0}% |",
                st.mc_triangles,
                st.output_triangles,
                st.mean_level,
                t * 1e3,
                st.output_triangles as f64 / t / 1e6,
                100.0 * st.time_refine / (st.time_refine + st.time_mc).max(1e-12)
            );
        }
    }
}
