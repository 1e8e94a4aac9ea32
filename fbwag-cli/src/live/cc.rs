//! `fbwag cc`: the companion-computer daemon. It runs the companion engine
//! on the FC link and is the companion's MAVLink node: it routes between
//! the FC link and any number of other links (`--out`: ground stations,
//! MAVProxy, other onboard programs) by the MAVLink routing rules, and it
//! is the gateway of the user's own autonomy (`--autonomy`), whose control
//! reaches the FC only while the companion holds control.
//!
//! What goes where:
//! - frames from the FC link: to the engine (the FC's protocol messages,
//!   trusted by ids and signature), then routed to the other links;
//! - frames from an `--out` link: routed (to the FC link where their
//!   addressee is, broadcasts everywhere but back), untouched; a frame
//!   claiming the FC's or the companion's own ids there is a spoof (or a
//!   loop) and is dropped;
//! - frames from the autonomy link: its RC_CHANNELS_OVERRIDE,
//!   SET_ATTITUDE_TARGET and MANUAL_CONTROL go to the engine's gate
//!   (re-addressed to the FC, signed with the companion's key, sent only
//!   while the companion holds control, dropped and counted otherwise);
//!   its other messages go to the `--out` links only, never to the FC: the
//!   autonomy flies the aircraft only through the gate;
//! - the companion's own messages (heartbeat, notices, control): to the FC
//!   link, and the broadcast ones to every other link too (so the autonomy
//!   and the ground station see the takeover).

use super::net::{self, LinkOptions, Net, Node};
use super::{mode_name, Clock, Events, Limiter, Log};
use fbwag_delegation::cc::{CcConfig, CcState};
use fbwag_delegation::control::{Control, Controller};
use fbwag_delegation::engine::{CcEngine, CcOutput, ControlVerdict, Verdict};
use fbwag_delegation::{Instant, Peer, Status};
use fbwag_dialect::mavframe::route::{LinkId, Links};
use fbwag_dialect::mavframe::router::Inbound;
use fbwag_dialect::{Dialect, Endpoint, Message, MessageView};
use serde_json::json;
use std::io;
use std::path::PathBuf;
use std::time::Duration;

/// Settings of the companion daemon.
pub struct CcOptions {
    /// The FC link.
    pub link: LinkOptions,
    /// Other links the companion routes to and from.
    pub outs: Vec<Endpoint>,
    /// The user's autonomy program's link.
    pub autonomy: Option<Endpoint>,
    pub own: Peer,
    pub fc: Peer,
    pub rate_hz: f64,
    /// The built-in controller (ignored when an autonomy link is given).
    pub controller: Box<dyn Controller + Send>,
    pub require_signed: bool,
    pub duration: Option<Duration>,
    pub exit_after_handback: bool,
    pub events: Option<PathBuf>,
    /// Stop as at the end of the run on SIGTERM, and on SIGINT when run
    /// from a terminal (`fbwag cc`; not the demo, which runs both daemons).
    pub stop_on_signals: bool,
}

/// What the daemon did, for the demo and tests.
#[derive(Debug, Default, Clone, Copy)]
pub struct CcReport {
    pub takeovers: u32,
    pub handbacks: u32,
}

/// Runs the companion daemon until its duration ends (or the hand-back,
/// with `exit_after_handback`).
pub fn run_cc(o: CcOptions, out: Box<dyn io::Write + Send>) -> io::Result<CcReport> {
    net::block_on(run(o, out))
}

struct Daemon {
    engine: CcEngine,
    own: Peer,
    fc: Peer,
    controller: Option<Box<dyn Controller + Send>>,
    /// The `--out` links, and the autonomy's.
    outs: Links,
    autonomy: Option<LinkId>,
    events: Events,
    fc_mode: Option<u32>,
    report: CcReport,
    spoofs: Limiter,
    gate: Limiter,
    /// The FC's notices, texts and mode changes logged:
    /// [`super::HEARD_PER_SECOND`].
    heard: Limiter,
    spoofed: u64,
    duration: Option<Duration>,
    exit_after_handback: bool,
}

async fn run(o: CcOptions, out: Box<dyn io::Write + Send>) -> io::Result<CcReport> {
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
    let events = Events::open(o.events.as_deref(), clock)?;
    let mut net = Net::open(&o.link, &mut log).await?;
    let mut outs = Links::NONE;
    for e in &o.outs {
        outs = outs.union(Links::only(net.add(e).await?));
    }
    let autonomy = match &o.autonomy {
        Some(e) => Some(net.add(e).await?),
        None => None,
    };
    log.line(&format!(
        "FC link {} as {}/{}, serving FC {}/{}, {}{}",
        o.link.endpoint,
        o.own.sysid,
        o.own.compid,
        o.fc.sysid,
        o.fc.compid,
        match &o.autonomy {
            Some(a) => format!("autonomy on {a}"),
            None => format!("controller {}", o.controller.name()),
        },
        if o.require_signed {
            ", signed frames only"
        } else {
            ""
        }
    ));
    for out in &o.outs {
        log.line(&format!("routing to and from {out}"));
    }
    if !o.outs.is_empty() {
        log.line(&match o.link.routed_rate {
            Some(rate) => format!(
                "routed to the FC link: at most {rate} bytes/s (--routed-rate), the companion's own frames first"
            ),
            None => "routed to the FC link: unpaced (--routed-rate off)".to_string(),
        });
    }
    let mut daemon = Daemon {
        engine,
        own: o.own,
        fc: o.fc,
        controller: o.autonomy.is_none().then_some(o.controller),
        outs,
        autonomy,
        events,
        fc_mode: None,
        report: CcReport::default(),
        spoofs: Limiter::new(5, Duration::from_secs(10)),
        gate: Limiter::new(5, Duration::from_secs(10)),
        heard: Limiter::new(super::HEARD_PER_SECOND, Duration::from_secs(1)),
        spoofed: 0,
        duration: o.duration,
        exit_after_handback: o.exit_after_handback,
    };
    net::run(&mut daemon, net, &clock, &mut log, o.stop_on_signals).await;
    daemon.summary();
    Ok(daemon.report)
}

impl Node for Daemon {
    fn poll_timeout(&self) -> Option<Instant> {
        self.engine.poll_timeout()
    }

    fn handle_timeout(&mut self, now: Instant, net: &mut Net, log: &mut Log) {
        self.engine.handle_timeout(now);
        self.drain(now, net, log);
    }

    fn handle_frame(
        &mut self,
        now: Instant,
        inbound: &Inbound<Dialect>,
        net: &mut Net,
        log: &mut Log,
    ) {
        if inbound.link == net.main {
            self.on_fc_frame(now, inbound, net, log);
        } else if Some(inbound.link) == self.autonomy {
            self.on_autonomy_frame(now, inbound, net, log);
        } else {
            self.on_out_frame(inbound, net, log);
        }
    }

    fn done(&self, clock: &Clock) -> bool {
        self.duration
            .is_some_and(|d| clock.secs() >= d.as_secs_f64())
            || (self.exit_after_handback
                && self.report.handbacks > 0
                && self.engine.state() != CcState::Controlling)
    }
}

impl Daemon {
    /// A frame from the FC link: the engine judges it; then it is routed.
    fn on_fc_frame(
        &mut self,
        now: Instant,
        inbound: &Inbound<Dialect>,
        net: &mut Net,
        log: &mut Log,
    ) {
        let frame = &inbound.frame;
        let h = frame.header();
        if (h.sysid, h.compid) == (self.own.sysid, self.own.compid) {
            self.spoof(inbound, "the companion's own ids on the FC link", log);
            return;
        }
        let verdict = self
            .engine
            .handle_frame(now, &frame.frame(), frame.is_authenticated());
        if verdict == Verdict::Trusted {
            self.describe(frame, log);
        }
        // A rebooted FC speaking from a new port is answered there by the
        // peer rule alone: at once when its frame is authenticated, after
        // the old port's silence otherwise. (Forgetting the peer at every
        // reboot let a forged unsigned "reboot" move it to the attacker at
        // once, and the real FC's RC loss went unanswered: RTL.)
        net.judged(inbound, verdict, log);
        self.drain(now, net, log);
        net.router.forward(inbound);
    }

    /// A frame from an `--out` link: routed, unless it claims the FC's or
    /// the companion's ids (those live on the FC link, and here).
    fn on_out_frame(&mut self, inbound: &Inbound<Dialect>, net: &mut Net, log: &mut Log) {
        if self.claims_ours(inbound) {
            self.spoof(
                inbound,
                "the FC's or the companion's ids on another link",
                log,
            );
            return;
        }
        net.router.forward(inbound);
    }

    /// A frame from the autonomy: control through the gate; the rest to the
    /// `--out` links only.
    fn on_autonomy_frame(
        &mut self,
        now: Instant,
        inbound: &Inbound<Dialect>,
        net: &mut Net,
        log: &mut Log,
    ) {
        if self.claims_ours(inbound) {
            self.spoof(
                inbound,
                "the FC's or the companion's ids on the autonomy link",
                log,
            );
            return;
        }
        let frame = inbound.frame.frame();
        let view = MessageView::new(frame.msg_id(), frame.payload());
        if let Some(control) = view.as_ref().and_then(Control::from_view) {
            match self.engine.submit_control(now, control) {
                ControlVerdict::Forwarded => self.drain(now, net, log),
                ControlVerdict::NotInControl => self.gate.log(log, "gated controls", || {
                    format!(
                        "autonomy {} dropped: the companion does not hold control",
                        control.name()
                    )
                }),
            }
            return;
        }
        net.router.learn(inbound);
        // Routed traffic: after the companion's own frames on those links.
        net.router.send_routed(self.outs, inbound.frame.as_bytes());
    }

    /// The frame claims the FC's or the companion's ids (which live on the
    /// FC link, and here).
    fn claims_ours(&self, inbound: &Inbound<Dialect>) -> bool {
        let h = inbound.frame.header();
        let ids = (h.sysid, h.compid);
        ids == (self.own.sysid, self.own.compid) || ids == (self.fc.sysid, self.fc.compid)
    }

    fn spoof(&mut self, inbound: &Inbound<Dialect>, what: &str, log: &mut Log) {
        self.spoofed = self.spoofed.saturating_add(1);
        let h = inbound.frame.header();
        let source = inbound
            .source
            .map_or(String::new(), |s| format!(" from {s}"));
        self.spoofs.log(log, "spoofed frames", || {
            format!(
                "dropped a frame as {}/{}{source}: {what}",
                h.sysid, h.compid
            )
        });
    }

    /// Carries out the engine's outputs.
    fn drain(&mut self, now: Instant, net: &mut Net, log: &mut Log) {
        while let Some(out) = self.engine.poll_output() {
            match out {
                CcOutput::Transmit(msg) => self.transmit(&msg, net, log),
                CcOutput::ControlDue => {
                    if let Some(c) = &mut self.controller {
                        let control = c.control(now, self.fc);
                        let _ = self.engine.submit_control(now, control);
                    }
                }
                CcOutput::ControlStarted { event } => {
                    self.report.takeovers += 1;
                    let who = self
                        .controller
                        .as_ref()
                        .map_or("the autonomy", |c| c.name());
                    log.line(&format!("takeover (event {event}): {who} streams control"));
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

    /// The companion's own message: to the FC link; a broadcast also to
    /// every other link.
    fn transmit(&mut self, msg: &Message, net: &mut Net, log: &mut Log) {
        if let Message::FbwagNotice(n) = msg {
            log.line(&format!(
                "-> FBWAG_NOTICE status {} event {}",
                n.failsafe_status.0, n.timestamp
            ));
            if n.failsafe_status == Status::NORMAL {
                self.report.handbacks += 1;
            }
        }
        let targeted = fbwag_dialect::mavframe::Encode::meta(msg)
            .target_system_offset
            .is_some();
        let to = if targeted {
            Links::only(net.main)
        } else {
            net.router.links()
        };
        net.router
            .send_message(to, self.own.sysid, self.own.compid, msg);
    }

    /// Logs what the FC says that a person follows: notices, its mode,
    /// its confirmations.
    fn describe(&mut self, frame: &fbwag_dialect::ReceivedFrame, log: &mut Log) {
        let f = frame.frame();
        match MessageView::new(f.msg_id(), f.payload()) {
            Some(MessageView::FbwagNotice(n)) => {
                self.heard.log(log, "notices, texts and mode changes", || {
                    format!(
                        "<- FBWAG_NOTICE status {} event {}",
                        n.failsafe_status().0,
                        n.timestamp()
                    )
                })
            }
            Some(MessageView::Statustext(t)) => {
                self.heard.log(log, "notices, texts and mode changes", || {
                    format!(
                        "<- STATUSTEXT {:?}",
                        String::from_utf8_lossy(t.text().as_bytes())
                    )
                })
            }
            Some(MessageView::Heartbeat(h)) if self.fc_mode != Some(h.custom_mode()) => {
                // Limited with the notices: without signing, anyone with
                // the FC's ids can flap its mode at every frame. A change
                // not admitted is reported by the next heartbeat admitted.
                let (show, suppressed) = self.heard.admit();
                if let Some(n) = suppressed {
                    log.line(&format!(
                        "({n} more notices, texts and mode changes suppressed)"
                    ));
                }
                if show {
                    self.fc_mode = Some(h.custom_mode());
                    let mode = mode_name(h.custom_mode());
                    log.line(&format!("FC mode {mode}"));
                    self.events.emit("fc_mode", json!({"mode": mode}));
                }
            }
            _ => {}
        }
    }

    fn summary(&mut self) {
        let s = *self.engine.stats();
        self.events.emit(
            "summary",
            json!({
                "takeovers": self.report.takeovers,
                "handbacks": self.report.handbacks,
                "trusted_frames": s.trusted_frames,
                "untrusted_frames": s.untrusted_frames,
                "untrusted_notices": s.untrusted_notices,
                "controls_forwarded": s.controls_forwarded,
                "controls_dropped": s.controls_dropped,
                "spoofed_frames": self.spoofed,
            }),
        );
    }
}
