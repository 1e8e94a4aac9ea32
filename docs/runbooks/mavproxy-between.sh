#!/usr/bin/env bash
# MAVProxy as the router between the FC and the companion, signed: the
# paper's set-up (MAVProxy on the companion computer owns the FC's port).
# Needs: fbwag on PATH; mavproxy.py on PATH with this repository's Python
# package (pip install "./python[mavproxy]": the FBWAG dialect and the
# MAVProxy module `fbwag`).
# On the aircraft: --master=/dev/serial0 --baudrate 460800.
set -euo pipefail
P_FC=${P_FC:-14550}                  # MAVProxy's master port (the FC's link)
P_CC=${P_CC:-14551}                  # the companion's port, MAVProxy's --out
KEY=$(printf %s fbwag-bench | sha256sum | cut -c1-64)   # = MAVProxy's `signing key fbwag-bench`
RUN=$(mktemp -d)
# On exit, stop what is still running and wait for it: its ports are free
# for the next run.
trap 'kill $(jobs -p) 2>/dev/null || true; wait' EXIT
fail() { echo "FAILED: $1"; for f in "$RUN"/*.log "$RUN"/*.jsonl; do
    [ -f "$f" ] && { echo "--- $f"; cat "$f"; }; done; exit 1; }
expect() { grep -q -- "$2" "$RUN/$1" && echo "ok: $1: $2" || fail "no '$2' in $1"; }
wait_for() { for _ in $(seq 150); do grep -q -- "$2" "$RUN/$1" && return; sleep 0.2; done; expect "$1" "$2"; }

# 1. The companion: signs its own frames, verifies the FC's.
fbwag cc --link udpin:127.0.0.1:$P_CC --sign-key $KEY --require-signed --duration 30 \
    >$RUN/cc.log 2>&1 &
# 2. MAVProxy with the key and the FBWAG dialect: it forwards the signed
#    FBWAG_NOTICE untouched (with its default dialect and a key it stops
#    routing at the first one: see docs/deployment.md).
PYTHONUNBUFFERED=1 mavproxy.py --master=udpin:127.0.0.1:$P_FC --out=udpout:127.0.0.1:$P_CC \
    --non-interactive --no-state --dialect=fbwag --load-module=fbwag \
    --cmd="signing key fbwag-bench" >$RUN/mavproxy.log 2>&1 &
wait_for mavproxy.log "Waiting for heartbeat"
# 3. The FC, once MAVProxy listens: RC lost at 3 s, back at 7 s.
fbwag fc-sim --link udpout:127.0.0.1:$P_FC --sign-key $KEY --require-signed \
    --rc-loss-at 3 --rc-back-at 7 --duration 9 >$RUN/fc.log 2>&1

# What to expect: the hand-over and back, no RTL; MAVProxy's fbwag module
# shows the FC's confirmation of the takeover and the mode by name.
expect fc.log "MODE CHANGE -> FBWAG (companion control)"
expect fc.log "MODE CHANGE -> FBWA (pilot in control)"
expect mavproxy.log "takeover confirmed by the FC"
expect mavproxy.log "FBWAG (companion control)"
if grep -q "RTL" $RUN/fc.log; then fail "the FC fell back to RTL"; fi
echo "runbook passed (logs in $RUN)"
