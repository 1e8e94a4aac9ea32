//! A link's task: it owns the transport, reads frames for the router and
//! sends what the router queues.

use super::datagram::Datagram;
use super::queues::{Command, Queues, RoutedBytes, RoutedFrame};
use super::transport::{send_connected, AsyncStream, Transport};
use super::{
    lock, Inbound, LinkConfig, LinkCounters, ReplayWindow, RouterEvent, DATAGRAM_FRAMES_MAX,
    DATAGRAM_ROOM, PARSE_CHUNK, REOPEN_INTERVAL,
};
use crate::conn::{ReceivedBuf, ReplyTo};
use crate::link::{Inbox, LinkCore, Peers, SigningFile};
use crate::message::MessageSet;
use crate::route::LinkId;
use crate::signing::state::SAVE_INTERVAL;
use crate::signing::Verifier;
use core::pin::Pin;
use std::boxed::Box;
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::vec;
use std::vec::Vec;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::sync::mpsc;
use tokio::time::Sleep;

/// One link's task.
pub(super) struct LinkTask<D: MessageSet> {
    pub(super) id: LinkId,
    pub(super) config: LinkConfig,
    pub(super) events: mpsc::Sender<RouterEvent<D>>,
    pub(super) commands: Queues,
    pub(super) counters: Arc<Mutex<LinkCounters>>,
    pub(super) signing: SigningFile,
    /// The replay window of the link's key, shared with the other links
    /// that have it ([`Router::add`](super::Router::add)).
    pub(super) window: Option<ReplayWindow>,
    /// The transport is open ([`Router::is_up`](super::Router::is_up)).
    pub(super) up: Arc<AtomicBool>,
    /// `tcpin`: clients accepted so far (each client's order).
    pub(super) clients_accepted: u64,
}

/// A link's core, as a task drives it.
pub(super) type Core<D> = LinkCore<D, Box<[u8]>>;

/// The bytes `command` sends, a message framed by `core` (`None`: none).
pub(super) fn outgoing<'a, D: MessageSet>(
    core: &'a mut Core<D>,
    command: &'a Command,
) -> Option<&'a [u8]> {
    match command {
        Command::Peers(_) | Command::Key(..) => None,
        Command::Raw(b) => Some(b),
        Command::Routed(_, routed) => routed_bytes(core, routed),
        Command::Message {
            sysid,
            compid,
            meta,
            payload,
            ..
        } => {
            core.adopt();
            core.framer
                .frame_payload(*sysid, *compid, meta, payload)
                .ok()
        }
    }
}

/// The bytes a link sends for a routed frame: framed again and signed by
/// `core` where the owner asked ([`Router::route_signed`](super::Router::route_signed)).
pub(super) fn routed_bytes<'a, D: MessageSet>(
    core: &'a mut Core<D>,
    routed: &'a RoutedBytes,
) -> Option<&'a [u8]> {
    match routed.sign {
        None => Some(&routed.bytes),
        Some(meta) => {
            core.adopt();
            core.framer.resign(&routed.bytes, meta).ok()
        }
    }
}

impl<D: MessageSet + 'static> LinkTask<D> {
    /// An inbox with the link's key and `room` bytes to receive into.
    pub(super) fn inbox(&self, room: usize) -> Inbox<D, Box<[u8]>> {
        let mut inbox = Inbox::new(self.signing.parser(), vec![0u8; room].into_boxed_slice());
        inbox.set_chunk(PARSE_CHUNK);
        inbox
    }

    /// Runs the link until the router is dropped, reopening it when it
    /// fails; `first` is its opening in [`Router::add`](super::Router::add).
    pub(super) async fn run(mut self, first: io::Result<Transport>) {
        let mut transport = match first {
            Ok(t) => Some(t),
            Err(error) => {
                let down = RouterEvent::LinkDown {
                    link: self.id,
                    error,
                };
                if self.events.send(down).await.is_err() || self.wait_reopen().await.is_err() {
                    return;
                }
                None
            }
        };
        let mut core = LinkCore {
            inbox: self.inbox(DATAGRAM_ROOM),
            framer: self.signing.framer(),
        };
        loop {
            let t = match transport.take() {
                Some(t) => t,
                None => match Transport::open(&self.config).await {
                    Ok(t) => {
                        self.up.store(true, Ordering::Relaxed);
                        let _ = self
                            .events
                            .send(RouterEvent::LinkUp { link: self.id })
                            .await;
                        t
                    }
                    Err(_) => {
                        if self.wait_reopen().await.is_err() {
                            return;
                        }
                        continue;
                    }
                },
            };
            let ended = match t {
                Transport::Udp {
                    socket,
                    to,
                    replies,
                } => self.udp(socket, to, replies, &mut core).await,
                Transport::Stream(stream) => self.stream(stream, &mut core).await,
                Transport::Server(listener) => self.server(listener, &mut core).await,
            };
            self.save(&core, true);
            match ended {
                Ended::RouterGone => return,
                Ended::Failed(error) => {
                    self.up.store(false, Ordering::Relaxed);
                    let down = RouterEvent::LinkDown {
                        link: self.id,
                        error,
                    };
                    if self.events.send(down).await.is_err() {
                        return;
                    }
                    self.go_on_from(&core);
                    core.inbox = self.inbox(DATAGRAM_ROOM);
                    if self.wait_reopen().await.is_err() {
                        return;
                    }
                }
            }
        }
    }

    /// Waits [`REOPEN_INTERVAL`], dropping what is queued meanwhile; `Err`
    /// when the router is gone.
    async fn wait_reopen(&mut self) -> Result<(), ()> {
        let until = tokio::time::Instant::now() + REOPEN_INTERVAL;
        loop {
            tokio::select! {
                _ = tokio::time::sleep_until(until) => return Ok(()),
                more = self.commands.drop_next() => if !more { return Err(()) },
            }
        }
    }

    /// Saves the signing state if due, or now as at exit (`last`), with
    /// the key's replay window; failures are counted.
    pub(super) fn save(&mut self, core: &Core<D>, last: bool) {
        if !self.signing.keeps_state() {
            return;
        }
        let window = self.window.as_deref().map(lock);
        let verifier = window.as_deref().or(core.inbox.parser.verifier());
        if !self.signing.save(&core.framer, verifier, last) {
            self.count(|c| c.state_save_errors = c.state_save_errors.saturating_add(1));
        }
    }

    /// Signs and verifies with `key` from now on, in its replay `window`:
    /// a new parser and signer (the sequence numbers go on).
    pub(super) fn rekey(
        &mut self,
        core: &mut Core<D>,
        key: Option<[u8; 32]>,
        window: Option<ReplayWindow>,
    ) {
        self.signing.set_key(key);
        self.window = window;
        core.inbox.parser = self.signing.parser();
        core.framer.set_signer(self.signing.signer());
    }

    /// Signing goes on from where the failed transport was.
    fn go_on_from(&mut self, core: &Core<D>) {
        let window = self.window.as_deref().map(lock);
        let verifier = window.as_deref().or(core.inbox.parser.verifier());
        self.signing.go_on_from(&core.framer, verifier);
    }

    /// The next frame the core holds, parsed in the key's replay window;
    /// then the link's signer adopts the window's notion of now.
    fn next_frame(&mut self, core: &mut Core<D>) -> Option<ReceivedBuf<D>> {
        let frame = in_window(self.window.as_deref(), &mut core.inbox, Inbox::next);
        self.adopt(core);
        frame
    }

    /// The signer adopts what the key's replay window accepted (on any of
    /// its links): before framing, and after receiving.
    pub(super) fn adopt(&self, core: &mut Core<D>) {
        match self.window.as_deref() {
            Some(window) => core.framer.adopt_from(Some(&*lock(window))),
            None => core.adopt(),
        }
    }

    pub(super) fn count(&self, f: impl FnOnce(&mut LinkCounters)) {
        f(&mut self.counters.lock().unwrap_or_else(|e| e.into_inner()));
    }

    /// Hands every frame the core holds to the router (at the end of a
    /// stream, `eof`, those the held bytes still make). Parsed
    /// [`PARSE_CHUNK`] bytes at a time, yielding in between, so one large
    /// datagram never holds the runtime (and the owner's timers) for long.
    /// `Ok(true)` when a frame among them vouches for its sender.
    async fn deliver(&mut self, core: &mut Core<D>, eof: bool) -> Result<bool, ()> {
        let mut vouched = false;
        loop {
            let frame = match self.next_frame(core) {
                Some(frame) => frame,
                None if core.inbox.held() > 0 => {
                    tokio::task::yield_now().await;
                    continue;
                }
                None if eof => {
                    let at_eof = |i: &mut Inbox<D, _>| i.take_at_eof(|r| ReceivedBuf::from(&r));
                    match in_window(self.window.as_deref(), &mut core.inbox, at_eof) {
                        Some(frame) => frame,
                        None => break,
                    }
                }
                None => break,
            };
            vouched |= core.inbox.vouches(&frame);
            let source = core.inbox.source;
            let event = RouterEvent::Frame(Inbound {
                link: self.id,
                frame,
                source,
            });
            if self.events.send(event).await.is_err() {
                return Err(());
            }
        }
        let stats = *core.inbox.parser.stats();
        self.count(|c| c.parser = stats);
        Ok(vouched)
    }

    /// A UDP link: `udpout` (`target`, a connected socket) sends to its
    /// target; `udpin` and `udpbcast` (`replies`) to the peers of the
    /// link's rule, `udpbcast` to its broadcast address (`target`) while
    /// there is none.
    async fn udp(
        &mut self,
        socket: Datagram,
        target: Option<SocketAddr>,
        replies: bool,
        core: &mut Core<D>,
    ) -> Ended {
        let mut peers = Peers::new(self.config.reply_to);
        let mut datagram = Vec::with_capacity(DATAGRAM_FRAMES_MAX);
        let mut tick = SaveTick::new(self.signing.keeps_state());
        loop {
            tokio::select! {
                () = tick.next() => self.save(core, false),
                // A failed receive (an ICMP error on some systems) says
                // nothing about the next one: it is skipped.
                r = socket.recv_from(core.inbox.space()) => if let Ok((n, from)) = r {
                    core.inbox.received(n, Some(from), true);
                    let refused = core.inbox.parser.stats().bad_signature;
                    match self.deliver(core, false).await {
                        Err(()) => return Ended::RouterGone,
                        // Only a frame accepted makes its sender a peer.
                        Ok(vouched) => if vouched && replies {
                            peers.heard(Some(from));
                        }
                    }
                    let stats = core.inbox.parser.stats();
                    let bad = stats.bad_signature > refused;
                    if let (Some(sender), true) = (stats.bad_signature_sender, bad && replies) {
                        let event = RouterEvent::BadSignature { link: self.id, source: from, sender };
                        if self.events.send(event).await.is_err() {
                            return Ended::RouterGone;
                        }
                    }
                    self.save(core, false);
                },
                c = self.commands.recv() => {
                    let Some(c) = c else { return Ended::RouterGone };
                    match c {
                        Command::Peers(addrs) => {
                            owner_gives(&mut peers, &addrs);
                            continue;
                        }
                        Command::Key(key, window) => {
                            self.rekey(core, key, window);
                            continue;
                        }
                        _ => {}
                    }
                    let to = c.to();
                    self.adopt(core);
                    let Some(bytes) = outgoing(core, &c) else { continue };
                    // Frames queued behind, for the same addressees, join it.
                    let more = to.is_none().then(|| self.commands.queued_routed()).flatten();
                    let (bytes, frames) = match more {
                        Some(next) => {
                            datagram.clear();
                            datagram.extend_from_slice(bytes);
                            let joined = self.coalesce(next, &mut datagram);
                            (&datagram[..], 1 + joined)
                        }
                        None => (bytes, 1),
                    };
                    let sent = match (replies, to) {
                        (true, Some(to)) => socket.send_to(bytes, to).await.map(drop),
                        (true, None) => send_each(&socket, peers.targets(target), bytes).await,
                        (false, _) => send_connected(&socket, bytes).await,
                    };
                    match sent {
                        Ok(()) => self.count(|c| c.frames_out = c.frames_out.saturating_add(frames)),
                        Err(_) => self.count(|c| c.send_errors = c.send_errors.saturating_add(1)),
                    }
                    self.save(core, false);
                }
            }
        }
    }

    /// Appends `next` and the routed frames queued behind it to
    /// `datagram` while they fit in [`DATAGRAM_FRAMES_MAX`] bytes; the
    /// first that does not (or that the link signs: signing it twice would
    /// spend a signing timestamp) goes next, in a datagram of its own.
    /// The frames appended.
    fn coalesce(&mut self, next: RoutedFrame, datagram: &mut Vec<u8>) -> u64 {
        let mut next = Some(next);
        let mut joined = 0;
        while let Some((from, routed)) = next.take() {
            if routed.sign.is_some() || datagram.len() + routed.bytes.len() > DATAGRAM_FRAMES_MAX {
                self.commands.hold((from, routed));
                break;
            }
            datagram.extend_from_slice(&routed.bytes);
            joined += 1;
            next = self.commands.queued_routed();
        }
        joined
    }

    async fn stream(&mut self, mut stream: Box<dyn AsyncStream>, core: &mut Core<D>) -> Ended {
        let mut tick = SaveTick::new(self.signing.keeps_state());
        loop {
            tokio::select! {
                () = tick.next() => self.save(core, false),
                r = stream.read(core.inbox.space()) => match r {
                    Ok(0) => {
                        let _ = self.deliver(core, true).await;
                        return Ended::Failed(io::Error::new(io::ErrorKind::UnexpectedEof, "closed by the peer"));
                    }
                    Ok(n) => {
                        core.inbox.received(n, None, false);
                        if self.deliver(core, false).await.is_err() {
                            return Ended::RouterGone;
                        }
                        self.save(core, false);
                    }
                    Err(e) => return Ended::Failed(e),
                },
                c = self.commands.recv() => {
                    let Some(c) = c else { return Ended::RouterGone };
                    if let Command::Key(key, window) = c {
                        self.rekey(core, key, window);
                        continue;
                    }
                    self.adopt(core);
                    let Some(bytes) = outgoing(core, &c) else { continue };
                    if let Err(e) = stream.write_all(bytes).await {
                        self.count(|c| c.send_errors = c.send_errors.saturating_add(1));
                        return Ended::Failed(e);
                    }
                    self.count(|c| c.frames_out = c.frames_out.saturating_add(1));
                    self.save(core, false);
                }
            }
        }
    }
}

/// The tick that saves a link's signing state while the link is quiet:
/// a save is otherwise asked for after each frame and send only, so a link
/// that fell silent right after accepting frames kept them unsaved, and a
/// crash then let them be replayed into the restarted program. One timer
/// a link, reset as it fires: none made per frame.
pub(super) struct SaveTick(Option<Pin<Box<Sleep>>>);

impl SaveTick {
    /// Every [`SAVE_INTERVAL`] for a link that `keeps` a state file;
    /// never for one that does not.
    pub(super) fn new(keeps: bool) -> SaveTick {
        SaveTick(keeps.then(|| Box::pin(tokio::time::sleep(SAVE_INTERVAL))))
    }

    /// Waits for the next tick. Cancel-safe (a `select!` branch): the
    /// timer lives in `self`.
    pub(super) async fn next(&mut self) {
        match &mut self.0 {
            Some(sleep) => {
                sleep.as_mut().await;
                let next = tokio::time::Instant::now() + SAVE_INTERVAL;
                sleep.as_mut().reset(next);
            }
            None => std::future::pending().await,
        }
    }
}

impl Command {
    /// `Message`'s one addressee, if given.
    pub(super) fn to(&self) -> Option<SocketAddr> {
        match self {
            Command::Message { to, .. } => *to,
            _ => None,
        }
    }
}

/// [`Router::set_peers`](super::Router::set_peers): the peers of a link under [`ReplyTo::Owner`](crate::conn::ReplyTo::Owner).
pub(super) fn owner_gives(peers: &mut Peers, addrs: &[SocketAddr]) {
    if peers.rule == ReplyTo::Owner {
        peers.given(addrs);
    }
}

/// Sends `bytes` to each of `to`: the first error, once each was tried.
pub(super) async fn send_each(
    socket: &Datagram,
    to: impl Iterator<Item = SocketAddr>,
    bytes: &[u8],
) -> io::Result<()> {
    let mut sent = Ok(());
    for to in to {
        if let (Err(e), Ok(())) = (socket.send_to(bytes, to).await, &sent) {
            sent = Err(e);
        }
    }
    sent
}

/// Runs `f` on `inbox` with `window` (the key's shared replay state) in
/// its parser's place, swapped back after: what `f` accepts is recorded in
/// the window, for every link of the key.
pub(super) fn in_window<D: MessageSet, R>(
    window: Option<&Mutex<Verifier>>,
    inbox: &mut Inbox<D, Box<[u8]>>,
    f: impl FnOnce(&mut Inbox<D, Box<[u8]>>) -> R,
) -> R {
    let mut shared = window.map(lock);
    let mut exchange = |inbox: &mut Inbox<D, Box<[u8]>>| {
        if let (Some(shared), Some(own)) = (shared.as_deref_mut(), inbox.parser.verifier_mut()) {
            core::mem::swap(shared, own);
        }
    };
    exchange(inbox);
    let r = f(inbox);
    exchange(inbox);
    r
}

/// How a link's transport ended.
pub(super) enum Ended {
    /// The router was dropped: the task ends.
    RouterGone,
    /// The transport failed: reopen it.
    Failed(io::Error),
}
