#!/usr/bin/env bash
# Quick start: installs the missing Debian packages, builds the Rust core
# (build/core) and the VTK module with the precisemc tool (build/vtk, the
# same directories as the tests, so nothing builds twice), then runs the
# tool on the built-in samples:
#
#   precisemc --sample all -o out/sample.vtp --compare out/compare.png \
#             --distance out/distance.png
#
# which writes out/sample-{tube,atoms,ml}.vtp and the two pictures and
# prints a table per sample. Idempotent; quick when nothing changed.
# Needs Debian 12, root or sudo, and a Rust toolchain (https://rustup.rs).
# Environment: JOBS (default 2) build parallelism.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# shellcheck source=lib.sh
source "$ROOT/scripts/lib.sh"

ensure_packages
ensure_rust

# The build is logged to a file, shown only if it fails.
mkdir -p build out
log="$ROOT/build/quickstart-build.log"
echo "building build/core and build/vtk (log: build/quickstart-build.log) ..."
if ! pmc_build_vtk >"$log" 2>&1; then
  tail -n 40 "$log" >&2
  echo "quickstart: the build failed, see $log" >&2
  exit 1
fi

echo "running: precisemc --sample all -o out/sample.vtp --compare out/compare.png --distance out/distance.png"
echo
"$PMC_VTK_BUILD/bin/precisemc" --sample all -o out/sample.vtp \
  --compare out/compare.png --distance out/distance.png
echo
echo "the tool: $PMC_VTK_BUILD/bin/precisemc --help"
