//! `fbwag cc`: the companion-computer daemon. It runs the companion's node
//! (`fbwag_delegation::node::CompanionNode`: the companion engine and the
//! policy of its links) on the FC link, any number of ground-side links
//! (`--out`: ground stations, MAVProxy, other onboard programs) and the
//! user's autonomy (`--autonomy`), and carries out what the node decides:
//! the node says which frames are protocol input, which go where (by the
//! MAVLink routing rules, byte for byte), whom each listening link answers,
//! which autonomy control reaches the FC (through the companion's gate,
//! only while it holds control) and which frames are dropped and why. This
//! module moves bytes and time, and reports.

use super::net::{self, LinkOptions, Named, Net, Node, Plan, Shell};
use super::tlog::TlogCounts;
use super::{mode_name, Clock, Events, Level, Limiter, Log, LogOptions, Tlog};
use crate::args::LinkFilter;
use fbwag_delegation::cc::{CcConfig, CcState};
use fbwag_delegation::control::Controller;
use fbwag_delegation::engine::CcOutput;
use fbwag_delegation::node::{
    AutonomyFallback, CompanionEvent, CompanionNode, ControlSource, LinkSpec, Output, Role,
};
use fbwag_delegation::{Moment, Peer, Status};
use fbwag_dialect::mavframe::route::{LinkId, Links};
use fbwag_dialect::mavframe::router::Inbound;
use fbwag_dialect::mavframe::Framer;
use fbwag_dialect::mavframe::Received;
use fbwag_dialect::{Dialect, Endpoint, Message, MessageView};
use serde_json::json;
use std::io;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// Settings of the companion daemon.
pub struct CcOptions {
    /// The FC link.
    pub link: LinkOptions,
    /// Other links the companion routes to and from.
    pub outs: Vec<Named>,
    /// Filters, each naming its link by its place among `outs`, then
    /// `trusted_outs`, then `autonomy`.
    pub filters: Vec<LinkFilter>,
    /// De-duplication window of routed frames (`None`: off).
    pub dedup: Option<Duration>,
    /// Links trusted like the key ([`LinkSpec::trusted`]).
    pub trusted_outs: Vec<Named>,
    /// They may be on other than loopback addresses.
    pub trusted_out_remote: bool,
    /// The user's autonomy program's link.
    pub autonomy: Option<Named>,
    /// The autonomy program's address: the autonomy link answers it only,
    /// and drops frames from anyone else.
    pub autonomy_peer: Option<SocketAddr>,
    /// What flies while the autonomy is silent.
    pub autonomy_fallback: AutonomyFallback,
    pub own: Peer,
    pub fc: Peer,
    pub rate_hz: f64,
    /// The built-in controller (ignored when an autonomy link is given).
    pub controller: Box<dyn Controller + Send + Sync>,
    pub require_signed: bool,
    pub duration: Option<Duration>,
    pub exit_after_handback: bool,
    pub events: Option<PathBuf>,
    /// Lines logged: this level and above.
    pub log_level: crate::live::Level,
    /// The text report's period (`None`: none), and the status events'.
    pub report: Option<std::time::Duration>,
    /// Log every frame accepted from any link, and the companion's own, to
    /// `.tlog` files.
    pub tlog: Option<LogOptions>,
    /// Stop as at the end of the run on SIGTERM, and on SIGINT when run
    /// from a terminal (`fbwag cc`; not the demo, which runs both daemons).
    pub stop_on_signals: bool,
}

/// What the daemon did, for the demo and tests.
#[derive(Debug, Default, Clone, Copy)]
pub struct CcReport {
    pub takeovers: u32,
    pub handbacks: u32,
    /// The FC was heard during the run.
    pub fc_heard: bool,
}

/// Runs the companion daemon until its duration ends (or the hand-back,
/// with `exit_after_handback`).
pub fn run_cc(o: CcOptions, out: Box<dyn io::Write + Send>) -> io::Result<CcReport> {
    net::block_on(run(o, out))
}

struct Daemon {
    node: CompanionNode,
    own: Peer,
    /// The FC's ids.
    fc: Peer,
    /// The built-in controller, when there is no autonomy.
    controller: Option<Box<dyn Controller + Send + Sync>>,
    events: Events,
    fc_mode: Option<u32>,
    report: CcReport,
    /// The FC's notices, texts and mode changes logged:
    /// [`super::HEARD_PER_SECOND`].
    heard: Limiter,
    duration: Option<Duration>,
    exit_after_handback: bool,
    tlog: Option<OwnLog>,
    /// The FC was heard at least once.
    fc_found: bool,
    /// The autonomy is silent (`None`: no autonomy).
    autonomy_silent: Option<bool>,
}

/// The telemetry log, with what frames the companion's own messages for it
/// (the links frame them again, each with its sequence and signature).
struct OwnLog {
    tlog: Tlog,
    framer: Framer,
    /// The losses when last reported.
    reported: TlogCounts,
}

impl OwnLog {
    fn sent(&mut self, own: Peer, message: &Message) {
        if let Ok(frame) = self.framer.frame(own.sysid, own.compid, message) {
            self.tlog.sent(frame);
        }
    }

    /// The counts in the log when frames were lost since the last report.
    fn report(&mut self, log: &mut Log, events: &mut Events) {
        self.tlog.notes(log);
        let now = self.tlog.counts();
        let was = self.reported;
        if (now.dropped, now.unwritten) != (was.dropped, was.unwritten) {
            self.reported = now;
            log.warn(&super::tlog::line(&now));
            events.emit("tlog", now.json());
        }
    }
}

/// The daemon's links, to be opened, each with its place in the node.
struct Planned {
    plan: Plan,
    specs: Vec<(LinkId, LinkSpec)>,
    /// The links filters name: the `--out` links, then the
    /// `--trusted-out` links, then the autonomy's, each in order; and
    /// their endpoints, for the log.
    filtered: Vec<LinkId>,
    filtered_endpoints: Vec<String>,
    autonomy: Option<LinkId>,
}

fn plan_links(o: &CcOptions, log: &mut Log) -> io::Result<Planned> {
    let mut plan = Plan::main(&o.link, log)?;
    let spec = |role, endpoint, peer| LinkSpec::new(role, net::answers(endpoint, peer));
    let mut specs = vec![(0, spec(Role::Peer, &o.link.endpoint, o.link.peer))];
    let mut filtered = Vec::new();
    for e in &o.outs {
        // Ground links verify with the key too: a ground station that signs
        // reaches the FC where signing is required.
        let link = plan.add(e, o.link.key, None);
        specs.push((link, spec(Role::Ground, &e.endpoint, None)));
        filtered.push(link);
    }
    for e in &o.trusted_outs {
        // Checked at start (`check_trusted`), and again at each reopen
        // after the name is resolved again.
        let loopback_only = !o.trusted_out_remote;
        let link = plan.add_checked(e, o.link.key, None, loopback_only);
        let trusted = LinkSpec {
            trusted: true,
            ..spec(Role::Ground, &e.endpoint, None)
        };
        specs.push((link, trusted));
        filtered.push(link);
    }
    let mut autonomy = None;
    if let Some(e) = &o.autonomy {
        let link = plan.add(e, None, o.autonomy_peer);
        specs.push((link, spec(Role::Autonomy, &e.endpoint, o.autonomy_peer)));
        filtered.push(link);
        autonomy = Some(link);
    }
    let filtered_endpoints = (o.outs.iter().chain(&o.trusted_outs))
        .chain(&o.autonomy)
        .map(ToString::to_string)
        .collect();
    Ok(Planned {
        plan,
        specs,
        filtered,
        filtered_endpoints,
        autonomy,
    })
}

/// Why a `--trusted-out` link is refused.
#[derive(Debug, thiserror::Error)]
pub enum TrustedOutError {
    /// Its address is not loopback (and `--trusted-out-remote` is not set).
    #[error("{0} is not a loopback address: anyone who can reach it could command the aircraft (--trusted-out-remote accepts it)")]
    NotLocal(String),
    /// Its host name did not resolve.
    #[error("{0}")]
    Resolve(fbwag_dialect::mavframe::conn::ResolveError),
}

/// A trusted link must be local: loopback addresses (every address its
/// host name resolves to) or a serial port, unless `remote` allows any.
pub fn check_trusted(endpoint: &Endpoint, remote: bool) -> Result<(), TrustedOutError> {
    let Some(address) = endpoint.address().filter(|_| !remote) else {
        return Ok(());
    };
    let resolved = address.resolve().map_err(TrustedOutError::Resolve)?;
    match resolved.iter().find(|a| !a.ip().is_loopback()) {
        Some(a) => Err(TrustedOutError::NotLocal(a.to_string())),
        None => Ok(()),
    }
}

fn invalid(e: impl std::error::Error + Send + Sync + 'static) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, e)
}

async fn run(o: CcOptions, out: Box<dyn io::Write + Send>) -> io::Result<CcReport> {
    let clock = Clock::start();
    let mut log = Log::new(out, "cc", o.log_level, super::Style::of_stdout());
    let cfg = CcConfig {
        own: o.own,
        fc: o.fc,
        require_signed: o.require_signed,
        control_period: Duration::from_secs_f64(1.0 / o.rate_hz),
        ..CcConfig::default()
    };
    let events = Events::open(o.events.as_deref(), clock)?;
    let tlog = o.tlog.as_ref().map(|t| Tlog::start(t, "cc")).transpose()?;
    let opened = plan_links(&o, &mut log)?;
    let fc_link = (o.link.name.clone()).unwrap_or_else(|| o.link.endpoint.to_string());
    let source = opened
        .autonomy
        .map_or(ControlSource::Builtin, |link| ControlSource::Autonomy {
            link,
            fallback: o.autonomy_fallback,
            silence: fbwag_delegation::node::AUTONOMY_SILENCE,
        });
    let mut node = CompanionNode::new(cfg, source, clock.now()).map_err(invalid)?;
    for (link, spec) in &opened.specs {
        node.add_link(*link, *spec).map_err(invalid)?;
    }
    log_start(&o, &mut log);
    let (links, endpoints) = (&opened.filtered, &opened.filtered_endpoints);
    net::set_filters(&o.filters, links, endpoints, &mut log, |link, d, f| {
        node.set_filter(link, d, f)
    })?;
    node.set_dedup(o.dedup);
    if let Some(window) = o.dedup {
        let ms = window.as_millis();
        log.info(&format!("copies of a routed frame within {ms} ms dropped"));
    }
    let daemon = Daemon {
        node,
        own: o.own,
        fc: o.fc,
        controller: o.autonomy.is_none().then_some(o.controller),
        events,
        fc_mode: None,
        report: CcReport::default(),
        heard: Limiter::new(super::HEARD_PER_SECOND, Duration::from_secs(1)),
        duration: o.duration,
        exit_after_handback: o.exit_after_handback,
        tlog: tlog.map(|tlog| OwnLog {
            tlog,
            framer: Framer::new(),
            reported: TlogCounts::default(),
        }),
        fc_found: false,
        autonomy_silent: None,
    };
    let shell = Shell::new(daemon, log, clock, 0, o.report);
    let router = opened.plan.open(shell).await?;
    let Shell {
        node: mut daemon,
        mut log,
        ..
    } = net::run(router, o.stop_on_signals).await?;
    let tlog = daemon.tlog.as_mut().map(|t| t.tlog.finish(&mut log));
    if let Some(counts) = tlog {
        log.info(&super::tlog::line(&counts));
    }
    if !daemon.fc_found {
        log.error(&format!(
            "the FC ({}/{}) was never heard on its link {}: check the connection, its baud rate and the key",
            o.fc.sysid, o.fc.compid, fc_link
        ));
    }
    daemon.summary(tlog);
    daemon.report.fc_heard = daemon.fc_found;
    Ok(daemon.report)
}

/// What the daemon says at start.
fn log_start(o: &CcOptions, log: &mut Log) {
    log.info(&format!(
        "FC link {} as {}/{}, serving FC {}/{}, {}{}",
        Named {
            endpoint: o.link.endpoint.clone(),
            name: o.link.name.clone(),
        },
        o.own.sysid,
        o.own.compid,
        o.fc.sysid,
        o.fc.compid,
        match &o.autonomy {
            Some(a) => format!(
                "autonomy on {a} (silent 500 ms: {})",
                match o.autonomy_fallback {
                    AutonomyFallback::Decline => "takeovers declined",
                    AutonomyFallback::WingsLevel => "wings level until it speaks",
                }
            ),
            None => format!("controller {}", o.controller.name()),
        },
        if o.require_signed {
            ", signed frames only"
        } else {
            ""
        }
    ));
    for out in &o.outs {
        log.info(&format!("routing to and from {out}"));
    }
    for out in &o.trusted_outs {
        log.info(&format!(
            "routing to and from {out}, trusted: what it sends reaches the FC signed"
        ));
    }
    if !o.outs.is_empty() || !o.trusted_outs.is_empty() {
        log.info(&match o.link.routed_rate {
            Some(rate) => format!(
                "routed to the FC link: at most {rate} bytes/s (--routed-rate), the companion's own frames first"
            ),
            None => "routed to the FC link: unpaced (--routed-rate off)".to_string(),
        });
    }
}

impl Node for Daemon {
    fn poll_timeout(&self) -> Option<Moment> {
        self.node.poll_timeout()
    }

    fn handle_timeout(&mut self, now: Moment, net: &mut Net<'_, '_>) {
        self.node.handle_timeout(now);
        self.drain(now, net);
    }

    fn tick(&mut self, net: &mut Net<'_, '_>) {
        // The log writer's notes (a file begun, a write error) as they
        // come.
        if let Some(t) = &mut self.tlog {
            t.tlog.notes(net.log);
        }
    }

    fn handle_frame(&mut self, now: Moment, inbound: &Inbound<'_, Dialect>, net: &mut Net<'_, '_>) {
        let fate = self.node.handle_frame(now, net::arrival(inbound));
        match fate.dropped {
            Some(reason) => net.dropped(inbound, reason),
            None => {
                if let Some(t) = &mut self.tlog {
                    // The FC's own trusted HEARTBEAT says whether it is
                    // armed (`--log-mode while-armed`).
                    let h = inbound.frame.header();
                    let fc = fate.input && Peer::new(h.sysid, h.compid) == self.fc;
                    if let Some(armed) = fc.then(|| super::vehicle::armed(&inbound.frame)).flatten()
                    {
                        t.tlog.set_armed(armed);
                    }
                    t.tlog.received(inbound.link, inbound.frame.as_bytes());
                }
                if fate.input && inbound.link == net.main() {
                    self.describe(&inbound.frame, net.log);
                }
                if fate.sign {
                    net.out.route_signed(inbound, fate.route);
                } else if !fate.route.is_empty() {
                    net.out.route(inbound, fate.route);
                }
            }
        }
        self.drain(now, net);
    }

    fn link_reopened(&mut self, link: LinkId) {
        self.node.link_reopened(link);
    }

    fn report(&mut self, net: &mut Net<'_, '_>) {
        net.report_drops(self.node.drops(), &mut self.events);
        if let Some(t) = &mut self.tlog {
            t.report(net.log, &mut self.events);
        }
    }

    fn bad_signature(
        &mut self,
        now: Moment,
        link: LinkId,
        source: SocketAddr,
        sender: Peer,
        net: &mut Net<'_, '_>,
    ) {
        self.node.handle_bad_signature(now, link, source, sender);
        self.drain(now, net);
    }

    fn status(&mut self, net: &mut Net<'_, '_>) {
        let state = match self.node.engine().state() {
            CcState::Idle if self.fc_found => "lost",
            CcState::Idle => "never heard",
            CcState::Standby => "found",
            CcState::Controlling => "controlling",
        };
        let mut more = serde_json::Map::new();
        more.insert("fc".into(), state.into());
        if let Some(silent) = self.autonomy_silent {
            let autonomy = if silent { "silent" } else { "speaking" };
            more.insert("autonomy".into(), autonomy.into());
        }
        more.insert("takeovers".into(), self.report.takeovers.into());
        net.status(self.node.drops(), more, &mut self.events);
    }

    fn events(&mut self) -> &mut Events {
        &mut self.events
    }

    fn done(&self, clock: &Clock) -> bool {
        self.duration
            .is_some_and(|d| clock.secs() >= d.as_secs_f64())
            || (self.exit_after_handback
                && self.report.handbacks > 0
                && self.node.engine().state() != CcState::Controlling)
    }
}

impl Daemon {
    /// Carries out the node's outputs.
    fn drain(&mut self, now: Moment, net: &mut Net<'_, '_>) {
        while let Some(out) = self.node.poll_output() {
            match out {
                Output::Transmit { links, message } => {
                    self.note_sent(&message, net.log);
                    if let Some(t) = &mut self.tlog {
                        t.sent(self.own, &message);
                    }
                    net.out
                        .send_message(links, self.own.sysid, self.own.compid, &message);
                }
                Output::TransmitTo { link, to, message } => {
                    if let Some(t) = &mut self.tlog {
                        t.sent(self.own, &message);
                    }
                    net.out.send_message_to(
                        Links::only(link),
                        Some(to),
                        self.own.sysid,
                        self.own.compid,
                        &message,
                    );
                }
                Output::Peers { link, peers } => net.set_peers(link, peers),
                Output::Event(CompanionEvent::Engine(event)) => {
                    self.engine_event(now, event, net.log)
                }
                Output::Event(CompanionEvent::AutonomySilent(silent)) => {
                    self.autonomy_silent = Some(silent);
                    if silent {
                        net.log.warn("autonomy silent");
                    } else {
                        net.log.notice("autonomy speaks");
                    }
                    self.events.emit(
                        "autonomy",
                        json!({"state": if silent { "silent" } else { "speaking" }}),
                    );
                }
                // Outputs added later.
                _ => {}
            }
        }
    }

    fn engine_event(&mut self, now: Moment, event: CcOutput, log: &mut Log) {
        match event {
            CcOutput::ControlDue => {
                if let Some(c) = &mut self.controller {
                    let control = c.control(now, self.node.engine().machine().config().fc);
                    let _ = self.node.submit_control(now, control);
                }
            }
            CcOutput::ControlStarted { event } => {
                self.report.takeovers += 1;
                let who = self
                    .controller
                    .as_ref()
                    .map_or("the autonomy", |c| c.name());
                log.notice(&format!("takeover (event {event}): {who} streams control"));
                self.events
                    .emit("control", json!({"state": "start", "fc_event": event}));
            }
            CcOutput::ControlStopped => {
                log.notice("control ends: overrides stopped");
                self.events.emit("control", json!({"state": "stop"}));
            }
            CcOutput::Declined { event } => {
                log.warn(&format!(
                    "takeover of event {event} declined: the autonomy is silent (the FC falls back)"
                ));
                self.events.emit(
                    "takeover",
                    json!({"decision": "declined", "reason": "autonomy silent", "fc_event": event}),
                );
            }
            CcOutput::FcFound => {
                self.fc_found = true;
                log.notice("FC found");
                self.events.emit("fc", json!({"state": "found"}));
            }
            CcOutput::FcLost => {
                log.warn("FC lost (silent)");
                self.events.emit("fc", json!({"state": "lost"}));
            }
            CcOutput::FcRebooted => {
                log.warn("FC rebooted: answering its new boot");
                self.events.emit("fc", json!({"state": "rebooted"}));
            }
            CcOutput::Superseded { event, by } => {
                let by = format!("{}/{}", by.sysid, by.compid);
                log.error(&format!(
                    "the FC accepted companion {by} for event {event}, not this one: control stopped"
                ));
                self.events.emit(
                    "takeover",
                    json!({"decision": "superseded", "by": by, "fc_event": event}),
                );
            }
            // Sent through the node; and outputs added later.
            _ => {}
        }
    }

    /// Logs the companion's notices as they go, and counts hand-backs.
    fn note_sent(&mut self, msg: &Message, log: &mut Log) {
        if let Message::FbwagNotice(n) = msg {
            log.info(&format!(
                "-> FBWAG_NOTICE status {} event {}",
                n.failsafe_status.0, n.timestamp
            ));
            if n.failsafe_status == Status::NORMAL
                && self.node.engine().machine().stats().declines == 0
            {
                self.report.handbacks += 1;
            }
        }
    }

    /// Logs what the FC says that a person follows: notices, its mode,
    /// its confirmations.
    fn describe(&mut self, frame: &Received<'_, Dialect>, log: &mut Log) {
        let f = frame.frame();
        match MessageView::new(f.msg_id(), f.payload()) {
            Some(MessageView::FbwagNotice(n)) => {
                self.heard
                    .log(log, Level::Info, "notices, texts and mode changes", || {
                        format!(
                            "<- FBWAG_NOTICE status {} event {}",
                            n.failsafe_status().0,
                            n.timestamp()
                        )
                    })
            }
            Some(MessageView::Statustext(t)) => {
                self.heard
                    .log(log, Level::Info, "notices, texts and mode changes", || {
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
                    log.info(&format!(
                        "({n} more notices, texts and mode changes suppressed)"
                    ));
                }
                if show {
                    self.fc_mode = Some(h.custom_mode());
                    let mode = mode_name(h.custom_mode());
                    log.notice(&format!("FC mode {mode}"));
                    self.events.emit("fc_mode", json!({"mode": mode}));
                }
            }
            _ => {}
        }
    }

    fn summary(&mut self, tlog: Option<TlogCounts>) {
        let s = *self.node.engine().stats();
        let mut summary = json!({
                "takeovers": self.report.takeovers,
                "handbacks": self.report.handbacks,
                "trusted_frames": s.trusted_frames,
                "untrusted_frames": s.untrusted_frames,
                "untrusted_notices": s.untrusted_notices,
                "controls_forwarded": s.controls_forwarded,
                "controls_dropped": s.controls_dropped,
                "dropped": net::drop_counts(self.node.drops()),
        });
        if let Some(counts) = tlog {
            summary["tlog"] = counts.json();
        }
        self.events.emit("summary", summary);
    }
}
