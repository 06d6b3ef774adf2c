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
