//! `fbwag router`: MAVLink routing alone, between any number of links
//! (serial, UDP in/out, TCP client/server), by the MAVLink routing rules
//! (see `mavframe::route`): addressed frames go where their addressee was
//! seen, broadcasts and unknown ids everywhere but back; frames are
//! forwarded untouched, so signed frames stay verifiable end to end.
//!
//! Where each frame goes, whom each listening link answers and what is
//! dropped is the router node's (`fbwag_delegation::node::RouterNode`);
//! this module moves bytes and reports.

use super::net::{self, drop_counts, LinkChanges, LinkReports};
use super::signals::StopSignals;
use super::vehicle::RouterLogs;
use super::{Clock, Events, Health, Level, Limiter, Log, LogOptions, STATUS_EVERY};
use crate::args::{LinkFilter, RoutedRate};
use fbwag_delegation::node::{Answers, DropReason, Drops, Output, RouterNode};
use fbwag_dialect::mavframe::parser::Unsigned;
use fbwag_dialect::mavframe::route::Links;
use fbwag_dialect::mavframe::router::{Inbound, LinkConfig, Router, RouterEvent};
use fbwag_dialect::{Dialect, Endpoint};
use serde_json::json;
use std::io;
use std::net::SocketAddr;
use std::num::NonZeroU32;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::sync::oneshot;

/// Settings of the router.
#[derive(Debug, Clone)]
pub struct RouterOptions {
    /// The links, in order.
    pub endpoints: Vec<Endpoint>,
    /// Their names (`NAME=CONN`), where given.
    pub names: Vec<Option<String>>,
    /// Filters, each naming its link by its place in `endpoints`.
    pub filters: Vec<LinkFilter>,
    /// The pace of what is routed to each link, in `endpoints`' order
    /// (`None`: unpaced).
    pub routed_rates: Vec<Option<RoutedRate>>,
    /// De-duplication window (`None`: off).
    pub dedup: Option<Duration>,
    /// Each link's key (`None`: the link verifies nothing), in
    /// `endpoints`' order.
    pub keys: Vec<Option<[u8; 32]>>,
    /// Route only frames whose signature verified.
    pub require_signed: bool,
    /// Keep each link's signing state: the first link's in this file, link
    /// N's (from 1) in this path with `.N` added.
    pub signing_state: Option<PathBuf>,
    /// The address each listening link answers, and no other (`None`:
    /// whom the node chooses), in `endpoints`' order.
    pub peers: Vec<Option<SocketAddr>>,
    /// The links that get every frame routed, by their place in
    /// `endpoints`.
    pub sniffers: Vec<usize>,
    /// Stop after this long.
    pub duration: Option<Duration>,
    /// A traffic line this often.
    /// The text report's period (`None`: none); the status events'.
    pub report: Option<Duration>,
    /// Machine-readable events.
    pub events: Option<PathBuf>,
    /// Lines logged: this level and above.
    pub log_level: crate::live::Level,
    /// Log every frame routed (every frame the node did not drop) to
    /// `.tlog` files.
    pub tlog: Option<LogOptions>,
    /// Every link this system is heard on becomes a sniffer.
    pub sniffer_sysid: Option<u8>,
    /// The serial links with RTS/CTS flow control, by their place in
    /// `endpoints`.
    pub flow_control: Vec<usize>,
    /// Receive the vehicle's DataFlash log into `.bin` files.
    pub flight_log: Option<LogOptions>,
    /// The vehicle's system id (`None`: the first autopilot heard).
    pub log_sysid: Option<u8>,
}

/// The pace of what is routed to link `index` (`e`), if it was given.
fn paced(o: &RouterOptions, index: usize, e: &Endpoint) -> Option<NonZeroU32> {
    let given = o.routed_rates.get(index).copied().flatten()?;
    net::routed_rate(e, Some(given))
}

/// The signing state file of link `index`.
fn state_file(path: &Path, index: usize) -> PathBuf {
    if index == 0 {
        return path.to_owned();
    }
    let mut name = path.as_os_str().to_owned();
    name.push(format!(".{index}"));
    PathBuf::from(name)
}

/// Counts of what the router did.
#[derive(Debug, Default)]
struct Traffic {
    frames: u64,
    /// Frames handed to the links (a frame routed to two links counts
    /// twice), some of which their full queues may have dropped.
    forwarded: u64,
}

impl Traffic {
    /// The traffic line: frames in, sent on (routed, less what the links'
    /// queues dropped: a link slower than what is routed to it drops
    /// frames after the node let them go), dropped by the node and by the
    /// links.
    fn line(&self, node_dropped: u64, queue_dropped: u64) -> String {
        let mut line = format!(
            "{} frames in, {} sent on, {} dropped",
            self.frames,
            self.forwarded.saturating_sub(queue_dropped),
            node_dropped
        );
        if queue_dropped > 0 {
            line.push_str(&format!(", {queue_dropped} lost in full link queues"));
        }
        line
    }

    /// The summary's counts, as [`line`](Self::line) has them.
    fn json(&self, drops: &Drops, queue_dropped: u64) -> serde_json::Value {
        json!({
            "frames": self.frames,
            "forwarded": self.forwarded.saturating_sub(queue_dropped),
            "dropped": drop_counts(drops),
            "queue_dropped": queue_dropped,
        })
    }
}

/// Routed frames the links' queues dropped so far, every link's
/// (`LinkCounters::routed_dropped`).
fn queue_dropped(router: &Router<Dialect>) -> u64 {
    router
        .links()
        .iter()
        .map(|l| router.counters(l).routed_dropped)
        .fold(0, u64::saturating_add)
}

/// Runs the router for its duration (or until killed), printing a line
/// per link change and a summary every `report`.
pub fn run_router(o: RouterOptions, out: Box<dyn io::Write + Send>) -> io::Result<()> {
    net::block_on(async move {
        let clock = Clock::start();
        let mut log = Log::new(out, "router", o.log_level, super::Style::of_stdout());
        let mut events = Events::open(o.events.as_deref(), clock)?;
        let mut router = Router::<Dialect>::new();
        let mut node = RouterNode::new(o.require_signed);
        node.set_dedup(o.dedup);
        let mut links = Vec::with_capacity(o.endpoints.len());
        for (i, e) in o.endpoints.iter().enumerate() {
            let key = o.keys.get(i).copied().flatten();
            let peer = o.peers.get(i).copied().flatten();
            let name = o.names.get(i).cloned().flatten();
            let mut config = LinkConfig::new(e.clone());
            config.key = key;
            config.name = name.clone();
            // The node drops what signing requires it to, counted.
            config.unsigned = Unsigned::Accept;
            config.reply_to = net::reply_to(peer);
            config.signing_state = o.signing_state.as_deref().map(|p| state_file(p, i));
            config.routed_rate = paced(&o, i, e);
            config.flow_control = o.flow_control.contains(&i);
            let link = router
                .add(config)
                .await
                .map_err(|err| net::opened(e, err))?;
            let answers = net::answers(e, peer);
            node.add_link(link, answers, key.is_some())
                .map_err(|err| io::Error::new(io::ErrorKind::InvalidInput, err))?;
            // Numbered, with what it was given: options name links by
            // place or name.
            let key = if key.is_some() { ", its key" } else { "" };
            let flow = if o.flow_control.contains(&i) {
                ", RTS/CTS"
            } else {
                ""
            };
            let pinned = match answers {
                Answers::Fixed(p) => format!(", answers {p} only"),
                _ => String::new(),
            };
            let named = name.map_or(String::new(), |n| format!(" {n}"));
            log.info(&format!("link {}{named}: {e}{key}{flow}{pinned}", i + 1));
            links.push(link);
        }
        let labels: Vec<String> = links.iter().map(|&l| router.name(l)).collect();
        net::set_filters(&o.filters, &links, &labels, &mut log, |link, d, f| {
            node.set_filter(link, d, f)
        })?;
        for &i in &o.sniffers {
            let Some(&link) = links.get(i) else {
                let error = format!("no link {} to sniff", i + 1);
                return Err(io::Error::new(io::ErrorKind::InvalidInput, error));
            };
            node.set_sniffer(link)
                .map_err(|err| io::Error::new(io::ErrorKind::InvalidInput, err))?;
            log.info(&format!(
                "link {}: {} gets every frame routed",
                i + 1,
                o.endpoints[i]
            ));
        }
        if let Some(window) = o.dedup {
            log.info(&format!(
                "copies of a frame within {} ms dropped",
                window.as_millis()
            ));
        }
        let keyed = (links.iter().zip(&o.keys))
            .filter(|(_, k)| k.is_some())
            .fold(Links::NONE, |all, (&l, _)| all.union(Links::only(l)));
        let mut logs = RouterLogs::start(
            o.tlog.as_ref(),
            o.flight_log.as_ref(),
            o.log_sysid,
            o.sniffer_sysid,
            keyed,
        )?;
        let mut stopped = StopSignals::new(true, &mut log).watch();
        let traffic = serve(
            &o,
            &mut router,
            &mut node,
            &mut log,
            &mut events,
            &mut logs,
            &mut stopped,
        )
        .await;
        let lost = queue_dropped(&router);
        log.notice(&format!(
            "done: {}",
            traffic.line(node.drops().total(), lost)
        ));
        let mut summary = traffic.json(node.drops(), lost);
        logs.finish(&mut log, &router, &mut summary);
        events.emit("summary", summary);
        router.shutdown(Duration::from_secs(1)).await;
        Ok(())
    })
}

/// What the router's loop keeps between events.
struct Serving<'a> {
    router: &'a mut Router<Dialect>,
    node: &'a mut RouterNode,
    log: &'a mut Log,
    links: LinkChanges,
    drops: Limiter,
    traffic: Traffic,
    clock: Clock,
    logs: &'a mut RouterLogs,
    /// What the links refused and lost, with each report.
    link_reports: LinkReports,
    /// The links' state and totals, for `link` and `status` events.
    health: Health,
}

impl Serving<'_> {
    /// A frame to the node, and on where it says.
    fn frame(&mut self, f: &Inbound<Dialect>) {
        self.traffic.frames += 1;
        let now = self.clock.now();
        let fate = self.node.handle_frame(now, net::arrival(f));
        match fate.dropped {
            Some(reason) => log_drop(f, reason, &mut self.drops, self.log),
            None => {
                self.logs.frame(now, f, self.router, self.node, self.log);
                self.router.route(f, fate.route);
                self.traffic.forwarded += fate.route.len() as u64;
            }
        }
        while let Some(Output::Peers { link, peers }) = self.node.poll_output() {
            let list: Vec<SocketAddr> = peers.iter().collect();
            self.router.set_peers(link, &list);
        }
        self.logs.poll(now, self.router);
    }

    /// The status event.
    fn status(&mut self, events: &mut Events) {
        let more = serde_json::Map::new();
        self.health
            .status(self.router, self.node.drops(), more, events);
    }

    /// The traffic line of every report, and the drops event.
    fn report(&mut self, events: &mut Events) {
        let (dropped, lost) = (self.node.drops(), queue_dropped(self.router));
        self.log.info(&self.traffic.line(dropped.total(), lost));
        self.link_reports.report(self.router, self.log);
        events.emit(
            "drops",
            json!({ "dropped": drop_counts(dropped), "queue_dropped": lost }),
        );
        self.logs.report(self.log, events);
    }
}

/// The router's loop: each frame to the node and on where it says; link
/// changes and a traffic line every `o.report` logged.
async fn serve(
    o: &RouterOptions,
    router: &mut Router<Dialect>,
    node: &mut RouterNode,
    log: &mut Log,
    events: &mut Events,
    logs: &mut RouterLogs,
    stopped: &mut oneshot::Receiver<&'static str>,
) -> Traffic {
    let end = o.duration.map(|d| tokio::time::Instant::now() + d);
    let every = o.report.unwrap_or(STATUS_EVERY);
    let mut next_report = tokio::time::Instant::now() + every;
    let mut s = Serving {
        router,
        node,
        log,
        links: LinkChanges::default(),
        drops: Limiter::new(5, Duration::from_secs(10)),
        traffic: Traffic::default(),
        clock: Clock::start(),
        logs,
        link_reports: LinkReports::default(),
        health: Health::new(every),
    };
    s.health.started(s.router, events);
    // One timer, reset when it fires: one made per turn (per frame) was
    // registered with the runtime's timer wheel and cleared every time.
    let wake = |next: tokio::time::Instant| end.map_or(next, |e| e.min(next));
    let timer = tokio::time::sleep_until(wake(next_report));
    tokio::pin!(timer);
    loop {
        tokio::select! {
            event = s.router.recv() => match event {
                Some(RouterEvent::Frame(f)) => s.frame(&f),
                Some(event) => {
                    s.health.changed(s.router, &event, events);
                    if let Some(link) = s.links.log(s.router, event, s.log) {
                        s.node.link_reopened(link);
                    }
                }
                None => break,
            },
            () = &mut timer => {
                let now = tokio::time::Instant::now();
                if end.is_some_and(|e| now >= e) {
                    break;
                }
                s.logs.poll(s.clock.now(), s.router);
                if now >= next_report {
                    next_report += every;
                    if o.report.is_some() {
                        s.report(events);
                    }
                    s.status(events);
                }
                timer.as_mut().reset(wake(next_report));
            }
            Ok(name) = &mut *stopped, if !stopped.is_terminated() => {
                s.log.notice(&format!("{name}: stopping (again to stop at once)"));
                break;
            }
        }
        s.logs.notes(s.log);
        // The flight log's timers (asking again, silence), when sooner.
        if let Some(due) = s.logs.poll_timeout() {
            let wait = due.0.saturating_sub(s.clock.now().0);
            let due = tokio::time::Instant::now() + Duration::from_micros(wait);
            if due < timer.deadline() {
                timer.as_mut().reset(due);
            }
        }
    }
    // The last status, before the summary.
    s.status(events);
    s.traffic
}

/// A frame the node dropped: logged, rate-limited.
fn log_drop(f: &Inbound<Dialect>, reason: DropReason, limiter: &mut Limiter, log: &mut Log) {
    limiter.log(log, Level::Warn, "dropped frames", || {
        let h = f.frame.header();
        format!(
            "dropped a frame from {}/{}{}: {}",
            h.sysid,
            h.compid,
            f.source.map_or(String::new(), |s| format!(" ({s})")),
            reason.name()
        )
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use fbwag_dialect::mavframe::route::Links;
    use fbwag_dialect::mavframe::router::LINK_QUEUE;

    /// Frames routed to a link faster than it sends overflow its routed
    /// queue: they count as lost, not sent on, in the line and the summary.
    #[test]
    fn frames_a_full_link_queue_drops_are_not_sent_on() {
        let sink = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let to = sink.local_addr().unwrap();
        net::block_on(async move {
            let mut router = Router::<Dialect>::new();
            let endpoint: Endpoint = format!("udpout:{to}").parse().unwrap();
            let link = router.add(LinkConfig::new(endpoint)).await?;
            // HEARTBEAT (MAVLink 2, nine zero bytes of payload).
            let mut frame = vec![0xfd, 9, 0, 0, 0, 1, 1, 0, 0, 0];
            frame.extend([0; 11]);
            // On one thread the link's task cannot run while these are
            // routed: its queue takes what it holds, the rest is dropped.
            let routed = 5_000;
            for _ in 0..routed {
                router.send_routed(Links::only(link), &frame);
            }
            let traffic = Traffic {
                frames: routed,
                forwarded: routed,
            };
            let lost = queue_dropped(&router);
            let sent = LINK_QUEUE as u64;
            assert_eq!(lost, routed - sent, "all but a queueful lost");
            assert_eq!(
                traffic.line(0, lost),
                format!("{routed} frames in, {sent} sent on, 0 dropped, {lost} lost in full link queues")
            );
            let summary = traffic.json(&Drops::default(), lost);
            assert_eq!(summary["forwarded"], sent);
            assert_eq!(summary["queue_dropped"], lost);
            router.shutdown(Duration::from_secs(1)).await;
            Ok(())
        })
        .unwrap();
    }
}
