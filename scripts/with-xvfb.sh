#!/usr/bin/env bash
# Runs a command with $DISPLAY on a private Xvfb and stops the server
# afterwards; exits with the command's status.
#
#     scripts/with-xvfb.sh COMMAND [ARGS...]
#
# Xvfb -displayfd picks a free display itself, so runs started at the same
# moment never collide (xvfb-run -a guesses a number from lock files and
# can give two runs the same one). -noreset: by default the server resets
# when its last client disconnects, and a client connecting during the
# reset is refused; with several MPI ranks, one rank closing its test
# window while another connects made VTK abort ("bad X server connection").
set -u
dir="$(mktemp -d)"
trap 'rm -rf "$dir"' EXIT
mkfifo "$dir/display"
Xvfb -displayfd 3 -screen 0 1920x1080x24 -nolisten tcp -noreset 3>"$dir/display" >"$dir/log" 2>&1 &
pid=$!
display=""
read -r -t 60 display <"$dir/display"
if [ -z "$display" ]; then
    echo "error: Xvfb did not start:" >&2
    cat "$dir/log" >&2
    kill "$pid" 2>/dev/null
    exit 1
fi
DISPLAY=":$display" "$@"
status=$?
kill "$pid" 2>/dev/null
wait "$pid" 2>/dev/null
exit "$status"
