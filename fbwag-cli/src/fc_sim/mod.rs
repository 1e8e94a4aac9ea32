//! `fbwag fc-sim`: a flight-controller simulator speaking like ArduPlane.
//! It runs the FC's node (`fbwag_delegation::node::FcNode`: the policy of
//! its link around the FC engine: receiver sampling, the FC state machine, its
//! heartbeats and notices, the control it applies) with a receiver that
//! fails and returns on schedule, flies a kinematic fixed-wing model
//! ([`plane`]) in the mode the engine chose (the applied control
//! steers it in companion control), reports it as ArduPlane does
//! ([`telemetry`]), and serves ground stations ([`gcs`]):
//! commands, parameters ([`params`]), telemetry rates, an empty
//! mission.
//!
//! Ground-station services answer any sender the node lets through (with
//! `--require-signed` only frames whose signature verified, as ArduPilot
//! serves only signed frames on a link that requires signing).
//! They never decide who flies: commands that would (mode changes, arming,
//! RTL, reboot) are denied, and the parameters that decide it change only
//! while disarmed and the pilot flies (others at any time). The simulator
//! arms itself at `--arm-at` (at start by default); until then its RC
//! failsafe is not armed, as ArduPlane's is not on the ground.

use crate::live::net::{self, LinkOptions, Net, Node, Plan, Shell};
use crate::live::{mode_name, Clock, Events, Level, Limiter, Log};
use fbwag_delegation::control::Control;
use fbwag_delegation::engine::FcOutput;
use fbwag_delegation::fc::{Authority, FcConfig};
use fbwag_delegation::node::{FcNode, LinkSpec, Output, Role};
use fbwag_delegation::{mode, wire, Moment, Peer};
use fbwag_dialect::dialects::ardupilotmega::{MavRemoteLogDataBlockCommands, RemoteLogDataBlock};
use fbwag_dialect::dialects::minimal::{Heartbeat, MavModeFlag, MavState};
use fbwag_dialect::mavframe::router::Inbound;
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{Dialect, Message};
use gcs::{Stream, Streams, Unhandled};
use params::Settings;
use plane::{Guidance, Home, Plane, Sticks};
use remote_log::RemoteLog;
use serde_json::json;
use std::io;
use std::path::PathBuf;
use std::time::Duration;
use telemetry::Status;

pub mod dataflash;
pub mod gcs;
pub mod params;
pub mod plane;
pub mod remote_log;
mod serve;
pub mod signing;
pub mod telemetry;

/// The mode the pilot flies while the receiver works: an ArduPlane mode
/// flown with the sticks. The engine reports the pilot's authority as FBWA;
/// fc-sim reports this mode instead (in the HEARTBEAT, the log and the
/// events), so a ground station that cannot name FBWA (MAVSDK) can name the
/// pilot's mode. The other modes (CIRCLE, FBWAG, RTL) are the engine's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum PilotMode {
    Manual,
    Stabilize,
    Training,
    Acro,
    Fbwa,
    Fbwb,
    Cruise,
}

impl PilotMode {
    /// ArduPlane's HEARTBEAT `custom_mode`.
    pub fn custom_mode(self) -> u32 {
        match self {
            PilotMode::Manual => mode::MANUAL,
            PilotMode::Stabilize => 2,
            PilotMode::Training => 3,
            PilotMode::Acro => 4,
            PilotMode::Fbwa => mode::FBWA,
            PilotMode::Fbwb => 6,
            PilotMode::Cruise => 7,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            PilotMode::Manual => "MANUAL",
            PilotMode::Stabilize => "STABILIZE",
            PilotMode::Training => "TRAINING",
            PilotMode::Acro => "ACRO",
            PilotMode::Fbwa => "FBWA",
            PilotMode::Fbwb => "FBWB",
            PilotMode::Cruise => "CRUISE",
        }
    }
}

/// Settings of the flight-controller simulator.
pub struct FcOptions {
    pub link: LinkOptions,
    pub own: Peer,
    pub companion: Peer,
    /// When the receiver fails and comes back (seconds after start; no
    /// return: lost to the end), in order, not overlapping.
    pub outages: Vec<(f64, Option<f64>)>,
    pub duration: f64,
    pub require_signed: bool,
    pub events: Option<PathBuf>,
    /// Lines logged: this level and above.
    pub log_level: crate::live::Level,
    /// The text report's period (`None`: none), and the status events'.
    pub report: Option<std::time::Duration>,
    /// See `CcOptions::stop_on_signals`.
    pub stop_on_signals: bool,
    /// Where the model starts (and RTL returns to).
    pub home: Home,
    /// The pilot's flight mode.
    pub pilot_mode: PilotMode,
    /// When the FC arms (seconds after start; 0: armed from the start).
    pub arm_at: f64,
    /// Where a key SETUP_SIGNING sets is kept (`--signing-state PATH`:
    /// `PATH.key`).
    pub key_file: Option<PathBuf>,
}

/// What the FC simulator saw, for the demo and tests.
#[derive(Debug, Default, Clone)]
pub struct FcReport {
    /// (seconds, authority) at every change.
    pub timeline: Vec<(f64, Authority)>,
    /// Seconds from each receiver failure to companion control, for the
    /// failures that were handed over.
    pub handovers: Vec<f64>,
    /// Receiver failures.
    pub outages: usize,
    /// Seconds at which the receiver was last lost, while no handover has
    /// followed.
    pub rc_lost_at: Option<f64>,
}

/// The pilot's sticks (the receiver's channels 1–8 while it works):
/// centred, trim throttle.
const PILOT_CHANNELS: [u16; 8] = [1500, 1500, 1450, 1500, 1500, 1500, 1500, 1500];

/// The log's ATT records go this often (µs): ArduPilot logs attitude at
/// 25 Hz.
const LOG_EVERY_US: u64 = 40_000;

/// PARAM_VALUEs of a list request go out one per this interval: a flood of
/// list requests restarts the list instead of multiplying it.
const PARAM_LIST_INTERVAL: Duration = Duration::from_millis(10);

/// The parameter list being sent: next index and when.
#[derive(Debug, Clone, Copy)]
struct ParamCursor {
    index: usize,
    due: Moment,
    to: Peer,
}

struct Daemon {
    node: FcNode,
    /// The engine's configuration and the model's airspeed (parameters
    /// read and write them).
    settings: Settings,
    /// When the FC arms (seconds), and whether it has.
    arm_at: f64,
    armed: bool,
    /// Where a key SETUP_SIGNING sets is kept.
    key_file: Option<PathBuf>,
    own: Peer,
    outages: Vec<(f64, Option<f64>)>,
    duration: f64,
    receiver_ok: bool,
    /// Channels 1–8 of the control applied now (none outside companion
    /// control).
    applied: Option<[u16; 8]>,
    pilot_mode: PilotMode,
    plane: Plane,
    streams: Streams,
    param_list: Option<ParamCursor>,
    /// The DataFlash log over MAVLink, while a client takes it.
    flight_log: RemoteLog,
    /// When the log's next ATT record is due (µs; POS every fifth).
    log_due: u64,
    log_records: u64,
    unhandled: Unhandled,
    refused_unsigned: u64,
    /// STATUSTEXT replies (reasons of refusals): at most 5 per 10 s.
    texts: Limiter,
    gcs_log: Limiter,
    /// Trusted notices logged: [`crate::live::HEARD_PER_SECOND`].
    heard: Limiter,
    events: Events,
    report: FcReport,
    clock: Clock,
}

/// Runs the FC simulator for its duration.
pub fn run_fc(o: FcOptions, out: Box<dyn io::Write + Send>) -> io::Result<FcReport> {
    net::block_on(run(o, out))
}

async fn run(o: FcOptions, out: Box<dyn io::Write + Send>) -> io::Result<FcReport> {
    let clock = Clock::start();
    let mut log = Log::new(out, "fc", o.log_level, crate::live::Style::of_stdout());
    let cfg = FcConfig {
        own: o.own,
        companion: o.companion,
        require_signed: o.require_signed,
        ..FcConfig::default()
    };
    let invalid = |e| io::Error::new(io::ErrorKind::InvalidInput, e);
    let mut node = FcNode::new(cfg, clock.now()).map_err(invalid)?;
    let endpoint = o.link.endpoint.clone();
    let plan = Plan::main(&o.link, &mut log)?;
    let spec = LinkSpec::new(Role::Peer, net::answers(&endpoint, o.link.peer));
    node.add_link(0, spec).map_err(invalid)?;
    let events = Events::open(o.events.as_deref(), clock)?;
    log_start(&o, &endpoint, &mut log);
    let mut daemon = Daemon {
        node,
        settings: Settings {
            fc: cfg,
            cruise_airspeed: plane::CRUISE_AIRSPEED as f32,
        },
        arm_at: o.arm_at,
        armed: false,
        key_file: o.key_file.clone(),
        own: o.own,
        outages: o.outages,
        duration: o.duration,
        receiver_ok: true,
        applied: None,
        pilot_mode: o.pilot_mode,
        plane: Plane::new(o.home),
        streams: Streams::new(clock.now().0),
        param_list: None,
        flight_log: RemoteLog::default(),
        log_due: 0,
        log_records: 0,
        unhandled: Unhandled::default(),
        refused_unsigned: 0,
        texts: Limiter::new(5, Duration::from_secs(10)),
        gcs_log: Limiter::new(10, Duration::from_secs(10)),
        heard: Limiter::new(crate::live::HEARD_PER_SECOND, Duration::from_secs(1)),
        events,
        report: FcReport::default(),
        clock,
    };
    daemon
        .events
        .emit("mode", json!({"mode": o.pilot_mode.name()}));
    daemon.update_arming(&mut log);
    let router = plan
        .open(Shell::new(daemon, log, clock, 0, o.report))
        .await?;
    let Shell {
        node: mut daemon,
        mut log,
        ..
    } = net::run(router, o.stop_on_signals).await?;
    daemon.finish(&mut log);
    Ok(daemon.report)
}

/// The first line of the log: who the simulator is, and where.
fn log_start(o: &FcOptions, endpoint: &fbwag_dialect::Endpoint, log: &mut Log) {
    log.info(&format!(
        "ArduPlane simulator on {endpoint} as {}/{}; companion {}/{}{}; home {},{},{}",
        o.own.sysid,
        o.own.compid,
        o.companion.sysid,
        o.companion.compid,
        if o.require_signed {
            ", signed frames only"
        } else {
            ""
        },
        o.home.lat_deg,
        o.home.lon_deg,
        o.home.alt_m,
    ));
}

impl Daemon {
    /// The exit summary: the engine's counters (over every engine a
    /// parameter change replaced) and what was left unanswered.
    fn finish(&mut self, log: &mut Log) {
        let s = self.node.stats();
        let unhandled = self.unhandled.summary();
        if !unhandled.is_empty() {
            let list: Vec<String> = unhandled.iter().map(|(k, n)| format!("{k} x{n}")).collect();
            log.info(&format!("not served: {}", list.join(", ")));
        }
        let unhandled: serde_json::Map<String, serde_json::Value> =
            unhandled.into_iter().map(|(k, n)| (k, n.into())).collect();
        self.events.emit(
            "summary",
            json!({
                "trusted_frames": s.trusted_frames,
                "untrusted_frames": s.untrusted_frames,
                "untrusted_notices": s.untrusted_notices,
                "controls_applied": s.controls_applied,
                "controls_untrusted": s.controls_untrusted,
                "controls_misaddressed": s.controls_misaddressed,
                "controls_outside_companion": s.controls_outside_companion,
                "gcs_unsigned_refused": self.refused_unsigned,
                "dropped": net::drop_counts(self.node.drops()),
                "not_served": unhandled,
            }),
        );
    }

    /// The scheduled receiver state at `t` seconds.
    fn receiver_at(&self, t: f64) -> bool {
        !self
            .outages
            .iter()
            .any(|&(lost, back)| t >= lost && back.is_none_or(|b| t < b))
    }

    /// Arms at `arm_at`: from then on the engine sees the receiver's
    /// state (disarmed, the RC failsafe is not armed: it sees a working
    /// receiver).
    fn update_arming(&mut self, log: &mut Log) {
        if self.armed || self.clock.secs() < self.arm_at {
            return;
        }
        self.armed = true;
        self.node.set_receiver_ok(self.receiver_ok);
        log.notice("armed");
        self.events.emit("armed", json!({"armed": true}));
    }

    fn update_receiver(&mut self, log: &mut Log) {
        let t = self.clock.secs();
        let ok = self.receiver_at(t);
        if ok == self.receiver_ok {
            return;
        }
        self.receiver_ok = ok;
        self.node.set_receiver_ok(ok || !self.armed);
        if ok {
            log.notice("receiver: signal back");
        } else {
            self.report.rc_lost_at = Some(t);
            self.report.outages += 1;
            log.warn("receiver: signal lost (failsafe)");
        }
        self.events
            .emit("receiver", json!({"state": if ok { "ok" } else { "lost" }}));
    }

    /// When the scheduled receiver state (or arming) next changes.
    fn next_receiver_change(&self) -> Option<Moment> {
        let t = self.clock.secs();
        let arming = (!self.armed).then_some(self.arm_at);
        self.outages
            .iter()
            .flat_map(|&(lost, back)| [Some(lost), back])
            .chain([arming])
            .flatten()
            .filter(|&at| at > t)
            .map(|at| Moment((at * 1e6) as u64))
            .min()
    }

    fn drain(&mut self, net: &mut Net<'_, '_>) {
        while let Some(out) = self.node.poll_output() {
            match out {
                Output::Transmit {
                    links,
                    message: Message::Heartbeat(h),
                } => {
                    let h = self.heartbeat(h);
                    net.out
                        .send_message(links, self.own.sysid, self.own.compid, &h);
                }
                Output::Transmit { links, message } => {
                    log_sent(&message, net.log);
                    net.out
                        .send_message(links, self.own.sysid, self.own.compid, &message);
                }
                Output::TransmitTo {
                    link,
                    to,
                    message: Message::Heartbeat(h),
                } => {
                    let h = self.heartbeat(h);
                    net.out.send_message_to(
                        fbwag_dialect::mavframe::route::Links::only(link),
                        Some(to),
                        self.own.sysid,
                        self.own.compid,
                        &h,
                    );
                }
                Output::TransmitTo { .. } => {}
                Output::Peers { link, peers } => net.set_peers(link, peers),
                Output::Event(FcOutput::SetMode(a)) => self.mode_changed(a, net.log),
                Output::Event(FcOutput::ApplyControl { from, control }) => {
                    self.apply(from, &control)
                }
                Output::Event(FcOutput::ReleaseControl) => self.applied = None,
                // Sent through the node; and outputs added later.
                _ => {}
            }
        }
    }

    /// The HEARTBEAT the engine built, as ArduPlane would send it: the
    /// pilot's own mode while the pilot flies (the engine's number for
    /// that is FBWA), STANDBY and not armed until armed, CRITICAL while
    /// a failsafe (the lost receiver) is on. The companion reads only
    /// whether the mode is FBWAG, which this never changes.
    fn heartbeat(&self, mut h: Heartbeat) -> Heartbeat {
        if h.custom_mode == wire::custom_mode(Authority::Pilot) {
            h.custom_mode = self.pilot_mode.custom_mode();
        }
        if !self.armed {
            h.base_mode.remove(MavModeFlag::SAFETY_ARMED);
            h.system_status = MavState::STANDBY;
        } else if !self.receiver_ok {
            h.system_status = MavState::CRITICAL;
        }
        h
    }

    /// ArduPlane's number of the mode flown now, as the HEARTBEAT says.
    fn mode_number(&self) -> u8 {
        let number = match self.node.engine().authority() {
            Authority::Pilot => self.pilot_mode.custom_mode(),
            other => wire::custom_mode(other),
        };
        u8::try_from(number).unwrap_or(u8::MAX)
    }

    /// The log over MAVLink: the records due (ATT at 25 Hz, POS at 5 Hz),
    /// then the blocks to send, from the log's component.
    fn send_log(&mut self, now: Moment, net: &mut Net<'_, '_>) {
        if self.flight_log.client().is_none() {
            return;
        }
        while self.log_due <= now.0 {
            let s = self.plane.snapshot();
            let t = self.log_due;
            self.flight_log
                .record(&dataflash::att(t, s.roll, s.pitch, s.heading));
            if self.log_records % 5 == 0 {
                let pos = dataflash::pos(t, s.lat_deg, s.lon_deg, s.alt_m, s.height_m);
                self.flight_log.record(&pos);
            }
            self.log_records += 1;
            self.log_due += LOG_EVERY_US;
        }
        let Some(to) = self.flight_log.client() else {
            return;
        };
        for (seqno, data) in self.flight_log.poll(now.0) {
            let block = RemoteLogDataBlock {
                target_system: to.sysid,
                target_component: to.compid,
                seqno: MavRemoteLogDataBlockCommands(seqno),
                data,
            };
            net.send(self.own.sysid, remote_log::LOG_COMPID, &block);
        }
    }

    /// The name of the mode reported for authority `a`.
    fn reported_mode(&self, a: Authority) -> String {
        match a {
            Authority::Pilot => self.pilot_mode.name().into(),
            other => mode_name(wire::custom_mode(other)),
        }
    }

    fn mode_changed(&mut self, a: Authority, log: &mut Log) {
        let t = self.clock.secs();
        self.report.timeline.push((t, a));
        let mode = self.reported_mode(a);
        let why = match a {
            Authority::Pilot => "pilot in control",
            Authority::Handshake => "asking the companion to take over",
            Authority::Companion => "companion control",
            Authority::Rtl => "fallback",
        };
        log.notice(&format!("MODE CHANGE -> {mode} ({why})"));
        // ArduPilot's reasons: the radio (1), its failsafe (3), the GCS (2).
        let reason = match a {
            Authority::Pilot => 1,
            Authority::Handshake | Authority::Rtl => 3,
            Authority::Companion => 2,
        };
        let number = self.mode_number();
        let us = self.clock.now().0;
        self.flight_log.record(&dataflash::mode(us, number, reason));
        self.events.emit("mode", json!({"mode": mode}));
        if a == Authority::Companion {
            if let Some(lost) = self.report.rc_lost_at.take() {
                let ms = (t - lost) * 1000.0;
                self.report.handovers.push(t - lost);
                log.notice(&format!("handover {ms:.0} ms after the receiver failed"));
                self.events
                    .emit("handover", json!({"ms": ms.round() as u64}));
            }
        }
    }

    /// Applies trusted control: the channels the model flies by and the
    /// telemetry reports.
    fn apply(&mut self, from: fbwag_delegation::Origin, control: &Control) {
        let channels = channels_of(control);
        self.applied = Some(channels);
        self.events.emit(
            "control_applied",
            json!({
                "sysid": from.peer.sysid,
                "compid": from.peer.compid,
                "authenticated": from.authenticated,
                "message": control.name(),
                "channels": channels,
            }),
        );
    }

    /// Channels 1–8 in effect: the applied control's where it sets a
    /// channel (0 and 65535 leave it), the pilot's otherwise.
    fn channels(&self) -> [u16; 8] {
        let mut ch = PILOT_CHANNELS;
        if let Some(applied) = self.applied {
            for (c, a) in ch.iter_mut().zip(applied) {
                if a != 0 && a != u16::MAX {
                    *c = a;
                }
            }
        }
        ch
    }

    /// What flies the model in the engine's current mode.
    fn guidance(&self) -> Guidance {
        match self.node.engine().authority() {
            Authority::Pilot | Authority::Companion => {
                Guidance::Sticks(Sticks::from_channels(&self.channels()))
            }
            Authority::Handshake => Guidance::Circle,
            Authority::Rtl => Guidance::ReturnHome,
        }
    }

    /// Flies the model up to `now` under the guidance in force until now:
    /// called before anything that may change it.
    fn fly_to(&mut self, now: Moment) {
        let guidance = self.guidance();
        self.plane.advance_to(now.0 as f64 / 1e6, guidance);
    }

    fn status(&self, now: Moment) -> Status {
        Status {
            time_boot_ms: (now.0 / 1000) as u32,
            receiver_ok: self.receiver_ok,
            channels: self.channels(),
        }
    }

    fn send(&self, msg: &dyn Encode, net: &mut Net<'_, '_>) {
        net.send(self.own.sysid, self.own.compid, msg);
    }

    fn send_stream(&self, s: Stream, now: Moment, net: &mut Net<'_, '_>) {
        let msg = telemetry::build(s, &self.plane, &self.status(now));
        self.send(&msg, net);
    }

    fn telemetry(&mut self, now: Moment, net: &mut Net<'_, '_>) {
        for s in self.streams.due(now.0) {
            self.send_stream(s, now, net);
        }
        self.send_param_list(now, net);
    }
}

/// Logs the protocol's own messages as they go.
fn log_sent(msg: &Message, log: &mut Log) {
    match msg {
        Message::FbwagNotice(n) => log.info(&format!(
            "-> FBWAG_NOTICE status {} event {}",
            n.failsafe_status.0, n.timestamp
        )),
        Message::Statustext(t) => {
            let end = t.text.iter().position(|&b| b == 0).unwrap_or(t.text.len());
            log.info(&format!(
                "-> STATUSTEXT {:?}",
                String::from_utf8_lossy(&t.text[..end])
            ))
        }
        _ => {}
    }
}

/// Channels 1–8 a control message stands for: an RC override as it is;
/// MANUAL_CONTROL's axes mapped to aileron, elevator, throttle, rudder;
/// SET_ATTITUDE_TARGET's roll and thrust likewise.
fn channels_of(control: &Control) -> [u16; 8] {
    let pwm = |v: f32| (1500.0 + v.clamp(-1.0, 1.0) * 500.0) as u16;
    match control {
        Control::RcOverride(_) => control.rc_channels().unwrap_or_default(),
        Control::Manual(m) => [
            pwm(m.y as f32 / 1000.0),
            pwm(-(m.x as f32) / 1000.0),
            (1000.0 + (m.z as f32).clamp(0.0, 1000.0)) as u16,
            pwm(m.r as f32 / 1000.0),
            0,
            0,
            0,
            0,
        ],
        Control::Attitude(a) => {
            let [w, x, y, z] = a.q;
            let roll = (2.0 * (w * x + y * z)).atan2(1.0 - 2.0 * (x * x + y * y));
            let roll = if roll.is_finite() { roll } else { 0.0 };
            let thrust = if a.thrust.is_finite() { a.thrust } else { 0.0 };
            [
                pwm(roll / 0.78),
                1500,
                (1000.0 + thrust.clamp(0.0, 1.0) * 1000.0) as u16,
                1500,
                0,
                0,
                0,
                0,
            ]
        }
    }
}

impl Node for Daemon {
    fn poll_timeout(&self) -> Option<Moment> {
        [
            self.node.poll_timeout(),
            self.streams.poll_timeout().map(Moment),
            self.param_list.map(|c| c.due),
            self.next_receiver_change(),
            self.flight_log.poll_timeout().map(Moment),
            self.flight_log.client().map(|_| Moment(self.log_due)),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    fn handle_timeout(&mut self, now: Moment, net: &mut Net<'_, '_>) {
        self.fly_to(now);
        self.update_arming(net.log);
        self.update_receiver(net.log);
        self.node.handle_timeout(now);
        self.drain(net);
        self.telemetry(now, net);
        self.send_log(now, net);
    }

    fn handle_frame(&mut self, now: Moment, inbound: &Inbound<'_, Dialect>, net: &mut Net<'_, '_>) {
        self.fly_to(now);
        let fate = self.node.handle_frame(now, net::arrival(inbound));
        if let Some(reason) = fate.dropped {
            net.dropped(inbound, reason);
        }
        let frame = &inbound.frame;
        if fate.input && frame.frame().msg_id() == fbwag_dialect::FbwagNotice::ID {
            if let Some(Message::FbwagNotice(n)) = frame.message() {
                self.heard.log(net.log, Level::Info, "notices", || {
                    format!(
                        "<- FBWAG_NOTICE status {} event {}",
                        n.failsafe_status.0, n.timestamp
                    )
                });
            }
        }
        self.drain(net);
        if fate.dropped.is_none() {
            self.serve_frame(now, frame, fate.serve, net);
        }
    }

    fn link_reopened(&mut self, link: fbwag_dialect::mavframe::route::LinkId) {
        self.node.link_reopened(link);
    }

    fn report(&mut self, net: &mut Net<'_, '_>) {
        net.report_drops(self.node.drops(), &mut self.events);
    }

    fn bad_signature(
        &mut self,
        now: Moment,
        link: fbwag_dialect::mavframe::route::LinkId,
        source: std::net::SocketAddr,
        sender: Peer,
        net: &mut Net<'_, '_>,
    ) {
        self.node.handle_bad_signature(now, link, source, sender);
        self.drain(net);
    }

    fn status(&mut self, net: &mut Net<'_, '_>) {
        let mut more = serde_json::Map::new();
        let mode = self.reported_mode(self.node.engine().authority());
        more.insert("mode".into(), mode.into());
        more.insert("armed".into(), self.armed.into());
        let receiver = if self.receiver_ok { "ok" } else { "lost" };
        more.insert("receiver".into(), receiver.into());
        net.status(self.node.drops(), more, &mut self.events);
    }

    fn events(&mut self) -> &mut Events {
        &mut self.events
    }

    fn done(&self, clock: &Clock) -> bool {
        clock.secs() >= self.duration
    }
}
