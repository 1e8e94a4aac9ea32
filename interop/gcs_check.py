#!/usr/bin/env python3
"""Two pymavlink 2.4.50 programs on two links of a MAVLink router: a ground
station (255/190) and another onboard program (7/7). They send heartbeats,
the ground station addresses one COMMAND_LONG to 7/7 and one to 9/9 (a
system nobody has seen), and both record what reaches them. Prints one
JSON line at the end.

usage: gcs_check.py GCS_CONNECTION OTHER_CONNECTION [--seconds N]
"""
import argparse
import json
import time

from common import connect, fbwag

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("gcs")
parser.add_argument("other")
parser.add_argument("--seconds", type=float, default=8.0)
args = parser.parse_args()

gcs = connect(args.gcs, 255, 190)
other = connect(args.other, 7, 7)
seen = {"gcs": {}, "other": {}}
notices = []
commands_at_other = []
fc_modes = []
echoes = 0
overrides_at = {"gcs": 0, "other": 0}
sent_commands = False
start = time.time()
next_hb = 0.0
while time.time() - start < args.seconds:
    now = time.time()
    if now >= next_hb:
        for c in (gcs, other):
            c.mav.heartbeat_send(fbwag.MAV_TYPE_GCS, fbwag.MAV_AUTOPILOT_INVALID, 0, 0, fbwag.MAV_STATE_ACTIVE)
        next_hb = now + 0.5
    if not sent_commands and now - start > 2.0:
        # 7/7 has spoken by now: the router knows where it is.
        gcs.mav.command_long_send(7, 7, 31000, 0, 1, 0, 0, 0, 0, 0, 0)
        gcs.mav.command_long_send(9, 9, 31001, 0, 1, 0, 0, 0, 0, 0, 0)
        sent_commands = True
    for name, c in (("gcs", gcs), ("other", other)):
        m = c.recv_match(blocking=False)
        while m is not None:
            kind = m.get_type()
            src = (m.get_srcSystem(), m.get_srcComponent())
            seen[name][kind] = seen[name].get(kind, 0) + 1
            if name == "gcs" and src == (255, 190):
                echoes += 1
            if name == "gcs" and kind == "FBWAG_NOTICE":
                notices.append([src[0], src[1], m.failsafe_status])
            if name == "gcs" and kind == "HEARTBEAT" and src == (1, 1):
                if not fc_modes or fc_modes[-1] != m.custom_mode:
                    fc_modes.append(m.custom_mode)
            if name == "other" and kind == "COMMAND_LONG":
                commands_at_other.append([m.target_system, m.target_component, m.command])
            if kind == "RC_CHANNELS_OVERRIDE":
                overrides_at[name] += 1
            m = c.recv_match(blocking=False)
    time.sleep(0.005)
print(json.dumps({"notices": notices, "fc_modes": fc_modes, "commands_at_other": commands_at_other,
                  "echoes": echoes, "overrides_at": overrides_at, "seen": seen}), flush=True)
