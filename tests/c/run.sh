#!/usr/bin/env bash
# C API tests: builds the crate (release), then builds and runs the C and
# C++ test programs against it
#   1. normally, linked with the shared library,
#   2. with -fsanitize=address,undefined on the C side, linked with the
#      static library (LeakSanitizer on),
#   3. under valgrind --leak-check=full, linked with the static library,
# then tests the CMake package (install tree, build tree, pkg-config, and
# a plain `cargo build` into the target directory it shares: two more
# compilations of the crate).
#
# Usage: bash tests/c/run.sh        (from anywhere; idempotent)
# Env:   CARGO_TARGET_DIR           cargo's target directory (default: <crate>/target)
#        PMC_SKIP_VALGRIND=1        skip the valgrind pass
#        PMC_SKIP_CMAKE=1           skip the CMake package tests
#        PMC_TEST_SEED=<n>          seed of test_random
#
# Prints "c-api: N passed, M failed" last and exits non-zero on any failure.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
TARGET_DIR=${CARGO_TARGET_DIR:-$ROOT/target}
LIB_DIR=$TARGET_DIR/release
OUT=$TARGET_DIR/c-tests
LOGS=$OUT/logs

passed=0
failed=0
failed_names=()

log() { printf '%s\n' "$*" >&2; }

# Runs one test: run_test NAME COMMAND... (output in $LOGS/NAME.log).
run_test() {
    local name=$1
    shift
    local logfile=$LOGS/$name.log
    if "$@" >"$logfile" 2>&1; then
        passed=$((passed + 1))
        log "PASS $name"
    else
        failed=$((failed + 1))
        failed_names+=("$name")
        log "FAIL $name (log: $logfile)"
        tail -n 30 "$logfile" >&2 || true
    fi
}

finish() {
    if ((failed > 0)); then
        log "failed: ${failed_names[*]}"
    fi
    echo "c-api: $passed passed, $failed failed"
    if ((failed > 0)); then exit 1; fi
    exit 0
}

# --- Debian packages ----------------------------------------------------------
need=()
for pkg in gcc g++ make cmake pkg-config valgrind; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
done
if ((${#need[@]} > 0)); then
    log "installing: ${need[*]}"
    export DEBIAN_FRONTEND=noninteractive
    if ! apt-get install -y --no-install-recommends "${need[@]}" >&2; then
        apt-get update >&2
        apt-get install -y --no-install-recommends "${need[@]}" >&2
    fi
fi

# --- the crate ----------------------------------------------------------------
mkdir -p "$OUT/bin" "$LOGS"
rm -f "$LOGS"/*.log
# Built with the SONAME the CMake build gives it (libprecisemc.so.0.<minor>
# before 1.0, as CMakeLists.txt says), so that the CMake package test
# below shares this build instead of linking the library again; programs
# linked against it find the SONAME as a link beside it.
version=$(sed -n 's/^#define PMC_VERSION_STRING "\(.*\)"/\1/p' "$ROOT/include/precisemc.h")
IFS=. read -r vmajor vminor _ <<<"$version"
if ((vmajor == 0)); then SONAME=libprecisemc.so.0.$vminor; else SONAME=libprecisemc.so.$vmajor; fi
log "cargo build --release --lib (SONAME $SONAME)"
(cd "$ROOT" && PRECISEMC_SONAME=$SONAME cargo build --release --lib >&2)
for f in libprecisemc.a libprecisemc.so; do
    [[ -f $LIB_DIR/$f ]] || { log "missing $LIB_DIR/$f"; exit 1; }
done
ln -sfn libprecisemc.so "$LIB_DIR/$SONAME"

CWARN=(-std=c99 -Wall -Wextra -Wpedantic -Werror)
CXXWARN=(-std=c++11 -Wall -Wextra -Wpedantic -Werror)
INC=(-I"$ROOT/include" -I"$ROOT/tests/c")
# The native libraries of the Rust static library (cargo rustc -- --print
# native-static-libs), as in cmake/PreciseMCCargo.cmake.
NATIVE=(-lgcc_s -lutil -lrt -lpthread -lm -ldl)
SHARED=(-L"$LIB_DIR" -lprecisemc -Wl,-rpath,"$LIB_DIR" -lm -pthread)
STATIC=("$LIB_DIR/libprecisemc.a" "${NATIVE[@]}" -pthread)
SAN=(-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer)
PROGRAMS=(test_extract test_errors test_progress test_random test_robust test_executor test_struct_size)

build() { # build OUTPUT COMPILER FLAGS... (compile errors are test failures)
    local out=$1
    shift
    "$@" -o "$out"
}

# --- compile-only checks --------------------------------------------------------
for std in c99 c11; do
    run_test "header_alone_$std" gcc -std=$std -Wall -Wextra -Wpedantic -Werror \
        -I"$ROOT/include" -c "$ROOT/tests/c/header_alone.c" -o "$OUT/bin/header_alone_$std.o"
done
run_test header_alone_cxx11 g++ "${CXXWARN[@]}" -I"$ROOT/include" -x c++ \
    -c "$ROOT/tests/c/header_alone.c" -o "$OUT/bin/header_alone_cxx.o"

# --- 1. normal, shared library ----------------------------------------------------
for p in "${PROGRAMS[@]}"; do
    run_test "build_$p" build "$OUT/bin/$p" gcc "${CWARN[@]}" -O1 -g "${INC[@]}" \
        "$ROOT/tests/c/$p.c" "${SHARED[@]}"
    [[ -x $OUT/bin/$p ]] && run_test "run_$p" "$OUT/bin/$p"
done
# Unloading after extractions on helper threads (dlopen, shared library only).
run_test build_test_unload build "$OUT/bin/test_unload" gcc "${CWARN[@]}" -O1 -g "${INC[@]}" \
    "$ROOT/tests/c/test_unload.c" -ldl -lm -pthread
[[ -x $OUT/bin/test_unload ]] && run_test run_test_unload "$OUT/bin/test_unload" "$LIB_DIR/libprecisemc.so"
run_test build_test_cxx build "$OUT/bin/test_cxx" g++ "${CXXWARN[@]}" -O1 -g "${INC[@]}" \
    "$ROOT/tests/c/test_cxx.cpp" "${SHARED[@]}"
[[ -x $OUT/bin/test_cxx ]] && run_test run_test_cxx "$OUT/bin/test_cxx"

# --- 2. AddressSanitizer + UndefinedBehaviorSanitizer, static library -----------
# LeakSanitizer is on: the library frees everything it allocates (thread
# locals included), so a leak is a real failure.
export ASAN_OPTIONS=detect_leaks=1:abort_on_error=0:halt_on_error=1
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
for p in "${PROGRAMS[@]}"; do
    run_test "build_asan_$p" build "$OUT/bin/asan_$p" gcc "${CWARN[@]}" -O1 -g "${SAN[@]}" \
        "${INC[@]}" "$ROOT/tests/c/$p.c" "${STATIC[@]}"
    [[ -x $OUT/bin/asan_$p ]] && run_test "run_asan_$p" "$OUT/bin/asan_$p"
done
run_test build_asan_test_cxx build "$OUT/bin/asan_test_cxx" g++ "${CXXWARN[@]}" -O1 -g \
    "${SAN[@]}" "${INC[@]}" "$ROOT/tests/c/test_cxx.cpp" "${STATIC[@]}"
[[ -x $OUT/bin/asan_test_cxx ]] && run_test run_asan_test_cxx "$OUT/bin/asan_test_cxx"
unset ASAN_OPTIONS UBSAN_OPTIONS

# --- 3. valgrind, static library ------------------------------------------------------
if [[ ${PMC_SKIP_VALGRIND:-0} != 1 ]]; then
    # "Possibly lost" blocks are reported but not errors: the library's
    # helper threads outlive pmc_extract (parked for reuse), and those
    # still alive at process exit hold their thread-local blocks.
    VG=(valgrind --leak-check=full --errors-for-leak-kinds=definite,indirect
        --error-exitcode=1 --quiet)
    for p in "${PROGRAMS[@]}"; do
        run_test "build_static_$p" build "$OUT/bin/static_$p" gcc "${CWARN[@]}" -O1 -g \
            "${INC[@]}" "$ROOT/tests/c/$p.c" "${STATIC[@]}"
        # Fewer random iterations: valgrind is ~50x slower.
        [[ -x $OUT/bin/static_$p ]] &&
            run_test "valgrind_$p" env PMC_TEST_ITERATIONS=60 "${VG[@]}" "$OUT/bin/static_$p"
    done
fi

# --- 4. CMake package ---------------------------------------------------------------------
if [[ ${PMC_SKIP_CMAKE:-0} != 1 ]]; then
    CB=$OUT/cmake-build
    PREFIX=$OUT/prefix
    rm -rf "$PREFIX" "$OUT"/consumer-*
    # Share cargo's release build instead of building the crate again.
    run_test cmake_configure cmake -S "$ROOT" -B "$CB" -DPRECISEMC_CARGO_TARGET_DIR="$TARGET_DIR"
    run_test cmake_build cmake --build "$CB"
    run_test cmake_install cmake --install "$CB" --prefix "$PREFIX"

    # The shared library has its SONAME, and programs record it (not the
    # file name or path they were linked against) and find it at run time.
    needs_soname() { # needs_soname EXE
        local needed
        needed=$(readelf -d "$1" | sed -n 's/.*(NEEDED).*\[\(libprecisemc[^]]*\)\].*/\1/p')
        [[ $needed == "$SONAME" ]] || { log "$1 needs '$needed', not $SONAME"; return 1; }
        # grep reads all of ldd's output: `grep -q` stops at the match and
        # ldd, killed by SIGPIPE, then failed the pipeline (pipefail) now
        # and then.
        ldd "$1" | grep "$SONAME => /" >/dev/null || { log "$1: $SONAME not found"; return 1; }
    }
    soname_of() { readelf -d "$1" | sed -n 's/.*(SONAME).*\[\(.*\)\].*/\1/p'; }
    installed_library() {
        local lib=$PREFIX/lib
        # The real file, the SONAME link to it, and the link for -lprecisemc.
        [[ -f $lib/libprecisemc.so.$version && ! -L $lib/libprecisemc.so.$version ]] &&
            [[ $(readlink "$lib/$SONAME") == "libprecisemc.so.$version" ]] &&
            [[ $(readlink "$lib/libprecisemc.so") == "$SONAME" ]] &&
            [[ $(soname_of "$lib/libprecisemc.so.$version") == "$SONAME" ]] &&
            [[ $(soname_of "$LIB_DIR/libprecisemc.so") == "$SONAME" ]]
    }
    run_test cmake_installed_library installed_library
    # Both licence texts, as the files of the source tree.
    installed_licences() {
        local f
        for f in LICENSE-MIT LICENSE-APACHE; do
            cmp "$ROOT/$f" "$PREFIX/share/licenses/PreciseMC/$f" || return 1
        done
    }
    run_test cmake_installed_licences installed_licences

    consumer() { # consumer NAME CMAKE_ARGS...
        local dir=$OUT/consumer-$1
        shift
        cmake -S "$ROOT/tests/cmake_consumer" -B "$dir" "$@" &&
            cmake --build "$dir" &&
            (cd "$dir" && ctest --output-on-failure) &&
            needs_soname "$dir/consumer_shared" &&
            # The static one must not need libprecisemc.so.
            ! ldd "$dir/consumer_static" | grep libprecisemc >/dev/null
    }
    run_test cmake_consumer_install consumer install -DCMAKE_PREFIX_PATH="$PREFIX" \
        -DPMC_EXPECTED_VERSION="$version"
    run_test cmake_consumer_build_tree consumer build-tree -DPreciseMC_DIR="$CB" \
        -DPMC_EXPECTED_VERSION="$version"

    pkgconfig_consumer() { # pkgconfig_consumer shared|static
        local pc=(env PKG_CONFIG_PATH="$PREFIX/lib/pkgconfig" pkg-config)
        local exe=$OUT/consumer-pkgconfig-$1
        local cflags libs libdir
        cflags=$("${pc[@]}" --cflags precisemc)
        libdir=$("${pc[@]}" --variable=libdir precisemc)
        if [[ $1 == shared ]]; then
            libs=$("${pc[@]}" --libs precisemc)
            # shellcheck disable=SC2086
            gcc "${CWARN[@]}" $cflags "$ROOT/tests/cmake_consumer/main.c" $libs \
                -Wl,-rpath,"$libdir" -o "$exe"
            needs_soname "$exe" || return 1
        else
            # precisemc-static.pc names the archive itself.
            libs=$("${pc[@]}" --libs precisemc-static)
            # shellcheck disable=SC2086
            gcc "${CWARN[@]}" $cflags "$ROOT/tests/cmake_consumer/main.c" $libs -o "$exe"
            ! ldd "$exe" | grep libprecisemc >/dev/null || return 1
            [[ $("${pc[@]}" --modversion precisemc-static) == "$version" ]] || return 1
        fi
        [[ $("${pc[@]}" --modversion precisemc) == "$version" ]] &&
            "$exe"
    }
    run_test pkgconfig_shared pkgconfig_consumer shared
    run_test pkgconfig_static pkgconfig_consumer static

    # An absolute CMAKE_INSTALL_INCLUDEDIR (as some packagers pass) lands
    # in both .pc files as it is, and the header is found through them.
    absolute_includedir() {
        local cb=$OUT/cmake-build-absinc prefix=$OUT/prefix-absinc inc=$OUT/absinc-include
        rm -rf "$prefix" "$inc"
        cmake -S "$ROOT" -B "$cb" -DPRECISEMC_CARGO_TARGET_DIR="$TARGET_DIR" \
            -DCMAKE_INSTALL_INCLUDEDIR="$inc" >/dev/null &&
            cmake --build "$cb" >/dev/null &&
            cmake --install "$cb" --prefix "$prefix" >/dev/null || return 1
        [[ -f $inc/precisemc.h ]] || { log "no header in $inc"; return 1; }
        local pc=(env PKG_CONFIG_PATH="$prefix/lib/pkgconfig" pkg-config) name flags
        for name in precisemc precisemc-static; do
            flags=$("${pc[@]}" --cflags "$name")
            [[ ${flags% } == "-I$inc" ]] || { log "$name: cflags '$flags'"; return 1; }
        done
        # shellcheck disable=SC2046
        gcc "${CWARN[@]}" $("${pc[@]}" --cflags precisemc) "$ROOT/tests/cmake_consumer/main.c" \
            $("${pc[@]}" --libs precisemc-static) -o "$OUT/consumer-absinc" &&
            "$OUT/consumer-absinc"
    }
    run_test pkgconfig_absolute_includedir absolute_includedir

    # A plain `cargo build` into the target directory the CMake build shares
    # links the library without its SONAME (build.rs adds it only with
    # PRECISEMC_SONAME). `cmake --install`, which does not build, refuses
    # it; `cmake --build` runs cargo again, which relinks it with the SONAME
    # (CMake's file dependencies did not see the difference: the install got
    # the library without a SONAME, and consumers linked against it recorded
    # its absolute path). Last: the target directory is left as it was.
    plain_cargo_build() {
        (cd "$ROOT" && env -u PRECISEMC_SONAME cargo build --release --lib >&2) &&
            [[ -z $(soname_of "$LIB_DIR/libprecisemc.so") ]]
    }
    install_refuses_library_without_soname() {
        local prefix=$OUT/prefix-plain msg
        rm -rf "$prefix"
        plain_cargo_build || { log "the plain cargo build failed or gave a SONAME"; return 1; }
        if msg=$(cmake --install "$CB" --prefix "$prefix" 2>&1); then
            log "installed a library without a SONAME"
            return 1
        fi
        log "$msg"
        # CMake wraps the message: compare it on one line.
        msg=$(tr -s ' \n' ' ' <<<"$msg")
        grep -F "libprecisemc.so has no SONAME, not $SONAME" <<<"$msg" >/dev/null &&
            grep -F "Run \`cmake --build $CB\`" <<<"$msg" >/dev/null
    }
    build_relinks_library_without_soname() {
        local prefix=$OUT/prefix-plain dir=$OUT/consumer-plain
        rm -rf "$prefix" "$dir"
        # Independent of the test above: the scenario of a plain build first.
        if [[ -n $(soname_of "$LIB_DIR/libprecisemc.so") ]]; then
            plain_cargo_build || { log "the plain cargo build failed or gave a SONAME"; return 1; }
        fi
        cmake --build "$CB" && cmake --install "$CB" --prefix "$prefix" || return 1
        local real=$prefix/lib/libprecisemc.so.$version
        [[ $(soname_of "$real") == "$SONAME" ]] || { log "$real: SONAME '$(soname_of "$real")'"; return 1; }
        [[ $(soname_of "$LIB_DIR/libprecisemc.so") == "$SONAME" ]] || return 1
        cmake -S "$ROOT/tests/cmake_consumer" -B "$dir" -DCMAKE_PREFIX_PATH="$prefix" &&
            cmake --build "$dir" &&
            needs_soname "$dir/consumer_shared" &&
            "$dir/consumer_shared"
    }
    run_test cmake_install_refuses_library_without_soname install_refuses_library_without_soname
    run_test cmake_build_relinks_library_without_soname build_relinks_library_without_soname
fi

finish
