#!/usr/bin/env bash
# The smallest receiver a board would flash (benches/receiver): a no_std
# library that parses a byte stream and reads HEARTBEAT's custom_mode,
# built with opt-level "s", LTO, one codegen unit and panic=abort, on
# mavframe (no default features, a dialect of HEARTBEAT alone from
# mavgen-rs) and on the mavlink crate's `embedded` build (0.21,
# minimal.xml).
# Measured for a Cortex-M4F (thumbv7em-none-eabihf, installed with rustup
# when missing): the static library linked alone with rust-lld, kept from
# `receive` (--gc-sections), its flash image (.text, .rodata, .data) from
# the section headers. The memory routines of compiler-builtins (memcpy,
# memmove, memset: every firmware links them once, the C library's on a C
# firmware) are counted apart; the bound is on the rest, the receiver's own.
#   bash benches/scripts/receiver_size.sh         both, one run: the table BENCHMARKS.md shows
#   bash benches/scripts/receiver_size.sh check   mavframe's alone: fails past BOUND bytes
# Each library is also built for this machine and run on a stream (garbage,
# a frame with a bad checksum, a frame of an unknown id, two HEARTBEATs
# split by garbage, then zeros): it must return the last HEARTBEAT's
# custom_mode.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."

BOUND=6144
BOARD=thumbv7em-none-eabihf
MANIFEST=benches/receiver/Cargo.toml
TARGET="${CARGO_TARGET_DIR:-$PWD/target}"
LLD="$(rustc --print sysroot)/lib/rustlib/$(rustc -vV | sed -n 's/^host: //p')/bin/rust-lld"

# The flash image of ELF $1, and the part of it that is compiler-builtins'
# memory routines: "total builtins".
sizes() {
    local total builtins
    total=0
    for hex in $(readelf -S -W "$1" | sed 's/^ *\[ *[0-9]*\] *//' |
        awk '$1 == ".text" || $1 == ".rodata" || $1 == ".data" { print $5 }'); do
        total=$((total + 16#$hex))
    done
    builtins=$(readelf -s -W "$1" | awk '
        $8 ~ /compiler_builtins3mem|^__aeabi_mem/ { n += $3 }
        END { print n + 0 }')
    echo "$total $builtins"
}

# Runs library $1's `receive` on the stream above.
run() {
    python3 - "$1" <<'PY'
import ctypes, struct, sys

def crc(data, extra):
    c = 0xFFFF
    for b in bytes(data) + bytes([extra]):
        t = b ^ (c & 0xFF)
        t = (t ^ (t << 4)) & 0xFF
        c = ((c >> 8) ^ (t << 8) ^ (t << 3) ^ (t >> 4)) & 0xFFFF
    return c

def frame(msg_id, payload, extra, seq):
    body = bytes([len(payload), 0, 0, seq, 1, 1]) + msg_id.to_bytes(3, "little") + payload
    return b"\xfd" + body + struct.pack("<H", crc(body, extra))

def heartbeat(mode, seq):
    # custom_mode, type, autopilot, base_mode, system_status, mavlink_version
    return frame(0, struct.pack("<IBBBBB", mode, 1, 3, 0x81, 4, 3), 50, seq)

bad = bytearray(heartbeat(7, 1))
bad[12] ^= 0xFF
stream = (b"\x00\xfe\xfd garbage" + bytes(bad) + heartbeat(1234, 2)
          + frame(42424, b"\x01\x02\x03", 0, 3) + b"\xfd\xfd\x00" + heartbeat(5678, 4)
          # The mavlink crate's embedded reader fills its whole buffer with
          # read_exact: bytes after the last frame, so that it gets there.
          + bytes(1024))
lib = ctypes.CDLL(sys.argv[1])
lib.receive.restype = ctypes.c_uint32
lib.receive.argtypes = [ctypes.c_char_p, ctypes.c_size_t]
got = lib.receive(stream, len(stream))
if got != 5678:
    sys.exit(f"{sys.argv[1]}: receive() returned {got}, not 5678")
PY
}

# Builds receiver $1 (fbwag, mavlink) for this machine: its library's path.
build_host() {
    cargo build --quiet --release --locked --manifest-path "$MANIFEST" -p "receiver-$1" \
        --target-dir "$TARGET" >&2
    echo "$TARGET/release/libreceiver_$1.so"
}

# Builds receiver $1 for the board and links it from `receive`: the ELF's path.
build_board() {
    rustup target list --installed | grep -qx "$BOARD" || rustup target add "$BOARD" >&2
    cargo rustc --quiet --release --locked --manifest-path "$MANIFEST" -p "receiver-$1" \
        --target "$BOARD" --target-dir "$TARGET" --crate-type staticlib >&2
    local dir="$TARGET/$BOARD/release"
    "$LLD" -flavor gnu --gc-sections -e receive -o "$dir/receiver_$1.elf" "$dir/libreceiver_$1.a"
    echo "$dir/receiver_$1.elf"
}

run "$(build_host fbwag)"
read -r total builtins < <(sizes "$(build_board fbwag)")
own=$((total - builtins))
if [ "${1:-}" = check ]; then
    echo "receiver on mavframe, $BOARD: $own bytes of its own code and data (bound $BOUND), $builtins of memory routines"
    if [ "$own" -gt "$BOUND" ]; then
        echo "the receiver on mavframe grew past $BOUND bytes" >&2
        exit 1
    fi
    exit 0
fi
run "$(build_host mavlink)"
read -r mtotal mbuiltins < <(sizes "$(build_board mavlink)")
echo "| receiver ($BOARD) | its own (B) | memory routines (B) | flashed (B) |"
echo "|---|---:|---:|---:|"
echo "| mavframe, no default features, HEARTBEAT only | **$own** | $builtins | $total |"
echo "| mavlink 0.21, \`embedded\`, minimal.xml | **$((mtotal - mbuiltins))** | $mbuiltins | $mtotal |"
