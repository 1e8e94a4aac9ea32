#!/usr/bin/env python3
"""Decode a MAVLink byte stream with pymavlink 2.4.50 (fbwag dialect) to JSON lines.

One line per decoded frame, keys in this order:

  {"version":2,"seq":0,"sysid":1,"compid":1,"msgid":15001,"name":"FBWAG_NOTICE",
   "signed":false,"fields":{"timestamp":123456,"system_id":1,"component_id":1,
   "failsafe_status":1,"text":"FBWAG"}}

- "fields" in wire order (pymavlink's ordered_fieldnames: base fields sorted
  by type size, then extensions in XML order);
- integers as JSON numbers; floats as Python's repr of the value pymavlink
  unpacked (float32 widened to float64, e.g. 0.10000000149011612); NaN and
  infinities as the strings "NaN", "inf", "-inf";
- arrays as JSON arrays (uint8_t arrays included: pymavlink unpacks them as
  lists of ints); char fields as the string pymavlink makes of them: cut at
  the first NUL, decoded as ASCII with U+FFFD for every byte >= 0x80
  (--chars latin1 instead maps each byte to U+0000..U+00FF, losslessly, from
  pymavlink's raw copy of the field); output is ASCII, non-ASCII characters
  as JSON \\uXXXX escapes;
- "version" from the frame's start byte (0xFE: 1, 0xFD: 2); "signed" is true
  when the frame carries a signature block (incompat flag 0x01), whether or not
  it was verified (pymavlink itself only sets its _signed after a check with
  a key: see --sign-key).

Input: a file or stdin (-), raw bytes by default; --hex for hex text (any
whitespace ignored, an optional 0x prefix per token); --tlog for pymavlink
.tlog (8-byte big-endian microsecond timestamp before each frame).

Parsing never stops early: pymavlink's parser runs with robust_parsing, every
bad frame is counted by kind, and the summary goes to stderr. Exit status is
0 even with bad frames (use --strict for 1). Frames with an id the dialect
lacks are counted (pymavlink cannot check their CRC) and not printed.
"""
import argparse
import math
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import fbwag_dialect  # noqa: E402

_json_str = None
_raw_chars = False


def json_string(s):
    return _json_str(s)


def fmt_value(v):
    t = type(v)
    if t is int:
        return str(v)
    if t is float:
        if v != v:
            return '"NaN"'
        if v in (math.inf, -math.inf):
            return '"inf"' if v > 0 else '"-inf"'
        return repr(v)
    if t is bytes:
        cut = v.find(b"\0")
        if cut >= 0:
            v = v[:cut]
        return json_string(v.decode("utf-8", errors="backslashreplace"))
    if t is list or t is tuple:
        return "[" + ",".join(fmt_value(x) for x in v) + "]"
    if t is bool:
        return "true" if v else "false"
    if t is str:
        return json_string(v)
    raise TypeError("unexpected field value %r" % (v,))


def field_value(msg, name):
    v = getattr(msg, name)
    if _raw_chars and type(v) is str:
        # pymavlink keeps the bytes it decoded (trailing NULs stripped) here
        raw = getattr(msg, "_%s_raw" % name)
        return raw.split(b"\0", 1)[0].decode("latin-1")
    return v


def frame_json(msg):
    buf = msg.get_msgbuf()
    hdr = msg.get_header()
    version = 1 if buf[0] == 0xFE else 2
    signed = version == 2 and bool(hdr.incompat_flags & 0x01)
    fields = ",".join('"%s":%s' % (name, fmt_value(field_value(msg, name)))
                      for name in msg.ordered_fieldnames)
    return ('{"version":%d,"seq":%d,"sysid":%d,"compid":%d,"msgid":%d,"name":"%s",'
            '"signed":%s,"fields":{%s}}'
            % (version, hdr.seq, hdr.srcSystem, hdr.srcComponent, hdr.msgId,
               msg.get_type(), "true" if signed else "false", fields))


class Stats(object):
    def __init__(self):
        self.decoded = 0
        self.v1 = 0
        self.signed = 0
        self.bad_crc = 0
        self.bad_sig = 0
        self.bad_flags = 0
        self.bad_other = 0
        self.junk_bytes = 0
        self.unknown = 0
        self.tlog_resync = 0
        self.reasons = {}

    def bad(self, msg):
        reason = msg.reason
        if reason == "Bad prefix":
            self.junk_bytes += len(msg.data)
            return
        if "invalid MAVLink CRC" in reason:
            self.bad_crc += 1
        elif "Invalid signature" in reason:
            self.bad_sig += 1
        elif "invalid incompat_flags" in reason:
            self.bad_flags += 1
        else:
            self.bad_other += 1
            key = re.sub(r"(0x)?[0-9a-f]+\b", "N", reason)[:70]
            self.reasons[key] = self.reasons.get(key, 0) + 1

    def summary(self):
        s = ("decode_json: %d frames decoded (%d MAVLink 1, %d signed), %d bad CRC, "
             "%d bad signature, %d bad incompat flags, %d other errors, %d unknown msgid, "
             "%d junk bytes skipped"
             % (self.decoded, self.v1, self.signed, self.bad_crc, self.bad_sig, self.bad_flags,
                self.bad_other, self.unknown, self.junk_bytes))
        if self.tlog_resync:
            s += ", %d tlog resyncs" % self.tlog_resync
        for k in sorted(self.reasons):
            s += "\n  %d x %s" % (self.reasons[k], k)
        return s

    @property
    def errors(self):
        return (self.bad_crc + self.bad_sig + self.bad_flags + self.bad_other
                + self.junk_bytes + self.tlog_resync)


class Decoder(object):
    def __init__(self, mod, out, key=None):
        self.mod = mod
        self.out = out
        self.stats = Stats()
        self.mav = mod.MAVLink(None)
        self.mav.robust_parsing = True
        if key is not None:
            self.mav.signing.secret_key = key
            # pymavlink rejects every unsigned frame once a key is set, and
            # calls allow_unsigned_callback for unsigned frames AND for frames
            # whose signature failed. Accept only the former: a failed check
            # has just incremented badsig_count.
            self._badsig_seen = 0

            def allow_unsigned(mav, msgid):
                if mav.signing.badsig_count != self._badsig_seen:
                    self._badsig_seen = mav.signing.badsig_count
                    return False
                return True
            self.mav.signing.allow_unsigned_callback = allow_unsigned
        self.lines = []

    def feed(self, data):
        msgs = self.mav.parse_buffer(data)
        if msgs:
            self.handle(msgs)

    def handle(self, msgs):
        st = self.stats
        mod = self.mod
        lines = self.lines
        for m in msgs:
            if isinstance(m, mod.MAVLink_bad_data):
                st.bad(m)
            elif isinstance(m, mod.MAVLink_unknown):
                st.unknown += 1
            else:
                line = frame_json(m)
                st.decoded += 1
                if line[11] == "1":
                    st.v1 += 1
                elif m.get_header().incompat_flags & 1:
                    st.signed += 1
                lines.append(line)
        if len(lines) >= 4096:
            self.flush()

    def flush(self):
        if self.lines:
            self.out.write("\n".join(self.lines) + "\n")
            self.lines = []

    def finish(self):
        # Bytes left in pymavlink's buffer are an incomplete frame.
        left = self.mav.buf_len()
        if left:
            self.stats.bad_other += 1
            k = "truncated frame at end of input (%d bytes)" % left
            self.stats.reasons[k] = self.stats.reasons.get(k, 0) + 1
        self.flush()


def frame_length(data, i):
    """Length of the MAVLink frame starting at data[i], or None."""
    if i >= len(data):
        return None
    stx = data[i]
    if stx == 0xFE:
        return data[i + 1] + 8 if i + 1 < len(data) else None
    if stx == 0xFD:
        if i + 2 >= len(data):
            return None
        return data[i + 1] + 12 + (13 if data[i + 2] & 1 else 0)
    return None


def tlog_frames(data, stats):
    """Split a .tlog into frames: [8-byte BE timestamp][frame], repeated.
    On a record that does not start with a MAVLink start byte, skip one byte
    and retry (counted once per resync)."""
    i, n = 0, len(data)
    resyncing = False
    while i + 8 < n:
        length = frame_length(data, i + 8)
        if length is None:
            if not resyncing:
                stats.tlog_resync += 1
                resyncing = True
            i += 1
            continue
        resyncing = False
        yield data[i + 8:i + 8 + length]
        i += 8 + length
    if i < n:
        stats.bad_other += 1
        k = "truncated tlog record at end of input"
        stats.reasons[k] = stats.reasons.get(k, 0) + 1


def read_input(path, hexmode):
    if path == "-":
        data = sys.stdin.buffer.read()
    else:
        with open(path, "rb") as f:
            data = f.read()
    if hexmode:
        text = data.decode("ascii", errors="replace")
        tokens = text.split()
        try:
            data = bytes.fromhex("".join(t[2:] if t[:2].lower() == "0x" else t for t in tokens))
        except ValueError as e:
            sys.exit("decode_json: --hex input is not hex: %s" % e)
    return data


def main():
    global _json_str, _raw_chars
    ap = argparse.ArgumentParser(
        description="Decode MAVLink frames with pymavlink (fbwag dialect) and print one "
                    "JSON object per frame; a summary goes to stderr.",
        epilog="Example:\n  echo fd0c0000000101993a0040e201000101014642574147d933 | "
               "decode_json.py --hex",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("input", nargs="?", default="-", help="file to read (default: stdin)")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--hex", action="store_true", help="input is hex text; whitespace is ignored")
    g.add_argument("--tlog", action="store_true",
                   help="input is a .tlog: 8-byte big-endian timestamp before each frame")
    ap.add_argument("--sign-key", metavar="HEX64", default=None,
                    help="verify signatures with this key (pymavlink's check: a wrong "
                         "signature, or a timestamp not above the last one of its "
                         "(link, sysid, compid) stream, makes the frame an error); "
                         "unsigned frames are still decoded")
    ap.add_argument("--chars", choices=("pymavlink", "latin1"), default="pymavlink",
                    help="char fields: pymavlink's string (non-ASCII bytes become U+FFFD; "
                         "default) or every byte as U+0000..U+00FF")
    ap.add_argument("--strict", action="store_true", help="exit 1 if any error was counted")
    args = ap.parse_args()

    key = None
    if args.sign_key is not None:
        try:
            key = bytes.fromhex(args.sign_key)
        except ValueError:
            ap.error("--sign-key: not hex")
        if len(key) != 32:
            ap.error("--sign-key: need 64 hex digits")

    import json
    _json_str = json.JSONEncoder(ensure_ascii=True).encode
    _raw_chars = args.chars == "latin1"

    mod = fbwag_dialect.load("2.0")
    out = sys.stdout
    dec = Decoder(mod, out, key)
    data = read_input(args.input, args.hex)
    if args.tlog:
        for frame in tlog_frames(data, dec.stats):
            dec.feed(frame)
    else:
        chunk = 1 << 16
        for i in range(0, len(data), chunk):
            dec.feed(data[i:i + chunk])
    dec.finish()
    out.flush()
    print(dec.stats.summary(), file=sys.stderr)
    if args.strict and dec.stats.errors:
        sys.exit(1)


if __name__ == "__main__":
    try:
        main()
    except BrokenPipeError:
        # reader went away (e.g. "| head"): stop quietly, as cat does
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        sys.exit(141)
