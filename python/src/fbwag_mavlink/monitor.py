"""The RC-failsafe delegation as a ground station sees it from the flight
controller's frames, with no dependency on MAVProxy: the MAVProxy module
`fbwag` (fbwag_mavlink.mavproxy_fbwag) feeds it every packet it receives and
prints what it says.

What the FC sends (message_definitions/fbwag.xml, docs/delegation.md):
  - FBWAG_NOTICE status 1 when RC is lost (one event, retried), then
    status 0 whenever delegation ends: RC is back, or the FC fell back to
    RTL (the companion did not take over, declined, or lost control).
    Status 0 alone does not say which: the FC's mode does.
  - HEARTBEAT custom_mode: CIRCLE while it waits for the companion,
    30 (FBWAG) in companion control, 11 (RTL) after a fallback, the pilot's
    mode when RC is back. It is sent at once on a mode change.
  - STATUSTEXT "FBWAG-ACK: CC has taken over!" / "FBWAG-ACK: RC has taken
    over!" confirming a takeover and a hand-back.
"""
import time

from pymavlink import mavutil

FBWAG_NOTICE_ID = 15001
MODE_FBWAG = 30
MODE_RTL = 11
MODE_CIRCLE = 1  # the FC's mode while it waits for the companion
STATUS_NORMAL = 0
STATUS_RC_LOST = 1
STATUS_CC_TAKEOVER_CONFIRMED = 2
STATUS_NAMES = {STATUS_NORMAL: "NORMAL", STATUS_RC_LOST: "RC_LOST",
                STATUS_CC_TAKEOVER_CONFIRMED: "CC_TAKEOVER_CONFIRMED"}
ACK_PREFIX = "FBWAG-ACK:"
# The FC's default handshake timeout (first notice to RTL without an
# acknowledgement) is 5 s; a fallback well before it means the companion
# answered the RC-loss notice with status 0 (it declined).
DECLINED_BEFORE_S = 4.0

# Where the delegation stands, as the FC's frames tell it.
PILOT = "pilot"
HANDSHAKE = "handshake"
COMPANION = "companion"
RTL = "rtl"


def mode_name(custom_mode):
    """ArduPlane's mode names, plus the companion-control mode."""
    if custom_mode == MODE_FBWAG:
        return "FBWAG"
    return mavutil.mode_mapping_apm.get(custom_mode, "Mode(%d)" % custom_mode)


def name_fbwag_mode():
    """Add FBWAG (30) to pymavlink's ArduPlane mode names, unless the
    installed pymavlink already names 30 (then its name stays)."""
    mavutil.mode_mapping_apm.setdefault(MODE_FBWAG, "FBWAG")


def fbwag_bindings():
    """pymavlink's generated FBWAG dialect (wire 2.0), or None if absent."""
    try:
        from pymavlink.dialects.v20 import fbwag
    except ImportError:
        return None
    return fbwag


class DelegationMonitor:
    """Follows the delegation from the FC's packets and says what happens.

    fc_ids() gives the FC's (system, component) as the ground station
    targets it; say(text) prints a line; clock() is wall time in seconds;
    dialect is the FBWAG bindings (wire 2.0), by default the installed ones.
    """

    def __init__(self, fc_ids, say=print, clock=time.time, dialect=None):
        self.fc_ids = fc_ids
        self.say = say
        self.clock = clock
        self.dialect = dialect if dialect is not None else fbwag_bindings()
        # The bindings' own parser decodes UNKNOWN_15001 frames under another
        # dialect; it never sends, so it needs no file.
        self.decoder = self.dialect.MAVLink(None) if self.dialect is not None else None
        self.fc_mode = None
        self.fc_mode_since = None
        self.phase = PILOT
        self.rc_lost_event = None  # FC timestamp of the current RC-loss event
        self.rc_lost_at = None  # wall time its first notice arrived
        # Whether that notice was the event's first (not a retry heard by a
        # module loaded during the handshake): only then can the time to
        # the fallback tell a declined takeover from the handshake timeout.
        self.rc_lost_from_start = False
        self.circle_since = None  # a change into CIRCLE seen, when
        self.declined_event = None  # RC-loss event the companion answered with 0
        self.rtl_reason = None
        self.last_notice = None  # (status, event, wall time, meaning)
        self.last_ack = None  # (text, wall time)
        self.notices_in = 0
        self.takeovers = 0
        self.handbacks = 0
        self.fallbacks = 0

    # --- packets ----------------------------------------------------------

    def packet(self, m):
        mtype = m.get_type()
        if mtype == "UNKNOWN_%d" % FBWAG_NOTICE_ID:
            m = self.decode_unknown(m)
            if m is None:
                return
            mtype = m.get_type()
        if mtype == "HEARTBEAT":
            self.on_heartbeat(m)
        elif mtype == "FBWAG_NOTICE":
            if self.from_fc(m):
                self.on_fc_notice(m)
            elif m.get_srcSystem() == self.fc_ids()[0]:
                self.on_companion_notice(m)
        elif mtype == "STATUSTEXT" and self.from_fc(m):
            self.on_statustext(m)

    def decode_unknown(self, m):
        """An FBWAG_NOTICE that the ground station's dialect does not know."""
        if self.decoder is None:
            return None
        try:
            return self.decoder.decode(bytearray(m.data))
        except Exception as e:  # pymavlink raises MAVError and struct errors
            self.say("fbwag: undecodable FBWAG_NOTICE: %s" % e)
            return None

    def from_fc(self, m):
        system, component = self.fc_ids()
        return m.get_srcSystem() == system and m.get_srcComponent() in (component, 1)

    def on_heartbeat(self, m):
        # Only the FC's heartbeat carries the vehicle's mode; a GCS or the
        # companion send their own.
        if not self.from_fc(m) or m.type == mavutil.mavlink.MAV_TYPE_GCS:
            return
        if m.autopilot == mavutil.mavlink.MAV_AUTOPILOT_INVALID:
            return
        if m.custom_mode == self.fc_mode:
            return
        before, self.fc_mode = self.fc_mode, m.custom_mode
        self.fc_mode_since = self.clock()
        if before is None:
            self.say("fbwag: FC mode %s" % mode_name(m.custom_mode))
            return
        meaning = self.mode_changed(m.custom_mode)
        self.say("fbwag: FC mode %s -> %s%s" % (mode_name(before), mode_name(m.custom_mode),
                                                meaning))
        if self.phase == RTL and m.custom_mode == MODE_RTL:
            self.say("fbwag: RTL: %s" % self.rtl_reason)

    def mode_changed(self, mode):
        """Moves the phase on a new FC mode; the words for the change."""
        if mode == MODE_FBWAG:
            self.phase = COMPANION
            return " (companion control)"
        if mode == MODE_RTL:
            if self.phase in (HANDSHAKE, COMPANION):
                # RC is still lost (it would be the pilot's mode otherwise):
                # the delegation failed or ended without the pilot.
                self.rtl_reason = self.why_rtl()
                self.phase = RTL
                self.fallbacks += 1
                return " (RTL, RC still lost)"
            return " (RTL)"
        if mode == MODE_CIRCLE:
            self.circle_since = self.clock()
        if self.phase == HANDSHAKE and mode == MODE_CIRCLE:
            return " (RC lost, waiting for the companion)"
        if self.phase != PILOT:
            # Out of the handshake, companion control or RTL into any other
            # mode: the FC does that only when the receiver is back.
            self.phase = PILOT
            return " (RC back, pilot in control)"
        return ""

    def why_rtl(self):
        """Why the FC fell back, from what was seen of the current event."""
        declined = self.declined_event is not None and self.declined_event == self.rc_lost_event
        if self.phase == COMPANION:
            if declined:
                return "the companion gave control back, RC still lost"
            return ("companion control ended (the companion gave control back, or its "
                    "control or heartbeat stopped), RC still lost")
        if declined:
            return "companion did not take over: it declined, RC still lost"
        if not self.rc_lost_from_start:
            return "companion did not take over, RC still lost"
        waited = self.clock() - self.rc_lost_at
        if waited < DECLINED_BEFORE_S:
            return ("companion did not take over: it declined (the FC fell back %.1f s after "
                    "the RC-loss notice, before its 5 s handshake timeout), RC still lost"
                    % waited)
        return ("companion did not take over: no acknowledgement accepted by the FC in "
                "%.1f s, RC still lost" % waited)

    def on_fc_notice(self, m):
        self.notices_in += 1
        status, event = m.failsafe_status, m.timestamp
        if status == STATUS_RC_LOST and event != self.rc_lost_event:
            self.rc_lost_event = event
            self.rc_lost_at = self.clock()
            # The FC enters CIRCLE with the event's first notice: either the
            # change comes after this notice, or it was just seen.
            self.rc_lost_from_start = self.fc_mode != MODE_CIRCLE or (
                self.circle_since is not None and self.rc_lost_at - self.circle_since < 1.0)
            self.rtl_reason = None
            if self.phase != COMPANION:
                self.phase = HANDSHAKE
        meaning = self.notice_meaning(status)
        self.last_notice = (status, event, self.clock(), meaning)
        self.say("fbwag: <- FBWAG_NOTICE from %d/%d: status %d %s, event %d" % (
            m.get_srcSystem(), m.get_srcComponent(), status, meaning, event))

    def notice_meaning(self, status):
        """The words for a notice of the FC, given where the delegation stands."""
        name = STATUS_NAMES.get(status, "(unknown status)")
        if status == STATUS_RC_LOST:
            return name + " (FC asks the companion)"
        if status != STATUS_NORMAL:
            return name
        if self.phase == RTL:
            # The reason was said with the mode change ("fbwag: RTL: ...").
            return name + " (not delegated: FC in RTL, RC still lost)"
        if self.phase in (HANDSHAKE, COMPANION):
            # Sent before the heartbeat with the FC's new mode: RC back or
            # RTL, which that heartbeat tells.
            return name + " (delegation ended: the FC's next mode tells why)"
        if self.fc_mode == MODE_RTL:
            return name + " (not delegated: FC in RTL)"
        return name + " (RC in control)"

    def on_companion_notice(self, m):
        """A notice of another component of the vehicle (the companion's
        answers, when this ground station hears them)."""
        status, event = m.failsafe_status, m.timestamp
        if status == STATUS_NORMAL and event == self.rc_lost_event and self.phase in (
                HANDSHAKE, COMPANION):
            self.declined_event = event
            what = "declines the takeover" if self.phase == HANDSHAKE else "gives control back"
            self.say("fbwag: <- FBWAG_NOTICE from %d/%d: status 0, event %d: the companion %s"
                     % (m.get_srcSystem(), m.get_srcComponent(), event, what))

    def on_statustext(self, m):
        text = m.text if isinstance(m.text, str) else m.text.decode("ascii", "replace")
        if not text.startswith(ACK_PREFIX):
            return
        self.last_ack = (text, self.clock())
        if "CC has taken over" in text:
            self.takeovers += 1
            self.phase = COMPANION
            self.say("fbwag: takeover confirmed by the FC: %s" % text)
        elif "RC has taken over" in text and self.phase == RTL:
            # The FC's answer to the companion's acknowledgement of status 0:
            # the companion has stopped, but RC is still lost.
            self.say("fbwag: the FC confirms the companion stopped (FC in RTL, RC still lost): %s"
                     % text)
        elif "RC has taken over" in text:
            self.handbacks += 1
            self.say("fbwag: hand-back confirmed by the FC: %s" % text)
        else:
            self.say("fbwag: %s" % text)

    # --- state --------------------------------------------------------------

    def controller(self):
        """Who flies, as far as the FC's mode and notices tell."""
        if self.fc_mode is None:
            return "unknown (no heartbeat from the FC yet)"
        if self.phase == COMPANION or self.fc_mode == MODE_FBWAG:
            return "companion computer"
        if self.phase == RTL:
            return "FC (RTL: %s)" % self.rtl_reason
        if self.fc_mode == MODE_RTL:
            return "FC (RTL)"
        if self.phase == HANDSHAKE:
            return "FC (RC lost, waiting for the companion)"
        return "pilot (RC)"

    def status_lines(self, target, notices_out):
        """`fbwag status`: the delegation state, one line each."""
        now = self.clock()
        lines = []
        if self.fc_mode is None:
            lines.append("fbwag: FC: no heartbeat yet")
        else:
            lines.append("fbwag: FC %d/%d mode %s (%d) for %.1f s" % (
                target[0], target[1], mode_name(self.fc_mode), self.fc_mode,
                now - self.fc_mode_since))
        lines.append("fbwag: in control: %s" % self.controller())
        if self.last_notice is None:
            lines.append("fbwag: no FBWAG_NOTICE from the FC yet")
        else:
            status, event, at, meaning = self.last_notice
            lines.append("fbwag: last notice: status %d %s, event %d, %.1f s ago" % (
                status, meaning, event, now - at))
        if self.last_ack is not None:
            lines.append("fbwag: last FC confirmation: %r, %.1f s ago" % (
                self.last_ack[0], now - self.last_ack[1]))
        lines.append("fbwag: notices in %d, sent %d; takeovers %d, hand-backs %d, RTL fallbacks %d"
                     % (self.notices_in, notices_out, self.takeovers, self.handbacks,
                        self.fallbacks))
        return lines
