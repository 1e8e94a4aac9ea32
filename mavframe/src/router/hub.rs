//! What the links and the policy share, behind one lock: the policy, each
//! link's way out (its queues, framer, peers, counters and, for UDP, its
//! socket) and the replay window of each key. The task that receives a
//! frame takes the lock, has the policy judge the frame ([`Hub::judge`])
//! and queues it to its links through [`Out`]; routed frames that batch
//! sends to one link leave together when the batch ends, at once when the
//! link has nothing queued, else after what waits.

use super::queues::{sender_key, Next, Packet, Queues};
use super::udp::Datagram;
use super::{
    Inbound, LinkConfig, LinkCounters, Policy, DATAGRAM_FRAMES_MAX, MAX_CLIENTS, SENDS_PER_TURN,
};
use crate::conn::Endpoint;
use crate::frame::MAX_FRAME_LEN;
use crate::framer::Framer;
use crate::link::{Inbox, SigningFile};
use crate::message::{Encode, MessageSet};
use crate::parser::{Received, Stats};
use crate::received::ReceivedBuf;
use crate::route::{LinkId, Links};
use crate::signing::state::SigningState;
use crate::signing::Verifier;
use core::num::NonZeroU32;
use std::boxed::Box;
use std::io;
use std::net::SocketAddr;
use std::string::{String, ToString};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::Duration;
use std::vec::Vec;
use tokio::sync::Notify;
use tokio::time::Instant;

/// How long a send that found the socket's buffer full waits before it
/// is tried again.
pub(super) const SEND_RETRY: Duration = Duration::from_millis(1);

/// `hub`, locked (a poisoned lock still holds whole queues and counters:
/// each change to them is one call).
pub(super) fn lock<P>(hub: &Mutex<Hub<P>>) -> MutexGuard<'_, Hub<P>> {
    hub.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The replay state of one key, shared by its links: a frame one link
/// accepted is a replay on every other, as MAVLink keys replay state by
/// the signature's stream wherever a frame arrives (with a window per
/// link, a listener on one link replayed there what another had accepted).
pub(super) type Window = ([u8; 32], Verifier);

/// The policy and the links' ways out.
pub(super) struct Hub<P> {
    pub(super) policy: P,
    pub(super) outs: Vec<LinkOut>,
    /// One replay window per key.
    pub(super) windows: Vec<Window>,
    /// The router is gone: the tasks send what is queued and end.
    pub(super) closed: bool,
}

/// What a batch of received bytes held, for a `tcpin` client's standing.
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct Batch {
    /// Bytes are held still: the task yields, then judges again.
    pub(super) more: bool,
    /// A frame was accepted.
    pub(super) frames: bool,
    /// An authenticated frame was.
    pub(super) authenticated: bool,
}

impl<P> Hub<P> {
    pub(super) fn new(policy: P) -> Self {
        Hub {
            policy,
            outs: Vec::new(),
            windows: Vec::new(),
            closed: false,
        }
    }

    /// Runs `f` on the policy and an [`Out`] of the links.
    pub(super) fn with<R>(&mut self, f: impl FnOnce(&mut P, &mut Out<'_>) -> R) -> R {
        let Hub {
            policy,
            outs,
            windows,
            ..
        } = self;
        f(policy, &mut Out::new(outs, windows))
    }

    /// The router is gone: the UDP links' receivers see it at once.
    pub(super) fn close(&mut self) {
        self.closed = true;
        for o in &self.outs {
            if let Way::Udp { socket, .. } = &o.way {
                socket.stop_receiving();
            }
        }
    }

    /// The window of the key `signing` verifies with (made for its first
    /// link), raised to what `signing` saved.
    pub(super) fn share_window(&mut self, signing: &SigningFile) {
        let Some((key, saved)) = signing.verifier() else {
            return;
        };
        let window = window_of(&mut self.windows, key, || saved.clone());
        window.restore(saved.newest_timestamp(), &saved.floors(), saved.streams());
    }

    /// Has the policy judge every frame `inbox` holds that link `link`
    /// received ([`judge()`]), the routed frames going when it returns.
    pub(super) fn judge<D: MessageSet>(
        &mut self,
        link: LinkId,
        inbox: &mut Inbox<D, Box<[u8]>>,
        key: Option<[u8; 32]>,
        eof: bool,
    ) -> Batch
    where
        P: Policy<D>,
    {
        let Hub {
            policy,
            outs,
            windows,
            ..
        } = self;
        judge(policy, &mut Out::new(outs, windows), link, inbox, key, eof)
    }

    /// The policy, and the links' ways out for as long as the [`Out`]
    /// lives (what it gathers goes when it is dropped).
    pub(super) fn parts(&mut self) -> (&mut P, Out<'_>) {
        let Hub {
            policy,
            outs,
            windows,
            ..
        } = self;
        (policy, Out::new(outs, windows))
    }
}

/// Has `policy` judge every frame `inbox` holds that link `link` received
/// (parsed in the replay window of `key`, the parser's), and queue each
/// where it says through `out`; at the end of a stream (`eof`), those the
/// held bytes still make. At most one chunk of bytes without a frame is
/// parsed: [`Batch::more`] says bytes remain.
pub(super) fn judge<D: MessageSet, P: Policy<D>>(
    policy: &mut P,
    out: &mut Out<'_>,
    link: LinkId,
    inbox: &mut Inbox<D, Box<[u8]>>,
    key: Option<[u8; 32]>,
    eof: bool,
) -> Batch {
    let slot = key.and_then(|k| out.windows.iter().position(|(w, _)| *w == k));
    let source = inbox.source;
    let (mut frames, mut authenticated) = (false, false);
    let mut judge = |frame: Received<'_, D>, out: &mut Out<'_>| {
        frames = true;
        authenticated |= frame.is_authenticated();
        policy.frame(&Inbound::new(link, frame, source), out);
    };
    loop {
        // Unsigned links (the most) judge the frame where the parser
        // found it; keyed ones a copy, so that the window is back in its
        // place for what the policy sends.
        let judged = match slot {
            None => inbox.take(|f| judge(f, out)).is_ok(),
            Some(s) => match in_window(&mut out.windows[s].1, inbox, Inbox::next) {
                Some(copy) => {
                    judge(copy.received(), out);
                    true
                }
                None => false,
            },
        };
        if !judged {
            break;
        }
    }
    let more = inbox.held() > 0;
    let at_eof = |i: &mut Inbox<D, _>| i.take_at_eof(|r| ReceivedBuf::from(&r));
    while let Some(copy) = match slot {
        _ if !eof || more => None,
        None => at_eof(inbox),
        Some(s) => in_window(&mut out.windows[s].1, inbox, at_eof),
    } {
        judge(copy.received(), out);
    }
    Batch {
        more,
        frames,
        authenticated,
    }
}

/// The window of `key` in `windows`, made by `new` if none has it.
fn window_of(
    windows: &mut Vec<Window>,
    key: [u8; 32],
    new: impl FnOnce() -> Verifier,
) -> &mut Verifier {
    let at = match windows.iter().position(|(k, _)| *k == key) {
        Some(at) => at,
        None => {
            windows.push((key, new()));
            windows.len() - 1
        }
    };
    &mut windows[at].1
}

/// Runs `f` on `inbox` with `window` (the key's shared replay state) in
/// its parser's place, swapped back after: what `f` accepts is recorded in
/// the window, for every link of the key.
pub(super) fn in_window<D: MessageSet, R>(
    window: &mut Verifier,
    inbox: &mut Inbox<D, Box<[u8]>>,
    f: impl FnOnce(&mut Inbox<D, Box<[u8]>>) -> R,
) -> R {
    let mut exchange = |inbox: &mut Inbox<D, Box<[u8]>>| {
        if let Some(own) = inbox.parser.verifier_mut() {
            core::mem::swap(window, own);
        }
    };
    exchange(inbox);
    let r = f(inbox);
    exchange(inbox);
    r
}

/// How a link's frames leave now.
pub(super) enum Way {
    /// The link is down (or not open yet): what is sent to it is dropped.
    Down,
    /// A UDP socket: written at once by whoever sends.
    Udp {
        socket: Arc<Datagram>,
        /// `udpout`'s target (a connected socket), or `udpbcast`'s
        /// broadcast address (where frames go while the link has no peer).
        target: Option<SocketAddr>,
    },
    /// A byte stream (TCP, serial): written by the link's task.
    Stream,
    /// `tcpin`: its clients, each written by its own task.
    Server { clients: Vec<Client> },
}

/// A `tcpin` client, as the link sees it.
pub(super) struct Client {
    pub(super) addr: SocketAddr,
    pub(super) queues: Queues,
    pub(super) wake: Arc<Notify>,
    /// What it has sent: [`SHOWN_NOTHING`], [`SHOWN_FRAMES`] or
    /// [`SHOWN_AUTHENTICATED`].
    pub(super) standing: u8,
    /// Accepted as the link's `order`th client.
    pub(super) order: u64,
    /// Let go (evicted, its queue full, the link rekeyed or failed): its
    /// task ends.
    pub(super) closed: bool,
}

/// No frame accepted from the client yet.
pub(super) const SHOWN_NOTHING: u8 = 0;
/// Frames accepted, none authenticated.
pub(super) const SHOWN_FRAMES: u8 = 1;
/// An authenticated frame.
pub(super) const SHOWN_AUTHENTICATED: u8 = 2;

impl Client {
    /// Lets the client go: its task ends.
    pub(super) fn close(&mut self) {
        self.closed = true;
        self.wake.notify_one();
    }
}

/// Whether `peers` names `addr` (a peer with port 0: every port of its
/// host, a TCP client's port being its system's choice).
pub(super) fn names(peers: &[SocketAddr], addr: SocketAddr) -> bool {
    peers
        .iter()
        .any(|p| p.ip() == addr.ip() && (p.port() == 0 || p.port() == addr.port()))
}

/// What became of a send tried at once.
enum Sent {
    Went,
    /// The socket's buffer was full: nothing went, try again later.
    Blocked,
    Failed,
}

/// One link's way out.
pub(super) struct LinkOut {
    endpoint: Endpoint,
    name: Option<String>,
    pub(super) counters: LinkCounters,
    pub(super) up: bool,
    pub(super) way: Way,
    /// Whom a listening link (`udpin`, `udpbcast`, `tcpin`) sends to: the
    /// policy's ([`Out::set_peers`]).
    pub(super) peers: Vec<SocketAddr>,
    listening: bool,
    pub(super) framer: Framer,
    /// The key the framer signs with (its window is adopted from).
    pub(super) key: Option<[u8; 32]>,
    /// A new key for the link's parser ([`Out::set_key`]), for its task.
    pub(super) rekey: Option<Option<[u8; 32]>>,
    /// The routed pace of each `tcpin` client.
    pub(super) rate: Option<NonZeroU32>,
    pub(super) queues: Queues,
    /// Routed frames the current batch sends to the link, to go together.
    gathered: Vec<u8>,
    gathered_frames: u64,
    /// The link's task.
    pub(super) wake: Arc<Notify>,
}

impl LinkOut {
    pub(super) fn new(config: &LinkConfig, framer: Framer, wake: Arc<Notify>) -> LinkOut {
        // A `tcpin` link paces each client's connection, not its fan-out.
        let rate = match config.endpoint {
            Endpoint::TcpIn(_) => None,
            _ => config.routed_rate,
        };
        LinkOut {
            endpoint: config.endpoint.clone(),
            name: config.name.clone(),
            counters: LinkCounters::default(),
            up: false,
            way: Way::Down,
            peers: Vec::new(),
            listening: config.is_listening(),
            framer,
            key: config.key,
            rekey: None,
            rate: config.routed_rate,
            queues: Queues::link(rate),
            gathered: Vec::with_capacity(DATAGRAM_FRAMES_MAX),
            gathered_frames: 0,
            wake,
        }
    }

    /// The link's transport is `way` from now on (`Way::Down`: it failed;
    /// what was queued is dropped, and its clients let go).
    pub(super) fn set_way(&mut self, way: Way) {
        if let Way::Server { clients } = &mut self.way {
            clients.iter_mut().for_each(Client::close);
        }
        self.up = !matches!(way, Way::Down);
        if !self.up {
            let dropped = self.queues.clear();
            self.counters.routed_dropped = self.counters.routed_dropped.saturating_add(dropped);
            self.gathered.clear();
            self.gathered_frames = 0;
        }
        self.way = way;
    }

    /// Routed `bytes` (a frame) from sender `from`: gathered with the
    /// batch's others for this link, or queued (paced, or for `tcpin`
    /// clients). True when gathered: the batch's end sends it.
    fn route(&mut self, from: u32, bytes: &[u8]) -> bool {
        let paced = self.queues.is_paced();
        match &mut self.way {
            Way::Down => false,
            Way::Server { clients } => {
                let (mut queued, mut dropped) = (0, 0);
                for c in clients.iter_mut() {
                    if c.closed || !names(&self.peers, c.addr) {
                        continue;
                    }
                    // A client behind on routed frames loses them
                    // (counted), not its connection: it may be the peer.
                    match c.queues.push_routed(from, Packet::new(bytes, 1)) {
                        0 => queued += 1,
                        n => dropped += n,
                    }
                    c.wake.notify_one();
                }
                self.count_out(queued);
                self.count_routed_dropped(dropped);
                false
            }
            _ if paced => {
                let dropped = self.queues.push_routed(from, Packet::new(bytes, 1));
                self.count_routed_dropped(dropped);
                self.wake.notify_one();
                false
            }
            _ => {
                if self.gathered.len() + bytes.len() > DATAGRAM_FRAMES_MAX {
                    self.flush();
                }
                self.gathered.extend_from_slice(bytes);
                self.gathered_frames += 1;
                true
            }
        }
    }

    /// The routed frames gathered: sent now if nothing waits before them
    /// on a UDP link, else queued for the link's task.
    pub(super) fn flush(&mut self) {
        if self.gathered.is_empty() {
            return;
        }
        let frames = core::mem::take(&mut self.gathered_frames);
        let gathered = core::mem::take(&mut self.gathered);
        if matches!(self.way, Way::Udp { .. }) && self.queues.is_empty() {
            match self.send_now(&gathered, None) {
                Sent::Went => self.count_out(frames),
                Sent::Failed => self.count_send_error(),
                Sent::Blocked => self.queue_routed(Packet::new(&gathered, frames)),
            }
        } else if !matches!(self.way, Way::Down) {
            self.queue_routed(Packet::new(&gathered, frames));
        }
        self.gathered = gathered;
        self.gathered.clear();
    }

    fn queue_routed(&mut self, packet: Packet) {
        let dropped = self.queues.push_routed(0, packet);
        self.count_routed_dropped(dropped);
        self.wake.notify_one();
    }

    /// The owner's `packet`: sent now on a UDP link whose owner's queue is
    /// empty, else queued (to each `tcpin` client that gets it: one whose
    /// queue is full is let go).
    fn own(&mut self, packet: Packet) {
        match &mut self.way {
            Way::Down => {}
            Way::Server { clients } => {
                let mut queued = 0;
                for c in clients.iter_mut().filter(|c| !c.closed) {
                    let gets = packet
                        .to
                        .map_or_else(|| names(&self.peers, c.addr), |to| c.addr == to);
                    if !gets {
                        continue;
                    }
                    match c.queues.push_own(packet.clone()) {
                        true => {
                            queued += 1;
                            c.wake.notify_one();
                        }
                        false => c.close(),
                    }
                }
                self.count_out(queued);
            }
            Way::Udp { .. } if self.queues.own_is_empty() => {
                match self.send_now(&packet.bytes, packet.to) {
                    Sent::Went => self.count_out(packet.frames),
                    Sent::Failed => self.count_send_error(),
                    Sent::Blocked => self.queue_own(packet),
                }
            }
            _ => self.queue_own(packet),
        }
    }

    fn queue_own(&mut self, packet: Packet) {
        if !self.queues.push_own(packet) {
            self.counters.dropped_full = self.counters.dropped_full.saturating_add(1);
        }
        self.wake.notify_one();
    }

    /// Sends `bytes` on a UDP link now, without waiting: to `to`, or the
    /// link's target (`udpout`), or its peers (`udpin`, `udpbcast`; the
    /// broadcast address while there is none).
    fn send_now(&self, bytes: &[u8], to: Option<SocketAddr>) -> Sent {
        let Way::Udp { socket, target } = &self.way else {
            return Sent::Blocked;
        };
        if !self.listening {
            return sent(socket.try_send(bytes), true);
        }
        if let Some(to) = to {
            return sent(socket.try_send_to(bytes, to), true);
        }
        let fallback = target.filter(|_| self.peers.is_empty());
        let mut result = Sent::Went;
        let targets = self.peers.iter().copied().filter(|p| p.port() != 0);
        for (i, to) in targets.chain(fallback).enumerate() {
            // Only a first send that found the buffer full is tried
            // again: the others would send the first peer a copy.
            match sent(socket.try_send_to(bytes, to), i == 0) {
                Sent::Went => {}
                other if matches!(result, Sent::Went) => result = other,
                _ => {}
            }
        }
        result
    }

    /// Sends what the link's queues hold, while the socket takes it (a UDP
    /// link's task, woken): `Some(wait)` when the rest must wait that long
    /// (for the pace, or room in the socket's buffer), `None` when nothing
    /// is left, or [`SENDS_PER_TURN`] went (then the task is woken again).
    /// `unpaced`: the router is gone.
    pub(super) fn send_queued(&mut self, unpaced: bool) -> Option<Duration> {
        let now = Instant::now();
        for _ in 0..SENDS_PER_TURN {
            let (class, packet) = match self.queues.next(now, unpaced) {
                Next::Send(class, packet) => (class, packet),
                Next::Wait(wait) => return Some(wait),
                Next::Idle => return None,
            };
            match self.send_now(&packet.bytes, packet.to) {
                Sent::Went => self.count_out(packet.frames),
                Sent::Failed => self.count_send_error(),
                Sent::Blocked => {
                    self.queues.put_back(class, packet);
                    return Some(SEND_RETRY);
                }
            }
        }
        self.wake.notify_one();
        None
    }

    pub(super) fn count_out(&mut self, frames: u64) {
        self.counters.frames_out = self.counters.frames_out.saturating_add(frames);
    }

    pub(super) fn count_send_error(&mut self) {
        self.counters.send_errors = self.counters.send_errors.saturating_add(1);
    }

    pub(super) fn count_routed_dropped(&mut self, n: u64) {
        self.counters.routed_dropped = self.counters.routed_dropped.saturating_add(n);
    }
}

/// A send's outcome; `retry`: a full buffer is [`Sent::Blocked`], else a
/// failure.
fn sent(result: io::Result<usize>, retry: bool) -> Sent {
    match result {
        Ok(_) => Sent::Went,
        Err(e) if retry && e.kind() == io::ErrorKind::WouldBlock => Sent::Blocked,
        Err(_) => Sent::Failed,
    }
}

/// The links, as the policy and the owner send on them: under the lock
/// the link tasks share, for as long as a frame is judged (or the owner's
/// [`Router::with`](super::Router::with) runs). Routed frames gathered for
/// a link leave together when it ends.
pub struct Out<'a> {
    outs: &'a mut Vec<LinkOut>,
    windows: &'a mut Vec<Window>,
    /// Links with routed frames gathered.
    touched: Links,
}

impl<'a> Out<'a> {
    fn new(outs: &'a mut Vec<LinkOut>, windows: &'a mut Vec<Window>) -> Self {
        Out {
            outs,
            windows,
            touched: Links::NONE,
        }
    }

    /// Every link.
    pub fn links(&self) -> Links {
        Links::all(self.outs.len())
    }

    fn link(&self, link: LinkId) -> Option<&LinkOut> {
        self.outs.get(usize::from(link))
    }

    /// The endpoint of `link`.
    pub fn endpoint(&self, link: LinkId) -> Option<&Endpoint> {
        self.link(link).map(|l| &l.endpoint)
    }

    /// The name of `link`: the one it was given ([`LinkConfig::name`]),
    /// else its endpoint's connection string.
    pub fn name(&self, link: LinkId) -> String {
        self.link(link)
            .map(|l| l.name.clone().unwrap_or_else(|| l.endpoint.to_string()))
            .unwrap_or_default()
    }

    /// Whether `link`'s transport is open now (a link that failed is
    /// down until it is open again: [`RouterEvent::LinkDown`](super::RouterEvent::LinkDown),
    /// [`RouterEvent::LinkUp`](super::RouterEvent::LinkUp)).
    pub fn is_up(&self, link: LinkId) -> bool {
        self.link(link).is_some_and(|l| l.up)
    }

    /// The counters of `link`.
    pub fn counters(&self, link: LinkId) -> LinkCounters {
        self.link(link).map(|l| l.counters).unwrap_or_default()
    }

    /// Sends `inbound`'s bytes, untouched, on `links` (those that exist);
    /// returns those. Routed traffic: after the owner's own frames, and
    /// dropped first ([`LinkCounters::routed_dropped`]) when a link cannot
    /// keep up; paced per sender on a link with
    /// [`LinkConfig::routed_rate`].
    pub fn route<D: MessageSet>(&mut self, inbound: &Inbound<'_, D>, links: Links) -> Links {
        self.route_as(inbound, links, false)
    }

    /// [`route`](Self::route), except that each link frames it again,
    /// signed with the link's key (when it has one) and sequence numbers
    /// kept: for a link the owner trusts like the key (a local ground tool
    /// that cannot sign). A MAVLink 1 frame goes as MAVLink 2; a frame of
    /// an id the dialect does not know (whose checksum cannot be made)
    /// goes nowhere.
    pub fn route_signed<D: MessageSet>(&mut self, inbound: &Inbound<'_, D>, links: Links) -> Links {
        match inbound.frame.meta() {
            Some(_) => self.route_as(inbound, links, true),
            None => Links::NONE,
        }
    }

    fn route_as<D: MessageSet>(
        &mut self,
        inbound: &Inbound<'_, D>,
        links: Links,
        sign: bool,
    ) -> Links {
        let to = links.intersection(self.links());
        let bytes = inbound.frame.as_bytes();
        // (A hash per frame only when a link of `to` needs it.)
        let mut from = None;
        let mut signed = [0u8; MAX_FRAME_LEN];
        for link in to.iter() {
            let i = usize::from(link);
            let from = match self.outs[i].rate {
                Some(_) => *from.get_or_insert_with(|| sender_key(inbound.link, inbound.source)),
                None => 0,
            };
            let bytes = match inbound.frame.meta().filter(|_| sign) {
                None => bytes,
                Some(meta) => {
                    self.adopt(i);
                    match self.outs[i].framer.resign(bytes, meta) {
                        Ok(b) => {
                            signed[..b.len()].copy_from_slice(b);
                            &signed[..b.len()]
                        }
                        Err(_) => continue,
                    }
                }
            };
            if self.outs[i].route(from, bytes) {
                self.touched = self.touched.union(Links::only(link));
            }
        }
        to
    }

    /// Sends `bytes` on each of `links` as routed traffic, as
    /// [`route`](Self::route) does: after the owner's own frames, and
    /// dropped first. For frames the owner passes on for someone else (a
    /// local program's telemetry for the ground stations, say), which must
    /// not hold its own protocol frames back.
    pub fn send_routed(&mut self, links: Links, bytes: &[u8]) {
        for link in links.intersection(self.links()).iter() {
            if self.outs[usize::from(link)].route(0, bytes) {
                self.touched = self.touched.union(Links::only(link));
            }
        }
    }

    /// Sends frame bytes, untouched, on `links`, as the owner's.
    pub fn send_raw(&mut self, links: Links, bytes: &[u8]) {
        for link in links.intersection(self.links()).iter() {
            self.outs[usize::from(link)].own(Packet::new(bytes, 1));
        }
    }

    /// Frames `message` as `sysid`/`compid` on each of `links` (with each
    /// link's sequence numbers and signer) and sends it. Any message: a
    /// generated one, a dialect's `Message` enum, a `&dyn Encode`.
    pub fn send_message(
        &mut self,
        links: Links,
        sysid: u8,
        compid: u8,
        message: &(impl Encode + ?Sized),
    ) {
        self.send_message_to(links, None, sysid, compid, message);
    }

    /// [`send_message`](Self::send_message), on a listening link (`udpin`,
    /// `tcpin`) to `to` only when given, without making it a peer: for an
    /// answer to one sender (a signed heartbeat that lets a peer whose
    /// clock is behind adopt this node's signing time).
    pub fn send_message_to(
        &mut self,
        links: Links,
        to: Option<SocketAddr>,
        sysid: u8,
        compid: u8,
        message: &(impl Encode + ?Sized),
    ) {
        let meta = message.meta();
        let mut payload = [0u8; 255];
        let Ok(len) = message.emit_payload(&mut payload) else {
            return;
        };
        for link in links.intersection(self.links()).iter() {
            let i = usize::from(link);
            self.adopt(i);
            let o = &mut self.outs[i];
            let Ok(bytes) = o.framer.frame_payload(sysid, compid, meta, &payload[..len]) else {
                continue;
            };
            let mut packet = Packet::new(bytes, 1);
            packet.to = to;
            o.own(packet);
        }
    }

    /// A listening link (`udpin`, `udpbcast`, `tcpin`) sends to `peers`
    /// from now on, and only to them (the first [`MAX_CLIENTS`]; on a UDP
    /// link, a peer of port 0 gets nothing); a `tcpin` link never evicts
    /// their clients. Call it when the set changes, not per frame.
    pub fn set_peers(&mut self, link: LinkId, peers: &[SocketAddr]) {
        if let Some(o) = self.outs.get_mut(usize::from(link)) {
            o.peers.clear();
            o.peers.extend(peers.iter().take(MAX_CLIENTS));
        }
    }

    /// Signs and verifies `link`'s frames with `key` from now on (`None`:
    /// neither), in the key's replay window, its timestamps from the
    /// clock: what a flight controller does on SETUP_SIGNING. What is sent
    /// after this call is signed with it; the link's parser takes it once
    /// the frames received before are judged. A `tcpin` link's clients
    /// are let go: they connect again under the key.
    pub fn set_key(&mut self, link: LinkId, key: Option<[u8; 32]>) {
        let Some(o) = self.outs.get_mut(usize::from(link)) else {
            return;
        };
        if let Some(k) = key {
            window_of(self.windows, k, || Verifier::starting_now(k));
        }
        o.key = key;
        o.framer
            .set_signer(key.map(|k| SigningState::default().signer(k, 0)));
        o.rekey = Some(key);
        o.wake.notify_one();
    }

    /// Link `i`'s signer adopts what its key's window accepted (on any of
    /// its links): before framing.
    fn adopt(&mut self, i: usize) {
        let o = &mut self.outs[i];
        let window = o
            .key
            .and_then(|key| self.windows.iter().find(|(k, _)| *k == key));
        o.framer.adopt_from(window.map(|(_, w)| w));
    }
}

impl Out<'_> {
    /// The routed frames gathered go now.
    pub(super) fn flush(&mut self) {
        for link in core::mem::replace(&mut self.touched, Links::NONE).iter() {
            if let Some(o) = self.outs.get_mut(usize::from(link)) {
                o.flush();
            }
        }
    }

    /// Link `link`'s parser counters.
    pub(super) fn set_parser_stats(&mut self, link: LinkId, stats: Stats) {
        if let Some(o) = self.outs.get_mut(usize::from(link)) {
            o.counters.parser = stats;
        }
    }
}

impl Drop for Out<'_> {
    /// The routed frames gathered go.
    fn drop(&mut self) {
        self.flush();
    }
}
