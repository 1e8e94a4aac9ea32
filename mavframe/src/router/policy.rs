//! What a router does with the frames its links receive: the [`Policy`]
//! trait, and [`Forward`], the plain router's.

use super::{Inbound, LinkConfig, Out, RouterEvent, MAX_CLIENTS};
use crate::conn::Endpoint;
use crate::message::MessageSet;
use crate::peers::{Heard, PeerSet};
use crate::route::{LinkId, Links, RoutingTable};
use core::time::Duration;
use std::boxed::Box;
use std::net::SocketAddr;
use std::time::Instant;
use std::vec::Vec;

/// The rules a router's links follow, sans-IO: where each frame goes, whom
/// each listening link answers, what the owner sends. The router calls it
/// in the task that received the frame, under the lock the links share,
/// and carries out what it asks through [`Out`] there and then (a link
/// with an empty queue sends at once). Its calls are short and never
/// wait: every frame of every link passes through them.
pub trait Policy<D: MessageSet>: Send + 'static {
    /// Link `link` was added ([`Router::add`](super::Router::add)), before
    /// any frame of it.
    fn link_added(&mut self, link: LinkId, config: &LinkConfig, out: &mut Out<'_>) {
        let _ = (link, config, out);
    }

    /// A frame `inbound.link` received: judged, and sent on where the
    /// policy says ([`Out::route`]), or not.
    fn frame(&mut self, inbound: &Inbound<'_, D>, out: &mut Out<'_>);

    /// A link failed, opened again, or refused a datagram's signature.
    fn event(&mut self, event: RouterEvent, out: &mut Out<'_>) {
        let _ = (event, out);
    }
}

/// The plain router's policy: the MAVLink routing rules over a
/// [`RoutingTable`] (addressed frames to the link where the addressee was
/// seen, broadcasts everywhere but back, byte for byte; routes learned
/// trusted from authenticated frames and from the links
/// [`set_trusted`](Forward::set_trusted) names), and each listening link
/// (`udpin`, `udpbcast`, `tcpin`) answering the senders of the frames its
/// parser accepted, authenticated ones on a link with a key, in a
/// [`PeerSet`] (up to eight on a UDP link, a station that keeps speaking
/// never displaced; on `tcpin`, each client's connection, up to
/// [`MAX_CLIENTS`]). A datagram alone never moves them; a link opened
/// again forgets them.
#[derive(Debug, Clone)]
pub struct Forward {
    table: RoutingTable,
    trusted: Links,
    keyed: Links,
    /// Each listening link's peers, by link.
    peers: Vec<Option<Answered>>,
    /// The origin of the peer sets' times.
    epoch: Instant,
}

impl Default for Forward {
    fn default() -> Self {
        Self::new()
    }
}

impl Forward {
    /// No route known yet, no link trusted.
    pub fn new() -> Self {
        Forward {
            table: RoutingTable::new(),
            trusted: Links::NONE,
            keyed: Links::NONE,
            peers: Vec::new(),
            epoch: Instant::now(),
        }
    }

    /// Frames from `link` teach the table trusted routes (see
    /// [`crate::route`]) whether authenticated or not: a link the owner
    /// trusts (a serial port to the autopilot, say). No link is, at first.
    pub fn set_trusted(&mut self, link: LinkId, trusted: bool) {
        self.trusted = match trusted {
            true => self.trusted.union(Links::only(link)),
            false => self.trusted.without(link),
        };
    }

    /// The routing table.
    pub fn table(&self) -> &RoutingTable {
        &self.table
    }

    /// The peers of listening link `link`, if it is one.
    fn peers_of(&mut self, link: LinkId) -> Option<&mut Answered> {
        self.peers.get_mut(usize::from(link))?.as_mut()
    }

    /// `source` sent `link` a frame that vouches for it: a peer if the
    /// set lets it be; the link told when the set changed.
    fn heard(&mut self, link: LinkId, source: SocketAddr, out: &mut Out<'_>) {
        let now = self.epoch.elapsed();
        let Some(set) = self.peers_of(link) else {
            return;
        };
        if set.heard(source, now).changed() {
            out.set_peers(link, &set.list());
        }
    }
}

/// Whom a listening link answers: a UDP link's stations, or a `tcpin`
/// link's clients.
#[derive(Debug, Clone)]
// One per listening link: the UDP set's room costs less than a box.
#[allow(clippy::large_enum_variant)]
enum Answered {
    Udp(PeerSet),
    Tcp(Box<PeerSet<MAX_CLIENTS>>),
}

impl Answered {
    fn heard(&mut self, addr: SocketAddr, now: Duration) -> Heard {
        match self {
            Answered::Udp(set) => set.heard(addr, now),
            Answered::Tcp(set) => set.heard(addr, now),
        }
    }

    fn list(&self) -> Vec<SocketAddr> {
        match self {
            Answered::Udp(set) => set.iter().collect(),
            Answered::Tcp(set) => set.iter().collect(),
        }
    }

    fn clear(&mut self) {
        match self {
            Answered::Udp(set) => set.clear(),
            Answered::Tcp(set) => set.clear(),
        }
    }
}

impl<D: MessageSet> Policy<D> for Forward {
    fn link_added(&mut self, link: LinkId, config: &LinkConfig, _: &mut Out<'_>) {
        let i = usize::from(link);
        if self.peers.len() <= i {
            self.peers.resize(i + 1, None);
        }
        self.peers[i] = match config.endpoint {
            Endpoint::TcpIn(_) => Some(Answered::Tcp(Box::default())),
            _ if config.is_listening() => Some(Answered::Udp(PeerSet::new())),
            _ => None,
        };
        if config.key.is_some() {
            self.keyed = self.keyed.union(Links::only(link));
        }
    }

    fn frame(&mut self, inbound: &Inbound<'_, D>, out: &mut Out<'_>) {
        let link = inbound.link;
        let authenticated = inbound.frame.is_authenticated();
        // An unsigned frame, even accepted, is anyone's on a keyed link.
        if let (Some(source), true) = (inbound.source, authenticated || !self.keyed.contains(link))
        {
            self.heard(link, source, out);
        }
        let trusted = authenticated || self.trusted.contains(link);
        let frame = inbound.frame.frame();
        let meta = inbound.frame.meta();
        let to = self.table.route(link, &frame, meta, out.links(), trusted);
        out.route(inbound, to);
    }

    fn event(&mut self, event: RouterEvent, out: &mut Out<'_>) {
        if let RouterEvent::LinkUp { link } = event {
            if let Some(set) = self.peers_of(link) {
                set.clear();
                out.set_peers(link, &[]);
            }
        }
    }
}
