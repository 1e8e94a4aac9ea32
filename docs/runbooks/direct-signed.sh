#!/usr/bin/env bash
# The FC and the companion, signed, on one link: the paper's hand-over.
# Needs: fbwag on PATH (cargo install --path fbwag-cli).
# On the aircraft the link is the FC's serial port (`--link
# serial:/dev/serial0:460800` on the companion); here fc-sim stands in for
# the FC over UDP on 127.0.0.1.
set -euo pipefail
P_FC=${P_FC:-14550}                  # the companion's port for the FC
KEY=$(printf %s fbwag-bench | sha256sum | cut -c1-64)   # 64 hex digits, both sides
RUN=$(mktemp -d)                     # logs and signing state of this run
# On exit, stop what is still running and wait for it: its ports are free
# for the next run.
trap 'kill $(jobs -p) 2>/dev/null || true; wait' EXIT
fail() { echo "FAILED: $1"; for f in "$RUN"/*.log "$RUN"/*.jsonl; do
    [ -f "$f" ] && { echo "--- $f"; cat "$f"; }; done; exit 1; }
expect() { grep -q -- "$2" "$RUN/$1" && echo "ok: $1: $2" || fail "no '$2' in $1"; }

# 1. The companion first: it listens, and answers the FC once it hears it.
fbwag cc --link udpin:127.0.0.1:$P_FC --sign-key $KEY --require-signed \
    --signing-state $RUN/cc.state --duration 12 >$RUN/cc.log 2>&1 &
sleep 0.5
# 2. The FC: the pilot's receiver fails at 3 s and comes back at 7 s.
fbwag fc-sim --link udpout:127.0.0.1:$P_FC --sign-key $KEY --require-signed \
    --signing-state $RUN/fc.state --rc-loss-at 3 --rc-back-at 7 --duration 9 >$RUN/fc.log 2>&1

# What to expect: the FC hands control to the companion about 0.1 s after
# the loss, and takes it back when the receiver returns; no RTL.
expect fc.log "MODE CHANGE -> FBWAG (companion control)"
expect fc.log "handover"
expect fc.log "MODE CHANGE -> FBWA (pilot in control)"
if grep -q "RTL" $RUN/fc.log; then fail "the FC fell back to RTL"; fi
echo "runbook passed (logs in $RUN)"
