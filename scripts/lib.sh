# Shared helpers of the project's scripts (sourced, not run).

# Debian packages the build and the tests need.
PMC_DEBIAN_PACKAGES=(cmake pkg-config g++ libvtk9-dev python3-vtk9 python3-pytest python3-numpy xvfb xauth valgrind)

# Installs whatever of PMC_DEBIAN_PACKAGES is missing (quick when all are there).
ensure_packages() {
    local missing=()
    for p in "${PMC_DEBIAN_PACKAGES[@]}"; do
        dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
    done
    if [ "${#missing[@]}" -gt 0 ]; then
        echo "installing Debian packages: ${missing[*]}"
        local sudo=""
        [ "$(id -u)" -eq 0 ] || sudo="sudo"
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "${missing[@]}" >/dev/null
    fi
}

# Makes sure cargo, clippy and rustfmt are available.
ensure_rust() {
    if ! command -v cargo >/dev/null 2>&1 && [ -f "$HOME/.cargo/env" ]; then
        # shellcheck disable=SC1091
        source "$HOME/.cargo/env"
    fi
    command -v cargo >/dev/null 2>&1 || { echo "error: Rust (cargo) is required: https://rustup.rs" >&2; return 1; }
    if command -v rustup >/dev/null 2>&1; then
        rustup component list --installed 2>/dev/null | grep -q '^clippy' || rustup component add clippy
        rustup component list --installed 2>/dev/null | grep -q '^rustfmt' || rustup component add rustfmt
    fi
}

# The VTK side adds the Python headers and make to the list above, and
# Mesa's software OpenGL driver, which the pictures render with under Xvfb.
PMC_DEBIAN_PACKAGES+=(make python3-dev libgl1-mesa-dri)

# Builds the core (build/core: Rust library, C header, CMake package) and the
# VTK module with its Python wrapping, C++ tests and the precisemc tool
# (build/vtk), incrementally: configure steps run once, later calls only
# rebuild what changed. Shared by tests/vtk/run.sh, tests/cli/run.sh and
# scripts/quickstart.sh, so nothing builds twice. Sets PMC_VTK_BUILD.
# Environment: JOBS (default 2), PMC_SKIP_APT=1 never calls apt-get.
pmc_build_vtk() {
    local root core vtk configured=""
    root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
    core="$root/build/core"
    vtk="$root/build/vtk"
    if [ "${PMC_SKIP_APT:-0}" != 1 ]; then ensure_packages || return 1; fi
    ensure_rust || return 1
    if [ ! -f "$core/CMakeCache.txt" ]; then
        cmake -S "$root" -B "$core" -DCMAKE_BUILD_TYPE=Release || return 1
    fi
    cmake --build "$core" -j"${JOBS:-2}" || return 1
    if [ -f "$vtk/CMakeCache.txt" ]; then
        configured="$(sed -n 's/^PreciseMC_DIR:[A-Z]*=//p' "$vtk/CMakeCache.txt")"
    fi
    if [ "$configured" != "$core" ]; then
        cmake -S "$root/cpp" -B "$vtk" -DCMAKE_BUILD_TYPE=Release \
            -DPreciseMC_DIR="$core" -DPython3_EXECUTABLE=/usr/bin/python3 || return 1
    fi
    cmake --build "$vtk" -j"${JOBS:-2}" || return 1
    PMC_VTK_BUILD="$vtk"
}
