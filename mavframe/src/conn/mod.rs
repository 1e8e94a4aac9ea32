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
//! # use mavframe::{Dialect, MessageMeta};
//! # struct MyDialect; impl Dialect for MyDialect { type Message = (); type View<'a> = ();
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

pub use endpoint::{Address, Endpoint, ParseEndpointError, ResolveError, DEFAULT_BAUD};
pub use file::FileLink;
#[cfg(feature = "serial")]
pub use serial::{Serial, WRITE_TIMEOUT as SERIAL_WRITE_TIMEOUT};
pub use split::{Receiver, Sender, SplitError, SPLIT_ZERO_WAIT};
pub use tcp::{TcpClient, TcpServer, MAX_PENDING_OUTPUT};
pub use transport::{open, AnyTransport, Transport};
pub use udp::{ReplyTo, UdpBcast, UdpIn, UdpOut};
// What connections return; no_std code uses it too (`crate::ReceivedFrame`).
pub use crate::received::ReceivedFrame;

use crate::frame::{encode, Header, Version, MAX_FRAME_LEN};
use crate::message::{Dialect, Encode};
use crate::parser::{LinkStats, Parser, Stats};
use crate::signing::{timestamp_now, Signer};
use core::fmt;
use std::boxed::Box;
use std::io;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use std::vec;
use transport::Deadline;

/// Receive buffer of a connection: one whole UDP datagram (65,507 bytes at
/// most), so none is cut short; stream transports fill it as they can.
pub const RECV_BUFFER_LEN: usize = 64 * 1024;

/// The receive side shared by the blocking and async connections: the
/// parser and the bytes read but not parsed yet.
pub(crate) struct Inbox<D: Dialect> {
    parser: Parser<D>,
    buf: Box<[u8]>,
    start: usize,
    end: usize,
    /// Each read is one datagram (see [`Transport::is_datagram`]).
    datagrams: bool,
    /// The parser has not been told yet that the datagram read ended.
    datagram_open: bool,
    /// The verifier's notion of now after the last frame, which the link's
    /// signer adopts ([`Outbox::for_inbox`]; shared, as a split
    /// connection's halves may live on two threads).
    verified: Arc<AtomicU64>,
}

impl<D: Dialect> Inbox<D> {
    pub(crate) fn new(parser: Parser<D>, datagrams: bool) -> Self {
        Inbox {
            parser,
            buf: vec![0u8; RECV_BUFFER_LEN].into_boxed_slice(),
            start: 0,
            end: 0,
            datagrams,
            datagram_open: false,
            verified: Arc::default(),
        }
    }

    /// The next frame in the bytes already read; at the end of a datagram,
    /// those its end decides. What the verifier accepted is then handed to
    /// the link's signer ([`Inbox::verified`]).
    pub(crate) fn next(&mut self) -> Option<ReceivedFrame<D>> {
        let frame = self.parse_next();
        if let Some(v) = self.parser.verifier() {
            self.verified
                .fetch_max(v.newest_timestamp(), Ordering::Relaxed);
        }
        frame
    }

    fn parse_next(&mut self) -> Option<ReceivedFrame<D>> {
        if let Some(frame) = self.next_in_buffer() {
            return Some(frame);
        }
        if self.datagram_open {
            match self.parser.end_of_datagram() {
                Some(r) => return Some(ReceivedFrame::from(&r)),
                None => self.datagram_open = false,
            }
        }
        None
    }

    fn next_in_buffer(&mut self) -> Option<ReceivedFrame<D>> {
        while self.start < self.end {
            let mut input = &self.buf[self.start..self.end];
            // A datagram read is the whole datagram: its end is known now.
            let got = if self.datagrams {
                self.parser.next_in_datagram(&mut input)
            } else {
                self.parser.next(&mut input)
            }
            .map(|r| ReceivedFrame::from(&r));
            let start = self.end - input.len();
            let progressed = start != self.start;
            self.start = start;
            if got.is_some() {
                return got;
            }
            // The parser consumes its whole input before it says None; this
            // only guards against spinning should that ever change.
            if !progressed {
                self.start = self.end;
            }
        }
        None
    }

    /// The next frame, reading from `transport` as needed, waiting up to
    /// `timeout` in all (see [`Connection::recv`]).
    pub(crate) fn recv<T: Transport + ?Sized>(
        &mut self,
        transport: &mut T,
        timeout: Option<Duration>,
    ) -> io::Result<Option<ReceivedFrame<D>>> {
        let deadline = Deadline::after(timeout);
        loop {
            if let Some(frame) = self.next() {
                // With a key, only an authenticated frame vouches for its
                // sender (`udpin` answers whom the transport is told of).
                if frame.is_authenticated() || self.parser.verifier().is_none() {
                    transport.accepted();
                }
                return Ok(Some(frame));
            }
            let n = transport.recv(self.space(), deadline.remaining())?;
            if n == 0 {
                return Ok(None);
            }
            self.filled(n);
        }
    }

    /// Where the transport reads to: the whole buffer, since it is read
    /// into only once parsed to the end (the parser keeps a partial frame).
    pub(crate) fn space(&mut self) -> &mut [u8] {
        &mut self.buf
    }

    /// `n` bytes were read into [`space`](Self::space).
    pub(crate) fn filled(&mut self, n: usize) {
        self.start = 0;
        self.end = n.min(self.buf.len());
        self.datagram_open = self.datagrams;
    }
}

/// The send side shared by the blocking and async connections.
pub(crate) struct Outbox {
    pub(crate) signer: Option<Signer>,
    pub(crate) version: Version,
    pub(crate) seq: u8,
    buf: [u8; MAX_FRAME_LEN],
    /// The link's verified timestamps ([`Inbox::verified`]), adopted by the
    /// signer before each frame.
    verified: Arc<AtomicU64>,
}

impl Outbox {
    pub(crate) fn new() -> Self {
        Outbox {
            signer: None,
            version: Version::V2,
            seq: 0,
            buf: [0; MAX_FRAME_LEN],
            verified: Arc::default(),
        }
    }

    /// The send side of the link `inbox` receives on: its signer adopts
    /// what `inbox`'s verifier accepts (see `crate::signing`).
    pub(crate) fn for_inbox<D: Dialect>(inbox: &Inbox<D>) -> Self {
        Outbox {
            verified: inbox.verified.clone(),
            ..Outbox::new()
        }
    }

    /// The header for an automatically numbered frame.
    pub(crate) fn auto_header(&mut self, sysid: u8, compid: u8) -> Header {
        let seq = self.seq;
        self.seq = seq.wrapping_add(1);
        Header { seq, sysid, compid }
    }

    /// Encodes a frame and returns its bytes.
    pub(crate) fn encode<M: Encode + ?Sized>(
        &mut self,
        version: Version,
        header: Header,
        msg: &M,
    ) -> io::Result<&[u8]> {
        if let Some(signer) = &mut self.signer {
            // Receivers drop a new stream whose timestamps are more than a
            // minute behind the newest they have seen: keep up with the
            // clock, never going back. The clock is read for every frame, on
            // purpose: the signer counts one tick (10 µs) per frame, so a
            // sender slower than 100,000 frames/s falls behind real time by
            // however long it paused, which only a clock can tell; reading
            // it every N frames instead leaves the lag unbounded (a link
            // that sends once a minute would lag N minutes). std has no
            // cheaper clock (a coarse one needs `unsafe` libc or another
            // dependency), and the read is ~35 ns of a send that costs a
            // system call.
            signer.advance_to(timestamp_now());
            signer.advance_to(self.verified.load(Ordering::Relaxed));
        }
        let n = encode(version, header, msg, self.signer.as_mut(), &mut self.buf)
            .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
        Ok(&self.buf[..n])
    }
}

/// A MAVLink link: a transport, a parser for dialect `D`, and the sending
/// state (protocol version, sequence number, signer).
///
/// `T` is any [`Transport`]; the default, [`AnyTransport`], is what
/// [`Connection::open`] makes from an [`Endpoint`].
pub struct Connection<D: Dialect, T: Transport = AnyTransport> {
    transport: T,
    inbox: Inbox<D>,
    outbox: Outbox,
}

impl<D: Dialect, T: Transport + fmt::Debug> fmt::Debug for Connection<D, T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Connection")
            .field("transport", &self.transport)
            .field("parser", &self.inbox.parser)
            .field("version", &self.outbox.version)
            .field("next_seq", &self.outbox.seq)
            .field("signer", &self.outbox.signer)
            .finish()
    }
}

impl<D: Dialect> Connection<D, AnyTransport> {
    /// Opens `endpoint` (see [`open`]) with a parser without signing.
    pub fn open(endpoint: &Endpoint) -> io::Result<Self> {
        Ok(Self::new(open(endpoint)?))
    }
}

impl<D: Dialect, T: Transport> Connection<D, T> {
    /// A connection over `transport`, with a parser without signing
    /// (signed frames are accepted unverified).
    pub fn new(transport: T) -> Self {
        Self::with_parser(transport, Parser::new())
    }

    /// A connection whose frames go through `parser`: one made with
    /// [`Parser::with_signing`] verifies signatures.
    pub fn with_parser(transport: T, parser: Parser<D>) -> Self {
        let datagrams = transport.is_datagram();
        let inbox = Inbox::new(parser, datagrams);
        Connection {
            transport,
            outbox: Outbox::for_inbox(&inbox),
            inbox,
        }
    }

    /// The next frame the parser accepts, waiting up to `timeout` in all
    /// (`None`: without limit; zero: only bytes already there); `Ok(None)`
    /// when the time runs out first. Frames already read are returned
    /// without touching the transport.
    pub fn recv(&mut self, timeout: Option<Duration>) -> io::Result<Option<ReceivedFrame<D>>> {
        self.inbox.recv(&mut self.transport, timeout)
    }

    /// Sends `msg` with `header` in the connection's protocol version
    /// ([`set_version`](Self::set_version); MAVLink 2 unless changed),
    /// signed when a signer is set.
    pub fn send<M: Encode + ?Sized>(&mut self, header: Header, msg: &M) -> io::Result<()> {
        self.send_version(self.outbox.version, header, msg)
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
        let frame = self.outbox.encode(version, header, msg)?;
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
        let header = self.outbox.auto_header(sysid, compid);
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
        self.outbox.version = version;
    }

    /// The protocol version of [`send`](Self::send).
    pub fn version(&self) -> Version {
        self.outbox.version
    }

    /// Signs every MAVLink 2 frame sent from now on (`None`: stop signing).
    /// The signer's timestamp is kept at least at the current time.
    pub fn set_signer(&mut self, signer: Option<Signer>) {
        self.outbox.signer = signer;
    }

    /// The signer, if frames are signed.
    pub fn signer(&self) -> Option<&Signer> {
        self.outbox.signer.as_ref()
    }

    /// The sequence number [`send_auto`](Self::send_auto) uses next.
    pub fn next_seq(&self) -> u8 {
        self.outbox.seq
    }

    /// Sets the sequence number [`send_auto`](Self::send_auto) uses next.
    pub fn set_next_seq(&mut self, seq: u8) {
        self.outbox.seq = seq;
    }

    /// The parser's counters (frames, bad checksums, dropped bytes, …).
    pub fn stats(&self) -> &Stats {
        self.inbox.parser.stats()
    }

    /// Sequence statistics per sender.
    pub fn links(&self) -> &[LinkStats] {
        self.inbox.parser.links()
    }

    /// The parser.
    pub fn parser(&self) -> &Parser<D> {
        &self.inbox.parser
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
        let mut out = Outbox::new();
        for v in 0..3 {
            let h = out.auto_header(1, 1);
            bytes.extend_from_slice(out.encode(Version::V2, h, &Ping { value: v }).unwrap());
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
        fn stamp(out: &mut Outbox) -> u64 {
            let h = out.auto_header(1, 1);
            let bytes = out.encode(Version::V2, h, &Ping { value: 1 }).unwrap();
            Frame::new_checked(bytes)
                .unwrap()
                .signature()
                .unwrap()
                .timestamp()
        }
        let mut out = Outbox::new();
        out.signer = Some(Signer::new([3; 32], 0, 0));
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
        out.signer = Some(Signer::new([3; 32], 0, ahead));
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
        let mut out = Outbox::new();
        let h = out.auto_header(1, 1);
        out.encode(Version::V2, h, &Ping { value })
            .unwrap()
            .to_vec()
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
        let mut inbox = Inbox::<TestDialect>::new(Parser::new(), false);
        let push = |inbox: &mut Inbox<TestDialect>, bytes: &[u8]| {
            inbox.space()[..bytes.len()].copy_from_slice(bytes);
            inbox.filled(bytes.len());
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
        check::<ReceivedFrame<TestDialect>>();
        check::<Endpoint>();
        check_send::<AnyTransport>();
        check_send::<Connection<TestDialect>>();
        assert!(core::mem::size_of::<ReceivedFrame<TestDialect>>() <= MAX_FRAME_LEN + 32);
    }
}
