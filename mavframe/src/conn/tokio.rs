//! Async connections on tokio (feature `tokio`): UDP (`udpin`, `udpout`)
//! and TCP client (`tcp`).
//!
//! Same framing and parsing as the blocking [`Connection`](super::Connection);
//! timeouts are tokio's (`tokio::time::timeout(d, link.recv())`, which
//! needs tokio's `time` feature in the application). `tcpin` and `serial`
//! are not offered here: use the blocking transports on a blocking thread
//! (`tokio::task::spawn_blocking`).

use super::endpoint::Endpoint;
use super::{Inbox, Outbox, ReceivedFrame};
use crate::frame::{Header, Version};
use crate::message::{Dialect, Encode};
use crate::parser::{LinkStats, Parser, Stats};
use crate::signing::Signer;
use ::tokio::io::{AsyncReadExt, AsyncWriteExt};
use ::tokio::net::{TcpStream, UdpSocket};
use core::fmt;
use std::io;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr};

#[derive(Debug)]
enum Kind {
    UdpIn {
        socket: UdpSocket,
        peer: Option<SocketAddr>,
    },
    UdpOut {
        socket: UdpSocket,
        target: SocketAddr,
    },
    Tcp(TcpStream),
}

/// An async byte transport: what [`AsyncConnection`] sends and receives
/// through. Behaves as the blocking [`UdpIn`](super::UdpIn),
/// [`UdpOut`](super::UdpOut) and [`TcpClient`](super::TcpClient) do.
#[derive(Debug)]
pub struct AsyncTransport {
    kind: Kind,
}

/// The first address `addr` resolves to.
async fn addr_first(addr: &super::Address) -> io::Result<SocketAddr> {
    let all = addr.resolve_async().await?;
    // resolve_async never returns an empty list.
    all.first()
        .copied()
        .ok_or_else(|| io::Error::from(io::ErrorKind::NotFound))
}

impl AsyncTransport {
    /// Binds or connects as `endpoint` says (host names resolved now);
    /// `tcpin:`, `udpbcast:`, `serial:` and `file:` fail with
    /// [`io::ErrorKind::Unsupported`] (the `router` module and
    /// [`codec`](super::codec) cover tcpin and serial).
    pub async fn open(endpoint: &Endpoint) -> io::Result<Self> {
        let kind = match endpoint {
            Endpoint::UdpIn(addr) => Kind::UdpIn {
                socket: UdpSocket::bind(addr.resolve_async().await?.as_slice()).await?,
                peer: None,
            },
            Endpoint::UdpOut(target) => {
                let target = addr_first(target).await?;
                let local = match target {
                    SocketAddr::V4(_) => SocketAddr::from((Ipv4Addr::UNSPECIFIED, 0)),
                    SocketAddr::V6(_) => SocketAddr::from((Ipv6Addr::UNSPECIFIED, 0)),
                };
                Kind::UdpOut {
                    socket: UdpSocket::bind(local).await?,
                    target,
                }
            }
            Endpoint::Tcp(addr) => {
                let stream = TcpStream::connect(addr.resolve_async().await?.as_slice()).await?;
                stream.set_nodelay(true)?;
                Kind::Tcp(stream)
            }
            _ => {
                return Err(io::Error::new(
                    io::ErrorKind::Unsupported,
                    std::format!(
                        "{}: not available as an async transport; use the blocking one",
                        endpoint.scheme()
                    ),
                ))
            }
        };
        Ok(AsyncTransport { kind })
    }

    /// The local address (the port the system chose for port 0).
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        match &self.kind {
            Kind::UdpIn { socket, .. } | Kind::UdpOut { socket, .. } => socket.local_addr(),
            Kind::Tcp(stream) => stream.local_addr(),
        }
    }

    /// Where frames go: the last UDP sender for `udpin` (`None` before the
    /// first datagram), the target for `udpout`, the server for `tcp`.
    pub fn peer(&self) -> Option<SocketAddr> {
        match &self.kind {
            Kind::UdpIn { peer, .. } => *peer,
            Kind::UdpOut { target, .. } => Some(*target),
            Kind::Tcp(stream) => stream.peer_addr().ok(),
        }
    }

    /// Sends one frame. `udpin` without a peer yet drops it, as the
    /// blocking transport does.
    ///
    /// Not cancel-safe over TCP: dropped half-way, a frame may be cut
    /// short on the stream.
    pub async fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        match &mut self.kind {
            Kind::UdpIn { socket, peer } => match peer {
                Some(p) => socket.send_to(frame, *p).await.map(drop),
                None => Ok(()),
            },
            Kind::UdpOut { socket, target } => socket.send_to(frame, *target).await.map(drop),
            Kind::Tcp(stream) => stream.write_all(frame).await,
        }
    }

    /// True for UDP: each [`recv`](Self::recv) is one datagram (see
    /// [`Transport::is_datagram`](super::Transport::is_datagram)).
    pub fn is_datagram(&self) -> bool {
        matches!(self.kind, Kind::UdpIn { .. } | Kind::UdpOut { .. })
    }

    /// Waits for bytes and reads them into `buf`; never returns 0 for a
    /// non-empty `buf` (a closed TCP stream is `UnexpectedEof`).
    /// Cancel-safe: dropped before it completes, it has read nothing.
    pub async fn recv(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        loop {
            let got = match &mut self.kind {
                Kind::UdpIn { socket, peer } => socket.recv_from(buf).await.map(|(n, from)| {
                    if n > 0 {
                        *peer = Some(from);
                    }
                    n
                }),
                Kind::UdpOut { socket, .. } => socket.recv_from(buf).await.map(|(n, _)| n),
                Kind::Tcp(stream) => match stream.read(buf).await {
                    Ok(0) => {
                        return Err(io::Error::new(
                            io::ErrorKind::UnexpectedEof,
                            "connection closed by peer",
                        ))
                    }
                    other => other,
                },
            };
            match got {
                // An empty datagram: nothing to parse, keep waiting.
                Ok(0) => {}
                Ok(n) => return Ok(n),
                // As in the blocking UDP transports: a Windows report of an
                // earlier send's ICMP error is no reason to stop receiving.
                Err(e)
                    if matches!(self.kind, Kind::UdpIn { .. } | Kind::UdpOut { .. })
                        && matches!(
                            e.kind(),
                            io::ErrorKind::ConnectionReset | io::ErrorKind::ConnectionRefused
                        ) => {}
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
    }
}

/// The async [`Connection`](super::Connection): same methods, `async`,
/// without timeouts (wrap calls in `tokio::time::timeout`).
pub struct AsyncConnection<D: Dialect> {
    transport: AsyncTransport,
    inbox: Inbox<D>,
    outbox: Outbox,
}

impl<D: Dialect> fmt::Debug for AsyncConnection<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("AsyncConnection")
            .field("transport", &self.transport)
            .field("parser", &self.inbox.parser)
            .field("version", &self.outbox.version)
            .field("next_seq", &self.outbox.seq)
            .field("signer", &self.outbox.signer)
            .finish()
    }
}

impl<D: Dialect> AsyncConnection<D> {
    /// Opens `endpoint` (see [`AsyncTransport::open`]) with a parser
    /// without signing.
    pub async fn open(endpoint: &Endpoint) -> io::Result<Self> {
        Ok(Self::new(AsyncTransport::open(endpoint).await?))
    }

    /// A connection over `transport`, with a parser without signing.
    pub fn new(transport: AsyncTransport) -> Self {
        Self::with_parser(transport, Parser::new())
    }

    /// A connection whose frames go through `parser` (e.g. one verifying
    /// signatures).
    pub fn with_parser(transport: AsyncTransport, parser: Parser<D>) -> Self {
        let datagrams = transport.is_datagram();
        let inbox = Inbox::new(parser, datagrams);
        AsyncConnection {
            transport,
            outbox: Outbox::for_inbox(&inbox),
            inbox,
        }
    }

    /// The next frame the parser accepts.
    ///
    /// Cancel-safe (e.g. under `tokio::time::timeout` or `select!`): bytes
    /// read are kept in the connection until parsed, so dropping this
    /// future loses no frame.
    pub async fn recv(&mut self) -> io::Result<ReceivedFrame<D>> {
        loop {
            if let Some(frame) = self.inbox.next() {
                return Ok(frame);
            }
            let n = self.transport.recv(self.inbox.space()).await?;
            self.inbox.filled(n);
        }
    }

    /// Sends `msg` with `header` in the connection's protocol version
    /// (MAVLink 2 unless [`set_version`](Self::set_version) says otherwise),
    /// signed when a signer is set. Not cancel-safe over TCP (see
    /// [`AsyncTransport::send`]).
    pub async fn send<M: Encode + ?Sized>(&mut self, header: Header, msg: &M) -> io::Result<()> {
        self.send_version(self.outbox.version, header, msg).await
    }

    /// Sends `msg` with `header` in `version`.
    pub async fn send_version<M: Encode + ?Sized>(
        &mut self,
        version: Version,
        header: Header,
        msg: &M,
    ) -> io::Result<()> {
        let frame = self.outbox.encode(version, header, msg)?;
        self.transport.send(frame).await
    }

    /// Sends `msg` as `sysid`/`compid` with the next sequence number, which
    /// then advances (wrapping).
    pub async fn send_auto<M: Encode + ?Sized>(
        &mut self,
        sysid: u8,
        compid: u8,
        msg: &M,
    ) -> io::Result<()> {
        let header = self.outbox.auto_header(sysid, compid);
        self.send(header, msg).await
    }

    /// Sends bytes as they are (forwarded frames).
    pub async fn send_raw(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.transport.send(bytes).await
    }

    /// Sets the protocol version of [`send`](Self::send).
    pub fn set_version(&mut self, version: Version) {
        self.outbox.version = version;
    }

    /// The protocol version of [`send`](Self::send).
    pub fn version(&self) -> Version {
        self.outbox.version
    }

    /// Signs every MAVLink 2 frame sent from now on (`None`: stop).
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

    /// The parser's counters.
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
    pub fn transport(&self) -> &AsyncTransport {
        &self.transport
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_dialect::{Ping, TestDialect};
    use super::*;
    use ::tokio::time::{timeout, Duration};
    use std::net::TcpListener;

    fn block_on<F: core::future::Future>(f: F) -> F::Output {
        ::tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap()
            .block_on(f)
    }

    const LIMIT: Duration = Duration::from_secs(2);

    #[test]
    fn udp_both_ways() {
        block_on(async {
            let mut server =
                AsyncConnection::<TestDialect>::open(&"udpin:127.0.0.1:0".parse().unwrap())
                    .await
                    .unwrap();
            let port = server.transport().local_addr().unwrap().port();
            let target = Endpoint::UdpOut(SocketAddr::from((Ipv4Addr::LOCALHOST, port)).into());
            let mut client = AsyncConnection::<TestDialect>::open(&target).await.unwrap();
            // Nobody has spoken to the server yet: its send goes nowhere.
            server.send_auto(1, 1, &Ping { value: 0 }).await.unwrap();
            client.send_auto(2, 1, &Ping { value: 7 }).await.unwrap();
            client.send_auto(2, 1, &Ping { value: 8 }).await.unwrap();
            for v in [7, 8] {
                let f = timeout(LIMIT, server.recv()).await.unwrap().unwrap();
                assert_eq!(f.message(), Some(Ping { value: v }));
                assert_eq!(f.header().sysid, 2);
            }
            assert_eq!(server.stats().frames, 2);
            let client_port = client.transport().local_addr().unwrap().port();
            assert_eq!(
                server.transport().peer().map(|a| a.port()),
                Some(client_port)
            );
            server.send_auto(1, 1, &Ping { value: 9 }).await.unwrap();
            let f = timeout(LIMIT, client.recv()).await.unwrap().unwrap();
            assert_eq!(f.message(), Some(Ping { value: 9 }));
            assert_eq!(f.header().seq, 1, "the dropped send still took seq 0");
            // Cancelled receives lose nothing.
            assert!(timeout(Duration::from_millis(20), client.recv())
                .await
                .is_err());
            server.send_auto(1, 1, &Ping { value: 10 }).await.unwrap();
            let f = timeout(LIMIT, client.recv()).await.unwrap().unwrap();
            assert_eq!(f.message(), Some(Ping { value: 10 }));
        });
    }

    #[test]
    fn tcp_client_split_writes_and_eof() {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let addr = listener.local_addr().unwrap();
        let peer = std::thread::spawn(move || {
            use std::io::{Read, Write};
            let (mut s, _) = listener.accept().unwrap();
            s.set_read_timeout(Some(LIMIT)).unwrap();
            let mut out = Outbox::new();
            let mut bytes = std::vec::Vec::new();
            for v in 0..3 {
                let h = out.auto_header(1, 1);
                bytes.extend_from_slice(out.encode(Version::V2, h, &Ping { value: v }).unwrap());
            }
            // Cut inside headers and payloads, with pauses so the reads see
            // separate chunks.
            for chunk in bytes.chunks(5) {
                s.write_all(chunk).unwrap();
                std::thread::sleep(Duration::from_millis(2));
            }
            let mut got = [0u8; 64];
            let n = s.read(&mut got).unwrap();
            got[..n].to_vec()
            // `s` drops here: the client sees the end of the stream.
        });
        block_on(async {
            let mut client = AsyncConnection::<TestDialect>::open(&Endpoint::Tcp(addr.into()))
                .await
                .unwrap();
            for v in 0..3 {
                let f = timeout(LIMIT, client.recv()).await.unwrap().unwrap();
                assert_eq!(f.message(), Some(Ping { value: v }));
            }
            client.send_auto(3, 4, &Ping { value: 5 }).await.unwrap();
            let err = timeout(LIMIT, client.recv()).await.unwrap().unwrap_err();
            assert_eq!(err.kind(), io::ErrorKind::UnexpectedEof);
        });
        let sent = peer.join().unwrap();
        let mut parser = Parser::<TestDialect>::new();
        let mut input = &sent[..];
        let f = parser.next(&mut input).unwrap();
        assert_eq!(
            f.frame.header(),
            Header {
                seq: 0,
                sysid: 3,
                compid: 4
            }
        );
        assert_eq!(f.message(), Some(Ping { value: 5 }));
    }

    /// As the blocking connection: a datagram's end ends the frames in it,
    /// so a false header there does not hold the next datagram's frame.
    #[test]
    fn udp_false_header_at_a_datagrams_end_is_given_up() {
        block_on(async {
            let mut server =
                AsyncConnection::<TestDialect>::open(&"udpin:127.0.0.1:0".parse().unwrap())
                    .await
                    .unwrap();
            assert!(server.transport().is_datagram());
            let port = server.transport().local_addr().unwrap().port();
            let target = Endpoint::UdpOut(SocketAddr::from((Ipv4Addr::LOCALHOST, port)).into());
            let mut client = AsyncConnection::<TestDialect>::open(&target).await.unwrap();
            // Ping (known id) claiming a 200-byte payload.
            let false_header = [0xFD, 200, 0, 0, 0, 1, 1, 1, 0, 0];
            client.send_raw(&false_header).await.unwrap();
            client.send_auto(2, 1, &Ping { value: 11 }).await.unwrap();
            let f = timeout(LIMIT, server.recv()).await.unwrap().unwrap();
            assert_eq!(f.message(), Some(Ping { value: 11 }));
            assert_eq!(server.stats().bytes_dropped, 10);
        });
    }

    #[test]
    fn tcpin_and_serial_are_refused() {
        block_on(async {
            for s in ["tcpin:127.0.0.1:0", "serial:/dev/null"] {
                let err = AsyncTransport::open(&s.parse().unwrap()).await.unwrap_err();
                assert_eq!(err.kind(), io::ErrorKind::Unsupported);
            }
        });
    }
}
