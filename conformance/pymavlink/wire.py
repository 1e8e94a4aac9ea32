#!/usr/bin/env python3
"""pymavlink 2.4.50 as a peer of the conformance tests (conformance/tests/wire.rs).

One process per dialect and run, file in, file out:

  wire.py frames  --dialect fbwag|all --key HEX            < cases   > results
  wire.py streams --dialect fbwag|all --key HEX|- --accept-unsigned 0|1 < streams > results

Value text (shared with the Rust and C sides), fields in wire order:
  name=value;name=value;...
integers in decimal (a scalar char as its byte), float/double as the hex of
their IEEE bits (8 / 16 digits), char[N] as the hex of all N bytes, other
arrays as comma-separated elements.

frames: each input line is
  IDX MODE MSGID SEQ SYSID COMPID LINK SIGN_TS VALUES RUSTHEX
(MODE v2 | v2s | v1). pymavlink builds the message from VALUES with the
generated class's constructor (XML order) and packs it (`msg.pack(mav,
force_mavlink1=...)`, signed with the key for v2s), and decodes RUSTHEX with
its parser (`parse_char`; with the key, and no unsigned callback, for v2s).
Output per line:
  IDX PYHEX RDEC
RDEC is "ok:SIG:SEQ:SYSID:COMPID:VALUES" or "rej:REASON"; SIG is 1 when
pymavlink verified the signature (its msg._signed), else 0. Decoded values are
pymavlink's: integers as it unpacked them, floats from the Python float it
holds (float32 narrowed back, which is exact for any float32 but a
signalling NaN: see docs/conformance.md), char fields from its raw copy
(`_<name>_raw`, trailing NULs restored to N bytes).

streams: each input line is
  STREAMHEX [FRAMEHEX ...]
pymavlink parses the stream (robust_parsing, as decode_json.py; with the key
unless "-": unsigned frames go through allow_unsigned_callback, which accepts
them only with --accept-unsigned 1 and never for a frame whose signature just
failed), then checks every FRAMEHEX on its own with a fresh parser state.
Output per line, tab separated:
  ACCEPTED  STANDALONE  UNKNOWN
ACCEPTED: the frames of known messages pymavlink returned, hex, space
separated ("-" for none); STANDALONE: one 0/1 per FRAMEHEX ("-" for none);
UNKNOWN: how many MAVLink_unknown it returned.
"""
import argparse
import os
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

_F32 = struct.Struct("<f")
_U32 = struct.Struct("<I")
_F64 = struct.Struct("<d")
_U64 = struct.Struct("<Q")


def load_dialect(name):
    if name == "fbwag":
        import fbwag_dialect
        return fbwag_dialect.load()
    if name == "all":
        from pymavlink.dialects.v20 import all as mod
        return mod
    raise SystemExit("wire.py: unknown dialect %r" % name)


class Fields(object):
    """Per message class: (name, base type, array length) in XML order and in
    wire order."""

    cache = {}

    @classmethod
    def of(cls, msgtype):
        f = cls.cache.get(msgtype)
        if f is None:
            f = cls.cache[msgtype] = cls(msgtype)
        return f

    def __init__(self, t):
        # array_lengths is in wire order (ordered_fieldnames), fieldtypes in
        # XML order (fieldnames).
        alen = dict(zip(t.ordered_fieldnames, t.array_lengths))
        types = dict(zip(t.fieldnames, t.fieldtypes))
        self.xml = [(n, base_type(types[n]), alen[n]) for n in t.fieldnames]
        self.wire = [(n, base_type(types[n]), alen[n]) for n in t.ordered_fieldnames]


def base_type(t):
    # HEARTBEAT.mavlink_version is "uint8_t_mavlink_version".
    return "uint8_t" if t.startswith("uint8_t") else t


def parse_elem(t, s):
    if t == "float":
        return _F32.unpack(_U32.pack(int(s, 16)))[0]
    if t == "double":
        return _F64.unpack(_U64.pack(int(s, 16)))[0]
    return int(s)


def parse_values(fields, text):
    vals = dict(kv.split("=", 1) for kv in text.split(";"))
    args = []
    for name, t, n in fields.xml:
        s = vals.pop(name)
        if t == "char":
            args.append(bytes.fromhex(s) if n else bytes([int(s)]))
        elif n:
            args.append([parse_elem(t, e) for e in s.split(",")])
        else:
            args.append(parse_elem(t, s))
    if vals:
        raise ValueError("fields pymavlink does not know: %s" % sorted(vals))
    return args


def fmt_elem(t, v):
    if t == "float":
        return "%08x" % _U32.unpack(_F32.pack(v))[0]
    if t == "double":
        return "%016x" % _U64.unpack(_F64.pack(v))[0]
    return str(v)


def fmt_values(msg, fields):
    out = []
    for name, t, n in fields.wire:
        if t == "char":
            raw = getattr(msg, "_%s_raw" % name)
            raw = raw + b"\0" * (max(n, 1) - len(raw))
            s = raw.hex() if n else str(raw[0])
        elif n:
            s = ",".join(fmt_elem(t, e) for e in getattr(msg, name))
        else:
            s = fmt_elem(t, getattr(msg, name))
        out.append("%s=%s" % (name, s))
    return ";".join(out)


def decode_one(mod, mav, frame):
    """pymavlink's verdict on one whole frame: the token described above."""
    try:
        m = mav.parse_char(frame)
    except mod.MAVError as e:
        return "rej:" + str(e).replace(" ", "_")[:60]
    if m is None or mav.buf_len() != 0:
        return "rej:incomplete"
    if isinstance(m, (mod.MAVLink_bad_data, mod.MAVLink_unknown)):
        return "rej:" + type(m).__name__
    h = m.get_header()
    return "ok:%d:%d:%d:%d:%s" % (1 if m.get_signed() else 0, h.seq, h.srcSystem, h.srcComponent,
                                  fmt_values(m, Fields.of(type(m))))


def cmd_frames(mod, key, inp, out):
    tx = mod.MAVLink(None)
    tx.signing.secret_key = key
    rx_plain = mod.MAVLink(None)
    rx_signed = mod.MAVLink(None)
    rx_signed.signing.secret_key = key
    lines = []
    for line in inp:
        idx, mode, msgid, seq, sysid, compid, link, ts, values, rhex = line.split()
        msgtype = mod.mavlink_map[int(msgid)]
        fields = Fields.of(msgtype)
        msg = msgtype(*parse_values(fields, values))
        tx.seq, tx.srcSystem, tx.srcComponent = int(seq), int(sysid), int(compid)
        signed = mode == "v2s"
        tx.signing.sign_outgoing = signed
        if signed:
            tx.signing.link_id = int(link)
            tx.signing.timestamp = int(ts)
        pybuf = msg.pack(tx, force_mavlink1=(mode == "v1"))
        rdec = decode_one(mod, rx_signed if signed else rx_plain, bytes.fromhex(rhex))
        lines.append("%s %s %s" % (idx, pybuf.hex(), rdec))
        if len(lines) >= 2048:
            out.write("\n".join(lines) + "\n")
            lines = []
    if lines:
        out.write("\n".join(lines) + "\n")


class Policy(object):
    """A parser with the stream policy: key or not, unsigned accepted or not."""

    def __init__(self, mod, key, accept_unsigned):
        self.mod = mod
        self.key = key
        self.accept_unsigned = accept_unsigned

    def fresh(self, robust):
        mav = self.mod.MAVLink(None)
        mav.robust_parsing = robust
        if self.key is not None:
            mav.signing.secret_key = self.key
            seen = [0]

            # Called for unsigned frames and for failed signatures alike; a
            # failure has just incremented badsig_count (as decode_json.py).
            def allow(m, msgid):
                if m.signing.badsig_count != seen[0]:
                    seen[0] = m.signing.badsig_count
                    return False
                return self.accept_unsigned
            mav.signing.allow_unsigned_callback = allow
        return mav


def cmd_streams(mod, key, accept_unsigned, inp, out):
    policy = Policy(mod, key, accept_unsigned)
    for line in inp:
        parts = line.split()
        stream = bytes.fromhex(parts[0])
        mav = policy.fresh(True)
        accepted, unknown = [], 0
        for m in mav.parse_buffer(stream) or []:
            if isinstance(m, mod.MAVLink_bad_data):
                continue
            if isinstance(m, mod.MAVLink_unknown):
                unknown += 1
                continue
            accepted.append(bytes(m.get_msgbuf()).hex())
        verdicts = []
        for fhex in parts[1:]:
            one = policy.fresh(False)
            try:
                m = one.parse_char(bytes.fromhex(fhex))
                ok = (m is not None and one.buf_len() == 0
                      and not isinstance(m, (mod.MAVLink_bad_data, mod.MAVLink_unknown)))
            except mod.MAVError:
                ok = False
            verdicts.append("1" if ok else "0")
        out.write("%s\t%s\t%d\n" % (" ".join(accepted) or "-", "".join(verdicts) or "-", unknown))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("command", choices=["frames", "streams"])
    ap.add_argument("--dialect", required=True, choices=["fbwag", "all"])
    ap.add_argument("--key", required=True, help="signing key, 64 hex digits, or - for none")
    ap.add_argument("--accept-unsigned", type=int, default=1)
    args = ap.parse_args()
    mod = load_dialect(args.dialect)
    key = None if args.key == "-" else bytes.fromhex(args.key)
    if args.command == "frames":
        if key is None:
            raise SystemExit("wire.py frames needs --key")
        cmd_frames(mod, key, sys.stdin, sys.stdout)
    else:
        cmd_streams(mod, key, bool(args.accept_unsigned), sys.stdin, sys.stdout)


if __name__ == "__main__":
    main()
