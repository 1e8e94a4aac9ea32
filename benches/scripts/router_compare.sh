#!/usr/bin/env bash
# `fbwag router` next to mavlink-router (mavlink-routerd, C++), the router
# integrators install today, in one run on 127.0.0.1 UDP:
#
#   fbwag router udpin:127.0.0.1:A1 udpout:127.0.0.1:B1
#   mavlink-routerd -t 0 -e 127.0.0.1:B2 127.0.0.1:A2
#
# Both routers run at once, pinned to ROUTER_CPU; the load source and the
# checking sink (benches/c/router_load.c, gcc -O2) run on LOAD_CPU and take
# the routers in turn, phase by phase, so a slow spell of the shared machine
# hits both alike. The load: MAVLink 2 frames of six ArduPlane telemetry
# types from four systems. Measured per router:
#   - throughput at saturation (sendmmsg as fast as it goes), one frame per
#     datagram and ten: frames/s delivered to the sink, loss and where;
#   - CPU per frame read (/proc/PID/stat utime+stime; schedstat's ns beside
#     it, as the tick is 10 ms) at saturation and at 2,000 and 20,000 frames/s;
#   - latency, median and p99, at 1,000 frames/s (a send-time table).
# About 35 s of load (ROUTER_LOAD_SCALE=0.5 halves it). Prints a markdown
# table with fbwag ÷ mavlink-routerd ratios, saved under target/bench-results/.
#
# Env: MAVLINK_ROUTERD (required: the path of mavlink-routerd; BENCHMARKS.md,
#      "mavlink-router, built from source", says which build was measured),
#      ROUTER_CPU (default 0), LOAD_CPU (default 1), PORT_BASE (four UDP
#      ports from it, default 24600), ROUTER_LOAD_SCALE (phase lengths,
#      default 1), SKIP_BUILD=1 (use target/release/fbwag as it is).
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)"
cd "$REPO"

if [ -z "${MAVLINK_ROUTERD:-}" ] || [ ! -x "${MAVLINK_ROUTERD}" ]; then
    cat >&2 <<'EOF'
router_compare.sh needs MAVLINK_ROUTERD, the path of a mavlink-routerd
binary (mavlink-router, the mavlink-router/mavlink-router project on GitHub).
Build it from its source with meson and ninja as its README says (its
MAVLink C library submodule, when missing, can be generated with
pymavlink's mavgen, C, wire protocol 2.0, from ardupilotmega.xml);
BENCHMARKS.md, "mavlink-router, built from source", gives the commit and
build options of the published figures. Then:
    MAVLINK_ROUTERD=/path/to/build/src/mavlink-routerd bash benches/scripts/router_compare.sh
EOF
    exit 2
fi
command -v taskset >/dev/null || { echo "router_compare.sh needs taskset (util-linux)" >&2; exit 2; }

ROUTER_CPU="${ROUTER_CPU:-0}"
LOAD_CPU="${LOAD_CPU:-1}"
PORT_BASE="${PORT_BASE:-24600}"
A1=$PORT_BASE B1=$((PORT_BASE + 1)) A2=$((PORT_BASE + 2)) B2=$((PORT_BASE + 3))

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
LOAD="$REPO/target/bench-bin/router_load"
mkdir -p "$(dirname "$LOAD")"
gcc -O2 -Wall -Wextra -pthread -o "$LOAD" benches/c/router_load.c

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
for _ in $(seq 50); do
    if grep -q ":$(printf %04X "$A1") " /proc/net/udp && grep -q ":$(printf %04X "$A2") " /proc/net/udp; then break; fi
    sleep 0.1
done
for p in "$FB_PID" "$MR_PID"; do
    kill -0 "$p" 2>/dev/null || { echo "a router did not start:" >&2; cat "$TMP"/*.log >&2; exit 1; }
done

echo "==> load on core $LOAD_CPU, routers on core $ROUTER_CPU (about $(awk -v s="${ROUTER_LOAD_SCALE:-1}" 'BEGIN{print int(35*s)}') s)" >&2
taskset -c "$LOAD_CPU" "$LOAD" "fbwag:$FB_PID:$A1:$B1" "mavlink-routerd:$MR_PID:$A2:$B2" > "$TMP/raw.txt"

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
