#!/usr/bin/env python3
"""A scripted ArduPlane-like FC (pymavlink 2.4.50, FBWAG dialect) for finding
out what MAVSDK needs: it adds one kind of telemetry per phase, then walks
HEARTBEAT custom_mode through ArduPlane's plane modes and FBWAG (30), and
logs every message it receives (answering none of them).

Phases (each --phase seconds; the log says when each starts):
  1 heartbeat only (MAV_TYPE_FIXED_WING, MAV_AUTOPILOT_ARDUPILOTMEGA, FBWA)
  2 + SYS_STATUS: gyro, accelerometer, magnetometer, RC receiver, GPS and
      the pre-arm check present, enabled and healthy
  3 + GLOBAL_POSITION_INT
  4 + GPS_RAW_INT (3D fix, 10 satellites)
  5 + HOME_POSITION
  6 modes: custom_mode 0..26 and 30, --mode-step seconds each

usage: mavsdk_bench_fc.py udpout:127.0.0.1:14540 [--phase 4] [--mode-step 1.5]
Log lines: "<seconds> fc: ..." on stdout.
"""
import argparse
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from common import connect, fbwag  # noqa: E402

START = time.monotonic()
PLANE_MODES = list(range(0, 27)) + [30]
SENSORS = (fbwag.MAV_SYS_STATUS_SENSOR_3D_GYRO | fbwag.MAV_SYS_STATUS_SENSOR_3D_ACCEL
           | fbwag.MAV_SYS_STATUS_SENSOR_3D_MAG | fbwag.MAV_SYS_STATUS_SENSOR_RC_RECEIVER
           | fbwag.MAV_SYS_STATUS_SENSOR_GPS | fbwag.MAV_SYS_STATUS_PREARM_CHECK)
LAT, LON, ALT_MM = 504500000, 305200000, 180000  # Kyiv, 180 m


def log(text):
    print("%7.3f fc: %s" % (time.monotonic() - START, text), flush=True)


def describe(m):
    t = m.get_type()
    if t in ("COMMAND_LONG", "COMMAND_INT"):
        return "%s command=%d param1=%g param2=%g" % (t, m.command, m.param1, m.param2)
    if t == "PARAM_REQUEST_READ":
        return "%s %s index=%d" % (t, m.param_id, m.param_index)
    if t == "HEARTBEAT":
        return "HEARTBEAT type=%d autopilot=%d" % (m.type, m.autopilot)
    return t


class Fc:
    def __init__(self, device):
        self.link = connect(device, 1, 1)
        self.mode = 5
        self.phase = 1
        self.t0 = time.monotonic()

    def send(self):
        now = time.monotonic()
        ms = int((now - self.t0) * 1000) & 0xFFFFFFFF
        mav = self.link.mav
        mav.heartbeat_send(fbwag.MAV_TYPE_FIXED_WING, fbwag.MAV_AUTOPILOT_ARDUPILOTMEGA,
                           fbwag.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
                           | fbwag.MAV_MODE_FLAG_SAFETY_ARMED, self.mode,
                           fbwag.MAV_STATE_ACTIVE)
        if self.phase >= 2:
            mav.sys_status_send(SENSORS, SENSORS, SENSORS, 200, 12000, -1, -1, 0, 0, 0, 0, 0, 0)
        if self.phase >= 3:
            mav.global_position_int_send(ms, LAT, LON, ALT_MM, 50000, 1500, 0, 0, 9000)
        if self.phase >= 4:
            mav.gps_raw_int_send(ms * 1000, 3, LAT, LON, ALT_MM, 80, 120, 1500, 9000, 10)
        if self.phase >= 5:
            mav.home_position_send(LAT, LON, ALT_MM - 50000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0)

    def pump(self, seconds):
        """Send at 2 Hz and log what arrives, for `seconds`."""
        end = time.monotonic() + seconds
        next_send = 0.0
        while time.monotonic() < end:
            if time.monotonic() >= next_send:
                self.send()
                next_send = time.monotonic() + 0.5
            m = self.link.recv_match(blocking=True, timeout=0.05)
            if m is not None and m.get_type() != "BAD_DATA":
                log("<- %d/%d %s" % (m.get_srcSystem(), m.get_srcComponent(), describe(m)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("device", help="pymavlink connection string")
    ap.add_argument("--phase", type=float, default=4.0, help="seconds per telemetry phase")
    ap.add_argument("--mode-step", type=float, default=1.5, help="seconds per mode")
    args = ap.parse_args()
    fc = Fc(args.device)
    names = ["heartbeat only", "+ SYS_STATUS", "+ GLOBAL_POSITION_INT", "+ GPS_RAW_INT",
             "+ HOME_POSITION"]
    for i, name in enumerate(names, 1):
        fc.phase = i
        log("phase %d: %s" % (i, name))
        fc.pump(args.phase)
    for mode in PLANE_MODES:
        fc.mode = mode
        log("mode %d" % mode)
        fc.pump(args.mode_step)
    log("done")


if __name__ == "__main__":
    main()
