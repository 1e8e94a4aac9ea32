//! `fbwag fc-sim`: a flight-controller simulator speaking like ArduPlane.
//! It runs the FC engine (receiver sampling, the FC state machine, its
//! heartbeats and notices, the control it applies) with a receiver that
//! fails and returns on schedule, and sends ArduPlane-like telemetry in
//! which the applied control shows.

use super::link::{self, Link, LinkOptions, Node};
use super::{mode_name, Clock, Events, Log};
use fbwag_delegation::control::Control;
use fbwag_delegation::engine::{FcEngine, FcOutput, Verdict};
use fbwag_delegation::fc::{Authority, FcConfig};
use fbwag_delegation::{wire, Instant, Peer};
use fbwag_dialect::dialects::common::{Attitude, RcChannels, SysStatus};
use fbwag_dialect::{Message, ReceivedFrame};
use serde_json::json;
use std::io;
use std::path::PathBuf;
use std::time::Duration;

/// Settings of the flight-controller simulator.
pub struct FcOptions {
    pub link: LinkOptions,
    pub own: Peer,
    pub companion: Peer,
    pub rc_loss_at: Option<f64>,
    pub rc_back_at: Option<f64>,
    pub duration: f64,
    pub require_signed: bool,
    pub events: Option<PathBuf>,
}

/// What the FC simulator saw, for the demo and tests.
#[derive(Debug, Default, Clone)]
pub struct FcReport {
    /// (seconds, authority) at every change.
    pub timeline: Vec<(f64, Authority)>,
    /// Seconds from RC loss (receiver) to companion control.
    pub handover: Option<f64>,
    /// Seconds at which the receiver was lost.
    pub rc_lost_at: Option<f64>,
}

const ATTITUDE_PERIOD: Duration = Duration::from_millis(100);
const SLOW_PERIOD: Duration = Duration::from_millis(500);

struct Daemon {
    engine: FcEngine,
    own: Peer,
    rc_loss_at: Option<f64>,
    rc_back_at: Option<f64>,
    duration: f64,
    receiver_ok: bool,
    /// Channels 1–8 of the control applied now (none outside companion
    /// control).
    applied: Option<[u16; 8]>,
    roll: f32,
    next_attitude: Instant,
    next_slow: Instant,
    events: Events,
    report: FcReport,
    clock: Clock,
}

/// Runs the FC simulator for its duration.
pub fn run_fc(o: FcOptions, out: Box<dyn io::Write + Send>) -> io::Result<FcReport> {
    let clock = Clock::start();
    let mut log = Log::new(out, clock, "fc");
    let cfg = FcConfig {
        own: o.own,
        companion: o.companion,
        require_signed: o.require_signed,
        ..FcConfig::default()
    };
    let engine = FcEngine::new(cfg, clock.now())
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
    let endpoint = o.link.endpoint.clone();
    let mut link = Link::open(o.link, &mut log)?;
    let events = Events::open(o.events.as_deref(), clock)?;
    log.line(&format!(
        "ArduPlane simulator on {endpoint} as {}/{}; companion {}/{}{}",
        o.own.sysid,
        o.own.compid,
        o.companion.sysid,
        o.companion.compid,
        if o.require_signed {
            ", signed frames only"
        } else {
            ""
        }
    ));
    let mut daemon = Daemon {
        engine,
        own: o.own,
        rc_loss_at: o.rc_loss_at,
        rc_back_at: o.rc_back_at,
        duration: o.duration,
        receiver_ok: true,
        applied: None,
        roll: 0.0,
        next_attitude: clock.now(),
        next_slow: clock.now(),
        events,
        report: FcReport::default(),
        clock,
    };
    daemon.events.emit(
        "mode",
        json!({"mode": mode_name(wire::custom_mode(Authority::Pilot))}),
    );
    link::run(&mut daemon, &mut link, &clock, &mut log);
    let s = *daemon.engine.stats();
    daemon.events.emit(
        "summary",
        json!({
            "trusted_frames": s.trusted_frames,
            "untrusted_frames": s.untrusted_frames,
            "untrusted_notices": s.untrusted_notices,
            "controls_applied": s.controls_applied,
            "controls_untrusted": s.controls_untrusted,
            "controls_misaddressed": s.controls_misaddressed,
            "controls_outside_companion": s.controls_outside_companion,
        }),
    );
    Ok(daemon.report)
}

impl Daemon {
    /// The scheduled receiver state at `t` seconds.
    fn receiver_at(&self, t: f64) -> bool {
        !(self.rc_loss_at.is_some_and(|l| t >= l) && self.rc_back_at.is_none_or(|b| t < b))
    }

    fn update_receiver(&mut self, log: &mut Log) {
        let t = self.clock.secs();
        let ok = self.receiver_at(t);
        if ok == self.receiver_ok {
            return;
        }
        self.receiver_ok = ok;
        self.engine.set_receiver_ok(ok);
        if ok {
            log.line("receiver: signal back");
        } else {
            self.report.rc_lost_at = Some(t);
            log.line("receiver: signal lost (failsafe)");
        }
        self.events
            .emit("receiver", json!({"state": if ok { "ok" } else { "lost" }}));
    }

    /// When the scheduled receiver state next changes.
    fn next_receiver_change(&self) -> Option<Instant> {
        let t = self.clock.secs();
        [self.rc_loss_at, self.rc_back_at]
            .into_iter()
            .flatten()
            .filter(|&at| at > t)
            .map(|at| Instant((at * 1e6) as u64))
            .min()
    }

    fn drain(&mut self, link: &mut Link, log: &mut Log) {
        while let Some(out) = self.engine.poll_output() {
            match out {
                FcOutput::Transmit(msg) => {
                    match &msg {
                        Message::FbwagNotice(n) => log.line(&format!(
                            "-> FBWAG_NOTICE status {} event {}",
                            n.failsafe_status.0, n.timestamp
                        )),
                        Message::Statustext(t) => {
                            let end = t.text.iter().position(|&b| b == 0).unwrap_or(t.text.len());
                            log.line(&format!(
                                "-> STATUSTEXT {:?}",
                                String::from_utf8_lossy(&t.text[..end])
                            ))
                        }
                        _ => {}
                    }
                    link.send(self.own.sysid, self.own.compid, &msg, log);
                }
                FcOutput::SetMode(a) => self.mode_changed(a, log),
                FcOutput::ApplyControl { from, control } => self.apply(from, &control),
                FcOutput::ReleaseControl => self.applied = None,
            }
        }
    }

    fn mode_changed(&mut self, a: Authority, log: &mut Log) {
        let t = self.clock.secs();
        self.report.timeline.push((t, a));
        let mode = mode_name(wire::custom_mode(a));
        let why = match a {
            Authority::Pilot => "pilot in control",
            Authority::Handshake => "asking the companion to take over",
            Authority::Companion => "companion control",
            Authority::Rtl => "fallback",
        };
        log.line(&format!("MODE CHANGE -> {mode} ({why})"));
        self.events.emit("mode", json!({"mode": mode}));
        if a == Authority::Companion && self.report.handover.is_none() {
            if let Some(lost) = self.report.rc_lost_at {
                let ms = (t - lost) * 1000.0;
                self.report.handover = Some(t - lost);
                log.line(&format!("handover {ms:.0} ms after the receiver failed"));
                self.events
                    .emit("handover", json!({"ms": ms.round() as u64}));
            }
        }
    }

    /// Applies trusted control: the channels the telemetry and the roll
    /// model follow.
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

    fn telemetry(&mut self, now: Instant, link: &mut Link, log: &mut Log) {
        let t = self.clock.secs();
        if now >= self.next_attitude {
            self.next_attitude = now + ATTITUDE_PERIOD;
            // Roll follows the aileron channel in companion control.
            let target = match self.applied {
                Some(c) if c[0] != 0 && c[0] != u16::MAX => (c[0] as f32 - 1500.0) / 500.0 * 0.78,
                _ => 0.0,
            };
            self.roll += (target - self.roll) * 0.2;
            let att = Attitude {
                time_boot_ms: (t * 1000.0) as u32,
                roll: self.roll,
                pitch: 0.02,
                yaw: (t as f32 * 0.05) % std::f32::consts::TAU,
                ..Default::default()
            };
            link.send(self.own.sysid, self.own.compid, &att, log);
        }
        if now >= self.next_slow {
            self.next_slow = now + SLOW_PERIOD;
            let pilot = [1500, 1500, 1400, 1500, 1500, 1500, 1500, 1500];
            let ch = self.applied.unwrap_or(pilot);
            let pick = |i: usize| {
                if ch[i] == 0 || ch[i] == u16::MAX {
                    pilot[i]
                } else {
                    ch[i]
                }
            };
            let rc = RcChannels {
                time_boot_ms: (t * 1000.0) as u32,
                chancount: 8,
                chan1_raw: pick(0),
                chan2_raw: pick(1),
                chan3_raw: pick(2),
                chan4_raw: pick(3),
                chan5_raw: pick(4),
                chan6_raw: pick(5),
                chan7_raw: pick(6),
                chan8_raw: pick(7),
                // 0–254 (254: 100 %); 255 would mean "unknown".
                rssi: if self.receiver_ok { 254 } else { 0 },
                ..Default::default()
            };
            link.send(self.own.sysid, self.own.compid, &rc, log);
            let sys = SysStatus {
                voltage_battery: 12_400,
                battery_remaining: 80,
                ..Default::default()
            };
            link.send(self.own.sysid, self.own.compid, &sys, log);
        }
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
    fn poll_timeout(&self) -> Option<Instant> {
        [
            self.engine.poll_timeout(),
            Some(self.next_attitude),
            Some(self.next_slow),
            self.next_receiver_change(),
        ]
        .into_iter()
        .flatten()
        .min()
    }

    fn handle_timeout(&mut self, now: Instant, link: &mut Link, log: &mut Log) {
        self.update_receiver(log);
        self.engine.handle_timeout(now);
        self.drain(link, log);
        self.telemetry(now, link, log);
    }

    fn handle_frame(
        &mut self,
        now: Instant,
        frame: &ReceivedFrame,
        link: &mut Link,
        log: &mut Log,
    ) -> Verdict {
        let f = frame.frame();
        let verdict = self.engine.handle_frame(now, &f, frame.is_authenticated());
        if verdict == Verdict::Trusted && f.msg_id() == fbwag_dialect::FbwagNotice::ID {
            if let Some(Message::FbwagNotice(n)) = frame.message() {
                log.line(&format!(
                    "<- FBWAG_NOTICE status {} event {}",
                    n.failsafe_status.0, n.timestamp
                ));
            }
        }
        self.drain(link, log);
        verdict
    }

    fn done(&self, clock: &Clock) -> bool {
        clock.secs() >= self.duration
    }
}
