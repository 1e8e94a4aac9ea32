#!/usr/bin/env bash
# Mutation testing of the protocol's checks, as a measurement (not a test:
# scripts/test.sh does not run it). cargo-mutants (pinned below, installed
# from crates.io when missing) changes the product one small way at a time
# (a comparison flipped, a condition forced, a function's body replaced)
# and runs the fast checks against each change: a mutant they do not catch
# is a gap in the checks, or an equivalent change (BENCHMARKS.md lists each
# survivor and which).
#
# SCOPE (what is mutated):
#   engines   fbwag-delegation/src/engine/{fc,cc}.rs
#   node      fbwag-delegation/src/node/{companion,flight}.rs (the nodes' policy)
#   core      fbwag-delegation/src/node/{mod,peers,router}.rs (what the nodes share)
#   machines  fbwag-delegation/src/{fc,cc}.rs (the state machines)
#   verifier  mavframe/src/signing/verifier.rs
# The checks run in two passes, so that the model check (tens of seconds)
# runs only for a mutant the unit tests let through:
#   1. unit: the mutated crate's tests (fbwag-delegation's: the machines,
#      engines, nodes, digest, filters and simulated trials; mavframe's for
#      the verifier). A run 5 times longer than the unmutated one (a
#      deadline made a busy loop) is stopped and counted a timeout.
#   2. model: every mutant pass 1 missed, against fbwag-model's tests
#      (the quick world to its fixpoint, the harness, the planted faults),
#      with a fixed 300 s limit.
# cargo-mutants times pass 1's limit from an unmutated run of the mutated
# crate's tests alone, which is why the model is a pass of its own: in
# one pass its tests would outlast that limit and pass as timeouts.
# The nodes' digests (model-check machinery, not policy) are not mutated.
#
#   bash benches/scripts/mutants.sh SCOPE [K/N] [again]
#
# K/N (default 0/1) takes the K-th of N shards of the scope. `again`
# tests only the mutants the last run of that scope and shard missed (after
# a test was added for them); the counts are of both runs together. On
# this 2-core machine the node's 102 mutants took 21 minutes in pass 1.
# Results go to target/mutants/SCOPE-K-N/: done/ holds what each pass
# caught (caught-unit.txt, caught-model.txt, timeout.txt, unviable.txt),
# missed.txt what is left, and pass-*/mutants.out/ cargo-mutants' logs.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."

VERSION=25.3.1
if ! cargo mutants --version 2>/dev/null | grep -qx "cargo-mutants $VERSION"; then
    cargo install --locked cargo-mutants --version "$VERSION"
fi

scope="${1:?usage: mutants.sh engines|node|core|machines|verifier [K/N] [again]}"
shard="${2:-0/1}"
again="${3:-}"
case "$scope" in
    engines)  files=(fbwag-delegation/src/engine/fc.rs fbwag-delegation/src/engine/cc.rs) ;;
    node)     files=(fbwag-delegation/src/node/companion.rs fbwag-delegation/src/node/flight.rs) ;;
    core)     files=(fbwag-delegation/src/node/mod.rs fbwag-delegation/src/node/peers.rs
                     fbwag-delegation/src/node/router.rs) ;;
    machines) files=(fbwag-delegation/src/fc.rs fbwag-delegation/src/cc.rs) ;;
    verifier) files=(mavframe/src/signing/verifier.rs) ;;
    *) echo "unknown scope $scope" >&2; exit 2 ;;
esac
[[ -z "$again" || "$again" == again ]] || { echo "unknown argument $again" >&2; exit 2; }

# --gitignore: the build copies leave out what git ignores (build trees).
args=(--exclude-re digest --jobs 1 --no-shuffle --gitignore true)
for f in "${files[@]}"; do args+=(--file "$f"); done
# Features as the test command has them: the simulator's tests are behind
# fbwag-delegation's `sim`, mavframe's signing-state tests behind `std`.
case "$scope" in
    verifier) args+=(--all-features) ;;
    *) args+=(--features fbwag-delegation/sim) ;;
esac
out="target/mutants/$scope-${shard/\//-}"
done_dir="$out/done"
if [[ -z "$again" ]]; then
    rm -rf "$out"
    mkdir -p "$done_dir"
    touch "$done_dir"/{caught-unit,caught-model,timeout,unviable}.txt
    cargo mutants "${args[@]}" --list --shard "$shard" > "$out/shard.txt"
elif [[ ! -f "$out/shard.txt" ]]; then
    echo "no earlier run of $scope $shard to take up again" >&2; exit 2
fi
count() { wc -l < "$1"; }

# Leaves in $out/missed.txt the shard's mutants no pass has caught yet.
left() { cat "$done_dir"/*.txt | grep -vxF -f - "$out/shard.txt" > "$out/missed.txt" || true; }

# One pass over the mutants still missed: every other mutant of the scope
# is marked done for `--iterate`; what it catches is added to done/.
pass() {
    local name="$1" caught_as="$2"; shift 2
    left
    (( $(count "$out/missed.txt") > 0 )) || return 0
    local dir="$out/pass-$name"
    rm -rf "$dir"
    mkdir -p "$dir/mutants.out"
    cargo mutants "${args[@]}" --list | grep -vxF -f "$out/missed.txt" \
        > "$dir/mutants.out/previously_caught.txt" || true
    # Exit 2 and 3 say mutants were missed or timed out: results.
    local status=0
    cargo mutants "${args[@]}" --iterate --output "$dir" "$@" || status=$?
    if (( status != 0 && status != 2 && status != 3 )); then
        echo "cargo mutants failed (exit $status): see $dir/mutants.out/log" >&2
        exit 1
    fi
    local result="$dir/mutants.out"
    for kind in caught timeout unviable; do
        [[ -f "$result/$kind.txt" ]] || continue
        local to="$kind"; [[ $kind == caught ]] && to="$caught_as"
        cat "$result/$kind.txt" >> "$done_dir/$to.txt"
    done
}

# Pass 1. The checks build as the test command's do (the workspace's test
# profile: the checker's crates optimised).
pass unit caught-unit --timeout-multiplier 5
pass model caught-model --baseline skip --timeout 300 --test-package fbwag-model
left

caught=$(( $(count "$done_dir/caught-unit.txt") + $(count "$done_dir/caught-model.txt") ))
timeout=$(count "$done_dir/timeout.txt")
missed=$(count "$out/missed.txt")
unviable=$(count "$done_dir/unviable.txt")
viable=$((caught + missed + timeout))
echo "$scope $shard: $caught caught ($(count "$done_dir/caught-model.txt") by the model)," \
     "$timeout timeouts, $missed missed, $unviable unviable" \
     "(caught $(( viable ? 100 * (caught + timeout) / viable : 0 )) % of $viable viable)"
if [[ -s "$out/missed.txt" ]]; then echo "missed:"; cat "$out/missed.txt"; fi
