//! The node policy: every frame's fate, decided once, sans-IO.
//!
//! A program that speaks this protocol is a MAVLink *node* with several
//! links: the companion ([`CompanionNode`]: the FC link, ground-station
//! links, the autonomy's link), the flight controller ([`FcNode`]: its
//! companion link, which also carries ground stations' traffic) and a plain
//! router ([`RouterNode`]). For every frame a link delivers, the node takes
//! the link, the source address, the frame and whether its signature
//! verified, with the time, and returns its [`Fate`]: protocol input to
//! the engine, control through the companion's gate, the links it is routed
//! to (byte for byte), or a drop with a counted [`DropReason`]. It also
//! decides whom each listening link answers ([`Output::Peers`]) and on
//! which links its own messages go ([`Output::Transmit`]).
//!
//! The programs (`fbwag cc`, `fbwag fc-sim`, `fbwag router`) and the
//! simulator only move bytes and time: each rule below lives here and
//! nowhere else.
//!
//! | source | frame | signature | fate |
//! |---|---|---|---|
//! | any link | the node's own ids | any | dropped: `own_ids` (a loop, or a spoof) |
//! | peer link, from an address that is not the link's peer | any | not verified | dropped: `not_peer` (a verified frame moves the peer; so does an unsigned trusted frame once the peer is silent 3 s, without signing) |
//! | peer link | the peer's ids | verified, or signing not required | engine input; routed to ground links and the autonomy |
//! | peer link | the peer's ids | not verified, signing required | dropped: `unauthenticated` |
//! | peer link | other ids | not verified, signing required | routed to ground links only (never to the autonomy) |
//! | ground link | the FC's or the companion's ids | any | dropped: `impersonation` (they live on the peer link) |
//! | ground link | other ids | not verified, signing required | routed to ground links only; dropped (`unauthenticated`) when it was addressed only to the FC or the autonomy |
//! | ground link | other ids | verified, or signing not required | routed by the routing table, to every kind of link |
//! | trusted ground link ([`LinkSpec::trusted`]) | other ids | not verified, a message the dialect knows | as verified, and signed on the way ([`Fate::sign`]) |
//! | trusted ground link | a frame that would change who flies ([`crate::protected`]: delegation and failsafe parameters, SETUP_SIGNING, control, FTP writes, SERIAL_CONTROL) | not verified | dropped: `protected` (never signed on) |
//! | autonomy link, from an address other than the autonomy's | any | any | dropped: `not_peer` |
//! | autonomy link | the FC's or the companion's ids | any | dropped: `impersonation` |
//! | autonomy link | RC_CHANNELS_OVERRIDE, SET_ATTITUDE_TARGET, MANUAL_CONTROL | any | the companion's gate: to the FC, re-addressed and signed, while the companion holds control; else dropped: `gated` |
//! | autonomy link | REQUEST_DATA_STREAM, MAV_CMD_SET_MESSAGE_INTERVAL, MAV_CMD_REQUEST_MESSAGE | any | to the FC, signed on ([`Fate::sign`]) |
//! | autonomy link | other messages | any | routed to ground links only, never to the FC |
//! | router link | any | not verified, signing required | dropped: `unauthenticated` |
//! | any link, once the rows above let it be routed | refused by the link's in-filter | any | dropped: `filtered` |
//! | any link, once the rows above let it be routed | the same bytes went on less than the de-duplication window ago | any | dropped: `duplicate` |
//! | any | routed to a link whose out-filter refuses it | any | that link is taken off its route (no drop) |
//!
//! Filters ([`Filter`], per link and direction, from [`FilterRules`]:
//! allow or block by message id, source system, source component) and
//! de-duplication ([`Dedup`], one window for the node, off by default)
//! narrow routing and nothing else. They are asked after the rules of
//! trust, so they can remove a frame or a link from a route but never
//! admit what those rules refuse. On the companion they never touch the
//! protocol: a frame of the FC link reaches the engine before its
//! in-filter is asked (an input the engine took is no drop, only not
//! routed on), control from the autonomy goes to the gate unfiltered, and
//! the node's own messages ([`Output::Transmit`]) pass no out-filter. An
//! in-filter is asked after the link admitted the frame's source, so it
//! does not change whom a listening link answers, and before the frame's
//! route is learned, so a refused source teaches none; de-duplication
//! after the in-filter, so that a copy refused on one link cannot make
//! another link's copy a duplicate.
//!
//! Listening links (`udpin`, `tcpin`) answer only whom the node admits
//! ([`Peers`], under `mavframe::peers`' rule): the peer link and the autonomy link one address (a
//! verified frame's source at once; without signing, the first trusted
//! source, replaced after 3 s of silence), ground links the stations that
//! spoke recently (8 at most, half of them for stations whose frames
//! verified: a newcomer takes a free slot or a slot silent 3 s, so a
//! stranger can neither push a speaking station out nor, without the key,
//! take the slots of stations that sign). The routing table holds every
//! sender (with `std`; [`ROUTES`] without a heap), and routes learned
//! from verified frames, from the peer link or from the autonomy outrank
//! those learned from strangers, so a flood of ids cannot make the node
//! forget the FC.
//!
//! Call order, as for the engines: after every `handle_*` call drain
//! `poll_output` until `None`, then call `handle_timeout` at
//! `poll_timeout()`.

mod companion;
mod digest;
mod filter;
mod flight;
mod peers;
mod router;

pub use companion::{
    AutonomyFallback, CompanionEvent, CompanionNode, ControlSource, AUTONOMY_SILENCE,
};
pub use filter::{
    Dedup, Direction, Filter, FilterError, FilterRules, IdSet, Rule, DEDUP_SLOTS, MAX_MSG_IDS,
};
pub use flight::FcNode;
use peers::{Admission, Answered};
pub use peers::{Peers, MAX_PEERS, PEER_SILENCE};
pub use router::RouterNode;

use crate::{Moment, Peer};
use core::net::SocketAddr;
#[cfg(not(feature = "std"))]
use fbwag_dialect::mavframe::route::FixedRoutingTable;
#[cfg(feature = "std")]
use fbwag_dialect::mavframe::route::RoutingTable;
use fbwag_dialect::{Frame, Message};

pub use fbwag_dialect::mavframe::route::{LinkId, Links};

/// Links a node has at most.
pub const MAX_LINKS: usize = 32;

/// Senders (system, component) the routing table holds without `std`
/// (no heap: a fixed array, whose least recently seen stranger goes when a
/// new sender finds it full). With `std` it holds every sender.
pub const ROUTES: usize = 256;

/// The routing table: with `std`, every sender of the network (a swarm
/// behind the FC's radio makes the node forget nobody); without, the
/// [`ROUTES`] most recently seen, trusted ones first.
#[cfg(feature = "std")]
type Table = RoutingTable;
#[cfg(not(feature = "std"))]
type Table = FixedRoutingTable<ROUTES>;

/// What a link is to the node.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Role {
    /// The link to the protocol peer: the companion's FC link, the FC's
    /// companion link.
    Peer,
    /// Ground stations, MAVProxy, other programs; every link of a router.
    Ground,
    /// The companion's autonomy program.
    Autonomy,
}

/// Whom a link sends to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Answers {
    /// The one far end it was opened to (`udpout`, `tcp`, serial): nothing
    /// to choose, and nobody else can send into it.
    Target,
    /// This address only (`--peer`; a port of 0 matches any port of that
    /// host, as a TCP client's port is its system's choice).
    Fixed(SocketAddr),
    /// Whom the node admits (`udpin`, `tcpin`): see the [module docs](self).
    Chosen,
}

/// A link as the node sees it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct LinkSpec {
    /// What it is.
    pub role: Role,
    /// Whom it sends to.
    pub answers: Answers,
    /// A ground link trusted like the key (`fbwag cc --trusted-out`): its
    /// frames count as verified, and those that are not go on signed
    /// ([`Fate::sign`]). For a local tool that cannot sign; whoever can
    /// send into the link can command the FC.
    pub trusted: bool,
}

impl LinkSpec {
    /// A link of `role` answering `answers`, not trusted.
    pub const fn new(role: Role, answers: Answers) -> Self {
        LinkSpec {
            role,
            answers,
            trusted: false,
        }
    }
}

/// A frame a link delivered.
#[derive(Debug, Clone, Copy)]
pub struct Arrival<'a> {
    /// The link.
    pub link: LinkId,
    /// The sender's address (datagram links, `tcpin` clients).
    pub source: Option<SocketAddr>,
    /// The frame, as the link's parser accepted it.
    pub frame: Frame<&'a [u8]>,
    /// Its signature verified with the link's key.
    pub authenticated: bool,
}

/// Why a node dropped a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum DropReason {
    /// It claims the node's own ids: a loop, or a spoof.
    OwnIds,
    /// It claims a trusted party's ids (the FC's, the companion's) on a
    /// link where that party does not live.
    Impersonation,
    /// Not authenticated where signing is required, and bound for
    /// something that acts (the engine, the FC, the autonomy).
    Unauthenticated,
    /// From an address the link does not answer (not its peer).
    NotPeer,
    /// Control while the companion does not hold control.
    Gated,
    /// Refused by the in-filter of its link ([`Direction::In`]).
    Filtered,
    /// A copy of a frame that went on less than the de-duplication
    /// window before ([`Dedup`]).
    Duplicate,
    /// An unsigned frame of a link trusted like the key that would change
    /// who flies ([`crate::protected`]): never signed on for it.
    Protected,
}

impl DropReason {
    /// Every reason, in the order of [`Drops::counts`].
    pub const ALL: [DropReason; 8] = [
        DropReason::OwnIds,
        DropReason::Impersonation,
        DropReason::Unauthenticated,
        DropReason::NotPeer,
        DropReason::Gated,
        DropReason::Filtered,
        DropReason::Duplicate,
        DropReason::Protected,
    ];

    /// Its name in logs and events.
    pub const fn name(self) -> &'static str {
        match self {
            DropReason::OwnIds => "own_ids",
            DropReason::Impersonation => "impersonation",
            DropReason::Unauthenticated => "unauthenticated",
            DropReason::NotPeer => "not_peer",
            DropReason::Gated => "gated",
            DropReason::Filtered => "filtered",
            DropReason::Duplicate => "duplicate",
            DropReason::Protected => "protected",
        }
    }
}

/// Frames dropped, by reason (saturating).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Drops([u64; DropReason::ALL.len()]);

impl Drops {
    fn count(&mut self, reason: DropReason) {
        let i = DropReason::ALL
            .iter()
            .position(|r| *r == reason)
            .unwrap_or(0);
        self.0[i] = self.0[i].saturating_add(1);
    }

    /// Frames dropped for `reason`.
    pub fn get(&self, reason: DropReason) -> u64 {
        DropReason::ALL
            .iter()
            .position(|r| *r == reason)
            .map_or(0, |i| self.0[i])
    }

    /// Each reason with its count.
    pub fn counts(&self) -> impl Iterator<Item = (DropReason, u64)> + '_ {
        DropReason::ALL.iter().copied().zip(self.0)
    }

    /// All frames dropped.
    pub fn total(&self) -> u64 {
        self.0.iter().fold(0, |a, n| a.saturating_add(*n))
    }
}

/// What became of a frame.
#[must_use]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Fate {
    /// The links it goes to, byte for byte (after the node's own frames).
    pub route: Links,
    /// Why it was dropped, if it was (it goes nowhere then).
    pub dropped: Option<DropReason>,
    /// It was a protocol input the engine acted on.
    pub input: bool,
    /// The FC serves it as a ground station's request (parameters,
    /// commands, telemetry rates).
    pub serve: bool,
    /// Each link of `route` frames it again, signed with its key, instead
    /// of sending its bytes: an unverified frame of a trusted link
    /// ([`LinkSpec::trusted`]).
    pub sign: bool,
}

impl Fate {
    fn dropped(reason: DropReason) -> Fate {
        Fate {
            dropped: Some(reason),
            ..Fate::default()
        }
    }

    fn routed(route: Links) -> Fate {
        Fate {
            route,
            ..Fate::default()
        }
    }
}

/// What a node asks its program to do.
// No allocation (no_std): a message to send is carried by value.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum Output<E> {
    /// Frame `message` with the node's ids and send it on `links` (each
    /// link signs with its key).
    Transmit {
        /// Where.
        links: Links,
        /// What.
        message: Message,
    },
    /// Frame `message` with the node's ids and send it on listening link
    /// `link` to `to` only, which does not become a peer: the node's
    /// signed heartbeat for a key holder whose clock is behind (see
    /// docs/delegation.md, "Signing time").
    TransmitTo {
        /// The link.
        link: LinkId,
        /// The address.
        to: SocketAddr,
        /// What.
        message: Message,
    },
    /// A listening link answers these addresses from now on.
    Peers {
        /// The link.
        link: LinkId,
        /// Whom it answers.
        peers: Peers,
    },
    /// The engine's event (mode changes, control to apply, handover).
    Event(E),
}

/// A link's place in a node.
#[derive(Debug, Clone)]
struct LinkState {
    spec: LinkSpec,
    peers: Answered,
    /// What it delivers that goes on ([`Direction::In`]).
    filter_in: Filter,
    /// What it is sent ([`Direction::Out`]).
    filter_out: Filter,
}

/// What every node has: its links, whom they answer, the routing table
/// and the drop counters.
#[derive(Debug, Clone)]
struct Core {
    links: [Option<LinkState>; MAX_LINKS],
    table: Table,
    drops: Drops,
    require_signed: bool,
    /// Who got a time beacon lately, and when ([`Core::time_beacon`]).
    beacons: Beacons,
    /// Links whose out-filter is not [`Filter::ALL`]: the others cost
    /// nothing per frame.
    filtered_out: Links,
    /// The links of each role, in [`Role`]'s order: kept as links are
    /// added, as every frame asks.
    roles: [Links; 3],
    /// Frames seen lately, when de-duplication is on.
    dedup: Option<Dedup>,
    /// Links that get addressed frames too, whoever they are for.
    sniffers: Links,
}

/// Errors of a node's set-up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeError {
    /// More than [`MAX_LINKS`] links.
    TooManyLinks,
    /// The link number is taken, or past [`MAX_LINKS`].
    BadLink(LinkId),
    /// The engine's settings.
    Config(crate::ConfigError),
}

impl core::fmt::Display for NodeError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            NodeError::TooManyLinks => write!(f, "more than {MAX_LINKS} links"),
            NodeError::BadLink(l) => write!(f, "link {l} is taken or out of range"),
            NodeError::Config(e) => write!(f, "{e}"),
        }
    }
}

impl core::error::Error for NodeError {}

impl From<crate::ConfigError> for NodeError {
    fn from(e: crate::ConfigError) -> Self {
        NodeError::Config(e)
    }
}

impl Core {
    fn new(require_signed: bool) -> Self {
        Core {
            links: [const { None }; MAX_LINKS],
            table: Table::new(),
            drops: Drops::default(),
            require_signed,
            beacons: Beacons::default(),
            filtered_out: Links::NONE,
            roles: [Links::NONE; 3],
            dedup: None,
            sniffers: Links::NONE,
        }
    }

    fn add(&mut self, link: LinkId, spec: LinkSpec) -> Result<(), NodeError> {
        let slot = self
            .links
            .get_mut(usize::from(link))
            .ok_or(NodeError::BadLink(link))?;
        if slot.is_some() {
            return Err(NodeError::BadLink(link));
        }
        let peers = if spec.role == Role::Ground {
            Answered::stations()
        } else {
            Answered::One(Default::default())
        };
        *slot = Some(LinkState {
            spec,
            peers,
            filter_in: Filter::ALL,
            filter_out: Filter::ALL,
        });
        let role = &mut self.roles[spec.role as usize];
        *role = role.union(Links::only(link));
        Ok(())
    }

    /// Sets the filter of `link` in `direction`.
    fn set_filter(
        &mut self,
        link: LinkId,
        direction: Direction,
        filter: Filter,
    ) -> Result<(), NodeError> {
        let state = self
            .links
            .get_mut(usize::from(link))
            .and_then(|l| l.as_mut())
            .ok_or(NodeError::BadLink(link))?;
        match direction {
            Direction::In => state.filter_in = filter,
            Direction::Out => {
                state.filter_out = filter;
                self.filtered_out = if filter.is_all() {
                    self.filtered_out.without(link)
                } else {
                    self.filtered_out.union(Links::only(link))
                };
            }
        }
        Ok(())
    }

    /// Sends `link` the frames addressed to others as well as the
    /// broadcasts (its out-filter still applies).
    fn set_sniffer(&mut self, link: LinkId) -> Result<(), NodeError> {
        self.spec(link).ok_or(NodeError::BadLink(link))?;
        self.sniffers = self.sniffers.union(Links::only(link));
        Ok(())
    }

    /// De-duplication over `window`, or none (`None`, or a zero window).
    fn set_dedup(&mut self, window: Option<core::time::Duration>) {
        self.dedup = window.filter(|w| !w.is_zero()).map(Dedup::new);
    }

    /// Whether a frame its link admitted may be routed: why not, if not.
    /// The in-filter first, so that a copy refused on one link does not
    /// make the copy another link admits a duplicate.
    fn screen(&mut self, a: &Arrival, now: Moment) -> Option<DropReason> {
        let state = self.links.get(usize::from(a.link))?.as_ref()?;
        if !state.filter_in.admits_frame(&a.frame) {
            return Some(DropReason::Filtered);
        }
        let dedup = self.dedup.as_mut()?;
        dedup
            .is_duplicate(a.frame.as_bytes(), now)
            .then_some(DropReason::Duplicate)
    }

    /// `to` without the links whose out-filter refuses `frame`.
    fn filter_out(&self, frame: &Frame<&[u8]>, to: Links) -> Links {
        to.intersection(self.filtered_out)
            .iter()
            .filter(|l| {
                self.links
                    .get(usize::from(*l))
                    .and_then(|s| s.as_ref())
                    .is_some_and(|s| !s.filter_out.admits_frame(frame))
            })
            .fold(to, Links::without)
    }

    fn spec(&self, link: LinkId) -> Option<LinkSpec> {
        self.links
            .get(usize::from(link))
            .and_then(|l| l.as_ref())
            .map(|l| l.spec)
    }

    /// The links of `role`.
    fn of(&self, role: Role) -> Links {
        self.roles[role as usize]
    }

    /// Every link.
    fn all(&self) -> Links {
        self.of(Role::Peer)
            .union(self.of(Role::Ground))
            .union(self.of(Role::Autonomy))
    }

    /// Whether the link takes frames from `source`: any source where the
    /// link has one far end; the configured one under `--peer`; a peer, or
    /// a newcomer the peer set admits (`joins`: the frame may make its
    /// source a peer; `displaces`: at once), where the node chooses.
    fn admits_source(
        &mut self,
        a: &Arrival,
        now: Moment,
        joins: bool,
        displaces: bool,
        out: &mut impl FnMut(LinkId, Peers),
    ) -> bool {
        let (Some(state), Some(source)) = (
            self.links
                .get_mut(usize::from(a.link))
                .and_then(|l| l.as_mut()),
            a.source,
        ) else {
            return true;
        };
        match state.spec.answers {
            Answers::Target => true,
            Answers::Fixed(peer) => {
                peer.ip() == source.ip() && (peer.port() == 0 || peer.port() == source.port())
            }
            Answers::Chosen if !joins => state.peers.contains(source),
            Answers::Chosen => match state.peers.heard(source, now, displaces) {
                Admission::Known => true,
                Admission::Added => {
                    out(a.link, state.peers.peers());
                    true
                }
                Admission::Refused => false,
            },
        }
    }

    /// Learns the sender's route (`trusted`: it outranks strangers'), then
    /// the links among `allowed` the routing rules send the frame to and
    /// whose out-filters admit it.
    fn route(&mut self, a: &Arrival, trusted: bool, allowed: Links) -> Links {
        let h = a.frame.header();
        self.table.learn(a.link, h.sysid, h.compid, trusted);
        let meta =
            <fbwag_dialect::Dialect as fbwag_dialect::mavframe::MessageSet>::meta(a.frame.msg_id());
        let others = allowed.intersection(self.all()).without(a.link);
        let to = match fbwag_dialect::mavframe::route::target(&a.frame, meta) {
            Some((sysid, compid)) => (self.table.links_to(sysid, compid))
                .union(self.sniffers)
                .intersection(others),
            None => others,
        };
        self.filter_out(&a.frame, to)
    }

    /// Where to send the node's signed heartbeat, if anywhere: `a` claims
    /// the peer's ids and carries a signature, but the link's parser could
    /// not accept it as fresh (it returns such a frame, signed with the
    /// key but stale, unauthenticated), from an address the listening
    /// link does not answer. Its sender holds the key: a peer whose clock
    /// is behind this node's, perhaps restarted on a new address while the
    /// link still answers the old one (or a replay). A heartbeat lets a
    /// genuine peer adopt this node's signing time, after which its frames
    /// are fresh and its next one moves the peer (a verified frame does at
    /// once); the sender does not become the peer, and learns nothing but
    /// the heartbeat. At most one a second to each address
    /// ([`Beacons`]): a replayer from one address (or a few) gets its own
    /// share, never the peer's.
    fn time_beacon(&mut self, a: &Arrival, now: Moment) -> Option<SocketAddr> {
        let source = a.source?;
        let state = self.links.get(usize::from(a.link))?.as_ref()?;
        let listening = state.spec.answers == Answers::Chosen;
        if !(a.frame.is_signed() && !a.authenticated && listening) {
            return None;
        }
        self.beacons.take(source, now).then_some(source)
    }

    /// Where to send the node's signed heartbeat when the peer link's
    /// parser refused a frame from `source` for its signature: a listening
    /// peer link, under the time beacon's limit ([`Beacons`]). A peer with
    /// another key then counts a bad signature too: a wrong key shows on
    /// both sides.
    fn signature_beacon(&mut self, link: LinkId, source: SocketAddr, now: Moment) -> bool {
        let Some(state) = self.links.get(usize::from(link)).and_then(|l| l.as_ref()) else {
            return false;
        };
        let listening = state.spec.role == Role::Peer && state.spec.answers == Answers::Chosen;
        // A link that answers a peer has its key right: a stranger's bad
        // signature there gets nothing.
        listening && state.peers.is_empty() && self.beacons.take(source, now)
    }

    /// The source rule of a peer link, once for the FC and the companion:
    /// `Ok(trusted)` when `a` may go on (from the link's peer, or a trusted
    /// frame that makes its source the peer: `Trust` with `peer`'s ids);
    /// otherwise a `not_peer` drop, after a time beacon (`heartbeat`, the
    /// node's own) to a key holder behind in time that claims `peer`'s ids.
    fn peer_source<E: Copy>(
        &mut self,
        a: &Arrival,
        now: Moment,
        peer: Peer,
        out: &mut crate::outbox::Outbox<Output<E>, 24>,
        heartbeat: impl FnOnce() -> Message,
    ) -> Result<bool, Fate> {
        let from = sender(&a.frame);
        let trusted = crate::Trust {
            peer,
            require_signed: self.require_signed,
        }
        .admits(crate::Origin {
            peer: from,
            authenticated: a.authenticated,
            seq: 0,
        });
        let admitted = self.admits_source(a, now, trusted, a.authenticated, &mut |link, peers| {
            out.push(Output::Peers { link, peers })
        });
        if admitted {
            return Ok(trusted);
        }
        if from == peer {
            if let Some(to) = self.time_beacon(a, now) {
                let message = heartbeat();
                out.push(Output::TransmitTo {
                    link: a.link,
                    to,
                    message,
                });
            }
        }
        Err(self.drop(DropReason::NotPeer))
    }

    /// Counts a drop.
    fn drop(&mut self, reason: DropReason) -> Fate {
        self.drops.count(reason);
        Fate::dropped(reason)
    }

    /// A link opened again: its peers are forgotten.
    fn reopened(&mut self, link: LinkId) {
        if let Some(Some(state)) = self.links.get_mut(usize::from(link)) {
            state.peers.clear();
        }
    }
}

/// Addresses a node sends time beacons to at once, at most
/// (`Core::time_beacon`): each gets one a second at most, and a new
/// address takes the place of one served more than a second ago.
pub const BEACON_ADDRESSES: usize = 16;

/// The time beacons sent lately: to which address, and when.
#[derive(Debug, Clone, Default)]
struct Beacons([Option<(SocketAddr, Moment)>; BEACON_ADDRESSES]);

impl Beacons {
    /// Whether `to` may have a beacon at `now`; if so, it is counted.
    fn take(&mut self, to: SocketAddr, now: Moment) -> bool {
        const PERIOD: core::time::Duration = core::time::Duration::from_secs(1);
        let idle = |slot: &Option<(SocketAddr, Moment)>| {
            slot.is_none_or(|(_, at)| now.since(at) >= PERIOD)
        };
        let slot = match self.0.iter().position(|s| s.is_some_and(|(a, _)| a == to)) {
            Some(i) if idle(&self.0[i]) => i,
            Some(_) => return false,
            None => match self.0.iter().position(idle) {
                Some(i) => i,
                None => return false,
            },
        };
        self.0[slot] = Some((to, now));
        true
    }
}

/// The sender of `frame`.
fn sender(frame: &Frame<&[u8]>) -> Peer {
    let h = frame.header();
    Peer::new(h.sysid, h.compid)
}

/// Whether the dialect knows `frame`'s message (a router can frame it
/// again: its checksum needs the message's CRC_EXTRA).
fn known(frame: &Frame<&[u8]>) -> bool {
    <fbwag_dialect::Dialect as fbwag_dialect::mavframe::MessageSet>::meta(frame.msg_id()).is_some()
}
