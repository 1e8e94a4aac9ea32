#!/usr/bin/env bash
# The smallest receiver a board would flash (benches/receiver): a no_std
# cdylib that parses a byte stream and reads HEARTBEAT's custom_mode, built
# with opt-level "s", LTO, one codegen unit and panic=abort, on mavframe
# (no default features, a dialect of HEARTBEAT alone from mavgen-rs) and on
# the mavlink crate's `embedded` build (0.21, minimal.xml). Measured as
# code (.text) and read-only data (.rodata, .data.rel.ro: read-only once
# relocated), from `size -A`, on x86_64 (the target installed here).
#   bash benches/scripts/receiver_size.sh         both, one run: the table BENCHMARKS.md shows
#   bash benches/scripts/receiver_size.sh check   mavframe's alone: fails past BOUND bytes
# Each library is loaded and run on a stream (garbage, a frame with a bad
# checksum, a frame of an unknown id, two HEARTBEATs split by garbage, then
# zeros): it must return the last HEARTBEAT's custom_mode.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/../.."

# The target is 6 KiB (6,144 bytes); the bound is what the parser takes
# now (BENCHMARKS.md, "A receiver on a board"), so that it cannot grow.
BOUND=6656
MANIFEST=benches/receiver/Cargo.toml
TARGET="${CARGO_TARGET_DIR:-$PWD/target}"

# code, read-only data of library $1.
sizes() {
    size -A "$1" | awk '
        $1 == ".text" { code += $2 }
        $1 == ".rodata" || $1 == ".data.rel.ro" { ro += $2 }
        END { print code, ro }'
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

# Builds receiver $1 (fbwag, mavlink): its library's path on stdout.
build() {
    cargo build --quiet --release --locked --manifest-path "$MANIFEST" -p "receiver-$1" \
        --target-dir "$TARGET" >&2
    echo "$TARGET/release/libreceiver_$1.so"
}

fbwag="$(build fbwag)"
run "$fbwag"
read -r code ro < <(sizes "$fbwag")
total=$((code + ro))
if [ "${1:-}" = check ]; then
    echo "receiver on mavframe: $code bytes of code + $ro of read-only data = $total (bound $BOUND)"
    if [ "$total" -gt "$BOUND" ]; then
        echo "the receiver on mavframe grew past $BOUND bytes" >&2
        exit 1
    fi
    exit 0
fi
mavlink="$(build mavlink)"
run "$mavlink"
read -r mcode mro < <(sizes "$mavlink")
echo "| receiver | code (B) | read-only data (B) | total (B) |"
echo "|---|---:|---:|---:|"
echo "| mavframe, no default features, HEARTBEAT only | $code | $ro | **$total** |"
echo "| mavlink 0.21, \`embedded\`, minimal.xml | $mcode | $mro | **$((mcode + mro))** |"
