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

use super::{mode_name, Clock, Events, Limiter, Log, PeerPin};
use fbwag_delegation::cc::{CcConfig, CcState};
use fbwag_delegation::control::{Control, Controller};
use fbwag_delegation::engine::{CcEngine, CcOutput, ControlVerdict, Verdict};
use fbwag_delegation::{Instant, Peer, Status};
use fbwag_dialect::mavframe::conn::ReplyTo;
use fbwag_dialect::mavframe::route::{LinkId, Links};
use fbwag_dialect::mavframe::router::{Inbound, LinkConfig, Router, RouterEvent};
use fbwag_dialect::{Dialect, Endpoint, Message, MessageView};
use serde_json::json;
use std::io;
use std::path::PathBuf;
use std::time::Duration;

/// Settings of the companion daemon.
pub struct CcOptions {
    /// The FC link.
    pub link: super::link::LinkOptions,
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
}

/// How often the links' refusals are summarised in the log.
const REFUSED_INTERVAL: Duration = Duration::from_secs(5);

/// What the daemon did, for the demo and tests.
#[derive(Debug, Default, Clone, Copy)]
pub struct CcReport {
    pub takeovers: u32,
    pub handbacks: u32,
}

/// Runs the companion daemon until its duration ends (or the hand-back,
/// with `exit_after_handback`).
pub fn run_cc(o: CcOptions, out: Box<dyn io::Write + Send>) -> io::Result<CcReport> {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?
        .block_on(run(o, out))
}

/// The links of the companion's node.
struct NodeLinks {
    router: Router<Dialect>,
    fc: LinkId,
    outs: Links,
    autonomy: Option<LinkId>,
}

struct Daemon {
    engine: CcEngine,
    own: Peer,
    fc: Peer,
    controller: Option<Box<dyn Controller + Send>>,
    events: Events,
    log: Log,
    pin: PeerPin,
    pinned_link: bool,
    fc_mode: Option<u32>,
    report: CcReport,
    untrusted: Limiter,
    spoofs: Limiter,
    gate: Limiter,
    link_errors: Limiter,
    spoofed: u64,
    /// The parser counters last summarised, per link, and when.
    refused_seen: Vec<fbwag_dialect::Stats>,
    refused_at: tokio::time::Instant,
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
    let mut links = open_links(&o).await?;
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
    let mut daemon = Daemon {
        engine,
        own: o.own,
        fc: o.fc,
        controller: o.autonomy.is_none().then_some(o.controller),
        events,
        log,
        pin: PeerPin::default(),
        pinned_link: matches!(o.link.endpoint, Endpoint::UdpIn(_)) && o.link.peer.is_none(),
        fc_mode: None,
        report: CcReport::default(),
        untrusted: Limiter::new(5, Duration::from_secs(10)),
        spoofs: Limiter::new(5, Duration::from_secs(10)),
        gate: Limiter::new(5, Duration::from_secs(10)),
        link_errors: Limiter::new(5, Duration::from_secs(10)),
        spoofed: 0,
        refused_seen: Vec::new(),
        refused_at: tokio::time::Instant::now(),
    };
    daemon
        .run(&mut links, &clock, o.duration, o.exit_after_handback)
        .await;
    daemon.summary();
    links.router.shutdown(Duration::from_secs(1)).await;
    Ok(daemon.report)
}

async fn open_links(o: &CcOptions) -> io::Result<NodeLinks> {
    let opened = |e: &Endpoint, err: io::Error| {
        io::Error::new(err.kind(), format!("cannot open {e}: {err}"))
    };
    let mut router = Router::new();
    let l = &o.link;
    let fc = router
        .add(LinkConfig {
            endpoint: l.endpoint.clone(),
            key: l.key,
            accept_unsigned: true,
            reply_to: l.peer.map_or(ReplyTo::Pinned, ReplyTo::Fixed),
            signing_state: l.signing_state.clone(),
        })
        .await
        .map_err(|e| opened(&l.endpoint, e))?;
    let mut outs = Links::NONE;
    for e in &o.outs {
        let id = router
            .add(LinkConfig::new(e.clone()))
            .await
            .map_err(|err| opened(e, err))?;
        outs = outs.union(Links::only(id));
    }
    let autonomy = match &o.autonomy {
        Some(e) => Some(
            router
                .add(LinkConfig::new(e.clone()))
                .await
                .map_err(|err| opened(e, err))?,
        ),
        None => None,
    };
    Ok(NodeLinks {
        router,
        fc,
        outs,
        autonomy,
    })
}

impl Daemon {
    async fn run(
        &mut self,
        links: &mut NodeLinks,
        clock: &Clock,
        duration: Option<Duration>,
        exit_after_handback: bool,
    ) {
        let end = duration.map(|d| tokio::time::Instant::now() + d);
        loop {
            if exit_after_handback
                && self.report.handbacks > 0
                && self.engine.state() != CcState::Controlling
            {
                return;
            }
            let now = clock.now();
            if self.engine.poll_timeout().is_some_and(|t| t <= now) {
                self.engine.handle_timeout(now);
                self.drain(now, links);
            }
            self.report_refused(links);
            // Never sleep past the engine's deadline; wake at least every
            // 100 ms to check the duration.
            let wait = self
                .engine
                .poll_timeout()
                .map_or(Duration::from_millis(100), |t| {
                    clock.until(t).min(Duration::from_millis(100))
                });
            let deadline = tokio::time::Instant::now() + wait;
            if end.is_some_and(|e| tokio::time::Instant::now() >= e) {
                return;
            }
            tokio::select! {
                event = links.router.recv() => match event {
                    Some(e) => self.event(e, links, clock),
                    None => return,
                },
                _ = tokio::time::sleep_until(deadline) => {}
            }
        }
    }

    fn event(&mut self, event: RouterEvent<Dialect>, links: &mut NodeLinks, clock: &Clock) {
        match event {
            RouterEvent::Frame(inbound) => {
                let now = clock.now();
                if inbound.link == links.fc {
                    self.on_fc_frame(now, &inbound, links);
                } else if Some(inbound.link) == links.autonomy {
                    self.on_autonomy_frame(now, &inbound, links);
                } else {
                    self.on_out_frame(&inbound, links);
                }
            }
            RouterEvent::LinkDown { link, error } => {
                let name = links.router.endpoint(link).map(|e| e.to_string());
                if link == links.fc {
                    self.pin.reset();
                }
                self.link_errors.log(&mut self.log, "link errors", || {
                    format!(
                        "link {} failed ({error}); opening it again every second",
                        name.unwrap_or_default()
                    )
                });
            }
            RouterEvent::LinkUp { link } => {
                let name = links.router.endpoint(link).map(|e| e.to_string());
                self.log
                    .line(&format!("link {} open again", name.unwrap_or_default()));
            }
        }
    }

    /// A frame from the FC link: the engine judges it; then it is routed.
    fn on_fc_frame(&mut self, now: Instant, inbound: &Inbound<Dialect>, links: &mut NodeLinks) {
        let frame = &inbound.frame;
        let h = frame.header();
        if (h.sysid, h.compid) == (self.own.sysid, self.own.compid) {
            self.spoof(inbound, "the companion's own ids on the FC link");
            return;
        }
        let reboots = self.engine.machine().stats().fc_reboots;
        let verdict = self
            .engine
            .handle_frame(now, &frame.frame(), frame.is_authenticated());
        match verdict {
            Verdict::Trusted => {
                self.describe(frame);
                if self.engine.machine().stats().fc_reboots != reboots {
                    // The new boot speaks from wherever it bound: answer it
                    // there at once (its notices need answers within its
                    // handshake, not after the old port's silence).
                    self.pin.reset();
                }
                if let (true, Some(source)) = (self.pinned_link, inbound.source) {
                    if let Some(peer) = self.pin.trusted(source, frame.is_authenticated()) {
                        links.router.pin_peer(links.fc, peer);
                        self.log.line(&format!("answering {peer} (trusted FC)"));
                    }
                }
            }
            Verdict::Untrusted => self.untrusted.log(&mut self.log, "untrusted frames", || {
                format!(
                    "not the FC: {} from {}/{}{}",
                    frame.meta().map_or("an unknown message", |m| m.name),
                    h.sysid,
                    h.compid,
                    if frame.is_authenticated() {
                        " (signed)"
                    } else {
                        " (not authenticated)"
                    }
                )
            }),
        }
        self.drain(now, links);
        links.router.forward(inbound);
    }

    /// A frame from an `--out` link: routed, unless it claims the FC's or
    /// the companion's ids (those live on the FC link, and here).
    fn on_out_frame(&mut self, inbound: &Inbound<Dialect>, links: &mut NodeLinks) {
        let h = inbound.frame.header();
        let ids = (h.sysid, h.compid);
        if ids == (self.own.sysid, self.own.compid) || ids == (self.fc.sysid, self.fc.compid) {
            self.spoof(inbound, "the FC's or the companion's ids on another link");
            return;
        }
        links.router.forward(inbound);
    }

    /// A frame from the autonomy: control through the gate; the rest to the
    /// `--out` links only.
    fn on_autonomy_frame(
        &mut self,
        now: Instant,
        inbound: &Inbound<Dialect>,
        links: &mut NodeLinks,
    ) {
        let frame = inbound.frame.frame();
        let h = frame.header();
        let ids = (h.sysid, h.compid);
        if ids == (self.own.sysid, self.own.compid) || ids == (self.fc.sysid, self.fc.compid) {
            self.spoof(
                inbound,
                "the FC's or the companion's ids on the autonomy link",
            );
            return;
        }
        let view = MessageView::new(frame.msg_id(), frame.payload());
        if let Some(control) = view.as_ref().and_then(Control::from_view) {
            match self.engine.submit_control(now, control) {
                ControlVerdict::Forwarded => self.drain(now, links),
                ControlVerdict::NotInControl => {
                    self.gate.log(&mut self.log, "gated controls", || {
                        format!(
                            "autonomy {} dropped: the companion does not hold control",
                            control.name()
                        )
                    })
                }
            }
            return;
        }
        links.router.learn(inbound);
        links.router.send_raw(links.outs, inbound.frame.as_bytes());
    }

    /// Every [`REFUSED_INTERVAL`], what each link's parser refused since
    /// (bad checksums, bad signatures, unsigned frames, bytes dropped), when
    /// it refused anything: one line per link, whatever the flood.
    fn report_refused(&mut self, links: &NodeLinks) {
        if self.refused_at.elapsed() < REFUSED_INTERVAL {
            return;
        }
        self.refused_at = tokio::time::Instant::now();
        for link in links.router.links().iter() {
            let now = links.router.counters(link).parser;
            let i = usize::from(link);
            if self.refused_seen.len() <= i {
                self.refused_seen.resize(i + 1, Default::default());
            }
            let was = std::mem::replace(&mut self.refused_seen[i], now);
            let parts: Vec<String> = [
                ("bad checksums", now.bad_crc - was.bad_crc),
                ("bad signatures", now.bad_signature - was.bad_signature),
                (
                    "unsigned refused",
                    now.unsigned_rejected - was.unsigned_rejected,
                ),
                ("bytes dropped", now.bytes_dropped - was.bytes_dropped),
            ]
            .iter()
            .filter(|(_, n)| *n > 0)
            .map(|(what, n)| format!("{n} {what}"))
            .collect();
            if !parts.is_empty() {
                let name = links.router.endpoint(link).map(|e| e.to_string());
                self.log.line(&format!(
                    "{}: link refused in the last {} s: {}",
                    name.unwrap_or_default(),
                    REFUSED_INTERVAL.as_secs(),
                    parts.join(", ")
                ));
            }
        }
    }

    fn spoof(&mut self, inbound: &Inbound<Dialect>, what: &str) {
        self.spoofed = self.spoofed.saturating_add(1);
        let h = inbound.frame.header();
        let source = inbound
            .source
            .map_or(String::new(), |s| format!(" from {s}"));
        self.spoofs.log(&mut self.log, "spoofed frames", || {
            format!(
                "dropped a frame as {}/{}{source}: {what}",
                h.sysid, h.compid
            )
        });
    }

    /// Carries out the engine's outputs.
    fn drain(&mut self, now: Instant, links: &mut NodeLinks) {
        while let Some(out) = self.engine.poll_output() {
            match out {
                CcOutput::Transmit(msg) => self.transmit(&msg, links),
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
                    self.log
                        .line(&format!("takeover (event {event}): {who} streams control"));
                    self.events
                        .emit("control", json!({"state": "start", "fc_event": event}));
                }
                CcOutput::ControlStopped => {
                    self.log.line("control ends: overrides stopped");
                    self.events.emit("control", json!({"state": "stop"}));
                }
                CcOutput::FcFound => {
                    self.log.line("FC found");
                    self.events.emit("fc", json!({"state": "found"}));
                }
                CcOutput::FcLost => {
                    self.log.line("FC lost (silent)");
                    self.events.emit("fc", json!({"state": "lost"}));
                }
                CcOutput::FcRebooted => {
                    self.log.line("FC rebooted: answering its new boot");
                    self.events.emit("fc", json!({"state": "rebooted"}));
                }
            }
        }
    }

    /// The companion's own message: to the FC link; a broadcast also to
    /// every other link.
    fn transmit(&mut self, msg: &Message, links: &mut NodeLinks) {
        if let Message::FbwagNotice(n) = msg {
            self.log.line(&format!(
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
            Links::only(links.fc)
        } else {
            links.router.links()
        };
        links
            .router
            .send_message(to, self.own.sysid, self.own.compid, msg);
    }

    /// Logs what the FC says that a person follows: notices, its mode,
    /// its confirmations.
    fn describe(&mut self, frame: &fbwag_dialect::ReceivedFrame) {
        let f = frame.frame();
        match MessageView::new(f.msg_id(), f.payload()) {
            Some(MessageView::FbwagNotice(n)) => self.log.line(&format!(
                "<- FBWAG_NOTICE status {} event {}",
                n.failsafe_status().0,
                n.timestamp()
            )),
            Some(MessageView::Statustext(t)) => self.log.line(&format!(
                "<- STATUSTEXT {:?}",
                String::from_utf8_lossy(t.text().as_bytes())
            )),
            Some(MessageView::Heartbeat(h)) if self.fc_mode != Some(h.custom_mode()) => {
                self.fc_mode = Some(h.custom_mode());
                let mode = mode_name(h.custom_mode());
                self.log.line(&format!("FC mode {mode}"));
                self.events.emit("fc_mode", json!({"mode": mode}));
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
