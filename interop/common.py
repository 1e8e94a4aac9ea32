"""Shared set-up for the interop scripts: pymavlink 2.4.50's own bindings of
message_definitions/fbwag.xml, installed as mavutil's dialect."""
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "conformance", "pymavlink"))

import fbwag_dialect  # noqa: E402
from pymavlink import mavutil  # noqa: E402

fbwag = fbwag_dialect.load("2.0")
# mavutil builds each connection's MAVLink object from its module-level
# `mavlink`: point it at the FBWAG bindings (what set_dialect does for the
# dialects pymavlink ships).
mavutil.mavlink = fbwag
mavutil.current_dialect = "fbwag"

MODE_FBWA, MODE_CIRCLE, MODE_RTL, MODE_FBWAG = 5, 1, 11, 30


def connect(device, sysid, compid):
    return mavutil.mavlink_connection(device, source_system=sysid, source_component=compid)


def log(who, text):
    print("%s: %s" % (who, text), flush=True)
