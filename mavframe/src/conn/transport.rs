//! The blocking byte transport under a [`Connection`](super::Connection),
//! and [`open`] for an [`Endpoint`].

use super::endpoint::Endpoint;
use super::file::FileLink;
use super::tcp::{TcpClient, TcpServer};
use super::udp::{UdpBcast, UdpIn, UdpOut};
use std::boxed::Box;
use std::io;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

/// Moves bytes over one link, blocking.
///
/// MAVLink frames go out whole (one `send` per frame, so a datagram
/// transport sends one frame per datagram); bytes come in as the link
/// delivers them, in any chunking: the parser above reassembles frames.
pub trait Transport {
    /// Sends one frame (or any bytes) to the peer or peers.
    fn send(&mut self, frame: &[u8]) -> io::Result<()>;

    /// Waits up to `timeout` (`None`: without limit; zero: only what is
    /// already there) for bytes and reads them into `buf`; returns their
    /// count, never 0 except when the time ran out with no data. A stream
    /// closed by its peer is an error (`UnexpectedEof`), not 0.
    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize>;

    /// True when each [`recv`](Self::recv) returns one whole datagram, in
    /// which frames never continue into the next (MAVLink over UDP): the
    /// connection then tells its parser where each ends, so a candidate cut
    /// by a datagram's end is given up at once instead of waiting for bytes
    /// that can never complete it (and holding back the frames after its
    /// start byte). False (the default) for byte streams (TCP, serial),
    /// where the rest of a frame may still come.
    fn is_datagram(&self) -> bool {
        false
    }

    /// The connection's parser accepted a frame from the bytes the last
    /// [`recv`](Self::recv) returned (an authenticated frame, when the
    /// parser verifies signatures): [`Connection`](super::Connection)
    /// calls this once per such frame, never for bytes that hold none. A
    /// transport that serves several remote ends decides whom it answers
    /// from this, never from bytes alone: [`UdpIn`] and [`UdpBcast`] make
    /// the sender a peer (see [`crate::peers`]). Does nothing by default.
    fn accepted(&mut self) {}
}

/// A transport behind a pointer is that transport.
macro_rules! forward {
    ($($ptr:ty),*) => {$(
        impl<T: Transport + ?Sized> Transport for $ptr {
            fn send(&mut self, frame: &[u8]) -> io::Result<()> {
                (**self).send(frame)
            }

            fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
                (**self).recv(buf, timeout)
            }

            fn is_datagram(&self) -> bool {
                (**self).is_datagram()
            }

            fn accepted(&mut self) {
                (**self).accepted()
            }
        }
    )*};
}
forward!(Box<T>, &mut T);

/// Any transport an [`Endpoint`] names, as [`open`] returns it.
///
/// An enum rather than `Box<dyn Transport>`: no allocation or dynamic call
/// per frame, the concrete transport stays reachable (its local address,
/// the last UDP peer, the TCP server's clients), and `Send` follows from the
/// variants. Custom transports plug into
/// [`Connection`](super::Connection) through its type parameter instead.
/// Non-exhaustive because the `serial` feature adds a variant.
#[derive(Debug)]
#[non_exhaustive]
pub enum AnyTransport {
    /// `udpin:`
    UdpIn(UdpIn),
    /// `udpout:`
    UdpOut(UdpOut),
    /// `udpbcast:`
    UdpBcast(UdpBcast),
    /// `file:`
    File(FileLink),
    /// `tcp:`
    Tcp(TcpClient),
    /// `tcpin:`
    TcpIn(TcpServer),
    /// `serial:` (feature `serial`)
    #[cfg(feature = "serial")]
    Serial(super::serial::Serial),
}

/// Opens the transport `endpoint` names: resolves host names, binds,
/// connects or opens the device now, so errors (a name that does not
/// resolve, address in use, connection refused, no such device) surface
/// here. A host name is resolved once, here: the link keeps the address
/// it got (see [`Address::resolve`](super::Address::resolve); a TCP
/// client tries each address in turn, UDP uses the first). A name that
/// does not resolve is an error of kind [`io::ErrorKind::NotFound`]
/// holding a [`ResolveError`](super::ResolveError).
///
/// Without the `serial` feature a `serial:` endpoint fails with
/// [`io::ErrorKind::Unsupported`].
pub fn open(endpoint: &Endpoint) -> io::Result<AnyTransport> {
    Ok(match endpoint {
        Endpoint::UdpIn(addr) => AnyTransport::UdpIn(UdpIn::bind(addr.resolve_first()?)?),
        Endpoint::UdpOut(addr) => AnyTransport::UdpOut(UdpOut::new(addr.resolve_first()?)?),
        Endpoint::UdpBcast(addr) => AnyTransport::UdpBcast(UdpBcast::new(addr.resolve_first()?)?),
        Endpoint::Tcp(addr) => AnyTransport::Tcp(TcpClient::connect_any(&addr.resolve()?)?),
        Endpoint::TcpIn(addr) => AnyTransport::TcpIn(TcpServer::bind(addr.resolve_first()?)?),
        Endpoint::File(path) => AnyTransport::File(FileLink::open(path)?),
        #[cfg(feature = "serial")]
        Endpoint::Serial { path, baud } => {
            AnyTransport::Serial(super::serial::Serial::open(path, *baud)?)
        }
        #[cfg(not(feature = "serial"))]
        Endpoint::Serial { .. } => {
            return Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "serial endpoints need mavframe's `serial` feature",
            ))
        }
    })
}

impl AnyTransport {
    /// The sender of the last datagram a UDP transport received: every
    /// frame a [`Connection`](super::Connection) returns came from it
    /// (which makes it no peer: see [`Transport::accepted`]). `None` for
    /// other transports, or before any datagram.
    pub fn last_source(&self) -> Option<SocketAddr> {
        match self {
            AnyTransport::UdpIn(t) => t.last_source(),
            AnyTransport::UdpOut(t) => t.last_source(),
            AnyTransport::UdpBcast(t) => t.last_source(),
            _ => None,
        }
    }

    /// The local address of a network transport (the port the system chose
    /// when the endpoint said 0); `Unsupported` for a serial port or file.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        match self {
            AnyTransport::UdpIn(t) => t.local_addr(),
            AnyTransport::UdpOut(t) => t.local_addr(),
            AnyTransport::UdpBcast(t) => t.local_addr(),
            AnyTransport::File(_) => Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "a file has no network address",
            )),
            AnyTransport::Tcp(t) => t.local_addr(),
            AnyTransport::TcpIn(t) => t.local_addr(),
            #[cfg(feature = "serial")]
            AnyTransport::Serial(_) => Err(io::Error::new(
                io::ErrorKind::Unsupported,
                "a serial port has no network address",
            )),
        }
    }
}

/// `$e` for the transport inside `$any`, named `$t`.
macro_rules! each {
    ($any:expr, $t:ident => $e:expr) => {
        match $any {
            AnyTransport::UdpIn($t) => $e,
            AnyTransport::UdpOut($t) => $e,
            AnyTransport::UdpBcast($t) => $e,
            AnyTransport::File($t) => $e,
            AnyTransport::Tcp($t) => $e,
            AnyTransport::TcpIn($t) => $e,
            #[cfg(feature = "serial")]
            AnyTransport::Serial($t) => $e,
        }
    };
}

impl Transport for AnyTransport {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        each!(self, t => t.send(frame))
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        each!(self, t => t.recv(buf, timeout))
    }

    fn is_datagram(&self) -> bool {
        each!(self, t => t.is_datagram())
    }

    fn accepted(&mut self) {
        each!(self, t => t.accepted())
    }
}

/// A point in time a wait must end by, from a caller's timeout.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Deadline(Option<Instant>);

impl Deadline {
    pub(crate) fn after(timeout: Option<Duration>) -> Self {
        // A timeout too far ahead to represent is no limit.
        Deadline(timeout.and_then(|t| Instant::now().checked_add(t)))
    }

    /// Time left: `None` without a limit, zero once passed.
    pub(crate) fn remaining(&self) -> Option<Duration> {
        self.0.map(|d| d.saturating_duration_since(Instant::now()))
    }

    pub(crate) fn passed(&self) -> bool {
        self.remaining() == Some(Duration::ZERO)
    }
}

/// How a std socket is set up to wait, as far as known, so a read with the
/// same timeout as the last one costs no system call to set up.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(crate) struct ReadMode {
    /// `None` while unknown (new socket, or a call failed half-way).
    nonblocking: Option<bool>,
    read_timeout: Option<Option<Duration>>,
    /// Another handle (a split-off sender) shares the socket, and with it
    /// the non-blocking flag: reads never set it, so that sender's writes
    /// never fail half-way with `WouldBlock`.
    shared: bool,
}

/// A zero-timeout read on a shared socket: the shortest wait a read
/// timeout can express without the non-blocking flag.
pub(crate) const SHARED_POLL: Duration = Duration::from_millis(1);

impl ReadMode {
    /// Another handle shares the socket from now on (see `shared`).
    pub(crate) fn share(&mut self) {
        self.shared = true;
    }
}

/// Mode setters shared by `UdpSocket` and `TcpStream`.
pub(crate) trait SetReadMode {
    fn set_nonblocking(&self, on: bool) -> io::Result<()>;
    fn set_read_timeout(&self, t: Option<Duration>) -> io::Result<()>;

    /// Makes the socket block (or not), if it does not already.
    fn ensure_nonblocking(&self, mode: &mut ReadMode, on: bool) -> io::Result<()> {
        if mode.nonblocking != Some(on) {
            mode.nonblocking = None;
            self.set_nonblocking(on)?;
            mode.nonblocking = Some(on);
        }
        Ok(())
    }

    /// Sets the socket up for a read waiting `timeout`. A zero timeout is
    /// a non-blocking read: std refuses a zero read timeout.
    fn prepare_read(&self, mode: &mut ReadMode, timeout: Option<Duration>) -> io::Result<()> {
        let timeout = match timeout {
            Some(Duration::ZERO) if mode.shared => Some(SHARED_POLL),
            Some(Duration::ZERO) => return self.ensure_nonblocking(mode, true),
            t => t,
        };
        self.ensure_nonblocking(mode, false)?;
        if mode.read_timeout != Some(timeout) {
            mode.read_timeout = None;
            self.set_read_timeout(timeout)?;
            mode.read_timeout = Some(timeout);
        }
        Ok(())
    }
}

impl SetReadMode for std::net::UdpSocket {
    fn set_nonblocking(&self, on: bool) -> io::Result<()> {
        std::net::UdpSocket::set_nonblocking(self, on)
    }
    fn set_read_timeout(&self, t: Option<Duration>) -> io::Result<()> {
        std::net::UdpSocket::set_read_timeout(self, t)
    }
}

impl SetReadMode for std::net::TcpStream {
    fn set_nonblocking(&self, on: bool) -> io::Result<()> {
        std::net::TcpStream::set_nonblocking(self, on)
    }
    fn set_read_timeout(&self, t: Option<Duration>) -> io::Result<()> {
        std::net::TcpStream::set_read_timeout(self, t)
    }
}

/// A byte stream's [`Transport::recv`] (TCP, serial): `read` waits up to
/// the time it is given (`None`: without limit). 0 once `timeout` ran out
/// with no data; a stream its peer closed is an `UnexpectedEof` error
/// (`closed` says what closed), so that 0 keeps meaning "timed out".
pub(crate) fn recv_stream(
    buf: &mut [u8],
    timeout: Option<Duration>,
    closed: &str,
    mut read: impl FnMut(&mut [u8], Option<Duration>) -> io::Result<usize>,
) -> io::Result<usize> {
    if buf.is_empty() {
        return Ok(0);
    }
    let deadline = Deadline::after(timeout);
    loop {
        match read(buf, deadline.remaining()) {
            Ok(0) => return Err(io::Error::new(io::ErrorKind::UnexpectedEof, closed)),
            Ok(n) => return Ok(n),
            Err(e) if is_timeout(&e) || e.kind() == io::ErrorKind::Interrupted => {
                if deadline.passed() {
                    return Ok(0);
                }
            }
            Err(e) => return Err(e),
        }
    }
}

/// True for the errors a timed-out or non-blocking read reports (Unix says
/// `WouldBlock`, Windows `TimedOut`).
pub(crate) fn is_timeout(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
    )
}
