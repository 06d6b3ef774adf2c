#!/usr/bin/env bash
# Tests of the precisemc command-line tool (tests/cli/test_cli.py): every
# sample, every output and input format, the pictures, and every kind of
# bad input. Builds build/core and build/vtk first (incrementally, with
# pmc_build_vtk from scripts/lib.sh: a no-op after tests/vtk/run.sh).
# Prints "cli: N passed, M failed, K skipped" last (a check that cannot
# run here, as the thread-limit check without root, is skipped and said
# so); exits non-zero on any failure.
#
# Environment: JOBS, PMC_SKIP_APT (see scripts/lib.sh); CLI_TMP to keep the
# scratch files in a given directory.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
# shellcheck source=../../scripts/lib.sh
source "$ROOT/scripts/lib.sh"

# The build's output is shown only when it fails.
log="$(mktemp)"
trap 'rm -f "$log"' EXIT
if ! pmc_build_vtk >"$log" 2>&1; then
  cat "$log" >&2
  echo "cli: build failed"
  echo "cli: 0 passed, 1 failed"
  exit 1
fi

scratch="${CLI_TMP:-}"
if [[ -z "$scratch" ]]; then
  scratch="$(mktemp -d)"
  trap 'rm -f "$log"; rm -rf "$scratch"' EXIT
fi
PRECISEMC="$PMC_VTK_BUILD/bin/precisemc" CLI_TMP="$scratch" PYTHONDONTWRITEBYTECODE=1 \
  /usr/bin/python3 "$ROOT/tests/cli/test_cli.py"
