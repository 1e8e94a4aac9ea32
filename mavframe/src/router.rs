//! A MAVLink router on tokio (feature `tokio`): links of every kind an
//! [`Endpoint`] names, one task each, and the routing rules of
//! [`crate::route`] between them.
//!
//! Each link task owns its transport and drives the link's core
//! (`crate::link`): its parser (with the link's key, if any, and that
//! key's replay window, one for every link with the key) and its
//! [`Framer`](crate::Framer) (sequence numbers and signing for messages
//! this node sends on it). It reads frames
//! and hands them to the [`Router`] as [`RouterEvent::Frame`]; it sends what
//! the router queues for it. A link that fails (a TCP peer gone, a serial
//! port unplugged) reports [`RouterEvent::LinkDown`] and is opened again
//! every second; no error of one link stops another.
//!
//! The router does not forward on its own: the owner reads each frame with
//! [`Router::recv`] and calls [`Router::forward`] for the frames it wants
//! routed by the router's table (all of them, for a plain router), or
//! [`Router::route`] to send one where its own policy says, so a node that
//! also speaks on its links (a companion computer) sees every frame first.
//! Frames are forwarded as received, byte for byte: signed frames stay
//! verifiable.
//!
//! Strangers on a link can neither take a peer's traffic nor drop its
//! routes:
//!
//! - `udpin` and `udpbcast` links send to the peers their [`ReplyTo`] rule
//!   names: by default the senders of frames the link's parser accepted
//!   (authenticated ones, on a link with a key), kept in a [`PeerSet`](crate::peers::PeerSet)
//!   (up to eight; a station that keeps speaking is never displaced); under [`ReplyTo::Owner`] only the
//!   addresses the owner gives ([`Router::set_peers`]). A datagram alone
//!   never moves them.
//! - `udpout` sockets are connected to their target: the system drops
//!   datagrams from anyone else.
//! - A `tcpin` link never evicts a client that has sent an authenticated
//!   frame or is a peer of its rule for a new connection (see
//!   [`MAX_CLIENTS`]).
//! - The routing table learns a route as trusted from an authenticated
//!   frame or a link the owner trusts ([`Router::set_trusted`]); a
//!   stranger's route never evicts a trusted one (see [`crate::route`]).
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
//! use mavframe::router::{LinkConfig, Router, RouterEvent};
//!
//! let mut router = Router::<D>::new();
//! router.add(LinkConfig::new("serial:/dev/serial0:460800".parse().unwrap())).await?;
//! router.add(LinkConfig::new("udpout:192.168.1.10:14550".parse().unwrap())).await?;
//! router.add(LinkConfig::new("tcpin:0.0.0.0:5760".parse().unwrap())).await?;
//! while let Some(event) = router.recv().await {
//!     if let RouterEvent::Frame(frame) = event {
//!         router.forward(&frame);
//!     }
//! }
//! # Ok(()) }
//! ```

/// Whom a listening link sends to ([`LinkConfig::reply_to`]); the same
/// rule as `conn`'s listening transports.
pub use crate::conn::ReplyTo;
use crate::conn::{Endpoint, ReceivedBuf};
use crate::link::SigningFile;
use crate::message::{Encode, MessageMeta, MessageSet};
use crate::parser::{Stats, Unsigned};
use crate::route::{LinkId, Links, RoutingTable};
use crate::signing::Verifier;
use core::num::NonZeroU32;
use queues::{count_routed_dropped, sender_key, Command, Queues, RoutedBytes, RoutedFrame};
use std::io;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use std::vec::Vec;
use task::LinkTask;
use tokio::sync::mpsc;
use transport::Transport;

mod datagram;
mod pace;
mod queues;
mod server;
mod task;
mod transport;

/// How often a failed link is opened again.
pub const REOPEN_INTERVAL: Duration = Duration::from_secs(1);

/// Frames queued for one link before further ones are dropped (and
/// counted): a slow or stalled link never blocks the router.
pub const LINK_QUEUE: usize = 512;

/// Frames read but not yet taken by [`Router::recv`]: when the owner falls
/// behind, link tasks wait (and UDP datagrams are dropped by the system)
/// instead of memory growing.
pub const INBOUND_QUEUE: usize = 1024;

/// The most bytes of frames a UDP link puts in one datagram it sends:
/// frames already queued for the same addressees leave together (never
/// split, never waited for), under a typical path MTU (1,500 bytes less
/// IP and UDP headers and room for a tunnel). MAVLink receivers
/// (mavlink-router, pymavlink, MAVProxy, MAVSDK) parse every frame of a
/// datagram; at ten frames per datagram in, one send per frame cost the
/// router as many system calls as frames.
pub const DATAGRAM_FRAMES_MAX: usize = 1_400;

/// Room for a whole UDP datagram (65,507 bytes at most), reserved before
/// each receive: [`LinkTask::deliver`] splits the bytes off the front of
/// the buffer, which takes their room with them, and a receive into less
/// room cuts the datagram short.
const DATAGRAM_ROOM: usize = crate::conn::RECV_BUFFER_LEN;

/// Room reserved before each read of a stream (TCP, serial): without it, a
/// buffer whose room the parsed bytes took is read 64 bytes at a time.
const STREAM_ROOM: usize = 4096;

/// Bytes parsed between yields to the runtime.
const PARSE_CHUNK: usize = 1024;

/// Output a `tcpin` client may have queued before it is dropped.
const CLIENT_QUEUE: usize = 256;

/// Clients a `tcpin` link serves at once. A connection beyond evicts the
/// client that has shown the least (nothing accepted, then unauthenticated
/// frames only; on a link with a key an unauthenticated frame shows
/// nothing), the oldest of those; it never evicts a client that has sent
/// an authenticated frame, nor a peer of the link's rule (the address of
/// [`ReplyTo::Fixed`], any port of its host for port 0; the owner's under
/// [`ReplyTo::Owner`]). When every client is one of those, the new
/// connection is closed instead ([`LinkCounters::refused_clients`]): idle,
/// garbage or unsigned connections cannot lock a signing peer out, nor run
/// the process out of file descriptors. The clients share the link's
/// verifier: a frame accepted from one is a replay from another.
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
    /// [`Router::name`] gives it back. `None` (the default): the link is
    /// named by its endpoint.
    pub name: Option<std::string::String>,
    /// Verify incoming signatures and sign outgoing messages with this key.
    pub key: Option<[u8; 32]>,
    /// When `key` is set: whether unsigned frames are returned (marked
    /// unauthenticated) or dropped. Without a key every frame is accepted.
    pub unsigned: Unsigned,
    /// `udpin`, `udpbcast` and `tcpin`: whom to send to (see [`ReplyTo`];
    /// `udpbcast` broadcasts while the rule names nobody; `tcpin` sends,
    /// under [`ReplyTo::Accepted`], to every client whose frame the link
    /// accepted (an authenticated one, with a key), else to the clients
    /// connected from the addresses the rule names).
    pub reply_to: ReplyTo,
    /// Keep the link's signing state (signer, verifier) in this file.
    pub signing_state: Option<PathBuf>,
    /// TCP links (and `tcpin` clients): let the kernel hold at most 8 KiB
    /// unsent (`TCP_NOTSENT_LOWAT`, Linux and Android), so that what is
    /// routed through the link cannot sit there, megabytes of it, ahead of
    /// the owner's own frames (a protocol's acknowledgement on a link
    /// slower than a flood routed to it). Off by default: a router's
    /// throughput on fast links is better without.
    pub bound_unsent: bool,
    /// Frames routed through the link ([`Router::forward`],
    /// [`Router::send_routed`]) go at most this many bytes a second (after
    /// a burst of an eighth of a second's, or one frame), each `tcpin`
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
    /// An unsigned link to `endpoint`; `udpin` answers the senders of the
    /// frames it accepts ([`ReplyTo::Accepted`]).
    pub fn new(endpoint: Endpoint) -> Self {
        LinkConfig {
            endpoint,
            name: None,
            key: None,
            unsigned: Unsigned::Accept,
            reply_to: ReplyTo::Accepted,
            signing_state: None,
            bound_unsent: false,
            routed_rate: None,
            loopback_only: false,
            flow_control: false,
        }
    }
}

/// A frame a link received.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct Inbound<D: MessageSet> {
    /// The link it came in on.
    pub link: LinkId,
    /// The frame, as the link's parser accepted it.
    pub frame: ReceivedBuf<D>,
    /// The sender's address (UDP, TCP clients of a `tcpin` link).
    pub source: Option<SocketAddr>,
}

/// What [`Router::recv`] reports.
// Frames are nearly every event: boxing them would allocate per frame.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
#[non_exhaustive]
pub enum RouterEvent<D: MessageSet> {
    /// A frame.
    Frame(Inbound<D>),
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
    /// key, perhaps, that the owner may tell so (a signed frame of its own
    /// it cannot verify either). One event per such datagram.
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

struct LinkHandle {
    endpoint: Endpoint,
    name: Option<std::string::String>,
    commands: mpsc::Sender<Command>,
    /// Frames routed through the link ([`Router::forward`]): see [`Queues`].
    routed: mpsc::Sender<RoutedFrame>,
    /// [`LinkConfig::routed_rate`] is set: routed frames need their
    /// sender's key.
    paced: bool,
    counters: Arc<Mutex<LinkCounters>>,
    /// The link's transport is open (set by its task).
    up: Arc<AtomicBool>,
    task: tokio::task::JoinHandle<()>,
}

/// Counters of one link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct LinkCounters {
    /// Frames queued for the link and dropped because its queue was full.
    pub dropped_full: u64,
    /// Frames routed to the link ([`Router::forward`]) and dropped because
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

/// The router: its links and the routing table.
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
/// use mavframe::router::{LinkConfig, Router, RouterEvent};
/// use std::time::Duration;
/// use tokio::net::UdpSocket;
///
/// let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
/// runtime.block_on(async {
///     // A ground station on this machine: here a bare UDP socket.
///     let station = UdpSocket::bind("127.0.0.1:0").await?;
///     let mut router = Router::<D>::new();
///     let to_station = format!("udpout:{}", station.local_addr()?);
///     let link = router.add(LinkConfig::new(to_station.parse()?)).await?;
///
///     // The router's own message, with the link's sequence numbers (and signer).
///     router.send_message(router.links(), 1, 191, &Ping(7));
///     let mut buf = [0u8; 280];
///     let (len, from) = station.recv_from(&mut buf).await?;
///
///     // The station sends a frame back: the owner sees it first...
///     station.send_to(&buf[..len], from).await?;
///     let inbound = loop {
///         match router.recv().await {
///             Some(RouterEvent::Frame(inbound)) => break inbound,
///             Some(_) => continue, // a link down or up again
///             None => unreachable!("links are reopened, never gone"),
///         }
///     };
///     assert_eq!((inbound.link, inbound.frame.message()), (link, Some(Ping(7))));
///     // ...and routes it: to every other link of a broadcast (none here).
///     assert!(router.forward(&inbound).is_empty());
///     router.shutdown(Duration::from_secs(1)).await;
///     Ok::<(), Box<dyn std::error::Error>>(())
/// })?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Router<D: MessageSet> {
    links: Vec<LinkHandle>,
    /// One replay window per key, shared by every link verifying with it.
    windows: Vec<([u8; 32], ReplayWindow)>,
    events: mpsc::Receiver<RouterEvent<D>>,
    events_tx: mpsc::Sender<RouterEvent<D>>,
    table: RoutingTable,
    /// Links whose frames the table learns as trusted
    /// ([`set_trusted`](Router::set_trusted)).
    trusted: Links,
}

impl<D: MessageSet + 'static> Default for Router<D> {
    fn default() -> Self {
        Self::new()
    }
}

impl<D: MessageSet + 'static> Router<D> {
    /// A router without links.
    pub fn new() -> Self {
        let (events_tx, events) = mpsc::channel(INBOUND_QUEUE);
        Router {
            links: Vec::new(),
            windows: Vec::new(),
            events,
            events_tx,
            table: RoutingTable::new(),
            trusted: Links::NONE,
        }
    }

    /// Opens a link now and runs it in a task of the current tokio
    /// runtime. At most 64 links. Only a damaged signing state file is an
    /// error here: a link that cannot be opened (a host name that does not
    /// resolve yet, an address in use, a server not up yet, a USB radio
    /// still enumerating) starts down, reported as
    /// [`RouterEvent::LinkDown`], and is opened again (its name resolved
    /// again) every [`REOPEN_INTERVAL`]: no link's failure stops the
    /// others.
    ///
    /// Links with the same key share one replay window: a signed frame
    /// accepted on one is refused as a replay on the others.
    pub async fn add(&mut self, config: LinkConfig) -> io::Result<LinkId> {
        if self.links.len() >= 64 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "a router has at most 64 links",
            ));
        }
        let id = self.links.len() as LinkId;
        let endpoint = config.endpoint.clone();
        let name = config.name.clone();
        if matches!(endpoint, Endpoint::File(_)) {
            return Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "file: endpoints are not routed: a capture cannot take frames",
            ));
        }
        let transport = Transport::open(&config).await;
        let up = Arc::new(AtomicBool::new(transport.is_ok()));
        let signing =
            SigningFile::open(config.key, config.unsigned, config.signing_state.as_deref())?;
        let window = self.window(&signing);
        let (commands, own) = mpsc::channel(LINK_QUEUE);
        let (routed, routed_rx) = mpsc::channel(LINK_QUEUE);
        let counters = Arc::new(Mutex::new(LinkCounters::default()));
        let paced = config.routed_rate.is_some();
        // A `tcpin` link paces each client's connection, not its fan-out.
        let rate = match config.endpoint {
            Endpoint::TcpIn(_) => None,
            _ => config.routed_rate,
        };
        let task = LinkTask {
            id,
            config,
            events: self.events_tx.clone(),
            commands: Queues::new(own, routed_rx, rate, counters.clone()),
            counters: counters.clone(),
            signing,
            window,
            up: up.clone(),
            clients_accepted: 0,
        };
        let task = tokio::spawn(task.run(transport));
        self.links.push(LinkHandle {
            endpoint,
            name,
            commands,
            routed,
            paced,
            counters,
            up,
            task,
        });
        Ok(id)
    }

    /// The replay window of the key `signing` verifies with, shared with
    /// the links added before with that key and raised to what `signing`
    /// saved: a frame accepted on one link is a replay on every other, as
    /// MAVLink keys replay state by (link id, system, component) of the
    /// signature wherever a frame arrives (with a window per link, a
    /// listener on one link replayed there what another link had
    /// accepted). `None` without a key.
    fn window(&mut self, signing: &SigningFile) -> Option<ReplayWindow> {
        let (key, saved) = signing.verifier()?;
        let window = self.window_of(key, || saved.clone());
        lock(&window).restore(saved.newest_timestamp(), &saved.floors(), saved.streams());
        Some(window)
    }

    /// The replay window of `key`, made by `new` for its first link.
    fn window_of(&mut self, key: [u8; 32], new: impl FnOnce() -> Verifier) -> ReplayWindow {
        if let Some((_, window)) = self.windows.iter().find(|(k, _)| *k == key) {
            return window.clone();
        }
        let window = Arc::new(Mutex::new(new()));
        self.windows.push((key, window.clone()));
        window
    }

    /// Signs and verifies `link`'s frames with `key` from now on (`None`:
    /// neither), in the key's replay window, its timestamps from the
    /// clock: what a flight controller does on SETUP_SIGNING. A `tcpin`
    /// link's clients are let go: they connect again under the key.
    pub fn set_key(&mut self, link: LinkId, key: Option<[u8; 32]>) {
        let window = key.map(|k| self.window_of(k, || Verifier::starting_now(k)));
        self.command(link, Command::Key(key, window));
    }

    /// Stops every link after what is queued for it, saving each link's
    /// signing state; waits up to `grace` for them.
    pub async fn shutdown(self, grace: Duration) {
        let Router { links, events, .. } = self;
        drop(events);
        let tasks: Vec<_> = links
            .into_iter()
            .map(|l| {
                drop((l.commands, l.routed));
                l.task
            })
            .collect();
        let _ = tokio::time::timeout(grace, async {
            for t in tasks {
                let _ = t.await;
            }
        })
        .await;
    }

    /// Every link.
    pub fn links(&self) -> Links {
        Links::all(self.links.len())
    }

    /// The endpoint of `link`.
    pub fn endpoint(&self, link: LinkId) -> Option<&Endpoint> {
        self.links.get(link as usize).map(|l| &l.endpoint)
    }

    /// The name of `link`: the one it was given
    /// ([`LinkConfig::name`]), else its endpoint's connection string.
    pub fn name(&self, link: LinkId) -> std::string::String {
        use std::string::ToString;
        self.links
            .get(link as usize)
            .map(|l| l.name.clone().unwrap_or_else(|| l.endpoint.to_string()))
            .unwrap_or_default()
    }

    /// Whether `link`'s transport is open now (a link that failed is
    /// down until it is open again: [`RouterEvent::LinkDown`],
    /// [`RouterEvent::LinkUp`]).
    pub fn is_up(&self, link: LinkId) -> bool {
        self.links
            .get(link as usize)
            .is_some_and(|l| l.up.load(Ordering::Relaxed))
    }

    /// The counters of `link`.
    pub fn counters(&self, link: LinkId) -> LinkCounters {
        self.links
            .get(link as usize)
            .map(|l| *l.counters.lock().unwrap_or_else(|e| e.into_inner()))
            .unwrap_or_default()
    }

    /// The next event; `None` only if every link task ended (never while
    /// the router lives: links are reopened).
    pub async fn recv(&mut self) -> Option<RouterEvent<D>> {
        self.events.recv().await
    }

    /// The routing table (read only).
    pub fn table(&self) -> &RoutingTable {
        &self.table
    }

    /// Learns `inbound`'s sender (trusted if the frame is authenticated
    /// or its link trusted: [`set_trusted`](Self::set_trusted)) and sends
    /// its bytes, untouched, to every link the routing rules name (see
    /// [`crate::route`]); returns them. On each link, routed frames go
    /// after the owner's own ([`send_raw`], [`send_message`]), and are the
    /// ones dropped when the link cannot keep up
    /// ([`LinkCounters::routed_dropped`]).
    ///
    /// [`send_raw`]: Router::send_raw
    /// [`send_message`]: Router::send_message
    pub fn forward(&mut self, inbound: &Inbound<D>) -> Links {
        let frame = inbound.frame.frame();
        let trusted = self.is_trusted(inbound);
        let to = self.table.route(
            inbound.link,
            &frame,
            inbound.frame.meta(),
            self.links(),
            trusted,
        );
        self.route(inbound, to)
    }

    /// Sends `inbound`'s bytes, untouched, on `links` (those that exist),
    /// as [`forward`](Self::forward) does but where the owner's policy
    /// says, without the router's table (which learns nothing); returns
    /// the links. Routed traffic: after the owner's own frames, dropped
    /// first, and paced per sender on a link with
    /// [`LinkConfig::routed_rate`].
    pub fn route(&self, inbound: &Inbound<D>, links: Links) -> Links {
        self.route_as(inbound, links, None)
    }

    /// [`route`](Self::route), except that each link frames it again,
    /// signed with the link's key (when it has one) and sequence numbers
    /// kept: for a link the owner trusts like the key (a local ground tool
    /// that cannot sign). A MAVLink 1 frame goes as MAVLink 2; a frame of
    /// an id the dialect does not know (whose checksum cannot be made)
    /// goes nowhere.
    pub fn route_signed(&self, inbound: &Inbound<D>, links: Links) -> Links {
        match inbound.frame.meta() {
            Some(meta) => self.route_as(inbound, links, Some(meta)),
            None => Links::NONE,
        }
    }

    fn route_as(
        &self,
        inbound: &Inbound<D>,
        links: Links,
        sign: Option<&'static MessageMeta>,
    ) -> Links {
        let to = links.intersection(self.links());
        // (A hash per frame only when a link of `to` needs it.)
        let paced = to
            .iter()
            .any(|l| self.links.get(l as usize).is_some_and(|l| l.paced));
        let from = if paced {
            sender_key(inbound.link, inbound.source)
        } else {
            0
        };
        self.send_routed_from(from, to, inbound.frame.as_bytes(), sign);
        to
    }

    /// Frames from `link` teach the table trusted routes (see
    /// [`crate::route`]) whether authenticated or not: a link the owner
    /// trusts (a serial port to the autopilot, say). No link is, at first.
    pub fn set_trusted(&mut self, link: LinkId, trusted: bool) {
        self.trusted = match trusted {
            true => self.trusted.union(Links::only(link)),
            false => self.trusted.without(link),
        };
    }

    /// Whether the table learns `inbound`'s sender as trusted.
    fn is_trusted(&self, inbound: &Inbound<D>) -> bool {
        inbound.frame.is_authenticated() || self.trusted.contains(inbound.link)
    }

    /// Sends `bytes` on each of `links` as routed traffic, as
    /// [`forward`](Self::forward) does: after the owner's own frames, and
    /// dropped first. For frames the owner passes on for someone else (a
    /// local program's telemetry for the ground stations, say), which must
    /// not hold its own protocol frames back.
    pub fn send_routed(&self, links: Links, bytes: &[u8]) {
        self.send_routed_from(0, links, bytes, None);
    }

    /// [`send_routed`](Self::send_routed), from the sender of key `from`.
    fn send_routed_from(
        &self,
        from: u32,
        links: Links,
        bytes: &[u8],
        sign: Option<&'static MessageMeta>,
    ) {
        for link in links.iter() {
            let Some(l) = self.links.get(link as usize) else {
                continue;
            };
            let bytes = RoutedBytes {
                bytes: bytes.into(),
                sign,
            };
            if l.routed.try_send((from, bytes)).is_err() {
                count_routed_dropped(&l.counters, 1);
            }
        }
    }

    /// Learns that `inbound`'s sender is reachable through its link
    /// without forwarding anything (for frames the owner keeps to itself),
    /// trusted as by [`forward`](Self::forward).
    pub fn learn(&mut self, inbound: &Inbound<D>) {
        let h = inbound.frame.header();
        let trusted = self.is_trusted(inbound);
        self.table.learn(inbound.link, h.sysid, h.compid, trusted);
    }

    /// Sends frame bytes, untouched, on `links`.
    pub fn send_raw(&self, links: Links, bytes: &[u8]) {
        for link in links.iter() {
            self.command(link, Command::Raw(bytes.into()));
        }
    }

    /// Frames `message` as `sysid`/`compid` on each of `links` (with each
    /// link's sequence numbers and signer) and sends it. Any message: a
    /// generated one, a dialect's `Message` enum, a `&dyn Encode`.
    pub fn send_message(
        &self,
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
        &self,
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
        for link in links.iter() {
            self.command(
                link,
                Command::Message {
                    sysid,
                    compid,
                    meta,
                    payload: payload[..len].into(),
                    to,
                },
            );
        }
    }

    /// A link under [`ReplyTo::Owner`] (`udpin`, `udpbcast`, `tcpin`)
    /// sends to `peers` from now on, and only to them (the first
    /// [`MAX_PEERS`](crate::peers::MAX_PEERS); port 0 ignored); a `tcpin`
    /// link never evicts their clients. Call it when the set changes, not
    /// per frame: each call is a command queued to the link.
    pub fn set_peers(&self, link: LinkId, peers: &[SocketAddr]) {
        self.command(link, Command::Peers(peers.into()));
    }

    /// [`set_peers`](Self::set_peers) of one address.
    pub fn pin_peer(&self, link: LinkId, peer: SocketAddr) {
        self.set_peers(link, &[peer]);
    }

    fn command(&self, link: LinkId, command: Command) {
        let Some(l) = self.links.get(link as usize) else {
            return;
        };
        if l.commands.try_send(command).is_err() {
            let mut c = l.counters.lock().unwrap_or_else(|e| e.into_inner());
            c.dropped_full = c.dropped_full.saturating_add(1);
        }
    }
}

/// The replay state of one key, shared by its links (see
/// [`Router::add`]); held only while a frame is parsed or a state saved,
/// never across an await.
pub(crate) type ReplayWindow = Arc<Mutex<Verifier>>;

/// `window`, locked (a poisoned lock still holds a whole verifier: each
/// change to it is one call).
fn lock(window: &Mutex<Verifier>) -> std::sync::MutexGuard<'_, Verifier> {
    window
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[cfg(test)]
mod tests;
