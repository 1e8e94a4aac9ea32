#!/usr/bin/env python3
"""MAVProxy module `fbwag`: the RC-failsafe delegation state as MAVProxy sees
it from the flight controller, and the paper's `fbwag notice send`.

Load it with `module load fbwag` once interop/install_dialect.py has installed
it into MAVProxy/modules/, or from a path: with interop/ on PYTHONPATH,
`module load mavproxy_fbwag` (MAVProxy tries MAVProxy.modules.mavproxy_NAME,
then NAME).

Loading it also teaches MAVProxy (through pymavlink's ArduPlane mode table,
mavutil.mode_mapping_apm) the name of mode 30, FBWAG: MAVProxy's own prompt
and "Mode ..." announcements then say FBWAG instead of Mode(30). (The mode
cannot be chosen from MAVProxy: `mode FBWAG` is sent, and the FC denies it,
as it denies every mode change a ground station asks for.)

It prints, as they happen:
  - every FBWAG_NOTICE the FC sends (status 1: RC lost, asks the companion to
    take over; status 0: RC back), with its event timestamp;
  - the FC's mode changes from its HEARTBEAT custom_mode, with the companion
    control mode (30, FBWAG) named;
  - the FC's "FBWAG-ACK: ..." STATUSTEXTs (takeover and hand-back confirmed).

Commands:
  fbwag status                                  the delegation state
  fbwag notice send SYS COMP STATUS TIMESTAMP   send an FBWAG_NOTICE to the FC
                                                (fields system_id, component_id,
                                                failsafe_status, timestamp; text
                                                "FBWAG"), from MAVProxy's ids

Works with `--dialect=fbwag` and with MAVProxy's default dialect: there the
FBWAG_NOTICE frames arrive as UNKNOWN_15001 and are decoded, and sent, with
the installed pymavlink.dialects.v20.fbwag. (But read docs/deployment.md
before combining the default dialect with a signing key.)
"""
import time

from MAVProxy.modules.lib import mp_module
from pymavlink import mavutil

FBWAG_NOTICE_ID = 15001
MODE_FBWAG = 30
STATUS_NAMES = {0: "NORMAL (RC in control)", 1: "RC_LOST (FC asks the companion)",
                2: "CC_TAKEOVER_CONFIRMED"}
ACK_PREFIX = "FBWAG-ACK:"


def mode_name(custom_mode):
    """ArduPlane's mode names, plus the companion-control mode."""
    if custom_mode == MODE_FBWAG:
        return "FBWAG"
    return mavutil.mode_mapping_apm.get(custom_mode, "Mode(%d)" % custom_mode)


def fbwag_bindings():
    """pymavlink's generated FBWAG dialect (wire 2.0), or None if absent."""
    try:
        from pymavlink.dialects.v20 import fbwag
    except ImportError:
        return None
    return fbwag


def name_fbwag_mode():
    """Add FBWAG (30) to pymavlink's ArduPlane mode names, unless the
    installed pymavlink already names 30 (then its name stays)."""
    mavutil.mode_mapping_apm.setdefault(MODE_FBWAG, "FBWAG")


class FbwagModule(mp_module.MPModule):
    def __init__(self, mpstate):
        # multi_vehicle: MAVProxy hands other modules only its target
        # system's packets, judged by the parsed header, and a message its
        # dialect does not know (UNKNOWN_15001) has an empty header (0/0).
        # This module checks the sender itself, after decoding.
        super(FbwagModule, self).__init__(mpstate, "fbwag", "FBWAG RC-failsafe delegation",
                                          public=True, multi_vehicle=True)
        name_fbwag_mode()
        self.add_command("fbwag", self.cmd_fbwag, "FBWAG delegation: status, notice send",
                         ["status", "notice send"])
        self.dialect = fbwag_bindings()
        # The bindings' own parser decodes UNKNOWN_15001 frames under another
        # dialect; it never sends, so it needs no file.
        self.decoder = self.dialect.MAVLink(None) if self.dialect is not None else None
        self.fc_mode = None
        self.fc_mode_since = None
        self.last_notice = None  # (status, event timestamp, wall time)
        self.last_ack = None  # (text, wall time)
        self.notices_in = 0
        self.notices_out = 0
        self.takeovers = 0
        self.handbacks = 0
        if self.dialect is None:
            print("fbwag: pymavlink.dialects.v20.fbwag is not installed "
                  "(run interop/install_dialect.py): notices cannot be decoded or sent")

    # --- packets from the FC ---------------------------------------------

    def mavlink_packet(self, m):
        mtype = m.get_type()
        if mtype == "HEARTBEAT":
            self.on_heartbeat(m)
        elif mtype == "FBWAG_NOTICE" and self.from_fc(m):
            self.on_notice(m)
        elif mtype == "UNKNOWN_%d" % FBWAG_NOTICE_ID:
            decoded = self.decode_unknown(m)
            if decoded is not None and self.from_fc(decoded):
                self.on_notice(decoded)
        elif mtype == "STATUSTEXT" and self.from_fc(m):
            self.on_statustext(m)

    def decode_unknown(self, m):
        """An FBWAG_NOTICE that MAVProxy's dialect does not know."""
        if self.decoder is None:
            return None
        try:
            return self.decoder.decode(bytearray(m.data))
        except Exception as e:  # pymavlink raises MAVError and struct errors
            print("fbwag: undecodable FBWAG_NOTICE: %s" % e)
            return None

    def from_fc(self, m):
        return m.get_srcSystem() == self.target_system and m.get_srcComponent() in (
            self.target_component, 1)

    def on_heartbeat(self, m):
        # Only the FC's heartbeat carries the vehicle's mode; a GCS or the
        # companion send their own.
        if not self.from_fc(m) or m.type == mavutil.mavlink.MAV_TYPE_GCS:
            return
        if m.autopilot == mavutil.mavlink.MAV_AUTOPILOT_INVALID:
            return
        if m.custom_mode == self.fc_mode:
            return
        before = self.fc_mode
        self.fc_mode = m.custom_mode
        self.fc_mode_since = time.time()
        if before is None:
            print("fbwag: FC mode %s" % mode_name(m.custom_mode))
            return
        print("fbwag: FC mode %s -> %s%s" % (mode_name(before), mode_name(m.custom_mode),
                                             self.mode_meaning(m.custom_mode)))

    @staticmethod
    def mode_meaning(mode):
        return {MODE_FBWAG: " (companion control)", 11: " (RTL)"}.get(mode, "")

    def on_notice(self, m):
        self.notices_in += 1
        self.last_notice = (m.failsafe_status, m.timestamp, time.time())
        print("fbwag: <- FBWAG_NOTICE from %d/%d: status %d %s, event %d" % (
            m.get_srcSystem(), m.get_srcComponent(), m.failsafe_status,
            STATUS_NAMES.get(m.failsafe_status, "(unknown status)"), m.timestamp))

    def on_statustext(self, m):
        text = m.text if isinstance(m.text, str) else m.text.decode("ascii", "replace")
        if not text.startswith(ACK_PREFIX):
            return
        self.last_ack = (text, time.time())
        if "CC has taken over" in text:
            self.takeovers += 1
            print("fbwag: takeover confirmed by the FC: %s" % text)
        elif "RC has taken over" in text:
            self.handbacks += 1
            print("fbwag: hand-back confirmed by the FC: %s" % text)
        else:
            print("fbwag: %s" % text)

    # --- commands --------------------------------------------------------

    def cmd_fbwag(self, args):
        usage = "usage: fbwag <status|notice send SYS COMP STATUS TIMESTAMP>"
        if args[:1] == ["status"]:
            self.cmd_status()
        elif args[:2] == ["notice", "send"]:
            self.cmd_notice_send(args[2:])
        else:
            print(usage)

    def controller(self):
        """Who flies, as far as the FC's mode and notices tell."""
        if self.fc_mode is None:
            return "unknown (no heartbeat from the FC yet)"
        if self.fc_mode == MODE_FBWAG:
            return "companion computer"
        if self.fc_mode == 11:
            return "FC (RTL)"
        if self.last_notice is not None and self.last_notice[0] == 1:
            return "FC (RC lost, waiting for the companion)"
        return "pilot (RC)"

    def cmd_status(self):
        now = time.time()
        if self.fc_mode is None:
            print("fbwag: FC: no heartbeat yet")
        else:
            print("fbwag: FC %d/%d mode %s (%d) for %.1f s" % (
                self.target_system, self.target_component, mode_name(self.fc_mode),
                self.fc_mode, now - self.fc_mode_since))
        print("fbwag: in control: %s" % self.controller())
        if self.last_notice is None:
            print("fbwag: no FBWAG_NOTICE from the FC yet")
        else:
            status, event, at = self.last_notice
            print("fbwag: last notice: status %d %s, event %d, %.1f s ago" % (
                status, STATUS_NAMES.get(status, ""), event, now - at))
        if self.last_ack is not None:
            print("fbwag: last FC confirmation: %r, %.1f s ago" % (self.last_ack[0],
                                                                  now - self.last_ack[1]))
        print("fbwag: notices in %d, sent %d; takeovers %d, hand-backs %d" % (
            self.notices_in, self.notices_out, self.takeovers, self.handbacks))

    def cmd_notice_send(self, args):
        usage = "usage: fbwag notice send SYS COMP STATUS TIMESTAMP"
        if len(args) != 4:
            print(usage)
            return
        try:
            sysid, compid, status, stamp = (int(a, 0) for a in args)
        except ValueError:
            print(usage)
            return
        if not (0 <= sysid <= 255 and 0 <= compid <= 255 and 0 <= status <= 255
                and 0 <= stamp <= 0xFFFFFFFF):
            print("fbwag: SYS, COMP, STATUS are 0..255, TIMESTAMP 0..4294967295")
            return
        if self.dialect is None:
            print("fbwag: cannot send: pymavlink.dialects.v20.fbwag is not installed")
            return
        msg = self.dialect.MAVLink_fbwag_notice_message(sysid, compid, status, b"FBWAG", stamp)
        # MAVLink.send packs with the link's own sequence, ids and signing,
        # whichever dialect the link was opened with.
        self.master.mav.send(msg)
        self.notices_out += 1
        print("fbwag: -> FBWAG_NOTICE system_id %d component_id %d status %d timestamp %d" % (
            sysid, compid, status, stamp))


def init(mpstate):
    """MAVProxy's module entry point."""
    return FbwagModule(mpstate)
