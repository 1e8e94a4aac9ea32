//! MAVLink routing, sans-IO: which links a received frame goes to.
//!
//! The rules are mavlink.io's ("Routing"), as ArduPilot and mavlink-router
//! apply them:
//!
//! - every frame teaches the table that its sender (system, component) is
//!   reachable through the link it came in on;
//! - a frame addressed to a system (its message has `target_system`,
//!   non-zero) goes to the links where that system was seen; with a
//!   non-zero `target_component`, where that component was seen (or where
//!   only the system was seen through a component 0 sender); an addressee
//!   never seen goes nowhere;
//! - every other frame (no target field, target 0, or an id the dialect does
//!   not know, whose fields cannot be read) is a broadcast: every link;
//! - never back to the link it came from, and the frame's bytes are
//!   forwarded as received (signed frames stay verifiable).
//!
//! A sender seen on several links is reachable through all of them: a frame
//! forged with another system's ids cannot divert that system's traffic
//! away from its real link.
//!
//! Routes are *trusted* or not, as the caller says when it learns them
//! (`trusted`: the frame was authenticated, or came on a link the owner
//! trusts): strangers on a link can neither drop a trusted route nor share
//! it.
//!
//! - An untrusted frame with a trusted route's ids changes nothing: the
//!   forger's link gets no copy of that system's traffic. An untrusted
//!   route becomes trusted with its first trusted frame, and from then on
//!   goes only where trusted frames came from. Nor does an untrusted
//!   component 0 sender (which stands for its whole system) share a
//!   trusted component's traffic.
//! - A table that must forget a route forgets the least recently seen
//!   untrusted one; a trusted route is forgotten only for another trusted
//!   one (the least recently seen trusted route then goes), never for a
//!   stranger's: a flood of made-up ids cannot push the autopilot out of
//!   the table.
//!
//! Two tables apply these rules. `RoutingTable` (feature `alloc`, which
//! `std` turns on) holds every sender ever seen and forgets none: the key
//! space (system, component) has 65,536 addresses, so a table with room
//! for each of them needs no eviction, and a swarm of a thousand systems,
//! or a flood of made-up ids, makes it forget nobody (the vehicle least
//! of all). [`FixedRoutingTable<N>`](FixedRoutingTable) is for `no_std`
//! builds without a heap: `N` senders in an array, and the eviction rule
//! above when a new sender finds it full.
//!
//! ```
//! use mavframe::route::{FixedRoutingTable, Links};
//! use mavframe::{Frame, MessageMeta};
//! # let meta = MessageMeta::new(76, "COMMAND_LONG", 152, 33, 33, &[]).with_target_offsets(Some(30), Some(31));
//! # fn frame(sysid: u8, compid: u8, payload: &[u8]) -> Vec<u8> {
//! #   let mut b = vec![0xfd, payload.len() as u8, 0, 0, 0, sysid, compid, 76, 0, 0];
//! #   b.extend_from_slice(payload); b.extend_from_slice(&[0, 0]); b }
//! let mut table = FixedRoutingTable::<16>::new();
//! // The autopilot (1/1) speaks on link 0 (trusted), a ground station
//! // (255/190) on link 2.
//! table.learn(0, 1, 1, true);
//! table.learn(2, 255, 190, false);
//! // A COMMAND_LONG from the ground station to system 1, component 1:
//! let mut payload = [0u8; 33];
//! payload[30] = 1;
//! payload[31] = 1;
//! let bytes = frame(255, 190, &payload);
//! let f = Frame::new_checked(&bytes).unwrap();
//! let to = table.route(2, &f, Some(&meta), Links::all(3), false);
//! assert_eq!(to, Links::only(0));
//! ```

use crate::frame::Frame;
use crate::message::MessageMeta;
#[cfg(feature = "alloc")]
use alloc::collections::BTreeMap;

/// A link's number in a router: 0..64.
pub type LinkId = u8;

/// A set of links (at most 64). Its `Debug` lists the links' numbers:
/// `Links[1, 3]`.
///
/// ```
/// use mavframe::route::Links;
///
/// let links = Links::only(1).union(Links::only(3));
/// assert_eq!(format!("{links:?}"), "Links[1, 3]");
/// assert_eq!(links.iter().collect::<Vec<_>>(), [1, 3]);
/// ```
#[derive(Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Links(u64);

impl core::fmt::Debug for Links {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str("Links")?;
        f.debug_list().entries(self.iter()).finish()
    }
}

impl Links {
    /// No link.
    pub const NONE: Links = Links(0);

    /// Links `0..n` (`n` ≤ 64).
    pub const fn all(n: usize) -> Links {
        if n >= 64 {
            Links(u64::MAX)
        } else {
            Links((1u64 << n) - 1)
        }
    }

    /// Only `link`.
    pub const fn only(link: LinkId) -> Links {
        Links(1u64 << (link & 63))
    }

    /// Whether `link` is in the set.
    pub const fn contains(self, link: LinkId) -> bool {
        self.0 & (1u64 << (link & 63)) != 0
    }

    /// The set without `link`.
    pub const fn without(self, link: LinkId) -> Links {
        Links(self.0 & !(1u64 << (link & 63)))
    }

    /// Both sets' links.
    pub const fn union(self, other: Links) -> Links {
        Links(self.0 | other.0)
    }

    /// Links in both sets.
    pub const fn intersection(self, other: Links) -> Links {
        Links(self.0 & other.0)
    }

    /// True when empty.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }

    /// The links, in order: a step per link in the set, not per bit.
    pub fn iter(self) -> impl Iterator<Item = LinkId> {
        let mut rest = self.0;
        core::iter::from_fn(move || {
            let link = rest.trailing_zeros();
            rest &= rest.checked_sub(1)?;
            Some(link as LinkId)
        })
    }

    /// How many links.
    pub const fn len(self) -> usize {
        self.0.count_ones() as usize
    }
}

/// What the table knows of one sender: the links it was seen on, and
/// whether a trusted frame taught them.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
struct Route {
    links: Links,
    /// Learned from a trusted frame (see the module docs).
    trusted: bool,
}

impl Route {
    const fn new(link: LinkId, trusted: bool) -> Route {
        Route {
            links: Links::only(link),
            trusted,
        }
    }

    /// Another frame of this sender came in on `link` (`trusted` as for
    /// `learn`): the trust rules of the module docs. False when the frame
    /// changed nothing (a stranger's frame with a trusted sender's ids),
    /// which then does not count as the sender being heard either.
    fn heard(&mut self, link: LinkId, trusted: bool) -> bool {
        match (self.trusted, trusted) {
            (true, false) => return false,
            // Trusted from now on: only where trusted frames came from.
            (false, true) => *self = Route::new(link, true),
            _ => self.links = self.links.union(Links::only(link)),
        }
        true
    }
}

/// Where a frame to one component goes, from that component's route and
/// its system's component 0 sender's (which stands for the whole system):
/// both, but a trusted component shares nothing with an untrusted
/// component 0, or a stranger claiming the system would get a copy of the
/// component's traffic.
fn to_component(component: Option<Route>, system: Option<Route>) -> Links {
    let links = |r: Option<Route>| r.map_or(Links::NONE, |r| r.links);
    match (component, system) {
        (Some(c), Some(s)) if c.trusted && !s.trusted => c.links,
        _ => links(component).union(links(system)),
    }
}

/// A sender's key: the system in the high byte, so that a system's
/// components sort together (one range of the map).
const fn key(sysid: u8, compid: u8) -> u16 {
    u16::from_be_bytes([sysid, compid])
}

/// Where each (system, component) was seen: every sender of the network,
/// none ever forgotten (see the module docs). A map ordered by (system,
/// component): a frame costs one search to learn its sender and one or two
/// to find its addressee (a range, for component 0). The key space bounds
/// it: at most 65,280 senders (system 0 is never learned), 2.4 MiB of
/// heap when every one was seen; an empty table allocates nothing.
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash)]
pub struct RoutingTable {
    routes: BTreeMap<u16, Route>,
}

#[cfg(feature = "alloc")]
impl RoutingTable {
    /// An empty table.
    pub const fn new() -> Self {
        RoutingTable {
            routes: BTreeMap::new(),
        }
    }

    /// Records that `sysid`/`compid` sent a frame through `link`;
    /// `trusted`: the frame was authenticated, or its link is trusted (see
    /// the module docs for what an untrusted frame may change). System 0
    /// is nobody (the broadcast address) and is not learned.
    pub fn learn(&mut self, link: LinkId, sysid: u8, compid: u8, trusted: bool) {
        if sysid == 0 {
            return;
        }
        self.routes
            .entry(key(sysid, compid))
            .and_modify(|r| {
                r.heard(link, trusted);
            })
            .or_insert(Route::new(link, trusted));
    }

    /// The links where `sysid` (and `compid`, unless 0) was seen.
    pub fn links_to(&self, sysid: u8, compid: u8) -> Links {
        if compid != 0 {
            let route = |c| self.routes.get(&key(sysid, c)).copied();
            return to_component(route(compid), route(0));
        }
        self.routes
            .range(key(sysid, 0)..=key(sysid, u8::MAX))
            .fold(Links::NONE, |acc, (_, r)| acc.union(r.links))
    }

    /// Senders held.
    pub fn len(&self) -> usize {
        self.routes.len()
    }

    /// True when no sender was learned.
    pub fn is_empty(&self) -> bool {
        self.routes.is_empty()
    }

    /// Learns `frame`'s sender on `from` (`trusted` as for
    /// [`learn`](Self::learn)), then returns the links among `links` (the
    /// router's open links) it must be forwarded to. `meta` is the
    /// message's table row (`None` for an id the dialect does not know:
    /// such a frame is forwarded everywhere, raw).
    pub fn route<T: AsRef<[u8]>>(
        &mut self,
        from: LinkId,
        frame: &Frame<T>,
        meta: Option<&MessageMeta>,
        links: Links,
        trusted: bool,
    ) -> Links {
        let frame = &frame.as_view();
        let h = frame.header();
        self.learn(from, h.sysid, h.compid, trusted);
        forward(frame, meta, links.without(from), |s, c| self.links_to(s, c))
    }
}

/// One sender of a [`FixedRoutingTable`].
#[derive(Debug, Clone, Copy, Default, Hash)]
struct Slot {
    key: u16,
    route: Route,
    /// Learning order, for eviction: the least recently seen route goes.
    seen: u64,
}

/// Where each (system, component) was seen, without a heap: up to `N`
/// senders in an array (a full table forgets the untrusted sender heard
/// least recently; see the module docs). For `no_std` builds without
/// `alloc`; with it, `RoutingTable` holds every sender.
#[derive(Debug, Clone, Hash)]
pub struct FixedRoutingTable<const N: usize = 64> {
    slots: [Slot; N],
    len: usize,
    clock: u64,
}

impl<const N: usize> Default for FixedRoutingTable<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FixedRoutingTable<N> {
    /// An empty table.
    pub const fn new() -> Self {
        const EMPTY: Slot = Slot {
            key: 0,
            route: Route {
                links: Links::NONE,
                trusted: false,
            },
            seen: 0,
        };
        FixedRoutingTable {
            slots: [EMPTY; N],
            len: 0,
            clock: 0,
        }
    }

    /// Records that `sysid`/`compid` sent a frame through `link`;
    /// `trusted`: the frame was authenticated, or its link is trusted (see
    /// the module docs for what an untrusted frame may change). System 0
    /// is nobody (the broadcast address) and is not learned. A new sender in a full table takes the
    /// place of the least recently seen untrusted one, or, if it is
    /// trusted and every route is, of the least recently seen trusted one.
    pub fn learn(&mut self, link: LinkId, sysid: u8, compid: u8, trusted: bool) {
        if sysid == 0 || N == 0 {
            return;
        }
        self.clock += 1;
        let (clock, key) = (self.clock, key(sysid, compid));
        if let Some(s) = self.slots[..self.len].iter_mut().find(|s| s.key == key) {
            if s.route.heard(link, trusted) {
                s.seen = clock;
            }
            return;
        }
        let Some(at) = self.free_slot(trusted) else {
            return;
        };
        self.slots[at] = Slot {
            key,
            route: Route::new(link, trusted),
            seen: clock,
        };
    }

    /// The slot a new route takes: a free one, else the least recently
    /// seen untrusted route's, else (for a trusted route only) the least
    /// recently seen trusted route's.
    fn free_slot(&mut self, trusted: bool) -> Option<usize> {
        if self.len < N {
            self.len += 1;
            return Some(self.len - 1);
        }
        let least_recent = |want_trusted: bool| {
            (0..N)
                .filter(|&i| self.slots[i].route.trusted == want_trusted)
                .min_by_key(|&i| self.slots[i].seen)
        };
        least_recent(false).or_else(|| least_recent(true).filter(|_| trusted))
    }

    /// The links where `sysid` (and `compid`, unless 0) was seen.
    pub fn links_to(&self, sysid: u8, compid: u8) -> Links {
        let held = &self.slots[..self.len];
        if compid != 0 {
            let route = |c| {
                held.iter()
                    .find(|s| s.key == key(sysid, c))
                    .map(|s| s.route)
            };
            return to_component(route(compid), route(0));
        }
        held.iter()
            .filter(|s| s.key.to_be_bytes()[0] == sysid)
            .fold(Links::NONE, |acc, s| acc.union(s.route.links))
    }

    /// Senders held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when no sender was learned.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Learns `frame`'s sender on `from` (`trusted` as for
    /// [`learn`](Self::learn)), then returns the links among `links` (the
    /// router's open links) it must be forwarded to. `meta` is the
    /// message's table row (`None` for an id the dialect does not know:
    /// such a frame is forwarded everywhere, raw).
    pub fn route<T: AsRef<[u8]>>(
        &mut self,
        from: LinkId,
        frame: &Frame<T>,
        meta: Option<&MessageMeta>,
        links: Links,
        trusted: bool,
    ) -> Links {
        let frame = &frame.as_view();
        let h = frame.header();
        self.learn(from, h.sysid, h.compid, trusted);
        forward(frame, meta, links.without(from), |s, c| self.links_to(s, c))
    }
}

/// The routing rules' last step, for both tables: an addressed frame to
/// `others` where its addressee was seen (`links_to`), any other to every
/// one of `others` (the open links but the one it came from).
fn forward(
    frame: &Frame<&[u8]>,
    meta: Option<&MessageMeta>,
    others: Links,
    links_to: impl FnOnce(u8, u8) -> Links,
) -> Links {
    match target(frame, meta) {
        Some((sysid, compid)) => links_to(sysid, compid).intersection(others),
        None => others,
    }
}

/// A frame's addressee, when it has one: `Some((system, component))` for a
/// message with a non-zero `target_system` (component 0: every component).
/// Fields beyond a truncated payload read as zero, as MAVLink 2 requires.
pub fn target(frame: &Frame<&[u8]>, meta: Option<&MessageMeta>) -> Option<(u8, u8)> {
    let meta = meta?;
    let payload = frame.payload();
    let read = |at: Option<u8>| {
        at.and_then(|i| payload.get(i as usize).copied())
            .unwrap_or(0)
    };
    let sysid = read(meta.target_system_offset);
    (meta.target_system_offset.is_some() && sysid != 0)
        .then(|| (sysid, read(meta.target_component_offset)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::STX_V2;
    use std::vec::Vec;

    #[test]
    fn a_set_of_links_iterates_its_links_in_order() {
        let listed = |l: Links| l.iter().collect::<Vec<_>>();
        assert_eq!(listed(Links::NONE), Vec::<LinkId>::new());
        assert_eq!(listed(Links::all(64)), (0..64).collect::<Vec<_>>());
        let some = Links::only(0).union(Links::only(5)).union(Links::only(63));
        assert_eq!(listed(some), [0, 5, 63]);
        assert_eq!(
            (some.len(), Links::NONE.len(), Links::all(64).len()),
            (3, 0, 64)
        );
        assert!(Links::NONE.is_empty() && !some.is_empty());
    }

    const TARGETED: MessageMeta = MessageMeta::new(76, "COMMAND_LONG", 152, 33, 33, &[])
        .with_target_offsets(Some(30), Some(31));
    const UNTARGETED: MessageMeta = MessageMeta::new(0, "HEARTBEAT", 50, 9, 9, &[]);

    /// Both tables, so that each rule is checked on each.
    trait Table: Default {
        fn learn(&mut self, link: LinkId, sysid: u8, compid: u8, trusted: bool);
        fn links_to(&self, sysid: u8, compid: u8) -> Links;
        fn route(&mut self, from: LinkId, b: &[u8], meta: Option<&MessageMeta>) -> Links;
    }

    macro_rules! table {
        ($t:ty) => {
            impl Table for $t {
                fn learn(&mut self, link: LinkId, sysid: u8, compid: u8, trusted: bool) {
                    <$t>::learn(self, link, sysid, compid, trusted)
                }
                fn links_to(&self, sysid: u8, compid: u8) -> Links {
                    <$t>::links_to(self, sysid, compid)
                }
                fn route(&mut self, from: LinkId, b: &[u8], meta: Option<&MessageMeta>) -> Links {
                    let f = Frame::new_checked(b).unwrap();
                    <$t>::route(self, from, &f, meta, Links::all(4), false)
                }
            }
        };
    }
    table!(FixedRoutingTable<8>);
    #[cfg(feature = "alloc")]
    table!(RoutingTable);

    /// Runs each rule's check on the fixed table and, with `alloc`, on the
    /// map.
    macro_rules! both {
        ($($name:ident),* $(,)?) => {
            mod fixed {
                $(#[test]
                fn $name() {
                    super::$name::<super::FixedRoutingTable<8>>();
                })*
            }
            #[cfg(feature = "alloc")]
            mod map {
                $(#[test]
                fn $name() {
                    super::$name::<super::RoutingTable>();
                })*
            }
        };
    }
    both!(
        a_stranger_claiming_component_0_gets_no_copy,
        broadcasts_go_everywhere_but_back,
        addressed_frames_go_only_where_the_addressee_was_seen,
        a_forged_sender_cannot_divert_traffic,
        a_stranger_gets_no_copy_of_a_trusted_senders_traffic,
    );

    /// A frame's bytes (checksum not needed by the router).
    fn bytes(sysid: u8, compid: u8, target: Option<(u8, u8)>) -> [u8; 45] {
        let mut b = [0u8; 45];
        b[..10].copy_from_slice(&[STX_V2, 33, 0, 0, 0, sysid, compid, 76, 0, 0]);
        if let Some((s, c)) = target {
            b[10 + 30] = s;
            b[10 + 31] = c;
        }
        b
    }

    fn broadcasts_go_everywhere_but_back<T: Table>() {
        let mut t = T::default();
        let hb = bytes(1, 1, None);
        assert_eq!(t.route(1, &hb, Some(&UNTARGETED)), Links(0b1101));
        // Target system 0 is a broadcast too; unknown ids likewise.
        let zero = bytes(255, 190, Some((0, 0)));
        assert_eq!(t.route(2, &zero, Some(&TARGETED)), Links(0b1011));
        assert_eq!(t.route(3, &zero, None), Links(0b0111));
        t.learn(0, 0, 0, true);
        assert_eq!(t.links_to(0, 0), Links::NONE, "system 0 is nobody");
    }

    fn addressed_frames_go_only_where_the_addressee_was_seen<T: Table>() {
        let mut t = T::default();
        let to_fc = bytes(255, 190, Some((1, 1)));
        assert_eq!(
            t.route(2, &to_fc, Some(&TARGETED)),
            Links::NONE,
            "an unknown addressee goes nowhere"
        );
        t.learn(0, 1, 1, true); // the autopilot on link 0
        t.learn(3, 1, 191, true); // its companion on link 3
        t.learn(1, 2, 1, true); // another system's autopilot on link 1
        assert_eq!(t.route(2, &to_fc, Some(&TARGETED)), Links::only(0));
        let to_system = bytes(255, 190, Some((1, 0)));
        assert_eq!(
            t.route(2, &to_system, Some(&TARGETED)),
            Links(0b1001),
            "component 0: every component of the system"
        );
        // A component 0 sender stands for the whole system.
        t.learn(1, 1, 0, true);
        assert_eq!(t.route(2, &to_fc, Some(&TARGETED)), Links(0b0011));
        // The addressee's own link is never the one it came from.
        let from_fc_link = bytes(1, 191, Some((1, 1)));
        assert_eq!(t.route(0, &from_fc_link, Some(&TARGETED)), Links::only(1));
    }

    fn a_forged_sender_cannot_divert_traffic<T: Table>() {
        let mut t = T::default();
        t.learn(0, 1, 1, false);
        // An attacker on link 2 sends frames with the autopilot's ids.
        t.learn(2, 1, 1, false);
        let to_fc = bytes(255, 190, Some((1, 1)));
        let to = t.route(3, &to_fc, Some(&TARGETED));
        assert!(to.contains(0), "still reaches the real autopilot");
    }

    /// An untrusted frame with a trusted route's ids gets its link no
    /// copy; an untrusted route that turns trusted keeps only the trusted
    /// link, then adds the links trusted frames come from.
    fn a_stranger_gets_no_copy_of_a_trusted_senders_traffic<T: Table>() {
        let mut t = T::default();
        t.learn(0, 1, 1, true);
        t.learn(2, 1, 1, false);
        assert_eq!(t.links_to(1, 1), Links::only(0));
        t.learn(2, 5, 1, false);
        t.learn(3, 5, 1, true);
        assert_eq!(
            t.links_to(5, 1),
            Links::only(3),
            "the stranger's link dropped"
        );
        t.learn(1, 5, 1, true);
        assert_eq!(t.links_to(5, 1), Links(0b1010));
    }

    /// Component 0 stands for the whole system, but a stranger's
    /// component 0 does not share a trusted component's traffic; an
    /// untrusted component still shares with it, and a frame to every
    /// component of the system reaches both.
    fn a_stranger_claiming_component_0_gets_no_copy<T: Table>() {
        let mut t = T::default();
        t.learn(0, 1, 1, true);
        t.learn(2, 1, 0, false);
        assert_eq!(t.links_to(1, 1), Links::only(0));
        assert_eq!(t.links_to(1, 0), Links(0b101));
        assert_eq!(t.links_to(1, 7), Links::only(2), "unseen: the system's");
        t.learn(3, 1, 0, true);
        assert_eq!(t.links_to(1, 1), Links::only(0).union(Links::only(3)));
        t.learn(0, 4, 1, false);
        t.learn(2, 4, 0, false);
        assert_eq!(t.links_to(4, 1), Links(0b101));
    }

    #[test]
    fn a_truncated_payload_reads_a_zero_target() {
        // MAVLink 2 drops trailing zeros: a COMMAND_LONG to 0/0 may end
        // before its target bytes.
        let mut b = bytes(255, 190, None);
        b[1] = 10;
        let f = Frame::new_checked(&b[..22]).unwrap();
        assert_eq!(target(&f, Some(&TARGETED)), None);
    }

    /// Every (system, component) but system 0: 65,280 senders.
    #[cfg(feature = "alloc")]
    fn every_address() -> impl Iterator<Item = (u8, u8)> {
        (1..=u8::MAX).flat_map(|s| (0..=u8::MAX).map(move |c| (s, c)))
    }

    /// Every address the key space has is held, each where it was seen
    /// (a link per address, chosen from both ids so neighbours differ).
    #[cfg(feature = "alloc")]
    #[test]
    fn the_map_holds_every_address() {
        let link = |s: u8, c: u8| (s ^ c.rotate_left(3)) % 64;
        let mut t = RoutingTable::new();
        for (s, c) in every_address() {
            t.learn(link(s, c), s, c, false);
        }
        assert_eq!(t.len(), 255 * 256);
        for (s, c) in every_address().filter(|&(_, c)| c != 0) {
            let want = Links::only(link(s, c)).union(Links::only(link(s, 0)));
            assert_eq!(t.links_to(s, c), want, "{s}/{c}");
        }
        let system_9 = (0..=u8::MAX).fold(Links::NONE, |acc, c| acc.union(Links::only(link(9, c))));
        assert_eq!(t.links_to(9, 0), system_9);
    }

    /// The fleet behind a radio: the vehicle (1/1) and 1,000 other senders
    /// (250 systems of 4 components), all on the vehicle's link 0, none
    /// trusted; then a ground station on link 1 addresses the vehicle.
    /// Every sender is held, and the command goes to link 0, as it does
    /// while the swarm keeps talking.
    #[cfg(feature = "alloc")]
    #[test]
    fn the_map_holds_a_thousand_senders_beside_the_vehicle() {
        let mut t = RoutingTable::new();
        t.learn(0, 1, 1, false);
        let swarm = (2..=251u8).flat_map(|s| (1..=4u8).map(move |c| (s, c)));
        for (s, c) in swarm.clone().chain(swarm.clone()) {
            t.learn(0, s, c, false);
        }
        assert_eq!(t.len(), 1 + 1_000);
        let to_vehicle = bytes(255, 190, Some((1, 1)));
        let f = Frame::new_checked(&to_vehicle[..]).unwrap();
        for _ in 0..200 {
            let to = t.route(1, &f, Some(&TARGETED), Links::all(2), false);
            assert_eq!(to, Links::only(0));
        }
        assert!(swarm
            .clone()
            .all(|(s, c)| t.links_to(s, c) == Links::only(0)));
    }

    /// Trust at scale: a trusted autopilot and companion, then strangers on
    /// link 2 claim every address, theirs included, twice. The trusted
    /// routes keep their one link; every stranger is held; a stranger's
    /// route turned trusted on link 3 drops link 2 and no untrusted frame
    /// adds it back.
    #[cfg(feature = "alloc")]
    #[test]
    fn the_map_keeps_trust_priorities_at_scale() {
        let mut t = RoutingTable::new();
        t.learn(0, 1, 1, true);
        t.learn(1, 1, 191, true);
        for (s, c) in every_address().chain(every_address()) {
            t.learn(2, s, c, false);
        }
        assert_eq!(t.len(), 255 * 256);
        assert_eq!(t.routes[&key(1, 1)], Route::new(0, true), "1/1");
        assert_eq!(t.routes[&key(1, 191)], Route::new(1, true), "1/191");
        assert_eq!(t.links_to(1, 1), Links::only(0), "not the stranger's 1/0");
        assert_eq!(t.links_to(1, 191), Links::only(1));
        let turned = (100..=199u8).flat_map(|s| (1..=10u8).map(move |c| (s, c)));
        for (s, c) in turned.clone() {
            t.learn(3, s, c, true);
            t.learn(2, s, c, false);
        }
        for (s, c) in turned {
            assert_eq!(t.routes[&key(s, c)], Route::new(3, true), "{s}/{c}");
        }
        assert_eq!(t.routes[&key(100, 11)], Route::new(2, false));
    }

    #[test]
    fn a_full_table_forgets_the_least_recent_sender() {
        let mut t = FixedRoutingTable::<2>::new();
        t.learn(0, 1, 1, false);
        t.learn(1, 2, 1, false);
        t.learn(0, 1, 1, false); // heard again: now the most recent
        t.learn(2, 3, 1, false); // evicts 2/1
        assert_eq!(t.links_to(1, 1), Links::only(0));
        assert_eq!(t.links_to(2, 1), Links::NONE);
        assert_eq!(t.links_to(3, 1), Links::only(2));
        assert_eq!(t.len(), 2);
    }

    /// HEARTBEATs of 1,000 strangers' senders never evict the autopilot's
    /// trusted route from the fixed table (the least recently seen route
    /// went, whoever it was); strangers evict each other, oldest first.
    #[test]
    fn strangers_never_evict_a_trusted_route() {
        let mut t = FixedRoutingTable::<256>::new();
        t.learn(0, 1, 1, true);
        let strangers = (2..=251u8).flat_map(|s| (1..=4u8).map(move |c| (s, c)));
        for (s, c) in strangers.clone() {
            t.learn(2, s, c, false);
        }
        assert_eq!(t.len(), 256);
        assert_eq!(t.links_to(1, 1), Links::only(0));
        let (newest, held) = strangers
            .clone()
            .enumerate()
            .fold((0, 0), |(n, h), (i, (s, c))| {
                let here = t.links_to(s, c) == Links::only(2);
                (if here { i } else { n }, h + usize::from(here))
            });
        assert_eq!((newest, held), (999, 255), "the 255 newest strangers");
        assert_eq!(t.links_to(2, 1), Links::NONE, "the oldest stranger went");
    }

    /// Trusted routes go least recently seen first among themselves; a
    /// table of trusted routes only learns no stranger.
    #[test]
    fn trusted_routes_evict_each_other_least_recent_first() {
        let mut t = FixedRoutingTable::<3>::new();
        t.learn(0, 1, 1, true);
        t.learn(1, 2, 1, true);
        t.learn(2, 9, 1, false);
        t.learn(0, 1, 1, true); // now the most recent
        t.learn(3, 3, 1, true); // the stranger goes first, trusted or not
        assert_eq!(t.links_to(9, 1), Links::NONE);
        t.learn(3, 4, 1, true); // full of trusted routes: 2/1 goes
        assert_eq!(t.links_to(2, 1), Links::NONE);
        assert_eq!(t.links_to(1, 1), Links::only(0));
        t.learn(2, 9, 1, false);
        assert_eq!(
            t.links_to(9, 1),
            Links::NONE,
            "a stranger evicted a trusted route"
        );
        for (sysid, link) in [(1, 0), (3, 3), (4, 3)] {
            assert_eq!(t.links_to(sysid, 1), Links::only(link), "{sysid}");
        }
    }

    /// A stranger's frame with a trusted route's ids does not count as
    /// that route being heard: it cannot keep an old trusted route alive
    /// against a newer one.
    #[test]
    fn a_forged_frame_does_not_refresh_a_trusted_route() {
        let mut t = FixedRoutingTable::<2>::new();
        t.learn(0, 1, 1, true);
        t.learn(1, 2, 1, true);
        t.learn(2, 1, 1, false); // forged: 1/1 stays the least recent
        t.learn(3, 3, 1, true);
        assert_eq!(t.links_to(1, 1), Links::NONE);
        assert_eq!(t.links_to(2, 1), Links::only(1));
    }
}
