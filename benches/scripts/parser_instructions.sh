#!/usr/bin/env bash
# Instructions per input byte of the parser on the inputs of the parser's
# worst-case benchmark, counted by valgrind (cachegrind): exact and the same
# on every run, where MB/s on a shared machine moves by 20 % or more. The
# time per byte follows the instructions closely on these inputs (a few
# table look-ups per candidate, no cache misses to speak of), so the ratio
# of two inputs' counts is what the parser's speed ratio would be at equal
# instructions per cycle; random bytes run at a higher rate (a vectorised
# search), so the count understates their lead.
#
#   [CHUNK=N | READS=N | READS=dN] bash benches/scripts/parser_instructions.sh [INPUT...]
#
# Each input is parsed once and three times (in CHUNK-byte reads: 64 KiB by
# default, as `fbwag decode` reads; serial and TCP reads are a few hundred
# bytes or fewer; READS=dN parses N-byte datagrams, as the daemons' UDP
# links do); the difference over two passes and 256 KiB is the figure,
# so that building the inputs does not count. Inputs: the names of
# `benches::worst::inputs` (default: all of them), or hex:PATTERN; a
# `keyed` after a name parses with a key (unsigned frames refused). Under
# valgrind SHA-256 runs without the CPU's SHA instructions: counts of keyed
# inputs include a software SHA-256.
set -euo pipefail
cd "$(dirname "$0")/../.."
command -v valgrind >/dev/null || { echo "valgrind is needed (apt-get install valgrind)" >&2; exit 1; }
cargo build --release -q -p benches --example parser_worst
bin=target/release/examples/parser_worst
# READS=dN: datagrams of N bytes (next_in_datagram, end_of_datagram), as
# a UDP link parses them; else CHUNK-byte reads of a stream.
reads="chunk=${CHUNK:-65536}"
case "${READS:-}" in
    d[0-9]*) reads="datagram=${READS#d}" ;;
    [0-9]*) reads="chunk=$READS" ;;
esac
count() {
    valgrind --tool=cachegrind --cache-sim=no --cachegrind-out-file=/dev/null \
        "$bin" one "$@" "$reads" 2>&1 | awk '/I *refs/ { gsub(",", "", $NF); print $NF }'
}
inputs=("$@")
if [ ${#inputs[@]} -eq 0 ]; then
    inputs=(random dense_fd_fe mixed_half_start found_mix issue_pattern all_fe all_fd
        "signed_raw keyed" "signed_raw_confirmed keyed" found_a found_b found_c "found_c keyed"
        found_d "found_e keyed" found_f "found_f keyed" "found_g keyed" "found_h keyed"
        found_i "found_i keyed" found_j "found_j keyed" found_k "found_k keyed" found_l
        "found_l keyed" found_m "found_m keyed" found_n
        "found_n keyed" many_senders "many_senders keyed")
fi
printf '%-28s %10s\n' input instr/B
for input in "${inputs[@]}"; do
    # shellcheck disable=SC2086 # "name keyed" is two arguments
    one=$(count $input passes=1)
    three=$(count $input passes=3)
    awk -v a="$one" -v b="$three" -v n="$input" \
        'BEGIN { printf "%-28s %10.1f\n", n, (b - a) / 2 / 262144 }'
done
