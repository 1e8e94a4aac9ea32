//! A MAVLink router on tokio (feature `tokio`): links of every kind an
//! [`Endpoint`] names, one task each, and the routing rules of
//! [`crate::route`] between them.
//!
//! Each link task owns its transport and drives the link's core
//! (`crate::link`): its parser (with the link's key, if any: signatures are
//! verified per link) and its [`Framer`](crate::Framer) (sequence numbers
//! and signing for messages this node sends on it). It reads frames
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

use crate::conn::{AnyTransport, Endpoint, ReceivedBuf, ReplyTo};
use crate::link::{Inbox, LinkCore, Peers, SigningFile};
use crate::message::{Encode, MessageMeta, MessageSet};
use crate::parser::{Stats, Unsigned};
use crate::route::{LinkId, Links, RoutingTable};
use crate::signing::Verifier;
use std::boxed::Box;
use std::io;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use std::vec;
use std::vec::Vec;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::mpsc;

mod datagram;
mod pace;
use core::num::NonZeroU32;
use datagram::Datagram;
use pace::Backlog;

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
pub struct LinkConfig {
    /// Where to listen or connect.
    pub endpoint: Endpoint,
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
}

impl LinkConfig {
    /// An unsigned link to `endpoint`; `udpin` answers the senders of the
    /// frames it accepts ([`ReplyTo::Accepted`]).
    pub fn new(endpoint: Endpoint) -> Self {
        LinkConfig {
            endpoint,
            key: None,
            unsigned: Unsigned::Accept,
            reply_to: ReplyTo::Accepted,
            signing_state: None,
            bound_unsent: false,
            routed_rate: None,
        }
    }
}

/// A frame a link received.
#[derive(Debug, Clone)]
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
}

/// What the router tells a link task.
enum Command {
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
    /// [`ReplyTo::Owner`]: send to these addresses ([`Router::set_peers`]).
    Peers(Box<[SocketAddr]>),
    /// Send this frame, routed from another link ([`Queues`]), from the
    /// sender of this key ([`sender_key`]).
    Routed(u32, RoutedBytes),
}

/// A routed frame's bytes, and the message's row when the link signs it on
/// the way ([`Router::route_signed`]).
#[derive(Debug, Clone)]
struct RoutedBytes {
    bytes: Box<[u8]>,
    sign: Option<&'static MessageMeta>,
}

impl AsRef<[u8]> for RoutedBytes {
    fn as_ref(&self) -> &[u8] {
        &self.bytes
    }
}

struct LinkHandle {
    endpoint: Endpoint,
    commands: mpsc::Sender<Command>,
    /// Frames routed through the link ([`Router::forward`]): see [`Queues`].
    routed: mpsc::Sender<RoutedFrame>,
    /// [`LinkConfig::routed_rate`] is set: routed frames need their
    /// sender's key.
    paced: bool,
    counters: Arc<Mutex<LinkCounters>>,
    task: tokio::task::JoinHandle<()>,
}

/// A routed frame in a link's queue: the key of its sender
/// ([`sender_key`]) and its bytes.
type RoutedFrame = (u32, RoutedBytes);

/// The key of a routed frame's sender: the link it came in on and the
/// address it came from (a paced link queues senders apart: [`Backlog`]).
/// 0 is the owner's (frames it routes itself, [`Router::send_routed`]).
fn sender_key(link: LinkId, source: Option<SocketAddr>) -> u32 {
    use core::hash::{Hash, Hasher};
    let mut h = std::collections::hash_map::DefaultHasher::new();
    (link, source).hash(&mut h);
    (h.finish() as u32).max(1)
}

/// A link's queues, as its task reads them: the owner's frames and
/// commands, and the frames routed through the link, which go only when
/// none of the owner's wait, and no faster than the link's
/// [`LinkConfig::routed_rate`] (the [`pace`] module). Routed traffic (a
/// ground station's flood of another link) never holds the owner's
/// protocol frames back behind it: on a link slower than that flood, one
/// queue let it crowd them out, and the companion's acknowledgement never
/// reached the FC.
struct Queues {
    own: mpsc::Receiver<Command>,
    routed: mpsc::Receiver<RoutedFrame>,
    /// The owner's queue is closed (the router is gone): what was routed
    /// goes out as it is, unpaced, then the link ends.
    own_closed: bool,
    /// The routed queue's sender is gone (the router with it).
    routed_closed: bool,
    /// With [`LinkConfig::routed_rate`]: the routed frames the pace holds
    /// back.
    backlog: Option<Backlog<RoutedBytes>>,
    /// The link's counters: frames the backlog drops.
    counters: Arc<Mutex<LinkCounters>>,
    /// A routed frame taken to share a datagram that had no room left for
    /// it ([`Queues::queued_routed`]): the next to go.
    held: Option<RoutedFrame>,
}

impl Queues {
    fn new(
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
    async fn recv(&mut self) -> Option<Command> {
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
    async fn drop_next(&mut self) -> bool {
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
    fn queued_routed(&mut self) -> Option<RoutedFrame> {
        if self.backlog.is_some() || self.own_closed || !self.own.is_empty() {
            return None;
        }
        self.routed.try_recv().ok()
    }

    /// A frame [`queued_routed`](Self::queued_routed) gave that did not
    /// fit: the next [`recv`](Self::recv) returns it.
    fn hold(&mut self, frame: RoutedFrame) {
        self.held = Some(frame);
    }
}

/// Adds `n` routed frames dropped to a link's counters.
fn count_routed_dropped(counters: &Mutex<LinkCounters>, n: u64) {
    if n > 0 {
        let mut c = counters.lock().unwrap_or_else(PoisonError::into_inner);
        c.routed_dropped = c.routed_dropped.saturating_add(n);
    }
}

/// What [`Queues::paced`] decided.
enum Paced {
    /// Return this.
    Go(Option<Command>),
    /// Wait for a queue, or this long for the pace.
    Wait(Option<Duration>),
}

/// Sleeps `wait` (a branch disabled when `None`).
async fn sleep_for(wait: Option<Duration>) {
    tokio::time::sleep(wait.unwrap_or_default()).await;
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
/// #   const META: MessageMeta = MessageMeta { id: 4, name: "PING", crc_extra: 237, min_len: 1,
/// #     max_len: 1, target_system_offset: None, target_component_offset: None, fields: &[] };
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
            events,
            events_tx,
            table: RoutingTable::new(),
            trusted: Links::NONE,
        }
    }

    /// Opens a link now and runs it in a task of the current tokio
    /// runtime. At most 64 links. Errors surface here (address in use, a
    /// damaged signing state file), but for a TCP client or a serial port:
    /// their far end may come later than this program (a server not up
    /// yet, a USB radio still enumerating), so such a link starts down,
    /// reported as [`RouterEvent::LinkDown`], and is opened again every
    /// [`REOPEN_INTERVAL`].
    pub async fn add(&mut self, config: LinkConfig) -> io::Result<LinkId> {
        if self.links.len() >= 64 {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "a router has at most 64 links",
            ));
        }
        let id = self.links.len() as LinkId;
        let endpoint = config.endpoint.clone();
        let transport = match Transport::open(&config).await {
            Err(e) if !matches!(endpoint, Endpoint::Tcp(_) | Endpoint::Serial { .. }) => {
                return Err(e)
            }
            opened => opened,
        };
        let signing =
            SigningFile::open(config.key, config.unsigned, config.signing_state.as_deref())?;
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
            clients_accepted: 0,
        };
        let task = tokio::spawn(task.run(transport));
        self.links.push(LinkHandle {
            endpoint,
            commands,
            routed,
            paced,
            counters,
            task,
        });
        Ok(id)
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

/// A link's transport, open.
enum Transport {
    Udp {
        socket: Datagram,
        /// `udpout`'s target, or `udpbcast`'s broadcast address (where
        /// frames go while the reply rule names nobody).
        to: Option<SocketAddr>,
        /// `udpin` and `udpbcast`: frames go to the peers of the link's
        /// rule.
        replies: bool,
    },
    Stream(Box<dyn AsyncStream>),
    Server(TcpListener),
}

/// An async byte stream (TCP client, serial port).
trait AsyncStream: AsyncRead + AsyncWrite + Send + Unpin {}
impl<T: AsyncRead + AsyncWrite + Send + Unpin> AsyncStream for T {}

impl Transport {
    /// Opens `config`'s endpoint: resolved and opened as the blocking
    /// transports are ([`conn::open`](crate::conn::open): `udpout`
    /// connected to its target, `udpbcast` with `SO_BROADCAST`), on a
    /// blocking thread, then handed to tokio.
    async fn open(config: &LinkConfig) -> io::Result<Transport> {
        let endpoint = config.endpoint.clone();
        let opened = match &endpoint {
            Endpoint::File(_) => {
                return Err(io::Error::new(
                    io::ErrorKind::Unsupported,
                    "file: endpoints are not routed: a capture cannot take frames",
                ))
            }
            Endpoint::Serial { path, baud } => {
                use tokio_serial::SerialPortBuilderExt;
                let port = tokio_serial::new(path, *baud).open_native_async()?;
                return Ok(Transport::Stream(Box::new(port)));
            }
            // (tokio's listener: SO_REUSEADDR, as the system's is not.)
            Endpoint::TcpIn(addr) => {
                let addr = addr.clone();
                let addrs = blocking(move || Ok(addr.resolve()?)).await?;
                return Ok(Transport::Server(
                    TcpListener::bind(addrs.as_slice()).await?,
                ));
            }
            _ => blocking(move || crate::conn::open(&endpoint)).await?,
        };
        let udp = |socket: &std::net::UdpSocket, to, replies| {
            let socket = Datagram::new(socket.try_clone()?)?;
            io::Result::Ok(Transport::Udp {
                socket,
                to,
                replies,
            })
        };
        match opened {
            AnyTransport::UdpIn(t) => udp(t.get_ref(), None, true),
            AnyTransport::UdpOut(t) => udp(t.get_ref(), Some(t.target()), false),
            AnyTransport::UdpBcast(t) => udp(t.get_ref(), Some(t.target()), true),
            AnyTransport::Tcp(t) => {
                let stream = t.get_ref().try_clone()?;
                stream.set_nonblocking(true)?;
                let stream = TcpStream::from_std(stream)?;
                if config.bound_unsent {
                    bound_unsent(&stream);
                }
                Ok(Transport::Stream(Box::new(stream)))
            }
            _ => Err(io::ErrorKind::Unsupported.into()),
        }
    }
}

/// Runs `f` (a name lookup, a connect) on tokio's blocking threads.
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> io::Result<T> + Send + 'static,
) -> io::Result<T> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(io::Error::other)?
}

/// Sends `bytes` on a connected socket (`udpout`). A send that reports an
/// earlier datagram's ICMP error (Linux does on connected sockets, once
/// per error) sent nothing: tried once more, so a target that is not up
/// yet costs no frame once it is.
async fn send_connected(socket: &Datagram, bytes: &[u8]) -> io::Result<()> {
    match socket.send(bytes).await {
        Err(e) if crate::conn::is_refused(&e) => socket.send(bytes).await.map(drop),
        other => other.map(drop),
    }
}

/// Bytes a TCP link with [`LinkConfig::bound_unsent`] lets the kernel hold
/// unsent (`TCP_NOTSENT_LOWAT`, Linux and Android; elsewhere the system
/// decides). Frames routed through a link go after its owner's own in the
/// link's queues ([`Queues`]), but the kernel's send buffer grows to
/// megabytes by itself: on a link slower than a flood routed to it, the
/// owner's frames then waited seconds behind the flood's. This bounds only
/// what is not sent yet, not what is in flight. (What the far end has
/// received and not yet passed on, a modem's or a relay's buffer, is out of
/// the sender's reach.)
#[cfg(any(target_os = "linux", target_os = "android"))]
const TCP_UNSENT_MAX: u32 = 8 * 1024;

/// See [`TCP_UNSENT_MAX`]. (Best effort: without it the link works as
/// before, its owner's frames first in its queues.)
fn bound_unsent(stream: &TcpStream) {
    #[cfg(any(target_os = "linux", target_os = "android"))]
    let _ = socket2::SockRef::from(stream).set_tcp_notsent_lowat(TCP_UNSENT_MAX);
    #[cfg(not(any(target_os = "linux", target_os = "android")))]
    let _ = stream;
}

/// One link's task.
struct LinkTask<D: MessageSet> {
    id: LinkId,
    config: LinkConfig,
    events: mpsc::Sender<RouterEvent<D>>,
    commands: Queues,
    counters: Arc<Mutex<LinkCounters>>,
    signing: SigningFile,
    /// `tcpin`: clients accepted so far (each client's order).
    clients_accepted: u64,
}

/// A link's core, as a task drives it.
type Core<D> = LinkCore<D, Box<[u8]>>;

/// The bytes `command` sends, a message framed by `core` (`None`: none).
fn outgoing<'a, D: MessageSet>(core: &'a mut Core<D>, command: &'a Command) -> Option<&'a [u8]> {
    match command {
        Command::Peers(_) => None,
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
/// `core` where the owner asked ([`Router::route_signed`]).
fn routed_bytes<'a, D: MessageSet>(
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
    fn inbox(&self, room: usize) -> Inbox<D, Box<[u8]>> {
        let mut inbox = Inbox::new(self.signing.parser(), vec![0u8; room].into_boxed_slice());
        inbox.set_chunk(PARSE_CHUNK);
        inbox
    }

    /// Runs the link until the router is dropped, reopening it when it
    /// fails; `first` is its opening in [`Router::add`].
    async fn run(mut self, first: io::Result<Transport>) {
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
            self.save(&core, None, true);
            match ended {
                Ended::RouterGone => return,
                Ended::Failed(error) => {
                    let down = RouterEvent::LinkDown {
                        link: self.id,
                        error,
                    };
                    if self.events.send(down).await.is_err() {
                        return;
                    }
                    // Signing goes on from where the failed transport was.
                    let verifier = core.inbox.parser.verifier();
                    self.signing.go_on_from(&core.framer, verifier);
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
    /// `verifier` (`None`: the core's); failures are counted.
    fn save(&mut self, core: &Core<D>, verifier: Option<&Verifier>, last: bool) {
        let verifier = verifier.or(core.inbox.parser.verifier());
        if !self.signing.save(&core.framer, verifier, last) {
            self.count(|c| c.state_save_errors = c.state_save_errors.saturating_add(1));
        }
    }

    fn count(&self, f: impl FnOnce(&mut LinkCounters)) {
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
            let frame = match core.next() {
                Some(frame) => frame,
                None if core.inbox.held() > 0 => {
                    tokio::task::yield_now().await;
                    continue;
                }
                None if eof => match core.inbox.take_at_eof(|r| ReceivedBuf::from(&r)) {
                    Some(frame) => frame,
                    None => break,
                },
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
        loop {
            tokio::select! {
                // A failed receive (an ICMP error on some systems) says
                // nothing about the next one: it is skipped.
                r = socket.recv_from(core.inbox.space()) => if let Ok((n, from)) = r {
                    core.inbox.received(n, Some(from), true);
                    match self.deliver(core, false).await {
                        Err(()) => return Ended::RouterGone,
                        // Only a frame accepted makes its sender a peer.
                        Ok(vouched) => if vouched && replies {
                            peers.heard(Some(from));
                        }
                    }
                    self.save(core, None, false);
                },
                c = self.commands.recv() => {
                    let Some(c) = c else { return Ended::RouterGone };
                    if let Command::Peers(addrs) = &c {
                        owner_gives(&mut peers, addrs);
                        continue;
                    }
                    let to = c.to();
                    let Some(bytes) = outgoing(core, &c) else { continue };
                    // Frames queued behind, for the same addressees, join it.
                    let more = to.is_none().then(|| self.commands.queued_routed()).flatten();
                    let bytes = match more {
                        Some(next) => {
                            datagram.clear();
                            datagram.extend_from_slice(bytes);
                            self.coalesce(next, &mut datagram);
                            &datagram[..]
                        }
                        None => bytes,
                    };
                    let sent = match (replies, to) {
                        (true, Some(to)) => socket.send_to(bytes, to).await.map(drop),
                        (true, None) => send_each(&socket, peers.targets(target), bytes).await,
                        (false, _) => send_connected(&socket, bytes).await,
                    };
                    if sent.is_err() {
                        self.count(|c| c.send_errors = c.send_errors.saturating_add(1));
                    }
                    self.save(core, None, false);
                }
            }
        }
    }

    /// Appends `next` and the routed frames queued behind it to
    /// `datagram` while they fit in [`DATAGRAM_FRAMES_MAX`] bytes; the
    /// first that does not (or that the link signs: signing it twice would
    /// spend a signing timestamp) goes next, in a datagram of its own.
    fn coalesce(&mut self, next: RoutedFrame, datagram: &mut Vec<u8>) {
        let mut next = Some(next);
        while let Some((from, routed)) = next.take() {
            if routed.sign.is_some() || datagram.len() + routed.bytes.len() > DATAGRAM_FRAMES_MAX {
                self.commands.hold((from, routed));
                return;
            }
            datagram.extend_from_slice(&routed.bytes);
            next = self.commands.queued_routed();
        }
    }

    async fn stream(&mut self, mut stream: Box<dyn AsyncStream>, core: &mut Core<D>) -> Ended {
        loop {
            tokio::select! {
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
                        self.save(core, None, false);
                    }
                    Err(e) => return Ended::Failed(e),
                },
                c = self.commands.recv() => {
                    let Some(c) = c else { return Ended::RouterGone };
                    let Some(bytes) = outgoing(core, &c) else { continue };
                    if let Err(e) = stream.write_all(bytes).await {
                        self.count(|c| c.send_errors = c.send_errors.saturating_add(1));
                        return Ended::Failed(e);
                    }
                    self.save(core, None, false);
                }
            }
        }
    }

    /// `tcpin`: every client in a task of its own (with its own parser),
    /// fed the link's output through a bounded queue: a client that falls
    /// [`CLIENT_QUEUE`] frames behind is dropped, the others go on. At most
    /// [`MAX_CLIENTS`] at once; the link's [`ReplyTo`] rule says which get
    /// the output.
    async fn server(&mut self, listener: TcpListener, core: &mut Core<D>) -> Ended {
        // One verifier for all clients, swapped into each one's parser while
        // it parses: a frame accepted from one client is a replay from any
        // other (with one each, a capture replayed on a new connection was
        // authenticated again, and could move the owner's peer).
        let shared = core
            .inbox
            .parser
            .verifier_mut()
            .map(|v| Arc::new(Mutex::new(v.clone())));
        let lock =
            |v: &Arc<Mutex<Verifier>>| v.lock().unwrap_or_else(PoisonError::into_inner).clone();
        let mut clients: Vec<Client> = Vec::new();
        let mut peers = Peers::new(self.config.reply_to);
        let mut paused_until = None::<tokio::time::Instant>;
        loop {
            let resume = paused_until.unwrap_or_else(tokio::time::Instant::now);
            tokio::select! {
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
                    let Some(c) = c else {
                        // The link's last save (in `run`) is of the shared
                        // state, not of the one the link opened with.
                        if let (Some(v), Some(own)) = (&shared, core.inbox.parser.verifier_mut()) {
                            *own = lock(v);
                        }
                        return Ended::RouterGone;
                    };
                    match &c {
                        Command::Peers(addrs) => owner_gives(&mut peers, addrs),
                        // After the owner's own, in each client's queue
                        // for them. A client behind on those loses frames
                        // (counted), not its connection: routed bursts
                        // come faster than any one client takes them, and
                        // the client may be the protocol peer.
                        Command::Routed(from, routed) => {
                            let verifier = shared.as_ref().map(lock);
                            core.framer.adopt_from(verifier.as_ref());
                            let Some(bytes) = routed_bytes(core, routed) else { continue };
                            let b = RoutedBytes { bytes: bytes.into(), sign: None };
                            let mut full = 0u64;
                            clients.retain(|c| {
                                !c.gets(&peers)
                                    || match c.routed.try_send((*from, b.clone())) {
                                        Ok(()) => true,
                                        Err(mpsc::error::TrySendError::Full(_)) => {
                                            full += 1;
                                            true
                                        }
                                        Err(mpsc::error::TrySendError::Closed(_)) => false,
                                    }
                            });
                            count_routed_dropped(&self.counters, full);
                        }
                        Command::Raw(_) | Command::Message { .. } => {
                            let verifier = shared.as_ref().map(lock);
                            core.framer.adopt_from(verifier.as_ref());
                            let to = c.to();
                            let Some(bytes) = outgoing(core, &c) else { continue };
                            let bytes: Box<[u8]> = bytes.into();
                            let gets = |c: &Client| to.map_or_else(|| c.gets(&peers), |to| c.addr == to);
                            // Full or closed: the client is dropped.
                            clients.retain(|c| !gets(c) || c.output.try_send(Command::Raw(bytes.clone())).is_ok());
                            self.save(core, verifier.as_ref(), false);
                        }
                    }
                }
            }
        }
    }
}

impl Command {
    /// `Message`'s one addressee, if given.
    fn to(&self) -> Option<SocketAddr> {
        match self {
            Command::Message { to, .. } => *to,
            _ => None,
        }
    }
}

/// [`Router::set_peers`]: the peers of a link under [`ReplyTo::Owner`].
fn owner_gives(peers: &mut Peers, addrs: &[SocketAddr]) {
    if peers.rule == ReplyTo::Owner {
        peers.given(addrs);
    }
}

/// Sends `bytes` to each of `to`: the first error, once each was tried.
async fn send_each(
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

impl<D: MessageSet + 'static> LinkTask<D> {
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
        shared: &Option<Arc<Mutex<Verifier>>>,
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
struct Client {
    addr: SocketAddr,
    output: mpsc::Sender<Command>,
    /// Frames routed to the link, sent after `output`'s ([`Queues`]).
    routed: mpsc::Sender<RoutedFrame>,
    /// What it has sent: [`SHOWN_NOTHING`], [`SHOWN_FRAMES`] or
    /// [`SHOWN_AUTHENTICATED`] (set by its task).
    standing: Arc<AtomicU8>,
    /// Accepted as the link's `order`th client.
    order: u64,
}

/// No frame accepted from the client yet.
const SHOWN_NOTHING: u8 = 0;
/// Frames accepted, none authenticated.
const SHOWN_FRAMES: u8 = 1;
/// An authenticated frame.
const SHOWN_AUTHENTICATED: u8 = 2;

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
fn evict(clients: &mut Vec<Client>, peers: &Peers) -> bool {
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
fn is_out_of_descriptors(e: &io::Error) -> bool {
    // EMFILE and ENFILE, the same numbers on Linux, the BSDs and macOS.
    cfg!(unix) && matches!(e.raw_os_error(), Some(23 | 24))
}

/// How a link's transport ended.
enum Ended {
    /// The router was dropped: the task ends.
    RouterGone,
    /// The transport failed: reopen it.
    Failed(io::Error),
}

/// What a `tcpin` client's task needs of its link.
struct ClientTask {
    addr: SocketAddr,
    link: LinkId,
    /// The link's verifier, when it has a key (see [`LinkTask::server`]).
    shared: Option<Arc<Mutex<Verifier>>>,
    /// What the client has shown ([`Client::standing`]).
    standing: Arc<AtomicU8>,
}

/// A client that takes longer than this to accept a frame is dropped (its
/// task would otherwise wait on it for good, with its socket, after the
/// link let it go).
#[cfg(not(test))]
const CLIENT_WRITE_TIMEOUT: Duration = Duration::from_secs(2);
/// (The same rule, quicker to test.)
#[cfg(test)]
const CLIENT_WRITE_TIMEOUT: Duration = Duration::from_millis(300);

async fn serve_client<D: MessageSet>(
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
                    take_shared(&mut inbox, task.shared.as_deref(), &mut frames);
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

/// The frames `inbox` holds, parsed with the link's `shared` verifier
/// state (if any) in the client's parser, into `frames` (one vector for
/// the client's life, not one per read).
fn take_shared<D: MessageSet>(
    inbox: &mut Inbox<D, Box<[u8]>>,
    shared: Option<&Mutex<Verifier>>,
    frames: &mut Vec<ReceivedBuf<D>>,
) {
    let mut state = shared.map(|m| m.lock().unwrap_or_else(PoisonError::into_inner));
    let mut exchange = |inbox: &mut Inbox<D, Box<[u8]>>| {
        if let (Some(state), Some(own)) = (state.as_deref_mut(), inbox.parser.verifier_mut()) {
            core::mem::swap(state, own);
        }
    };
    exchange(inbox);
    loop {
        match inbox.next() {
            Some(frame) => frames.push(frame),
            None if inbox.held() > 0 => {}
            None => break,
        }
    }
    exchange(inbox);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conn::test_dialect::{Ping, TestDialect};
    use crate::frame::{FrameBuf, Header, Version};
    use crate::peers::MAX_PEERS;
    use crate::Parser;
    use std::format;
    use std::net::UdpSocket as StdUdp;
    use std::vec::Vec;
    use tokio::net::UdpSocket;

    /// Datagrams of garbage (65,507 and 20 bytes) before each frame: no
    /// frame is cut short. (A receive into the room the earlier datagrams'
    /// bytes left lost one 63-byte frame in 1,040 on a plain link, and
    /// every frame after a large datagram.)
    #[tokio::test]
    async fn no_datagram_is_cut_short_after_a_large_one() {
        let probe = StdUdp::bind("127.0.0.1:0").unwrap();
        let port = probe.local_addr().unwrap().port();
        drop(probe);
        let mut router = Router::<TestDialect>::new();
        let url = format!("udpin:127.0.0.1:{port}");
        router
            .add(LinkConfig::new(url.parse().unwrap()))
            .await
            .unwrap();
        let sender = StdUdp::bind("127.0.0.1:0").unwrap();
        let to = ("127.0.0.1", port);
        let garbage = std::vec![0u8; 65_507];
        for value in 0..20u32 {
            let h = Header {
                seq: value as u8,
                sysid: 1,
                compid: 1,
            };
            let frame = FrameBuf::encode(Version::V2, h, &Ping { value }, None).unwrap();
            // 29 bytes of room left, then 9: less than the frame's 16.
            sender.send_to(&garbage, to).unwrap();
            sender.send_to(&garbage[..20], to).unwrap();
            sender.send_to(&frame, to).unwrap();
            let event = tokio::time::timeout(Duration::from_secs(2), router.recv()).await;
            let Ok(Some(RouterEvent::Frame(inbound))) = event else {
                panic!("frame {value} lost");
            };
            assert_eq!(inbound.frame.as_bytes(), &frame[..], "frame {value}");
        }
    }

    async fn tcpin(reply_to: ReplyTo) -> (Router<TestDialect>, LinkId, SocketAddr) {
        let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let mut router = Router::<TestDialect>::new();
        let mut config = LinkConfig::new(format!("tcpin:{addr}").parse().unwrap());
        config.reply_to = reply_to;
        let link = router.add(config).await.unwrap();
        (router, link, addr)
    }

    fn ping(value: u32) -> FrameBuf {
        let h = Header {
            seq: value as u8,
            sysid: 1,
            compid: 1,
        };
        FrameBuf::encode(Version::V2, h, &Ping { value }, None).unwrap()
    }

    /// Reads what arrives within `ms`: `None` at the end of the stream.
    async fn read_for(stream: &mut TcpStream, ms: u64) -> Option<Vec<u8>> {
        let mut got = Vec::new();
        let mut buf = [0u8; 256];
        let until = tokio::time::Instant::now() + Duration::from_millis(ms);
        loop {
            match tokio::time::timeout_at(until, stream.read(&mut buf)).await {
                Err(_) => return Some(got),
                Ok(Ok(0)) | Ok(Err(_)) => return None,
                Ok(Ok(n)) => got.extend_from_slice(&buf[..n]),
            }
        }
    }

    /// A TCP client link whose server is not up yet, and a serial port
    /// that is not there, start down rather than fail the router; the TCP
    /// link opens once its server listens. A listening link that cannot
    /// bind still fails at once (a mistake, not a peer that comes later).
    #[tokio::test]
    async fn a_tcp_link_whose_server_comes_later_opens_then() {
        let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let mut router = Router::<TestDialect>::new();
        let tcp = LinkConfig::new(format!("tcp:{addr}").parse().unwrap());
        let link = router.add(tcp).await.unwrap();
        let serial = LinkConfig::new("serial:/dev/no-such-port:57600".parse().unwrap());
        let absent = router.add(serial).await.unwrap();
        let mut down = Vec::new();
        for _ in 0..2 {
            match tokio::time::timeout(Duration::from_secs(2), router.recv()).await {
                Ok(Some(RouterEvent::LinkDown { link, .. })) => down.push(link),
                _ => panic!("no LinkDown"),
            }
        }
        down.sort_unstable();
        assert_eq!(down, [link, absent]);
        let bound = StdUdp::bind("127.0.0.1:0").unwrap();
        let taken = LinkConfig::new(
            format!("udpin:{}", bound.local_addr().unwrap())
                .parse()
                .unwrap(),
        );
        assert!(
            router.add(taken).await.is_err(),
            "a port in use is an error"
        );

        let server = tokio::net::TcpListener::bind(addr).await.unwrap();
        let (mut stream, _) = tokio::time::timeout(Duration::from_secs(3), server.accept())
            .await
            .expect("the link connects within its reopening interval")
            .unwrap();
        let up = tokio::time::timeout(Duration::from_secs(1), router.recv()).await;
        assert!(matches!(up, Ok(Some(RouterEvent::LinkUp { link: l })) if l == link));
        router.send_raw(Links::only(link), &ping(7));
        assert_eq!(read_for(&mut stream, 300).await.unwrap(), &ping(7)[..]);
    }

    /// `tcpin` under [`ReplyTo::Owner`]: nothing goes out until the owner
    /// names a client, then only to that client (before, every client got
    /// everything: a stranger that connected received the companion's
    /// control).
    #[tokio::test]
    async fn tcpin_sends_only_to_the_owners_peer() {
        let (mut router, link, addr) = tcpin(ReplyTo::Owner).await;
        let mut peer = TcpStream::connect(addr).await.unwrap();
        let mut stranger = TcpStream::connect(addr).await.unwrap();
        peer.write_all(&ping(1)).await.unwrap();
        let Some(RouterEvent::Frame(inbound)) = router.recv().await else {
            panic!("no frame");
        };
        assert_eq!(inbound.source, Some(peer.local_addr().unwrap()));
        router.send_raw(Links::only(link), &ping(2));
        assert_eq!(
            read_for(&mut peer, 200).await,
            Some(Vec::new()),
            "no peer named yet"
        );
        router.pin_peer(link, peer.local_addr().unwrap());
        router.send_raw(Links::only(link), &ping(3));
        assert_eq!(read_for(&mut peer, 300).await, Some(ping(3).to_vec()));
        assert_eq!(read_for(&mut stranger, 100).await, Some(Vec::new()));
    }

    /// A link sends its owner's frames before routed ones queued earlier,
    /// each class in order; once the router is gone, what was routed is
    /// still sent, then the link ends.
    #[tokio::test]
    async fn a_link_sends_the_owners_frames_before_routed_ones() {
        let (own_tx, own) = mpsc::channel(8);
        let (routed_tx, routed) = mpsc::channel(8);
        let mut queues = Queues::new(own, routed, None, Arc::default());
        for b in [1u8, 2, 3] {
            routed_tx
                .try_send((1, unsigned(Box::from(&[b][..]))))
                .unwrap();
        }
        for b in [7u8, 8] {
            own_tx.try_send(Command::Raw(Box::from(&[b][..]))).unwrap();
        }
        async fn next(queues: &mut Queues) -> Option<(bool, u8)> {
            match queues.recv().await {
                Some(Command::Raw(b)) => Some((true, b[0])),
                Some(Command::Routed(_, b)) => Some((false, b.bytes[0])),
                Some(_) => panic!("not a frame"),
                None => None,
            }
        }
        let q = &mut queues;
        assert_eq!(next(q).await, Some((true, 7)));
        assert_eq!(next(q).await, Some((true, 8)));
        assert_eq!(next(q).await, Some((false, 1)));
        own_tx
            .try_send(Command::Raw(Box::from(&[9u8][..])))
            .unwrap();
        assert_eq!(next(q).await, Some((true, 9)));
        drop((own_tx, routed_tx));
        assert_eq!(next(q).await, Some((false, 2)));
        assert_eq!(next(q).await, Some((false, 3)));
        assert_eq!(next(q).await, None);
    }

    /// A paced link's queues at 2,240 bytes a second (a burst and a
    /// backlog of 280 bytes: one longest frame, then one every 125 ms), with
    /// the senders of its two queues and its counters.
    struct Paced {
        own: mpsc::Sender<Command>,
        routed: mpsc::Sender<RoutedFrame>,
        queues: Queues,
        counters: Arc<Mutex<LinkCounters>>,
    }

    fn paced() -> Paced {
        let (own, own_rx) = mpsc::channel(8);
        let (routed, routed_rx) = mpsc::channel(LINK_QUEUE);
        let counters = Arc::new(Mutex::new(LinkCounters::default()));
        let queues = Queues::new(own_rx, routed_rx, NonZeroU32::new(2_240), counters.clone());
        Paced {
            own,
            routed,
            queues,
            counters,
        }
    }

    /// `len` bytes of `b`, routed from sender `from`.
    fn unsigned(bytes: Box<[u8]>) -> RoutedBytes {
        RoutedBytes { bytes, sign: None }
    }

    fn routed_frame(from: u32, b: u8, len: usize) -> RoutedFrame {
        (from, unsigned(std::vec![b; len].into_boxed_slice()))
    }

    /// A frame of the owner's: one byte, `b`.
    fn own_frame(b: u8) -> Command {
        Command::Raw(Box::from(&[b][..]))
    }

    /// A paced link sends routed frames at its rate after a burst, and its
    /// owner's frames at once while a routed one waits; once the router is
    /// gone, what was routed goes unpaced.
    #[tokio::test(start_paused = true)]
    async fn a_paced_link_holds_routed_frames_never_its_own() {
        use tokio::time::{sleep, Instant};
        let Paced {
            own: own_tx,
            routed: routed_tx,
            mut queues,
            ..
        } = paced();
        for b in 0..5u8 {
            routed_tx.try_send(routed_frame(1, b, 280)).unwrap();
        }
        let t0 = Instant::now();
        async fn next(queues: &mut Queues, t0: Instant) -> (u64, bool, u8) {
            let c = queues.recv().await;
            let ms = t0.elapsed().as_millis() as u64;
            match c {
                Some(Command::Raw(b)) => (ms, true, b[0]),
                Some(Command::Routed(_, b)) => (ms, false, b.bytes[0]),
                _ => panic!("not a frame"),
            }
        }
        let q = &mut queues;
        assert_eq!(next(q, t0).await, (0, false, 0));
        let sender = tokio::spawn(async move {
            sleep(Duration::from_millis(30)).await;
            own_tx.send(own_frame(9)).await.unwrap();
            own_tx
        });
        assert_eq!(
            next(q, t0).await,
            (30, true, 9),
            "the owner's frame at once"
        );
        assert_eq!(next(q, t0).await, (125, false, 1));
        assert_eq!(next(q, t0).await, (250, false, 2));
        drop((sender.await.unwrap(), routed_tx));
        assert_eq!(
            next(q, t0).await,
            (250, false, 3),
            "unpaced once the router is gone"
        );
        assert_eq!(next(q, t0).await, (250, false, 4));
        assert!(q.recv().await.is_none());
    }

    /// Routed frames beyond a second of the pace are dropped, the oldest
    /// first, and counted: a frame routed into a flood goes within about a
    /// second. The owner's frame queued while a routed one waits for the
    /// pace goes first; a link that is down drops what the pace held.
    #[tokio::test(start_paused = true)]
    async fn a_paced_link_keeps_a_second_of_routed_frames_the_newest() {
        use tokio::time::Instant;
        let Paced {
            own: own_tx,
            routed: routed_tx,
            queues: mut q,
            counters,
        } = paced();
        let frame = |b: u8| routed_frame(1, b, 280);
        for b in 0..100u8 {
            routed_tx.try_send(frame(b)).unwrap();
        }
        let t0 = Instant::now();
        let mut got: Vec<(u128, u8)> = Vec::new();
        while got.last().is_none_or(|g| g.1 != 200) && got.len() < 20 {
            match q.recv().await {
                Some(Command::Routed(_, b)) => got.push((t0.elapsed().as_millis(), b.bytes[0])),
                _ => panic!("not a routed frame"),
            }
            if got.len() == 2 {
                // Queued behind a flood: goes within a second.
                routed_tx.try_send(frame(200)).unwrap();
                own_tx.try_send(own_frame(9)).unwrap();
                assert!(
                    matches!(q.recv().await, Some(Command::Raw(_))),
                    "the owner's first"
                );
            }
        }
        let last = got
            .iter()
            .find(|g| g.1 == 200)
            .expect("the late frame went");
        assert!(last.0 <= 1_250, "{got:?}");
        assert_eq!(
            got.len(),
            10,
            "the first, eight newest of the flood, the late one: {got:?}"
        );
        let dropped = counters.lock().unwrap().routed_dropped;
        assert!(dropped >= 90, "{dropped} dropped, {got:?}");
        // Down: what the pace held is dropped.
        routed_tx.try_send(frame(201)).unwrap();
        routed_tx.try_send(frame(202)).unwrap();
        assert!(matches!(q.recv().await, Some(Command::Routed(..))));
        let before = counters.lock().unwrap().routed_dropped;
        routed_tx.try_send(frame(203)).unwrap();
        assert!(q.drop_next().await);
        assert!(q.backlog.as_ref().is_some_and(Backlog::is_empty));
        let held = counters.lock().unwrap().routed_dropped - before;
        assert_eq!(held, 1, "202, held by the pace, dropped and counted");
        drop((own_tx, routed_tx));
        assert!(!q.drop_next().await);
    }

    /// A routed frame the pace has let go still waits for the owner's frame
    /// queued meanwhile; a `recv` cancelled while the pace holds a frame
    /// keeps it.
    #[tokio::test(start_paused = true)]
    async fn a_paced_link_lets_the_owners_frame_pass_a_released_one() {
        use tokio::time::{sleep, timeout};
        let Paced {
            own: own_tx,
            routed: routed_tx,
            queues: mut q,
            ..
        } = paced();
        for b in [0u8, 1] {
            routed_tx.try_send(routed_frame(1, b, 280)).unwrap();
        }
        assert!(matches!(q.recv().await, Some(Command::Routed(_, b)) if b.bytes[0] == 0));
        // Frame 1 taken into the backlog, held 125 ms: cancelled at 10.
        assert!(timeout(Duration::from_millis(10), q.recv()).await.is_err());
        sleep(Duration::from_millis(200)).await;
        own_tx.try_send(own_frame(9)).unwrap();
        assert!(
            matches!(q.recv().await, Some(Command::Raw(_))),
            "the owner's first"
        );
        assert!(
            matches!(q.recv().await, Some(Command::Routed(_, b)) if b.bytes[0] == 1),
            "then 1, kept"
        );
    }

    /// A paced link serves the senders of routed frames in turn: a frame
    /// from a quiet sender goes at its turn, not behind a flood from
    /// another, whose oldest frames are the ones dropped.
    #[tokio::test(start_paused = true)]
    async fn a_paced_link_serves_a_quiet_sender_before_a_flood() {
        let Paced {
            own: _own_tx,
            routed: routed_tx,
            queues: mut q,
            counters,
        } = paced();
        for b in 0..200u8 {
            routed_tx.try_send(routed_frame(7, b, 280)).unwrap();
        }
        routed_tx.try_send(routed_frame(9, 255, 40)).unwrap();
        let mut got = Vec::new();
        while !got.contains(&255) {
            match q.recv().await {
                Some(Command::Routed(_, b)) => got.push(b.bytes[0]),
                _ => panic!("not a routed frame"),
            }
            assert!(
                got.len() < 5,
                "the quiet sender waits behind the flood: {got:?}"
            );
        }
        assert!(counters.lock().unwrap().routed_dropped >= 190);
    }

    /// A client that stops reading is dropped once a write to it has
    /// waited [`CLIENT_WRITE_TIMEOUT`], its queue not yet full: its task
    /// ends and its socket closes. (Its task waited on it for good, with
    /// the socket, and wrote on when it read again.)
    #[tokio::test]
    async fn tcpin_drops_a_client_that_stops_reading() {
        let (mut router, link, addr) = tcpin(ReplyTo::Accepted).await;
        let socket = tokio::net::TcpSocket::new_v4().unwrap();
        socket.set_recv_buffer_size(4096).unwrap();
        let mut sleeper = socket.connect(addr).await.unwrap();
        sleeper.write_all(&ping(1)).await.unwrap();
        let _ = router.recv().await;
        // 13 MB in 200 writes (fewer than the client's queue holds): far
        // more than the sockets' buffers, so the writes stall.
        let chunk = std::vec![0u8; 64 * 1024];
        let chunks = 200;
        for _ in 0..chunks {
            router.send_raw(Links::only(link), &chunk);
        }
        tokio::time::sleep(CLIENT_WRITE_TIMEOUT * 3).await;
        // Reading again: what the buffers held, then the end of the stream.
        let (mut got, mut buf) = (0usize, std::vec![0u8; 64 * 1024]);
        let until = tokio::time::Instant::now() + Duration::from_secs(5);
        let ended = loop {
            match tokio::time::timeout_at(until, sleeper.read(&mut buf)).await {
                Err(_) => break false,
                Ok(Ok(0)) | Ok(Err(_)) => break true,
                Ok(Ok(n)) => got += n,
            }
        };
        assert!(ended, "the connection is still open after {got} bytes");
        assert!(got < chunks * chunk.len(), "all {got} bytes were sent");
    }

    /// More connections than [`MAX_CLIENTS`]: idle ones are evicted, oldest
    /// first; the owner's peer and one that sent frames stay.
    #[tokio::test]
    async fn tcpin_evicts_idle_clients_never_the_owners_peer() {
        let (mut router, link, addr) = tcpin(ReplyTo::Owner).await;
        let mut peer = TcpStream::connect(addr).await.unwrap();
        peer.write_all(&ping(1)).await.unwrap();
        let _ = router.recv().await;
        router.pin_peer(link, peer.local_addr().unwrap());
        let mut idle = Vec::new();
        for _ in 0..MAX_CLIENTS - 2 {
            idle.push(TcpStream::connect(addr).await.unwrap());
        }
        let mut talker = TcpStream::connect(addr).await.unwrap();
        talker.write_all(&ping(2)).await.unwrap();
        let _ = router.recv().await;
        // The link is full: each of these evicts the oldest idle client.
        let mut late = Vec::new();
        for _ in 0..5 {
            late.push(TcpStream::connect(addr).await.unwrap());
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        for (i, stream) in idle.iter_mut().enumerate() {
            let open = read_for(stream, 20).await.is_some();
            assert_eq!(open, i >= 5, "idle client {i}");
        }
        assert!(read_for(&mut talker, 20).await.is_some(), "the talker");
        router.send_raw(Links::only(link), &ping(3));
        assert_eq!(read_for(&mut peer, 300).await, Some(ping(3).to_vec()));
    }

    /// A signed frame accepted from one `tcpin` client is a replay from
    /// any other: the clients share the link's verifier. (Each had its own,
    /// so a capture replayed on a new connection was authenticated again
    /// and, under the daemons' peer rule, moved the pinned peer to the
    /// attacker.)
    #[tokio::test]
    async fn tcpin_clients_share_one_replay_window() {
        use crate::signing::{timestamp_now, Signer};
        let key = [5u8; 32];
        let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let mut router = Router::<TestDialect>::new();
        let mut config = LinkConfig::new(format!("tcpin:{addr}").parse().unwrap());
        config.key = Some(key);
        router.add(config).await.unwrap();
        let mut signer = Signer::new(key, 1, timestamp_now());
        let h = |seq| Header {
            seq,
            sysid: 1,
            compid: 1,
        };
        let first =
            FrameBuf::encode(Version::V2, h(1), &Ping { value: 1 }, Some(&mut signer)).unwrap();
        let second =
            FrameBuf::encode(Version::V2, h(2), &Ping { value: 2 }, Some(&mut signer)).unwrap();
        let mut peer = TcpStream::connect(addr).await.unwrap();
        peer.write_all(&first).await.unwrap();
        peer.write_all(&second).await.unwrap();
        for want in [&first, &second] {
            let Some(RouterEvent::Frame(f)) = router.recv().await else {
                panic!("no frame");
            };
            assert!(f.frame.is_authenticated());
            assert_eq!(f.frame.as_bytes(), &want[..]);
        }
        let mut replayer = TcpStream::connect(addr).await.unwrap();
        replayer.write_all(&first).await.unwrap();
        replayer.write_all(&ping(9)).await.unwrap();
        // Unsigned frames are accepted on this link, unauthenticated: so is
        // the replay (the key's frame, stale), never authenticated.
        for want in [&first[..], &ping(9)[..]] {
            let Some(RouterEvent::Frame(f)) = router.recv().await else {
                panic!("no frame");
            };
            assert!(!f.frame.is_authenticated(), "a replay was authenticated");
            assert_eq!(f.frame.as_bytes(), want);
        }
    }

    /// Under `--peer IP:0` (any port of that host), the client from that
    /// host is the peer and is not evicted while others can be: here it
    /// connects first and stays idle, then more strangers than the link
    /// serves come from another loopback address. (The eviction matched the
    /// peer's address exactly, port 0 included, so it matched no client.)
    #[tokio::test]
    async fn tcpin_never_evicts_the_peer_of_an_any_port_rule() {
        let any_port: SocketAddr = "127.0.0.1:0".parse().unwrap();
        let (router, link, addr) = tcpin(ReplyTo::Fixed(any_port)).await;
        let mut peer = TcpStream::connect(addr).await.unwrap();
        let mut strangers = Vec::new();
        for _ in 0..MAX_CLIENTS + 4 {
            let socket = tokio::net::TcpSocket::new_v4().unwrap();
            socket.bind("127.0.0.2:0".parse().unwrap()).unwrap();
            strangers.push(socket.connect(addr).await.unwrap());
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
        router.send_raw(Links::only(link), &ping(3));
        assert_eq!(read_for(&mut peer, 300).await, Some(ping(3).to_vec()));
        let closed = {
            let mut n = 0;
            for s in &mut strangers {
                n += usize::from(read_for(s, 10).await.is_none());
            }
            n
        };
        assert_eq!(closed, 5, "the oldest strangers evicted");
    }

    /// A `tcpin` link with a state file saves, when it ends, the verifier
    /// its clients share, not the one it opened with (which had seen no
    /// frame: a restart would have accepted every capture of the run).
    #[tokio::test]
    async fn tcpin_saves_the_shared_verifier_at_the_end() {
        use crate::signing::state::StateFile;
        use crate::signing::{timestamp_now, Signer};
        let key = [6u8; 32];
        let dir = std::env::temp_dir().join(format!("mavframe-tcpin-state-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("link.state");
        let _ = std::fs::remove_file(&path);
        let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let mut router = Router::<TestDialect>::new();
        let mut config = LinkConfig::new(format!("tcpin:{addr}").parse().unwrap());
        (config.key, config.signing_state) = (Some(key), Some(path.clone()));
        router.add(config).await.unwrap();
        let mut signer = Signer::new(key, 3, timestamp_now());
        let h = Header {
            seq: 0,
            sysid: 7,
            compid: 8,
        };
        let frame =
            FrameBuf::encode(Version::V2, h, &Ping { value: 1 }, Some(&mut signer)).unwrap();
        let mut peer = TcpStream::connect(addr).await.unwrap();
        peer.write_all(&frame).await.unwrap();
        let Some(RouterEvent::Frame(f)) = router.recv().await else {
            panic!("no frame");
        };
        assert!(f.frame.is_authenticated());
        router.shutdown(Duration::from_secs(2)).await;
        let (file, _) = StateFile::open(&path).unwrap();
        let streams = &file.state().streams;
        assert!(
            streams
                .iter()
                .any(|s| (s.link_id, s.sysid, s.compid) == (3, 7, 8)),
            "the stream the client's frame came on is saved: {streams:?}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A `udpin` link on 127.0.0.1 with `reply_to` (`None`: the default
    /// rule), and its address.
    async fn udpin(reply_to: Option<ReplyTo>) -> (Router<TestDialect>, LinkId, SocketAddr) {
        let probe = StdUdp::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let mut router = Router::<TestDialect>::new();
        let mut config = LinkConfig::new(format!("udpin:{addr}").parse().unwrap());
        if let Some(rule) = reply_to {
            config.reply_to = rule;
        }
        let link = router.add(config).await.unwrap();
        (router, link, addr)
    }

    /// A router with one link, `udpout` to `target`.
    async fn udpout_to(target: &UdpSocket) -> (Router<TestDialect>, LinkId) {
        let mut router = Router::<TestDialect>::new();
        let url = format!("udpout:{}", target.local_addr().unwrap());
        let link = router
            .add(LinkConfig::new(url.parse().unwrap()))
            .await
            .unwrap();
        (router, link)
    }

    /// A UDP socket on 127.0.0.1 (a station, a stranger).
    async fn udp_socket() -> UdpSocket {
        UdpSocket::bind("127.0.0.1:0").await.unwrap()
    }

    /// The datagram `socket` receives within `ms`, if any.
    async fn datagram_for(socket: &UdpSocket, ms: u64) -> Option<Vec<u8>> {
        let mut buf = [0u8; 512];
        let got = tokio::time::timeout(Duration::from_millis(ms), socket.recv(&mut buf)).await;
        got.ok().and_then(Result::ok).map(|n| buf[..n].to_vec())
    }

    /// The next frame the router reports, within 2 s.
    async fn next_frame(router: &mut Router<TestDialect>) -> Inbound<TestDialect> {
        match tokio::time::timeout(Duration::from_secs(2), router.recv()).await {
            Ok(Some(RouterEvent::Frame(f))) => f,
            _ => panic!("no frame"),
        }
    }

    /// Waits (2 s at most) until `link`'s parser has dropped `bytes` bytes.
    async fn dropped_bytes(router: &Router<TestDialect>, link: LinkId, bytes: u64) {
        let until = tokio::time::Instant::now() + Duration::from_secs(2);
        while router.counters(link).parser.bytes_dropped < bytes {
            assert!(tokio::time::Instant::now() < until, "bytes not received");
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
    }

    /// A stranger's 1-byte datagrams, every 10 ms, never move a `udpin`
    /// link's replies away from the station whose frame it accepted.
    /// (Answering whoever sent last, a datagram without a frame took the
    /// station's traffic.)
    #[tokio::test]
    async fn udpin_is_not_redirected_by_datagrams_without_a_frame() {
        let (mut router, link, addr) = udpin(None).await;
        let (station, stranger) = (udp_socket().await, udp_socket().await);
        station.send_to(&ping(1), addr).await.unwrap();
        next_frame(&mut router).await;
        for i in 0..20u64 {
            stranger.send_to(&[0u8], addr).await.unwrap();
            tokio::time::sleep(Duration::from_millis(10)).await;
            dropped_bytes(&router, link, i + 1).await;
            router.send_raw(Links::only(link), &ping(2));
            assert_eq!(
                datagram_for(&station, 500).await,
                Some(ping(2).to_vec()),
                "datagram {i}"
            );
        }
        assert_eq!(
            datagram_for(&stranger, 50).await,
            None,
            "the stranger got traffic"
        );
    }

    /// 200 strangers, each with a valid frame, arrive while a station keeps
    /// speaking: the station receives every frame sent meanwhile, and at
    /// most [`MAX_PEERS`] − 1 strangers (the free slots) get copies.
    #[tokio::test]
    async fn a_speaking_station_keeps_its_traffic_among_200_strangers() {
        let (mut router, link, addr) = udpin(None).await;
        let station = udp_socket().await;
        let mut strangers = Vec::new();
        for i in 0..200u32 {
            if i % 20 == 0 {
                station.send_to(&ping(1000 + i), addr).await.unwrap();
                next_frame(&mut router).await;
            }
            let s = udp_socket().await;
            s.send_to(&ping(i), addr).await.unwrap();
            next_frame(&mut router).await;
            strangers.push(s);
            if i % 20 == 19 {
                router.send_raw(Links::only(link), &ping(5000 + i));
                let got = datagram_for(&station, 500).await;
                assert_eq!(got, Some(ping(5000 + i).to_vec()), "after stranger {i}");
            }
        }
        let mut served = 0;
        for s in &strangers {
            served += usize::from(datagram_for(s, 1).await.is_some());
        }
        assert!(served < MAX_PEERS, "{served} strangers got traffic");
    }

    /// Frames routed to a `udpout` link faster than it sends leave
    /// together: as many whole frames per datagram as fit in
    /// [`DATAGRAM_FRAMES_MAX`] bytes, every one intact and in order.
    #[tokio::test]
    async fn udpout_sends_frames_queued_together_in_one_datagram() {
        let target = udp_socket().await;
        let (router, link) = udpout_to(&target).await;
        // On one thread the link's task runs only once all are queued.
        let frames: Vec<FrameBuf> = (0..200).map(|i| ping(0x0101_0100 + i)).collect();
        for f in &frames {
            router.send_routed(Links::only(link), f);
        }
        let per_datagram = DATAGRAM_FRAMES_MAX / frames[0].len();
        let sent: Vec<u8> = frames.iter().flat_map(|f| f.iter().copied()).collect();
        let mut got = Vec::new();
        let mut datagrams = Vec::new();
        let mut buf = [0u8; 2048];
        while got.len() < sent.len() {
            let n = tokio::time::timeout(Duration::from_secs(2), target.recv(&mut buf))
                .await
                .expect("every frame arrives")
                .unwrap();
            got.extend_from_slice(&buf[..n]);
            datagrams.push(n);
        }
        assert_eq!(got, sent, "every frame intact, in order");
        let full = per_datagram * frames[0].len();
        let rest = sent.len() - 2 * full;
        assert_eq!(
            datagrams,
            [full, full, rest],
            "whole frames, up to the limit"
        );
    }

    /// A `udpout` link's socket is connected to its target: a frame sent to
    /// its local port from a third socket never reaches the router, the
    /// target's does.
    #[tokio::test]
    async fn udpout_ignores_third_parties() {
        let target = udp_socket().await;
        let (mut router, link) = udpout_to(&target).await;
        router.send_raw(Links::only(link), &ping(1));
        let mut buf = [0u8; 64];
        let (_, local) = tokio::time::timeout(Duration::from_secs(2), target.recv_from(&mut buf))
            .await
            .unwrap()
            .unwrap();
        let local = SocketAddr::from(([127, 0, 0, 1], local.port()));
        let third = udp_socket().await;
        third.send_to(&ping(66), local).await.unwrap();
        target.send_to(&ping(7), local).await.unwrap();
        let f = next_frame(&mut router).await;
        assert_eq!(
            f.frame.as_bytes(),
            &ping(7)[..],
            "a third party's frame was taken"
        );
        assert_eq!(f.source, Some(target.local_addr().unwrap()));
    }

    /// A signed PING from `sysid`, stream `link_id` of `key`.
    fn signed_ping(key: [u8; 32], link_id: u8, sysid: u8) -> FrameBuf {
        use crate::signing::{timestamp_now, Signer};
        let mut signer = Signer::new(key, link_id, timestamp_now());
        let h = Header {
            seq: 0,
            sysid,
            compid: 1,
        };
        FrameBuf::encode(Version::V2, h, &Ping { value: 1 }, Some(&mut signer)).unwrap()
    }

    /// A `tcpin` link with a key whose every client has sent an
    /// authenticated frame: a flood of new connections, each sending an
    /// unsigned frame, evicts none of them; the new connections are closed.
    /// (The oldest authenticated client was evicted for the first of them.)
    #[tokio::test]
    async fn tcpin_flood_never_evicts_an_authenticated_client() {
        let key = [8u8; 32];
        let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let mut router = Router::<TestDialect>::new();
        let mut config = LinkConfig::new(format!("tcpin:{addr}").parse().unwrap());
        config.key = Some(key);
        let link = router.add(config).await.unwrap();
        let mut clients = Vec::new();
        for i in 0..MAX_CLIENTS as u8 {
            let mut c = TcpStream::connect(addr).await.unwrap();
            c.write_all(&signed_ping(key, 1, 10 + i)).await.unwrap();
            let f = next_frame(&mut router).await;
            assert!(f.frame.is_authenticated());
            clients.push(c);
        }
        let mut flood = Vec::new();
        for i in 0..20u32 {
            let mut s = TcpStream::connect(addr).await.unwrap();
            let _ = s.write_all(&ping(i)).await;
            flood.push(s);
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        router.send_raw(Links::only(link), &ping(3));
        for (i, c) in clients.iter_mut().enumerate() {
            let mut got = [0u8; 13];
            let read = tokio::time::timeout(Duration::from_secs(2), c.read_exact(&mut got)).await;
            assert!(matches!(read, Ok(Ok(_))), "client {i} evicted");
            assert_eq!(got[..], ping(3)[..], "client {i}");
        }
        for (i, s) in flood.iter_mut().enumerate() {
            assert_eq!(read_for(s, 20).await, None, "flood connection {i} is open");
        }
        assert_eq!(router.counters(link).refused_clients, 20);
    }

    /// A `tcpin` link without a key under [`ReplyTo::Owner`]: a flood of
    /// connections, each sending an unsigned frame every 10 ms, never
    /// evicts the client the owner named, and gets none of its traffic.
    #[tokio::test]
    async fn tcpin_flood_never_evicts_the_owners_peer() {
        let (mut router, link, addr) = tcpin(ReplyTo::Owner).await;
        let mut peer = TcpStream::connect(addr).await.unwrap();
        peer.write_all(&ping(1)).await.unwrap();
        next_frame(&mut router).await;
        router.set_peers(link, &[peer.local_addr().unwrap()]);
        let mut flood = Vec::new();
        for i in 0..MAX_CLIENTS as u32 + 8 {
            let mut s = TcpStream::connect(addr).await.unwrap();
            let _ = s.write_all(&ping(i)).await;
            flood.push(s);
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        router.send_raw(Links::only(link), &ping(3));
        assert_eq!(read_for(&mut peer, 300).await, Some(ping(3).to_vec()));
        let mut served = 0;
        for s in &mut flood {
            served += usize::from(read_for(s, 5).await.is_some_and(|b| !b.is_empty()));
        }
        assert_eq!(served, 0, "strangers got the owner's traffic");
    }

    /// `udpin` under [`ReplyTo::Owner`]: nothing goes out until the owner
    /// names peers, then to those only, whoever sends frames.
    #[tokio::test]
    async fn udpin_sends_only_to_the_owners_peers() {
        let (mut router, link, addr) = udpin(Some(ReplyTo::Owner)).await;
        let (a, b, stranger) = (udp_socket().await, udp_socket().await, udp_socket().await);
        for s in [&a, &b, &stranger] {
            s.send_to(&ping(1), addr).await.unwrap();
            next_frame(&mut router).await;
        }
        router.send_raw(Links::only(link), &ping(2));
        assert_eq!(datagram_for(&a, 100).await, None, "no peer named yet");
        let named = [a.local_addr().unwrap(), b.local_addr().unwrap()];
        router.set_peers(link, &named);
        router.send_raw(Links::only(link), &ping(3));
        assert_eq!(datagram_for(&a, 500).await, Some(ping(3).to_vec()));
        assert_eq!(datagram_for(&b, 500).await, Some(ping(3).to_vec()));
        assert_eq!(datagram_for(&stranger, 50).await, None);
        router.pin_peer(link, b.local_addr().unwrap());
        router.send_raw(Links::only(link), &ping(4));
        assert_eq!(datagram_for(&b, 500).await, Some(ping(4).to_vec()));
        assert_eq!(datagram_for(&a, 50).await, None, "pin_peer: one peer");
    }

    /// On a `udpin` link with a key, an unsigned frame (accepted, as the
    /// link's policy says) makes its sender no peer; an authenticated one
    /// does.
    #[tokio::test]
    async fn udpin_with_a_key_answers_only_authenticated_senders() {
        let key = [9u8; 32];
        let probe = StdUdp::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let mut router = Router::<TestDialect>::new();
        let mut config = LinkConfig::new(format!("udpin:{addr}").parse().unwrap());
        config.key = Some(key);
        let link = router.add(config).await.unwrap();
        let (station, stranger) = (udp_socket().await, udp_socket().await);
        stranger.send_to(&ping(1), addr).await.unwrap();
        assert!(!next_frame(&mut router).await.frame.is_authenticated());
        router.send_raw(Links::only(link), &ping(2));
        assert_eq!(
            datagram_for(&stranger, 100).await,
            None,
            "an unsigned sender answered"
        );
        station
            .send_to(&signed_ping(key, 1, 1), addr)
            .await
            .unwrap();
        assert!(next_frame(&mut router).await.frame.is_authenticated());
        router.send_raw(Links::only(link), &ping(3));
        assert_eq!(datagram_for(&station, 500).await, Some(ping(3).to_vec()));
        assert_eq!(datagram_for(&stranger, 50).await, None);
    }

    /// `Router::route` sends a frame where the owner says, and the table
    /// learns nothing from it.
    #[tokio::test]
    async fn route_sends_where_the_owner_says_without_the_table() {
        let (mut router, from, addr) = udpin(None).await;
        let (t1, t2) = (udp_socket().await, udp_socket().await);
        let mut outs = Vec::new();
        for t in [&t1, &t2] {
            let url = format!("udpout:{}", t.local_addr().unwrap());
            outs.push(
                router
                    .add(LinkConfig::new(url.parse().unwrap()))
                    .await
                    .unwrap(),
            );
        }
        let station = udp_socket().await;
        station.send_to(&ping(5), addr).await.unwrap();
        let inbound = next_frame(&mut router).await;
        assert_eq!(inbound.link, from);
        let to = router.route(&inbound, Links::only(outs[1]).union(Links::only(40)));
        assert_eq!(to, Links::only(outs[1]), "links that exist only");
        assert_eq!(datagram_for(&t2, 500).await, Some(ping(5).to_vec()));
        assert_eq!(datagram_for(&t1, 50).await, None);
        assert_eq!(
            router.table().links_to(1, 1),
            Links::NONE,
            "the table learned"
        );
    }

    /// `route_signed` frames an unsigned frame again on each link, signed
    /// with that link's key and keeping the sender's header; a link
    /// without a key sends it unsigned, and `route` never signs.
    #[tokio::test]
    async fn route_signed_signs_with_each_links_key() {
        use crate::signing::Verifier;
        let key = [7u8; 32];
        let (mut router, _, addr) = udpin(None).await;
        let (signed_to, plain_to) = (udp_socket().await, udp_socket().await);
        let mut keyed = LinkConfig::new(
            format!("udpout:{}", signed_to.local_addr().unwrap())
                .parse()
                .unwrap(),
        );
        keyed.key = Some(key);
        let keyed = router.add(keyed).await.unwrap();
        let plain_url = format!("udpout:{}", plain_to.local_addr().unwrap());
        let plain = router
            .add(LinkConfig::new(plain_url.parse().unwrap()))
            .await
            .unwrap();
        udp_socket().await.send_to(&ping(5), addr).await.unwrap();
        let inbound = next_frame(&mut router).await;

        router.route(&inbound, Links::only(keyed));
        assert_eq!(
            datagram_for(&signed_to, 500).await,
            Some(ping(5).to_vec()),
            "route: as it came"
        );
        router.route_signed(&inbound, Links::only(keyed).union(Links::only(plain)));
        let got = datagram_for(&signed_to, 500).await.expect("a frame");
        let frame = crate::frame::Frame::new_checked(&got[..]).unwrap();
        assert!(frame.is_signed());
        assert_eq!(
            frame.header(),
            inbound.frame.header(),
            "the sender's header kept"
        );
        assert_eq!(frame.payload(), inbound.frame.frame().payload());
        let mut verifier = Verifier::<4>::starting_now(key);
        assert_eq!(
            verifier.verify(&frame),
            Ok(()),
            "signed with the link's key"
        );
        assert_eq!(
            datagram_for(&plain_to, 500).await,
            Some(ping(5).to_vec()),
            "no key: unsigned"
        );
    }

    /// `forward` learns authenticated senders, and every sender of a link
    /// the owner trusts, as trusted: 200 strangers' ids through another
    /// link never evict that route.
    #[tokio::test]
    async fn forward_keeps_trusted_routes_among_200_strangers() {
        let (mut router, trusted, _) = udpin(None).await;
        let other = LinkConfig::new("udpin:127.0.0.1:0".parse().unwrap());
        let stranger_link = router.add(other).await.unwrap();
        router.set_trusted(trusted, true);
        let inbound = |link, sysid: u8| {
            let h = Header {
                seq: 0,
                sysid,
                compid: 1,
            };
            let bytes = FrameBuf::encode(Version::V2, h, &Ping { value: 1 }, None).unwrap();
            let mut parser = Parser::<TestDialect>::new();
            let mut input = &[&bytes[..], &[0xfd][..]].concat()[..];
            let frame = ReceivedBuf::from(&parser.next(&mut input).unwrap());
            Inbound::<TestDialect> {
                link,
                frame,
                source: None,
            }
        };
        router.forward(&inbound(trusted, 1));
        for id in 0..200u8 {
            router.forward(&inbound(stranger_link, 2 + id));
        }
        assert_eq!(router.table().links_to(1, 1), Links::only(trusted));
    }
}
