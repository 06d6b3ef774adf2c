#!/usr/bin/env bash
# Build the PreciseMC core and the VTK module, then run the VTK validation
# tests: CTest (C++) in build/vtk and pytest under Debian's /usr/bin/python3.
#
#   tests/vtk/run.sh            # from anywhere; works in the repository root
#
# Idempotent: packages are installed only when missing, configure steps run
# only once (CMake re-runs itself when a CMakeLists.txt changes) and the
# builds are incremental. Exits non-zero if anything fails.
#
# Environment: JOBS (default 2) build parallelism; PMC_SKIP_APT=1 to never
# call apt-get.
set -euo pipefail

ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$ROOT"
JOBS="${JOBS:-2}"
PY=/usr/bin/python3
CORE_BUILD="$ROOT/build/core"
VTK_BUILD="$ROOT/build/vtk"

log() { printf '\n== %s\n' "$*"; }

# --- Debian packages -------------------------------------------------------
packages=(cmake g++ make libvtk9-dev python3-vtk9 python3-dev python3-numpy python3-pytest)
missing=()
for p in "${packages[@]}"; do
  if ! dpkg -s "$p" >/dev/null 2>&1; then
    missing+=("$p")
  fi
done
if ((${#missing[@]})); then
  if [[ "${PMC_SKIP_APT:-0}" == 1 ]]; then
    echo "missing packages: ${missing[*]} (PMC_SKIP_APT=1: not installing)" >&2
    exit 1
  fi
  log "installing ${missing[*]}"
  SUDO=()
  if [[ "$(id -u)" != 0 ]]; then SUDO=(sudo); fi
  "${SUDO[@]}" apt-get update -qq
  DEBIAN_FRONTEND=noninteractive "${SUDO[@]}" apt-get install -y -qq "${missing[@]}"
fi

# --- The core (Rust library, C header, CMake package) ----------------------
if [[ -f "$ROOT/CMakeLists.txt" ]]; then
  log "core: $CORE_BUILD"
  if [[ ! -f "$CORE_BUILD/CMakeCache.txt" ]]; then
    cmake -S . -B "$CORE_BUILD" -DCMAKE_BUILD_TYPE=Release
  fi
  cmake --build "$CORE_BUILD" -j"$JOBS"
  PRECISEMC_DIR="$CORE_BUILD"
else
  # No top-level CMake project yet: build with cargo and describe the
  # library with a minimal package file (same target names).
  log "core: no top-level CMakeLists.txt, using cargo and a stand-in package"
  cargo build --release -j"$JOBS"
  PRECISEMC_DIR="$ROOT/build/core-cargo"
  mkdir -p "$PRECISEMC_DIR"
  cat >"$PRECISEMC_DIR/PreciseMCConfig.cmake.new" <<CONFIG
# Stand-in for the PreciseMC package, written by tests/vtk/run.sh.
if (NOT TARGET PreciseMC::precisemc)
  add_library(PreciseMC::precisemc SHARED IMPORTED)
  set_target_properties(PreciseMC::precisemc PROPERTIES
    IMPORTED_LOCATION "$ROOT/target/release/libprecisemc.so"
    INTERFACE_INCLUDE_DIRECTORIES "$ROOT/include")
  add_library(PreciseMC::precisemc_static STATIC IMPORTED)
  set_target_properties(PreciseMC::precisemc_static PROPERTIES
    IMPORTED_LOCATION "$ROOT/target/release/libprecisemc.a"
    INTERFACE_INCLUDE_DIRECTORIES "$ROOT/include"
    INTERFACE_LINK_LIBRARIES "pthread;dl;m")
endif ()
set(PreciseMC_FOUND TRUE)
CONFIG
  # Only touch the file when it changes, to keep the VTK build incremental.
  if ! cmp -s "$PRECISEMC_DIR/PreciseMCConfig.cmake.new" "$PRECISEMC_DIR/PreciseMCConfig.cmake"; then
    mv "$PRECISEMC_DIR/PreciseMCConfig.cmake.new" "$PRECISEMC_DIR/PreciseMCConfig.cmake"
  else
    rm "$PRECISEMC_DIR/PreciseMCConfig.cmake.new"
  fi
fi

# --- The VTK module ----------------------------------------------------------
log "vtk module: $VTK_BUILD"
configured_dir=""
if [[ -f "$VTK_BUILD/CMakeCache.txt" ]]; then
  configured_dir="$(sed -n 's/^PreciseMC_DIR:[A-Z]*=//p' "$VTK_BUILD/CMakeCache.txt")"
fi
if [[ "$configured_dir" != "$PRECISEMC_DIR" ]]; then
  cmake -S cpp -B "$VTK_BUILD" \
    -DCMAKE_BUILD_TYPE=Release \
    -DPreciseMC_DIR="$PRECISEMC_DIR" \
    -DPython3_EXECUTABLE="$PY"
fi
cmake --build "$VTK_BUILD" -j"$JOBS"

# --- Tests ------------------------------------------------------------------
status=0
log "ctest"
(cd "$VTK_BUILD" && ctest --output-on-failure) || status=1

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
