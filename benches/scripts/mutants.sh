#!/usr/bin/env bash
# Mutation testing of the protocol's checks, as a measurement (not a test:
# scripts/test.sh does not run it). cargo-mutants (pinned below, installed
# from crates.io when missing) changes the product one small way at a time
# (a comparison flipped, a condition forced, a function's body replaced)
# and runs the fast checks against each change: a mutant they do not catch
# is a gap in the checks, or an equivalent change (BENCHMARKS.md lists each
# survivor and which).
#
#   bash benches/scripts/mutants.sh SCOPE [SHARD]
#
# SCOPE (what is mutated, and which checks run):
#   engines   fbwag-delegation/src/engine/{fc,cc}.rs
#   node      fbwag-delegation/src/node/{companion,flight}.rs
#   machines  fbwag-delegation/src/{fc,cc}.rs (the state machines)
#   verifier  mavframe/src/signing/verifier.rs
# The checks named: fbwag-delegation's tests (the machines, engines,
# nodes, digest, filters, the simulated trials) and fbwag-model's (the
# quick world's fixpoint, the harness, the planted faults); for the
# verifier, mavframe's and fbwag-model's. cargo-mutants 25.3.1 runs those
# of the mutated crate alone (its baseline log shows the command), so the
# model's tests are not part of the score. The nodes' digests (model-check
# machinery, not policy) are not mutated.
# SHARD is K/N (default 0/1): the engines' 53 mutants took 19 minutes on
# this 2-core machine (BENCHMARKS.md, "Checks").
# Results go to target/mutants/SCOPE-K-N/ (outcomes.json, caught.txt,
# missed.txt, timeout.txt, unviable.txt).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."

VERSION=25.3.1
if ! cargo mutants --version 2>/dev/null | grep -qx "cargo-mutants $VERSION"; then
    cargo install --locked cargo-mutants --version "$VERSION"
fi

scope="${1:?usage: mutants.sh engines|node|machines|verifier [K/N] [cargo-mutants options]}"
shard="${2:-0/1}"
shift $(( $# < 2 ? $# : 2 ))
case "$scope" in
    engines)  files=(fbwag-delegation/src/engine/fc.rs fbwag-delegation/src/engine/cc.rs)
              tests=(fbwag-delegation fbwag-model) ;;
    node)     files=(fbwag-delegation/src/node/companion.rs fbwag-delegation/src/node/flight.rs)
              tests=(fbwag-delegation fbwag-model) ;;
    machines) files=(fbwag-delegation/src/fc.rs fbwag-delegation/src/cc.rs)
              tests=(fbwag-delegation fbwag-model) ;;
    verifier) files=(mavframe/src/signing/verifier.rs)
              tests=(mavframe fbwag-model) ;;
    *) echo "unknown scope $scope" >&2; exit 2 ;;
esac

args=()
for f in "${files[@]}"; do args+=(--file "$f"); done
for t in "${tests[@]}"; do args+=(--test-package "$t"); done
# The simulator's tests are behind fbwag-delegation's `sim` feature, a
# feature only a scope that tests that crate can name.
if [[ " ${tests[*]} " == *" fbwag-delegation "* ]]; then
    args+=(--features fbwag-delegation/sim)
fi
out="target/mutants/$scope-${shard/\//-}"
mkdir -p "$out"

# The checks build as the test command's do (the workspace's test profile: the
# checker's crates optimised). A mutant whose checks run 5 times longer
# than unmutated ones (a loop made endless) is stopped: a timeout, caught.
cargo mutants "${args[@]}" \
    --exclude-re 'digest' \
    --shard "$shard" \
    --timeout-multiplier 5 \
    --jobs 1 \
    --output "$out" \
    --no-shuffle \
    "$@" || true

summary() { wc -l < "$out/mutants.out/$1.txt" 2>/dev/null || echo 0; }
caught=$(summary caught); missed=$(summary missed)
timeout=$(summary timeout); unviable=$(summary unviable)
viable=$((caught + missed + timeout))
echo "$scope $shard: $caught caught, $timeout timeouts, $missed missed, $unviable unviable" \
     "(caught $(( viable ? 100 * (caught + timeout) / viable : 0 )) % of $viable viable)"
