//! Criterion benchmarks of `precisemc::extract` on the built-in samples.
//!
//! * `mc`: plain Marching Cubes (refinement off), classic and trilinear
//!   topology, on the smooth 128^3 and 256^3 `f32` samples with 1 and 2
//!   threads; throughput in cells.
//! * `refine`: refinement on the tube (9^3), atoms (14^3) and
//!   Marschner–Lobb (41^3) samples at several epsilons and rules, one
//!   thread; throughput in output triangles.
//!
//! ```text
//! cargo bench --bench extract             # everything (a few minutes)
//! cargo bench --bench extract -- refine   # one group
//! cargo bench --bench extract -- --quick  # short runs
//! ```

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use precisemc::samples::{self, SampleVolume};
use precisemc::{extract, Options, Rule, Topology};

fn configure<'a>(
    c: &'a mut Criterion,
    name: &str,
) -> criterion::BenchmarkGroup<'a, criterion::measurement::WallTime> {
    let mut g = c.benchmark_group(name);
    g.sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    g
}

fn bench_mc(c: &mut Criterion) {
    let mut g = configure(c, "mc");
    for n in [128u64, 256] {
        let s = samples::smooth(n);
        let volume = s.volume();
        g.throughput(Throughput::Elements(s.cell_count()));
        for topology in [Topology::Classic, Topology::Trilinear] {
            for threads in [1usize, 2] {
                let options = Options {
                    threads,
                    ..Options::marching_cubes(topology)
                };
                let id = BenchmarkId::new(format!("smooth{n}/{topology:?}"), format!("t{threads}"));
                g.bench_with_input(id, &options, |b, o| {
                    b.iter(|| extract(&volume, s.isovalue, o).unwrap())
                });
            }
        }
    }
    g.finish();
}

fn bench_refine_one(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    s: &SampleVolume,
    epsilon: f64,
    max_level: u32,
    rule: Rule,
) {
    let volume = s.volume();
    let options = Options {
        epsilon,
        max_level,
        rule,
        threads: 1,
        ..Options::default()
    };
    let out = extract(&volume, s.isovalue, &options)
        .unwrap()
        .stats
        .output_triangles;
    g.throughput(Throughput::Elements(out));
    let id = BenchmarkId::new(
        format!("{}/{rule:?}/L{max_level}", s.name),
        format!("eps{epsilon}"),
    );
    g.bench_with_input(id, &options, |b, o| {
        b.iter(|| extract(&volume, s.isovalue, o).unwrap())
    });
}

fn bench_refine(c: &mut Criterion) {
    let mut g = configure(c, "refine");
    let tube = samples::tube(9);
    for epsilon in [1e-3, 2e-4] {
        for rule in [Rule::A, Rule::A1, Rule::A2, Rule::B] {
            bench_refine_one(&mut g, &tube, epsilon, 10, rule);
        }
    }
    let atoms = samples::atoms(14);
    for epsilon in [1e-2, 1e-3] {
        for rule in [Rule::A, Rule::A1, Rule::A2, Rule::B] {
            bench_refine_one(&mut g, &atoms, epsilon, 10, rule);
        }
    }
    let ml = samples::marschner_lobb(41);
    for epsilon in [1e-2, 1e-3] {
        bench_refine_one(&mut g, &ml, epsilon, 5, Rule::A1);
    }
    g.finish();
}

criterion_group!(benches, bench_mc, bench_refine);
criterion_main!(benches);
