//! What `fbwag fc-sim` serves a ground station, ArduPlane-like: commands
//! (each answered with a COMMAND_ACK), the parameter protocol, telemetry
//! rates (REQUEST_DATA_STREAM, MAV_CMD_SET_MESSAGE_INTERVAL), an empty
//! mission, TIMESYNC. This module reads requests out of frames and decides
//! answers, without I/O; the daemon (`fc.rs`) carries them out.
//!
//! The delegation protocol is not served here: who is trusted, which control
//! is applied and which mode the FC flies are the engine's. So a command
//! that would change who flies (a mode change, arming, RTL, a reposition, a
//! reboot) is refused with MAV_RESULT_DENIED: the engine has no input
//! through which a ground station could ask for a mode, and fc-sim does not
//! decide modes beside it.

use fbwag_delegation::Peer;
use fbwag_dialect::dialects::common::{MavCmd, MavDataStream, MavMissionType};
use fbwag_dialect::mavframe::Frame;
use fbwag_dialect::MessageView;
use std::collections::BTreeMap;
use std::time::Duration;

/// A request to a GCS service, read from one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// COMMAND_LONG or COMMAND_INT.
    Command(Command),
    /// The legacy SET_MODE message (acknowledged, as ArduPilot does, with a
    /// COMMAND_ACK whose `command` is 11, SET_MODE's message id).
    SetMode,
    ParamList,
    /// PARAM_REQUEST_READ: by index when it is not −1, else by name.
    ParamRead {
        index: i16,
        id: [u8; 16],
    },
    ParamSet {
        id: [u8; 16],
        value: f32,
    },
    /// REQUEST_DATA_STREAM: `rate_hz` 0 or `start` false stops the group.
    DataStream {
        stream: MavDataStream,
        rate_hz: u16,
        start: bool,
    },
    /// MISSION_REQUEST_LIST: answered with an empty list.
    MissionList(MavMissionType),
    /// MISSION_COUNT (an upload): refused, fc-sim flies no missions; but a
    /// count of 0 (MAVSDK's way to clear a mission) is accepted.
    MissionUpload {
        mission_type: MavMissionType,
        count: u16,
    },
    /// MISSION_REQUEST_INT / MISSION_REQUEST: an item of the (empty) list.
    MissionItem(MavMissionType),
    /// MISSION_CLEAR_ALL: the list is empty already.
    MissionClear(MavMissionType),
    /// TIMESYNC asking for our time (`tc1` 0); `ts1` is echoed.
    Timesync {
        ts1: i64,
    },
    /// SETUP_SIGNING: sign and verify with this key from now on (all
    /// zeros with a zero timestamp: no signing), as ArduPilot does.
    SetupSigning {
        key: [u8; 32],
        timestamp: u64,
    },
    /// REMOTE_LOG_BLOCK_STATUS: START or STOP of the log over MAVLink, or
    /// a block's ACK or NACK ([`super::remote_log`]).
    RemoteLog {
        seqno: u32,
        ack: bool,
    },
}

/// A command, from either COMMAND_LONG or COMMAND_INT.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    pub command: MavCmd,
    pub param1: f32,
    pub param2: f32,
    /// Came as COMMAND_INT.
    pub int: bool,
}

/// What a frame is to the GCS services.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Kind {
    /// A request addressed to this FC (or broadcast).
    Request(Request),
    /// A protocol message the engine handles (HEARTBEAT, FBWAG_NOTICE,
    /// control), an answer to us (MISSION_ACK, a TIMESYNC reply), or a
    /// request addressed to another system or component: nothing to serve.
    Other,
    /// A message fc-sim neither serves nor hands to the engine: logged and
    /// counted, so what ground stations ask and still miss is known.
    Unhandled,
}

/// Reads what `frame` asks of an FC with the ids `own`.
pub fn classify(f: Frame<&[u8]>, own: Peer) -> Kind {
    let Some(view) = MessageView::new(f.msg_id(), f.payload()) else {
        return Kind::Unhandled;
    };
    match request_of(&view) {
        Some((request, system, component))
            if (system == 0 || system == own.sysid)
                && (component == 0 || component == own.compid) =>
        {
            Kind::Request(request)
        }
        // A request for someone else (a router delivers everything).
        Some(_) => Kind::Other,
        None if handled_elsewhere(&view) => Kind::Other,
        None => Kind::Unhandled,
    }
}

/// The request in `view`, with the system and component it is addressed
/// to; `None` for anything that is not a request fc-sim serves.
fn request_of(view: &MessageView<'_>) -> Option<(Request, u8, u8)> {
    let command = |command, param1, param2, int| {
        Request::Command(Command {
            command,
            param1,
            param2,
            int,
        })
    };
    Some(match view {
        MessageView::CommandLong(c) => (
            command(c.command(), c.param1(), c.param2(), false),
            c.target_system(),
            c.target_component(),
        ),
        MessageView::CommandInt(c) => (
            command(c.command(), c.param1(), c.param2(), true),
            c.target_system(),
            c.target_component(),
        ),
        // SET_MODE has no component: every component of the system.
        MessageView::SetMode(m) => (Request::SetMode, m.target_system(), 0),
        MessageView::ParamRequestList(p) => {
            (Request::ParamList, p.target_system(), p.target_component())
        }
        MessageView::SetupSigning(s) => (
            Request::SetupSigning {
                key: s.secret_key().to_array(),
                timestamp: s.initial_timestamp(),
            },
            s.target_system(),
            s.target_component(),
        ),
        MessageView::ParamRequestRead(p) => (
            Request::ParamRead {
                index: p.param_index(),
                id: p.param_id().to_array(),
            },
            p.target_system(),
            p.target_component(),
        ),
        MessageView::ParamSet(p) => (
            Request::ParamSet {
                id: p.param_id().to_array(),
                value: p.param_value(),
            },
            p.target_system(),
            p.target_component(),
        ),
        MessageView::RequestDataStream(r) => (
            Request::DataStream {
                stream: r.req_stream_id(),
                rate_hz: r.req_message_rate(),
                start: r.start_stop() != 0,
            },
            r.target_system(),
            r.target_component(),
        ),
        _ => return mission_request_of(view),
    })
}

/// The mission protocol's requests, and TIMESYNC's (no target: to all).
fn mission_request_of(view: &MessageView<'_>) -> Option<(Request, u8, u8)> {
    Some(match view {
        MessageView::MissionRequestList(m) => (
            Request::MissionList(m.mission_type()),
            m.target_system(),
            m.target_component(),
        ),
        MessageView::MissionCount(m) => (
            Request::MissionUpload {
                mission_type: m.mission_type(),
                count: m.count(),
            },
            m.target_system(),
            m.target_component(),
        ),
        MessageView::MissionRequestInt(m) => (
            Request::MissionItem(m.mission_type()),
            m.target_system(),
            m.target_component(),
        ),
        MessageView::MissionRequest(m) => (
            Request::MissionItem(m.mission_type()),
            m.target_system(),
            m.target_component(),
        ),
        MessageView::MissionClearAll(m) => (
            Request::MissionClear(m.mission_type()),
            m.target_system(),
            m.target_component(),
        ),
        MessageView::Timesync(t) if t.tc1() == 0 => (Request::Timesync { ts1: t.ts1() }, 0, 0),
        MessageView::RemoteLogBlockStatus(r) => (
            Request::RemoteLog {
                seqno: r.seqno(),
                ack: r.status().0 != 0,
            },
            r.target_system(),
            r.target_component(),
        ),
        _ => return None,
    })
}

/// Messages that ask nothing of the GCS services: the protocol's (the
/// engine's), and answers to fc-sim (MISSION_ACK, a TIMESYNC reply).
fn handled_elsewhere(view: &MessageView<'_>) -> bool {
    matches!(
        view,
        MessageView::Heartbeat(_)
            | MessageView::FbwagNotice(_)
            | MessageView::RcChannelsOverride(_)
            | MessageView::SetAttitudeTarget(_)
            | MessageView::ManualControl(_)
            | MessageView::MissionAck(_)
            | MessageView::Timesync(_)
    )
}

/// The telemetry fc-sim sends, each at its own interval.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stream {
    Attitude,
    GlobalPosition,
    GpsRaw,
    VfrHud,
    SysStatus,
    RcChannels,
    ExtendedSysState,
    HomePosition,
    GpsGlobalOrigin,
}

impl Stream {
    pub const ALL: [Stream; 9] = [
        Stream::Attitude,
        Stream::GlobalPosition,
        Stream::GpsRaw,
        Stream::VfrHud,
        Stream::SysStatus,
        Stream::RcChannels,
        Stream::ExtendedSysState,
        Stream::HomePosition,
        Stream::GpsGlobalOrigin,
    ];

    /// The MAVLink message id it sends.
    pub fn msg_id(self) -> u32 {
        match self {
            Stream::Attitude => 30,
            Stream::GlobalPosition => 33,
            Stream::GpsRaw => 24,
            Stream::VfrHud => 74,
            Stream::SysStatus => 1,
            Stream::RcChannels => 65,
            Stream::ExtendedSysState => 245,
            Stream::HomePosition => 242,
            Stream::GpsGlobalOrigin => 49,
        }
    }

    pub fn by_msg_id(id: f32) -> Option<Stream> {
        Stream::ALL.into_iter().find(|s| s.msg_id() as f32 == id)
    }

    /// The rate before any request. HOME_POSITION goes every 5 s (and on
    /// request): ArduPilot sends it only on request and when home changes,
    /// but a ground station that subscribes late (MAVSDK's `home()`
    /// reports only new messages) would then never see it.
    pub fn default_interval(self) -> Option<Duration> {
        let ms = match self {
            Stream::Attitude => 100,
            Stream::GlobalPosition | Stream::VfrHud => 250,
            Stream::GpsRaw | Stream::SysStatus | Stream::RcChannels => 500,
            Stream::ExtendedSysState => 1000,
            Stream::HomePosition => 5000,
            // On request only, as ArduPilot's (the EKF origin: home here).
            Stream::GpsGlobalOrigin => return None,
        };
        Some(Duration::from_millis(ms))
    }

    /// Its REQUEST_DATA_STREAM group: ArduPlane's, except that
    /// EXTENDED_SYS_STATE (which ArduPlane sends only as a quadplane) is
    /// put with the status messages; HOME_POSITION and GPS_GLOBAL_ORIGIN
    /// are in no group.
    pub fn group(self) -> Option<MavDataStream> {
        Some(match self {
            Stream::SysStatus | Stream::GpsRaw | Stream::ExtendedSysState => {
                MavDataStream::EXTENDED_STATUS
            }
            Stream::GlobalPosition => MavDataStream::POSITION,
            Stream::RcChannels => MavDataStream::RC_CHANNELS,
            Stream::Attitude => MavDataStream::EXTRA1,
            Stream::VfrHud => MavDataStream::EXTRA2,
            Stream::HomePosition | Stream::GpsGlobalOrigin => return None,
        })
    }
}

impl Stream {
    /// The fastest it is sent, whatever a request asks: ATTITUDE at 50 Hz,
    /// the rest at 10 Hz. The delegation protocol's notices and heartbeats
    /// share the link: a ground station (anyone, without signing) must not
    /// be able to fill a 57600-baud radio with telemetry. At the caps all
    /// streams together are about 4 kB/s.
    pub fn min_interval(self) -> Duration {
        match self {
            Stream::Attitude => Duration::from_millis(20),
            _ => Duration::from_millis(100),
        }
    }
}

/// Each stream's interval (`None`: not sent) and next due time (µs of the
/// daemon's clock).
#[derive(Debug, Clone)]
pub struct Streams {
    interval: BTreeMap<Stream, Option<Duration>>,
    next: BTreeMap<Stream, u64>,
}

impl Streams {
    /// The default rates, every stream due at `now_us`.
    pub fn new(now_us: u64) -> Self {
        Streams {
            interval: Stream::ALL
                .into_iter()
                .map(|s| (s, s.default_interval()))
                .collect(),
            next: Stream::ALL.into_iter().map(|s| (s, now_us)).collect(),
        }
    }

    pub fn interval(&self, s: Stream) -> Option<Duration> {
        self.interval.get(&s).copied().flatten()
    }

    /// Sets one stream's interval (clamped to [`Stream::min_interval`]).
    /// The next message goes within the new interval (at once if the
    /// stream was off), never sooner than already due: repeating a request
    /// cannot make fc-sim send more.
    pub fn set(&mut self, s: Stream, interval: Option<Duration>, now_us: u64) {
        let was_on = self.interval(s).is_some();
        let interval = interval.map(|i| i.max(s.min_interval()));
        self.interval.insert(s, interval);
        let Some(interval) = interval else {
            return;
        };
        let within = now_us.saturating_add(interval.as_micros() as u64);
        let next = match self.next.get(&s) {
            Some(&due) if was_on => due.min(within),
            _ => now_us,
        };
        self.next.insert(s, next);
    }

    /// REQUEST_DATA_STREAM: every stream of `group` (all for ALL) at
    /// `rate_hz`, or off for `None`. False when the group has no stream here.
    pub fn set_group(&mut self, group: MavDataStream, rate_hz: Option<u16>, now_us: u64) -> bool {
        let interval = rate_hz.map(|hz| Duration::from_secs_f64(1.0 / f64::from(hz.max(1))));
        let members: Vec<Stream> = Stream::ALL
            .into_iter()
            .filter(|s| match s.group() {
                Some(g) => group == MavDataStream::ALL || g == group,
                None => false,
            })
            .collect();
        for s in &members {
            self.set(*s, interval, now_us);
        }
        !members.is_empty()
    }

    /// The streams due at `now_us`, each rescheduled one interval on (or
    /// from now, after a stall: no burst).
    pub fn due(&mut self, now_us: u64) -> Vec<Stream> {
        let mut due = Vec::new();
        for s in Stream::ALL {
            let (Some(interval), Some(next)) = (self.interval(s), self.next.get(&s).copied())
            else {
                continue;
            };
            if next > now_us {
                continue;
            }
            let step = interval.as_micros() as u64;
            let after = next.saturating_add(step);
            let after = if after > now_us {
                after
            } else {
                now_us.saturating_add(step)
            };
            self.next.insert(s, after);
            due.push(s);
        }
        due
    }

    /// When the next stream is due.
    pub fn poll_timeout(&self) -> Option<u64> {
        Stream::ALL
            .into_iter()
            .filter(|s| self.interval(*s).is_some())
            .filter_map(|s| self.next.get(&s).copied())
            .min()
    }
}

/// An interval asked by MAV_CMD_SET_MESSAGE_INTERVAL's param2 (µs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Interval {
    /// −1: stop.
    Off,
    /// 0: the default rate.
    Default,
    Every(Duration),
}

/// What a command asks fc-sim to do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Plan {
    /// Send AUTOPILOT_VERSION once.
    SendVersion,
    /// Send one message of this stream now.
    SendOnce(Stream),
    /// Change a stream's rate.
    SetInterval(Stream, Interval),
    /// Answer with MESSAGE_INTERVAL for this message id.
    GetInterval(u16),
    /// Done by accepting (e.g. the old capabilities request with param1 0).
    Nothing,
    /// Refused: it would change who flies, which the engine decides.
    Deny(&'static str),
    /// Known to fc-sim but with parameters it cannot take.
    Invalid,
    /// fc-sim does not implement it.
    Unsupported,
}

/// Why authority commands are denied, for the STATUSTEXT (≤ 50 chars).
pub const DENY_AUTHORITY: &str = "denied: the FBWAG engine decides modes";

/// The plan for `cmd`.
pub fn plan(cmd: &Command) -> Plan {
    match cmd.command {
        MavCmd::REQUEST_AUTOPILOT_CAPABILITIES if cmd.param1 == 1.0 => Plan::SendVersion,
        MavCmd::REQUEST_AUTOPILOT_CAPABILITIES => Plan::Nothing,
        MavCmd::REQUEST_MESSAGE => request_message(cmd.param1),
        MavCmd::GET_HOME_POSITION => Plan::SendOnce(Stream::HomePosition),
        MavCmd::SET_MESSAGE_INTERVAL => set_interval(cmd.param1, cmd.param2),
        MavCmd::GET_MESSAGE_INTERVAL => match message_id(cmd.param1) {
            Some(id) => Plan::GetInterval(id),
            None => Plan::Invalid,
        },
        c if changes_authority(c) => Plan::Deny(DENY_AUTHORITY),
        _ => Plan::Unsupported,
    }
}

/// Commands that would change who flies the aircraft or how: modes,
/// arming, navigation, termination, reboot.
fn changes_authority(c: MavCmd) -> bool {
    matches!(
        c,
        MavCmd::DO_SET_MODE
            | MavCmd::COMPONENT_ARM_DISARM
            | MavCmd::NAV_RETURN_TO_LAUNCH
            | MavCmd::NAV_LAND
            | MavCmd::NAV_TAKEOFF
            | MavCmd::NAV_LOITER_UNLIM
            | MavCmd::NAV_GUIDED_ENABLE
            | MavCmd::DO_REPOSITION
            | MavCmd::DO_PAUSE_CONTINUE
            | MavCmd::DO_LAND_START
            | MavCmd::DO_GO_AROUND
            | MavCmd::DO_FLIGHTTERMINATION
            | MavCmd::MISSION_START
            | MavCmd::OVERRIDE_GOTO
            | MavCmd::PREFLIGHT_REBOOT_SHUTDOWN
    )
}

/// A message id carried in a float parameter (whole, 0..65535).
fn message_id(p: f32) -> Option<u16> {
    (p.is_finite() && p.fract() == 0.0 && (0.0..=65535.0).contains(&p)).then_some(p as u16)
}

fn request_message(p1: f32) -> Plan {
    match message_id(p1) {
        Some(148) => Plan::SendVersion,
        Some(id) => match Stream::by_msg_id(f32::from(id)) {
            Some(s) => Plan::SendOnce(s),
            None => Plan::Unsupported,
        },
        None => Plan::Invalid,
    }
}

fn set_interval(p1: f32, p2: f32) -> Plan {
    let Some(id) = message_id(p1) else {
        return Plan::Invalid;
    };
    let Some(stream) = Stream::by_msg_id(f32::from(id)) else {
        // HEARTBEAT's rate is the protocol's (the FC's confirmation stream).
        return if id == 0 {
            Plan::Deny("denied: HEARTBEAT rate is the FBWAG engine's")
        } else {
            Plan::Unsupported
        };
    };
    let interval = match p2 {
        -1.0 => Interval::Off,
        0.0 => Interval::Default,
        v if v.is_finite() && v > 0.0 => Interval::Every(Duration::from_micros(v as u64)),
        _ => return Plan::Invalid,
    };
    Plan::SetInterval(stream, interval)
}

/// Counts of what fc-sim received and did not serve, by name (a command as
/// `COMMAND_LONG(519)`), bounded: past [`Unhandled::KINDS`] names the rest
/// is counted together, so crafted traffic cannot grow it without bound.
#[derive(Debug, Default, Clone)]
pub struct Unhandled {
    counts: BTreeMap<String, u64>,
    others: u64,
}

impl Unhandled {
    pub const KINDS: usize = 64;

    /// Counts one; true the first time this name is seen.
    pub fn note(&mut self, name: String) -> bool {
        if let Some(n) = self.counts.get_mut(&name) {
            *n = n.saturating_add(1);
            return false;
        }
        if self.counts.len() >= Self::KINDS {
            self.others = self.others.saturating_add(1);
            return false;
        }
        self.counts.insert(name, 1);
        true
    }

    /// (name, count), and the overflow as "(other)".
    pub fn summary(&self) -> Vec<(String, u64)> {
        let mut all: Vec<(String, u64)> =
            self.counts.iter().map(|(k, v)| (k.clone(), *v)).collect();
        if self.others > 0 {
            all.push(("(other)".into(), self.others));
        }
        all
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cmd(command: MavCmd, param1: f32, param2: f32) -> Command {
        Command {
            command,
            param1,
            param2,
            int: false,
        }
    }

    #[test]
    fn requests_mavsdk_sends_are_planned() {
        let p = |c, a, b| plan(&cmd(c, a, b));
        assert_eq!(p(MavCmd::REQUEST_MESSAGE, 148.0, 0.0), Plan::SendVersion);
        assert_eq!(
            p(MavCmd::REQUEST_MESSAGE, 242.0, 0.0),
            Plan::SendOnce(Stream::HomePosition)
        );
        assert_eq!(
            p(MavCmd::REQUEST_AUTOPILOT_CAPABILITIES, 1.0, 0.0),
            Plan::SendVersion
        );
        assert_eq!(
            p(MavCmd::SET_MESSAGE_INTERVAL, 33.0, 500_000.0),
            Plan::SetInterval(
                Stream::GlobalPosition,
                Interval::Every(Duration::from_millis(500))
            )
        );
        assert_eq!(
            p(MavCmd::SET_MESSAGE_INTERVAL, 33.0, -1.0),
            Plan::SetInterval(Stream::GlobalPosition, Interval::Off)
        );
    }

    #[test]
    fn authority_is_denied_unknown_is_unsupported_garbage_invalid() {
        let p = |c, a, b| plan(&cmd(c, a, b));
        assert_eq!(
            p(MavCmd::DO_SET_MODE, 1.0, 11.0),
            Plan::Deny(DENY_AUTHORITY)
        );
        assert_eq!(
            p(MavCmd::COMPONENT_ARM_DISARM, 0.0, 0.0),
            Plan::Deny(DENY_AUTHORITY)
        );
        assert!(matches!(
            p(MavCmd::SET_MESSAGE_INTERVAL, 0.0, 1e6),
            Plan::Deny(_)
        ));
        assert_eq!(p(MavCmd(31_000), 0.0, 0.0), Plan::Unsupported);
        assert_eq!(p(MavCmd::REQUEST_MESSAGE, 9999.0, 0.0), Plan::Unsupported);
        for bad in [f32::NAN, -3.0, 1.5, 1e9] {
            assert_eq!(p(MavCmd::REQUEST_MESSAGE, bad, 0.0), Plan::Invalid);
            assert_eq!(p(MavCmd::SET_MESSAGE_INTERVAL, bad, 1e6), Plan::Invalid);
        }
        for bad in [f32::NAN, f32::INFINITY, -3.0] {
            assert_eq!(p(MavCmd::SET_MESSAGE_INTERVAL, 33.0, bad), Plan::Invalid);
        }
        assert!(DENY_AUTHORITY.len() <= 50);
    }

    #[test]
    fn streams_follow_rates_and_never_burst() {
        let mut s = Streams::new(0);
        assert_eq!(s.due(0).len(), 8);
        assert_eq!(s.poll_timeout(), Some(100_000));
        // 1 Hz for everything, then position off.
        assert!(s.set_group(MavDataStream::ALL, Some(1), 0));
        s.set(Stream::GlobalPosition, None, 0);
        // All were just sent: the new rate does not send them again now.
        assert!(s.due(0).is_empty());
        let sent = s.due(1_000_000);
        assert!(!sent.contains(&Stream::GlobalPosition) && sent.len() == 6);
        // A long stall: each stream once (HOME_POSITION too, at its own
        // 5 s), not once per missed interval.
        assert_eq!(s.due(60_000_000).len(), 7);
        assert_eq!(s.poll_timeout(), Some(61_000_000));
        // Requests cannot go faster than the caps.
        s.set(Stream::Attitude, Some(Duration::from_micros(1)), 0);
        assert_eq!(
            s.interval(Stream::Attitude),
            Some(Duration::from_millis(20))
        );
        s.set_group(MavDataStream::ALL, Some(u16::MAX), 0);
        assert_eq!(s.interval(Stream::VfrHud), Some(Duration::from_millis(100)));
        assert!(!s.set_group(MavDataStream::RAW_SENSORS, Some(5), 0));
    }

    #[test]
    fn repeated_requests_do_not_multiply_messages() {
        let mut s = Streams::new(0);
        s.due(0);
        // A flood of the same request between two due times: nothing more
        // is sent than the rate says.
        let mut sent = 0;
        for t in (0..1_000_000).step_by(1000) {
            s.set_group(MavDataStream::EXTRA2, Some(10), t);
            sent += s.due(t).iter().filter(|&&x| x == Stream::VfrHud).count();
        }
        assert!(sent <= 11, "{sent} VFR_HUD in 1 s at 10 Hz");
        // Turning a stream on starts it at once.
        s.set(Stream::GlobalPosition, None, 0);
        s.set(Stream::GlobalPosition, Some(Duration::from_secs(1)), 5);
        assert!(s.due(5).contains(&Stream::GlobalPosition));
    }

    #[test]
    fn unhandled_counts_are_bounded() {
        let mut u = Unhandled::default();
        assert!(u.note("A".into()));
        assert!(!u.note("A".into()));
        for i in 0..1000 {
            u.note(format!("X{i}"));
        }
        let s = u.summary();
        assert_eq!(s.len(), Unhandled::KINDS + 1);
        assert_eq!(s[0], ("A".into(), 2));
        assert_eq!(s.last().unwrap().0, "(other)");
    }
}
