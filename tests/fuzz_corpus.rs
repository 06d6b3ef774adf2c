//! Replays the fuzz corpus (`fuzz/corpus/core/*`, `fuzz/corpus/c_api/*`)
//! through the same harness functions the libFuzzer targets call, on the
//! stable toolchain without libFuzzer, plus a few hundred pseudo-random
//! inputs of each. The harness panics when a guarantee is violated (see
//! `fuzz/src/lib.rs`); a failing file is named in the message.
//!
//! To add a regression input, copy it (a crash artifact or an interesting
//! input) into the corpus directory of its target.

#[path = "../fuzz/src/lib.rs"]
#[allow(dead_code)]
mod harness;

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};

fn corpus(dir: &str, target: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz")
        .join(dir)
        .join(target);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

fn replay(target: &str, f: fn(&[u8])) {
    replay_dir("corpus", target, f);
}

fn replay_dir(dir: &str, target: &str, f: fn(&[u8])) {
    let files = corpus(dir, target);
    assert!(!files.is_empty(), "empty corpus for {target}");
    let mut failures = Vec::new();
    for path in &files {
        let data = std::fs::read(path).unwrap();
        if catch_unwind(AssertUnwindSafe(|| f(&data))).is_err() {
            failures.push(path.display().to_string());
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} corpus files of {target} fail:\n{}",
        failures.len(),
        files.len(),
        failures.join("\n")
    );
}

/// Pseudo-random inputs of 0 to 300 bytes (splitmix64).
fn explore(f: fn(&[u8]), seed: u64, count: usize) {
    let mut s = seed;
    let mut next = || {
        s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    for i in 0..count {
        let len = (next() % 301) as usize;
        let data: Vec<u8> = (0..len).map(|_| next() as u8).collect();
        let t = std::time::Instant::now();
        let r = catch_unwind(AssertUnwindSafe(|| f(&data)));
        if t.elapsed().as_secs_f64() > 0.5 {
            let hex: String = data.iter().map(|b| format!("{b:02x}")).collect();
            eprintln!("slow input {i} ({:?}): {hex}", t.elapsed());
        }
        if r.is_err() {
            let hex: String = data.iter().map(|b| format!("{b:02x}")).collect();
            panic!("random input {i} (seed {seed}) fails; bytes (hex): {hex}");
        }
    }
}

#[test]
fn core_corpus() {
    replay("core", harness::fuzz_core);
}

#[test]
fn c_api_corpus() {
    replay("c_api", harness::fuzz_c_api);
}

#[test]
fn core_random_inputs() {
    explore(harness::fuzz_core, 1, 300);
}

#[test]
fn c_api_random_inputs() {
    explore(harness::fuzz_c_api, 2, 300);
}

/// Inputs of issues found by fuzzing and fixed (`fuzz/known/`): the
/// triangle cap exceeded by a few percent, and surfaces opened by
/// refinement where a sample differs from the isovalue by a rounding error
/// of the value range. The harness checks every input as strictly as
/// these (see README, Reliability).
#[test]
fn known_issues() {
    replay_dir("known", "core", harness::fuzz_core);
}
