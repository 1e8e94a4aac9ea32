#!/usr/bin/env bash
# Runs every check and test of the repository, from a clean clone:
#   formatting, clippy (-D warnings), rustdoc (-D warnings), and `cargo test`
#   over the workspace: unit tests, generator diagnostics and CLI, snapshot,
#   generated-code behaviour, and conformance against pymavlink 2.4.50.
# Installs what it needs itself: the pinned pymavlink in a venv under
# target/pyenv (cached; see scripts/python-env.sh) and the pinned MAVProxy,
# mavsdk and pymavlink in target/peerenv (cached; see scripts/peer-env.sh).
# Needs cargo, python3, gcc.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

step() { printf '\n==> %s\n' "$*"; }

step "Python reference environment (pymavlink 2.4.50)"
python="$(bash scripts/python-env.sh)"
"$python" -c 'import pymavlink; print("pymavlink", pymavlink.__version__)'

# The real peers of fbwag-cli/tests/mavproxy.rs, pinned, in target/peerenv
# (cached), with the FBWAG dialect and the MAVProxy module installed into them.
step "Peer environment (MAVProxy 1.8.75, mavsdk 3.17.4, pymavlink 2.4.50 + FBWAG dialect)"
peer="$(bash scripts/peer-env.sh)"
"$peer" -c 'from importlib.metadata import version as v
from pymavlink.dialects.v20 import fbwag
print("MAVProxy", v("MAVProxy"), "mavsdk", v("mavsdk"), "pymavlink", v("pymavlink"),
      "FBWAG_NOTICE crc_extra", fbwag.MAVLink_fbwag_notice_message.crc_extra)'

step "cargo fmt --check"
cargo fmt --all -- --check

step "cargo clippy -D warnings (default features, then all: serial, tokio)"
cargo clippy --workspace --all-targets --locked -- -D warnings
cargo clippy --workspace --all-targets --all-features --locked -- -D warnings

step "cargo doc -D warnings"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked

step "cargo test"
cargo test --workspace --locked

step "mavframe with every feature (serial over a pseudo-terminal, tokio)"
cargo test -p mavframe --all-features --locked

# --- conformance (issue 6) ---
# The conformance tests ran in `cargo test` above (conformance/tests/wire.rs
# prints its report: every message of fbwag.xml and all.xml against pymavlink
# 2.4.50 and the MAVLink C library, and the corrupted streams). Here: the
# bounded libFuzzer run (stable toolchain, 4 targets x 15 s) and the summary.
# What each check proves: docs/conformance.md.
step "conformance: bounded fuzz run (parser, frame, view, xml: 15 s each)"
bash conformance/scripts/fuzz.sh run 15

step "conformance: summary"
bash conformance/scripts/summary.sh
# --- end conformance (issue 6) ---

step "no_std builds: fbwag-dialect, fbwag-dialect-cc, fbwag-delegation, mavframe's embedded adapters"
cargo build -p fbwag-dialect --no-default-features --locked
cargo build -p fbwag-dialect-cc --no-default-features --locked
cargo build -p fbwag-dialect --no-default-features --features serde --locked
cargo build -p mavframe --no-default-features --features embedded-io,embedded-io-async --locked
# A host build links std anyway: no dependency of that build may turn std or
# alloc on; a bare-metal target proves the rest where it is installed.
embedded_tree="$(cargo tree -p mavframe --no-default-features --features embedded-io,embedded-io-async \
    -e normal,features --prefix none --locked)"
if grep -E 'feature "(std|alloc)"' <<<"$embedded_tree"; then
    echo "a dependency of mavframe's no_std build turns on std or alloc" >&2
    exit 1
fi
if rustup target list --installed 2>/dev/null | grep -qx thumbv7em-none-eabihf; then
    cargo build -p mavframe --no-default-features --features embedded-io,embedded-io-async \
        --target thumbv7em-none-eabihf --locked
else
    echo "thumbv7em-none-eabihf not installed: the bare-metal build of mavframe is skipped"
fi

step "fbwag-dialect generated at build time (feature codegen): full, a custom list"
cargo test -p fbwag-dialect --features codegen --locked
FBWAG_DIALECT_MESSAGES=ATTITUDE,COMMAND_LONG \
    cargo build -p fbwag-dialect --no-default-features --features codegen --locked
cargo build -p fbwag-delegation --no-default-features --locked
