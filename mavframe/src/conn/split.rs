//! [`Connection::split`]: a send half and a receive half that two threads
//! can use at once (one blocked in `recv` while the other sends).

use super::transport::AnyTransport;
use super::udp::UdpSender;
#[cfg(feature = "serial")]
use super::Transport;
use super::{recv, ConnInbox, Connection, ReceivedBuf};
use crate::frame::{Header, Version};
use crate::framer::Framer;
use crate::link::LinkCore;
use crate::message::{Encode, MessageSet};
use crate::parser::{LinkStats, Parser, Stats};
use crate::signing::Signer;
use core::fmt;
use std::boxed::Box;
use std::io::{self, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// The half that writes to the link.
#[derive(Debug)]
enum SendHalf {
    Udp(UdpSender),
    Tcp(TcpStream),
    #[cfg(feature = "serial")]
    Serial(super::serial::Serial),
    /// `file:`: nothing can be sent (see [`FileLink`](super::FileLink)).
    ReadOnly,
}

impl SendHalf {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        match self {
            // udpin before any peer: dropped, as the whole link does.
            SendHalf::Udp(udp) => udp.send(frame),
            // Blocking (split leaves the stream so): all or an error.
            SendHalf::Tcp(stream) => stream.write_all(frame),
            #[cfg(feature = "serial")]
            SendHalf::Serial(port) => port.send(frame),
            SendHalf::ReadOnly => Err(super::file::read_only()),
        }
    }
}

/// The sending half of a split [`Connection`]: owns the sending state
/// (version, sequence number, signer) and a handle on the link; `Send`,
/// so it can move to another thread while the [`Receiver`] blocks in
/// `recv`. Wrap it in a `Mutex` to send from several threads.
///
/// Made by [`Connection::split`], whose example sends from a thread of
/// its own while the receiving half waits.
#[derive(Debug)]
pub struct Sender {
    half: SendHalf,
    framer: Framer,
    /// What the [`Receiver`]'s verifier accepted, which the signer adopts.
    verified: Arc<AtomicU64>,
}

impl Sender {
    /// Sends `msg` with `header` (see [`Connection::send`]).
    pub fn send<M: Encode + ?Sized>(&mut self, header: Header, msg: &M) -> io::Result<()> {
        self.send_version(self.framer.version(), header, msg)
    }

    /// Sends `msg` with `header` in `version` (see
    /// [`Connection::send_version`]).
    pub fn send_version<M: Encode + ?Sized>(
        &mut self,
        version: Version,
        header: Header,
        msg: &M,
    ) -> io::Result<()> {
        self.framer.adopt(self.verified.load(Ordering::Relaxed));
        let frame = self.framer.frame_as(version, header, msg)?;
        self.half.send(frame)
    }

    /// Sends `msg` with the next sequence number (see
    /// [`Connection::send_auto`]).
    pub fn send_auto<M: Encode + ?Sized>(
        &mut self,
        sysid: u8,
        compid: u8,
        msg: &M,
    ) -> io::Result<()> {
        let header = self.framer.next_header(sysid, compid);
        self.send(header, msg)
    }

    /// Sends bytes as they are.
    pub fn send_raw(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.half.send(bytes)
    }

    /// Sets the protocol version of [`send`](Self::send).
    pub fn set_version(&mut self, version: Version) {
        self.framer.set_version(version);
    }

    /// Signs every MAVLink 2 frame sent from now on (`None`: stop).
    pub fn set_signer(&mut self, signer: Option<Signer>) {
        self.framer.set_signer(signer);
    }

    /// The signer, if frames are signed.
    pub fn signer(&self) -> Option<&Signer> {
        self.framer.signer()
    }

    /// The sequence number [`send_auto`](Self::send_auto) uses next.
    pub fn next_seq(&self) -> u8 {
        self.framer.seq()
    }

    /// Where a UDP link's next frame goes (`None`: nowhere yet, or not
    /// UDP); with several peers, the one heard most recently.
    pub fn peer(&self) -> Option<SocketAddr> {
        match &self.half {
            SendHalf::Udp(udp) => udp.peer(),
            _ => None,
        }
    }
}

/// The receiving half of a split [`Connection`]: the transport (used only
/// to read) and the parser.
///
/// Made by [`Connection::split`] (an example there).
pub struct Receiver<D: MessageSet> {
    transport: AnyTransport,
    inbox: ConnInbox<D>,
    /// Shared with the [`Sender`]: what the verifier accepted.
    verified: Arc<AtomicU64>,
}

impl<D: MessageSet> fmt::Debug for Receiver<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Receiver")
            .field("transport", &self.transport)
            .field("parser", self.parser())
            .finish()
    }
}

impl<D: MessageSet> Receiver<D> {
    /// The next frame (see [`Connection::recv`]). A zero timeout waits up
    /// to [`SPLIT_ZERO_WAIT`] on a network link: the halves share the
    /// socket's non-blocking flag, which the receiver must not set under
    /// the sender's writes.
    pub fn recv(&mut self, timeout: Option<Duration>) -> io::Result<Option<ReceivedBuf<D>>> {
        let frame = recv(&mut self.inbox, &mut self.transport, timeout)?;
        if let Some(v) = self.inbox.parser.verifier() {
            self.verified
                .fetch_max(v.newest_timestamp(), Ordering::Relaxed);
        }
        Ok(frame)
    }

    /// The parser's counters.
    pub fn stats(&self) -> &Stats {
        self.parser().stats()
    }

    /// Sequence statistics per sender.
    pub fn links(&self) -> &[LinkStats] {
        self.parser().links()
    }

    /// The parser.
    pub fn parser(&self) -> &Parser<D> {
        &self.inbox.parser
    }

    /// The transport (for its addresses; reading from it directly
    /// bypasses the parser).
    pub fn transport(&self) -> &AnyTransport {
        &self.transport
    }
}

/// How long a split [`Receiver`]'s zero-timeout `recv` may wait on a
/// network link (see [`Receiver::recv`]).
pub const SPLIT_ZERO_WAIT: Duration = super::transport::SHARED_POLL;

/// A connection that cannot be split, handed back whole with the reason.
pub struct SplitError<D: MessageSet> {
    /// The connection, unchanged apart from what a failed handle clone
    /// may have left set (a UDP or TCP socket's blocking mode).
    pub connection: Box<Connection<D>>,
    /// Why: `Unsupported` for `tcpin:`, or the system's error cloning
    /// the handle.
    pub error: io::Error,
}

impl<D: MessageSet> fmt::Debug for SplitError<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SplitError")
            .field("error", &self.error)
            .finish_non_exhaustive()
    }
}

impl<D: MessageSet> fmt::Display for SplitError<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "cannot split the connection: {}", self.error)
    }
}

impl<D: MessageSet> core::error::Error for SplitError<D> {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        Some(&self.error)
    }
}

/// The send half for `transport`, which keeps the receiving.
fn send_half(transport: &mut AnyTransport) -> io::Result<SendHalf> {
    Ok(match transport {
        AnyTransport::UdpIn(t) => SendHalf::Udp(t.split_sender()?),
        AnyTransport::UdpOut(t) => SendHalf::Udp(t.split_sender()?),
        AnyTransport::UdpBcast(t) => SendHalf::Udp(t.split_sender()?),
        AnyTransport::Tcp(t) => SendHalf::Tcp(t.split_sender()?),
        AnyTransport::File(_) => SendHalf::ReadOnly,
        #[cfg(feature = "serial")]
        AnyTransport::Serial(t) => SendHalf::Serial(t.split_sender()?),
        // The server's accepting, per-client output queues and reads all
        // run inside its own send/recv on one mio poll: two threads would
        // have to share that state under a lock held across the wait.
        AnyTransport::TcpIn(_) => {
            return Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "a tcpin: server cannot be split: its clients, queues and poll are one state; \
                 share the Connection behind a Mutex, or use the tokio router",
            ))
        }
    })
}

impl<D: MessageSet> Connection<D, AnyTransport> {
    /// Splits the connection into a [`Sender`] and a [`Receiver`] that
    /// two threads can use at once, e.g. one blocked in `recv` while the
    /// other sends heartbeats. The sender takes the sending state
    /// (version, sequence number, signer) and a second handle on the link
    /// (`try_clone` of the UDP or TCP socket or the serial port); the
    /// receiver keeps the transport and the parser with any bytes it
    /// held.
    ///
    /// `udpin:` and `udpbcast:` senders send to the receiver's peers as
    /// the whole link does (under `udpin:`'s `ReplyTo::Owner`, those given
    /// before the split); a `Fixed` rule is taken as it is. A
    /// `file:` sender refuses to send, as the link does. A `tcpin:`
    /// server cannot be split ([`SplitError`] hands the connection back).
    ///
    /// ```
    /// # use mavframe::{BufferTooSmall, MessageSet, MessageData, MessageMeta};
    /// # #[derive(Clone, Debug, PartialEq, Default)] struct Ping;
    /// # impl MessageData for Ping {
    /// #   const META: MessageMeta = MessageMeta::new(4, "PING", 237, 0, 0, &[]);
    /// #   type View<'a> = ();
    /// #   fn parse(_: &[u8]) -> Self { Ping }
    /// #   fn emit(&self, _: &mut [u8]) -> Result<usize, BufferTooSmall> { Ok(0) }
    /// #   fn view(_: &[u8]) {}
    /// # }
    /// # struct MyDialect; impl MessageSet for MyDialect { type Message = Ping; type View<'a> = ();
    /// #   const MESSAGES: &'static [MessageMeta] = &[Ping::META];
    /// #   fn parse(id: u32, _: &[u8]) -> Option<Ping> { (id == 4).then_some(Ping) }
    /// #   fn view(_: u32, _: &[u8]) -> Option<()> { None } }
    /// use mavframe::conn::Connection;
    /// use std::time::Duration;
    ///
    /// let server = Connection::<MyDialect>::open(&"udpin:127.0.0.1:0".parse()?)?;
    /// let port = server.transport().local_addr()?.port();
    /// let client = Connection::<MyDialect>::open(&format!("udpout:127.0.0.1:{port}").parse()?)?;
    /// let (mut tx, _rx) = client.split()?;
    /// let (_, mut rx) = server.split()?;
    /// let sending = std::thread::spawn(move || tx.send_auto(1, 1, &Ping));
    /// let frame = rx.recv(Some(Duration::from_secs(5)))?.expect("a frame");
    /// assert_eq!(frame.message(), Some(Ping));
    /// sending.join().unwrap()?;
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn split(mut self) -> Result<(Sender, Receiver<D>), SplitError<D>> {
        match send_half(&mut self.transport) {
            Ok(half) => {
                let LinkCore { inbox, framer } = self.core;
                let verified = Arc::new(AtomicU64::new(0));
                let receiver = Receiver {
                    transport: self.transport,
                    inbox,
                    verified: verified.clone(),
                };
                let sender = Sender {
                    half,
                    framer,
                    verified,
                };
                Ok((sender, receiver))
            }
            Err(error) => Err(SplitError {
                connection: Box::new(self),
                error,
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_dialect::{Ping, TestDialect};
    use super::super::Endpoint;
    use super::*;
    use std::sync::mpsc;
    use std::thread;
    use std::vec::Vec;

    const WAIT: Option<Duration> = Some(Duration::from_secs(5));

    fn open(s: &str) -> Connection<TestDialect> {
        Connection::open(&s.parse::<Endpoint>().unwrap()).unwrap()
    }

    /// A receiver blocked in `recv` on one thread while another thread
    /// sends through the same link: the far end gets every frame, and
    /// the receiver gets the far end's replies, in order.
    fn exchange(
        mut near_tx: Sender,
        near_rx: Receiver<TestDialect>,
        mut far: Connection<TestDialect>,
    ) {
        const N: u32 = 100;
        let (done_tx, done_rx) = mpsc::channel();
        let receiving = thread::spawn(move || {
            let mut rx = near_rx;
            let mut got = Vec::new();
            while got.len() < N as usize {
                match rx.recv(WAIT).unwrap() {
                    Some(f) => got.push(f.message().unwrap()),
                    None => break,
                }
            }
            done_tx.send(()).unwrap();
            got
        });
        let sending = thread::spawn(move || {
            for v in 0..N {
                near_tx.send_auto(1, 1, &Ping { value: v }).unwrap();
            }
            near_tx
        });
        for v in 0..N {
            let f = far.recv(WAIT).unwrap().expect("a frame from the sender");
            assert_eq!(f.message(), Some(Ping { value: v }));
            far.send_auto(2, 1, &Ping { value: 1000 + v }).unwrap();
        }
        let got = receiving.join().unwrap();
        done_rx.recv().unwrap();
        let want: Vec<Ping> = (0..N).map(|v| Ping { value: 1000 + v }).collect();
        assert_eq!(got, want);
        assert_eq!(sending.join().unwrap().next_seq(), N as u8);
    }

    #[test]
    fn udp_halves_work_from_two_threads() {
        let server = open("udpin:127.0.0.1:0");
        let port = server.transport().local_addr().unwrap().port();
        let client = open(&std::format!("udpout:127.0.0.1:{port}"));
        let (tx, rx) = client.split().unwrap();
        // The client speaks first, so udpin learns whom to answer.
        exchange(tx, rx, server);
    }

    #[test]
    fn udpin_sender_follows_the_receivers_last_sender() {
        let server = open("udpin:127.0.0.1:0");
        let port = server.transport().local_addr().unwrap().port();
        let (mut tx, mut rx) = server.split().unwrap();
        assert_eq!(tx.peer(), None);
        tx.send_auto(1, 1, &Ping { value: 0 }).unwrap(); // dropped: nobody yet
        let mut client = open(&std::format!("udpout:127.0.0.1:{port}"));
        client.send_auto(2, 1, &Ping { value: 1 }).unwrap();
        assert!(rx.recv(WAIT).unwrap().is_some());
        let client_port = client.transport().local_addr().unwrap().port();
        assert_eq!(tx.peer().map(|a| a.port()), Some(client_port));
        tx.send_auto(1, 1, &Ping { value: 2 }).unwrap();
        let f = client.recv(WAIT).unwrap().unwrap();
        assert_eq!(f.message(), Some(Ping { value: 2 }));
    }

    #[test]
    fn tcp_halves_work_from_two_threads() {
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let client = open(&std::format!("tcp:127.0.0.1:{port}"));
        let (stream, _) = listener.accept().unwrap();
        let far = super::super::TcpClient::from_stream(stream).unwrap();
        let far = Connection::<TestDialect>::new(AnyTransport::Tcp(far));
        let (tx, rx) = client.split().unwrap();
        exchange(tx, rx, far);
    }

    /// A zero-timeout receive on a split link waits at most a moment and
    /// leaves the socket blocking, so the sender's writes stay whole.
    #[test]
    fn a_zero_timeout_receive_keeps_the_shared_socket_blocking() {
        let client = open("udpout:127.0.0.1:9");
        let (mut tx, mut rx) = client.split().unwrap();
        assert!(rx.recv(Some(Duration::ZERO)).unwrap().is_none());
        let AnyTransport::UdpOut(udp) = rx.transport() else {
            panic!()
        };
        // A non-blocking socket would read WouldBlock here at once; a
        // blocking one with a read timeout times out.
        let mut buf = [0u8; 8];
        udp.get_ref()
            .set_read_timeout(Some(Duration::from_millis(20)))
            .unwrap();
        let e = udp.get_ref().recv(&mut buf).unwrap_err();
        assert!(super::super::transport::is_timeout(&e));
        tx.send_auto(1, 1, &Ping { value: 1 }).unwrap();
    }

    #[test]
    fn tcpin_cannot_split_and_comes_back_whole() {
        let server = open("tcpin:127.0.0.1:0");
        let addr = server.transport().local_addr().unwrap();
        let err = server.split().unwrap_err();
        assert_eq!(err.error.kind(), io::ErrorKind::Unsupported);
        assert_eq!(err.connection.transport().local_addr().unwrap(), addr);
    }

    #[test]
    fn halves_cross_threads() {
        fn check<T: Send>() {}
        check::<Sender>();
        check::<Receiver<TestDialect>>();
    }
}
