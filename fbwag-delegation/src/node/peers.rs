//! Whom a listening link answers: the node's choice, never the link's,
//! under the bounded rule of `mavframe::peers` (a newcomer takes a free
//! slot, or the slot of a peer silent for its silence period).

use crate::Moment;
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
    fn from_addrs(addrs: impl Iterator<Item = SocketAddr>) -> Self {
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

/// Stations of a ground link whose frames verified, and others: half of
/// the slots each, so strangers (without the key) never hold the slots of
/// stations that sign, however many addresses they speak from.
pub(super) const STATION_SLOTS: usize = MAX_PEERS / 2;

/// Whom a link the node chooses for answers: one peer (the FC link, the
/// autonomy's link) or the stations of a ground link.
// Links are few and fixed (no_std, no allocation): the one-peer variant's
// unused room costs less than a box.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
pub(super) enum Answered {
    /// One peer: a verified frame's source replaces it at once.
    One(PeerSet<1>),
    /// Stations: those whose frames verified, and the others.
    Stations {
        verified: PeerSet<STATION_SLOTS>,
        others: PeerSet<STATION_SLOTS>,
    },
}

impl Answered {
    /// Stations of a ground link.
    pub(super) fn stations() -> Self {
        Answered::Stations {
            verified: PeerSet::new(),
            others: PeerSet::new(),
        }
    }

    /// `addr` sent a frame the node admitted at `now`; `verified`: its
    /// signature verified, so on a one-peer link it becomes the peer at
    /// once (a peer restarted on a new port), and on a ground link it
    /// competes only with other stations that sign.
    pub(super) fn heard(&mut self, addr: SocketAddr, now: Moment, verified: bool) -> Admission {
        let t = Duration::from_micros(now.0);
        let heard = match self {
            Answered::One(set) => set.heard(addr, t),
            Answered::Stations { verified: v, .. } if verified => v.heard(addr, t),
            // A station that signed once stays among those that sign.
            Answered::Stations { verified: v, .. } if v.contains(addr) => v.heard(addr, t),
            Answered::Stations { others, .. } => others.heard(addr, t),
        };
        match (heard, &mut *self) {
            (Heard::Known, _) => Admission::Known,
            (Heard::Added(_), _) => Admission::Added,
            (Heard::Refused, Answered::One(set)) if verified && addr.port() != 0 => {
                set.set(&[addr], t);
                Admission::Added
            }
            (Heard::Refused, _) => Admission::Refused,
        }
    }

    pub(super) fn contains(&self, addr: SocketAddr) -> bool {
        match self {
            Answered::One(set) => set.contains(addr),
            Answered::Stations { verified, others } => {
                verified.contains(addr) || others.contains(addr)
            }
        }
    }

    /// Whether it answers no one yet.
    pub(super) fn is_empty(&self) -> bool {
        match self {
            Answered::One(set) => set.is_empty(),
            Answered::Stations { verified, others } => verified.is_empty() && others.is_empty(),
        }
    }

    pub(super) fn peers(&self) -> Peers {
        match self {
            Answered::One(set) => Peers::from_addrs(set.iter()),
            Answered::Stations { verified, others } => {
                let others = others.iter().filter(|a| !verified.contains(*a));
                Peers::from_addrs(verified.iter().chain(others))
            }
        }
    }

    /// Forgets every peer (the link was opened again).
    pub(super) fn clear(&mut self) {
        *self = match self {
            Answered::One(_) => Answered::One(PeerSet::new()),
            Answered::Stations { .. } => Answered::stations(),
        };
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
        assert_eq!(one.heard(addr(1), Moment::ZERO, false), Admission::Added);
        let soon = Moment::from_millis(100);
        assert_eq!(one.heard(addr(2), soon, false), Admission::Refused);
        assert_eq!(one.heard(addr(0), soon, true), Admission::Refused);
        assert_eq!(one.heard(addr(2), soon, true), Admission::Added);
        assert!(one.contains(addr(2)) && !one.contains(addr(1)));
        // Strangers fill the slots of stations that do not sign; one that
        // signs is answered all the same, and keeps its slot.
        let mut stations = Answered::stations();
        for port in 1..=MAX_PEERS as u16 {
            let want = if usize::from(port) <= STATION_SLOTS {
                Admission::Added
            } else {
                Admission::Refused
            };
            assert_eq!(stations.heard(addr(port), soon, false), want);
        }
        assert_eq!(stations.heard(addr(99), soon, true), Admission::Added);
        assert_eq!(stations.heard(addr(99), soon, false), Admission::Known);
        assert_eq!(stations.peers().iter().count(), STATION_SLOTS + 1);
    }
}
