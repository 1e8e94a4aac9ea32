#!/usr/bin/env bash
# Your own autonomy program behind the companion (--autonomy): it flies the
# aircraft, through the companion's gate, after the pilot's receiver fails.
# Needs: fbwag on PATH; python3 with pymavlink and this repository's Python
# package (pip install ./python: the FBWAG dialect); run from the
# repository's root (interop/autonomy.py is the example program).
set -euo pipefail
P_FC=${P_FC:-14550}                  # the companion's port for the FC
P_AUTONOMY=${P_AUTONOMY:-14560}      # the companion's port for the autonomy
P_PROGRAM=${P_PROGRAM:-14561}        # the port the autonomy sends from
PYTHON=${PYTHON:-python3}
KEY=$(printf %s fbwag-bench | sha256sum | cut -c1-64)
RUN=$(mktemp -d)
# On exit, stop what is still running and wait for it: its ports are free
# for the next run.
trap 'kill $(jobs -p) 2>/dev/null || true; wait' EXIT
fail() { echo "FAILED: $1"; for f in "$RUN"/*.log "$RUN"/*.jsonl; do
    [ -f "$f" ] && { echo "--- $f"; cat "$f"; }; done; exit 1; }
expect() { grep -q -- "$2" "$RUN/$1" && echo "ok: $1: $2" || fail "no '$2' in $1"; }
wait_for() { for _ in $(seq 150); do grep -q -- "$2" "$RUN/$1" && return; sleep 0.2; done; expect "$1" "$2"; }

# 1. The companion, with the autonomy's link (no key there: the program
#    speaks plain MAVLink; the companion signs what it lets through),
#    pinned to the port the program sends from: no other program on this
#    machine is heard there, whoever speaks first.
fbwag cc --link udpin:127.0.0.1:$P_FC --autonomy udpin:127.0.0.1:$P_AUTONOMY \
    --autonomy-peer 127.0.0.1:$P_PROGRAM \
    --sign-key $KEY --require-signed --duration 14 >$RUN/cc.log 2>&1 &
sleep 0.5
# 2. The autonomy speaks first, and streams its control (CHAN1 1234) all
#    the time: the companion drops it until it holds control.
PYTHONUNBUFFERED=1 $PYTHON interop/autonomy.py udpout:127.0.0.1:$P_AUTONOMY \
    --source-port $P_PROGRAM --seconds 11 --chan1 1234 >$RUN/autonomy.log 2>&1 &
wait_for autonomy.log "up"
# 3. The FC: RC lost at 3 s, back at 7 s; its events say which control it applied.
fbwag fc-sim --link udpout:127.0.0.1:$P_FC --sign-key $KEY --require-signed \
    --rc-loss-at 3 --rc-back-at 7 --duration 9 --events $RUN/fc-events.jsonl >$RUN/fc.log 2>&1
wait

# What to expect: the companion takes over and the FC applies the
# autonomy's control (CHAN1 1234), from the companion's ids and signed,
# only in companion control; then the pilot again.
expect fc.log "MODE CHANGE -> FBWAG (companion control)"
expect fc-events.jsonl '"control_applied"'
expect fc.log "MODE CHANGE -> FBWA (pilot in control)"
expect autonomy.log '"sent_in_control"'
echo "runbook passed (logs in $RUN)"
