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
//! - A full table forgets the least recently seen untrusted route; a
//!   trusted route is forgotten only for another trusted one (the least
//!   recently seen trusted route then goes), never for a stranger's: a
//!   flood of made-up ids cannot push the autopilot out of the table.
//! - An untrusted frame with a trusted route's ids changes nothing: the
//!   forger's link gets no copy of that system's traffic. An untrusted
//!   route becomes trusted with its first trusted frame, and from then on
//!   goes only where trusted frames came from.
//!
//! ```
//! use mavframe::route::{Links, RoutingTable};
//! use mavframe::{Frame, MessageMeta};
//! # let meta = MessageMeta { id: 76, name: "COMMAND_LONG", crc_extra: 152, min_len: 33,
//! #   max_len: 33, target_system_offset: Some(30), target_component_offset: Some(31), fields: &[] };
//! # fn frame(sysid: u8, compid: u8, payload: &[u8]) -> Vec<u8> {
//! #   let mut b = vec![0xfd, payload.len() as u8, 0, 0, 0, sysid, compid, 76, 0, 0];
//! #   b.extend_from_slice(payload); b.extend_from_slice(&[0, 0]); b }
//! let mut table = RoutingTable::<16>::new();
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

/// A link's number in a router: 0..64.
pub type LinkId = u8;

/// A set of links (at most 64), as a bit mask.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Links(pub u64);

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

    /// The links, in order.
    pub fn iter(self) -> impl Iterator<Item = LinkId> {
        (0..64u8).filter(move |&l| self.contains(l))
    }
}

#[derive(Debug, Clone, Copy, Default)]
struct Route {
    sysid: u8,
    compid: u8,
    links: Links,
    /// Learned from a trusted frame (see the module docs).
    trusted: bool,
    /// Learning order, for eviction: the least recently seen route goes.
    seen: u64,
}

/// Where each (system, component) was seen: up to `N` senders (a full
/// table forgets the untrusted sender heard least recently; see the module
/// docs).
#[derive(Debug, Clone)]
pub struct RoutingTable<const N: usize = 64> {
    routes: [Route; N],
    len: usize,
    clock: u64,
}

impl<const N: usize> Default for RoutingTable<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> RoutingTable<N> {
    /// An empty table.
    pub const fn new() -> Self {
        RoutingTable {
            routes: [Route {
                sysid: 0,
                compid: 0,
                links: Links::NONE,
                trusted: false,
                seen: 0,
            }; N],
            len: 0,
            clock: 0,
        }
    }

    /// Records that `sysid`/`compid` sent a frame through `link`;
    /// `trusted`: the frame was authenticated, or its link is trusted (see
    /// the module docs for what an untrusted frame may change). System 0
    /// is nobody (the broadcast address) and is not learned.
    pub fn learn(&mut self, link: LinkId, sysid: u8, compid: u8, trusted: bool) {
        if sysid == 0 || N == 0 {
            return;
        }
        self.clock += 1;
        let clock = self.clock;
        let routes = &mut self.routes[..self.len];
        if let Some(r) = routes
            .iter_mut()
            .find(|r| (r.sysid, r.compid) == (sysid, compid))
        {
            match (r.trusted, trusted) {
                // A stranger's frame with a trusted sender's ids.
                (true, false) => {}
                // Trusted from now on: only where trusted frames came from.
                (false, true) => (r.links, r.trusted, r.seen) = (Links::only(link), true, clock),
                _ => (r.links, r.seen) = (r.links.union(Links::only(link)), clock),
            }
            return;
        }
        let Some(slot) = self.free_slot(trusted) else {
            return;
        };
        self.routes[slot] = Route {
            sysid,
            compid,
            links: Links::only(link),
            trusted,
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
                .filter(|&i| self.routes[i].trusted == want_trusted)
                .min_by_key(|&i| self.routes[i].seen)
        };
        least_recent(false).or_else(|| least_recent(true).filter(|_| trusted))
    }

    /// The links where `sysid` (and `compid`, unless 0) was seen.
    pub fn links_to(&self, sysid: u8, compid: u8) -> Links {
        self.routes[..self.len]
            .iter()
            .filter(|r| r.sysid == sysid && (compid == 0 || r.compid == compid || r.compid == 0))
            .fold(Links::NONE, |acc, r| acc.union(r.links))
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
        let others = links.without(from);
        match target(frame, meta) {
            Some((sysid, compid)) => self.links_to(sysid, compid).intersection(others),
            None => others,
        }
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

    const TARGETED: MessageMeta = MessageMeta {
        id: 76,
        name: "COMMAND_LONG",
        crc_extra: 152,
        min_len: 33,
        max_len: 33,
        target_system_offset: Some(30),
        target_component_offset: Some(31),
        fields: &[],
    };
    const UNTARGETED: MessageMeta = MessageMeta {
        id: 0,
        name: "HEARTBEAT",
        crc_extra: 50,
        min_len: 9,
        max_len: 9,
        target_system_offset: None,
        target_component_offset: None,
        fields: &[],
    };

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

    fn route(t: &mut RoutingTable<8>, from: LinkId, b: &[u8], meta: Option<&MessageMeta>) -> Links {
        let f = Frame::new_checked(b).unwrap();
        t.route(from, &f, meta, Links::all(4), false)
    }

    #[test]
    fn broadcasts_go_everywhere_but_back() {
        let mut t = RoutingTable::<8>::new();
        let hb = bytes(1, 1, None);
        assert_eq!(route(&mut t, 1, &hb, Some(&UNTARGETED)), Links(0b1101));
        // Target system 0 is a broadcast too; unknown ids likewise.
        let zero = bytes(255, 190, Some((0, 0)));
        assert_eq!(route(&mut t, 2, &zero, Some(&TARGETED)), Links(0b1011));
        assert_eq!(route(&mut t, 3, &zero, None), Links(0b0111));
    }

    #[test]
    fn addressed_frames_go_only_where_the_addressee_was_seen() {
        let mut t = RoutingTable::<8>::new();
        let to_fc = bytes(255, 190, Some((1, 1)));
        assert_eq!(
            route(&mut t, 2, &to_fc, Some(&TARGETED)),
            Links::NONE,
            "an unknown addressee goes nowhere"
        );
        t.learn(0, 1, 1, true); // the autopilot on link 0
        t.learn(3, 1, 191, true); // its companion on link 3
        assert_eq!(route(&mut t, 2, &to_fc, Some(&TARGETED)), Links::only(0));
        let to_system = bytes(255, 190, Some((1, 0)));
        assert_eq!(
            route(&mut t, 2, &to_system, Some(&TARGETED)),
            Links(0b1001),
            "component 0: every component of the system"
        );
        // The addressee's own link is never the one it came from.
        let from_fc_link = bytes(1, 191, Some((1, 1)));
        assert_eq!(
            route(&mut t, 0, &from_fc_link, Some(&TARGETED)),
            Links::NONE
        );
    }

    #[test]
    fn a_forged_sender_cannot_divert_traffic() {
        let mut t = RoutingTable::<8>::new();
        t.learn(0, 1, 1, false);
        // An attacker on link 2 sends frames with the autopilot's ids.
        t.learn(2, 1, 1, false);
        let to_fc = bytes(255, 190, Some((1, 1)));
        let to = route(&mut t, 3, &to_fc, Some(&TARGETED));
        assert!(to.contains(0), "still reaches the real autopilot");
    }

    /// An untrusted frame with a trusted route's ids gets its link no
    /// copy; an untrusted route that turns trusted keeps only the trusted
    /// link, then adds the links trusted frames come from.
    #[test]
    fn a_stranger_gets_no_copy_of_a_trusted_senders_traffic() {
        let mut t = RoutingTable::<8>::new();
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

    #[test]
    fn a_full_table_forgets_the_least_recent_sender() {
        let mut t = RoutingTable::<2>::new();
        t.learn(0, 1, 1, false);
        t.learn(1, 2, 1, false);
        t.learn(0, 1, 1, false); // heard again: now the most recent
        t.learn(2, 3, 1, false); // evicts 2/1
        assert_eq!(t.links_to(1, 1), Links::only(0));
        assert_eq!(t.links_to(2, 1), Links::NONE);
        assert_eq!(t.links_to(3, 1), Links::only(2));
        t.learn(0, 0, 0, true);
        assert_eq!(t.links_to(0, 0), Links::NONE, "system 0 is nobody");
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

    /// HEARTBEATs of 200 strangers' ids never evict the autopilot's
    /// trusted route from a 64-route table (the least recently seen route
    /// went, whoever it was); strangers evict each other.
    #[test]
    fn strangers_never_evict_a_trusted_route() {
        let mut t = RoutingTable::<64>::new();
        t.learn(0, 1, 1, true);
        for id in 0..200u8 {
            t.learn(2, 2 + id, 1, false);
        }
        assert_eq!(t.links_to(1, 1), Links::only(0));
        assert_eq!(t.links_to(201, 1), Links::only(2), "the newest stranger");
        assert_eq!(t.links_to(2, 1), Links::NONE, "the oldest stranger went");
    }

    /// Trusted routes go least recently seen first among themselves; a
    /// table of trusted routes only learns no stranger.
    #[test]
    fn trusted_routes_evict_each_other_least_recent_first() {
        let mut t = RoutingTable::<3>::new();
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
}
