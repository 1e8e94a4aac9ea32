#!/usr/bin/env bash
# The companion owns the FC's link and routes it to MAVProxy (or any
# ground station) on --out; signed FC, MAVProxy without a key watching.
# Needs: fbwag on PATH; mavproxy.py on PATH with this repository's Python
# package (pip install "./python[mavproxy]").
# On the aircraft: fbwag cc --link serial:/dev/serial0:460800 ...
set -euo pipefail
P_FC=${P_FC:-14550}                  # the companion's port for the FC
P_MAVPROXY=${P_MAVPROXY:-14551}      # MAVProxy's master port, the companion's --out
KEY=$(printf %s fbwag-bench | sha256sum | cut -c1-64)
RUN=$(mktemp -d)
# On exit, stop what is still running and wait for it: its ports are free
# for the next run.
trap 'kill $(jobs -p) 2>/dev/null || true; wait' EXIT
fail() { echo "FAILED: $1"; for f in "$RUN"/*.log "$RUN"/*.jsonl; do
    [ -f "$f" ] && { echo "--- $f"; cat "$f"; }; done; exit 1; }
expect() { grep -q -- "$2" "$RUN/$1" && echo "ok: $1: $2" || fail "no '$2' in $1"; }
wait_for() { for _ in $(seq 150); do grep -q -- "$2" "$RUN/$1" && return; sleep 0.2; done; expect "$1" "$2"; }

# 1. MAVProxy, no key: it reads the signed frames the companion forwards
#    untouched; unsigned, its own requests reach the FC only as telemetry
#    requests that the companion drops (use --trusted-out for a tool that
#    must command: mavsdk-trusted-out.sh).
PYTHONUNBUFFERED=1 mavproxy.py --master=udpin:127.0.0.1:$P_MAVPROXY --no-state \
    --dialect=fbwag --load-module=fbwag --non-interactive >$RUN/mavproxy.log 2>&1 &
wait_for mavproxy.log "Waiting for heartbeat"
# 2. The companion: the FC link, and MAVProxy on --out.
fbwag cc --link udpin:127.0.0.1:$P_FC --out udpout:127.0.0.1:$P_MAVPROXY \
    --sign-key $KEY --require-signed --duration 12 >$RUN/cc.log 2>&1 &
sleep 0.5
# 3. The FC: RC lost at 2 s, back at 5 s.
fbwag fc-sim --link udpout:127.0.0.1:$P_FC --sign-key $KEY --require-signed \
    --rc-loss-at 2 --rc-back-at 5 --duration 6.5 >$RUN/fc.log 2>&1

# What to expect: the hand-over and back; MAVProxy sees the FC's notices,
# the takeover confirmation and the mode change to FBWAG.
expect fc.log "MODE CHANGE -> FBWAG (companion control)"
expect fc.log "MODE CHANGE -> FBWA (pilot in control)"
expect mavproxy.log "FBWAG_NOTICE from 1/1"
expect mavproxy.log "takeover confirmed by the FC"
echo "runbook passed (logs in $RUN)"
