#!/usr/bin/env bash
# The main job: regenerates the checked-in Rust bindings of the FBWAG dialect
# from message_definitions/fbwag.xml (after an edit of the XML, of the message
# list fbwag-dialect-cc/messages.txt, or of mavgen-rs):
#   fbwag-dialect/bindings/fbwag     every message (what fbwag-dialect compiles by default)
#   fbwag-dialect-cc/bindings        the companion computer's messages (crate fbwag-dialect-cc)
# `cargo test -p conformance --test bindings` fails while either is stale.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --locked -p mavgen-rs
gen=target/release/mavgen-rs
"$gen" generate message_definitions/fbwag.xml -o fbwag-dialect/bindings/fbwag
"$gen" generate message_definitions/fbwag.xml -o fbwag-dialect-cc/bindings \
    --messages @fbwag-dialect-cc/messages.txt
