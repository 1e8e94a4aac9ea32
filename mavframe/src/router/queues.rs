//! What waits to leave on a link (or a `tcpin` client), and the order it
//! leaves in: the owner's frames first, routed ones after them, paced.

use super::pace::Backlog;
use super::LINK_QUEUE;
use crate::route::LinkId;
use core::num::NonZeroU32;
use std::boxed::Box;
use std::collections::VecDeque;
use std::net::SocketAddr;
use std::time::Duration;
use tokio::time::Instant;

/// Bytes to send in one go: one or more whole frames.
#[derive(Debug, Clone)]
pub(super) struct Packet {
    pub(super) bytes: Box<[u8]>,
    /// The frames it holds.
    pub(super) frames: u64,
    /// On a listening link, to this address only (the owner's answer to
    /// one sender), whatever the link's peers.
    pub(super) to: Option<SocketAddr>,
}

impl Packet {
    /// One frame, or several routed together.
    pub(super) fn new(bytes: &[u8], frames: u64) -> Packet {
        Packet {
            bytes: bytes.into(),
            frames,
            to: None,
        }
    }
}

impl AsRef<[u8]> for Packet {
    fn as_ref(&self) -> &[u8] {
        &self.bytes
    }
}

/// Which queue a packet came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Class {
    /// The owner's.
    Own,
    /// Routed through the link.
    Routed,
}

/// What to send next.
pub(super) enum Next {
    Send(Class, Packet),
    /// Nothing until the pace lets the next routed frame go, this long.
    Wait(Duration),
    /// Nothing queued.
    Idle,
}

/// The key of a routed frame's sender: the link it came in on and the
/// address it came from (a paced link queues senders apart: [`Backlog`]).
/// 0 is the owner's (frames it routes itself).
pub(super) fn sender_key(link: LinkId, source: Option<SocketAddr>) -> u32 {
    use core::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (link, source).hash(&mut h);
    (h.finish() as u32).max(1)
}

/// A link's queues: the owner's packets, and the frames routed through
/// the link, which go only when none of the owner's wait, and no faster
/// than the link's [`LinkConfig::routed_rate`](super::LinkConfig::routed_rate)
/// (the [`pace`](super::pace) module). Routed traffic (a ground station's
/// flood of another link) never holds the owner's protocol frames back
/// behind it: on a link slower than that flood, one queue let it crowd
/// them out, and the companion's acknowledgement never reached the FC.
#[derive(Debug)]
pub(super) struct Queues {
    own: VecDeque<Packet>,
    routed: VecDeque<Packet>,
    /// With a routed rate: the routed frames the pace holds back.
    backlog: Option<Backlog<Packet>>,
    /// At most this many packets in each of `own` and `routed`.
    cap: usize,
}

impl Queues {
    /// Queues holding `cap` packets each, routed frames paced at `rate`.
    pub(super) fn new(rate: Option<NonZeroU32>, cap: usize) -> Queues {
        Queues {
            own: VecDeque::new(),
            routed: VecDeque::new(),
            backlog: rate.map(|r| Backlog::new(r, Instant::now())),
            cap,
        }
    }

    /// A link's: [`LINK_QUEUE`] packets each.
    pub(super) fn link(rate: Option<NonZeroU32>) -> Queues {
        Queues::new(rate, LINK_QUEUE)
    }

    /// Whether routed frames are paced.
    pub(super) fn is_paced(&self) -> bool {
        self.backlog.is_some()
    }

    /// Nothing of the owner's waits.
    pub(super) fn own_is_empty(&self) -> bool {
        self.own.is_empty()
    }

    /// Nothing waits at all.
    pub(super) fn is_empty(&self) -> bool {
        self.own.is_empty()
            && self.routed.is_empty()
            && self.backlog.as_ref().is_none_or(Backlog::is_empty)
    }

    /// Queues the owner's `packet`; false when the queue was full (it is
    /// dropped).
    pub(super) fn push_own(&mut self, packet: Packet) -> bool {
        if self.own.len() >= self.cap {
            return false;
        }
        self.own.push_back(packet);
        true
    }

    /// Queues a routed `packet` from sender `from` (paced, when the link
    /// is); the frames dropped to make room, or for want of it.
    pub(super) fn push_routed(&mut self, from: u32, packet: Packet) -> u64 {
        if let Some(backlog) = &mut self.backlog {
            return backlog.push(from, packet);
        }
        if self.routed.len() >= self.cap {
            return packet.frames;
        }
        self.routed.push_back(packet);
        0
    }

    /// The next packet to send at `now`: the owner's first, then a routed
    /// one (when the pace lets it go). `unpaced`: the router is gone, what
    /// was routed goes as it is.
    pub(super) fn next(&mut self, now: Instant, unpaced: bool) -> Next {
        if let Some(p) = self.own.pop_front() {
            return Next::Send(Class::Own, p);
        }
        if let Some(p) = self.routed.pop_front() {
            return Next::Send(Class::Routed, p);
        }
        let Some(backlog) = &mut self.backlog else {
            return Next::Idle;
        };
        let released = match unpaced {
            true => Ok(backlog.pop()),
            false => backlog.release(now),
        };
        match released {
            Ok(Some(p)) => Next::Send(Class::Routed, p),
            Ok(None) => Next::Idle,
            Err(wait) => Next::Wait(wait),
        }
    }

    /// `packet`, taken by [`next`](Self::next) and not sent (the socket's
    /// buffer was full): the next to go.
    pub(super) fn put_back(&mut self, class: Class, packet: Packet) {
        match class {
            Class::Own => self.own.push_front(packet),
            Class::Routed => self.routed.push_front(packet),
        }
    }

    /// Drops everything (the link is down): the routed frames dropped.
    pub(super) fn clear(&mut self) -> u64 {
        self.own.clear();
        let mut dropped: u64 = self.routed.drain(..).map(|p| p.frames).sum();
        if let Some(backlog) = &mut self.backlog {
            dropped += backlog.clear();
        }
        dropped
    }
}
