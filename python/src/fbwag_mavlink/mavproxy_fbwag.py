"""MAVProxy module `fbwag`: the RC-failsafe delegation state as MAVProxy sees
it from the flight controller, and the paper's `fbwag notice send`.

Installed with this package (`pip install ./python`), `module load fbwag`
finds it: the wheel places MAVProxy/modules/mavproxy_fbwag.py, which imports
this module (MAVProxy 1.8.75 tries MAVProxy.modules.mavproxy_NAME, then the
top-level module NAME). `module load fbwag_mavlink.mavproxy_fbwag` loads it
too, without that file.

Loading it also teaches MAVProxy (through pymavlink's ArduPlane mode table,
mavutil.mode_mapping_apm) the name of mode 30, FBWAG: MAVProxy's own prompt
and "Mode ..." announcements then say FBWAG instead of Mode(30). (The mode
cannot be chosen from MAVProxy: `mode FBWAG` is sent, and the FC denies it,
as it denies every mode change a ground station asks for.)

It prints, as they happen (fbwag_mavlink.monitor):
  - every FBWAG_NOTICE the FC sends (status 1: RC lost, asks the companion to
    take over; status 0: delegation ended), with its event timestamp and what
    it means given the FC's mode (RC in control, or RTL);
  - the FC's mode changes from its HEARTBEAT custom_mode, with the companion
    control mode (30, FBWAG) named, and on a fallback to RTL while RC is
    still lost a line "fbwag: RTL: <reason>" (the companion did not take
    over, declined, or lost control);
  - the FC's "FBWAG-ACK: ..." STATUSTEXTs (takeover and hand-back confirmed).

Commands:
  fbwag status                                  the delegation state
  fbwag notice send SYS COMP STATUS TIMESTAMP   send an FBWAG_NOTICE to the FC
                                                (fields system_id, component_id,
                                                failsafe_status, timestamp; text
                                                "FBWAG"), from MAVProxy's ids

Works with `--dialect=fbwag` and with MAVProxy's default dialect: there the
FBWAG_NOTICE frames arrive as UNKNOWN_15001 and are decoded, and sent, with
pymavlink.dialects.v20.fbwag. (But read docs/deployment.md before combining
the default dialect with a signing key.)
"""
from MAVProxy.modules.lib import mp_module

from fbwag_mavlink.monitor import DelegationMonitor, name_fbwag_mode


class FbwagModule(mp_module.MPModule):
    def __init__(self, mpstate):
        # multi_vehicle: MAVProxy hands other modules only its target
        # system's packets, judged by the parsed header, and a message its
        # dialect does not know (UNKNOWN_15001) has an empty header (0/0).
        # The monitor checks the sender itself, after decoding.
        super(FbwagModule, self).__init__(mpstate, "fbwag", "FBWAG RC-failsafe delegation",
                                          public=True, multi_vehicle=True)
        name_fbwag_mode()
        self.add_command("fbwag", self.cmd_fbwag, "FBWAG delegation: status, notice send",
                         ["status", "notice send"])
        self.monitor = DelegationMonitor(lambda: (self.target_system, self.target_component))
        self.notices_out = 0
        if self.monitor.dialect is None:
            print("fbwag: pymavlink.dialects.v20.fbwag is not installed "
                  "(pip install fbwag-mavlink): notices cannot be decoded or sent")

    def mavlink_packet(self, m):
        self.monitor.packet(m)

    def cmd_fbwag(self, args):
        if args[:1] == ["status"]:
            for line in self.monitor.status_lines((self.target_system, self.target_component),
                                                  self.notices_out):
                print(line)
        elif args[:2] == ["notice", "send"]:
            self.cmd_notice_send(args[2:])
        else:
            print("usage: fbwag <status|notice send SYS COMP STATUS TIMESTAMP>")

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
        dialect = self.monitor.dialect
        if dialect is None:
            print("fbwag: cannot send: pymavlink.dialects.v20.fbwag is not installed")
            return
        msg = dialect.MAVLink_fbwag_notice_message(sysid, compid, status, b"FBWAG", stamp)
        # MAVLink.send packs with the link's own sequence, ids and signing,
        # whichever dialect the link was opened with.
        self.master.mav.send(msg)
        self.notices_out += 1
        print("fbwag: -> FBWAG_NOTICE system_id %d component_id %d status %d timestamp %d" % (
            sysid, compid, status, stamp))


def init(mpstate):
    """MAVProxy's module entry point."""
    return FbwagModule(mpstate)
