#!/usr/bin/env bash
# Handover time of `fbwag cc` + `fbwag fc-sim` (signed, over 127.0.0.1)
# clean and under each flood into both daemons' ports, p50/p95/max over RUNS
# runs, and `fbwag decode` MB/s on 1 MB of each flood pattern. The safety
# outcomes of the same attacks are tests (fbwag-cli/tests/adversarial.rs);
# the times are here. See handover_under_flood.py for the set-up.
#
# Env: RUNS (runs per row, default 10); SLOW=1: the slow-link table alone. Needs cargo and python3 (stdlib).
# Prints markdown (also saved to target/bench-results/handover_under_flood.md).
set -euo pipefail

REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd -P)"
cd "$REPO"
cargo build --release --locked -p fbwag-cli >&2
mkdir -p target/bench-results
python3 benches/scripts/handover_under_flood.py target/release/fbwag "${RUNS:-10}" ${SLOW:+slow} |
    tee target/bench-results/handover_under_flood.md
