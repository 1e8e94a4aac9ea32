//! What the router follows of the vehicle ([`Vehicle`]: the autopilot's
//! HEARTBEATs): its arming, for `--log-mode while-armed`; its own log over
//! MAVLink ([`super::flight_log`], `--flight-log`); and, beside them, the
//! links a system is heard on (`--sniffer-sysid`). [`RouterLogs`] carries
//! them out for `fbwag router`: the node has judged each frame first.

use super::flight_log::{FlightLog, Reply, OWN_COMPID};
use super::logfiles::BLOCK_LEN;
use super::{Events, Log, LogOptions, Tlog};
use fbwag_delegation::node::RouterNode;
use fbwag_delegation::Moment;
use fbwag_dialect::dialects::ardupilotmega::RemoteLogDataBlock;
use fbwag_dialect::dialects::minimal::{Heartbeat, MavAutopilot, MavModeFlag};
use fbwag_dialect::mavframe::route::{LinkId, Links};
use fbwag_dialect::mavframe::router::{Inbound, Out};
use fbwag_dialect::mavframe::Received;
use fbwag_dialect::{Dialect, Message};
use std::io;

/// The autopilot's component id (MAV_COMP_ID_AUTOPILOT1).
const AUTOPILOT: u8 = 1;

/// The vehicle whose log and arming count, learned from its HEARTBEATs.
#[derive(Debug, Clone, Default)]
pub struct Vehicle {
    /// Its system id, given (`--log-sysid`) or learned.
    sysid: Option<u8>,
    /// The link its HEARTBEAT came in on first.
    link: Option<LinkId>,
    armed: Option<bool>,
}

impl Vehicle {
    /// The vehicle of system `sysid`, or the first autopilot heard.
    pub fn new(sysid: Option<u8>) -> Vehicle {
        Vehicle {
            sysid,
            ..Vehicle::default()
        }
    }

    /// Its system id and link, once heard.
    pub fn at(&self) -> Option<(u8, LinkId)> {
        Some((self.sysid?, self.link?))
    }

    /// Whether it is armed, once heard.
    pub fn armed(&self) -> Option<bool> {
        self.armed
    }

    /// A frame the router let through, on `link`; `trusted`: verified, or
    /// on a link without a key. Its arming, when this HEARTBEAT of the
    /// vehicle changed it.
    pub fn heard(
        &mut self,
        link: LinkId,
        frame: &Received<'_, Dialect>,
        trusted: bool,
    ) -> Option<bool> {
        if frame.msg_id() != Heartbeat::ID {
            return None;
        }
        let h = frame.header();
        if !trusted || h.compid != AUTOPILOT || self.sysid.is_some_and(|s| s != h.sysid) {
            return None;
        }
        if self.link.is_some_and(|l| l != link) {
            return None;
        }
        let armed = armed(frame)?;
        self.sysid = Some(h.sysid);
        self.link = Some(link);
        (self.armed != Some(armed)).then(|| {
            self.armed = Some(armed);
            armed
        })
    }

    /// Whether `frame`, on `link`, is the vehicle's and `trusted`.
    pub fn sent(&self, link: LinkId, frame: &Received<'_, Dialect>, trusted: bool) -> bool {
        trusted && self.at() == Some((frame.header().sysid, link))
    }
}

/// Whether `frame`, a HEARTBEAT of an autopilot, says armed (its
/// MAV_MODE_FLAG_SAFETY_ARMED bit); `None` for any other frame.
pub fn armed(frame: &Received<'_, Dialect>) -> Option<bool> {
    if frame.msg_id() != Heartbeat::ID {
        return None;
    }
    let Some(Message::Heartbeat(hb)) = frame.message() else {
        return None;
    };
    (hb.autopilot != MavAutopilot::INVALID)
        .then(|| hb.base_mode.contains(MavModeFlag::SAFETY_ARMED))
}

/// The router's logs, the vehicle they follow, and `--sniffer-sysid`.
pub struct RouterLogs {
    pub tlog: Option<Tlog>,
    pub flight: Option<FlightLog>,
    vehicle: Vehicle,
    /// The links with a key: there only verified frames count.
    keyed: Links,
    /// `--sniffer-sysid`, and the links made sniffers for it.
    sniffer_sysid: Option<u8>,
    sniffing: Links,
    replies: Vec<Reply>,
}

impl RouterLogs {
    /// Starts the logs given; the vehicle is system `sysid`, or the first
    /// autopilot heard; `keyed`: the links with a key.
    pub fn start(
        tlog: Option<&LogOptions>,
        flight: Option<&LogOptions>,
        sysid: Option<u8>,
        sniffer_sysid: Option<u8>,
        keyed: Links,
    ) -> io::Result<RouterLogs> {
        Ok(RouterLogs {
            tlog: tlog.map(|t| Tlog::start(t, "router")).transpose()?,
            flight: flight.map(|f| FlightLog::start(f, "router")).transpose()?,
            vehicle: Vehicle::new(sysid),
            keyed,
            sniffer_sysid,
            sniffing: Links::NONE,
            replies: Vec::new(),
        })
    }

    /// Whether it follows the frames routed: a log, or `--sniffer-sysid`.
    pub fn follows(&self) -> bool {
        self.tlog.is_some() || self.flight.is_some() || self.sniffer_sysid.is_some()
    }

    /// A frame the node let through, `f` (before it is routed; then
    /// [`poll`](Self::poll), once the link knows whom it answers).
    pub fn frame(
        &mut self,
        now: Moment,
        f: &Inbound<'_, Dialect>,
        out: &mut Out<'_>,
        node: &mut RouterNode,
        log: &mut Log,
    ) {
        let trusted = f.frame.is_authenticated() || !self.keyed.contains(f.link);
        if let Some(armed) = self.vehicle.heard(f.link, &f.frame, trusted) {
            if let Some(tlog) = &mut self.tlog {
                tlog.set_armed(armed);
            }
            let (sysid, _) = self.vehicle.at().unwrap_or_default();
            let state = if armed { "armed" } else { "disarmed" };
            log.notice(&format!("vehicle {sysid}: {state}"));
        }
        if let Some(tlog) = &mut self.tlog {
            tlog.received(f.link, f.frame.as_bytes());
        }
        self.sniff(f, trusted, out, node, log);
        if self.flight.is_some() && f.frame.msg_id() == RemoteLogDataBlock::ID {
            self.block(now, f, trusted);
        }
    }

    /// `--sniffer-sysid`: the link `f` came in on, when its system is the
    /// one named, is a sniffer from now on.
    fn sniff(
        &mut self,
        f: &Inbound<'_, Dialect>,
        trusted: bool,
        out: &mut Out<'_>,
        node: &mut RouterNode,
        log: &mut Log,
    ) {
        let Some(id) = self.sniffer_sysid else {
            return;
        };
        if !trusted || f.frame.header().sysid != id || self.sniffing.contains(f.link) {
            return;
        }
        if node.set_sniffer(f.link).is_ok() {
            self.sniffing = self.sniffing.union(Links::only(f.link));
            log.notice(&format!(
                "link {}: system {id} heard: gets every frame routed (--sniffer-sysid)",
                out.name(f.link)
            ));
        }
    }

    /// A REMOTE_LOG_DATA_BLOCK: taken when it is the vehicle's, to the
    /// router.
    fn block(&mut self, now: Moment, f: &Inbound<'_, Dialect>, trusted: bool) {
        let (Some(flight), Some((sysid, _))) = (&mut self.flight, self.vehicle.at()) else {
            return;
        };
        let Some(Message::RemoteLogDataBlock(b)) = f.frame.message() else {
            return;
        };
        if (b.target_system, b.target_component) != (sysid, OWN_COMPID) {
            // Another's (a ground station's, another router's) log.
            return;
        }
        if !self.vehicle.sent(f.link, &f.frame, trusted) {
            flight.tally.strangers += 1;
            return;
        }
        let data: &[u8; BLOCK_LEN] = &b.data;
        flight.block(now, b.seqno.0, data, &mut self.replies);
    }

    /// The flight log's timers, and its answers sent.
    pub fn poll(&mut self, now: Moment, out: &mut Out<'_>) {
        let Some(flight) = &mut self.flight else {
            return;
        };
        if let Some(reply) = flight.poll(now, self.vehicle.armed()) {
            self.replies.push(reply);
        }
        self.send(out);
    }

    /// The answers to the vehicle, on its link.
    fn send(&mut self, out: &mut Out<'_>) {
        let Some((sysid, link)) = self.vehicle.at() else {
            self.replies.clear();
            return;
        };
        for reply in self.replies.drain(..) {
            out.send_message(Links::only(link), sysid, OWN_COMPID, &reply.message(sysid));
        }
    }

    /// When [`poll`](Self::poll) is due.
    pub fn poll_timeout(&self) -> Option<Moment> {
        self.flight.as_ref()?.poll_timeout()
    }

    /// The writers' notes, into the log.
    pub fn notes(&mut self, log: &mut Log) {
        if let Some(tlog) = &mut self.tlog {
            tlog.notes(log);
        }
        if let Some(flight) = &mut self.flight {
            flight.notes(log);
        }
    }

    /// Each report: the logs' counts, logged and as events.
    pub fn report(&mut self, log: &mut Log, events: &mut Events) {
        if let Some(tlog) = &mut self.tlog {
            let counts = tlog.counts();
            log.info(&super::tlog::line(&counts));
            events.emit("tlog", counts.json());
        }
        if let Some(flight) = &mut self.flight {
            log.info(&flight.line());
            events.emit("flight_log", flight.json());
        }
    }

    /// Ends the logs (a STOP to the vehicle if its log was coming); their
    /// counts into the summary.
    pub fn finish(&mut self, log: &mut Log, out: &mut Out<'_>, summary: &mut serde_json::Value) {
        if let Some(tlog) = &mut self.tlog {
            let counts = tlog.finish(log);
            log.info(&super::tlog::line(&counts));
            summary["tlog"] = counts.json();
        }
        if let Some(flight) = &mut self.flight {
            let (_, stop) = flight.finish(log);
            log.info(&flight.line());
            summary["flight_log"] = flight.json();
            self.replies.extend(stop);
            self.send(out);
        }
    }
}
