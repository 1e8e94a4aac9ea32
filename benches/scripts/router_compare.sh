#!/usr/bin/env bash
# `fbwag router` next to mavlink-router (mavlink-routerd, C++), the router
# integrators install today, in one run on 127.0.0.1 UDP:
#
#   fbwag router udpin:127.0.0.1:A1 udpout:127.0.0.1:B1
#   mavlink-routerd -t 0 -e 127.0.0.1:B2 127.0.0.1:A2
#   udp_forward A3 B3    (benches/c/udp_forward.c: recv, send, nothing else)
#
# The third is not a router but a reference: what the kernel costs a
# program that forwards each datagram as it comes, which no router that
# does the same can undercut. All three run at once, pinned to ROUTER_CPU;
# the load source and the checking sink (benches/c/router_load.c, gcc -O2)
# run on LOAD_CPU. Each phase runs in slices (ROUTER_LOAD_SLICES, default
# 6), each router taking the load in turn in every slice, so a slow spell
# of the shared machine hits all alike; the table gives, beside each ratio,
# the range of the ratios of slices run side by side. The load: MAVLink 2
# frames of six ArduPlane telemetry types from four systems. Measured per
# router:
#   - throughput at saturation (sendmmsg as fast as it goes), one frame per
#     datagram and ten: frames/s delivered to the sink, loss and where;
#   - CPU per frame read (/proc/PID/stat utime+stime; schedstat's ns beside
#     it, as the tick is 10 ms) at saturation and at 2,000 and 20,000 frames/s;
#   - latency, median and p99, at 1,000 frames/s (a send-time table).
# About 70 s (ROUTER_LOAD_SCALE=0.5 halves the load). Prints a markdown
# table with fbwag ÷ mavlink-routerd ratios, and fbwag's bounds, each from
# this run: latency median at 1,000 frames/s ≤ mavlink-routerd's; CPU per
# frame at 2,000 frames/s ≤ 1.1× the bare forwarder's; at saturation
# ≥ 1.5× mavlink-routerd's frames/s at ≤ 0.6× its CPU per frame. Saved
# under target/bench-results/.
#
# Env: MAVLINK_ROUTERD (required: the path of mavlink-routerd; BENCHMARKS.md,
#      "The mavlink-router compared", says which build was measured),
#      ROUTER_CPU (default 0), LOAD_CPU (default 1), PORT_BASE (six UDP
#      ports from it, default 24600), ROUTER_LOAD_SCALE (phase lengths,
#      default 1), ROUTER_LOAD_SLICES (default 6), SKIP_BUILD=1 (use
#      target/release/fbwag as it is).
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)"
cd "$REPO"

if [ -z "${MAVLINK_ROUTERD:-}" ] || [ ! -x "${MAVLINK_ROUTERD}" ]; then
    cat >&2 <<'EOF'
router_compare.sh needs MAVLINK_ROUTERD, the path of a mavlink-routerd
binary (mavlink-router, the mavlink-router/mavlink-router project on GitHub),
built as that project's README says. BENCHMARKS.md, "The mavlink-router
compared", gives the commit and build type of the published figures. Then:
    MAVLINK_ROUTERD=/path/to/build/src/mavlink-routerd bash benches/scripts/router_compare.sh
EOF
    exit 2
fi
command -v taskset >/dev/null || { echo "router_compare.sh needs taskset (util-linux)" >&2; exit 2; }

ROUTER_CPU="${ROUTER_CPU:-0}"
LOAD_CPU="${LOAD_CPU:-1}"
PORT_BASE="${PORT_BASE:-24600}"
A1=$PORT_BASE B1=$((PORT_BASE + 1)) A2=$((PORT_BASE + 2)) B2=$((PORT_BASE + 3))
A3=$((PORT_BASE + 4)) B3=$((PORT_BASE + 5))

TMP="$(mktemp -d)"
PIDS=()
cleanup() {
    # Only the routers this script started, by pid.
    for p in "${PIDS[@]}"; do kill "$p" 2>/dev/null || true; done
    for p in "${PIDS[@]}"; do wait "$p" 2>/dev/null || true; done
    rm -rf "$TMP"
}
trap cleanup EXIT
OUT_DIR="$REPO/target/bench-results"; mkdir -p "$OUT_DIR"
REPORT="$OUT_DIR/router-compare-$(date -u +%Y%m%dT%H%M%SZ).md"

if [ "${SKIP_BUILD:-0}" != 1 ]; then
    echo "==> cargo build --release -p fbwag-cli --bin fbwag" >&2
    cargo build --release --locked -p fbwag-cli --bin fbwag >&2
fi
FBWAG="$REPO/target/release/fbwag"
[ -x "$FBWAG" ] || { echo "no $FBWAG (run without SKIP_BUILD=1)" >&2; exit 2; }
LOAD="$REPO/target/bench-bin/router_load" FORWARD="$REPO/target/bench-bin/udp_forward"
mkdir -p "$(dirname "$LOAD")"
gcc -O2 -Wall -Wextra -pthread -o "$LOAD" benches/c/router_load.c
gcc -O2 -Wall -Wextra -o "$FORWARD" benches/c/udp_forward.c

# mavlink-routerd reads /etc/mavlink-router/main.conf and config.d/ when
# present: a file with only its [General] header (an empty one is refused)
# and an empty directory keep it to the command line's links.
printf '[General]\n' > "$TMP/empty.conf"; mkdir "$TMP/conf.d"
taskset -c "$ROUTER_CPU" "$FBWAG" router "udpin:127.0.0.1:$A1" "udpout:127.0.0.1:$B1" \
    > "$TMP/fbwag.log" 2>&1 &
PIDS+=($!); FB_PID=$!
taskset -c "$ROUTER_CPU" "$MAVLINK_ROUTERD" -c "$TMP/empty.conf" -d "$TMP/conf.d" -t 0 \
    -e "127.0.0.1:$B2" "127.0.0.1:$A2" > "$TMP/mavlink-routerd.log" 2>&1 &
PIDS+=($!); MR_PID=$!
taskset -c "$ROUTER_CPU" "$FORWARD" "$A3" "$B3" > "$TMP/udp_forward.log" 2>&1 &
PIDS+=($!); FW_PID=$!
bound() { grep -q ":$(printf %04X "$1") " /proc/net/udp; }
for _ in $(seq 50); do
    if bound "$A1" && bound "$A2" && bound "$A3"; then break; fi
    sleep 0.1
done
for p in "$FB_PID" "$MR_PID" "$FW_PID"; do
    kill -0 "$p" 2>/dev/null || { echo "a router did not start:" >&2; cat "$TMP"/*.log >&2; exit 1; }
done

echo "==> load on core $LOAD_CPU, routers on core $ROUTER_CPU (about $(awk -v s="${ROUTER_LOAD_SCALE:-1}" 'BEGIN{print int(10 + 55*s)}') s)" >&2
taskset -c "$LOAD_CPU" "$LOAD" "fbwag:$FB_PID:$A1:$B1" "mavlink-routerd:$MR_PID:$A2:$B2" \
    "bare-forward:$FW_PID:$A3:$B3" > "$TMP/raw.txt"

{
    echo "# benches/scripts/router_compare.sh, $(date -u +%Y-%m-%dT%H:%MZ), $(git rev-parse --short HEAD)"
    echo
    echo "$(lscpu 2>/dev/null | sed -n 's/^Model name: *//p' | head -1), $(nproc) CPUs, $(uname -sr); load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
    echo "mavlink-routerd: $("$MAVLINK_ROUTERD" --version 2>&1 | head -1)"
    echo
    python3 benches/scripts/router_compare.py "$TMP/raw.txt"
    echo
    echo "Raw (router_load):"
    echo '```'
    cat "$TMP/raw.txt"
    echo '```'
} | tee "$REPORT"
echo "==> saved $REPORT" >&2
