#!/usr/bin/env bash
# libFuzzer runs of the fuzz/ targets (parser, frame, view, xml) on the stable
# toolchain: no cargo-fuzz and no nightly needed. The targets are ordinary
# cargo-fuzz targets (`cargo fuzz run parser` works where cargo-fuzz and a
# nightly toolchain are installed); this script builds them the way
# `cargo fuzz build -s none` does: SanitizerCoverage instrumentation through
# stable -C flags, --cfg fuzzing, debug assertions and overflow checks, for
# the explicit host target (so build scripts are not instrumented).
# AddressSanitizer is left out: it needs -Zsanitizer (nightly), and every
# crate fuzzed here is #![forbid(unsafe_code)].
#
#   conformance/scripts/fuzz.sh build
#   conformance/scripts/fuzz.sh run SECONDS [TARGET...]    bounded run (the test command: 15 s each)
#   conformance/scripts/fuzz.sh long TARGET [LIBFUZZER_ARGS...]   open-ended run, Ctrl-C to stop
#   conformance/scripts/fuzz.sh merge TARGET               minimise new inputs into fuzz/corpus/TARGET
#
# Inputs: fuzz/corpus/TARGET (checked in, never written by `run`/`long`);
# new inputs go to target/fuzz/corpus/TARGET. A crash is copied to
# fuzz/regressions/TARGET/ (kept: conformance/tests/fuzz_regressions.rs
# replays it under cargo test) and the run fails. `run` writes
# target/conformance/fuzz-summary.txt (executions per target).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)"
targets_all=(parser frame view xml)
host="$(rustc -vV | sed -n 's/^host: //p')"
tdir="$repo/target/fuzz"
bindir="$tdir/$host/release"

build() {
    local flags="--cfg fuzzing -Cpasses=sancov-module -Cllvm-args=-sanitizer-coverage-level=4"
    flags+=" -Cllvm-args=-sanitizer-coverage-inline-8bit-counters -Cllvm-args=-sanitizer-coverage-pc-table"
    flags+=" -Cllvm-args=-sanitizer-coverage-trace-compares -Cdebug-assertions -Coverflow-checks"
    RUSTFLAGS="$flags" cargo build --quiet --locked --release --bins \
        --manifest-path "$repo/fuzz/Cargo.toml" --target "$host" --target-dir "$tdir"
}

max_len() {
    case "$1" in
        xml) echo 16384 ;;
        *) echo 4096 ;;
    esac
}

# run_one TARGET SECONDS: one bounded libFuzzer run; prints the executions.
run_one() {
    local t="$1" secs="$2" log corpus art
    corpus="$tdir/corpus/$t"
    art="$tdir/artifacts/$t"
    log="$tdir/logs/$t.log"
    mkdir -p "$corpus" "$art" "$(dirname "$log")" "$repo/fuzz/corpus/$t"
    rm -f "$art"/crash-* "$art"/leak-* "$art"/timeout-* "$art"/oom-*
    local status=0
    "$bindir/$t" "$corpus" "$repo/fuzz/corpus/$t" \
        -max_total_time="$secs" -max_len="$(max_len "$t")" -timeout=10 -rss_limit_mb=2048 \
        -print_final_stats=1 -artifact_prefix="$art/" >"$log" 2>&1 || status=$?
    local execs
    execs="$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)"
    local found
    found="$(ls "$art" 2>/dev/null | grep -E '^(crash|leak|timeout|oom)-' || true)"
    if [ "$status" -ne 0 ] || [ -n "$found" ]; then
        mkdir -p "$repo/fuzz/regressions/$t"
        for f in $found; do cp "$art/$f" "$repo/fuzz/regressions/$t/$f"; done
        echo "fuzz: $t FAILED (exit $status); inputs kept in fuzz/regressions/$t/: ${found:-none}" >&2
        grep -m 20 -E 'panicked|ERROR|SUMMARY|deadly' "$log" >&2 || tail -20 "$log" >&2
        echo "$t ${execs:-0} failed"
        return 1
    fi
    echo "$t ${execs:-0} ok"
}

cmd="${1:-}"
case "$cmd" in
    build)
        build
        ;;
    run)
        secs="${2:?usage: fuzz.sh run SECONDS [TARGET...]}"
        shift 2
        targets=("$@")
        [ ${#targets[@]} -gt 0 ] || targets=("${targets_all[@]}")
        build
        mkdir -p "$repo/target/conformance"
        summary="$repo/target/conformance/fuzz-summary.txt"
        : >"$summary.tmp"
        failed=0
        # One target per core at a time (a libFuzzer run is one process, one
        # thread): each still gets its SECONDS of a whole core, and the runs
        # take a core's share of the time. FUZZ_JOBS overrides.
        jobs="${FUZZ_JOBS:-$(nproc)}"
        out="$tdir/run"
        rm -rf "$out"
        mkdir -p "$out"
        pids=()
        for t in "${targets[@]}"; do
            if [ "${#pids[@]}" -ge "$jobs" ]; then
                wait "${pids[0]}" || true
                pids=("${pids[@]:1}")
            fi
            run_one "$t" "$secs" >"$out/$t.line" 2>"$out/$t.err" &
            pids+=("$!")
        done
        wait
        for t in "${targets[@]}"; do
            cat "$out/$t.err" >&2
            line="$(cat "$out/$t.line")"
            set -- ${line:-$t 0 failed}
            [ "$3" = ok ] || failed=1
            echo "$* $secs" >>"$summary.tmp"
            printf 'fuzz: %-7s %12s executions in %s s: %s\n' "$1" "$2" "$secs" "$3"
        done
        mv "$summary.tmp" "$summary"
        exit "$failed"
        ;;
    long)
        t="${2:?usage: fuzz.sh long TARGET [LIBFUZZER_ARGS...]}"
        shift 2
        build
        mkdir -p "$tdir/corpus/$t" "$tdir/artifacts/$t"
        exec "$bindir/$t" "$tdir/corpus/$t" "$repo/fuzz/corpus/$t" -max_len="$(max_len "$t")" \
            -timeout=10 -rss_limit_mb=2048 -artifact_prefix="$tdir/artifacts/$t/" "$@"
        ;;
    merge)
        t="${2:?usage: fuzz.sh merge TARGET}"
        build
        mkdir -p "$tdir/corpus/$t" "$repo/fuzz/corpus/$t"
        # Keep only inputs that add coverage to what fuzz/corpus/TARGET has.
        "$bindir/$t" -merge=1 -max_len="$(max_len "$t")" "$repo/fuzz/corpus/$t" "$tdir/corpus/$t"
        ;;
    *)
        sed -n '2,25p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
        exit 2
        ;;
esac
