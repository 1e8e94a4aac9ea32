#!/usr/bin/env bash
# Whole-process generation time of message_definitions/all.xml, in one run:
#   (a) our CLI:  target/release/mavgen-rs generate all.xml -o DIR
#   (b) pymavlink 2.4.50 mavgen, --wire-protocol=2.0, --lang=Python3 and --lang=C
# Whole processes (interpreter start-up, XSD validation, file writing) are
# timed because that is what a build pays. Prints a markdown table of medians
# and the ratio pymavlink/ours.
#
# Env: RUNS (default 5), SKIP_BUILD=1 (use the existing release binary),
#      MAVGEN_RS=/path (time another build of our CLI),
#      NO_INSTALL=1 (never apt-get install hyperfine).
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)"
cd "$REPO"
RUNS="${RUNS:-5}"
XML="$REPO/message_definitions/all.xml"
OURS="${MAVGEN_RS:-$REPO/target/release/mavgen-rs}"

PY="$("$REPO/scripts/python-env.sh")"

# Always let cargo decide: a no-op when fresh, and never times a stale binary.
if [ "${SKIP_BUILD:-0}" != 1 ]; then
    cargo build --release -p mavgen-rs >&2 || echo "time_mavgen.sh: cargo build failed" >&2
fi
have_ours=0; [ -x "$OURS" ] && have_ours=1
[ "$have_ours" = 1 ] || echo "time_mavgen.sh: $OURS missing; timing pymavlink only" >&2

# hyperfine gives robust statistics; install it only when we are root.
if ! command -v hyperfine >/dev/null && [ "${NO_INSTALL:-0}" != 1 ] \
        && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    { apt-get install -y -qq hyperfine || { apt-get update -qq && apt-get install -y -qq hyperfine; }; } \
        >/dev/null 2>&1 || echo "time_mavgen.sh: could not install hyperfine; using bash timing" >&2
fi

TMP="$(mktemp -d)"; trap 'rm -rf "$TMP"' EXIT

# name|command; every run starts from an empty output directory.
benches=()
[ "$have_ours" = 1 ] && benches+=("mavgen-rs (ours)|$OURS generate $XML -o $TMP/out")
benches+=("pymavlink Python3|$PY -m pymavlink.tools.mavgen --lang=Python3 --wire-protocol=2.0 -o $TMP/out/all.py $XML")
benches+=("pymavlink C|$PY -m pymavlink.tools.mavgen --lang=C --wire-protocol=2.0 -o $TMP/out $XML")

# Check each command works once before timing it: timing a failure is useless.
for b in "${benches[@]}"; do
    rm -rf "$TMP/out"; mkdir -p "$TMP/out"
    if ! ${b#*|} >"$TMP/check.log" 2>&1; then
        echo "time_mavgen.sh: '${b%%|*}' failed:" >&2; tail -5 "$TMP/check.log" >&2; exit 1
    fi
done

median_of() {  # seconds on stdin, one per line -> median
    sort -g | awk '{v[NR]=$1} END {print (NR%2) ? v[(NR+1)/2] : (v[NR/2]+v[NR/2+1])/2}'
}

declare -A med
for b in "${benches[@]}"; do
    name="${b%%|*}"; cmd="${b#*|}"
    if command -v hyperfine >/dev/null; then
        hyperfine --style none --warmup 1 --runs "$RUNS" \
            --prepare "rm -rf $TMP/out && mkdir -p $TMP/out" \
            --export-json "$TMP/h.json" "$cmd" >/dev/null 2>&1
        med[$name]="$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1]))["results"][0]["median"])' "$TMP/h.json")"
    else
        for _ in $(seq "$RUNS"); do
            rm -rf "$TMP/out"; mkdir -p "$TMP/out"
            t0=$(date +%s.%N); $cmd >/dev/null 2>&1; t1=$(date +%s.%N)
            echo "$t0 $t1" | awk '{printf "%.6f\n", $2 - $1}'
        done | median_of > "$TMP/med"
        med[$name]="$(cat "$TMP/med")"
    fi
done

tool=$(command -v hyperfine >/dev/null && echo hyperfine || echo "bash date loop")
echo "all.xml, median of $RUNS runs ($tool), $(date -u +%Y-%m-%d)"
echo
echo "| generator | median (s) | pymavlink / ours |"
echo "|---|---:|---:|"
ours="${med[mavgen-rs (ours)]:-}"
for b in "${benches[@]}"; do
    name="${b%%|*}"; m="${med[$name]}"
    if [ -n "$ours" ]; then ratio=$(awk -v a="$m" -v b="$ours" 'BEGIN{printf "%.1f", a/b}'); else ratio="n/a"; fi
    printf '| %s | %.3f | %s |\n' "$name" "$m" "$ratio"
done
[ "$have_ours" = 1 ]  # non-zero exit when our CLI could not be timed
