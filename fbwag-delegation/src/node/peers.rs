//! Whom a listening link answers: the node's choice, never the link's,
//! under the bounded rule of `mavframe::peers` (a newcomer takes a free
//! slot, or the slot of a peer silent for its silence period).

use crate::Instant;
use core::net::SocketAddr;
use core::time::Duration;
use fbwag_dialect::mavframe::peers::{Heard, PeerSet};

pub use fbwag_dialect::mavframe::peers::{MAX_PEERS, SILENCE as PEER_SILENCE};

/// The addresses a link answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Peers {
    addrs: [Option<SocketAddr>; MAX_PEERS],
}

impl Peers {
    fn from_iter(addrs: impl Iterator<Item = SocketAddr>) -> Self {
        let mut peers = Peers::default();
        for (slot, addr) in peers.addrs.iter_mut().zip(addrs) {
            *slot = Some(addr);
        }
        peers
    }

    /// The addresses.
    pub fn iter(&self) -> impl Iterator<Item = SocketAddr> + '_ {
        self.addrs.iter().flatten().copied()
    }

    /// Whether `addr` is among them.
    pub fn contains(&self, addr: SocketAddr) -> bool {
        self.iter().any(|a| a == addr)
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.addrs.iter().all(Option::is_none)
    }
}

/// What [`Answered::heard`] made of a source.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Admission {
    /// Already answered.
    Known,
    /// Answered from now on: the set changed.
    Added,
    /// Not answered: every slot is held by a peer that spoke within
    /// [`PEER_SILENCE`] (or port 0, which nothing can be sent to).
    Refused,
}

/// Whom a link the node chooses for answers: one peer (the FC link, the
/// autonomy's link) or the stations of a ground link.
// Links are few and fixed (no_std, no allocation): the one-peer variant's
// unused room costs less than a box.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub(super) enum Answered {
    /// One peer: a verified frame's source replaces it at once.
    One(PeerSet<1>),
    /// Up to [`MAX_PEERS`] stations.
    Stations(PeerSet<MAX_PEERS>),
}

impl Answered {
    /// `addr` sent a frame the node admitted at `now`; `displaces`: its
    /// signature verified, so on a one-peer link it becomes the peer at
    /// once (a peer restarted on a new port).
    pub(super) fn heard(&mut self, addr: SocketAddr, now: Instant, displaces: bool) -> Admission {
        let t = Duration::from_micros(now.0);
        let heard = match self {
            Answered::One(set) => set.heard(addr, t),
            Answered::Stations(set) => set.heard(addr, t),
        };
        match (heard, &mut *self) {
            (Heard::Known, _) => Admission::Known,
            (Heard::Added(_), _) => Admission::Added,
            (Heard::Refused, Answered::One(set)) if displaces && addr.port() != 0 => {
                set.set(&[addr], t);
                Admission::Added
            }
            (Heard::Refused, _) => Admission::Refused,
        }
    }

    pub(super) fn contains(&self, addr: SocketAddr) -> bool {
        match self {
            Answered::One(set) => set.contains(addr),
            Answered::Stations(set) => set.contains(addr),
        }
    }

    pub(super) fn peers(&self) -> Peers {
        match self {
            Answered::One(set) => Peers::from_iter(set.iter()),
            Answered::Stations(set) => Peers::from_iter(set.iter()),
        }
    }

    /// Forgets every peer (the link was opened again).
    pub(super) fn clear(&mut self) {
        match self {
            Answered::One(set) => *set = PeerSet::new(),
            Answered::Stations(set) => *set = PeerSet::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn addr(port: u16) -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], port))
    }

    #[test]
    fn a_verified_frame_moves_a_single_peer_at_once_and_nothing_else_does() {
        let mut one = Answered::One(PeerSet::new());
        assert_eq!(one.heard(addr(1), Instant::ZERO, false), Admission::Added);
        let soon = Instant::from_millis(100);
        assert_eq!(one.heard(addr(2), soon, false), Admission::Refused);
        assert_eq!(one.heard(addr(0), soon, true), Admission::Refused);
        assert_eq!(one.heard(addr(2), soon, true), Admission::Added);
        assert!(one.contains(addr(2)) && !one.contains(addr(1)));
        let mut stations = Answered::Stations(PeerSet::new());
        for port in 1..=MAX_PEERS as u16 {
            assert_eq!(stations.heard(addr(port), soon, false), Admission::Added);
        }
        assert_eq!(stations.heard(addr(99), soon, true), Admission::Refused);
        assert_eq!(stations.peers().iter().count(), MAX_PEERS);
    }
}
