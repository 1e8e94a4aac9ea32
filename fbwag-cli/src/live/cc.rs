//! `fbwag cc`: the companion-computer daemon. It runs the companion engine
//! on the FC link: answers the FC's notices, streams the controller's
//! control while it holds control (the engine decides when), sends the
//! companion's 1 Hz heartbeat, and reports.

use super::link::{self, Link, LinkOptions, Node};
use super::{mode_name, Clock, Events, Log};
use fbwag_delegation::cc::{CcConfig, CcState};
use fbwag_delegation::control::Controller;
use fbwag_delegation::engine::{CcEngine, CcOutput, Verdict};
use fbwag_delegation::{Instant, Peer, Status};
use fbwag_dialect::{Message, MessageView, ReceivedFrame};
use serde_json::json;
use std::io;
use std::path::PathBuf;
use std::time::Duration;

/// Settings of the companion daemon.
pub struct CcOptions {
    pub link: LinkOptions,
    pub own: Peer,
    pub fc: Peer,
    pub rate_hz: f64,
    pub controller: Box<dyn Controller + Send>,
    pub require_signed: bool,
    pub duration: Option<Duration>,
    pub exit_after_handback: bool,
    pub events: Option<PathBuf>,
}

/// What the daemon did, for the demo and tests.
#[derive(Debug, Default, Clone, Copy)]
pub struct CcReport {
    pub takeovers: u32,
    pub handbacks: u32,
}

struct Daemon {
    engine: CcEngine,
    own: Peer,
    fc: Peer,
    controller: Box<dyn Controller + Send>,
    events: Events,
    duration: Option<Duration>,
    exit_after_handback: bool,
    fc_mode: Option<u32>,
    report: CcReport,
}

/// Runs the companion daemon until its duration ends (or the hand-back,
/// with `exit_after_handback`).
pub fn run_cc(o: CcOptions, out: Box<dyn io::Write + Send>) -> io::Result<CcReport> {
    let clock = Clock::start();
    let mut log = Log::new(out, clock, "cc");
    let cfg = CcConfig {
        own: o.own,
        fc: o.fc,
        require_signed: o.require_signed,
        control_period: Duration::from_secs_f64(1.0 / o.rate_hz),
        ..CcConfig::default()
    };
    let engine = CcEngine::new(cfg, clock.now())
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
    let endpoint = o.link.endpoint.clone();
    let mut link = Link::open(o.link, &mut log)?;
    let events = Events::open(o.events.as_deref(), clock)?;
    log.line(&format!(
        "listening on {endpoint} as {}/{}, serving FC {}/{}, controller {}{}",
        o.own.sysid,
        o.own.compid,
        o.fc.sysid,
        o.fc.compid,
        o.controller.name(),
        if o.require_signed {
            ", signed frames only"
        } else {
            ""
        }
    ));
    let mut daemon = Daemon {
        engine,
        own: o.own,
        fc: o.fc,
        controller: o.controller,
        events,
        duration: o.duration,
        exit_after_handback: o.exit_after_handback,
        fc_mode: None,
        report: CcReport::default(),
    };
    link::run(&mut daemon, &mut link, &clock, &mut log);
    let s = daemon.engine.stats();
    daemon.events.emit(
        "summary",
        json!({
            "takeovers": daemon.report.takeovers,
            "handbacks": daemon.report.handbacks,
            "trusted_frames": s.trusted_frames,
            "untrusted_frames": s.untrusted_frames,
            "untrusted_notices": s.untrusted_notices,
            "controls_forwarded": s.controls_forwarded,
            "controls_dropped": s.controls_dropped,
        }),
    );
    Ok(daemon.report)
}

impl Daemon {
    /// Carries out the engine's outputs.
    fn drain(&mut self, now: Instant, link: &mut Link, log: &mut Log) {
        while let Some(out) = self.engine.poll_output() {
            match out {
                CcOutput::Transmit(msg) => {
                    if let Message::FbwagNotice(n) = &msg {
                        log.line(&format!(
                            "-> FBWAG_NOTICE status {} event {}",
                            n.failsafe_status.0, n.timestamp
                        ));
                        if n.failsafe_status == Status::NORMAL {
                            self.report.handbacks += 1;
                        }
                    }
                    link.send(self.own.sysid, self.own.compid, &msg, log);
                }
                CcOutput::ControlDue => {
                    let control = self.controller.control(now, self.fc);
                    let _ = self.engine.submit_control(now, control);
                }
                CcOutput::ControlStarted { event } => {
                    self.report.takeovers += 1;
                    log.line(&format!(
                        "takeover (event {event}): {} streams control",
                        self.controller.name()
                    ));
                    self.events
                        .emit("control", json!({"state": "start", "fc_event": event}));
                }
                CcOutput::ControlStopped => {
                    log.line("control ends: overrides stopped");
                    self.events.emit("control", json!({"state": "stop"}));
                }
                CcOutput::FcFound => {
                    log.line("FC found");
                    self.events.emit("fc", json!({"state": "found"}));
                }
                CcOutput::FcLost => {
                    log.line("FC lost (silent)");
                    self.events.emit("fc", json!({"state": "lost"}));
                }
                CcOutput::FcRebooted => {
                    log.line("FC rebooted: answering its new boot");
                    self.events.emit("fc", json!({"state": "rebooted"}));
                }
            }
        }
    }

    /// Logs what the FC says that a person follows: notices, its mode,
    /// its confirmations.
    fn describe(&mut self, frame: &ReceivedFrame, log: &mut Log) {
        let f = frame.frame();
        match MessageView::new(f.msg_id(), f.payload()) {
            Some(MessageView::FbwagNotice(n)) => log.line(&format!(
                "<- FBWAG_NOTICE status {} event {}",
                n.failsafe_status().0,
                n.timestamp()
            )),
            Some(MessageView::Statustext(t)) => log.line(&format!(
                "<- STATUSTEXT {:?}",
                String::from_utf8_lossy(t.text().as_bytes())
            )),
            Some(MessageView::Heartbeat(h)) if self.fc_mode != Some(h.custom_mode()) => {
                self.fc_mode = Some(h.custom_mode());
                let mode = mode_name(h.custom_mode());
                log.line(&format!("FC mode {mode}"));
                self.events.emit("fc_mode", json!({"mode": mode}));
            }
            _ => {}
        }
    }
}

impl Node for Daemon {
    fn poll_timeout(&self) -> Option<Instant> {
        self.engine.poll_timeout()
    }

    fn handle_timeout(&mut self, now: Instant, link: &mut Link, log: &mut Log) {
        self.engine.handle_timeout(now);
        self.drain(now, link, log);
    }

    fn handle_frame(
        &mut self,
        now: Instant,
        frame: &ReceivedFrame,
        link: &mut Link,
        log: &mut Log,
    ) -> Verdict {
        let verdict = self
            .engine
            .handle_frame(now, &frame.frame(), frame.is_authenticated());
        if verdict == Verdict::Trusted {
            self.describe(frame, log);
        }
        self.drain(now, link, log);
        verdict
    }

    fn done(&self, clock: &Clock) -> bool {
        self.duration
            .is_some_and(|d| clock.secs() >= d.as_secs_f64())
            || (self.exit_after_handback
                && self.report.handbacks > 0
                && self.engine.state() != CcState::Controlling)
    }
}
