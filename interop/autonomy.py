#!/usr/bin/env python3
"""A user's autonomy program behind `fbwag cc --autonomy`, in the style of
the paper's Fig. 8, on pymavlink 2.4.50: it knows nothing of keys or
handshakes. It watches what the companion relays (the FC's HEARTBEAT mode
and FBWAG_NOTICEs, the companion's own notices) to know when the companion
holds control, and streams its own RC_CHANNELS_OVERRIDE (aileron CHAN1,
a value no built-in controller uses) at 20 Hz the whole time: the
companion must let it through only while it holds control.

Prints one JSON line at the end: what it sent and saw.

usage: autonomy.py CONNECTION [--seconds N] [--chan1 PWM] [--sysid N --compid N]
                   [--source-port PORT] [--attitude-hz HZ]

With udpout, --source-port sends from that port, the address `fbwag cc
--autonomy-peer` pins (pymavlink's udpout sends from a port of the
system's choice otherwise). --attitude-hz asks the FC for ATTITUDE at that
rate (MAV_CMD_SET_MESSAGE_INTERVAL, which the companion signs on) with
each heartbeat, and the JSON line says the most heard within one second
("attitude_hz").
"""
import argparse
import json
import time

from common import MODE_FBWAG, connect, fbwag, log

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("device", help="pymavlink connection string, e.g. udpout:127.0.0.1:14560")
parser.add_argument("--seconds", type=float, default=10.0)
parser.add_argument("--chan1", type=int, default=1234)
parser.add_argument("--sysid", type=int, default=1)
parser.add_argument("--compid", type=int, default=196)
parser.add_argument("--source-port", type=int, default=None)
parser.add_argument("--attitude-hz", type=float, default=None)
args = parser.parse_args()

link = connect(args.device, args.sysid, args.compid)
if args.source_port is not None:
    # Before the first send, which would bind a port of the system's choice.
    link.port.bind((link.destination_addr[0], args.source_port))
# Say we are here at once (udpout: the companion learns our address from
# it), then that we are up: a test starts its FC's timeline after this line.
link.mav.heartbeat_send(fbwag.MAV_TYPE_ONBOARD_CONTROLLER, fbwag.MAV_AUTOPILOT_INVALID, 0, 0,
                        fbwag.MAV_STATE_ACTIVE)
log("autonomy", "up")
sent = 0
in_control_sent = 0
modes = []
notices = []
in_control = False
attitudes = []
next_override = 0.0
next_heartbeat = time.time() + 1.0
end = time.time() + args.seconds
while time.time() < end:
    now = time.time()
    if now >= next_heartbeat:
        # Say we are here (udpout: the companion learns our address).
        link.mav.heartbeat_send(fbwag.MAV_TYPE_ONBOARD_CONTROLLER, fbwag.MAV_AUTOPILOT_INVALID, 0, 0,
                                fbwag.MAV_STATE_ACTIVE)
        if args.attitude_hz:
            link.mav.command_long_send(1, 1, fbwag.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                       fbwag.MAVLINK_MSG_ID_ATTITUDE, 1e6 / args.attitude_hz,
                                       0, 0, 0, 0, 0)
        next_heartbeat = now + 1.0
    if now >= next_override:
        # Whatever ids we write, the companion re-addresses to its FC.
        link.mav.rc_channels_override_send(0, 0, args.chan1, 1500, 1550, 1500, 0, 0, 0, 0)
        sent += 1
        if in_control:
            in_control_sent += 1
        next_override = now + 0.05
    msg = link.recv_match(blocking=True, timeout=0.01)
    if msg is None or msg.get_type() == "BAD_DATA":
        continue
    kind = msg.get_type()
    src = (msg.get_srcSystem(), msg.get_srcComponent())
    if kind == "ATTITUDE" and src == (1, 1):
        attitudes.append(now)
    if kind == "HEARTBEAT" and src == (1, 1):
        if not modes or modes[-1] != msg.custom_mode:
            modes.append(msg.custom_mode)
            log("autonomy", "FC mode %d" % msg.custom_mode)
        in_control = msg.custom_mode == MODE_FBWAG
    elif kind == "FBWAG_NOTICE":
        notices.append([src[0], src[1], msg.failsafe_status, msg.timestamp])
        log("autonomy", "FBWAG_NOTICE from %d/%d status %d" % (src[0], src[1], msg.failsafe_status))
# The most ATTITUDE frames heard within one second of the run.
busiest, first = 0, 0
for i, t in enumerate(attitudes):
    while attitudes[first] < t - 1.0:
        first += 1
    busiest = max(busiest, i - first + 1)
print(json.dumps({"sent": sent, "sent_in_control": in_control_sent, "modes": modes, "notices": notices,
                  "attitude_hz": busiest}),
      flush=True)
