#!/usr/bin/env bash
# Tests of the ParaView plugin (paraview/): installs ParaView 5.11 and what
# its CMake package needs (scripts/lib.sh: ensure_paraview), builds the
# plugin (build/paraview), loads it in pvbatch and pvpython (load.py), and
# compares distributed runs under `mpiexec -n 2|3|4 pvbatch` with the serial
# run, triangle for triangle (distributed.py), and renders a 2-rank run
# (paraview/screenshot.py). Closes with
# "paraview: N passed, M failed"; exits non-zero on failure.
set -uo pipefail
cd "$(dirname "$0")/../.."
source scripts/lib.sh

passed=0
failed=0
out=build/paraview/test-output
logs=()

# Runs a command with a time limit, echoes its ok/FAIL lines and counts
# them; a command that fails, prints no ok line or gets killed counts as
# one failure more.
run_checks() {
    local name="$1" log status oks fails
    shift
    log="$out/$name.log"
    timeout 600 "$@" >"$log" 2>&1
    status=$?
    grep -E '^(ok|FAIL) ' "$log" | sed "s/^/  [$name] /"
    oks=$(grep -c '^ok ' "$log")
    fails=$(grep -c '^FAIL ' "$log")
    passed=$((passed + oks))
    failed=$((failed + fails))
    if [ "$status" -ne 0 ] || [ "$oks" -eq 0 ]; then
        failed=$((failed + 1))
        echo "  [$name] FAILED (exit status $status); last lines of $log:"
        # Every rank's own error lines first: the tail often shows only
        # the rank that was killed after another one failed.
        grep -E 'ERR\||FATL\||X server|Abort' "$log" | head -n 10 | sed 's/^/    /'
        tail -n 25 "$log" | sed 's/^/    /'
    fi
    logs+=("$log")
}

start=$SECONDS
if ! pmc_build_paraview; then
    echo "error: the ParaView plugin did not build"
    echo "paraview: 0 passed, 1 failed"
    exit 1
fi
echo "plugin built: $PMC_PARAVIEW_PLUGIN ($((SECONDS - start)) s)"
pmc_paraview_env
mkdir -p "$out"
rm -f "$out"/*.npz

run_checks pvbatch-load pvbatch tests/paraview/load.py "$PMC_PARAVIEW_PLUGIN"
run_checks pvpython-load build/paraview-root/usr/bin/pvpython tests/paraview/load.py "$PMC_PARAVIEW_PLUGIN"

# The serial run writes the reference (its lines say nothing yet).
timeout 600 pvbatch tests/paraview/distributed.py "$PMC_PARAVIEW_PLUGIN" "$out/serial.npz" \
    >"$out/serial.log" 2>&1
serial_status=$?
# The reference counts only from a run that exited cleanly and printed
# no failure (a FAIL line here is a check of the serial surface itself).
if [ "$serial_status" -eq 0 ] && [ -f "$out/serial.npz" ] && ! grep -q '^FAIL ' "$out/serial.log"; then
    passed=$((passed + 1))
    grep -E '^[A-Za-z-]+: [0-9]+ triangles' "$out/serial.log" | sed 's/^/  [serial] /'
    for n in 2 3 4; do
        run_checks "mpi-$n" mpiexec -n "$n" --oversubscribe pvbatch tests/paraview/distributed.py \
            "$PMC_PARAVIEW_PLUGIN" "$out/mpi-$n.npz" "$out/serial.npz"
    done
else
    failed=$((failed + 1))
    grep -E '^FAIL ' "$out/serial.log" | sed 's/^/  [serial] /'
    echo "  [serial] FAILED (exit status $serial_status); last lines of $out/serial.log:"
    tail -n 25 "$out/serial.log" | sed 's/^/    /'
fi

# A picture of a 2-rank run (as docs/paraview.png), rendered under Xvfb.
run_checks screenshot scripts/with-xvfb.sh mpiexec -n 2 --oversubscribe pvbatch paraview/screenshot.py \
    "$PMC_PARAVIEW_PLUGIN" "$out/screenshot.png"

echo "paraview tests took $((SECONDS - start)) s"
echo "paraview: $passed passed, $failed failed"
[ "$failed" -eq 0 ]
