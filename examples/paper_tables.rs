//! Prints Markdown tables in the style of Tables 1 and 2 of Allamandri,
//! Cignoni, Montani and Scopigno, measured on the built-in samples:
//!
//! * Table 1: the thin "tube" (9x9x9, threshold 130.5) and the atom density
//!   map (14x14x14, threshold 50.5, like the paper's SOD section), for
//!   several epsilons and every rule, with max level 10;
//! * Table 2: the atom density map with max level 1..5 at three epsilons.
//!
//! Times are the wall time of one `extract` call on one thread (as the
//! paper's single-CPU figures), median of 5 runs (of 3 for configurations
//! taking over half a second a run), in milliseconds.
//!
//! ```text
//! cargo run --release --example paper_tables
//! ```

use std::time::Instant;

use precisemc::samples::{self, SampleVolume};
use precisemc::{extract, Mesh, Options, Rule, Topology};

/// Runs per configuration; the time printed is their median.
const RUNS: usize = 5;
/// Configurations whose first 3 runs take longer than this (ms) in total
/// report the median of those 3.
const SLOW_MS: f64 = 1500.0;

/// The rules compared, in the paper's order (B last: the paper describes it
/// but does not tabulate it).
const RULES: [Rule; 4] = [Rule::A, Rule::A1, Rule::A2, Rule::B];

/// One extraction measured `RUNS` times (3 when slow): the last mesh and
/// the median wall time in milliseconds.
fn measure(s: &SampleVolume, options: &Options) -> (Mesh, f64) {
    let volume = s.volume();
    let mut times = Vec::with_capacity(RUNS);
    let mut mesh = None;
    for run in 0..RUNS {
        // Slow configurations stop after 3 runs to keep the whole example
        // under a minute.
        if run == 3 && times.iter().sum::<f64>() > SLOW_MS {
            break;
        }
        let t = Instant::now();
        let m = extract(&volume, s.isovalue, options).expect("extraction failed");
        times.push(t.elapsed().as_secs_f64() * 1e3);
        mesh = Some(m);
    }
    times.sort_by(f64::total_cmp);
    (mesh.unwrap(), times[times.len() / 2])
}

fn options(epsilon: f64, max_level: u32, rule: Rule) -> Options {
    Options {
        epsilon,
        max_level,
        rule,
        topology: Topology::Trilinear,
        threads: 1,
        ..Options::default()
    }
}

/// Thousands separators, as in the paper.
fn thousands(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

fn machine() -> String {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|info| {
            info.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|m| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".to_string());
    format!("{model}, nproc = {cores}")
}

/// Plain Marching Cubes on the sample: triangles (trilinear and classic
/// topology) and the median time.
fn mc_line(s: &SampleVolume) -> String {
    let (tri, t) = measure(
        s,
        &Options {
            threads: 1,
            ..Options::marching_cubes(Topology::Trilinear)
        },
    );
    let (classic, _) = measure(
        s,
        &Options {
            threads: 1,
            ..Options::marching_cubes(Topology::Classic)
        },
    );
    format!(
        "MC: {} faces ({} with the vtkMarchingCubes table), {} ambiguous cells, {:.3} ms",
        thousands(tri.stats.mc_triangles),
        thousands(classic.stats.mc_triangles),
        tri.stats.ambiguous_cells,
        t
    )
}

/// Table 1: rows epsilon, column groups rules.
fn table1(s: &SampleVolume, label: &str, inverse_eps: &[u32], max_level: u32) {
    println!(
        "### \"{label}\" ({}x{}x{}, threshold={}, max level {max_level})\n",
        s.dims[0], s.dims[1], s.dims[2], s.isovalue
    );
    println!("{}\n", mc_line(s));
    let mut head = String::from("| precision (ε) |");
    let mut sep = String::from("|---|");
    for rule in RULES {
        head += &format!(" Rule {rule:?} #faces | maxL | meanL | time (ms) |");
        sep += "---:|---:|---:|---:|";
    }
    println!("{head}\n{sep}");
    let mut diag = Vec::new();
    for &inv in inverse_eps {
        let mut row = format!("| 1/{inv} |");
        let mut drow = format!("| 1/{inv} |");
        for rule in RULES {
            let (m, t) = measure(s, &options(1.0 / inv as f64, max_level, rule));
            let st = &m.stats;
            row += &format!(
                " {} | {} | {:.3} | {:.3} |",
                thousands(st.output_triangles),
                st.max_level,
                st.mean_level,
                t
            );
            drow += &format!(
                " {} | {} | {} | {} |",
                thousands(st.samples_evaluated),
                thousands(st.projection_failures),
                thousands(st.faces_above_epsilon),
                thousands(st.cells_refined_on_faces_only)
            );
        }
        println!("{row}");
        diag.push(drow);
    }
    println!("\nDiagnostics (sample points tested, projection failures, faces at max level still above ε, cells refined on their faces only):\n");
    let mut head = String::from("| precision (ε) |");
    let mut sep = String::from("|---|");
    for rule in RULES {
        head += &format!(" Rule {rule:?} tested | failures | above ε | faces only |");
        sep += "---:|---:|---:|---:|";
    }
    println!("{head}\n{sep}");
    for d in diag {
        println!("{d}");
    }
    println!();
}

/// Table 2: per epsilon, columns max level 1..=5, rows maxL, meanL, faces,
/// time (rule A1).
fn table2(s: &SampleVolume, label: &str, inverse_eps: &[u32], levels: u32) {
    println!(
        "### \"{label}\" ({}x{}x{}, threshold={}), Rule A1, max level 1..{levels}\n",
        s.dims[0], s.dims[1], s.dims[2], s.isovalue
    );
    println!("{}\n", mc_line(s));
    let mut head = String::from("| |");
    let mut sep = String::from("|---|");
    let mut lev = String::from("| max level |");
    for &inv in inverse_eps {
        for l in 1..=levels {
            head += &if l == 1 {
                format!(" ε = 1/{inv} |")
            } else {
                " |".to_string()
            };
            sep += "---:|";
            lev += &format!(" {l} |");
        }
    }
    let mut rows = [
        String::from("| maxL |"),
        String::from("| meanL |"),
        String::from("| no. faces |"),
        String::from("| time (ms) |"),
    ];
    for &inv in inverse_eps {
        for l in 1..=levels {
            let (m, t) = measure(s, &options(1.0 / inv as f64, l, Rule::A1));
            let st = &m.stats;
            rows[0] += &format!(" {} |", st.max_level);
            rows[1] += &format!(" {:.3} |", st.mean_level);
            rows[2] += &format!(" {} |", thousands(st.output_triangles));
            rows[3] += &format!(" {:.3} |", t);
        }
    }
    println!("{head}\n{sep}\n{lev}");
    for r in rows {
        println!("{r}");
    }
    println!();
}

fn main() {
    let start = Instant::now();
    println!("## PreciseMC: tables in the style of the paper's Tables 1-2\n");
    println!(
        "Machine: {}. One thread per extraction; times are wall-clock medians of {RUNS} runs \
         (3 when a run takes over {:.1} s).\n",
        machine(),
        SLOW_MS / 3000.0
    );
    let tube = samples::tube(9);
    let atoms = samples::atoms(14);

    println!("## Table 1\n");
    table1(&tube, "tube", &[1000, 2000, 4000, 5000, 10000], 10);
    table1(&atoms, "atoms", &[100, 500, 1000], 10);

    println!("## Table 2\n");
    table2(&atoms, "atoms", &[100, 500, 1000], 5);

    println!("Total time: {:.1} s", start.elapsed().as_secs_f64());
}
