#!/usr/bin/env bash
# Runs every test of the project: the Rust core (rustfmt, clippy, unit,
# integration, property and doc tests, rustdoc without warnings, the crate
# as packaged), the C API (sanitizers, valgrind, CMake package), the VTK
# filter (CTest and pytest), the command-line tool, the benchmark's quick
# mode, a short fuzzing run and the ParaView plugin (serial and under MPI).
# Installs the Debian packages it needs. Idempotent; quick when nothing
# changed.
set -euo pipefail
cd "$(dirname "$0")/.."
source scripts/lib.sh

passed=0
failed=0
stage() {
    local name="$1"
    shift
    echo "==> $name"
    if "$@"; then
        passed=$((passed + 1))
        echo "<== $name: ok"
    else
        failed=$((failed + 1))
        echo "<== $name: FAILED"
    fi
}

check_free_space
ensure_packages
ensure_rust

stage "rustfmt" cargo fmt --all -- --check
stage "clippy" cargo clippy --all-targets -- -D warnings
stage "cargo test" cargo test --all-targets
stage "doc tests" cargo test --doc
# The documentation builds without warnings (broken intra-doc links): the
# internals' too, then the public API's (built last, so that target/doc
# holds the public docs; each mode checks links the other does not).
stage "rustdoc (private items)" env RUSTDOCFLAGS="-D warnings" \
  cargo doc --no-deps --quiet --document-private-items
stage "rustdoc" env RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --quiet
# The crate as crates.io would hold it (Cargo.toml's include list) builds
# on its own. --offline: the stages above fetched its dependencies.
stage "crate package" cargo package --allow-dirty --offline --quiet
stage "C API" bash tests/c/run.sh
stage "VTK filter" bash tests/vtk/run.sh
stage "command-line tool" bash tests/cli/run.sh
# bench/run.sh --quick: every configuration of the benchmark runs (about 90 s).
stage "benchmark smoke" bash bench/run.sh --quick
# Short libFuzzer run of each target (25 s each; fuzz/run.sh SECONDS for longer).
stage "fuzz (short)" bash fuzz/run.sh 25
stage "ParaView plugin" bash tests/paraview/run.sh

echo "test suites: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
