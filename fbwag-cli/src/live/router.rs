//! `fbwag router`: MAVLink routing alone, between any number of links
//! (serial, UDP in/out, TCP client/server), by the MAVLink routing rules
//! (see `mavframe::route`): addressed frames go where their addressee was
//! seen, broadcasts and unknown ids everywhere but back; frames are
//! forwarded untouched, so signed frames stay verifiable end to end.
//!
//! Where each frame goes, whom each listening link answers and what is
//! dropped is the router node's (`fbwag_delegation::node::RouterNode`),
//! judged in the task of the link that received the frame; the daemon
//! has the shape of the others (`net::run`) and reports.

use super::net::{self, drop_counts, Net, Node, Plan, Shell};
use super::vehicle::RouterLogs;
use super::{Clock, Events, Level, Limiter, Log, LogOptions};
use crate::args::{LinkFilter, RoutedRate};
use fbwag_delegation::node::{Answers, DropReason, Drops, Output, RouterNode};
use fbwag_delegation::{Moment, Peer};
use fbwag_dialect::mavframe::parser::Unsigned;
use fbwag_dialect::mavframe::route::{LinkId, Links};
use fbwag_dialect::mavframe::router::{Inbound, LinkConfig, Out};
use fbwag_dialect::{Dialect, Endpoint};
use serde_json::json;
use std::io;
use std::net::SocketAddr;
use std::num::NonZeroU32;
use std::path::{Path, PathBuf};
use std::time::Duration;

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
fn queue_dropped(out: &Out<'_>) -> u64 {
    out.links()
        .iter()
        .map(|l| out.counters(l).routed_dropped)
        .fold(0, u64::saturating_add)
}

/// Runs the router for its duration (or until killed), printing a line
/// per link change and a summary every `report`.
pub fn run_router(o: RouterOptions, out: Box<dyn io::Write + Send>) -> io::Result<()> {
    net::block_on(async move {
        let clock = Clock::start();
        let mut log = Log::new(out, "router", o.log_level, super::Style::of_stdout());
        let events = Events::open(o.events.as_deref(), clock)?;
        let mut node = RouterNode::new(o.require_signed);
        node.set_dedup(o.dedup);
        let plan = plan_links(&o, &mut node, &mut log)?;
        let keyed = (o.keys.iter().enumerate())
            .filter(|(_, k)| k.is_some())
            .fold(Links::NONE, |all, (l, _)| {
                all.union(Links::only(l as LinkId))
            });
        let logs = RouterLogs::start(
            o.tlog.as_ref(),
            o.flight_log.as_ref(),
            o.log_sysid,
            o.sniffer_sysid,
            keyed,
        )?;
        let daemon = Routing {
            node,
            events,
            logs,
            drops: Limiter::new(5, Duration::from_secs(10)),
            traffic: Traffic::default(),
            duration: o.duration,
        };
        let router = plan
            .open(Shell::new(daemon, log, clock, 0, o.report))
            .await?;
        net::run(router, true).await?;
        Ok(())
    })
}

/// The router's links, each given to the node as it will be opened, its
/// filters and sniffers set.
fn plan_links(o: &RouterOptions, node: &mut RouterNode, log: &mut Log) -> io::Result<Plan> {
    let invalid = |err| io::Error::new(io::ErrorKind::InvalidInput, err);
    let mut plan = Plan::new();
    let mut links = Vec::with_capacity(o.endpoints.len());
    let mut labels = Vec::with_capacity(o.endpoints.len());
    for (i, e) in o.endpoints.iter().enumerate() {
        let key = o.keys.get(i).copied().flatten();
        let peer = o.peers.get(i).copied().flatten();
        let name = o.names.get(i).cloned().flatten();
        let mut config = LinkConfig::new(e.clone());
        config.key = key;
        config.name = name.clone();
        // The node drops what signing requires it to, counted.
        config.unsigned = Unsigned::Accept;
        config.signing_state = o.signing_state.as_deref().map(|p| state_file(p, i));
        config.routed_rate = paced(o, i, e);
        config.flow_control = o.flow_control.contains(&i);
        let link = plan.push(config, peer);
        let answers = net::answers(e, peer);
        node.add_link(link, answers, key.is_some())
            .map_err(invalid)?;
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
        let named = name.as_ref().map_or(String::new(), |n| format!(" {n}"));
        log.info(&format!("link {}{named}: {e}{key}{flow}{pinned}", i + 1));
        links.push(link);
        labels.push(name.unwrap_or_else(|| e.to_string()));
    }
    net::set_filters(&o.filters, &links, &labels, log, |link, d, f| {
        node.set_filter(link, d, f)
    })?;
    for &i in &o.sniffers {
        let Some(&link) = links.get(i) else {
            let error = format!("no link {} to sniff", i + 1);
            return Err(io::Error::new(io::ErrorKind::InvalidInput, error));
        };
        node.set_sniffer(link).map_err(invalid)?;
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
    Ok(plan)
}

/// The router daemon: its node, and what it counts and logs.
struct Routing {
    node: RouterNode,
    events: Events,
    /// The telemetry and flight logs, and `--sniffer-sysid`.
    logs: RouterLogs,
    drops: Limiter,
    traffic: Traffic,
    /// Stop after this long.
    duration: Option<Duration>,
}

impl Node for Routing {
    /// The flight log's timers (asking again, silence).
    fn poll_timeout(&self) -> Option<Moment> {
        self.logs.poll_timeout()
    }

    fn handle_timeout(&mut self, now: Moment, net: &mut Net<'_, '_>) {
        self.logs.poll(now, net.out);
    }

    /// A frame to the node, and on where it says.
    fn handle_frame(&mut self, now: Moment, f: &Inbound<'_, Dialect>, net: &mut Net<'_, '_>) {
        self.traffic.frames += 1;
        let fate = self.node.handle_frame(now, net::arrival(f));
        match fate.dropped {
            Some(reason) => log_drop(f, reason, &mut self.drops, net.log),
            None => {
                if self.logs.follows() {
                    (self.logs).frame(now, f, net.out, &mut self.node, net.log);
                }
                net.out.route(f, fate.route);
                self.traffic.forwarded += fate.route.len() as u64;
            }
        }
        while let Some(Output::Peers { link, peers }) = self.node.poll_output() {
            let list: Vec<SocketAddr> = peers.iter().collect();
            net.out.set_peers(link, &list);
        }
        self.logs.poll(now, net.out);
    }

    fn link_reopened(&mut self, link: LinkId) {
        self.node.link_reopened(link);
    }

    fn bad_signature(&mut self, _: Moment, _: LinkId, _: SocketAddr, _: Peer, _: &mut Net<'_, '_>) {
    }

    fn tick(&mut self, net: &mut Net<'_, '_>) {
        self.logs.notes(net.log);
    }

    /// The traffic line of every report, and the drops event.
    fn report(&mut self, net: &mut Net<'_, '_>) {
        let (dropped, lost) = (self.node.drops(), queue_dropped(net.out));
        net.log.info(&self.traffic.line(dropped.total(), lost));
        self.events.emit(
            "drops",
            json!({ "dropped": drop_counts(dropped), "queue_dropped": lost }),
        );
        self.logs.report(net.log, &mut self.events);
    }

    fn status(&mut self, net: &mut Net<'_, '_>) {
        net.status(self.node.drops(), serde_json::Map::new(), &mut self.events);
    }

    /// The summary: what was routed, dropped and lost, and the telemetry
    /// log's counts.
    fn finish(&mut self, net: &mut Net<'_, '_>) {
        let lost = queue_dropped(net.out);
        let line = self.traffic.line(self.node.drops().total(), lost);
        net.log.notice(&format!("done: {line}"));
        let mut summary = self.traffic.json(self.node.drops(), lost);
        self.logs.finish(net.log, net.out, &mut summary);
        self.events.emit("summary", summary);
    }

    fn events(&mut self) -> &mut Events {
        &mut self.events
    }

    fn done(&self, clock: &Clock) -> bool {
        self.duration
            .is_some_and(|d| clock.secs() >= d.as_secs_f64())
    }
}

/// A frame the node dropped: logged, rate-limited.
fn log_drop(f: &Inbound<'_, Dialect>, reason: DropReason, limiter: &mut Limiter, log: &mut Log) {
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

    /// Frames routed to a link faster than it sends, which its queue
    /// drops, count as lost, not sent on, in the line and the summary.
    #[test]
    fn frames_a_full_link_queue_drops_are_not_sent_on() {
        let (routed, lost) = (5_000, 4_488);
        let traffic = Traffic {
            frames: routed,
            forwarded: routed,
        };
        let sent = routed - lost;
        assert_eq!(
            traffic.line(0, lost),
            format!(
                "{routed} frames in, {sent} sent on, 0 dropped, {lost} lost in full link queues"
            )
        );
        let summary = traffic.json(&Drops::default(), lost);
        assert_eq!(summary["forwarded"], sent);
        assert_eq!(summary["queue_dropped"], lost);
    }
}
