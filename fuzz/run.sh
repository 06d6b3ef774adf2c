#!/usr/bin/env bash
# Runs the libFuzzer targets (core, c_api) for a bounded time each, on the
# stable toolchain: cargo-fuzz needs -Zsanitizer=address, which
# RUSTC_BOOTSTRAP=1 allows on stable. Installs cargo-fuzz (crates.io) if
# missing. New inputs go to fuzz/work/<target> (ignored by git); the
# curated corpus fuzz/corpus/<target> is only read. A crash leaves its
# input in fuzz/artifacts/<target>/ and fails the run: copy it into
# fuzz/corpus/<target>/ once fixed (tests/fuzz_corpus.rs replays it).
# A unit over 60 s counts as a hang: the instrumented build runs deep
# capped refinement (level 10 under a small triangle cap) some 60 times
# slower than a release build, where such inputs take well under 1 s.
#
# Usage: bash fuzz/run.sh [SECONDS_PER_TARGET] [TARGET...]
#   bash fuzz/run.sh            # 25 s per target (the test script's stage)
#   bash fuzz/run.sh 3600 core  # one hour on the core target
# Env: PMC_FUZZ_JOBS=<n> parallel fuzzing jobs per target (default 1).
set -euo pipefail
cd "$(dirname "$0")"
secs=${1:-25}
shift || true
targets=("$@")
((${#targets[@]})) || targets=(core c_api)

if ! cargo fuzz --version >/dev/null 2>&1; then
    echo "installing cargo-fuzz" >&2
    cargo install cargo-fuzz --locked >&2
fi
toolchain=()
if command -v rustup >/dev/null 2>&1; then toolchain=(+stable); fi
export RUSTC_BOOTSTRAP=1

jobs=()
if [[ -n ${PMC_FUZZ_JOBS:-} ]]; then jobs=(-jobs="$PMC_FUZZ_JOBS" -workers="$PMC_FUZZ_JOBS"); fi
status=0
for t in "${targets[@]}"; do
    mkdir -p "work/$t" "artifacts/$t"
    echo "==> fuzz $t for ${secs}s" >&2
    if ! cargo "${toolchain[@]}" fuzz run -O "$t" "work/$t" "corpus/$t" -- \
        -max_total_time="$secs" -timeout=60 -rss_limit_mb=3072 -max_len=4096 \
        ${jobs[@]+"${jobs[@]}"} -print_final_stats=1 2>"work/$t.log"; then
        status=1
        echo "FAILED: fuzz target $t (log: fuzz/work/$t.log)" >&2
        grep -a -A15 "panicked\|ERROR: libFuzzer\|ERROR: AddressSanitizer" "work/$t.log" | head -40 >&2 || true
    fi
    grep -a "stat::number_of_executed_units\|stat::average_exec_per_sec\|stat::peak_rss_mb\|^Done" "work/$t.log" >&2 || true
done
exit $status
