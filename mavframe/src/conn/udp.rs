//! UDP transports: `udpin` (listen; reply to the peer its [`ReplyTo`] rule
//! names) and `udpout` (send to one address, receive replies).

use super::transport::{is_timeout, Deadline, ReadMode, SetReadMode, Transport};
use std::io;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};
use std::sync::{Arc, Mutex, PoisonError};
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

/// The last sender, shared with a split-off [`Sender`](super::Sender)
/// that replies to it.
pub(crate) type SharedSource = Arc<Mutex<Option<SocketAddr>>>;

/// Records `from` as the last sender, and in `shared` when split.
fn note_source(last: &mut Option<SocketAddr>, shared: &Option<SharedSource>, from: SocketAddr) {
    *last = Some(from);
    if let Some(shared) = shared {
        // A poisoned lock only means another thread panicked mid-store of
        // a Copy value: the value is still whole.
        *shared.lock().unwrap_or_else(PoisonError::into_inner) = Some(from);
    }
}

/// [`recv_datagram`] for a [`Transport`]: the sender noted, 0 when the time
/// ran out.
fn recv_noting_source(
    socket: &UdpSocket,
    mode: &mut ReadMode,
    (last, shared): (&mut Option<SocketAddr>, &Option<SharedSource>),
    buf: &mut [u8],
    timeout: Option<Duration>,
) -> io::Result<usize> {
    Ok(match recv_datagram(socket, mode, buf, timeout)? {
        Some((n, from)) => {
            note_source(last, shared, from);
            n
        }
        None => 0,
    })
}

/// Reads a shared last sender.
pub(crate) fn shared_source(shared: &SharedSource) -> Option<SocketAddr> {
    *shared.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Whom a [`UdpIn`] sends to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReplyTo {
    /// The sender of the last datagram received, as MAVProxy and pymavlink
    /// do (the default). Anyone who can send a datagram to the port
    /// redirects what follows: fine for a ground station's port, wrong for
    /// a link that carries control.
    LastSender,
    /// This address only, whoever else sends.
    Fixed(SocketAddr),
    /// Only the address set with [`UdpIn::set_peer`] (nobody until then):
    /// the application pins the peer it has authenticated.
    Pinned,
}

/// `udpin:`: a bound socket that answers one peer, chosen by its
/// [`ReplyTo`] rule (by default the sender of the last datagram).
///
/// While there is nobody to send to, [`send`](Transport::send) drops frames
/// silently, as MAVProxy and pymavlink do (a ground station's heartbeat loop
/// must not fail before a vehicle shows up). A sender whose source port is
/// 0 can be received from but never replied to (no datagram can go to port
/// 0), so it never becomes the peer.
///
/// One [`send`](Transport::send) is one datagram, so each frame travels in
/// its own datagram, as MAVLink over UDP expects. A receive buffer should
/// hold a whole datagram (65,507 bytes; [`Connection`](super::Connection)'s
/// does): the system cuts a longer one short.
#[derive(Debug)]
pub struct UdpIn {
    socket: UdpSocket,
    reply_to: ReplyTo,
    /// The last sender (a possible peer), and the pinned peer.
    last_source: Option<SocketAddr>,
    pinned: Option<SocketAddr>,
    mode: ReadMode,
    /// Set by `split`: where a split-off sender reads the last sender.
    shared: Option<SharedSource>,
}

impl UdpIn {
    /// Binds to `addr` (port 0: the system picks one, see
    /// [`local_addr`](Self::local_addr)), replying to the last sender.
    pub fn bind(addr: SocketAddr) -> io::Result<Self> {
        Ok(UdpIn {
            socket: UdpSocket::bind(addr)?,
            reply_to: ReplyTo::LastSender,
            last_source: None,
            pinned: None,
            mode: ReadMode::default(),
            shared: None,
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// Chooses whom to send to from now on.
    pub fn set_reply_to(&mut self, reply_to: ReplyTo) {
        self.reply_to = reply_to;
    }

    /// The rule choosing whom to send to.
    pub fn reply_to(&self) -> ReplyTo {
        self.reply_to
    }

    /// Pins the peer of [`ReplyTo::Pinned`] (ignored for port 0).
    pub fn set_peer(&mut self, peer: SocketAddr) {
        if peer.port() != 0 {
            self.pinned = Some(peer);
        }
    }

    /// The peer frames go to now, if any.
    pub fn peer(&self) -> Option<SocketAddr> {
        match self.reply_to {
            ReplyTo::LastSender => self.last_source.filter(|a| a.port() != 0),
            ReplyTo::Fixed(addr) => Some(addr),
            ReplyTo::Pinned => self.pinned,
        }
    }

    /// The sender of the last datagram received (every frame a
    /// [`Connection`](super::Connection) returns came from it).
    pub fn last_source(&self) -> Option<SocketAddr> {
        self.last_source
    }

    /// The socket, for options this type does not cover.
    pub fn get_ref(&self) -> &UdpSocket {
        &self.socket
    }
}

impl UdpIn {
    /// The send half's handle: a clone of the socket and whom it sends to
    /// (the reply rule as it is now; a `LastSender` rule follows the
    /// receiving half from then on).
    pub(crate) fn split_sender(&mut self) -> io::Result<(UdpSocket, UdpPeer)> {
        self.mode.share();
        let peer = match self.reply_to {
            ReplyTo::LastSender => {
                let shared = Arc::new(Mutex::new(self.last_source));
                self.shared = Some(shared.clone());
                UdpPeer::LastSender(shared, None)
            }
            ReplyTo::Fixed(a) => UdpPeer::Fixed(Some(a)),
            ReplyTo::Pinned => UdpPeer::Fixed(self.pinned),
        };
        Ok((self.socket.try_clone()?, peer))
    }
}

/// Whom a split-off UDP sender sends to.
#[derive(Debug)]
pub(crate) enum UdpPeer {
    /// This address; nobody (frames dropped, as `udpin` does) for `None`.
    Fixed(Option<SocketAddr>),
    /// The receiving half's last sender, else the fallback (`udpbcast`'s
    /// broadcast address), else nobody.
    LastSender(SharedSource, Option<SocketAddr>),
}

impl UdpPeer {
    pub(crate) fn get(&self) -> Option<SocketAddr> {
        match self {
            UdpPeer::Fixed(a) => *a,
            UdpPeer::LastSender(shared, fallback) => shared_source(shared)
                .filter(|a| a.port() != 0)
                .or(*fallback),
        }
    }
}

impl Transport for UdpIn {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        match self.peer() {
            Some(peer) => self.socket.send_to(frame, peer).map(drop),
            None => Ok(()),
        }
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        let source = (&mut self.last_source, &self.shared);
        recv_noting_source(&self.socket, &mut self.mode, source, buf, timeout)
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
    last_source: Option<SocketAddr>,
    mode: ReadMode,
    /// Always `None`: a `udpout` sender has a fixed target.
    shared: Option<SharedSource>,
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
            last_source: None,
            mode: ReadMode::default(),
            shared: None,
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

    /// The sender of the last datagram received (replies are accepted from
    /// any address; see the type's docs).
    pub fn last_source(&self) -> Option<SocketAddr> {
        self.last_source
    }

    /// The socket, for options this type does not cover.
    pub fn get_ref(&self) -> &UdpSocket {
        &self.socket
    }
}

impl UdpOut {
    /// The send half's handle: a clone of the socket and its target.
    pub(crate) fn split_sender(&mut self) -> io::Result<(UdpSocket, UdpPeer)> {
        self.mode.share();
        Ok((self.socket.try_clone()?, UdpPeer::Fixed(Some(self.target))))
    }
}

impl Transport for UdpOut {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.socket.send_to(frame, self.target).map(drop)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        let source = (&mut self.last_source, &self.shared);
        recv_noting_source(&self.socket, &mut self.mode, source, buf, timeout)
    }

    fn is_datagram(&self) -> bool {
        true
    }
}

/// `udpbcast:`: broadcasts to one address (e.g. `255.255.255.255:14550`
/// or a subnet's broadcast address) from an ephemeral port with
/// `SO_BROADCAST` set, until a datagram arrives; from then on frames go to
/// the sender of the last datagram received, as MAVProxy's `udpbcast`
/// link does once a peer answers. (pymavlink's `mavudp` locks onto the
/// first sender for good; following the last one lets a restarted peer,
/// which comes back from a new port, take over.)
///
/// Anyone who can send a datagram to the port redirects what follows, as
/// with [`ReplyTo::LastSender`]: for discovery on a trusted network, not
/// for a link that carries control. A sender with source port 0 never
/// becomes the peer.
#[derive(Debug)]
pub struct UdpBcast {
    socket: UdpSocket,
    target: SocketAddr,
    last_source: Option<SocketAddr>,
    mode: ReadMode,
    /// Set by `split`: where a split-off sender reads the last sender.
    shared: Option<SharedSource>,
}

impl UdpBcast {
    /// Binds an ephemeral port of `target`'s address family with
    /// `SO_BROADCAST` set.
    pub fn new(target: SocketAddr) -> io::Result<Self> {
        let UdpOut { socket, .. } = UdpOut::new(target)?;
        socket.set_broadcast(true)?;
        Ok(UdpBcast {
            socket,
            target,
            last_source: None,
            mode: ReadMode::default(),
            shared: None,
        })
    }

    /// The ephemeral local address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket.local_addr()
    }

    /// The broadcast address frames go to until a peer answers.
    pub fn target(&self) -> SocketAddr {
        self.target
    }

    /// Where frames go now: the last sender, or the broadcast address.
    pub fn peer(&self) -> SocketAddr {
        self.last_source
            .filter(|a| a.port() != 0)
            .unwrap_or(self.target)
    }

    /// The sender of the last datagram received.
    pub fn last_source(&self) -> Option<SocketAddr> {
        self.last_source
    }

    /// The socket, for options this type does not cover.
    pub fn get_ref(&self) -> &UdpSocket {
        &self.socket
    }
}

impl UdpBcast {
    /// The send half's handle: a clone of the socket, sending to the
    /// receiving half's last sender, else broadcasting.
    pub(crate) fn split_sender(&mut self) -> io::Result<(UdpSocket, UdpPeer)> {
        self.mode.share();
        let shared = Arc::new(Mutex::new(self.last_source));
        self.shared = Some(shared.clone());
        let peer = UdpPeer::LastSender(shared, Some(self.target));
        Ok((self.socket.try_clone()?, peer))
    }
}

impl Transport for UdpBcast {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.socket.send_to(frame, self.peer()).map(drop)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        let source = (&mut self.last_source, &self.shared);
        recv_noting_source(&self.socket, &mut self.mode, source, buf, timeout)
    }

    fn is_datagram(&self) -> bool {
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::UdpSocket;
    use std::vec::Vec;

    fn local() -> SocketAddr {
        SocketAddr::from(([127, 0, 0, 1], 0))
    }

    /// A peer socket with a short read timeout.
    fn peer() -> UdpSocket {
        let s = UdpSocket::bind(local()).unwrap();
        s.set_read_timeout(Some(Duration::from_millis(300)))
            .unwrap();
        s
    }

    fn got(s: &UdpSocket) -> Option<Vec<u8>> {
        let mut buf = [0u8; 64];
        s.recv_from(&mut buf).ok().map(|(n, _)| buf[..n].to_vec())
    }

    fn receive(udp: &mut UdpIn) {
        let mut buf = [0u8; 64];
        assert!(udp.recv(&mut buf, Some(Duration::from_secs(2))).unwrap() > 0);
    }

    #[test]
    fn last_sender_is_answered_by_default() {
        let mut udp = UdpIn::bind(local()).unwrap();
        let at = udp.local_addr().unwrap();
        let (a, b) = (peer(), peer());
        udp.send(b"nobody yet").unwrap();
        a.send_to(b"x", at).unwrap();
        receive(&mut udp);
        udp.send(b"to a").unwrap();
        assert_eq!(got(&a).as_deref(), Some(&b"to a"[..]));
        b.send_to(b"y", at).unwrap();
        receive(&mut udp);
        udp.send(b"to b").unwrap();
        assert_eq!(got(&b).as_deref(), Some(&b"to b"[..]));
        assert_eq!(got(&a), None, "the last sender took over");
    }

    /// A pinned peer stays the peer whoever else sends: a stranger's
    /// datagrams cannot redirect the link.
    #[test]
    fn a_pinned_peer_is_not_redirected_by_strangers() {
        let mut udp = UdpIn::bind(local()).unwrap();
        udp.set_reply_to(ReplyTo::Pinned);
        let at = udp.local_addr().unwrap();
        let (real, stranger) = (peer(), peer());
        real.send_to(b"x", at).unwrap();
        receive(&mut udp);
        udp.send(b"before pinning").unwrap();
        assert_eq!(got(&real), None, "nothing is sent until a peer is pinned");
        udp.set_peer(real.local_addr().unwrap());
        stranger.send_to(b"hijack", at).unwrap();
        receive(&mut udp);
        assert_eq!(udp.last_source(), Some(stranger.local_addr().unwrap()));
        udp.send(b"still real").unwrap();
        assert_eq!(got(&real).as_deref(), Some(&b"still real"[..]));
        assert_eq!(got(&stranger), None);
        // Port 0 can never be a peer (no datagram can go there).
        udp.set_peer(SocketAddr::from(([127, 0, 0, 1], 0)));
        assert_eq!(udp.peer(), Some(real.local_addr().unwrap()));
    }

    /// `udpbcast` sends to its target (with SO_BROADCAST on) until a
    /// datagram arrives, then to the last sender.
    #[test]
    fn udpbcast_broadcasts_until_answered_then_follows_the_last_sender() {
        let (target, a, b) = (peer(), peer(), peer());
        let mut udp = UdpBcast::new(target.local_addr().unwrap()).unwrap();
        assert!(udp.get_ref().broadcast().unwrap());
        udp.send(b"anyone?").unwrap();
        assert_eq!(got(&target).as_deref(), Some(&b"anyone?"[..]));
        let at = SocketAddr::from(([127, 0, 0, 1], udp.local_addr().unwrap().port()));
        a.send_to(b"me", at).unwrap();
        let mut buf = [0u8; 64];
        assert_eq!(udp.recv(&mut buf, Some(Duration::from_secs(2))).unwrap(), 2);
        udp.send(b"to a").unwrap();
        assert_eq!(got(&a).as_deref(), Some(&b"to a"[..]));
        b.send_to(b"me too", at).unwrap();
        assert_eq!(udp.recv(&mut buf, Some(Duration::from_secs(2))).unwrap(), 6);
        udp.send(b"to b").unwrap();
        assert_eq!(got(&b).as_deref(), Some(&b"to b"[..]));
        assert_eq!(got(&a), None);
        assert_eq!(got(&target), None, "no more broadcasts once answered");
    }

    #[test]
    fn a_fixed_peer_is_the_only_one() {
        let mut udp = UdpIn::bind(local()).unwrap();
        let (fixed, other) = (peer(), peer());
        udp.set_reply_to(ReplyTo::Fixed(fixed.local_addr().unwrap()));
        udp.send(b"first").unwrap();
        assert_eq!(got(&fixed).as_deref(), Some(&b"first"[..]));
        other.send_to(b"x", udp.local_addr().unwrap()).unwrap();
        receive(&mut udp);
        udp.send(b"second").unwrap();
        assert_eq!(got(&fixed).as_deref(), Some(&b"second"[..]));
        assert_eq!(got(&other), None);
    }
}
