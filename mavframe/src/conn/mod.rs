//! Links to other MAVLink systems (feature `std`): MAVProxy-style
//! connection strings ([`Endpoint`]), blocking byte transports (UDP in,
//! out and broadcast, TCP client and server, capture files, serial with
//! feature `serial`), and [`Connection`], which frames messages over a
//! transport and parses what comes back. [`Connection::split`] gives a
//! [`Sender`] and a [`Receiver`] for two threads. Feature `tokio` adds
//! `conn::codec` (a tokio_util codec for any async byte stream); for async
//! links of every kind, with their peers, signing state and routing, use
//! `crate::router`.
//!
//! ```no_run
//! # use mavframe::{MessageSet, MessageMeta};
//! # struct MyDialect; impl MessageSet for MyDialect { type Message = (); type View<'a> = ();
//! #   const MESSAGES: &'static [MessageMeta] = &[];
//! #   fn parse(_: u32, _: &[u8]) -> Option<()> { None } fn view(_: u32, _: &[u8]) -> Option<()> { None } }
//! use mavframe::conn::{Connection, Endpoint};
//! use std::time::Duration;
//!
//! let endpoint: Endpoint = "udpin:0.0.0.0:14550".parse()?;
//! let mut link = Connection::<MyDialect>::open(&endpoint)?;
//! while let Some(received) = link.recv(Some(Duration::from_secs(1)))? {
//!     println!("{:?} {:?}", received.frame(), received.message());
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#[cfg(feature = "tokio")]
pub mod codec;
mod endpoint;
mod file;
#[cfg(feature = "serial")]
mod serial;
mod split;
mod tcp;
#[cfg(test)]
pub(crate) mod test_dialect;
mod transport;
mod udp;

pub use crate::link::ReplyTo;
pub use endpoint::{Address, Endpoint, ParseEndpointError, ResolveError, DEFAULT_BAUD};
pub use file::FileLink;
#[cfg(feature = "serial")]
pub use serial::{Serial, WRITE_TIMEOUT as SERIAL_WRITE_TIMEOUT};
pub use split::{Receiver, Sender, SplitError, SPLIT_ZERO_WAIT};
pub use tcp::{TcpClient, TcpServer, MAX_PENDING_OUTPUT};
pub use transport::{open, AnyTransport, Transport};
#[cfg(feature = "tokio")]
pub(crate) use udp::is_refused;
pub use udp::{UdpBcast, UdpIn, UdpOut};
// What connections return; no_std code uses it too (`crate::ReceivedBuf`).
pub use crate::received::ReceivedBuf;

use crate::frame::{Header, Version};
use crate::framer::Framer;
use crate::link::{Inbox, LinkCore};
use crate::message::{Encode, MessageSet};
use crate::parser::{LinkStats, Parser, Stats};
use crate::signing::Signer;
use core::fmt;
use std::boxed::Box;
use std::io;
use std::time::Duration;
use std::vec;
use transport::Deadline;

/// Receive buffer of a connection: one whole UDP datagram (65,507 bytes at
/// most), so none is cut short; stream transports fill it as they can.
pub const RECV_BUFFER_LEN: usize = 64 * 1024;

/// The receive side of a blocking link ([`Connection`], [`Receiver`]).
pub(crate) type ConnInbox<D> = Inbox<D, Box<[u8]>>;

/// A receive side with a buffer of [`RECV_BUFFER_LEN`].
pub(crate) fn inbox<D: MessageSet>(parser: Parser<D>) -> ConnInbox<D> {
    Inbox::new(parser, vec![0u8; RECV_BUFFER_LEN].into_boxed_slice())
}

/// The next frame in `inbox`, receiving from `transport` as needed,
/// waiting up to `timeout` in all (see [`Connection::recv`]).
pub(crate) fn recv<D: MessageSet, T: Transport + ?Sized>(
    inbox: &mut ConnInbox<D>,
    transport: &mut T,
    timeout: Option<Duration>,
) -> io::Result<Option<ReceivedBuf<D>>> {
    let deadline = Deadline::after(timeout);
    loop {
        if let Some(frame) = inbox.next() {
            // `udpin` answers whom the transport is told of.
            if inbox.vouches(&frame) {
                transport.accepted();
            }
            return Ok(Some(frame));
        }
        let n = transport.recv(inbox.space(), deadline.remaining())?;
        if n == 0 {
            return Ok(None);
        }
        inbox.received(n, None, transport.is_datagram());
    }
}

/// A MAVLink link: a transport, a parser for dialect `D`, and the sending
/// state (protocol version, sequence number, signer).
///
/// `T` is any [`Transport`]; the default, [`AnyTransport`], is what
/// [`Connection::open`] makes from an [`Endpoint`].
///
/// To receive on one thread and send on another, [`split`](Connection::split)
/// it; for tokio, see `codec` (feature `tokio`).
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
/// use mavframe::conn::Connection;
/// use std::time::Duration;
///
/// // A vehicle listening on a UDP port, and a ground station sending to it.
/// let mut vehicle = Connection::<D>::open(&"udpin:127.0.0.1:0".parse()?)?;
/// let port = vehicle.transport().local_addr()?.port();
/// let mut station = Connection::<D>::open(&format!("udpout:127.0.0.1:{port}").parse()?)?;
///
/// // `send_auto` numbers frames itself (and signs them, given a signer).
/// station.send_auto(255, 190, &Ping(7))?;
/// let received = vehicle.recv(Some(Duration::from_secs(5)))?.expect("a frame in time");
/// assert_eq!(received.message(), Some(Ping(7)));
/// assert_eq!(received.header().sysid, 255);
///
/// // `udpin` answers whom it heard from: the station gets the reply.
/// vehicle.send_auto(1, 1, &Ping(8))?;
/// let reply = station.recv(Some(Duration::from_secs(5)))?.expect("a reply");
/// assert_eq!(reply.message(), Some(Ping(8)));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Connection<D: MessageSet, T: Transport = AnyTransport> {
    transport: T,
    core: LinkCore<D, Box<[u8]>>,
}

impl<D: MessageSet, T: Transport + fmt::Debug> fmt::Debug for Connection<D, T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Connection")
            .field("transport", &self.transport)
            .field("parser", self.parser())
            .field("framer", &self.core.framer)
            .finish()
    }
}

impl<D: MessageSet> Connection<D, AnyTransport> {
    /// Opens `endpoint` (see [`open`]) with a parser without signing.
    pub fn open(endpoint: &Endpoint) -> io::Result<Self> {
        Ok(Self::new(open(endpoint)?))
    }
}

impl<D: MessageSet, T: Transport> Connection<D, T> {
    /// A connection over `transport`, with a parser without signing
    /// (signed frames are accepted unverified).
    pub fn new(transport: T) -> Self {
        Self::with_parser(transport, Parser::new())
    }

    /// A connection whose frames go through `parser`: one made with
    /// [`Parser::with_signing`] verifies signatures.
    pub fn with_parser(transport: T, parser: Parser<D>) -> Self {
        let core = LinkCore {
            inbox: inbox(parser),
            framer: Framer::new(),
        };
        Connection { transport, core }
    }

    /// The next frame the parser accepts, waiting up to `timeout` in all
    /// (`None`: without limit; zero: only bytes already there); `Ok(None)`
    /// when the time runs out first. Frames already read are returned
    /// without touching the transport.
    pub fn recv(&mut self, timeout: Option<Duration>) -> io::Result<Option<ReceivedBuf<D>>> {
        let frame = recv(&mut self.core.inbox, &mut self.transport, timeout)?;
        self.core.adopt();
        Ok(frame)
    }

    /// Sends `msg` with `header` in the connection's protocol version
    /// ([`set_version`](Self::set_version); MAVLink 2 unless changed),
    /// signed when a signer is set.
    pub fn send<M: Encode + ?Sized>(&mut self, header: Header, msg: &M) -> io::Result<()> {
        self.send_version(self.core.framer.version(), header, msg)
    }

    /// Sends `msg` with `header` in `version`. MAVLink 1 frames are never
    /// signed; a message id above 255 cannot be sent as MAVLink 1
    /// (`InvalidInput`).
    pub fn send_version<M: Encode + ?Sized>(
        &mut self,
        version: Version,
        header: Header,
        msg: &M,
    ) -> io::Result<()> {
        let frame = self.core.framer.frame_as(version, header, msg)?;
        self.transport.send(frame)
    }

    /// Sends `msg` as `sysid`/`compid` with the connection's next sequence
    /// number, which then advances (wrapping at 255), whether or not the
    /// transport succeeds: a receiver counts a failed send as lost.
    pub fn send_auto<M: Encode + ?Sized>(
        &mut self,
        sysid: u8,
        compid: u8,
        msg: &M,
    ) -> io::Result<()> {
        let header = self.core.framer.next_header(sysid, compid);
        self.send(header, msg)
    }

    /// Sends bytes as they are: a frame received elsewhere and forwarded
    /// (routers), or anything a test needs on the wire.
    pub fn send_raw(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.transport.send(bytes)
    }

    /// Sets the protocol version of [`send`](Self::send) and
    /// [`send_auto`](Self::send_auto).
    pub fn set_version(&mut self, version: Version) {
        self.core.framer.set_version(version);
    }

    /// The protocol version of [`send`](Self::send).
    pub fn version(&self) -> Version {
        self.core.framer.version()
    }

    /// Signs every MAVLink 2 frame sent from now on (`None`: stop signing).
    /// The signer's timestamp is kept at least at the current time.
    pub fn set_signer(&mut self, signer: Option<Signer>) {
        self.core.framer.set_signer(signer);
    }

    /// The signer, if frames are signed.
    pub fn signer(&self) -> Option<&Signer> {
        self.core.framer.signer()
    }

    /// The sequence number [`send_auto`](Self::send_auto) uses next.
    pub fn next_seq(&self) -> u8 {
        self.core.framer.seq()
    }

    /// Sets the sequence number [`send_auto`](Self::send_auto) uses next.
    pub fn set_next_seq(&mut self, seq: u8) {
        self.core.framer.set_seq(seq);
    }

    /// The parser's counters (frames, bad checksums, dropped bytes, …).
    pub fn stats(&self) -> &Stats {
        self.parser().stats()
    }

    /// Sequence statistics per sender.
    pub fn links(&self) -> &[LinkStats] {
        self.parser().links()
    }

    /// The parser.
    pub fn parser(&self) -> &Parser<D> {
        &self.core.inbox.parser
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// The transport, mutably (bytes sent or read through it bypass the
    /// connection's framing and parser).
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    /// The transport, dropping the parser and any bytes it held.
    pub fn into_transport(self) -> T {
        self.transport
    }
}

#[cfg(test)]
mod tests {
    use super::test_dialect::{Ping, TestDialect};
    use super::*;
    use crate::frame::MAX_FRAME_LEN;
    use std::net::SocketAddr;
    use std::string::ToString;

    fn udp_pair() -> (Connection<TestDialect>, Connection<TestDialect>) {
        let server =
            Connection::<TestDialect>::open(&"udpin:127.0.0.1:0".parse().unwrap()).unwrap();
        let port = server.transport().local_addr().unwrap().port();
        let client = Connection::<TestDialect>::open(&Endpoint::UdpOut(
            SocketAddr::from(([127, 0, 0, 1], port)).into(),
        ))
        .unwrap();
        (server, client)
    }

    #[test]
    fn several_frames_in_one_datagram_are_all_returned() {
        let (mut server, mut client) = udp_pair();
        let mut bytes = std::vec::Vec::new();
        let mut out = Framer::new();
        for v in 0..3 {
            bytes.extend_from_slice(out.frame(1, 1, &Ping { value: v }).unwrap());
        }
        client.send_raw(&bytes).unwrap();
        for v in 0..3 {
            let f = server.recv(Some(Duration::from_secs(2))).unwrap().unwrap();
            assert_eq!(f.message(), Some(Ping { value: v }));
            assert_eq!(f.header().seq, v as u8);
        }
        assert!(server.recv(Some(Duration::ZERO)).unwrap().is_none());
    }

    /// The signing timestamps `send` uses: strictly increasing in a burst
    /// (faster than the clock's 10 µs ticks), at the clock after a pause,
    /// and never back when the signer ran ahead of the clock.
    #[test]
    fn signed_frames_keep_up_with_the_clock_and_always_increase() {
        use crate::frame::Frame;
        use crate::signing::{timestamp_now, Signer};
        fn stamp(out: &mut Framer) -> u64 {
            let bytes = out.frame(1, 1, &Ping { value: 1 }).unwrap();
            Frame::new_checked(bytes)
                .unwrap()
                .signature()
                .unwrap()
                .timestamp()
        }
        let mut out = Framer::new();
        out.set_signer(Some(Signer::new([3; 32], 0, 0)));
        let start = timestamp_now();
        let burst: std::vec::Vec<u64> = (0..1000).map(|_| stamp(&mut out)).collect();
        assert!(burst[0] >= start);
        assert!(burst.windows(2).all(|w| w[1] > w[0]));
        std::thread::sleep(Duration::from_millis(20));
        let before = timestamp_now();
        let after_pause = stamp(&mut out);
        assert!(after_pause >= before, "{after_pause} < {before}");
        assert!(after_pause > burst[999]);
        // A signer ahead of the clock (timestamps may run ahead) goes on from
        // where it is.
        let ahead = timestamp_now() + 6_000_000;
        out.set_signer(Some(Signer::new([3; 32], 0, ahead)));
        assert_eq!(stamp(&mut out), ahead);
        assert_eq!(stamp(&mut out), ahead + 1);
    }

    #[test]
    fn v1_cannot_carry_large_ids_and_says_so() {
        let (_server, mut client) = udp_pair();
        let err = client
            .send_version(
                Version::V1,
                Header::default(),
                &test_dialect::Big::default(),
            )
            .unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::InvalidInput);
        assert_eq!(
            err.to_string(),
            "message id 300 does not fit MAVLink 1 (at most 255)"
        );
    }

    /// A MAVLink 2 header of Ping (known id) claiming a 200-byte payload:
    /// 10 bytes that start a 212-byte candidate.
    const FALSE_HEADER: [u8; 10] = [0xFD, 200, 0, 0, 0, 1, 1, 1, 0, 0];

    fn ping_frame(value: u32) -> std::vec::Vec<u8> {
        Framer::new().frame(1, 1, &Ping { value }).unwrap().to_vec()
    }

    /// A datagram ends every frame in it: a false header at the end of one
    /// is given up there, so the good frame of the next datagram comes out
    /// on that datagram's receive (it used to wait for 212 bytes).
    #[test]
    fn a_false_header_ending_a_datagram_does_not_hold_back_the_next_one() {
        let (mut server, mut client) = udp_pair();
        assert!(server.transport().is_datagram());
        client.send_raw(&FALSE_HEADER).unwrap();
        let good = ping_frame(5);
        client.send_raw(&good).unwrap();
        let f = server.recv(Some(Duration::from_secs(2))).unwrap().unwrap();
        assert_eq!(f.message(), Some(Ping { value: 5 }));
        assert_eq!(f.as_bytes(), &good[..]);
        assert_eq!(server.stats().bytes_dropped, FALSE_HEADER.len() as u64);
        assert_eq!(server.parser().pending(), 0);
        // Frames whole inside one datagram are unaffected, several at once.
        let two = [ping_frame(6), ping_frame(7)].concat();
        client
            .send_raw(&[&two[..], &FALSE_HEADER[..]].concat())
            .unwrap();
        for v in [6, 7] {
            let f = server.recv(Some(Duration::from_secs(2))).unwrap().unwrap();
            assert_eq!(f.message(), Some(Ping { value: v }));
        }
        assert!(server.recv(Some(Duration::ZERO)).unwrap().is_none());
        assert_eq!(server.parser().pending(), 0, "the false header is given up");
    }

    /// On a byte stream (TCP, serial) the rest of a frame may still come:
    /// the same bytes keep the parser waiting for the length claimed, and
    /// the good frame inside comes out once that many bytes arrived.
    #[test]
    fn a_false_header_on_a_stream_waits_for_the_length_it_claims() {
        let mut inbox = inbox::<TestDialect>(Parser::new());
        let push = |inbox: &mut ConnInbox<TestDialect>, bytes: &[u8]| {
            inbox.space()[..bytes.len()].copy_from_slice(bytes);
            inbox.received(bytes.len(), None, false);
            let mut got = std::vec::Vec::new();
            while let Some(f) = inbox.next() {
                got.push(f.message());
            }
            got
        };
        assert!(push(&mut inbox, &FALSE_HEADER).is_empty());
        let good = ping_frame(5);
        assert!(push(&mut inbox, &good).is_empty(), "still waiting");
        assert_eq!(
            push(&mut inbox, &[0u8; 200]),
            std::vec![Some(Ping { value: 5 })]
        );
    }

    /// `udpout:localhost:PORT` resolves at open and reaches a listener on
    /// 127.0.0.1; `tcp:` to a name that does not resolve fails at open
    /// with the typed error inside.
    #[test]
    fn host_names_resolve_at_open() {
        let mut server =
            Connection::<TestDialect>::open(&"udpin:127.0.0.1:0".parse().unwrap()).unwrap();
        let port = server.transport().local_addr().unwrap().port();
        let endpoint: Endpoint = std::format!("udpout:localhost:{port}").parse().unwrap();
        let mut client = Connection::<TestDialect>::open(&endpoint).unwrap();
        client.send_auto(1, 1, &Ping { value: 9 }).unwrap();
        let f = server.recv(Some(Duration::from_secs(2))).unwrap().unwrap();
        assert_eq!(f.message(), Some(Ping { value: 9 }));
        let bad: Endpoint = "tcp:no-such-host.invalid:5760".parse().unwrap();
        let err = Connection::<TestDialect>::open(&bad).unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::NotFound);
        let inner = err.get_ref().unwrap().downcast_ref::<ResolveError>();
        assert!(matches!(
            inner,
            Some(ResolveError::Lookup { port: 5760, .. })
        ));
    }

    /// `tcpout:` and `tcp:` open the same client.
    #[test]
    fn tcpout_connects() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let endpoint: Endpoint = std::format!("tcpout:127.0.0.1:{port}").parse().unwrap();
        let mut client = Connection::<TestDialect>::open(&endpoint).unwrap();
        let (mut peer, _) = listener.accept().unwrap();
        client.send_auto(1, 1, &Ping { value: 3 }).unwrap();
        let mut buf = [0u8; 64];
        use std::io::Read;
        let n = peer.read(&mut buf).unwrap();
        assert_eq!(&buf[..n], &ping_frame(3)[..]);
    }

    #[test]
    fn types_cross_threads_and_frames_stay_small() {
        fn check<T: Send + Sync>() {}
        fn check_send<T: Send>() {}
        check::<ReceivedBuf<TestDialect>>();
        check::<Endpoint>();
        check_send::<AnyTransport>();
        check_send::<Connection<TestDialect>>();
        assert!(core::mem::size_of::<ReceivedBuf<TestDialect>>() <= MAX_FRAME_LEN + 32);
    }
}
