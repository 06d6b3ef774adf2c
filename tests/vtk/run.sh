#!/usr/bin/env bash
# Build the PreciseMC core and the VTK module, then run the VTK validation
# tests: CTest (C++) in build/vtk and pytest under Debian's /usr/bin/python3.
#
#   tests/vtk/run.sh            # from anywhere; works in the repository root
#
# Idempotent: packages are installed only when missing, configure steps run
# only once (CMake re-runs itself when a CMakeLists.txt changes) and the
# builds are incremental (pmc_build_vtk in scripts/lib.sh, shared with the
# quick start and the command-line tests). Exits non-zero if anything fails.
#
# Environment: JOBS (default 2) build parallelism; PMC_SKIP_APT=1 to never
# call apt-get.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
# shellcheck source=../../scripts/lib.sh
source "$ROOT/scripts/lib.sh"
PY=/usr/bin/python3

log() { printf '\n== %s\n' "$*"; }

log "build: build/core and build/vtk"
pmc_build_vtk
VTK_BUILD="$PMC_VTK_BUILD"

# --- Tests ------------------------------------------------------------------
status=0
log "ctest"
# No tests at all (cpp/Testing leaves them out, with a warning, when a VTK
# component is missing) is a failure, not a pass.
(cd "$VTK_BUILD" && ctest --output-on-failure --no-tests=error) || status=1

log "pytest"
PYPATH="$(cat "$VTK_BUILD/precisemc_pythonpath.txt" 2>/dev/null || true)"
if [[ -z "$PYPATH" ]]; then
  echo "no Python package was built (VTK without Python wrapping?)" >&2
  exit 1
fi
PYTHONPATH="$PYPATH${PYTHONPATH:+:$PYTHONPATH}" \
LD_LIBRARY_PATH="$VTK_BUILD/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}" \
PRECISEMC_VTK_BUILD="$VTK_BUILD" PYTHONDONTWRITEBYTECODE=1 \
  "$PY" -m pytest "$ROOT/tests/vtk" -q -p no:cacheprovider || status=1

if ((status)); then
  log "FAILED"
else
  log "all VTK tests passed"
fi
exit "$status"
