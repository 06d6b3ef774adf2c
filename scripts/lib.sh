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

# Warns when the disk holding the project has less free space than a full
# test run writes (about 9 GiB of build output): a full disk otherwise shows
# up as compiler crashes in every later stage, far from the cause.
# Environment: PMC_MIN_FREE_GIB (default 10).
check_free_space() {
    local root need free_kib
    root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
    need="${PMC_MIN_FREE_GIB:-10}"
    free_kib="$(df -Pk "$root" 2>/dev/null | awk 'NR == 2 { print $4 }')"
    [ -n "$free_kib" ] || return 0
    if [ "$free_kib" -lt $((need * 1024 * 1024)) ]; then
        echo "warning: only $((free_kib / 1024 / 1024)) GiB free on the disk of $root;" \
            "a full test run writes about 9 GiB (target/, build/). Free some space" \
            "(e.g. 'cargo clean', old clones) if the build fails with 'No space left on device'." >&2
    fi
    return 0
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

# --- ParaView plugin (paraview/, tests/paraview) ---------------------------
# ParaView 5.11 from Debian 12, installed without its recommendations: the
# recommended python3-paraview conflicts with python3-vtk9 (the VTK tests'
# Python), so it is only unpacked into build/paraview-root (pvbatch finds
# its Python modules there through PYTHONPATH; the plugin build reads its
# wrapping hierarchies). The -dev packages are those ParaView's CMake
# package looks for; openmpi-bin brings mpiexec.
PMC_PARAVIEW_PACKAGES=(paraview paraview-dev openmpi-bin libopenmpi-dev libutfcpp-dev
    libdouble-conversion-dev liblz4-dev liblzma-dev libexpat1-dev zlib1g-dev libeigen3-dev
    libavcodec-dev libavformat-dev libavutil-dev libswresample-dev libswscale-dev
    python3-numpy xvfb xauth libgl1-mesa-dri)

# Installs the ParaView packages that are missing and unpacks python3-paraview
# (the version of the installed paraview) into build/paraview-root.
# Environment: PMC_SKIP_APT=1 never calls apt-get.
ensure_paraview() {
    local root missing=() sudo="" version deb tmp
    root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
    [ "$(id -u)" -eq 0 ] || sudo="sudo"
    for p in "${PMC_PARAVIEW_PACKAGES[@]}"; do
        dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
    done
    if [ "${#missing[@]}" -gt 0 ]; then
        [ "${PMC_SKIP_APT:-0}" != 1 ] || { echo "error: missing packages: ${missing[*]}" >&2; return 1; }
        echo "installing Debian packages: ${missing[*]}"
        $sudo apt-get update -qq
        DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends \
            "${missing[@]}" >/dev/null || return 1
    fi
    version="$(dpkg-query -W -f='${Version}' paraview)"
    if [ "$(cat "$root/build/paraview-root/version" 2>/dev/null)" != "$version" ]; then
        [ "${PMC_SKIP_APT:-0}" != 1 ] || { echo "error: python3-paraview is not unpacked" >&2; return 1; }
        tmp="$(mktemp -d)"
        chmod 777 "$tmp" # apt downloads as its sandbox user (_apt)
        if ! (cd "$tmp" && apt-get download -qq "python3-paraview=$version" 2>/dev/null); then
            $sudo apt-get update -qq
            (cd "$tmp" && apt-get download -qq "python3-paraview=$version") || { rm -rf "$tmp"; return 1; }
        fi
        deb="$(ls "$tmp"/python3-paraview_*.deb)"
        rm -rf "$root/build/paraview-root"
        mkdir -p "$root/build/paraview-root"
        dpkg -x "$deb" "$root/build/paraview-root" || { rm -rf "$tmp"; return 1; }
        echo "$version" >"$root/build/paraview-root/version"
        rm -rf "$tmp"
    fi
}

# Sets up the environment of pvbatch and mpiexec: ParaView's Python modules
# from build/paraview-root, OpenMPI allowed to run as root (CI runs as root).
pmc_paraview_env() {
    local root
    root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
    export PYTHONPATH="$root/build/paraview-root/usr/lib/python3/dist-packages${PYTHONPATH:+:$PYTHONPATH}"
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
    # No InfiniBand or other fabrics on these machines: shared memory only.
    export OMPI_MCA_btl="self,vader" OMPI_MCA_btl_vader_single_copy_mechanism=none
}

# Builds the core (build/core) and the ParaView plugin (build/paraview),
# incrementally. Sets PMC_PARAVIEW_PLUGIN to the plugin's path.
pmc_build_paraview() {
    local root core build
    root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
    core="$root/build/core"
    build="$root/build/paraview"
    if [ "${PMC_SKIP_APT:-0}" != 1 ]; then ensure_packages || return 1; fi
    ensure_paraview || return 1
    ensure_rust || return 1
    if [ ! -f "$core/CMakeCache.txt" ]; then
        cmake -S "$root" -B "$core" -DCMAKE_BUILD_TYPE=Release || return 1
    fi
    cmake --build "$core" -j"${JOBS:-2}" || return 1
    if [ ! -f "$build/CMakeCache.txt" ]; then
        cmake -S "$root/paraview" -B "$build" -DCMAKE_BUILD_TYPE=Release \
            -DPreciseMC_DIR="$core" -DPRECISEMC_PARAVIEW_ROOT="$root/build/paraview-root" || return 1
    fi
    cmake --build "$build" -j"${JOBS:-2}" || return 1
    PMC_PARAVIEW_PLUGIN="$(cat "$build/precisemc_plugin_path.txt")"
}
