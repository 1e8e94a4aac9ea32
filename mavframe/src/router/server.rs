//! `tcpin` links: the listener in the link's task, each client in a task
//! of its own that has the policy judge what it reads (as the link's) and
//! writes what the link sends it.

use super::hub::{lock, names, Client, Hub, Way, SHOWN_AUTHENTICATED, SHOWN_FRAMES, SHOWN_NOTHING};
use super::queues::{Next, Queues};
use super::task::{Alarm, Ended, LinkTask, SaveTick};
use super::transport::bound_unsent;
use super::{Policy, ACCEPT_BACKOFF, EVICTED_BACKOFF, MAX_CLIENTS, SENDS_PER_TURN, STREAM_ROOM};
use crate::link::Inbox;
use crate::message::MessageSet;
use crate::route::LinkId;
use core::marker::PhantomData;
use std::boxed::Box;
use std::io;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, Weak};
use std::time::Duration;
use std::vec::Vec;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::tcp::OwnedWriteHalf;
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Notify;
use tokio::task::JoinSet;
use tokio::time::Instant;

/// Sends a `tcpin` client may have queued, each class apart (the owner's,
/// routed ones), before the owner's further ones drop it (routed ones are
/// dropped, counted, instead).
const CLIENT_QUEUE: usize = 256;

/// A client that takes longer than this to accept a write is dropped (its
/// task would otherwise wait on it for good, with its socket).
#[cfg(not(test))]
pub(super) const CLIENT_WRITE_TIMEOUT: Duration = Duration::from_secs(2);
/// (The same rule, quicker to test.)
#[cfg(test)]
pub(super) const CLIENT_WRITE_TIMEOUT: Duration = Duration::from_millis(300);

impl<D: MessageSet + 'static, P: Policy<D>> LinkTask<D, P> {
    /// `tcpin`: accepts clients, at most [`MAX_CLIENTS`] at once, each
    /// served by a task of its own (see [`ClientTask`]); the link's peers
    /// ([`Out::set_peers`](super::Out::set_peers)) say which get the
    /// link's output.
    pub(super) async fn server(&mut self, listener: TcpListener) -> Ended {
        let mut clients = JoinSet::new();
        let mut paused_until = None::<Instant>;
        let mut tick = SaveTick::new(self.signing.keeps_state());
        loop {
            let resume = paused_until.unwrap_or_else(Instant::now);
            tokio::select! {
                // What the clients accepted, in the shared window.
                () = tick.next() => self.save(false),
                r = listener.accept(), if paused_until.is_none() => match r {
                    Ok((stream, addr)) => self.admit(stream, addr, &mut clients),
                    Err(e) => {
                        // Out of file descriptors, a client's socket makes
                        // room; any failure waits a little.
                        let evicted = self.on_server(|o, peers| {
                            o.counters.accept_errors = o.counters.accept_errors.saturating_add(1);
                            is_out_of_descriptors(&e) && evict(peers, o.clients())
                        });
                        let wait = if evicted { EVICTED_BACKOFF } else { ACCEPT_BACKOFF };
                        paused_until = Some(Instant::now() + wait);
                    }
                },
                _ = tokio::time::sleep_until(resume), if paused_until.is_some() => paused_until = None,
                Some(_) = clients.join_next(), if !clients.is_empty() => {}
                () = self.wake.notified() => {
                    if lock(&self.hub).closed {
                        // The clients send what is queued for them.
                        self.on_server(|o, _| o.clients().iter().for_each(|c| c.wake.notify_one()));
                        while clients.join_next().await.is_some() {}
                        return Ended::RouterGone;
                    }
                    // Clients parse with the key they connected under:
                    // they connect again.
                    if self.rekeyed(None) {
                        self.on_server(|o, _| o.clients().iter_mut().for_each(Client::close));
                    }
                }
            }
        }
    }

    /// Runs `f` on the link's way out and its peers, under the lock.
    fn on_server<R>(&self, f: impl FnOnce(&mut ServerOut<'_>, &[SocketAddr]) -> R) -> R {
        let mut hub = lock(&self.hub);
        let o = &mut hub.outs[usize::from(self.id)];
        let peers = o.peers.clone();
        f(
            &mut ServerOut {
                counters: &mut o.counters,
                way: &mut o.way,
            },
            &peers,
        )
    }

    /// A new `tcpin` client at `addr`: served by a task of its own, after
    /// the eviction of the client that has shown the least if the link is
    /// full; closed at once when every client is one the link never
    /// evicts (see [`MAX_CLIENTS`]).
    fn admit(&mut self, stream: TcpStream, addr: SocketAddr, tasks: &mut JoinSet<()>) {
        let _ = stream.set_nodelay(true);
        if self.config.bound_unsent {
            bound_unsent(&stream);
        }
        let order = self.clients_accepted + 1;
        let wake = Arc::new(Notify::new());
        let rate = self.config.routed_rate;
        let admitted = self.on_server(|o, peers| {
            o.clients().retain(|c| !c.closed);
            if o.clients().len() >= MAX_CLIENTS && !evict(peers, o.clients()) {
                o.counters.refused_clients = o.counters.refused_clients.saturating_add(1);
                return false;
            }
            o.clients().push(Client {
                addr,
                queues: Queues::new(rate, CLIENT_QUEUE),
                wake: wake.clone(),
                standing: SHOWN_NOTHING,
                order,
                closed: false,
            });
            true
        });
        if !admitted {
            return;
        }
        self.clients_accepted = order;
        let task = ClientTask::<D, P> {
            hub: Arc::downgrade(&self.hub),
            link: self.id,
            addr,
            order,
            wake,
            key: self.signing.key(),
            _dialect: PhantomData,
        };
        tasks.spawn(task.serve(stream, self.inbox(STREAM_ROOM)));
    }
}

/// A `tcpin` link's way out, as its task changes it.
struct ServerOut<'a> {
    counters: &'a mut super::LinkCounters,
    way: &'a mut Way,
}

impl ServerOut<'_> {
    fn clients(&mut self) -> &mut Vec<Client> {
        match self.way {
            Way::Server { clients } => clients,
            _ => unreachable!("a tcpin link's way out is its clients"),
        }
    }
}

/// Lets go the client that has shown the least, the oldest of those,
/// among those the link may evict (not one that sent an authenticated
/// frame, nor one of its `peers`; see [`MAX_CLIENTS`]). False when there
/// was none.
fn evict(peers: &[SocketAddr], clients: &mut [Client]) -> bool {
    let victim = clients
        .iter_mut()
        .filter(|c| !c.closed)
        .filter(|c| c.standing != SHOWN_AUTHENTICATED && !names(peers, c.addr))
        .min_by_key(|c| (c.standing, c.order));
    match victim {
        Some(c) => {
            c.close();
            true
        }
        None => false,
    }
}

/// Whether an accept failed for want of file descriptors (the process's or
/// the system's).
fn is_out_of_descriptors(e: &io::Error) -> bool {
    // EMFILE and ENFILE, the same numbers on Linux, the BSDs and macOS.
    cfg!(unix) && matches!(e.raw_os_error(), Some(23 | 24))
}

/// A `tcpin` client's task: what it reads is judged as the link's (in the
/// link's replay window: a frame accepted from one client is a replay from
/// any other), what is queued for it written.
struct ClientTask<D, P> {
    /// The links' hub, held only while a batch is judged or a queue
    /// read: a client never keeps a router alive.
    hub: Weak<Mutex<Hub<P>>>,
    link: LinkId,
    addr: SocketAddr,
    order: u64,
    wake: Arc<Notify>,
    /// The key it connected under.
    key: Option<[u8; 32]>,
    _dialect: PhantomData<fn() -> D>,
}

impl<D: MessageSet + 'static, P: Policy<D>> ClientTask<D, P> {
    async fn serve(self, stream: TcpStream, mut inbox: Inbox<D, Box<[u8]>>) {
        let (mut read, mut write) = stream.into_split();
        let mut alarm = Alarm::default();
        loop {
            let mut send = false;
            tokio::select! {
                r = read.read(inbox.space()) => match r {
                    Ok(n) if n > 0 => {
                        inbox.received(n, Some(self.addr), false);
                        if self.deliver(&mut inbox).await.is_none() {
                            break;
                        }
                    }
                    _ => break,
                },
                () = self.wake.notified() => send = true,
                () = alarm.fired() => send = true,
            }
            if send {
                match self.write_queued(&mut write).await {
                    Some(wait) => alarm.set(wait),
                    None => break,
                }
            }
        }
        self.with_client(|hub, at| {
            if let Some(c) = clients(hub, self.link).and_then(|c| c.get_mut(at)) {
                c.closed = true;
            }
        });
    }

    /// Runs `f` on the hub and this client's place among the link's
    /// clients, while both are there and the client is not let go.
    fn with_client<R>(&self, f: impl FnOnce(&mut Hub<P>, usize) -> R) -> Option<R> {
        let hub = self.hub.upgrade()?;
        let mut hub = lock(&hub);
        let at = clients(&mut hub, self.link)?
            .iter()
            .position(|c| c.order == self.order && !c.closed)?;
        Some(f(&mut hub, at))
    }

    /// Has the policy judge what the client sent, a chunk of bytes
    /// without a frame at a time: `None` once the client is let go.
    async fn deliver(&self, inbox: &mut Inbox<D, Box<[u8]>>) -> Option<()> {
        loop {
            let more = self.with_client(|hub, at| {
                let batch = hub.judge(self.link, inbox, self.key, false);
                let closed = hub.closed;
                // (Judging never removes a client: its place holds.)
                let client = clients(hub, self.link)?.get_mut(at)?;
                // With a key, only an authenticated frame shows more
                // than an idle connection does.
                let shown = match (batch.authenticated, batch.frames, self.key) {
                    (true, _, _) => SHOWN_AUTHENTICATED,
                    (false, true, None) => SHOWN_FRAMES,
                    _ => SHOWN_NOTHING,
                };
                client.standing = client.standing.max(shown);
                (!closed && !client.closed).then_some(batch.more)
            })??;
            if !more {
                return Some(());
            }
            tokio::task::yield_now().await;
        }
    }

    /// Writes what the client's queues hold: `Some(Some(wait))` when the
    /// rest waits for the pace; `None` when the client is done (let go,
    /// a write failed or timed out, the router gone and its queue sent).
    async fn write_queued(&self, write: &mut OwnedWriteHalf) -> Option<Option<Duration>> {
        for _ in 0..SENDS_PER_TURN {
            let next = self.with_client(|hub, at| {
                let closed = hub.closed;
                let c = clients(hub, self.link)?.get_mut(at)?;
                Some((c.queues.next(Instant::now(), closed), closed))
            })??;
            let packet = match next {
                (Next::Send(_, packet), _) => packet,
                (Next::Wait(wait), _) => return Some(Some(wait)),
                (Next::Idle, true) => return None,
                (Next::Idle, false) => return Some(None),
            };
            let written =
                tokio::time::timeout(CLIENT_WRITE_TIMEOUT, write.write_all(&packet.bytes)).await;
            if !matches!(written, Ok(Ok(()))) {
                return None;
            }
        }
        self.wake.notify_one();
        Some(None)
    }
}

/// The clients of `tcpin` link `link`, while it is open.
fn clients<P>(hub: &mut Hub<P>, link: LinkId) -> Option<&mut Vec<Client>> {
    match &mut hub.outs.get_mut(usize::from(link))?.way {
        Way::Server { clients } => Some(clients),
        _ => None,
    }
}
