#!/usr/bin/env python3
"""A logging UDP relay for MAVLink: sits between a peer that sends first
(udpout) and one that listens (udpin), forwards every datagram unchanged both
ways, and logs each frame it carries: direction, source system/component,
message id and name, sequence, signed or not.

    peer A (udpout:127.0.0.1:LISTEN) -> tap -> peer B (udpin:127.0.0.1:TO)

Replies from B go back to the last address A sent from. Frames are parsed
with pymavlink's generated FBWAG dialect (ardupilotmega + FBWAG_NOTICE);
ids it does not know are logged as UNKNOWN_<id> and forwarded all the same.

usage: mavlink_tap.py --listen 127.0.0.1:14540 --to 127.0.0.1:14541
                      [--seconds N] [--log FILE] [--summary]
One log line per frame:  <seconds> <a>b|b>a> <sys>/<comp> <id> <NAME> seq=<n> signed=<0|1>
--summary prints, at the end, each (direction, message) with its count.
"""
import argparse
import collections
import os
import select
import socket
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "conformance",
                                "pymavlink"))
import fbwag_dialect  # noqa: E402

SIGNED = 0x01


def addr(text):
    host, port = text.rsplit(":", 1)
    return host, int(port)


class Side:
    """One direction's parser: frames are logged, never altered."""

    def __init__(self, mav, label, log, counts):
        self.parser = mav.MAVLink(None)
        self.parser.robust_parsing = True
        self.label = label
        self.log = log
        self.counts = counts

    def feed(self, data, t):
        try:
            msgs = self.parser.parse_buffer(data) or []
        except Exception as e:  # a broken frame must not stop the relay
            self.log.write("%.3f %s parse error: %s\n" % (t, self.label, e))
            return
        for m in msgs:
            if m.get_type() == "BAD_DATA":
                continue
            sysid, compid, msgid, seq, signed = header(m.get_msgbuf())
            self.counts[(self.label, m.get_type(), msgid)] += 1
            self.log.write("%.3f %s %d/%d %d %s seq=%d signed=%d%s\n" % (
                t, self.label, sysid, compid, msgid, m.get_type(), seq, int(signed), detail(m)))


def detail(m):
    """What a request asks for: the command and its first two parameters
    (for MAV_CMD_SET_MESSAGE_INTERVAL and MAV_CMD_REQUEST_MESSAGE: the
    message id, and the interval), the parameter or the stream."""
    t = m.get_type()
    if t in ("COMMAND_LONG", "COMMAND_INT"):
        return " command=%d param1=%g param2=%g target=%d/%d" % (
            m.command, m.param1, m.param2, m.target_system, m.target_component)
    if t == "PARAM_REQUEST_READ":
        return " param_id=%s index=%d" % (m.param_id, m.param_index)
    if t == "REQUEST_DATA_STREAM":
        return " stream=%d rate=%d start=%d" % (m.req_stream_id, m.req_message_rate, m.start_stop)
    if t in ("MISSION_REQUEST_LIST", "MISSION_REQUEST_INT"):
        return " mission_type=%d" % m.mission_type
    if t == "HEARTBEAT":
        return " type=%d autopilot=%d custom_mode=%d" % (m.type, m.autopilot, m.custom_mode)
    return ""


def header(raw):
    """(sysid, compid, msgid, seq, signed) read from the frame's own bytes
    (pymavlink's UNKNOWN messages carry no parsed header)."""
    if raw[0] == 0xFD:
        return raw[5], raw[6], raw[7] | raw[8] << 8 | raw[9] << 16, raw[4], bool(raw[2] & SIGNED)
    return raw[3], raw[4], raw[5], raw[2], False


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--listen", type=addr, required=True, help="HOST:PORT peer A sends to")
    p.add_argument("--to", type=addr, required=True, help="HOST:PORT peer B listens on")
    p.add_argument("--seconds", type=float, default=60.0, help="stop after this long")
    p.add_argument("--log", help="log file (default: stdout)")
    p.add_argument("--summary", action="store_true", help="print message counts at the end")
    args = p.parse_args()

    mav = fbwag_dialect.load("2.0")
    log = open(args.log, "w", buffering=1) if args.log else sys.stdout
    counts = collections.Counter()
    a_to_b = Side(mav, "a>b", log, counts)
    b_to_a = Side(mav, "b>a", log, counts)
    front = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    front.bind(args.listen)
    back = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    back.bind((args.to[0], 0))
    print("tap: relaying %s:%d -> %s:%d" % (args.listen + args.to), file=sys.stderr, flush=True)
    peer_a = None
    start = time.monotonic()
    end = start + args.seconds
    while time.monotonic() < end:
        ready, _, _ = select.select([front, back], [], [], 0.1)
        for s in ready:
            data, src = s.recvfrom(65535)
            t = time.monotonic() - start
            if s is front:
                peer_a = src
                back.sendto(data, args.to)
                a_to_b.feed(data, t)
            elif peer_a is not None:
                front.sendto(data, peer_a)
                b_to_a.feed(data, t)
    if args.summary:
        for (label, name, msgid), n in sorted(counts.items()):
            print("summary %s %d %s %d" % (label, msgid, name, n))


if __name__ == "__main__":
    main()
