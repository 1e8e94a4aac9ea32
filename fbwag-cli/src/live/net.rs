//! A daemon's MAVLink node: its links on `mavframe::router` (one tokio task
//! each, parsing each datagram on its own, verifying signatures, reopening
//! what fails), and the loop both daemons run.
//!
//! The rules every daemon follows here:
//! - no send or receive error ends the program: a failed link is logged
//!   (at most 5 lines per 10 s) and opened again every second;
//! - receive work is bounded: link tasks parse at most 1 KB between yields,
//!   and the loop services the protocol's timers before every frame, so a
//!   flood delays the receiver sampling and the timers by one frame's work;
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
use fbwag_dialect::mavframe::conn::ReplyTo;
use fbwag_dialect::mavframe::parser::{Stats, Unsigned};
use fbwag_dialect::mavframe::route::{LinkId, Links};
use fbwag_dialect::mavframe::router::{Inbound, LinkConfig, LinkCounters, Router, RouterEvent};
use fbwag_dialect::mavframe::signing::state::{Loaded, StateFile};
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{Dialect, Endpoint};
use serde_json::json;
use std::io;
use std::net::SocketAddr;
use std::num::NonZeroU32;
use std::path::PathBuf;
use std::time::Duration;

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

/// A daemon's links: the main one (to the protocol peer) and any others.
pub struct Net {
    /// The router carrying every link.
    pub router: Router<Dialect>,
    /// The link to the protocol peer.
    pub main: LinkId,
    /// Frames the node dropped, logged at most 5 lines per 10 s.
    dropped: Limiter,
    link_changes: LinkChanges,
    /// The node's drop counts when last reported.
    drops_seen: Drops,
    reports: LinkReports,
    /// The text report's period (`None`: none).
    report: Option<Duration>,
    /// The links' state and totals, for `link` and `status` events.
    pub health: Health,
}

impl Net {
    /// Opens the main link now: errors here (address in use, no such
    /// device, a damaged signing state file) end the program before it
    /// starts; later errors never do.
    pub async fn open(opts: &LinkOptions, log: &mut Log) -> io::Result<Net> {
        match (&opts.signing_state, opts.key) {
            (Some(path), Some(_)) => log_state_file(path, log)?,
            (None, Some(_)) => log.warn(
                "signing state: none kept (--signing-state): after a restart, frames captured \
                 up to a minute before are accepted once",
            ),
            _ => {}
        }
        let mut router = Router::new();
        let mut config = LinkConfig::new(opts.endpoint.clone());
        config.key = opts.key;
        config.unsigned = Unsigned::Accept;
        config.reply_to = reply_to(opts.peer);
        config.signing_state = opts.signing_state.clone();
        // The protocol's link: what is routed to it (a ground station's
        // traffic) must not sit ahead of its frames.
        config.bound_unsent = true;
        config.routed_rate = opts.routed_rate;
        config.name = opts.name.clone();
        let main = router
            .add(config)
            .await
            .map_err(|e| opened(&opts.endpoint, e))?;
        Ok(Net {
            router,
            main,
            dropped: Limiter::new(5, Duration::from_secs(10)),
            link_changes: LinkChanges::default(),
            drops_seen: Drops::default(),
            reports: LinkReports::default(),
            report: None,
            health: Health::new(super::STATUS_EVERY),
        })
    }

    /// Reports every `every` in the log (`None`: never), and a status
    /// event then (every [`super::STATUS_EVERY`] without).
    pub fn set_report(&mut self, every: Option<Duration>) {
        self.report = every;
        self.health = Health::new(every.unwrap_or(super::STATUS_EVERY));
    }

    /// Opens another link: `key` verifies its frames' signatures (and signs
    /// what this node sends there); `peer`: a listening link answers this
    /// address only, else whom the node names.
    pub async fn add(
        &mut self,
        endpoint: &Named,
        key: Option<[u8; 32]>,
        peer: Option<SocketAddr>,
    ) -> io::Result<LinkId> {
        self.add_checked(endpoint, key, peer, false).await
    }

    /// [`add`](Self::add), and with `loopback_only` the link opens only on
    /// a loopback address, checked at every (re)open after its host name
    /// is resolved again (a link trusted like the key).
    pub async fn add_checked(
        &mut self,
        link: &Named,
        key: Option<[u8; 32]>,
        peer: Option<SocketAddr>,
        loopback_only: bool,
    ) -> io::Result<LinkId> {
        let mut config = LinkConfig::new(link.endpoint.clone());
        config.key = key;
        config.reply_to = reply_to(peer);
        config.loopback_only = loopback_only;
        config.name = link.name.clone();
        self.router
            .add(config)
            .await
            .map_err(|e| opened(&link.endpoint, e))
    }

    /// Sends `msg` as `sysid`/`compid` on the main link (framed and signed
    /// by the link). Never fails: a full queue or a failed send is counted
    /// by the link.
    pub fn send(&self, sysid: u8, compid: u8, msg: &(impl Encode + ?Sized)) {
        self.router
            .send_message(Links::only(self.main), sysid, compid, msg);
    }

    /// A listening link answers `peers` from now on (the node's choice).
    pub fn set_peers(&mut self, link: LinkId, peers: Peers, log: &mut Log) {
        let list: Vec<SocketAddr> = peers.iter().collect();
        self.router.set_peers(link, &list);
        let name = self.name(link);
        let list: Vec<String> = list.iter().map(ToString::to_string).collect();
        log.info(&format!("{name}: answering {}", list.join(", ")));
    }

    /// A frame the node dropped: logged, rate-limited.
    pub fn dropped(&mut self, inbound: &Inbound<Dialect>, reason: DropReason, log: &mut Log) {
        let name = self.name(inbound.link);
        let frame = &inbound.frame;
        self.dropped.log(log, Level::Warn, "dropped frames", || {
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

    /// With the links' reports (every `--report` period): the node's
    /// drops so far, by reason, when they changed.
    pub fn report_drops(&mut self, drops: &Drops, events: &mut Events) {
        if drops.total() == self.drops_seen.total() {
            return;
        }
        self.drops_seen = *drops;
        events.emit("drops", json!({ "dropped": drop_counts(drops) }));
    }

    fn name(&self, link: LinkId) -> String {
        link_name(&self.router, link)
    }

    /// Every report period, the links' report ([`LinkReports`]): true
    /// when it was due.
    fn report_refused(&mut self, log: &mut Log) -> bool {
        if self.report.is_none_or(|every| self.reports.since() < every) {
            return false;
        }
        self.reports.report(&self.router, log);
        true
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

    /// Logs what each link of `router` refused and lost since the last
    /// report.
    pub fn report(&mut self, router: &Router<Dialect>, log: &mut Log) {
        let secs = self.at.elapsed().as_secs_f64().round().max(1.0);
        self.at = tokio::time::Instant::now();
        for link in router.links().iter() {
            let counters = router.counters(link);
            let i = usize::from(link);
            if self.seen.len() <= i {
                self.seen.resize(i + 1, LinkCounters::default());
            }
            let was = std::mem::replace(&mut self.seen[i], counters);
            let name = link_name(router, link);
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

/// The name of `link` in the log and events: the one it was given
/// (`NAME=CONN`), else its connection string.
pub fn link_name(router: &Router<Dialect>, link: LinkId) -> String {
    router.name(link)
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
    pub fn log(
        &mut self,
        router: &Router<Dialect>,
        event: RouterEvent<Dialect>,
        log: &mut Log,
    ) -> Option<LinkId> {
        match event {
            RouterEvent::LinkDown { link, error } => {
                let name = link_name(router, link);
                self.errors.log(log, Level::Error, "link errors", || {
                    format!("link {name} failed ({error}); opening it again every second")
                });
                None
            }
            RouterEvent::LinkUp { link } => {
                log.notice(&format!("link {} open again", link_name(router, link)));
                Some(link)
            }
            // Frames, and what later versions of the router report.
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

/// The `ReplyTo` rule of a link: `--peer`, or whom the node names.
pub fn reply_to(peer: Option<SocketAddr>) -> ReplyTo {
    peer.map_or(ReplyTo::Owner, ReplyTo::Fixed)
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
pub fn arrival(inbound: &Inbound<Dialect>) -> Arrival<'_> {
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

/// What a daemon does with time and frames.
pub trait Node {
    /// When [`Node::handle_timeout`] must next run.
    fn poll_timeout(&self) -> Option<Moment>;
    /// Timers due at `now`.
    fn handle_timeout(&mut self, now: Moment, net: &mut Net, log: &mut Log);
    /// A frame from any link (see `inbound.link`): the node policy decides
    /// its fate; the daemon carries it out.
    fn handle_frame(
        &mut self,
        now: Moment,
        inbound: &Inbound<Dialect>,
        net: &mut Net,
        log: &mut Log,
    );
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
        net: &mut Net,
        log: &mut Log,
    );
    /// With the links' periodic report: the node's own (drops by reason,
    /// the telemetry log's losses).
    fn report(&mut self, net: &mut Net, log: &mut Log);
    /// The status event ([`Health::status`]) with the node's drops and
    /// its own state.
    fn status(&mut self, net: &mut Net);
    /// Its events, for the links' changes.
    fn events(&mut self) -> &mut Events;
    /// True when the daemon should stop.
    fn done(&self, clock: &Clock) -> bool;
}

/// Runs `node` until it is done: timers when due, then one event (a frame
/// or a link's change) or the next deadline, whichever comes first; then
/// the links are stopped, each saving its signing state.
/// With `signals`, SIGTERM (and SIGINT or SIGHUP, from a terminal) end it
/// the same way ([`StopSignals`]).
pub async fn run(node: &mut impl Node, mut net: Net, clock: &Clock, log: &mut Log, signals: bool) {
    let mut stopped = StopSignals::new(signals, log).watch();
    net.health.started(&net.router, node.events());
    while !node.done(clock) {
        let now = clock.now();
        if node.poll_timeout().is_some_and(|t| t <= now) {
            node.handle_timeout(now, &mut net, log);
        }
        if net.report_refused(log) {
            node.report(&mut net, log);
        }
        if net.health.due() {
            node.status(&mut net);
        }
        let wait = node
            .poll_timeout()
            .map_or(MAX_WAIT, |t| clock.until(t).min(MAX_WAIT));
        tokio::select! {
            event = net.router.recv() => match event {
                Some(RouterEvent::Frame(inbound)) => {
                    node.handle_frame(clock.now(), &inbound, &mut net, log)
                }
                Some(RouterEvent::BadSignature { link, source, sender }) => {
                    let sender = Peer::new(sender.0, sender.1);
                    node.bad_signature(clock.now(), link, source, sender, &mut net, log)
                }
                Some(event) => {
                    net.health.changed(&net.router, &event, node.events());
                    if let Some(link) = net.link_changes.log(&net.router, event, log) {
                        node.link_reopened(link);
                    }
                }
                None => break,
            },
            _ = tokio::time::sleep(wait) => {}
            Ok(name) = &mut stopped, if !stopped.is_terminated() => {
                log.notice(&format!("{name}: stopping (again to stop at once)"));
                break;
            }
        }
    }
    // The last status, before the summary.
    node.status(&mut net);
    net.router.shutdown(Duration::from_secs(1)).await;
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
