#!/usr/bin/env bash
# Prints the conformance summary of the last run: dialects,
# messages, frames compared per mode and peer, mismatches, good frames each
# parser recovered from the corrupted streams, fuzz executions, and a final
# `conformance: N passed, N failed` line. Reads what tests/wire.rs and
# scripts/fuzz.sh wrote under target/conformance/; exits 1 if anything
# failed or is missing.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)"
dir="$repo/target/conformance"
wire="$dir/wire-counts.txt"
fuzz="$dir/fuzz-summary.txt"
for f in "$wire" "$fuzz"; do
    [ -f "$f" ] || { echo "summary.sh: $f missing (run cargo test -p conformance and fuzz.sh run first)"; echo "conformance: 0 passed, 1 failed"; exit 1; }
done
awk -v fuzzfile="$fuzz" '
function mode_label(m) { return m == "v2" ? "MAVLink 2" : (m == "v2s" ? "MAVLink 2 signed" : "MAVLink 1") }
function peer_label(p) { return p == "Pymavlink" ? "pymavlink 2.4.50" : "MAVLink C library" }
$1 == "dialect" { dialects = dialects sep $2 ".xml (" $3 " messages)"; sep = ", "; nd++; nm += $3 }
$1 == "frames"  { key = $4 SUBSEP $3; n[key] += $5; bad[key] += $6; mism += $6 }
$1 == "recovered" { want[$3] += $4; rr[$3] += $5; rp[$3] += $6; rc[$3] += $7 }
$1 == "result"  { passed += $2; failed += $3 }
END {
    print ""
    print "== conformance summary =="
    printf "dialects: %d (%s), %d messages\n", nd, dialects, nm
    print "frames compared, each packed by both sides and decoded both ways:"
    printf "  %-19s %12s %18s %12s %11s\n", "", "MAVLink 2", "MAVLink 2 signed", "MAVLink 1", "mismatches"
    split("Pymavlink C", peers, " ")
    for (i = 1; i <= 2; i++) {
        p = peers[i]
        printf "  %-19s %12d %18d %12d %11d\n", peer_label(p), n[p SUBSEP "v2"], n[p SUBSEP "v2s"], n[p SUBSEP "v1"], bad[p SUBSEP "v2"] + bad[p SUBSEP "v2s"] + bad[p SUBSEP "v1"]
    }
    print "corrupted streams, good frames recovered (Rust / pymavlink / C of recoverable):"
    split("NoKey KeyAcceptUnsigned KeyRejectUnsigned", pol, " ")
    split("no key,key + unsigned accepted,key + unsigned refused", pl, ",")
    for (i = 1; i <= 3; i++) printf "  %-28s %6d / %6d / %6d of %6d\n", pl[i], rr[pol[i]], rp[pol[i]], rc[pol[i]], want[pol[i]]
    fexec = ""
    while ((getline line < fuzzfile) > 0) {
        split(line, f, " ")
        fexec = fexec (fexec == "" ? "" : ", ") f[1] " " f[2]
        if (f[3] == "ok") passed++; else failed++
        secs = f[4]
    }
    printf "fuzz executions (%s s per target): %s\n", secs, fexec
    printf "mismatches: %d\n", mism
    printf "conformance: %d passed, %d failed\n", passed, failed
    exit failed > 0 || mism > 0
}' "$wire"
