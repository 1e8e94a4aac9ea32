#!/usr/bin/env bash
# Runs every check and test of the repository, from a clean clone:
#   formatting, clippy (-D warnings), rustdoc (-D warnings), and `cargo test`
#   over the workspace: unit tests, generator diagnostics and CLI, snapshot,
#   generated-code behaviour, and conformance against pymavlink 2.4.50.
# Installs what it needs itself: the pinned pymavlink in a venv under
# target/pyenv (cached; see scripts/python-env.sh) and the pinned MAVProxy,
# mavsdk and pymavlink in target/peerenv, with python/ (fbwag-mavlink)
# installed (cached; see scripts/peer-env.sh).
# Needs cargo, python3, gcc.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
# A clean clone builds once: incremental caches only cost time and disk here.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"

# Each step with the time since the start: CI must stay well under 30 min.
step() { printf '\n==> %s (at %dm%02ds)\n' "$*" $((SECONDS / 60)) $((SECONDS % 60)); }

step "Python reference environment (pymavlink 2.4.50)"
python="$(bash scripts/python-env.sh)"
"$python" -c 'import pymavlink; print("pymavlink", pymavlink.__version__)'

# The real peers of fbwag-cli/tests/mavproxy.rs, pinned, in target/peerenv
# (cached), with this repository's package python/ (fbwag-mavlink: the FBWAG
# dialect for pymavlink and the MAVProxy module) installed by pip, which
# must write nothing into python/.
step "Peer environment (MAVProxy 1.8.75, mavsdk 3.17.4, pymavlink 2.4.50 + python/ fbwag-mavlink)"
python_tree() { git status --porcelain --ignored --untracked-files=all python/; }
python_before="$(python_tree)"
peer="$(bash scripts/peer-env.sh)"
[ "$(python_tree)" = "$python_before" ] || { echo "pip install ./python wrote into python/" >&2; python_tree >&2; exit 1; }
"$peer" -c 'from importlib.metadata import version as v
from pymavlink.dialects.v20 import fbwag
print("MAVProxy", v("MAVProxy"), "mavsdk", v("mavsdk"), "pymavlink", v("pymavlink"),
      "fbwag-mavlink", v("fbwag-mavlink"),
      "FBWAG_NOTICE crc_extra", fbwag.MAVLink_fbwag_notice_message.crc_extra)'

# python/: the checked-in dialect modules are pymavlink 2.4.50's mavgen output
# for message_definitions/fbwag.xml; the MAVProxy module fed frames (no
# MAVProxy). -B: no byte code in the tree.
step "python/ (fbwag-mavlink): dialect regenerated and compared, MAVProxy module"
"$peer" -B -m unittest discover -s python/tests -v

# fbwag-cli/tests/trust.rs runs daemons on a skewed clock (LD_PRELOAD).
step "libfaketime (daemons on a skewed clock)"
if [ ! -e /usr/lib/x86_64-linux-gnu/faketime/libfaketime.so.1 ]; then
    as_root=""; [ "$(id -u)" -eq 0 ] || as_root=sudo
    $as_root apt-get update
    $as_root env DEBIAN_FRONTEND=noninteractive apt-get install -y libfaketime
fi

step "cargo fmt --check"
cargo fmt --all -- --check

# Libraries with `test = false` (no unit tests: not compiled a second time
# as empty test binaries) must stay without: a unit test added to one
# would never run.
step "libraries with test = false have no unit tests"
cargo metadata --no-deps --format-version 1 --locked | python3 -c '
import json, os, re, sys
found = []
for p in json.load(sys.stdin)["packages"]:
    if not any("lib" in t["kind"] and not t["test"] for t in p["targets"]):
        continue
    root = os.path.dirname(p["manifest_path"])
    for d, subdirs, files in os.walk(root):
        if d == root:  # targets of their own, tested as such
            subdirs[:] = [s for s in subdirs if s not in ("tests", "examples", "benches", "target")]
        for f in files:
            path = os.path.join(d, f)
            if f.endswith(".rs") and re.search(r"#\[\s*(test|cfg\(\s*test\s*\))\s*\]", open(path).read()):
                found.append(os.path.relpath(path))
print("\n".join(f"{f}: a unit test in a library with test = false" for f in found) or "none found")
sys.exit(1 if found else 0)
'

# Builds with target directories of their own run in the background, beside
# clippy, rustdoc and the test build, which leave one of two cores idle much
# of the time: the fuzz targets (target/fuzz), and the published crates
# packaged and verified (target/package-verify, target/package-check).
# They are only builds, and they are joined before the first test runs, so
# no test, timed or not, shares the machine with them. The log is printed at
# the join; a failure there fails this script. In a process group of its
# own, so that an earlier failure stops it too.
BACKGROUND_LOG=target/test-background.log
mkdir -p target
bstep() { printf '\n==> [background] %s (at %dm%02ds)\n' "$*" $((SECONDS / 60)) $((SECONDS % 60)); }
set -m
(
    set -euo pipefail
    # Every library crate's public API against its snapshot in api/, so
    # that a change of an API shows in review: cargo-public-api (pinned,
    # built once into target/tools) over rustdoc's JSON (nightly).
    bstep "public API of the published libraries against api/ (scripts/public-api.sh)"
    bash scripts/public-api.sh check

    bstep "conformance: fuzz targets built (run below)"
    bash conformance/scripts/fuzz.sh build

    # --- publishing ---
    # Every crate meant for crates.io, packaged and verified together: cargo
    # (>= 1.83) builds each packaged tarball against the others through a local
    # registry overlay, so path dependencies not yet on crates.io resolve.
    # --allow-dirty: package the working tree as it is (a clean clone is clean).
    PUBLISHED=(-p mavframe -p mavgen-rs -p fbwag-dialect -p fbwag-dialect-cc -p fbwag-delegation -p fbwag-model -p fbwag-cli)
    bstep "cargo package: ${PUBLISHED[*]}"
    # The verification resolves the packaged crates as registry crates, which
    # cargo takes as immutable per version: it reuses their unpacked copies in
    # $CARGO_HOME/registry/src/<overlay>/ and what it compiled from them, so a
    # second run from the same checkout would verify against the first run's
    # code (same version, other code). So: those copies removed (the names are
    # not on crates.io: nothing else lives there), and a target directory of
    # its own, emptied first.
    PACKAGED=target/package-verify
    rm -rf "$PACKAGED"
    for crate in mavframe mavgen-rs fbwag-dialect fbwag-dialect-cc fbwag-delegation fbwag-model fbwag-cli; do
        version="$(cargo pkgid -p "$crate" | sed 's/.*[#@]//')"
        rm -rf "${CARGO_HOME:-$HOME/.cargo}"/registry/src/*/"$crate-$version"
    done
    cargo package --locked --allow-dirty --target-dir "$PACKAGED" "${PUBLISHED[@]}"

    # The verification builds default features only; `codegen` reads the XML
    # the package carries (message_definitions/, symbolic links in the
    # repository): generate from the packaged copy, against the packaged crates.
    bstep "packaged fbwag-dialect with feature codegen (its own message_definitions)"
    packaged() { echo "$PACKAGED/package/$1-$(cargo pkgid -p "$1" | sed 's/.*[#@]//')"; }
    cargo build --manifest-path "$(packaged fbwag-dialect)/Cargo.toml" --features codegen \
        --config "patch.crates-io.mavframe.path=\"$(packaged mavframe)\"" \
        --config "patch.crates-io.mavgen-rs.path=\"$(packaged mavgen-rs)\"" \
        --target-dir target/package-check
    # --- end publishing ---
    bstep "done"
) </dev/null >"$BACKGROUND_LOG" 2>&1 &
background=$!
set +m
trap 'kill -- "-$background" 2>/dev/null || true' EXIT

# The workspace's members ask for every feature of one another but
# fbwag-dialect's `codegen`, whose own code is the build script that
# generates the bindings (the same code as the checked-in copy, which a
# conformance test keeps equal): linted on its own, not by checking every
# crate above fbwag-dialect a second time.
step "cargo clippy -D warnings (workspace; fbwag-dialect's codegen build script)"
cargo clippy --workspace --all-targets --locked -- -D warnings
cargo clippy -p fbwag-dialect --lib --features codegen --locked -- -D warnings

step "cargo doc -D warnings"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked

step "API docs as docs.rs builds them, no link left as text"
bash scripts/check-docs.sh

step "cargo test: build"
cargo test --workspace --locked --no-run

step "background builds joined: fuzz targets, cargo package"
status=0
wait "$background" || status=$?
trap - EXIT
cat "$BACKGROUND_LOG"
if [ "$status" -ne 0 ]; then
    echo "the background builds failed (exit $status): $BACKGROUND_LOG" >&2
    exit "$status"
fi

step "cargo test"
cargo test --workspace --locked

# `cargo test` above ran mavframe's tests with every feature (serial over a
# pseudo-terminal, tokio, embedded-io): the workspace's members ask for all
# of them. Checked, so that a feature no member asks for is noticed.
step "mavframe's tests ran with every feature"
declared="$(cargo metadata --no-deps --format-version 1 --locked | python3 -c '
import json, sys
for p in json.load(sys.stdin)["packages"]:
    if p["name"] == "mavframe":
        print("\n".join(f for f in p["features"] if f != "default"))
' | LC_ALL=C sort)"
enabled="$(cargo tree --workspace -e features -i mavframe --prefix none --locked |
    sed -n 's/^mavframe feature "\([^"]*\)".*/\1/p' | LC_ALL=C sort -u)"
unasked="$(LC_ALL=C comm -23 <(echo "$declared") <(echo "$enabled"))"
if [ -n "$unasked" ]; then
    echo "no workspace member asks for mavframe's feature(s): $unasked" >&2
    exit 1
fi
echo "all of: $(echo $declared)"

# --- conformance ---
# The conformance tests ran in `cargo test` above (conformance/tests/wire.rs
# prints its report: every message of fbwag.xml and all.xml against pymavlink
# 2.4.50 and the MAVLink C library, and the corrupted streams). Here: the
# bounded libFuzzer run (stable toolchain, 4 targets x 15 s) and the summary.
# What each check proves: docs/conformance.md.
step "conformance: bounded fuzz run (parser, frame, view, xml: 15 s each)"
bash conformance/scripts/fuzz.sh run 15

step "conformance: summary"
bash conformance/scripts/summary.sh
# --- end conformance ---

step "no_std builds: fbwag-dialect, fbwag-dialect-cc, fbwag-delegation, mavframe's embedded adapters, the receiver's size"
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
# A Cortex-M4F target: the bare-metal builds below need it.
rustup target list --installed | grep -qx thumbv7em-none-eabihf ||
    rustup target add thumbv7em-none-eabihf
# The smallest receiver a board flashes (benches/receiver: a no_std library
# on mavframe without default features, size profile), run on a stream on
# this machine, and held to its bound of code and data on the board.
bash benches/scripts/receiver_size.sh check
cargo build -p mavframe --no-default-features --features embedded-io,embedded-io-async \
    --target thumbv7em-none-eabihf --locked

step "fbwag-dialect generated at build time (feature codegen): full, a custom list"
cargo test -p fbwag-dialect --features codegen --locked
FBWAG_DIALECT_MESSAGES=ATTITUDE,COMMAND_LONG \
    cargo build -p fbwag-dialect --no-default-features --features codegen --locked
cargo build -p fbwag-delegation --no-default-features --locked

# --- publishing and a user's crate ---
# (cargo package and the packaged codegen build ran in the background
# builds, above.)

# A crate outside the workspace, with its own lock file: the README's
# own-dialect section. Shares the target directory (the same dependency
# builds are reused).
step "examples/own-dialect: its own dialect, generated by build.rs, round-tripped"
CARGO_TARGET_DIR="$PWD/target" cargo run --manifest-path examples/own-dialect/Cargo.toml --locked
CARGO_TARGET_DIR="$PWD/target" cargo clippy --manifest-path examples/own-dialect/Cargo.toml \
    --locked --all-targets --features serde -- -D warnings
cargo fmt --manifest-path examples/own-dialect/Cargo.toml -- --check
# README.md shows the example's Cargo.toml and build.rs: the same text.
python3 - examples/own-dialect/Cargo.toml examples/own-dialect/build.rs <<'PY'
import sys
readme = open("README.md").read()
stale = [f for f in sys.argv[1:] if open(f).read() not in readme]
sys.exit(f"README.md does not show the current {', '.join(stale)}" if stale else 0)
PY
# --- end publishing ---

printf '\nAll checks passed in %dm%02ds.\n' $((SECONDS / 60)) $((SECONDS % 60))
