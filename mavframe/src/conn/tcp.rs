//! TCP transports: `tcp` (client) and `tcpin` (server for many clients).

use super::transport::{recv_stream, Deadline, ReadMode, SetReadMode, Transport};
use crate::frame::{frame_len, FrameError};
use core::fmt;
use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::time::Duration;
use std::vec::Vec;

/// `tcp:`: a TCP client.
///
/// Nagle's algorithm is off (`TCP_NODELAY`): frames are small and
/// latency-sensitive. A closed connection is an `UnexpectedEof` error from
/// [`recv`](Transport::recv); reconnecting is the caller's choice (open the
/// endpoint again).
#[derive(Debug)]
pub struct TcpClient {
    stream: TcpStream,
    mode: ReadMode,
}

impl TcpClient {
    /// Connects to `addr`, waiting as long as the system does.
    pub fn connect(addr: SocketAddr) -> io::Result<Self> {
        Self::from_stream(TcpStream::connect(addr)?)
    }

    /// Connects to the first of `addrs` that accepts (a host name's
    /// addresses); the last error when none does.
    pub fn connect_any(addrs: &[SocketAddr]) -> io::Result<Self> {
        Self::from_stream(TcpStream::connect(addrs)?)
    }

    /// Connects to `addr`, giving up after `timeout`.
    pub fn connect_timeout(addr: SocketAddr, timeout: Duration) -> io::Result<Self> {
        Self::from_stream(TcpStream::connect_timeout(&addr, timeout)?)
    }

    /// Wraps a connected stream (sets `TCP_NODELAY`).
    pub fn from_stream(stream: TcpStream) -> io::Result<Self> {
        stream.set_nodelay(true)?;
        Ok(TcpClient {
            stream,
            mode: ReadMode::default(),
        })
    }

    /// The local address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.stream.local_addr()
    }

    /// The server's address.
    pub fn peer_addr(&self) -> io::Result<SocketAddr> {
        self.stream.peer_addr()
    }

    /// The stream, for options this type does not cover (a write timeout,
    /// for one: writes block until the peer takes the bytes).
    pub fn get_ref(&self) -> &TcpStream {
        &self.stream
    }
}

impl TcpClient {
    /// The send half's handle: a clone of the stream, left blocking.
    pub(crate) fn split_sender(&mut self) -> io::Result<TcpStream> {
        self.mode.share();
        self.stream.ensure_nonblocking(&mut self.mode, false)?;
        self.stream.try_clone()
    }
}

impl Transport for TcpClient {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        // A zero-timeout recv leaves the socket non-blocking, and a write
        // cut short by WouldBlock would leave half a frame on the stream.
        self.stream.ensure_nonblocking(&mut self.mode, false)?;
        self.stream.write_all(frame)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        let (stream, mode) = (&mut self.stream, &mut self.mode);
        recv_stream(buf, timeout, "connection closed by peer", |buf, wait| {
            stream.prepare_read(mode, wait)?;
            stream.read(buf)
        })
    }
}

/// Output a slow client may have pending before it is dropped: 64 KiB,
/// about 240 full-size frames. Blocking on one stalled client would stall
/// every other client, and cutting a frame short would corrupt its stream.
pub const MAX_PENDING_OUTPUT: usize = 64 * 1024;

const LISTENER: mio::Token = mio::Token(usize::MAX);

struct Client {
    stream: mio::net::TcpStream,
    addr: SocketAddr,
    token: mio::Token,
    /// Read until `WouldBlock` clears it: readiness is edge-triggered.
    readable: bool,
    /// Bytes accepted by `send` that the socket has not taken yet.
    out: Vec<u8>,
    /// The start of a frame whose end has not arrived (less than a frame).
    held: Vec<u8>,
    /// Closed or failed: removed at the next clean-up.
    dead: bool,
}

impl Client {
    /// Writes pending output until done or the socket is full.
    fn flush(&mut self) -> io::Result<()> {
        let n = write_some(&mut self.stream, &self.out)?;
        self.out.drain(..n);
        Ok(())
    }

    /// Queues `frame` behind pending output, writing what the socket takes
    /// now; false when the client must be dropped.
    fn send(&mut self, frame: &[u8]) -> bool {
        if self.flush().is_err() {
            return false;
        }
        let written = if self.out.is_empty() {
            match write_some(&mut self.stream, frame) {
                Ok(n) => n,
                Err(_) => return false,
            }
        } else {
            0
        };
        let rest = &frame[written..];
        if self.out.len() + rest.len() > MAX_PENDING_OUTPUT {
            return false;
        }
        self.out.extend_from_slice(rest);
        true
    }

    /// One read into `buf` after the bytes held from the last one; returns
    /// the bytes up to the last frame boundary and holds the rest, or
    /// `None` when nothing can be returned yet (or the client is gone).
    fn read(&mut self, buf: &mut [u8]) -> Option<usize> {
        let held = self.held.len();
        if held >= buf.len() {
            // A buffer too small to hold a frame: pass bytes on uncut.
            let n = buf.len();
            buf.copy_from_slice(&self.held[..n]);
            self.held.drain(..n);
            return Some(n);
        }
        buf[..held].copy_from_slice(&self.held);
        match self.stream.read(&mut buf[held..]) {
            Ok(0) => self.dead = true,
            Ok(n) => {
                let total = held + n;
                let cut = whole_frames(&buf[..total]);
                self.held.clear();
                self.held.extend_from_slice(&buf[cut..total]);
                if cut > 0 {
                    return Some(cut);
                }
            }
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => self.readable = false,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(_) => self.dead = true,
        }
        None
    }
}

/// Writes as much of `data` as a non-blocking socket takes now.
fn write_some(stream: &mut mio::net::TcpStream, data: &[u8]) -> io::Result<usize> {
    let mut done = 0;
    while done < data.len() {
        match stream.write(&data[done..]) {
            Ok(0) => return Err(io::ErrorKind::WriteZero.into()),
            Ok(n) => done += n,
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(done)
}

/// `tcpin:`: a TCP server: accepts clients, sends every frame to all of
/// them, receives from any.
///
/// Everything happens inside [`send`](Transport::send) and
/// [`recv`](Transport::recv), on the caller's thread: new clients are
/// accepted without blocking, sockets are non-blocking, and `recv` waits
/// on all of them at once through mio (std cannot wait on several
/// sockets). A client that closes or fails, or falls more than
/// [`MAX_PENDING_OUTPUT`] bytes behind, is dropped; the others go on. With
/// no client connected, `send` succeeds and sends nothing. `recv` takes
/// turns between clients with data, so a busy one cannot starve the rest,
/// and returns one client's bytes at a time, up to a frame boundary: the
/// start of a frame whose end has not arrived waits in that client's
/// buffer, so frames of different clients never interleave.
pub struct TcpServer {
    poll: mio::Poll,
    events: mio::Events,
    listener: mio::net::TcpListener,
    clients: Vec<Client>,
    next_token: usize,
    /// Round-robin start for the next read.
    next_read: usize,
}

impl fmt::Debug for TcpServer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("TcpServer")
            .field("local_addr", &self.listener.local_addr().ok())
            .field(
                "clients",
                &self.clients.iter().map(|c| c.addr).collect::<Vec<_>>(),
            )
            .finish()
    }
}

impl TcpServer {
    /// Listens on `addr` (port 0: the system picks one, see
    /// [`local_addr`](Self::local_addr)).
    pub fn bind(addr: SocketAddr) -> io::Result<Self> {
        let poll = mio::Poll::new()?;
        let mut listener = mio::net::TcpListener::bind(addr)?;
        poll.registry()
            .register(&mut listener, LISTENER, mio::Interest::READABLE)?;
        Ok(TcpServer {
            poll,
            events: mio::Events::with_capacity(64),
            listener,
            clients: Vec::new(),
            next_token: 0,
            next_read: 0,
        })
    }

    /// The listening address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.listener.local_addr()
    }

    /// Addresses of the connected clients (as of the last `send`/`recv`).
    pub fn clients(&self) -> impl Iterator<Item = SocketAddr> + '_ {
        self.clients.iter().filter(|c| !c.dead).map(|c| c.addr)
    }

    /// Accepts every client waiting, without blocking.
    pub fn accept_pending(&mut self) {
        loop {
            match self.listener.accept() {
                Ok((mut stream, addr)) => {
                    let token = mio::Token(self.next_token);
                    self.next_token = (self.next_token + 1) % LISTENER.0;
                    // Small frames, latency-sensitive; a failure here is harmless.
                    let _ = stream.set_nodelay(true);
                    let interest = mio::Interest::READABLE | mio::Interest::WRITABLE;
                    if self
                        .poll
                        .registry()
                        .register(&mut stream, token, interest)
                        .is_ok()
                    {
                        self.clients.push(Client {
                            stream,
                            addr,
                            token,
                            // Data may have come before registration.
                            readable: true,
                            out: Vec::new(),
                            held: Vec::new(),
                            dead: false,
                        });
                    }
                }
                // A client that gave up before we accepted it: try the next.
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::ConnectionAborted
                            | io::ErrorKind::ConnectionReset
                            | io::ErrorKind::Interrupted
                    ) => {}
                // WouldBlock: none left. Anything else (out of descriptors)
                // is retried on the next call rather than failing the server.
                Err(_) => break,
            }
        }
    }

    /// Removes dead clients, closing their sockets.
    fn remove_dead(&mut self) {
        let registry = self.poll.registry();
        self.clients.retain_mut(|c| {
            if c.dead {
                // Dropping closes the socket; deregister first, as mio asks.
                let _ = registry.deregister(&mut c.stream);
            }
            !c.dead
        });
    }

    /// One read from the next client with data, in turn, cut at a frame
    /// boundary (see [`whole_frames`]).
    fn read_ready(&mut self, buf: &mut [u8]) -> Option<usize> {
        let count = self.clients.len();
        let mut got = None;
        for k in 0..count {
            let i = (self.next_read + k) % count;
            let c = &mut self.clients[i];
            while got.is_none() && c.readable && !c.dead {
                got = c.read(buf);
            }
            if got.is_some() {
                self.next_read = i + 1;
                break;
            }
        }
        self.remove_dead();
        got
    }
}

/// The length of `bytes` up to the end of its last whole frame: bytes that
/// start no frame pass, a frame its header says is incomplete is held.
///
/// The server merges its clients' streams into one: cutting each client's
/// bytes at frame boundaries keeps a frame split across TCP segments from
/// being interleaved with another client's bytes, which would lose it.
fn whole_frames(bytes: &[u8]) -> usize {
    let mut at = 0;
    while at < bytes.len() {
        match frame_len(&bytes[at..]) {
            Ok(n) if n <= bytes.len() - at => at += n,
            Ok(_) | Err(FrameError::Incomplete { .. }) => return at,
            // Not a start byte, or flags that make the length unknowable:
            // the parser decides what these bytes are.
            Err(_) => at += 1,
        }
    }
    at
}

impl Transport for TcpServer {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.accept_pending();
        for c in &mut self.clients {
            if !c.send(frame) {
                c.dead = true;
            }
        }
        self.remove_dead();
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        if buf.is_empty() {
            return Ok(0);
        }
        let deadline = Deadline::after(timeout);
        let mut polled = false;
        loop {
            self.accept_pending();
            // A writable event may be what woke us: move pending output on.
            for c in &mut self.clients {
                if !c.out.is_empty() && c.flush().is_err() {
                    c.dead = true;
                }
            }
            if let Some(n) = self.read_ready(buf) {
                return Ok(n);
            }
            let remaining = deadline.remaining();
            if polled && remaining == Some(Duration::ZERO) {
                return Ok(0);
            }
            match self.poll.poll(&mut self.events, remaining) {
                Ok(()) => {}
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
            polled = true;
            for event in self.events.iter() {
                if event.token() == LISTENER {
                    continue; // accept_pending runs on every turn
                }
                if event.is_readable() || event.is_read_closed() || event.is_error() {
                    if let Some(c) = self.clients.iter_mut().find(|c| c.token == event.token()) {
                        c.readable = true;
                    }
                }
            }
        }
    }
}
