//! Whom a link that several remote ends share sends to, sans-IO: a bounded
//! set of peer addresses, each with when it was last heard (no clock, no
//! allocation: the caller passes the time).
//!
//! A `udpin` port serves every ground station that spoke recently, up to
//! [`MAX_PEERS`] of them. The rule is meant to hold against strangers on
//! the network:
//!
//! - only the caller decides what makes an address heard (the links of
//!   `conn` and `router` call [`PeerSet::heard`] for the source of a frame
//!   the parser accepted, authenticated on a link with a key, never for a
//!   datagram merely received);
//! - a new address takes a slot only if one is free, or if the least
//!   recently heard holder has been silent for [`SILENCE`]: a station that
//!   keeps speaking is never displaced, however many strangers arrive;
//! - port 0 is never a peer (no datagram can go there).
//!
//! [`PeerSet::set`] replaces the set with addresses an owner chose (the
//! `ReplyTo::Owner` rule of `conn` and `router`).
//!
//! ```
//! use core::time::Duration;
//! use mavframe::peers::{Heard, PeerSet, SILENCE};
//!
//! let mut peers = PeerSet::<1>::new();
//! let (station, stranger) = ("10.0.0.2:14550".parse()?, "10.0.0.9:4000".parse()?);
//! let t = Duration::from_secs(100);
//! assert_eq!(peers.heard(station, t), Heard::Added(None));
//! assert_eq!(peers.heard(stranger, t + SILENCE / 2), Heard::Refused);
//! assert_eq!(peers.heard(stranger, t + SILENCE), Heard::Added(Some(station)));
//! assert_eq!(peers.iter().collect::<Vec<_>>(), [stranger]);
//! # Ok::<(), core::net::AddrParseError>(())
//! ```

use core::net::SocketAddr;
use core::time::Duration;

/// Peers a link serves at once.
pub const MAX_PEERS: usize = 8;

/// How long a peer must have been silent before a new address may take its
/// slot: three MAVLink heartbeat periods, so a station that is alive keeps
/// its slot through a lost heartbeat or two.
pub const SILENCE: Duration = Duration::from_secs(3);

/// What [`PeerSet::heard`] did with an address.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Heard {
    /// Already a peer: last heard now.
    Known,
    /// A new peer, in a free slot (`None`) or in the slot of this peer,
    /// silent for [`SILENCE`] at least.
    Added(Option<SocketAddr>),
    /// Not a peer: every slot's holder spoke within [`SILENCE`], or the
    /// address has port 0.
    Refused,
}

impl Heard {
    /// Whether the set's addresses changed.
    pub const fn changed(self) -> bool {
        matches!(self, Heard::Added(_))
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Peer {
    addr: SocketAddr,
    /// When it was last heard (the caller's clock).
    heard: Duration,
}

/// Up to `N` peer addresses ([`MAX_PEERS`] by default) and when each was
/// last heard; see the [module docs](self) for the rule.
///
/// Times are any monotonic clock's readings since a fixed origin of the
/// caller's choice; a time before a peer's last (another origin) counts as
/// no silence at all.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PeerSet<const N: usize = MAX_PEERS> {
    slots: [Option<Peer>; N],
}

impl<const N: usize> Default for PeerSet<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> PeerSet<N> {
    /// An empty set.
    pub const fn new() -> Self {
        PeerSet { slots: [None; N] }
    }

    /// `addr` was heard at `now` (its frame was accepted): it becomes or
    /// stays a peer if the rule lets it (see [`Heard`]).
    pub fn heard(&mut self, addr: SocketAddr, now: Duration) -> Heard {
        if addr.port() == 0 {
            return Heard::Refused;
        }
        if let Some(p) = self.slots.iter_mut().flatten().find(|p| p.addr == addr) {
            p.heard = p.heard.max(now);
            return Heard::Known;
        }
        let new = Some(Peer { addr, heard: now });
        if let Some(free) = self.slots.iter_mut().find(|s| s.is_none()) {
            *free = new;
            return Heard::Added(None);
        }
        // Full: only the least recently heard may go, and only if silent.
        let oldest = self
            .slots
            .iter_mut()
            .min_by_key(|s| s.map(|p| p.heard))
            .filter(|s| s.is_some_and(|p| now.saturating_sub(p.heard) >= SILENCE));
        match oldest {
            Some(slot) => {
                let gone = slot.map(|p| p.addr);
                *slot = new;
                Heard::Added(gone)
            }
            None => Heard::Refused,
        }
    }

    /// Replaces the peers with `addrs` (an owner's choice), heard at `now`:
    /// the first `N` distinct addresses whose port is not 0.
    pub fn set(&mut self, addrs: &[SocketAddr], now: Duration) {
        self.slots = [None; N];
        let mut filled = 0;
        for &addr in addrs {
            if filled == N {
                break;
            }
            if addr.port() != 0 && !self.contains(addr) {
                self.slots[filled] = Some(Peer { addr, heard: now });
                filled += 1;
            }
        }
    }

    /// Whether `addr` is a peer.
    pub fn contains(&self, addr: SocketAddr) -> bool {
        self.iter().any(|a| a == addr)
    }

    /// The peers, in no particular order.
    pub fn iter(&self) -> impl Iterator<Item = SocketAddr> + '_ {
        self.slots.iter().flatten().map(|p| p.addr)
    }

    /// The peer heard most recently.
    pub fn latest(&self) -> Option<SocketAddr> {
        self.slots
            .iter()
            .flatten()
            .max_by_key(|p| p.heard)
            .map(|p| p.addr)
    }

    /// When `addr` was last heard, if it is a peer.
    pub fn last_heard(&self, addr: SocketAddr) -> Option<Duration> {
        self.slots
            .iter()
            .flatten()
            .find(|p| p.addr == addr)
            .map(|p| p.heard)
    }

    /// The number of peers.
    pub fn len(&self) -> usize {
        self.iter().count()
    }

    /// True when there is no peer.
    pub fn is_empty(&self) -> bool {
        self.slots.iter().all(Option::is_none)
    }

    /// Forgets every peer.
    pub fn clear(&mut self) {
        self.slots = [None; N];
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use core::net::{IpAddr, Ipv4Addr};

    fn addr(host: u8, port: u16) -> SocketAddr {
        SocketAddr::new(IpAddr::V4(Ipv4Addr::new(10, 0, 0, host)), port)
    }

    fn secs(s: f64) -> Duration {
        Duration::from_secs_f64(s)
    }

    /// A station that keeps speaking keeps its slot while 200 strangers
    /// arrive, one every 50 ms: the free slots go to the first strangers,
    /// and a stranger takes another's slot only once that one has been
    /// silent for [`SILENCE`].
    #[test]
    fn a_speaking_peer_is_never_displaced() {
        let mut peers = PeerSet::<MAX_PEERS>::new();
        let station = addr(1, 14550);
        assert_eq!(peers.heard(station, secs(0.0)), Heard::Added(None));
        let mut t = 0.0;
        let mut heard = std::collections::BTreeMap::new();
        for i in 0..200u16 {
            t += 0.05;
            if i % 10 == 0 {
                assert_eq!(peers.heard(station, secs(t)), Heard::Known);
            }
            let stranger = addr(2, 1000 + i);
            match peers.heard(stranger, secs(t)) {
                Heard::Added(None) => assert!(i < 7, "a free slot for stranger {i}"),
                Heard::Added(Some(gone)) => {
                    let last: f64 = heard[&gone];
                    assert!(secs(t) - secs(last) >= SILENCE, "{gone} displaced by {i}");
                }
                Heard::Refused => assert!(i >= 7),
                Heard::Known => panic!("stranger {i} known"),
            }
            heard.insert(stranger, t);
            assert!(peers.contains(station), "displaced by stranger {i}");
        }
        assert_eq!(peers.len(), MAX_PEERS);
    }

    /// Full: a newcomer takes the slot of the least recently heard peer
    /// once it has been silent for [`SILENCE`], not a moment before, and
    /// never a more recently heard peer's.
    #[test]
    fn a_silent_peer_makes_room_after_the_silence_period() {
        let mut peers = PeerSet::<2>::new();
        let (a, b, c) = (addr(1, 1), addr(2, 2), addr(3, 3));
        peers.heard(a, secs(10.0));
        peers.heard(b, secs(11.0));
        let almost = secs(10.0) + SILENCE - Duration::from_millis(1);
        assert_eq!(peers.heard(c, almost), Heard::Refused);
        assert_eq!(peers.heard(c, secs(10.0) + SILENCE), Heard::Added(Some(a)));
        assert!(peers.contains(b) && peers.contains(c) && !peers.contains(a));
        assert_eq!(peers.latest(), Some(c));
        // A refused address's attempts do not count as heard.
        assert_eq!(peers.heard(a, secs(13.5)), Heard::Refused);
        assert_eq!(peers.heard(a, secs(14.0)), Heard::Added(Some(b)));
    }

    #[test]
    fn port_zero_is_never_a_peer() {
        let mut peers = PeerSet::<2>::new();
        assert_eq!(peers.heard(addr(1, 0), secs(0.0)), Heard::Refused);
        peers.set(&[addr(1, 0), addr(2, 5)], secs(0.0));
        assert_eq!(peers.iter().collect::<std::vec::Vec<_>>(), [addr(2, 5)]);
    }

    /// `set` keeps the first `N` distinct addresses; a clock from another
    /// origin (time going back) reads as no silence.
    #[test]
    fn an_owners_set_is_bounded_and_distinct() {
        let mut peers = PeerSet::<2>::new();
        peers.heard(addr(9, 9), secs(0.0));
        peers.set(&[addr(1, 1), addr(1, 1), addr(2, 2), addr(3, 3)], secs(5.0));
        let got: std::vec::Vec<_> = peers.iter().collect();
        assert_eq!(got, [addr(1, 1), addr(2, 2)]);
        assert_eq!(peers.heard(addr(4, 4), secs(1.0)), Heard::Refused);
        assert_eq!(peers.last_heard(addr(1, 1)), Some(secs(5.0)));
        peers.clear();
        assert!(peers.is_empty());
    }
}
