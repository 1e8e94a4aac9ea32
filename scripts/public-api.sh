#!/usr/bin/env bash
# The public API of each library crate meant for crates.io, as
# cargo-public-api lists it, against the snapshots in api/: every change to
# an API shows in review as a change of its snapshot.
#   bash scripts/public-api.sh install   cargo-public-api, pinned, in target/tools (cached)
#   bash scripts/public-api.sh check     fails, with the diff, when an API differs
#   bash scripts/public-api.sh update    writes the snapshots
# rustdoc's JSON needs a nightly rustdoc: the installed nightly toolchain,
# else the stable one with RUSTC_BOOTSTRAP=1 (the same JSON, the same
# listing). fbwag-cli has no library: its interface is its command line.
# Cost on 2 cores: from a clean clone about 70 s of CPU to build the tool and
# 55 s for the JSON (both only builds: the test command runs this among its
# background builds); with both cached, 20 s.
# The dialect crates' generated items (their `dialects` modules and the
# same items at the crate's root) are left out, with their count: the
# checked-in bindings hold them (conformance/tests/bindings.rs).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

VERSION=0.52.0
ROOT="$PWD/target/tools/cargo-public-api-$VERSION"
TOOL="$ROOT/bin/cargo-public-api"
# Its own target directory: rustdoc's JSON is built by another toolchain.
JSON_TARGET="$PWD/target/api"

# crate, then the features its API is listed with.
CRATES=(
    "mavframe --all-features"
    "mavgen-rs --no-default-features"
    "fbwag-dialect --features std,serial,tokio,serde,embedded-io,embedded-io-async"
    "fbwag-dialect-cc --all-features"
    "fbwag-delegation --all-features"
    "fbwag-model"
)

install() {
    if [ -x "$TOOL" ] && "$TOOL" --version | grep -qx "cargo-public-api $VERSION"; then
        return
    fi
    # --debug: built in 70 s of CPU instead of 170 (2 cores, cold); it
    # lists the largest crate here in 2.5 s instead of 0.9.
    cargo install --locked --quiet --debug "cargo-public-api@$VERSION" --root "$ROOT" \
        --target-dir "$PWD/target/tools/build"
}

# rustdoc's JSON of crate $1 with features "${@:2}": its path on stdout.
json() {
    local crate="$1"
    shift
    local toolchain=() bootstrap=()
    if rustup toolchain list 2>/dev/null | grep -q '^nightly'; then
        toolchain=(+nightly)
    else
        bootstrap=(env RUSTC_BOOTSTRAP=1)
    fi
    "${bootstrap[@]}" cargo "${toolchain[@]}" rustdoc --quiet --locked -p "$crate" --lib "$@" \
        --target-dir "$JSON_TARGET" -- -Z unstable-options --output-format json >&2
    echo "$JSON_TARGET/doc/${crate//-/_}.json"
}

# The listing of crate $1 (features "${@:2}"), generated items left out.
listing() {
    local crate="$1" json
    json="$(json "$@")"
    "$TOOL" --rustdoc-json "$json" -ss --color never |
        python3 -c '
import re, sys
crate = sys.argv[1]
lines = sys.stdin.read().splitlines()
gen = crate + "::dialects::"
# Every item a dialect module defines, by name: the same at the root.
names = {m.group(1) for l in lines for m in re.finditer(re.escape(gen) + r"\w+::(\w+)", l)}
path = re.compile(re.escape(crate) + r"::[\w:]*")
def subject(line):
    # An impl is its type'"'"'s (`impl From<Generated> for u8`: the trait'"'"'s).
    if line.startswith("impl ") and " for " in line:
        m = path.search(line.rsplit(" for ", 1)[1])
        if m:
            return m.group(0)
    m = path.search(line)
    return m.group(0) if m else ""
kept, left = [], 0
for l in lines:
    s = subject(l)
    parts = s.split("::")
    generated = s.startswith(gen) and not l.startswith("pub mod ")
    generated = generated or (len(parts) > 1 and parts[1] in names)
    if generated:
        left += 1
    else:
        kept.append(l)
if names:
    kept.insert(0, f"// {left} lines of generated items left out (the checked-in bindings)")
print("\n".join(kept))
' "${crate//-/_}"
}

case "${1:-check}" in
install)
    install
    ;;
check | update)
    install
    mkdir -p api
    status=0
    for entry in "${CRATES[@]}"; do
        read -r -a args <<<"$entry"
        crate="${args[0]}"
        new="$(listing "${args[@]}")"
        if [ "$1" = update ]; then
            printf '%s\n' "$new" >"api/$crate.txt"
            echo "api/$crate.txt: $(wc -l <"api/$crate.txt") lines"
        elif ! diff -u "api/$crate.txt" <(printf '%s\n' "$new") >&2; then
            echo "the public API of $crate differs from api/$crate.txt (above); if meant, run: bash scripts/public-api.sh update" >&2
            status=1
        else
            echo "$crate: the API is api/$crate.txt"
        fi
    done
    exit "$status"
    ;;
*)
    echo "usage: $0 [install|check|update]" >&2
    exit 2
    ;;
esac
