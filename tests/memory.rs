//! Memory bound of refinement under a triangle cap.
//!
//! A tiny epsilon (1e-6) with the highest level (10) would ask for
//! billions of triangles; with `max_triangles` set the output respects the
//! cap, `stats.budget_reached` is set, the mesh stays watertight, and the
//! peak resident memory (VmHWM from /proc/self/status, which must be
//! readable on Linux) grows by at most
//!
//!   input bytes + 100 bytes per output triangle + 16 MiB
//!
//! over its value once the input is built (observed on a 96^3 f64 volume,
//! cap 600 000: 41-43 MiB for 465 832 triangles, about 92-97 bytes per
//! triangle, against a bound of 67 MiB; until 2026-11-29 the bound was
//! 200 bytes per capped triangle + 64 MiB, 185 MiB, which a doubling
//! of the memory per triangle passed). The cap is what bounds the
//! working memory: refinement runs level by level and a level is kept
//! only while its triangles fit.
//!
//! This file holds a single test so that its binary runs nothing else
//! concurrently (Cargo builds each file of tests/ into its own process),
//! which would disturb the peak.

mod common;

use common::*;
use precisemc::{extract, Options, Rule, Topology, Volume};

/// Peak resident set size of this process, bytes (Linux only).
fn vm_hwm() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[test]
fn tiny_epsilon_is_held_by_the_triangle_cap() {
    let dims = [96, 96, 96];
    // Smooth blobs (a product of sines, cheaper than Gaussian bumps), the
    // border below the isovalue so that the surface is closed.
    let mut values = grid_fn(dims, |x, y, z| {
        (0.063 * x).sin() * (0.057 * y).cos()
            + (0.051 * y).sin() * (0.069 * z).cos()
            + (0.06 * z).sin() * (0.054 * x).cos()
            - 0.3
    });
    set_border(&mut values, dims, -2.0);
    let input_bytes = std::mem::size_of_val(values.as_slice()) as u64;
    let vol = Volume::new(&values, dims_u64(dims));
    let cap = 600_000u64;
    let opts = Options {
        epsilon: 1e-6,
        max_level: 10,
        rule: Rule::A1,
        topology: Topology::Trilinear,
        max_triangles: cap,
        threads: 2,
        ..Options::default()
    };
    let before = vm_hwm();
    let t = std::time::Instant::now();
    let mesh = extract(&vol, 0.0, &opts).unwrap();
    let secs = t.elapsed().as_secs_f64();
    let after = vm_hwm();

    assert_sane(&mesh);
    let s = &mesh.stats;
    eprintln!(
        "MC {} -> {} triangles (cap {cap}), level {} of 10, {secs:.2} s",
        s.mc_triangles, s.output_triangles, s.effective_max_level
    );
    assert!(
        s.mc_triangles > 20_000 && s.mc_triangles < cap,
        "{}",
        s.mc_triangles
    );
    assert!(s.output_triangles <= cap, "{} > cap", s.output_triangles);
    assert!(s.budget_reached);
    assert!(s.effective_max_level >= 1 && s.effective_max_level < 10);
    // The highest level that fits is kept: not the Marching Cubes mesh
    // alone (observed: 120 400 MC triangles, 465 832 at level 1, 0.8 s).
    assert!(s.output_triangles > s.mc_triangles);
    let c = check_mesh(&mesh);
    assert!(
        c.boundary_edges == 0
            && c.unbalanced_edges == 0
            && c.misoriented_edges == 0
            && c.degenerate == 0
            && c.duplicates == 0,
        "{c:?}"
    );
    assert!(signed_volume(&mesh.index_points, &mesh.triangles) > 0.0);

    if cfg!(target_os = "linux") {
        assert!(before.is_some() && after.is_some(), "VmHWM not read");
    }
    if let (Some(before), Some(after)) = (before, after) {
        let growth = after.saturating_sub(before);
        let bound = input_bytes + 100 * s.output_triangles + (16 << 20);
        eprintln!(
            "VmHWM {} -> {} MiB: growth {:.1} MiB, bound {:.1} MiB (input {:.1} MiB)",
            before >> 20,
            after >> 20,
            growth as f64 / 1048576.0,
            bound as f64 / 1048576.0,
            input_bytes as f64 / 1048576.0
        );
        assert!(
            growth <= bound,
            "peak RSS grew by {growth} bytes, bound {bound}"
        );
    } else {
        eprintln!("no /proc/self/status: memory not measured");
    }
}
