#!/usr/bin/env bash
# Benchmarks and accuracy report: PreciseMC against vtkMarchingCubes,
# vtkFlyingEdges3D and "upsample then contour" (bench/compare.py).
#
#   bash bench/run.sh            # full run, ~14-23 min on 2 cores -> bench/results/
#   bash bench/run.sh --quick    # ~1.5 min, small volumes -> bench/results-quick/
#   bash bench/run.sh --only ml,brain_epi   # re-run some volumes' rows
#   bash bench/run.sh --interleaved-only    # ~1 min, only the interleaved measure
#
# Builds build/core and build/vtk first (incrementally, pmc_build_vtk), installs
# python3-matplotlib from Debian if missing, and fetches the real volume (a
# test file of the nibabel wheel, from PyPI) into bench/.cache once.
# Environment: JOBS, PMC_SKIP_APT (see scripts/lib.sh), PMC_BENCH_CACHE.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# shellcheck source=../scripts/lib.sh
source "$ROOT/scripts/lib.sh"
PMC_DEBIAN_PACKAGES+=(python3-matplotlib python3-pip unzip)

log="$(mktemp)"
trap 'rm -f "$log"' EXIT
if ! pmc_build_vtk >"$log" 2>&1; then
  cat "$log" >&2
  echo "bench: build failed" >&2
  exit 1
fi

# The real volume: frame 0 of nibabel's tests/data/example4d.nii.gz (an
# fMRI EPI scan, 128x96x24 int16), taken from the nibabel wheel on PyPI.
cache="${PMC_BENCH_CACHE:-$ROOT/bench/.cache}"
mkdir -p "$cache"
if [[ ! -f "$cache/example4d.nii.gz" ]]; then
  tmp="$(mktemp -d)"
  if /usr/bin/python3 -m pip download --quiet --no-deps --only-binary=:all: \
      nibabel==5.4.2 -d "$tmp" >"$log" 2>&1 &&
    unzip -q -o -j "$tmp"/nibabel-*.whl 'nibabel/tests/data/example4d.nii.gz' -d "$cache"; then
    :
  else
    echo "bench: could not fetch nibabel's example4d.nii.gz from PyPI; the real volume is left out" >&2
  fi
  rm -rf "$tmp"
fi

PYTHONPATH="$(cat "$PMC_VTK_BUILD/precisemc_pythonpath.txt")${PYTHONPATH:+:$PYTHONPATH}" \
  PYTHONDONTWRITEBYTECODE=1 PMC_BENCH_CACHE="$cache" \
  /usr/bin/python3 "$ROOT/bench/compare.py" "$@"
