//! Scale test (not run in CI): a 1024x1024x512 `u8` volume and a 512^3
//! `f32` volume of smooth fields, generated in place, extracted with
//! refinement off and with a moderate refinement (epsilon 0.01, max level
//! 3). Prints time, triangles and peak RSS (VmHWM) against input and
//! output sizes.
//!
//! ```text
//! cargo run --release --example scale            # every case
//! cargo run --release --example scale -- f32 mc  # one case
//! ```
//!
//! Each case runs in a child process of its own so that its peak RSS is
//! not mixed with the others'. Needs about 3 GB of memory.

use std::process::Command;
use std::time::Instant;

use precisemc::{extract, Options, Volume};

fn vm_hwm_mib() -> f64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1)?.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// A smooth field in [-1.5, 1.5]: sums of products of sines of
/// wavelengths 60 to 110 samples (precomputed per axis, so generating
/// half a billion samples takes a few seconds).
fn field(dims: [usize; 3], mut put: impl FnMut(usize, f64)) {
    let axis = |n: usize, a: f64, b: f64| -> (Vec<f64>, Vec<f64>) {
        (
            (0..n).map(|i| (a * i as f64).sin()).collect(),
            (0..n).map(|i| (b * i as f64).cos()).collect(),
        )
    };
    let (sx, cx) = axis(dims[0], 0.063, 0.054);
    let (sy, cy) = axis(dims[1], 0.051, 0.057);
    let (sz, cz) = axis(dims[2], 0.06, 0.069);
    let mut idx = 0;
    for k in 0..dims[2] {
        for j in 0..dims[1] {
            for i in 0..dims[0] {
                put(idx, sx[i] * cy[j] + sy[j] * cz[k] + sz[k] * cx[i]);
                idx += 1;
            }
        }
    }
}

fn run_case(kind: &str, mode: &str) {
    let t0 = Instant::now();
    let (dims, u8s, f32s) = match kind {
        "u8" => {
            let dims = [1024usize, 1024, 512];
            let mut v = vec![0u8; dims[0] * dims[1] * dims[2]];
            field(dims, |i, f| v[i] = (127.5 + 80.0 * f).round() as u8);
            (dims, v, Vec::new())
        }
        _ => {
            let dims = [512usize, 512, 512];
            let mut v = vec![0f32; dims[0] * dims[1] * dims[2]];
            field(dims, |i, f| v[i] = f as f32);
            (dims, Vec::new(), v)
        }
    };
    let t_gen = t0.elapsed().as_secs_f64();
    let d = [dims[0] as u64, dims[1] as u64, dims[2] as u64];
    let (vol, iso, input_bytes) = if kind == "u8" {
        (Volume::new(&u8s, d), 100.5, u8s.len())
    } else {
        (Volume::new(&f32s, d), 0.3, f32s.len() * 4)
    };
    let opts = if mode == "mc" {
        Options::marching_cubes(Default::default())
    } else {
        Options {
            epsilon: 0.01,
            max_level: 3,
            ..Options::default()
        }
    };
    let before = vm_hwm_mib();
    let t = Instant::now();
    let mesh = extract(&vol, iso, &opts).expect("extraction failed");
    let secs = t.elapsed().as_secs_f64();
    let after = vm_hwm_mib();
    // Output arrays: points and index points (2 x 24 B), triangles (24 B),
    // levels (1 B).
    let out_bytes = mesh.points.len() * 48 + mesh.triangles.len() * 25;
    let mib = |b: usize| b as f64 / 1048576.0;
    println!(
        "{kind:>3} {:>4}x{:>4}x{:>3} {:>10} | {:>6.1} s | MC {:>10} -> {:>10} triangles, {:>9} points | \
         input {:>6.0} MiB, output {:>6.0} MiB, VmHWM {:>6.0} MiB (before extraction {:>6.0}) | generation {:.1} s",
        dims[0],
        dims[1],
        dims[2],
        if mode == "mc" { "MC" } else { "eps 0.01/3" },
        secs,
        mesh.stats.mc_triangles,
        mesh.triangles.len(),
        mesh.points.len(),
        mib(input_bytes),
        mib(out_bytes),
        after,
        before,
        t_gen,
    );
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() == 3 {
        run_case(&args[1], &args[2]);
        return;
    }
    let exe = std::env::current_exe().expect("current exe");
    println!(
        "{} threads; each case in its own process (VmHWM is per process)",
        std::thread::available_parallelism().map_or(0, |n| n.get())
    );
    for kind in ["f32", "u8"] {
        for mode in ["mc", "refine"] {
            let status = Command::new(&exe).args([kind, mode]).status();
            match status {
                Ok(s) if s.success() => {}
                other => println!("{kind} {mode}: failed ({other:?})"),
            }
        }
    }
}
