//! The one shape of every daemon (`fbwag cc`, `fbwag fc-sim`, `fbwag
//! router`): its links on `mavframe::router`, and its node as their policy.
//!
//! A frame a link receives is judged by the node in the task that received
//! it ([`Shell`], the router's policy: the node's `handle_frame`, then what
//! the node asks for, carried out at once through the router's
//! [`Out`]); the daemon's loop ([`run`]) runs the node's timers, the
//! reports and the status, and stops the links at the end.
//!
//! The rules every daemon follows here:
//! - no send or receive error ends the program: a failed link is logged
//!   (at most 5 lines per 10 s) and opened again every second;
//! - receive work is bounded: link tasks parse at most 1 KB without a
//!   frame between yields, and a frame's judgement is the node's few
//!   steps, so a flood delays the receiver sampling and the timers by a
//!   batch's work;
//! - who is answered and where each frame goes is the node policy's
//!   (`fbwag_delegation::node`): with `--peer ADDR` a listening link
//!   answers ADDR only; otherwise it answers whom the node names
//!   ([`Net::set_peers`]), never whoever spoke last;
//! - frames the node drops and each link's parser refusals are logged
//!   rate-limited, with counts.

use super::signals::StopSignals;
use super::{Clock, Events, Health, Level, Limiter, Log};
use crate::args::{LinkFilter, RoutedRate};
use fbwag_delegation::node::{Answers, Arrival, Direction, DropReason, Drops, Filter, Peers};
use fbwag_delegation::{Moment, Peer};
use fbwag_dialect::mavframe::parser::{Stats, Unsigned};
use fbwag_dialect::mavframe::route::{LinkId, Links};
use fbwag_dialect::mavframe::router::{
    Inbound, LinkConfig, LinkCounters, Out, Policy, Router, RouterEvent,
};
use fbwag_dialect::mavframe::signing::state::{Loaded, StateFile};
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{Dialect, Endpoint};
use serde_json::json;
use std::io;
use std::net::SocketAddr;
use std::num::NonZeroU32;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::Notify;

/// The longest the loop waits without looking at the clock.
const MAX_WAIT: Duration = Duration::from_millis(100);

/// The settings of a daemon's main link (to its protocol peer).
#[derive(Debug, Clone)]
pub struct LinkOptions {
    /// Where to connect or listen.
    pub endpoint: Endpoint,
    /// Its name (`NAME=CONN`), for the log and events.
    pub name: Option<String>,
    /// Sign what is sent and verify what comes with this key.
    pub key: Option<[u8; 32]>,
    /// `udpin` and `tcpin`: answer this address and no other.
    pub peer: Option<SocketAddr>,
    /// Keep the signer's and verifier's timestamps across restarts in this
    /// file (with `key`).
    pub signing_state: Option<PathBuf>,
    /// Bytes a second at most of what is routed to the link
    /// ([`LinkConfig::routed_rate`]): see [`routed_rate`].
    pub routed_rate: Option<NonZeroU32>,
}

/// A link's connection and the name it was given (`NAME=CONN`).
#[derive(Debug, Clone, PartialEq)]
pub struct Named {
    pub endpoint: Endpoint,
    pub name: Option<String>,
}

impl std::fmt::Display for Named {
    /// `NAME=CONN`, or `CONN` without a name.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.name {
            Some(name) => write!(f, "{name}={}", self.endpoint),
            None => write!(f, "{}", self.endpoint),
        }
    }
}

/// Routed bytes a second a daemon's main link takes by default when it is
/// not serial (a serial link's baud rate says what it carries): more than a
/// ground station's uplink needs (heartbeats, commands, parameter and
/// mission transfers: a few hundred), and less than a 115,200-baud link
/// carries (11.5 kB/s), so that a flood routed to such a link cannot fill
/// the buffer at its far end. A slower link behind TCP or UDP (a
/// 57,600-baud radio) needs `--routed-rate` set below its rate.
pub const DEFAULT_ROUTED_RATE: u32 = 8_000;

/// The pace of what is routed to the main link `endpoint`: as `given` by
/// `--routed-rate`, else half a serial link's byte rate (10 bits a byte on
/// the line), else [`DEFAULT_ROUTED_RATE`].
pub fn routed_rate(endpoint: &Endpoint, given: Option<RoutedRate>) -> Option<NonZeroU32> {
    let rate = match (given, endpoint) {
        (Some(RoutedRate::Off), _) => return None,
        (Some(RoutedRate::BytesPerSecond(rate)), _) => rate,
        (None, Endpoint::Serial { baud, .. }) => baud / 20,
        (None, _) => DEFAULT_ROUTED_RATE,
    };
    NonZeroU32::new(rate.max(1))
}

/// The links a daemon opens, in order, each with the id it will have: the
/// node is made knowing them, then [`Plan::open`] opens them on a router
/// whose policy it is.
pub struct Plan {
    links: Vec<LinkConfig>,
    /// Links that answer one address, whatever the node says (`--peer`).
    fixed: Vec<(LinkId, SocketAddr)>,
}

impl Plan {
    /// No link yet.
    pub fn new() -> Plan {
        Plan {
            links: Vec::new(),
            fixed: Vec::new(),
        }
    }

    /// The main link (to the protocol peer), link 0. A signing state file
    /// that is damaged or cannot be written ends the program before it
    /// starts; said in `log`.
    pub fn main(opts: &LinkOptions, log: &mut Log) -> io::Result<Plan> {
        match (&opts.signing_state, opts.key) {
            (Some(path), Some(_)) => log_state_file(path, log)?,
            (None, Some(_)) => log.warn(
                "signing state: none kept (--signing-state): after a restart, frames captured \
                 up to a minute before are accepted once",
            ),
            _ => {}
        }
        let mut config = LinkConfig::new(opts.endpoint.clone());
        config.key = opts.key;
        config.unsigned = Unsigned::Accept;
        config.signing_state = opts.signing_state.clone();
        // The protocol's link: what is routed to it (a ground station's
        // traffic) must not sit ahead of its frames.
        config.bound_unsent = true;
        config.routed_rate = opts.routed_rate;
        config.name = opts.name.clone();
        let mut plan = Plan::new();
        plan.push(config, opts.peer);
        Ok(plan)
    }

    /// Another link: `key` verifies its frames' signatures (and signs what
    /// this node sends there); `peer`: a listening link answers this
    /// address only, else whom the node names. Its id.
    pub fn add(&mut self, link: &Named, key: Option<[u8; 32]>, peer: Option<SocketAddr>) -> LinkId {
        self.add_checked(link, key, peer, false)
    }

    /// [`add`](Self::add), and with `loopback_only` the link opens only on
    /// a loopback address, checked at every (re)open after its host name
    /// is resolved again (a link trusted like the key).
    pub fn add_checked(
        &mut self,
        link: &Named,
        key: Option<[u8; 32]>,
        peer: Option<SocketAddr>,
        loopback_only: bool,
    ) -> LinkId {
        let mut config = LinkConfig::new(link.endpoint.clone());
        config.key = key;
        config.loopback_only = loopback_only;
        config.name = link.name.clone();
        self.push(config, peer)
    }

    /// A link as `config` says, answering `peer` only when given: its id.
    pub fn push(&mut self, config: LinkConfig, peer: Option<SocketAddr>) -> LinkId {
        let id = self.links.len() as LinkId;
        if let (Some(peer), true) = (peer, config.is_listening()) {
            self.fixed.push((id, peer));
        }
        self.links.push(config);
        id
    }

    /// Opens the links now, in order, on a router judging their frames by
    /// `shell`: errors here (an unsupported link, a damaged signing state
    /// file) end the program before it starts; later errors never do.
    pub async fn open<N: Node>(self, shell: Shell<N>) -> io::Result<Router<Dialect, Shell<N>>> {
        let mut router = Router::new(shell);
        for config in self.links {
            let endpoint = config.endpoint.clone();
            router.add(config).await.map_err(|e| opened(&endpoint, e))?;
        }
        router.with(|shell, out| {
            for (link, peer) in self.fixed {
                out.set_peers(link, &[peer]);
                shell.state.fixed.push(link);
            }
        });
        Ok(router)
    }
}

impl Default for Plan {
    fn default() -> Self {
        Plan::new()
    }
}

/// What a daemon keeps of its links between frames: logs' limits, the
/// reports' and the status's state.
pub struct NetState {
    /// The link to the protocol peer.
    main: LinkId,
    /// Frames the node dropped, logged at most 5 lines per 10 s.
    dropped: Limiter,
    link_changes: LinkChanges,
    /// The node's drop counts when last reported.
    drops_seen: Drops,
    reports: LinkReports,
    /// The text report's period (`None`: none).
    report: Option<Duration>,
    /// The links' state and totals, for `link` and `status` events.
    health: Health,
    /// Links that answer one address (`--peer`), whatever the node says.
    fixed: Vec<LinkId>,
}

/// A daemon's links, as its node acts on them: the router's [`Out`] (under
/// the lock the links share, for as long as a frame is judged or a timer
/// runs), the log, and what the daemon keeps of its links.
pub struct Net<'a, 'o> {
    /// The links' ways out: where frames go.
    pub out: &'a mut Out<'o>,
    /// The daemon's log.
    pub log: &'a mut Log,
    state: &'a mut NetState,
}

impl Net<'_, '_> {
    /// The link to the protocol peer.
    pub fn main(&self) -> LinkId {
        self.state.main
    }

    /// Sends `msg` as `sysid`/`compid` on the main link (framed and signed
    /// by the link). Never fails: a full queue or a failed send is counted
    /// by the link.
    pub fn send(&mut self, sysid: u8, compid: u8, msg: &(impl Encode + ?Sized)) {
        let main = self.state.main;
        self.out.send_message(Links::only(main), sysid, compid, msg);
    }

    /// A listening link answers `peers` from now on (the node's choice;
    /// one that answers `--peer` keeps it).
    pub fn set_peers(&mut self, link: LinkId, peers: Peers) {
        if self.state.fixed.contains(&link) {
            return;
        }
        let list: Vec<SocketAddr> = peers.iter().collect();
        self.out.set_peers(link, &list);
        let name = self.out.name(link);
        let list: Vec<String> = list.iter().map(ToString::to_string).collect();
        self.log
            .info(&format!("{name}: answering {}", list.join(", ")));
    }

    /// A frame the node dropped: logged, rate-limited.
    pub fn dropped(&mut self, inbound: &Inbound<'_, Dialect>, reason: DropReason) {
        let name = self.out.name(inbound.link);
        let frame = &inbound.frame;
        self.state
            .dropped
            .log(self.log, Level::Warn, "dropped frames", || {
                let h = frame.header();
                format!(
                    "{name}: dropped {} from {}/{}{}{}: {}",
                    frame.meta().map_or("an unknown message", |m| m.name),
                    h.sysid,
                    h.compid,
                    if frame.is_authenticated() {
                        ", signed"
                    } else {
                        ", not authenticated"
                    },
                    inbound.source.map_or(String::new(), |s| format!(" ({s})")),
                    reason.name(),
                )
            });
    }

    /// With the links' reports (every report period): the node's drops so
    /// far, by reason, when they changed.
    pub fn report_drops(&mut self, drops: &Drops, events: &mut Events) {
        if drops.total() == self.state.drops_seen.total() {
            return;
        }
        self.state.drops_seen = *drops;
        events.emit("drops", json!({ "dropped": drop_counts(drops) }));
    }

    /// The status event ([`Health::status`]) with the node's `drops` and
    /// its own state (`more`).
    pub fn status(
        &mut self,
        drops: &Drops,
        more: serde_json::Map<String, serde_json::Value>,
        events: &mut Events,
    ) {
        self.state.health.status(self.out, drops, more, events);
    }
}

/// A daemon's node as its router's policy: each frame to the node, and on
/// where it says; the links' changes logged and reported.
pub struct Shell<N> {
    /// The daemon.
    pub node: N,
    /// Its log.
    pub log: Log,
    clock: Clock,
    state: NetState,
    /// Wakes the daemon's loop when a frame moves the node's next deadline
    /// earlier than the one it sleeps to.
    wake: Arc<Notify>,
    /// The deadline the loop sleeps to.
    armed: Option<Moment>,
}

impl<N: Node> Shell<N> {
    /// `node` on links whose main one is `main`, reporting every `report`
    /// in the log (`None`: never), and a status event then (every
    /// [`super::STATUS_EVERY`] without).
    pub fn new(node: N, log: Log, clock: Clock, main: LinkId, report: Option<Duration>) -> Self {
        Shell {
            node,
            log,
            clock,
            state: NetState {
                main,
                dropped: Limiter::new(5, Duration::from_secs(10)),
                link_changes: LinkChanges::default(),
                drops_seen: Drops::default(),
                reports: LinkReports::default(),
                report,
                health: Health::new(report.unwrap_or(super::STATUS_EVERY)),
                fixed: Vec::new(),
            },
            wake: Arc::new(Notify::new()),
            armed: None,
        }
    }

    /// The node, the log and the links, for `f`.
    fn net<R>(&mut self, out: &mut Out<'_>, f: impl FnOnce(&mut N, &mut Net<'_, '_>) -> R) -> R {
        let mut net = Net {
            out,
            log: &mut self.log,
            state: &mut self.state,
        };
        f(&mut self.node, &mut net)
    }

    /// The loop is woken when the node's next deadline came earlier.
    fn rearm(&mut self) {
        let next = self.node.poll_timeout();
        if next.is_some_and(|t| self.armed.is_none_or(|armed| t < armed)) {
            self.armed = next;
            self.wake.notify_one();
        }
    }

    /// One turn of the daemon's loop at `now`: the node's timers when due,
    /// the reports and the status when due. How long the loop may sleep
    /// then, or `None` when the node is done.
    fn turn(&mut self, out: &mut Out<'_>) -> Option<Duration> {
        let now = self.clock.now();
        if self.node.poll_timeout().is_some_and(|t| t <= now) {
            self.net(out, |node, net| node.handle_timeout(now, net));
        }
        self.net(out, |node, net| node.tick(net));
        if self
            .state
            .report
            .is_some_and(|every| self.state.reports.since() >= every)
        {
            self.state.reports.report(out, &mut self.log);
            self.net(out, |node, net| node.report(net));
        }
        if self.state.health.due() {
            self.net(out, |node, net| node.status(net));
        }
        if self.node.done(&self.clock) {
            return None;
        }
        self.armed = self.node.poll_timeout();
        let wait = self
            .armed
            .map_or(MAX_WAIT, |t| self.clock.until(t).min(MAX_WAIT));
        Some(wait)
    }
}

impl<N: Node> Policy<Dialect> for Shell<N> {
    fn frame(&mut self, inbound: &Inbound<'_, Dialect>, out: &mut Out<'_>) {
        let now = self.clock.now();
        self.net(out, |node, net| node.handle_frame(now, inbound, net));
        self.rearm();
    }

    fn event(&mut self, event: RouterEvent, out: &mut Out<'_>) {
        if let RouterEvent::BadSignature {
            link,
            source,
            sender,
        } = event
        {
            let now = self.clock.now();
            let sender = Peer::new(sender.0, sender.1);
            self.net(out, |node, net| {
                node.bad_signature(now, link, source, sender, net)
            });
        } else {
            self.state.health.changed(out, &event, self.node.events());
            let reopened = self.state.link_changes.log(out, event, &mut self.log);
            if let Some(link) = reopened.filter(|l| !self.state.fixed.contains(l)) {
                // Whom it answered is forgotten, by the node and the link.
                out.set_peers(link, &[]);
            }
            if let Some(link) = reopened {
                self.node.link_reopened(link);
            }
        }
        self.rearm();
    }
}

/// What each link's parser refused (bad checksums, bad signatures,
/// unsigned frames, bytes dropped) and what each link lost (frames dropped
/// for a full queue, send errors, signing state saves that failed) since
/// the last report: a line or two per link when there is anything to say,
/// whatever the flood.
pub struct LinkReports {
    /// Each link's counters when last reported.
    seen: Vec<LinkCounters>,
    at: tokio::time::Instant,
}

impl Default for LinkReports {
    fn default() -> Self {
        LinkReports {
            seen: Vec::new(),
            at: tokio::time::Instant::now(),
        }
    }
}

impl LinkReports {
    /// The time since the last report.
    pub fn since(&self) -> Duration {
        self.at.elapsed()
    }

    /// Logs what each link refused and lost since the last report.
    pub fn report(&mut self, out: &Out<'_>, log: &mut Log) {
        let secs = self.at.elapsed().as_secs_f64().round().max(1.0);
        self.at = tokio::time::Instant::now();
        for link in out.links().iter() {
            let counters = out.counters(link);
            let i = usize::from(link);
            if self.seen.len() <= i {
                self.seen.resize(i + 1, LinkCounters::default());
            }
            let was = std::mem::replace(&mut self.seen[i], counters);
            let name = out.name(link);
            let lost = lost_parts(&was, &counters);
            if !lost.is_empty() {
                log.warn(&format!("{name}: link lost in the last {secs} s: {lost}"));
            }
            let refused = refused_parts(&was.parser, &counters.parser);
            if !refused.is_empty() {
                log.warn(&format!(
                    "{name}: link refused in the last {secs} s: {refused}"
                ));
            }
        }
    }
}

/// What a link's parser refused from `was` to `now`, in words ("" if
/// nothing). A reopened link's parser counts from zero again: saturating,
/// what it refused before is not reported.
fn refused_parts(was: &Stats, now: &Stats) -> String {
    in_words(&[
        ("bad checksums", now.bad_crc.saturating_sub(was.bad_crc)),
        (
            "bad signatures",
            now.bad_signature.saturating_sub(was.bad_signature),
        ),
        (
            "stale signing timestamps",
            now.stale_timestamp.saturating_sub(was.stale_timestamp),
        ),
        (
            "unsigned refused",
            now.unsigned_rejected.saturating_sub(was.unsigned_rejected),
        ),
        (
            "bytes dropped",
            now.bytes_dropped.saturating_sub(was.bytes_dropped),
        ),
    ])
}

/// The counts that are not 0, as "N what, M what".
fn in_words(counts: &[(&str, u64)]) -> String {
    let parts: Vec<String> = counts
        .iter()
        .filter(|(_, n)| *n > 0)
        .map(|(what, n)| format!("{n} {what}"))
        .collect();
    parts.join(", ")
}

/// Links' failures and returns, logged: failures at most 5 lines per 10 s
/// (a link that keeps failing is opened again every second).
pub struct LinkChanges {
    errors: Limiter,
}

impl Default for LinkChanges {
    fn default() -> Self {
        LinkChanges {
            errors: Limiter::new(5, Duration::from_secs(10)),
        }
    }
}

impl LinkChanges {
    /// A link's change: logged; returns the link opened again, whose peers
    /// the node forgets.
    pub fn log(&mut self, out: &Out<'_>, event: RouterEvent, log: &mut Log) -> Option<LinkId> {
        match event {
            RouterEvent::LinkDown { link, error } => {
                let name = out.name(link);
                self.errors.log(log, Level::Error, "link errors", || {
                    format!("link {name} failed ({error}); opening it again every second")
                });
                None
            }
            RouterEvent::LinkUp { link } => {
                log.notice(&format!("link {} open again", out.name(link)));
                Some(link)
            }
            // What later versions of the router report.
            _ => None,
        }
    }
}

/// What a link lost from `was` to `now`, in words ("" if nothing).
fn lost_parts(was: &LinkCounters, now: &LinkCounters) -> String {
    in_words(&[
        (
            "frames dropped (queue full)",
            now.dropped_full.saturating_sub(was.dropped_full),
        ),
        (
            "routed frames dropped (more routed to the link than it carries)",
            now.routed_dropped.saturating_sub(was.routed_dropped),
        ),
        (
            "send errors",
            now.send_errors.saturating_sub(was.send_errors),
        ),
        (
            "signing state saves failed (a restart would start from the last state saved)",
            now.state_save_errors.saturating_sub(was.state_save_errors),
        ),
    ])
}

/// Gives the node each filter of `filters` (`set`), on the link at its
/// place in `links` (called as its place in `endpoints` says), and logs
/// it.
pub fn set_filters<E: std::error::Error + Send + Sync + 'static>(
    filters: &[LinkFilter],
    links: &[LinkId],
    endpoints: &[String],
    log: &mut Log,
    mut set: impl FnMut(LinkId, Direction, Filter) -> Result<(), E>,
) -> io::Result<()> {
    for f in filters {
        let (Some(link), Some(endpoint)) = (links.get(f.index), endpoints.get(f.index)) else {
            let error = format!("no link {} to filter", f.index + 1);
            return Err(io::Error::new(io::ErrorKind::InvalidInput, error));
        };
        set(*link, f.direction, f.filter)
            .map_err(|err| io::Error::new(io::ErrorKind::InvalidInput, err))?;
        let way = match f.direction {
            Direction::In => "in from",
            Direction::Out => "out to",
        };
        log.info(&format!("filter {way} {endpoint}: {}", f.rules.join(" ")));
    }
    Ok(())
}

/// Whom a link opened to `endpoint` answers, for the node policy.
pub fn answers(endpoint: &Endpoint, peer: Option<SocketAddr>) -> Answers {
    match (endpoint, peer) {
        (Endpoint::UdpIn(_) | Endpoint::TcpIn(_), Some(peer)) => Answers::Fixed(peer),
        (Endpoint::UdpIn(_) | Endpoint::TcpIn(_), None) => Answers::Chosen,
        _ => Answers::Target,
    }
}

/// A frame a link delivered, as the node policy takes it.
pub fn arrival<'a>(inbound: &Inbound<'a, Dialect>) -> Arrival<'a> {
    Arrival {
        link: inbound.link,
        source: inbound.source,
        frame: inbound.frame.frame(),
        authenticated: inbound.frame.is_authenticated(),
    }
}

/// The node's drops as a JSON object: reason -> count.
pub fn drop_counts(drops: &Drops) -> serde_json::Value {
    drops
        .counts()
        .map(|(reason, n)| (reason.name().to_string(), n.into()))
        .collect::<serde_json::Map<_, _>>()
        .into()
}

/// `e`, naming the link that could not be opened.
pub fn opened(endpoint: &Endpoint, e: io::Error) -> io::Error {
    io::Error::new(e.kind(), format!("cannot open {endpoint}: {e}"))
}

/// Says what the signing state file holds (the router opens it again);
/// a damaged file stops the program: it could mean tampering, and dropping
/// it silently would reopen replays. So does a file that cannot be written
/// (written back now, as loaded): every save would fail, and the next start
/// would begin from the clock.
fn log_state_file(path: &std::path::Path, log: &mut Log) -> io::Result<()> {
    let (file, loaded) = StateFile::open(path).map_err(|e| {
        io::Error::other(format!(
            "signing state {}: {e}; remove the file to start from the clock",
            path.display()
        ))
    })?;
    file.state().save(path).map_err(|e| {
        io::Error::other(format!(
            "signing state {}: cannot be written (saves replace the file: its directory must be writable): {e}",
            path.display()
        ))
    })?;
    log.info(&match loaded {
        Loaded::Existing => format!(
            "signing state: loaded {} ({} streams)",
            path.display(),
            file.state().streams.len()
        ),
        Loaded::Fresh => format!(
            "signing state: no file at {} yet, starting from the clock",
            path.display()
        ),
    });
    Ok(())
}

/// What a daemon does with time and frames: its node, and what it
/// reports.
pub trait Node: Send + 'static {
    /// When [`Node::handle_timeout`] must next run.
    fn poll_timeout(&self) -> Option<Moment>;
    /// Timers due at `now`.
    fn handle_timeout(&mut self, now: Moment, net: &mut Net<'_, '_>);
    /// A frame from any link (see `inbound.link`), in the task that
    /// received it: the node policy decides its fate; the daemon carries
    /// it out.
    fn handle_frame(&mut self, now: Moment, inbound: &Inbound<'_, Dialect>, net: &mut Net<'_, '_>);
    /// Link `link` was opened again.
    fn link_reopened(&mut self, link: LinkId);
    /// Link `link`'s parser refused a frame of `sender` from `source` for
    /// its signature (the node may answer: a wrong key shows on both
    /// sides).
    fn bad_signature(
        &mut self,
        now: Moment,
        link: LinkId,
        source: SocketAddr,
        sender: Peer,
        net: &mut Net<'_, '_>,
    );
    /// Each turn of the daemon's loop (at least every 100 ms): notes of
    /// its own to log.
    fn tick(&mut self, net: &mut Net<'_, '_>) {
        let _ = net;
    }
    /// With the links' periodic report: the node's own (drops by reason,
    /// the telemetry log's losses).
    fn report(&mut self, net: &mut Net<'_, '_>);
    /// The status event ([`Net::status`]) with the node's drops and its
    /// own state.
    fn status(&mut self, net: &mut Net<'_, '_>);
    /// Its events, for the links' changes.
    fn events(&mut self) -> &mut Events;
    /// True when the daemon should stop.
    fn done(&self, clock: &Clock) -> bool;
    /// At the end, after the last status, the links still open: the
    /// daemon's summary of what they carried.
    fn finish(&mut self, net: &mut Net<'_, '_>) {
        let _ = net;
    }
}

/// Runs the daemon on `router` (its links, and its node as their
/// policy, which judges each frame in the link's task) until the node is
/// done: the node's timers when due, the reports and the status; then the
/// last status, and the links are stopped, each saving its signing state.
/// With `signals`, SIGTERM (and SIGINT or SIGHUP, from a terminal) end it
/// the same way ([`StopSignals`]). The daemon's node and log, for what it
/// says at the end.
pub async fn run<N: Node>(
    router: Router<Dialect, Shell<N>>,
    signals: bool,
) -> io::Result<Shell<N>> {
    let (wake, signals) = router.with(|shell, out| {
        shell.state.health.started(out, shell.node.events());
        (
            shell.wake.clone(),
            StopSignals::new(signals, &mut shell.log),
        )
    });
    let mut stopped = signals.watch();
    // One timer, reset each turn: not one made per turn.
    let timer = tokio::time::sleep(Duration::ZERO);
    tokio::pin!(timer);
    while let Some(wait) = router.with(|shell, out| shell.turn(out)) {
        timer.as_mut().reset(tokio::time::Instant::now() + wait);
        tokio::select! {
            () = &mut timer => {}
            () = wake.notified() => {}
            Ok(name) = &mut stopped, if !stopped.is_terminated() => {
                router.with(|shell, _| shell.log.notice(&format!("{name}: stopping (again to stop at once)")));
                break;
            }
        }
    }
    // The last status, before the summary.
    router.with(|shell, out| {
        shell.net(out, |node, net| {
            node.status(net);
            node.finish(net);
        })
    });
    router
        .shutdown(Duration::from_secs(1))
        .await
        .ok_or_else(|| io::Error::other("a link task outlived the daemon"))
}

/// Runs `daemon` on a current-thread tokio runtime, as a task: a task
/// its links wake is queued and run, where the future `block_on` drives
/// would cost an extra poll of the system's readiness per wake (an
/// `epoll_wait` per frame routed).
pub fn block_on<T: Send + 'static>(
    daemon: impl std::future::Future<Output = io::Result<T>> + Send + 'static,
) -> io::Result<T> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    rt.block_on(async {
        survive_file_size_limit();
        tokio::spawn(daemon).await
    })
    .unwrap_or_else(|e| std::panic::resume_unwind(e.into_panic()))
}

/// A file grown past the process's size limit (`ulimit -f`, `LimitFSIZE=`)
/// raises SIGXFSZ, whose default action ends the program: a daemon would
/// stop routing for its log. Handled instead, the write fails with EFBIG
/// like any other write error. (tokio's handler stays for the rest of the
/// process, so the listener need not.)
fn survive_file_size_limit() {
    #[cfg(unix)]
    {
        use tokio::signal::unix::{signal, SignalKind};
        let xfsz = rustix::process::Signal::XFSZ.as_raw();
        let _ = signal(SignalKind::from_raw(xfsz));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn routed_traffic_is_paced_below_the_link_by_default() {
        let serial: Endpoint = "serial:/dev/ttyS0:57600".parse().unwrap();
        let tcp: Endpoint = "tcp:127.0.0.1:5760".parse().unwrap();
        let rate = |e: &Endpoint, given| routed_rate(e, given).map(NonZeroU32::get);
        assert_eq!(rate(&serial, None), Some(2_880), "half of 5,760 B/s");
        assert_eq!(rate(&tcp, None), Some(DEFAULT_ROUTED_RATE));
        let given = Some(RoutedRate::BytesPerSecond(100));
        assert_eq!(rate(&serial, given), Some(100));
        assert_eq!(rate(&tcp, Some(RoutedRate::Off)), None);
        let slow: Endpoint = "serial:/dev/ttyS0:10".parse().unwrap();
        assert_eq!(rate(&slow, None), Some(1), "never 0");
    }
}
