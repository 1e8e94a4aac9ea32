//! `tcpin` links: the clients, each served by a task of its own.

use super::queues::{count_routed_dropped, Command, Queues, RoutedBytes, RoutedFrame};
use super::task::{
    in_window, outgoing, owner_gives, routed_bytes, Core, Ended, LinkTask, SaveTick,
};
use super::transport::bound_unsent;
use super::{
    Inbound, ReplayWindow, RouterEvent, ACCEPT_BACKOFF, CLIENT_QUEUE, EVICTED_BACKOFF, MAX_CLIENTS,
    STREAM_ROOM,
};
use crate::conn::{ReceivedBuf, ReplyTo};
use crate::link::{Inbox, Peers};
use crate::message::MessageSet;
use crate::route::LinkId;
use std::boxed::Box;
use std::io;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::Arc;
use std::time::Duration;
use std::vec::Vec;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;

impl<D: MessageSet + 'static> LinkTask<D> {
    /// `tcpin`: every client in a task of its own (with its own parser),
    /// fed the link's output through a bounded queue: a client that falls
    /// [`CLIENT_QUEUE`] frames behind is dropped, the others go on. At most
    /// [`MAX_CLIENTS`] at once; the link's [`ReplyTo`] rule says which get
    /// the output.
    pub(super) async fn server(&mut self, listener: TcpListener, core: &mut Core<D>) -> Ended {
        // The key's replay window, swapped into each client's parser while
        // it parses: a frame accepted from one client is a replay from any
        // other (with one each, a capture replayed on a new connection was
        // authenticated again, and could move the owner's peer).
        let shared = self.window.clone();
        let mut clients: Vec<Client> = Vec::new();
        let mut peers = Peers::new(self.config.reply_to);
        let mut paused_until = None::<tokio::time::Instant>;
        let mut tick = SaveTick::new(self.signing.keeps_state());
        loop {
            let resume = paused_until.unwrap_or_else(tokio::time::Instant::now);
            tokio::select! {
                // What the clients accepted, in the shared verifier.
                () = tick.next() => self.save(core, false),
                r = listener.accept(), if paused_until.is_none() => match r {
                    Ok((stream, addr)) => self.admit(stream, addr, &mut clients, &peers, &shared),
                    Err(e) => {
                        // Out of file descriptors, a client's socket makes
                        // room; any failure waits a little.
                        clients.retain(|c| !c.output.is_closed());
                        let evicted = is_out_of_descriptors(&e) && evict(&mut clients, &peers);
                        self.count(|c| c.accept_errors = c.accept_errors.saturating_add(1));
                        let wait = if evicted { EVICTED_BACKOFF } else { ACCEPT_BACKOFF };
                        paused_until = Some(tokio::time::Instant::now() + wait);
                    }
                },
                _ = tokio::time::sleep_until(resume), if paused_until.is_some() => paused_until = None,
                c = self.commands.recv() => {
                    let Some(c) = c else { return Ended::RouterGone };
                    match &c {
                        Command::Peers(addrs) => owner_gives(&mut peers, addrs),
                        // Clients parse with the key they connected
                        // under: they connect again.
                        Command::Key(key, window) => {
                            self.rekey(core, *key, window.clone());
                            clients.clear();
                        }
                        // After the owner's own, in each client's queue
                        // for them. A client behind on those loses frames
                        // (counted), not its connection: routed bursts
                        // come faster than any one client takes them, and
                        // the client may be the protocol peer.
                        Command::Routed(from, routed) => {
                            self.adopt(core);
                            let Some(bytes) = routed_bytes(core, routed) else { continue };
                            let b = RoutedBytes { bytes: bytes.into(), sign: None };
                            let (mut full, mut queued) = (0u64, 0u64);
                            clients.retain(|c| {
                                !c.gets(&peers)
                                    || match c.routed.try_send((*from, b.clone())) {
                                        Ok(()) => {
                                            queued += 1;
                                            true
                                        }
                                        Err(mpsc::error::TrySendError::Full(_)) => {
                                            full += 1;
                                            true
                                        }
                                        Err(mpsc::error::TrySendError::Closed(_)) => false,
                                    }
                            });
                            count_routed_dropped(&self.counters, full);
                            self.count(|c| c.frames_out = c.frames_out.saturating_add(queued));
                        }
                        Command::Raw(_) | Command::Message { .. } => {
                            self.adopt(core);
                            let to = c.to();
                            let Some(bytes) = outgoing(core, &c) else { continue };
                            let bytes: Box<[u8]> = bytes.into();
                            let gets = |c: &Client| to.map_or_else(|| c.gets(&peers), |to| c.addr == to);
                            // Full or closed: the client is dropped.
                            let before = clients.iter().filter(|c| gets(c)).count();
                            clients.retain(|c| !gets(c) || c.output.try_send(Command::Raw(bytes.clone())).is_ok());
                            let queued = clients.iter().filter(|c| gets(c)).count().min(before);
                            self.count(|c| c.frames_out = c.frames_out.saturating_add(queued as u64));
                            self.save(core, false);
                        }
                    }
                }
            }
        }
    }

    /// A new `tcpin` client at `addr`: served in a task of its own, after
    /// the eviction of the client that has shown the least if the link is
    /// full; closed at once when every client is one the link never evicts
    /// (see [`MAX_CLIENTS`]).
    fn admit(
        &mut self,
        stream: TcpStream,
        addr: SocketAddr,
        clients: &mut Vec<Client>,
        peers: &Peers,
        shared: &Option<ReplayWindow>,
    ) {
        clients.retain(|c| !c.output.is_closed());
        if clients.len() >= MAX_CLIENTS && !evict(clients, peers) {
            drop(stream);
            self.count(|c| c.refused_clients = c.refused_clients.saturating_add(1));
            return;
        }
        let _ = stream.set_nodelay(true);
        if self.config.bound_unsent {
            bound_unsent(&stream);
        }
        let (tx, own) = mpsc::channel(CLIENT_QUEUE);
        let (routed, routed_rx) = mpsc::channel(CLIENT_QUEUE);
        let standing = Arc::new(AtomicU8::new(SHOWN_NOTHING));
        self.clients_accepted += 1;
        clients.push(Client {
            addr,
            output: tx,
            routed,
            standing: standing.clone(),
            order: self.clients_accepted,
        });
        let task = ClientTask {
            addr,
            link: self.id,
            shared: shared.clone(),
            standing,
        };
        let rate = self.config.routed_rate;
        let output = Queues::new(own, routed_rx, rate, self.counters.clone());
        let events = self.events.clone();
        tokio::spawn(serve_client(
            stream,
            task,
            self.inbox(STREAM_ROOM),
            output,
            events,
        ));
    }
}

/// A `tcpin` client, as the link's task sees it.
pub(super) struct Client {
    addr: SocketAddr,
    output: mpsc::Sender<Command>,
    /// Frames routed to the link, sent after `output`'s ([`Queues`](super::queues::Queues)).
    routed: mpsc::Sender<RoutedFrame>,
    /// What it has sent: [`SHOWN_NOTHING`], [`SHOWN_FRAMES`] or
    /// [`SHOWN_AUTHENTICATED`] (set by its task).
    standing: Arc<AtomicU8>,
    /// Accepted as the link's `order`th client.
    order: u64,
}

/// No frame accepted from the client yet.
pub(super) const SHOWN_NOTHING: u8 = 0;
/// Frames accepted, none authenticated.
pub(super) const SHOWN_FRAMES: u8 = 1;
/// An authenticated frame.
pub(super) const SHOWN_AUTHENTICATED: u8 = 2;

impl Client {
    fn standing(&self) -> u8 {
        self.standing.load(Ordering::Relaxed)
    }

    /// Whether the link's output goes to this client: under
    /// [`ReplyTo::Accepted`], once a frame of its was accepted (an
    /// authenticated one, with a key); else when the rule names it.
    fn gets(&self, peers: &Peers) -> bool {
        match peers.rule {
            ReplyTo::Accepted => self.standing() >= SHOWN_FRAMES,
            _ => peers.names(self.addr),
        }
    }

    /// Whether the link never evicts this client: it sent an
    /// authenticated frame, or the rule names it.
    fn protected(&self, peers: &Peers) -> bool {
        self.standing() == SHOWN_AUTHENTICATED || peers.names(self.addr)
    }
}

/// Drops the client that has shown the least, the oldest of those, among
/// those not [`protected`](Client::protected) (see [`MAX_CLIENTS`]); its
/// task ends when its queue closes. False when there was none to drop.
pub(super) fn evict(clients: &mut Vec<Client>, peers: &Peers) -> bool {
    let victim = clients
        .iter()
        .enumerate()
        .filter(|(_, c)| !c.protected(peers))
        .min_by_key(|(_, c)| (c.standing(), c.order))
        .map(|(i, _)| i);
    if let Some(i) = victim {
        clients.swap_remove(i);
    }
    victim.is_some()
}

/// Whether an accept failed for want of file descriptors (the process's or
/// the system's).
pub(super) fn is_out_of_descriptors(e: &io::Error) -> bool {
    // EMFILE and ENFILE, the same numbers on Linux, the BSDs and macOS.
    cfg!(unix) && matches!(e.raw_os_error(), Some(23 | 24))
}

/// What a `tcpin` client's task needs of its link.
pub(super) struct ClientTask {
    addr: SocketAddr,
    link: LinkId,
    /// The key's replay window, when the link has a key (see
    /// [`LinkTask::server`]).
    shared: Option<ReplayWindow>,
    /// What the client has shown ([`Client::standing`]).
    standing: Arc<AtomicU8>,
}

/// A client that takes longer than this to accept a frame is dropped (its
/// task would otherwise wait on it for good, with its socket, after the
/// link let it go).
#[cfg(not(test))]
pub(super) const CLIENT_WRITE_TIMEOUT: Duration = Duration::from_secs(2);
/// (The same rule, quicker to test.)
#[cfg(test)]
pub(super) const CLIENT_WRITE_TIMEOUT: Duration = Duration::from_millis(300);

pub(super) async fn serve_client<D: MessageSet>(
    mut stream: TcpStream,
    task: ClientTask,
    mut inbox: Inbox<D, Box<[u8]>>,
    mut output: Queues,
    events: mpsc::Sender<RouterEvent<D>>,
) {
    let mut frames = Vec::new();
    loop {
        tokio::select! {
            r = stream.read(inbox.space()) => match r {
                Ok(n) if n > 0 => {
                    inbox.received(n, Some(task.addr), false);
                    in_window(task.shared.as_deref(), &mut inbox, |inbox| take_all(inbox, &mut frames));
                    for frame in frames.drain(..) {
                        // With a key, only an authenticated frame shows more
                        // than an idle connection does.
                        let shown = match (frame.is_authenticated(), &task.shared) {
                            (true, _) => SHOWN_AUTHENTICATED,
                            (false, None) => SHOWN_FRAMES,
                            (false, Some(_)) => SHOWN_NOTHING,
                        };
                        task.standing.fetch_max(shown, Ordering::Relaxed);
                        let event = RouterEvent::Frame(Inbound { link: task.link, frame, source: Some(task.addr) });
                        if events.send(event).await.is_err() {
                            return;
                        }
                    }
                }
                _ => return,
            },
            out = output.recv() => {
                let bytes = match &out {
                    Some(Command::Raw(bytes)) => bytes,
                    Some(Command::Routed(_, routed)) => &routed.bytes,
                    _ => return,
                };
                let written = tokio::time::timeout(CLIENT_WRITE_TIMEOUT, stream.write_all(bytes)).await;
                if !matches!(written, Ok(Ok(()))) {
                    return;
                }
            }
        }
    }
}

/// The frames `inbox` holds, into `frames` (one vector for the client's
/// life, not one per read).
fn take_all<D: MessageSet>(inbox: &mut Inbox<D, Box<[u8]>>, frames: &mut Vec<ReceivedBuf<D>>) {
    loop {
        match inbox.next() {
            Some(frame) => frames.push(frame),
            None if inbox.held() > 0 => {}
            None => break,
        }
    }
}
