#!/usr/bin/env python3
"""The paper's Fig. 8 companion listener, written anew on pymavlink 2.4.50
and its generated FBWAG dialect, completed so it can really fly the handover:
it echoes the event timestamp, streams RC_CHANNELS_OVERRIDE while in control
(wings level, cruise throttle) and hands back on status 0.

usage: cc_listener.py CONNECTION [--seconds N]
"""
import argparse
import time

from common import connect, fbwag, log

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("device", help="pymavlink connection string, e.g. udpin:127.0.0.1:14550")
parser.add_argument("--seconds", type=float, default=30.0, help="stop after this long")
args = parser.parse_args()

master = connect(args.device, 1, 191)
log("py-cc", "Waiting for heartbeat...")
master.wait_heartbeat(timeout=args.seconds)
log("py-cc", "Connected to MAVLink! (system %d, component %d)" % (master.target_system, master.target_component))

controlling = False
next_override = 0.0
takeovers = handbacks = 0
end = time.time() + args.seconds
while time.time() < end:
    msg = master.recv_match(type=["FBWAG_NOTICE", "STATUSTEXT"], blocking=True, timeout=0.02)
    if msg is not None and msg.get_type() == "FBWAG_NOTICE":
        if msg.failsafe_status == fbwag.FBWAG_FAILSAFE_STATUS_RC_LOST:
            log("py-cc", "RC FailSafe Triggered! Sending CC takeover confirmation... (event %d)" % msg.timestamp)
            master.mav.fbwag_notice_send(master.target_system, master.target_component,
                                         fbwag.FBWAG_FAILSAFE_STATUS_CC_TAKEOVER_CONFIRMED, b"FBWAG", msg.timestamp)
            if not controlling:
                takeovers += 1
            controlling = True
        elif msg.failsafe_status == fbwag.FBWAG_FAILSAFE_STATUS_NORMAL:
            log("py-cc", "RC back: stopping control, acknowledging (event %d)" % msg.timestamp)
            controlling = False
            master.mav.fbwag_notice_send(master.target_system, master.target_component,
                                         fbwag.FBWAG_FAILSAFE_STATUS_NORMAL, b"FBWAG", msg.timestamp)
            handbacks += 1
    elif msg is not None:
        log("py-cc", "STATUSTEXT %r" % msg.text)
    # Start sending control commands: the part Fig. 8 leaves out.
    if controlling and time.time() >= next_override:
        master.mav.rc_channels_override_send(master.target_system, master.target_component,
                                             1500, 1500, 1600, 1500, 0, 0, 0, 0)
        next_override = time.time() + 0.05
log("py-cc", "done: %d takeover(s), %d hand-back(s)" % (takeovers, handbacks))
