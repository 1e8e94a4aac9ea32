//! A MAVLink router on tokio (feature `tokio`): links of every kind an
//! [`Endpoint`] names, and a [`Policy`] that decides where each frame
//! goes.
//!
//! Each link has a task that owns its transport and its parser (with the
//! link's key, if any, and that key's replay window, one for every link
//! with the key); a UDP link receives on a thread of its own (tokio's
//! blocking pool), blocked in the socket's receive, so a datagram costs
//! the system calls of a program that only forwards. A frame a link
//! receives is judged by the policy *there*, and queued to the links the
//! policy names: no channel to an owner's task and back. The policy and
//! the links' ways out (their queues, framers, peers and counters) sit
//! behind one lock, taken once per datagram or read; a link whose queue
//! is empty is sent to at once (a UDP socket is written without waking
//! its task), a backlogged one gets the frame queued and its task woken. A link that fails (a TCP
//! peer gone, a serial port unplugged) is reported to the policy
//! ([`RouterEvent::LinkDown`]) and opened again every second; no error of
//! one link stops another.
//!
//! The router keeps links, transports, queues, pacing, signing per link,
//! reopening and health counters; the rules are the policy's. [`Forward`]
//! is the plain router's: the MAVLink routing rules over a
//! [`RoutingTable`](crate::route::RoutingTable), and each listening link
//! answering the senders of the frames it accepted, in a
//! [`PeerSet`](crate::peers::PeerSet). A program with a policy of its own
//! (a companion computer that also speaks on its links) implements
//! [`Policy`] over its sans-IO core and drives its timers with
//! [`Router::with`]. Frames are forwarded as received, byte for byte:
//! signed frames stay verifiable.
//!
//! Strangers on a link can neither take a peer's traffic nor drop its
//! routes:
//!
//! - `udpin`, `udpbcast` and `tcpin` links send to the peers the policy
//!   names ([`Out::set_peers`]) and to nobody else (`udpbcast` to its
//!   broadcast address while there is none). A datagram alone never moves
//!   them: [`Forward`] names the senders of frames the link's parser
//!   accepted (authenticated ones, on a link with a key).
//! - `udpout` sockets are connected to their target: the system drops
//!   datagrams from anyone else.
//! - A `tcpin` link never evicts a client that has sent an authenticated
//!   frame or is one of the link's peers for a new connection (see
//!   [`MAX_CLIENTS`]).
//!
//! ```no_run
//! # use mavframe::{MessageSet, MessageMeta, Encode, BufferTooSmall};
//! # #[derive(Debug, Clone, PartialEq)] struct M;
//! # impl Encode for M { fn meta(&self) -> &'static MessageMeta { unimplemented!() }
//! #   fn emit_payload(&self, _: &mut [u8]) -> Result<usize, BufferTooSmall> { Ok(0) } }
//! # struct D; impl MessageSet for D { type Message = M; type View<'a> = ();
//! #   const MESSAGES: &'static [MessageMeta] = &[];
//! #   fn parse(_: u32, _: &[u8]) -> Option<M> { None } fn view(_: u32, _: &[u8]) -> Option<()> { None } }
//! # async fn run() -> std::io::Result<()> {
//! use mavframe::router::{Forward, LinkConfig, Router};
//!
//! let mut router = Router::<D, _>::new(Forward::new());
//! router.add(LinkConfig::new("serial:/dev/serial0:460800".parse().unwrap())).await?;
//! router.add(LinkConfig::new("udpout:192.168.1.10:14550".parse().unwrap())).await?;
//! router.add(LinkConfig::new("tcpin:0.0.0.0:5760".parse().unwrap())).await?;
//! // The links route by themselves from here on.
//! std::future::pending::<()>().await;
//! # Ok(()) }
//! ```

use crate::conn::Endpoint;
use crate::link::SigningFile;
use crate::message::MessageSet;
use crate::parser::{Received, Stats, Unsigned};
use crate::route::{LinkId, Links};
use core::marker::PhantomData;
use core::num::NonZeroU32;
use hub::{lock, Hub, LinkOut};
use std::io;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use std::vec::Vec;
use task::LinkTask;
use tokio::sync::Notify;
use transport::Transport;

pub use hub::Out;
pub use policy::{Forward, Policy};

mod hub;
mod pace;
mod policy;
mod queues;
mod server;
mod task;
mod transport;
mod udp;

/// How often a failed link is opened again.
pub const REOPEN_INTERVAL: Duration = Duration::from_secs(1);

/// Sends queued for one link, each class apart (the owner's, and routed
/// ones), before further ones are dropped (and counted): a slow or
/// stalled link never blocks the router. A routed send is up to
/// [`DATAGRAM_FRAMES_MAX`] bytes of frames.
pub const LINK_QUEUE: usize = 512;

/// The most bytes of frames a link sends at once: routed frames a batch
/// of received bytes (a datagram, a read) sends to the same link leave
/// together (never split, never waited for), under a typical path MTU
/// (1,500 bytes less IP and UDP headers and room for a tunnel). MAVLink
/// receivers (mavlink-router, pymavlink, MAVProxy, MAVSDK) parse every
/// frame of a datagram; at ten frames per datagram in, one send per frame
/// cost the router as many system calls as frames.
pub const DATAGRAM_FRAMES_MAX: usize = 1_400;

/// Room for a whole UDP datagram (65,507 bytes at most), reserved before
/// each receive: a receive into less room cuts the datagram short.
const DATAGRAM_ROOM: usize = crate::conn::RECV_BUFFER_LEN;

/// Room reserved before each read of a stream (TCP, serial).
const STREAM_ROOM: usize = 4096;

/// Bytes parsed between yields to the runtime when they hold no frame.
const PARSE_CHUNK: usize = 1024;

/// Sends a task makes from its queues before it lets other tasks run.
const SENDS_PER_TURN: usize = 64;

/// Clients a `tcpin` link serves at once. A connection beyond evicts the
/// client that has shown the least (nothing accepted, then unauthenticated
/// frames only; on a link with a key an unauthenticated frame shows
/// nothing), the oldest of those; it never evicts a client that has sent
/// an authenticated frame, nor one of the link's peers ([`Out::set_peers`];
/// a peer with port 0 stands for every port of its host). When every
/// client is one of those, the new connection is closed instead
/// ([`LinkCounters::refused_clients`]): idle, garbage or unsigned
/// connections cannot lock a signing peer out, nor run the process out
/// of file descriptors. The clients share the link's replay window: a
/// frame accepted from one is a replay from another.
pub const MAX_CLIENTS: usize = 32;

/// A `tcpin` link whose accept failed waits this long before the next
/// (retried at once, out of file descriptors the link spun at 100 % CPU)...
const ACCEPT_BACKOFF: Duration = Duration::from_millis(50);
/// ...or this long when it evicted a client to make room (time for the
/// client's task to close its socket).
const EVICTED_BACKOFF: Duration = Duration::from_millis(5);

/// How one link is opened and secured.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct LinkConfig {
    /// Where to listen or connect.
    pub endpoint: Endpoint,
    /// What the owner calls the link (mavlink-router's endpoint names):
    /// [`Out::name`] gives it back. `None` (the default): the link is
    /// named by its endpoint.
    pub name: Option<std::string::String>,
    /// Verify incoming signatures and sign outgoing messages with this key.
    pub key: Option<[u8; 32]>,
    /// When `key` is set: whether unsigned frames are returned (marked
    /// unauthenticated) or dropped. Without a key every frame is accepted.
    pub unsigned: Unsigned,
    /// Keep the link's signing state (signer, verifier) in this file.
    pub signing_state: Option<PathBuf>,
    /// TCP links (and `tcpin` clients): let the kernel hold at most 8 KiB
    /// unsent (`TCP_NOTSENT_LOWAT`, Linux and Android), so that what is
    /// routed through the link cannot sit there, megabytes of it, ahead of
    /// the owner's own frames (a protocol's acknowledgement on a link
    /// slower than a flood routed to it). Off by default: a router's
    /// throughput on fast links is better without.
    pub bound_unsent: bool,
    /// Frames routed through the link ([`Out::route`],
    /// [`Out::send_routed`]) go at most this many bytes a second (after a
    /// burst of an eighth of a second's, or one frame), each `tcpin`
    /// client's apart; the owner's own frames are never held back behind
    /// them. Below the link's own rate, a flood routed to the link can
    /// never fill its far end's buffer (a modem's, a serial bridge's): the
    /// owner's next frame waits behind one burst at most; the kernel bound
    /// above cannot reach that buffer. The pace holds back a second of
    /// routed frames at most, a queue per sender (link and source address)
    /// served in turn, dropping the oldest of the longest queue first
    /// ([`LinkCounters::routed_dropped`]): a flood from one sender does not
    /// hold another's frames back. It drops what it holds while the link
    /// is down. `None` (the default): unpaced.
    pub routed_rate: Option<NonZeroU32>,
    /// The link opens only on a loopback address (its target, or the
    /// address it listens on), checked at every (re)open, after the host
    /// name is resolved again: for a link trusted like the key, whose
    /// name must not come to resolve elsewhere. Off by default.
    pub loopback_only: bool,
    /// Serial links: RTS/CTS hardware flow control (mavlink-router's
    /// `FlowControl`), for a radio modem that signals when its buffer is
    /// full. Off by default (what flight controllers' ports use).
    pub flow_control: bool,
}

impl LinkConfig {
    /// An unsigned link to `endpoint`.
    pub fn new(endpoint: Endpoint) -> Self {
        LinkConfig {
            endpoint,
            name: None,
            key: None,
            unsigned: Unsigned::Accept,
            signing_state: None,
            bound_unsent: false,
            routed_rate: None,
            loopback_only: false,
            flow_control: false,
        }
    }

    /// Whether the link is shared by several remote ends (`udpin`,
    /// `udpbcast`, `tcpin`), and so sends to the peers the policy names.
    pub fn is_listening(&self) -> bool {
        matches!(
            self.endpoint,
            Endpoint::UdpIn(_) | Endpoint::UdpBcast(_) | Endpoint::TcpIn(_)
        )
    }
}

/// A frame a link received, as the policy is given it.
#[derive(Debug)]
#[non_exhaustive]
pub struct Inbound<'a, D: MessageSet> {
    /// The link it came in on.
    pub link: LinkId,
    /// The frame, as the link's parser accepted it.
    pub frame: Received<'a, D>,
    /// The sender's address (UDP, TCP clients of a `tcpin` link).
    pub source: Option<SocketAddr>,
}

impl<'a, D: MessageSet> Inbound<'a, D> {
    /// A frame `link` received from `source`: for a policy's tests, and a
    /// program that feeds a policy frames of its own.
    pub fn new(link: LinkId, frame: Received<'a, D>, source: Option<SocketAddr>) -> Self {
        Inbound {
            link,
            frame,
            source,
        }
    }
}

/// What happened to a link, as the policy is told ([`Policy::event`]).
#[derive(Debug)]
#[non_exhaustive]
pub enum RouterEvent {
    /// A link failed; it is opened again every [`REOPEN_INTERVAL`].
    LinkDown {
        /// The link.
        link: LinkId,
        /// Why.
        error: io::Error,
    },
    /// A failed link is open again.
    LinkUp {
        /// The link.
        link: LinkId,
    },
    /// A listening link (`udpin`, `udpbcast`) received from `source` a
    /// datagram holding a frame of a known id whose checksum is good and
    /// whose signature did not verify with the link's key (refused by the
    /// parser, counted in [`Stats::bad_signature`]): a peer with another
    /// key, perhaps, that the policy may tell so (a signed frame of its
    /// own it cannot verify either). One event per such datagram.
    BadSignature {
        /// The link.
        link: LinkId,
        /// Where the datagram came from.
        source: SocketAddr,
        /// The refused frame's sender (system, component), as its
        /// checksum vouches.
        sender: (u8, u8),
    },
}

/// Counters of one link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct LinkCounters {
    /// The owner's frames dropped because the link's queue was full.
    pub dropped_full: u64,
    /// Frames routed to the link ([`Out::route`]) and dropped because
    /// their queue was full: they go after the owner's own, so a link
    /// slower than what is routed to it drops these first.
    pub routed_dropped: u64,
    /// Frames sent: handed to the system whole (a datagram's frames, a
    /// stream's write), or to a `tcpin` client's queue.
    pub frames_out: u64,
    /// Sends that failed (the frame is lost; the link goes on).
    pub send_errors: u64,
    /// `tcpin`: connections that could not be accepted (each pauses
    /// accepting for a moment).
    pub accept_errors: u64,
    /// `tcpin`: connections closed at once because every client was one
    /// the link never evicts (see [`MAX_CLIENTS`]).
    pub refused_clients: u64,
    /// Saves of the signing state file that failed (each tried again a
    /// save interval later; until one succeeds, a restart would start
    /// from the last state saved).
    pub state_save_errors: u64,
    /// The link's parser's counters.
    pub parser: Stats,
}

/// The router: its links, and the policy their frames are judged by.
///
/// ```
/// # use mavframe::{BufferTooSmall, MessageSet, MessageData, MessageMeta};
/// # #[derive(Clone, Debug, PartialEq, Default)] struct Ping(u8);
/// # impl MessageData for Ping {
/// #   const META: MessageMeta = MessageMeta::new(4, "PING", 237, 1, 1, &[]);
/// #   type View<'a> = u8;
/// #   fn parse(p: &[u8]) -> Self { Ping(p.first().copied().unwrap_or(0)) }
/// #   fn emit(&self, p: &mut [u8]) -> Result<usize, BufferTooSmall> {
/// #     *p.first_mut().ok_or(BufferTooSmall { needed: 1, got: 0 })? = self.0; Ok(1) }
/// #   fn view(p: &[u8]) -> u8 { p.first().copied().unwrap_or(0) }
/// # }
/// # struct D;
/// # impl MessageSet for D { type Message = Ping; type View<'a> = u8;
/// #   const MESSAGES: &'static [MessageMeta] = &[Ping::META];
/// #   fn parse(id: u32, p: &[u8]) -> Option<Ping> { (id == 4).then(|| Ping::parse(p)) }
/// #   fn view(id: u32, p: &[u8]) -> Option<u8> { (id == 4).then(|| Ping::view(p)) } }
/// // `D`, `Ping`: a stand-in dialect of one message, declared out of sight
/// // (this crate sits below the generator); use a generated crate's
/// // `MessageSet` and messages, e.g. `fbwag_dialect::Dialect`.
/// use mavframe::router::{Forward, LinkConfig, Router};
/// use std::time::Duration;
/// use tokio::net::UdpSocket;
///
/// let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
/// runtime.block_on(async {
///     // Two ground stations on this machine: here bare UDP sockets.
///     let (a, b) = (UdpSocket::bind("127.0.0.1:0").await?, UdpSocket::bind("127.0.0.1:0").await?);
///     let mut router = Router::<D, _>::new(Forward::new());
///     let to_a = router.add(LinkConfig::new(format!("udpout:{}", a.local_addr()?).parse()?)).await?;
///     router.add(LinkConfig::new(format!("udpout:{}", b.local_addr()?).parse()?)).await?;
///
///     // The router's own message, with the link's sequence numbers (and signer).
///     router.with(|_, out| out.send_message(out.links(), 1, 191, &Ping(7)));
///     let mut buf = [0u8; 280];
///     let (len, from) = a.recv_from(&mut buf).await?;
///     b.recv_from(&mut [0u8; 280]).await?;
///
///     // A's frame back: a broadcast, routed to every other link, B.
///     a.send_to(&buf[..len], from).await?;
///     let (got, _) = b.recv_from(&mut buf).await?;
///     assert_eq!(got, len);
///     // The policy learned where system 1 is.
///     assert!(router.with(|forward, _| forward.table().links_to(1, 191).contains(to_a)));
///     router.shutdown(Duration::from_secs(1)).await;
///     Ok::<(), Box<dyn std::error::Error>>(())
/// })?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Router<D: MessageSet, P> {
    hub: Arc<Mutex<Hub<P>>>,
    /// Each link's task, and what wakes it.
    tasks: Vec<(tokio::task::JoinHandle<()>, Arc<Notify>)>,
    _dialect: PhantomData<fn() -> D>,
}

impl<D: MessageSet + 'static, P: Policy<D>> Router<D, P> {
    /// A router without links, judging frames by `policy`.
    pub fn new(policy: P) -> Self {
        Router {
            hub: Arc::new(Mutex::new(Hub::new(policy))),
            tasks: Vec::new(),
            _dialect: PhantomData,
        }
    }

    /// Opens a link now and runs it in a task of the current tokio
    /// runtime; the policy is told ([`Policy::link_added`]). At most 64
    /// links. Only a damaged signing state file is an error here: a link
    /// that cannot be opened (a host name that does not resolve yet, an
    /// address in use, a server not up yet, a USB radio still enumerating)
    /// starts down, reported as [`RouterEvent::LinkDown`], and is opened
    /// again (its name resolved again) every [`REOPEN_INTERVAL`]: no
    /// link's failure stops the others.
    ///
    /// Links with the same key share one replay window: a signed frame
    /// accepted on one is refused as a replay on the others.
    pub async fn add(&mut self, config: LinkConfig) -> io::Result<LinkId> {
        if self.tasks.len() >= 64 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "a router has at most 64 links",
            ));
        }
        if matches!(config.endpoint, Endpoint::File(_)) {
            return Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "file: endpoints are not routed: a capture cannot take frames",
            ));
        }
        let transport = Transport::open(&config).await;
        let signing =
            SigningFile::open(config.key, config.unsigned, config.signing_state.as_deref())?;
        let wake = Arc::new(Notify::new());
        let id = self.tasks.len() as LinkId;
        {
            let mut hub = lock(&self.hub);
            hub.share_window(&signing);
            let mut link = LinkOut::new(&config, signing.framer(), wake.clone());
            if let Ok(t) = &transport {
                link.set_way(t.way());
            }
            hub.outs.push(link);
            hub.with(|policy, out| Policy::<D>::link_added(policy, id, &config, out));
        }
        let task = LinkTask::<D, P> {
            id,
            config,
            hub: self.hub.clone(),
            signing,
            wake: wake.clone(),
            clients_accepted: 0,
            _dialect: PhantomData,
        };
        self.tasks.push((tokio::spawn(task.run(transport)), wake));
        Ok(id)
    }

    /// Runs `f` on the policy and the links' ways out, under the lock the
    /// link tasks take for each frame: for the owner's timers and its own
    /// messages. What `f` queues goes when it returns.
    pub fn with<R>(&self, f: impl FnOnce(&mut P, &mut Out<'_>) -> R) -> R {
        lock(&self.hub).with(f)
    }

    /// Every link.
    pub fn links(&self) -> Links {
        Links::all(self.tasks.len())
    }

    /// The name of `link` ([`Out::name`]).
    pub fn name(&self, link: LinkId) -> std::string::String {
        self.with(|_, out| out.name(link))
    }

    /// Whether `link`'s transport is open now ([`Out::is_up`]).
    pub fn is_up(&self, link: LinkId) -> bool {
        self.with(|_, out| out.is_up(link))
    }

    /// The counters of `link` ([`Out::counters`]).
    pub fn counters(&self, link: LinkId) -> LinkCounters {
        self.with(|_, out| out.counters(link))
    }

    /// Stops every link after what is queued for it (routed frames
    /// unpaced), saving each link's signing state; waits up to `grace` for
    /// them, then ends the rest. Returns the policy, once no task holds it.
    pub async fn shutdown(mut self, grace: Duration) -> Option<P> {
        let mut tasks = std::mem::take(&mut self.tasks);
        lock(&self.hub).close();
        for (_, wake) in &tasks {
            wake.notify_one();
        }
        let mut done = 0;
        let _ = tokio::time::timeout(grace, async {
            for (task, _) in tasks.iter_mut() {
                let _ = task.await;
                done += 1;
            }
        })
        .await;
        for (task, _) in tasks.into_iter().skip(done) {
            task.abort();
            let _ = task.await;
        }
        let hub = self.hub.clone();
        drop(self);
        let hub = Arc::try_unwrap(hub).ok()?;
        Some(hub.into_inner().unwrap_or_else(|e| e.into_inner()).policy)
    }
}

impl<D: MessageSet, P> Drop for Router<D, P> {
    /// The link tasks send what is queued, save their signing state and
    /// end.
    fn drop(&mut self) {
        lock(&self.hub).close();
        for (_, wake) in &self.tasks {
            wake.notify_one();
        }
    }
}

#[cfg(test)]
mod tests;
