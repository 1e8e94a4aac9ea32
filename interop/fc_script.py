#!/usr/bin/env python3
"""A flight controller scripted with pymavlink 2.4.50 (FBWAG dialect) that
checks a companion's answers: RC lost (status 1) must be acknowledged with
status 2 echoing the event timestamp from the companion's ids, followed by an
RC_CHANNELS_OVERRIDE stream; RC back (status 0) must be acknowledged with
status 0 and the stream must stop. Prints one line per check; exit status 0
when all pass.

usage: fc_script.py CONNECTION [--cc-sysid 1] [--cc-compid 191]
"""
import argparse
import sys
import time

from common import MODE_FBWA, MODE_FBWAG, connect, fbwag, log

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("device")
p.add_argument("--cc-sysid", type=int, default=1)
p.add_argument("--cc-compid", type=int, default=191)
args = p.parse_args()

fc = connect(args.device, 1, 1)
failures = []


def check(ok, what):
    log("py-fc", ("PASS " if ok else "FAIL ") + what)
    if not ok:
        failures.append(what)


def heartbeat(mode):
    fc.mav.heartbeat_send(fbwag.MAV_TYPE_FIXED_WING, fbwag.MAV_AUTOPILOT_ARDUPILOTMEGA,
                          fbwag.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, mode, fbwag.MAV_STATE_ACTIVE)


def pump(seconds, mode, hb_period):
    """Heartbeats in `mode` while collecting the companion's frames."""
    got = []
    end = time.time() + seconds
    next_hb = 0.0
    while time.time() < end:
        if time.time() >= next_hb:
            heartbeat(mode)
            next_hb = time.time() + hb_period
        m = fc.recv_match(blocking=True, timeout=0.02)
        if m is not None and m.get_type() != "BAD_DATA":
            got.append(m)
    return got


# The companion sends first with udpout; with udpin we learn its address
# from its heartbeat.
frames = pump(2.0, MODE_FBWA, 0.2)
check(any(m.get_type() == "HEARTBEAT" and m.get_srcComponent() == args.cc_compid for m in frames),
      "companion heartbeat received")

event = 1234
fc.mav.fbwag_notice_send(1, 1, fbwag.FBWAG_FAILSAFE_STATUS_RC_LOST, b"FBWAG", event)
frames = pump(0.5, 1, 1.0)
acks = [m for m in frames if m.get_type() == "FBWAG_NOTICE"]
check(len(acks) >= 1 and acks[0].failsafe_status == fbwag.FBWAG_FAILSAFE_STATUS_CC_TAKEOVER_CONFIRMED,
      "status 1 answered with status 2")
check(bool(acks) and acks[0].timestamp == event, "the acknowledgement echoes the event timestamp")
check(bool(acks) and (acks[0].get_srcSystem(), acks[0].get_srcComponent()) == (args.cc_sysid, args.cc_compid),
      "the acknowledgement comes from the companion's ids")

# Confirm the takeover the way the FBWAG FC does; the stream must flow.
fc.mav.statustext_send(fbwag.MAV_SEVERITY_INFO, b"FBWAG-ACK: CC has taken over!", event & 0xFFFF, 0)
frames = pump(1.5, MODE_FBWAG, 0.2)
overrides = [m for m in frames if m.get_type() == "RC_CHANNELS_OVERRIDE"]
check(len(overrides) >= 20, "RC_CHANNELS_OVERRIDE streamed while delegated (%d in 1.5 s)" % len(overrides))
check(all(m.target_system == 1 and m.target_component == 1 for m in overrides), "overrides target the FC")

event0 = 5678
fc.mav.fbwag_notice_send(1, 1, fbwag.FBWAG_FAILSAFE_STATUS_NORMAL, b"FBWAG", event0)
frames = pump(0.5, MODE_FBWA, 0.2)
acks0 = [m for m in frames if m.get_type() == "FBWAG_NOTICE"]
check(any(m.failsafe_status == fbwag.FBWAG_FAILSAFE_STATUS_NORMAL and m.timestamp == event0 for m in acks0),
      "status 0 acknowledged with status 0, same timestamp")
frames = pump(0.7, MODE_FBWA, 0.2)
late = [m for m in frames if m.get_type() == "RC_CHANNELS_OVERRIDE"]
check(not late, "overrides stop after the hand-back (%d seen)" % len(late))

log("py-fc", "%d check(s) failed" % len(failures))
sys.exit(1 if failures else 0)
