//! UDP transports: `udpin` (listen, reply to the last peer) and `udpout`
//! (send to one address, receive replies).

use super::transport::{is_timeout, Deadline, ReadMode, SetReadMode, Transport};
use std::io;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};
use std::time::Duration;

/// Waits for one non-empty datagram; `None` when the time ran out.
fn recv_datagram(
    socket: &UdpSocket,
    mode: &mut ReadMode,
    buf: &mut [u8],
    timeout: Option<Duration>,
) -> io::Result<Option<(usize, SocketAddr)>> {
    let deadline = Deadline::after(timeout);
    loop {
        socket.prepare_read(mode, deadline.remaining())?;
        match socket.recv_from(buf) {
            // An empty datagram carries nothing for the parser, and 0 would
            // read as "timed out": keep waiting.
            Ok((0, _)) => {}
            Ok((n, from)) => return Ok(Some((n, from))),
            Err(e) if is_timeout(&e) => return Ok(None),
            // Windows reports an earlier send's ICMP "port unreachable" on
            // the next receive (Linux does not, on unconnected sockets): it
            // says nothing about incoming data, and a peer may start later.
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::ConnectionReset
                        | io::ErrorKind::ConnectionRefused
                        | io::ErrorKind::Interrupted
                ) => {}
            Err(e) => return Err(e),
        }
        if deadline.passed() {
            return Ok(None);
        }
    }
}

/// `udpin:`: a bound socket that answers whoever spoke last.
///
/// Until a first datagram arrives there is nobody to send to, and
/// [`send`](Transport::send) drops frames silently, as MAVProxy and
/// pymavlink do (a ground station's heartbeat loop must not fail before a
/// vehicle shows up). With several peers, replies follow the most recent
/// sender: this is a point-to-point link, not a router.
///
/// One [`send`](Transport::send) is one datagram, so each frame travels in
/// its own datagram, as MAVLink over UDP expects. A receive buffer should
/// hold a whole datagram (65,507 bytes; [`Connection`](super::Connection)'s
/// does): the system cuts a longer one short.
#[derive(Debug)]
pub struct UdpIn {
    socket: UdpSocket,
    peer: Option<SocketAddr>,
    mode: ReadMode,
}

impl UdpIn {
    /// Binds to `addr` (port 0: the system picks one, see
    /// [`local_addr`](Self::local_addr)).
    pub fn bind(addr: SocketAddr) -> io::Result<Self> {
        Ok(UdpIn {
            socket: UdpSocket::bind(addr)?,
            peer: None,
            mode: ReadMode::default(),
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// The peer replies go to: the sender of the last datagram received.
    pub fn peer(&self) -> Option<SocketAddr> {
        self.peer
    }

    /// The socket, for options this type does not cover.
    pub fn get_ref(&self) -> &UdpSocket {
        &self.socket
    }
}

impl Transport for UdpIn {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        match self.peer {
            Some(peer) => self.socket.send_to(frame, peer).map(drop),
            None => Ok(()),
        }
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        Ok(
            match recv_datagram(&self.socket, &mut self.mode, buf, timeout)? {
                Some((n, from)) => {
                    self.peer = Some(from);
                    n
                }
                None => 0,
            },
        )
    }

    fn is_datagram(&self) -> bool {
        true
    }
}

/// `udpout:`: sends to one address from an ephemeral port and receives
/// what comes back.
///
/// The socket is not `connect`ed: datagrams from any sender are received
/// (as pymavlink's `udpout` does, so a reply from another address of the
/// peer still arrives), and a peer that is not up yet causes no error on
/// later receives. Broadcast targets need
/// `get_ref().set_broadcast(true)`.
///
/// One [`send`](Transport::send) is one datagram, so each frame travels in
/// its own datagram, as MAVLink over UDP expects. A receive buffer should
/// hold a whole datagram (65,507 bytes; [`Connection`](super::Connection)'s
/// does): the system cuts a longer one short.
#[derive(Debug)]
pub struct UdpOut {
    socket: UdpSocket,
    target: SocketAddr,
    mode: ReadMode,
}

impl UdpOut {
    /// Binds an ephemeral port of `target`'s address family.
    pub fn new(target: SocketAddr) -> io::Result<Self> {
        let local = match target {
            SocketAddr::V4(_) => SocketAddr::from((Ipv4Addr::UNSPECIFIED, 0)),
            SocketAddr::V6(_) => SocketAddr::from((Ipv6Addr::UNSPECIFIED, 0)),
        };
        Ok(UdpOut {
            socket: UdpSocket::bind(local)?,
            target,
            mode: ReadMode::default(),
        })
    }

    /// The ephemeral local address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Where frames are sent.
    pub fn target(&self) -> SocketAddr {
        self.target
    }

    /// The socket, for options this type does not cover.
    pub fn get_ref(&self) -> &UdpSocket {
        &self.socket
    }
}

impl Transport for UdpOut {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.socket.send_to(frame, self.target).map(drop)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        Ok(recv_datagram(&self.socket, &mut self.mode, buf, timeout)?.map_or(0, |(n, _)| n))
    }

    fn is_datagram(&self) -> bool {
        true
    }
}
