"""The MAVProxy module's view of the delegation (fbwag_mavlink.monitor, and
the module around it), fed real MAVLink 2 frames of the FC and the
companion, packed and parsed by pymavlink: no MAVProxy needed."""
import importlib
import importlib.util
import os
import sys
import types
import unittest
from unittest import mock

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
# The package's source, ahead of any installed copy.
sys.path.insert(0, os.path.join(ROOT, "src"))

from fbwag_mavlink import monitor  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega  # noqa: E402


def load_checked_in_dialect():
    path = os.path.join(ROOT, "dialects", "v20", "fbwag.py")
    spec = importlib.util.spec_from_file_location("fbwag_checked_in_v20", path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


FBWAG = load_checked_in_dialect()
FC = (1, 1)
CC = (1, 191)
FBWA, CIRCLE, RTL = 5, 1, 11


class Clock:
    def __init__(self):
        self.now = 1000.0

    def __call__(self):
        return self.now


class Vehicle:
    """Frames as the FC and the companion send them, parsed as a ground
    station parses them (with the FBWAG dialect, or ArduPilot's, which does
    not know FBWAG_NOTICE)."""

    def __init__(self, gcs_dialect=FBWAG):
        self.clock = Clock()
        self.lines = []
        self.gcs_dialect = gcs_dialect
        self.monitor = monitor.DelegationMonitor(lambda: FC, say=self.lines.append,
                                                 clock=self.clock, dialect=FBWAG)
        self.senders = {ids: FBWAG.MAVLink(None, srcSystem=ids[0], srcComponent=ids[1])
                        for ids in (FC, CC)}

    def send(self, src, msg, at=None):
        if at is not None:
            self.clock.now = 1000.0 + at
        frame = msg.pack(self.senders[src])
        parsed = self.gcs_dialect.MAVLink(None).parse_buffer(bytearray(frame))
        assert parsed and len(parsed) == 1, parsed
        self.monitor.packet(parsed[0])

    def heartbeat(self, mode, at=None):
        self.send(FC, FBWAG.MAVLink_heartbeat_message(
            FBWAG.MAV_TYPE_FIXED_WING, FBWAG.MAV_AUTOPILOT_ARDUPILOTMEGA,
            FBWAG.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | FBWAG.MAV_MODE_FLAG_SAFETY_ARMED,
            mode, FBWAG.MAV_STATE_ACTIVE, 3), at)

    def notice(self, status, event, at=None, src=FC):
        self.send(src, FBWAG.MAVLink_fbwag_notice_message(src[0], src[1], status, b"FBWAG",
                                                          event), at)

    def text(self, text, at=None):
        self.send(FC, FBWAG.MAVLink_statustext_message(6, text.encode(), 0, 0), at)

    def output(self):
        return "\n".join(self.lines)

    def rc_lost(self, event=2000):
        """The FC starts a handshake at t = 0: CIRCLE, then notice 1."""
        self.heartbeat(FBWA, at=-1.0)
        self.heartbeat(CIRCLE, at=0.0)
        self.notice(1, event, at=0.0)


class RtlFallback(unittest.TestCase):
    def assert_rtl_said(self, v, reason):
        out = v.output()
        self.assertIn("fbwag: RTL: %s" % reason, out)
        self.assertNotIn("(RC in control)", out)
        self.assertNotIn("RC back", out)
        self.assertTrue(v.monitor.controller().startswith("FC (RTL: %s" % reason),
                        v.monitor.controller())

    def test_no_acknowledgement_in_5_s_is_an_rtl_without_the_companion(self):
        v = Vehicle()
        v.rc_lost()
        for at in (1.0, 2.0, 3.0):
            v.notice(1, 2000, at=at)
        # fc-sim's order: the mode (heartbeat at once), then notice 0.
        v.heartbeat(RTL, at=5.0)
        v.notice(0, 7000, at=5.0)
        self.assert_rtl_said(v, "companion did not take over: no acknowledgement accepted by the "
                                "FC in 5.0 s")
        self.assertIn("status 0 NORMAL (not delegated: FC in RTL, RC still lost", v.output())

    def test_notice_before_the_mode_says_neither_rc_nor_rtl_until_the_mode_does(self):
        v = Vehicle()
        v.rc_lost()
        v.notice(0, 7000, at=5.0)
        self.assertIn("status 0 NORMAL (delegation ended: the FC's next mode tells why)",
                      v.output())
        v.heartbeat(RTL, at=5.1)
        self.assert_rtl_said(v, "companion did not take over: no acknowledgement accepted by the "
                                "FC in 5.1 s")

    def test_an_early_fallback_is_a_declined_takeover(self):
        v = Vehicle()
        v.rc_lost()
        v.heartbeat(RTL, at=0.3)
        v.notice(0, 2300, at=0.3)
        # The companion acknowledges status 0; the FC's confirmation is no
        # hand-back to the pilot while RC is lost.
        v.text("FBWAG-ACK: RC has taken over!", at=0.4)
        self.assertIn("fbwag: the FC confirms the companion stopped (FC in RTL, RC still lost)",
                      v.output())
        self.assertNotIn("hand-back", v.output())
        self.assert_rtl_said(v, "companion did not take over: it declined (the FC fell back "
                                "0.3 s after the RC-loss notice")

    def test_a_module_loaded_during_the_handshake_does_not_guess(self):
        v = Vehicle()
        v.heartbeat(CIRCLE, at=2.5)  # its first heartbeat: the handshake began earlier
        v.notice(1, 2000, at=3.0)  # a retry
        v.heartbeat(RTL, at=5.0)
        self.assert_rtl_said(v, "companion did not take over, RC still lost")
        self.assertNotIn("declined", v.output())

    def test_the_companions_status_0_heard_is_a_declined_takeover(self):
        v = Vehicle()
        v.rc_lost()
        v.notice(0, 2000, at=4.6, src=CC)
        v.heartbeat(RTL, at=4.6)
        self.assertIn("the companion declines the takeover", v.output())
        self.assert_rtl_said(v, "companion did not take over: it declined, RC still lost")

    def test_companion_control_lost_is_said_as_such(self):
        v = Vehicle()
        v.rc_lost()
        v.notice(2, 2000, at=0.1, src=CC)  # the companion's ack: not a decline
        v.heartbeat(30, at=0.1)
        v.text("FBWAG-ACK: CC has taken over!", at=0.1)
        self.assertEqual(v.monitor.controller(), "companion computer")
        v.heartbeat(RTL, at=2.0)
        v.notice(0, 4000, at=2.0)
        self.assert_rtl_said(v, "companion control ended")

    def test_rc_back_after_rtl_is_the_pilot(self):
        v = Vehicle()
        v.rc_lost()
        v.heartbeat(RTL, at=5.0)
        v.notice(0, 7000, at=5.0)
        v.heartbeat(FBWA, at=8.0)
        self.assertIn("fbwag: FC mode RTL -> FBWA (RC back, pilot in control)", v.output())
        self.assertEqual(v.monitor.controller(), "pilot (RC)")

    def test_default_dialect_frames_are_decoded_too(self):
        # MAVProxy's default dialect: FBWAG_NOTICE arrives as UNKNOWN_15001.
        v = Vehicle(gcs_dialect=ardupilotmega)
        v.rc_lost()
        v.heartbeat(RTL, at=5.0)
        v.notice(0, 7000, at=5.0)
        self.assertIn("fbwag: <- FBWAG_NOTICE from 1/1: status 1 RC_LOST", v.output())
        self.assert_rtl_said(v, "companion did not take over: no acknowledgement accepted by the "
                                "FC in 5.0 s")


class HandBack(unittest.TestCase):
    def test_a_full_cycle_never_says_rtl(self):
        v = Vehicle()
        v.rc_lost()
        v.heartbeat(30, at=0.1)
        v.text("FBWAG-ACK: CC has taken over!", at=0.1)
        v.heartbeat(FBWA, at=3.0)
        v.notice(0, 5000, at=3.0)
        v.text("FBWAG-ACK: RC has taken over!", at=3.1)
        out = v.output()
        for line in ("fbwag: <- FBWAG_NOTICE from 1/1: status 1 RC_LOST (FC asks the companion), "
                     "event 2000",
                     "fbwag: FC mode CIRCLE -> FBWAG (companion control)",
                     "fbwag: takeover confirmed by the FC",
                     "fbwag: FC mode FBWAG -> FBWA (RC back, pilot in control)",
                     "fbwag: <- FBWAG_NOTICE from 1/1: status 0 NORMAL (RC in control), "
                     "event 5000",
                     "fbwag: hand-back confirmed by the FC"):
            self.assertIn(line, out)
        self.assertNotIn("RTL", out)
        self.assertEqual(v.monitor.controller(), "pilot (RC)")

    def test_rc_back_during_the_handshake_is_the_pilot(self):
        v = Vehicle()
        v.rc_lost()
        v.heartbeat(FBWA, at=2.0)
        v.notice(0, 4000, at=2.0)
        self.assertIn("fbwag: FC mode CIRCLE -> FBWA (RC back, pilot in control)", v.output())
        self.assertNotIn("RTL", v.output())

    def test_others_frames_are_ignored(self):
        v = Vehicle()
        v.heartbeat(FBWA)
        v.monitor.fc_ids = lambda: (2, 1)
        v.heartbeat(RTL, at=1.0)
        v.notice(1, 10, at=1.0)
        self.assertEqual(v.output(), "fbwag: FC mode FBWA")


class MavproxyModule(unittest.TestCase):
    """The MAVProxy module around the monitor, with MAVProxy's MPModule
    replaced by the few members the module uses."""

    def test_packets_reach_the_monitor_and_status_prints(self):
        class MPModule:
            def __init__(self, mpstate, name, description=None, public=False,
                         multi_vehicle=False):
                self.commands = {}
                self.target_system, self.target_component = FC

            def add_command(self, name, fn, description, completions=None):
                self.commands[name] = fn

        lib = types.ModuleType("MAVProxy.modules.lib")
        lib.mp_module = types.SimpleNamespace(MPModule=MPModule)
        stubs = {"MAVProxy": types.ModuleType("MAVProxy"),
                 "MAVProxy.modules": types.ModuleType("MAVProxy.modules"),
                 "MAVProxy.modules.lib": lib,
                 "MAVProxy.modules.lib.mp_module": lib.mp_module}
        with mock.patch.dict(sys.modules, stubs):
            sys.modules.pop("fbwag_mavlink.mavproxy_fbwag", None)
            module = importlib.import_module("fbwag_mavlink.mavproxy_fbwag").init(None)
            sys.modules.pop("fbwag_mavlink.mavproxy_fbwag", None)
        printed = []
        module.monitor.say = printed.append
        module.monitor.dialect = FBWAG
        v = Vehicle()
        v.monitor = module.monitor
        module.monitor.clock = v.clock
        v.rc_lost()
        v.heartbeat(RTL, at=5.0)
        with mock.patch("builtins.print", printed.append):
            module.commands["fbwag"](["status"])
        out = "\n".join(printed)
        self.assertIn("fbwag: RTL: companion did not take over", out)
        self.assertIn("fbwag: in control: FC (RTL: companion did not take over", out)


if __name__ == "__main__":
    unittest.main()
