//! What the router queues for a link task, and how the task takes it:
//! the owner's commands first, routed frames paced.

use super::pace::Backlog;
use super::LinkCounters;
use crate::message::MessageMeta;
use crate::route::LinkId;
use core::num::NonZeroU32;
use std::boxed::Box;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tokio::sync::mpsc;

/// What the router tells a link task.
pub(super) enum Command {
    /// Send these frame bytes as they are.
    Raw(Box<[u8]>),
    /// Frame this message (the link's sequence numbers and signer) and send
    /// (`to`: on a `udpin` or `tcpin` link, to that address only, whatever
    /// the link's peers).
    Message {
        sysid: u8,
        compid: u8,
        meta: &'static MessageMeta,
        payload: Box<[u8]>,
        to: Option<SocketAddr>,
    },
    /// [`ReplyTo::Owner`](crate::conn::ReplyTo::Owner): send to these addresses ([`Router::set_peers`](super::Router::set_peers)).
    Peers(Box<[SocketAddr]>),
    /// Send this frame, routed from another link ([`Queues`](super::queues::Queues)), from the
    /// sender of this key ([`sender_key`]).
    Routed(u32, RoutedBytes),
    /// Sign and verify with this key from now on (`None`: none), in its
    /// replay window ([`Router::set_key`](super::Router::set_key)).
    Key(Option<[u8; 32]>, Option<super::ReplayWindow>),
}

/// A routed frame's bytes, and the message's row when the link signs it on
/// the way ([`Router::route_signed`](super::Router::route_signed)).
#[derive(Debug, Clone)]
pub(super) struct RoutedBytes {
    pub(super) bytes: Box<[u8]>,
    pub(super) sign: Option<&'static MessageMeta>,
}

impl AsRef<[u8]> for RoutedBytes {
    fn as_ref(&self) -> &[u8] {
        &self.bytes
    }
}

/// A routed frame in a link's queue: the key of its sender
/// ([`sender_key`]) and its bytes.
pub(super) type RoutedFrame = (u32, RoutedBytes);

/// The key of a routed frame's sender: the link it came in on and the
/// address it came from (a paced link queues senders apart: [`Backlog`]).
/// 0 is the owner's (frames it routes itself, [`Router::send_routed`](super::Router::send_routed)).
pub(super) fn sender_key(link: LinkId, source: Option<SocketAddr>) -> u32 {
    use core::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (link, source).hash(&mut h);
    (h.finish() as u32).max(1)
}

/// A link's queues, as its task reads them: the owner's frames and
/// commands, and the frames routed through the link, which go only when
/// none of the owner's wait, and no faster than the link's
/// [`LinkConfig::routed_rate`](super::LinkConfig::routed_rate) (the [`pace`](super::pace) module). Routed traffic (a
/// ground station's flood of another link) never holds the owner's
/// protocol frames back behind it: on a link slower than that flood, one
/// queue let it crowd them out, and the companion's acknowledgement never
/// reached the FC.
pub(super) struct Queues {
    own: mpsc::Receiver<Command>,
    routed: mpsc::Receiver<RoutedFrame>,
    /// The owner's queue is closed (the router is gone): what was routed
    /// goes out as it is, unpaced, then the link ends.
    own_closed: bool,
    /// The routed queue's sender is gone (the router with it).
    routed_closed: bool,
    /// With [`LinkConfig::routed_rate`](super::LinkConfig::routed_rate): the routed frames the pace holds
    /// back.
    pub(super) backlog: Option<Backlog<RoutedBytes>>,
    /// The link's counters: frames the backlog drops.
    counters: Arc<Mutex<LinkCounters>>,
    /// A routed frame taken to share a datagram that had no room left for
    /// it ([`Queues::queued_routed`]): the next to go.
    held: Option<RoutedFrame>,
}

impl Queues {
    pub(super) fn new(
        own: mpsc::Receiver<Command>,
        routed: mpsc::Receiver<RoutedFrame>,
        rate: Option<NonZeroU32>,
        counters: Arc<Mutex<LinkCounters>>,
    ) -> Queues {
        Queues {
            own,
            routed,
            own_closed: false,
            routed_closed: false,
            backlog: rate.map(|r| Backlog::new(r, tokio::time::Instant::now())),
            counters,
            held: None,
        }
    }

    /// The next command, the owner's first; `None` once the router is
    /// gone (after what was queued). Cancel-safe: what it takes from the
    /// queues before it returns stays in the backlog.
    pub(super) async fn recv(&mut self) -> Option<Command> {
        if let Some((from, bytes)) = self.held.take() {
            return Some(Command::Routed(from, bytes));
        }
        loop {
            let wait = match self.paced() {
                Paced::Go(c) => return c,
                Paced::Wait(wait) => wait,
            };
            tokio::select! {
                biased;
                c = self.own.recv(), if !self.own_closed => match c {
                    Some(c) => return Some(c),
                    None => self.own_closed = true,
                },
                r = self.routed.recv(), if !self.routed_closed && !self.own_closed => match (r, &mut self.backlog) {
                    (Some((from, bytes)), None) => return Some(Command::Routed(from, bytes)),
                    (Some((from, bytes)), Some(backlog)) => {
                        let dropped = backlog.push(from, bytes);
                        count_routed_dropped(&self.counters, dropped);
                    }
                    (None, _) => self.routed_closed = true,
                },
                () = sleep_for(wait), if wait.is_some() => {}
            }
        }
    }

    /// What [`recv`](Self::recv) does before it waits: once the router is
    /// gone, the frames routed so far, unpaced; else a frame of the owner's
    /// already queued, then the oldest routed frame held back when the pace
    /// lets it go; else how long the pace holds it (`None`: nothing held).
    fn paced(&mut self) -> Paced {
        if self.own_closed {
            let held = self.backlog.as_mut().and_then(Backlog::pop).map(|b| (0, b));
            let next = held.or_else(|| self.routed.try_recv().ok());
            return Paced::Go(next.map(|(from, b)| Command::Routed(from, b)));
        }
        if self.backlog.as_ref().is_none_or(Backlog::is_empty) {
            return Paced::Wait(None);
        }
        match self.own.try_recv() {
            Ok(c) => return Paced::Go(Some(c)),
            Err(mpsc::error::TryRecvError::Disconnected) => {
                self.own_closed = true;
                return self.paced();
            }
            Err(mpsc::error::TryRecvError::Empty) => {}
        }
        match self
            .backlog
            .as_mut()
            .map(|b| b.release(tokio::time::Instant::now()))
        {
            Some(Ok(Some(bytes))) => Paced::Go(Some(Command::Routed(0, bytes))),
            Some(Err(wait)) => Paced::Wait(Some(wait)),
            _ => Paced::Wait(None),
        }
    }

    /// Waits for the next command or routed frame and drops it, with the
    /// backlog (a link that is down): `false` once the router is gone.
    pub(super) async fn drop_next(&mut self) -> bool {
        if self.held.take().is_some() {
            count_routed_dropped(&self.counters, 1);
            return true;
        }
        if let Some(backlog) = &mut self.backlog {
            let dropped = backlog.clear();
            count_routed_dropped(&self.counters, dropped);
        }
        if self.own_closed {
            return false;
        }
        tokio::select! {
            biased;
            c = self.own.recv() => {
                self.own_closed = c.is_none();
                c.is_some()
            }
            r = self.routed.recv(), if !self.routed_closed => {
                self.routed_closed = r.is_none();
                true
            }
        }
    }

    /// A routed frame already queued, to share the datagram of the frame
    /// just taken: only when nothing paces the link and none of the
    /// owner's frames waits (they go first).
    pub(super) fn queued_routed(&mut self) -> Option<RoutedFrame> {
        if self.backlog.is_some() || self.own_closed || !self.own.is_empty() {
            return None;
        }
        self.routed.try_recv().ok()
    }

    /// A frame [`queued_routed`](Self::queued_routed) gave that did not
    /// fit: the next [`recv`](Self::recv) returns it.
    pub(super) fn hold(&mut self, frame: RoutedFrame) {
        self.held = Some(frame);
    }
}

/// Adds `n` routed frames dropped to a link's counters.
pub(super) fn count_routed_dropped(counters: &Mutex<LinkCounters>, n: u64) {
    if n > 0 {
        let mut c = counters.lock().unwrap_or_else(PoisonError::into_inner);
        c.routed_dropped = c.routed_dropped.saturating_add(n);
    }
}

/// What [`Queues::paced`] decided.
pub(super) enum Paced {
    /// Return this.
    Go(Option<Command>),
    /// Wait for a queue, or this long for the pace.
    Wait(Option<Duration>),
}

/// Sleeps `wait` (a branch disabled when `None`).
pub(super) async fn sleep_for(wait: Option<Duration>) {
    tokio::time::sleep(wait.unwrap_or_default()).await;
}
