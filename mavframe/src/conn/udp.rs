//! UDP transports: `udpin` (listen; send to the peers its [`ReplyTo`] rule
//! names), `udpout` (a socket connected to one address) and `udpbcast`
//! (broadcast until a frame is accepted, then send to its senders).
//!
//! Whom `udpin` and `udpbcast` answer is never decided by a datagram
//! alone: anyone can send one, from any port. Under the default rule,
//! [`ReplyTo::Accepted`], a sender becomes a peer only once the
//! connection's parser accepted a frame of its (authenticated, on a link
//! with a key; see [`Transport::accepted`]), and by the rule of
//! [`crate::peers`]: up to [`MAX_PEERS`](crate::peers::MAX_PEERS) peers, a new one taking a slot
//! only if one is free or its holder has been silent for
//! [`SILENCE`](crate::peers::SILENCE). A stranger's datagrams, valid
//! frames or not, neither take a station's traffic nor displace it.

use super::transport::{is_timeout, Deadline, ReadMode, SetReadMode, Transport};
use crate::link::{Peers, ReplyTo};
use std::io;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};
use std::time::Duration;

/// What every UDP transport holds: its socket, how the socket waits, and
/// the sender of the last datagram.
#[derive(Debug)]
struct Udp {
    socket: UdpSocket,
    mode: ReadMode,
    last_source: Option<SocketAddr>,
}

impl Udp {
    fn new(socket: UdpSocket) -> Udp {
        Udp {
            socket,
            mode: ReadMode::default(),
            last_source: None,
        }
    }

    /// Waits for one non-empty datagram, noting its sender; 0 when the
    /// time ran out.
    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        let deadline = Deadline::after(timeout);
        loop {
            self.socket
                .prepare_read(&mut self.mode, deadline.remaining())?;
            match self.socket.recv_from(buf) {
                // An empty datagram carries nothing for the parser, and 0
                // would read as "timed out": keep waiting.
                Ok((0, _)) => {}
                Ok((n, from)) => {
                    self.last_source = Some(from);
                    return Ok(n);
                }
                Err(e) if is_timeout(&e) => return Ok(0),
                // An earlier send's ICMP "port unreachable", reported on the
                // next receive (Windows; Linux on connected sockets, as
                // `udpout`'s): it says nothing about incoming data, and a
                // peer may start later.
                Err(e) if is_refused(&e) || e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
            if deadline.passed() {
                return Ok(0);
            }
        }
    }

    /// A send half: a clone of the socket (reads never set the
    /// non-blocking flag they share from then on), sending to `peers`,
    /// else to `to`.
    fn sender(&mut self, peers: Option<Peers>, to: Option<SocketAddr>) -> io::Result<UdpSender> {
        self.mode.share();
        let socket = self.socket.try_clone()?;
        Ok(UdpSender { socket, peers, to })
    }
}

/// An error that reports an earlier datagram's ICMP error, not this call's.
pub(crate) fn is_refused(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::ConnectionReset | io::ErrorKind::ConnectionRefused
    )
}

/// Sends `frame` on a connected socket. A send that reports an earlier
/// datagram's ICMP error (Linux does on connected sockets, once per error)
/// sent nothing: tried once more, so a peer that is not up yet, or
/// restarted, causes no error.
pub(crate) fn send_connected(socket: &UdpSocket, frame: &[u8]) -> io::Result<()> {
    match socket.send(frame) {
        Err(e) if is_refused(&e) => socket.send(frame).map(drop),
        other => other.map(drop),
    }
}

/// Sends `frame` to each of `peers`: the first error, once every peer was
/// tried (a peer gone does not keep the others from theirs).
fn send_each(
    socket: &UdpSocket,
    peers: impl Iterator<Item = SocketAddr>,
    frame: &[u8],
) -> io::Result<()> {
    let mut first = Ok(());
    for peer in peers {
        if let (Err(e), Ok(())) = (socket.send_to(frame, peer), &first) {
            first = Err(e);
        }
    }
    first
}

/// `udpin:`: a bound socket that answers the peers its [`ReplyTo`] rule
/// names (by default, the senders of frames the connection accepted: see
/// the module docs).
///
/// While there is nobody to send to, [`send`](Transport::send) drops frames
/// silently, as MAVProxy and pymavlink do (a ground station's heartbeat loop
/// must not fail before a vehicle shows up). A sender whose source port is
/// 0 can be received from but never replied to (no datagram can go to port
/// 0), so it never becomes a peer.
///
/// One [`send`](Transport::send) is one datagram per peer, so each frame
/// travels in its own datagram, as MAVLink over UDP expects. A receive
/// buffer should hold a whole datagram (65,507 bytes;
/// [`Connection`](super::Connection)'s does): the system cuts a longer one
/// short.
#[derive(Debug)]
pub struct UdpIn {
    /// (The sender of its last datagram is not a peer for that.)
    udp: Udp,
    peers: Peers,
}

impl UdpIn {
    /// Binds to `addr` (port 0: the system picks one, see
    /// [`local_addr`](Self::local_addr)), under [`ReplyTo::Accepted`].
    pub fn bind(addr: SocketAddr) -> io::Result<Self> {
        Ok(UdpIn {
            udp: Udp::new(UdpSocket::bind(addr)?),
            peers: Peers::new(ReplyTo::Accepted),
        })
    }

    /// The bound address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.udp.socket.local_addr()
    }

    /// Chooses whom to send to from now on (a new rule starts with no
    /// peers).
    pub fn set_reply_to(&mut self, reply_to: ReplyTo) {
        self.peers.set_rule(reply_to);
    }

    /// The rule choosing whom to send to.
    pub fn reply_to(&self) -> ReplyTo {
        self.peers.rule
    }

    /// Sets the peers of [`ReplyTo::Owner`]: frames go to these addresses
    /// only (the first [`MAX_PEERS`](crate::peers::MAX_PEERS), port 0 ignored) until the next call.
    /// Under [`ReplyTo::Accepted`] they are peers as if heard now; under
    /// [`ReplyTo::Fixed`] they are not used.
    pub fn set_peers(&mut self, peers: &[SocketAddr]) {
        self.peers.given(peers);
    }

    /// [`set_peers`](Self::set_peers) of one address (ignored for port 0:
    /// the peers stay as they are).
    pub fn set_peer(&mut self, peer: SocketAddr) {
        if peer.port() != 0 {
            self.set_peers(&[peer]);
        }
    }

    /// Where frames go now, if anywhere: the fixed address, else the peer
    /// heard (or given) most recently. See [`peers`](Self::peers) for all.
    pub fn peer(&self) -> Option<SocketAddr> {
        self.peers.latest()
    }

    /// Every address a frame goes to now.
    pub fn peers(&self) -> impl Iterator<Item = SocketAddr> + '_ {
        self.peers.targets(None)
    }

    /// The sender of the last datagram received (every frame a
    /// [`Connection`](super::Connection) returns came from it; that alone
    /// makes it no peer).
    pub fn last_source(&self) -> Option<SocketAddr> {
        self.udp.last_source
    }

    /// The socket, for options this type does not cover.
    pub fn get_ref(&self) -> &UdpSocket {
        &self.udp.socket
    }
}

impl UdpIn {
    /// The send half's handle: a clone of the socket and whom it sends to
    /// (the fixed address, or the peers, which follow the receiving half's
    /// from then on).
    pub(crate) fn split_sender(&mut self) -> io::Result<UdpSender> {
        self.udp.sender(Some(self.peers.clone()), None)
    }
}

/// A split-off UDP send half: a clone of the socket, and whom it sends to.
#[derive(Debug)]
pub(crate) struct UdpSender {
    socket: UdpSocket,
    /// `udpin`, `udpbcast`: the receiving half's peers (shared); `None`:
    /// the socket's connected address (`udpout`).
    peers: Option<Peers>,
    /// `udpout`'s target, `udpbcast`'s broadcast address (where frames go
    /// while there is no peer; `udpin` drops them then).
    to: Option<SocketAddr>,
}

impl UdpSender {
    /// Where frames go: the peer heard most recently, or the one address.
    pub(crate) fn peer(&self) -> Option<SocketAddr> {
        self.peers.as_ref().and_then(Peers::latest).or(self.to)
    }

    pub(crate) fn send(&self, frame: &[u8]) -> io::Result<()> {
        match &self.peers {
            None => send_connected(&self.socket, frame),
            Some(peers) => send_each(&self.socket, peers.targets(self.to), frame),
        }
    }
}

impl Transport for UdpIn {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        send_each(&self.udp.socket, self.peers(), frame)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        self.udp.recv(buf, timeout)
    }

    fn is_datagram(&self) -> bool {
        true
    }

    fn accepted(&mut self) {
        self.peers.heard(self.udp.last_source);
    }
}

/// An ephemeral port of `target`'s address family, unconnected.
fn ephemeral(target: SocketAddr) -> io::Result<UdpSocket> {
    let local = match target {
        SocketAddr::V4(_) => SocketAddr::from((Ipv4Addr::UNSPECIFIED, 0)),
        SocketAddr::V6(_) => SocketAddr::from((Ipv6Addr::UNSPECIFIED, 0)),
    };
    UdpSocket::bind(local)
}

/// `udpout:`: sends to one address from an ephemeral port and receives
/// what comes back from that address.
///
/// The socket is `connect`ed to the target: the system drops datagrams
/// from any other address, so a stranger cannot slip frames in as the
/// target's by sending to the local port (a reply from another address of
/// the peer is dropped too). An ICMP error an earlier datagram drew (the
/// peer not up yet) is no error of a later receive or send. Broadcast
/// targets need `udpbcast:` (a socket connected to a broadcast address
/// would receive no answer).
///
/// One [`send`](Transport::send) is one datagram, so each frame travels in
/// its own datagram, as MAVLink over UDP expects. A receive buffer should
/// hold a whole datagram (65,507 bytes; [`Connection`](super::Connection)'s
/// does): the system cuts a longer one short.
#[derive(Debug)]
pub struct UdpOut {
    udp: Udp,
    target: SocketAddr,
}

impl UdpOut {
    /// Binds an ephemeral port of `target`'s address family and connects
    /// it to `target`.
    pub fn new(target: SocketAddr) -> io::Result<Self> {
        let socket = ephemeral(target)?;
        socket.connect(target)?;
        Ok(UdpOut {
            udp: Udp::new(socket),
            target,
        })
    }

    /// The local address (the system's choice of port, and of the address
    /// that reaches the target).
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.udp.socket.local_addr()
    }

    /// Where frames are sent, and the only address they are received from.
    pub fn target(&self) -> SocketAddr {
        self.target
    }

    /// The sender of the last datagram received (the target, once it
    /// answered).
    pub fn last_source(&self) -> Option<SocketAddr> {
        self.udp.last_source
    }

    /// The socket, for options this type does not cover.
    pub fn get_ref(&self) -> &UdpSocket {
        &self.udp.socket
    }
}

impl UdpOut {
    /// The send half's handle: a clone of the socket, connected to the
    /// target.
    pub(crate) fn split_sender(&mut self) -> io::Result<UdpSender> {
        self.udp.sender(None, Some(self.target))
    }
}

impl Transport for UdpOut {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        send_connected(&self.udp.socket, frame)
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        self.udp.recv(buf, timeout)
    }

    fn is_datagram(&self) -> bool {
        true
    }
}

/// `udpbcast:`: broadcasts to one address (e.g. `255.255.255.255:14550`
/// or a subnet's broadcast address) from an ephemeral port with
/// `SO_BROADCAST` set, until a frame is accepted; from then on frames go
/// to the senders of accepted frames, by [`ReplyTo::Accepted`]'s rule (up
/// to [`MAX_PEERS`](crate::peers::MAX_PEERS), a station that keeps speaking never displaced), as
/// MAVProxy's `udpbcast` link answers a peer once one speaks. A datagram
/// without an accepted frame moves nothing; a sender with source port 0
/// never becomes a peer.
#[derive(Debug)]
pub struct UdpBcast {
    udp: Udp,
    target: SocketAddr,
    peers: Peers,
}

impl UdpBcast {
    /// Binds an ephemeral port of `target`'s address family with
    /// `SO_BROADCAST` set.
    pub fn new(target: SocketAddr) -> io::Result<Self> {
        let socket = ephemeral(target)?;
        socket.set_broadcast(true)?;
        Ok(UdpBcast {
            udp: Udp::new(socket),
            target,
            peers: Peers::new(ReplyTo::Accepted),
        })
    }

    /// The ephemeral local address.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.udp.socket.local_addr()
    }

    /// The broadcast address frames go to until a peer answers.
    pub fn target(&self) -> SocketAddr {
        self.target
    }

    /// Where frames go now: the peer heard most recently, or the broadcast
    /// address (see [`peers`](Self::peers) for all).
    pub fn peer(&self) -> SocketAddr {
        self.peers.latest().unwrap_or(self.target)
    }

    /// The peers (none while broadcasting).
    pub fn peers(&self) -> impl Iterator<Item = SocketAddr> + '_ {
        self.peers.targets(None)
    }

    /// The sender of the last datagram received.
    pub fn last_source(&self) -> Option<SocketAddr> {
        self.udp.last_source
    }

    /// The socket, for options this type does not cover.
    pub fn get_ref(&self) -> &UdpSocket {
        &self.udp.socket
    }
}

impl UdpBcast {
    /// The send half's handle: a clone of the socket, sending to the
    /// receiving half's peers, else broadcasting.
    pub(crate) fn split_sender(&mut self) -> io::Result<UdpSender> {
        self.udp.sender(Some(self.peers.clone()), Some(self.target))
    }
}

impl Transport for UdpBcast {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        send_each(
            &self.udp.socket,
            self.peers.targets(Some(self.target)),
            frame,
        )
    }

    fn recv(&mut self, buf: &mut [u8], timeout: Option<Duration>) -> io::Result<usize> {
        self.udp.recv(buf, timeout)
    }

    fn is_datagram(&self) -> bool {
        true
    }

    fn accepted(&mut self) {
        self.peers.heard(self.udp.last_source);
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

    /// By default a sender is answered once a frame of its was accepted
    /// (the connection calls `accepted`), with every other peer; a
    /// datagram alone moves nothing.
    #[test]
    fn senders_of_accepted_frames_are_answered_by_default() {
        let mut udp = UdpIn::bind(local()).unwrap();
        assert_eq!(udp.reply_to(), ReplyTo::Accepted);
        let at = udp.local_addr().unwrap();
        let (a, b) = (peer(), peer());
        udp.send(b"nobody yet").unwrap();
        a.send_to(b"x", at).unwrap();
        receive(&mut udp);
        udp.send(b"still nobody").unwrap();
        assert_eq!(got(&a), None, "a datagram alone made a peer");
        udp.accepted();
        udp.send(b"to a").unwrap();
        assert_eq!(got(&a).as_deref(), Some(&b"to a"[..]));
        b.send_to(b"y", at).unwrap();
        receive(&mut udp);
        udp.accepted();
        udp.send(b"to both").unwrap();
        assert_eq!(got(&a).as_deref(), Some(&b"to both"[..]));
        assert_eq!(got(&b).as_deref(), Some(&b"to both"[..]));
        assert_eq!(udp.peer(), Some(b.local_addr().unwrap()), "the latest");
        assert_eq!(udp.peers().count(), 2);
    }

    /// Under [`ReplyTo::Owner`] the owner's peers stay the peers whoever
    /// else sends, accepted frames or not.
    #[test]
    fn an_owners_peer_is_not_redirected_by_strangers() {
        let mut udp = UdpIn::bind(local()).unwrap();
        udp.set_reply_to(ReplyTo::Owner);
        let at = udp.local_addr().unwrap();
        let (real, stranger) = (peer(), peer());
        real.send_to(b"x", at).unwrap();
        receive(&mut udp);
        udp.accepted();
        udp.send(b"before the owner says").unwrap();
        assert_eq!(
            got(&real),
            None,
            "nothing is sent until the owner names a peer"
        );
        udp.set_peer(real.local_addr().unwrap());
        stranger.send_to(b"hijack", at).unwrap();
        receive(&mut udp);
        udp.accepted();
        assert_eq!(udp.last_source(), Some(stranger.local_addr().unwrap()));
        udp.send(b"still real").unwrap();
        assert_eq!(got(&real).as_deref(), Some(&b"still real"[..]));
        assert_eq!(got(&stranger), None);
        // Port 0 can never be a peer (no datagram can go there).
        udp.set_peer(SocketAddr::from(([127, 0, 0, 1], 0)));
        assert_eq!(udp.peer(), Some(real.local_addr().unwrap()));
        udp.set_peers(&[stranger.local_addr().unwrap(), real.local_addr().unwrap()]);
        udp.send(b"both").unwrap();
        assert_eq!(got(&real).as_deref(), Some(&b"both"[..]));
        assert_eq!(got(&stranger).as_deref(), Some(&b"both"[..]));
    }

    /// `udpbcast` sends to its target (with SO_BROADCAST on) until a frame
    /// is accepted, then to the senders of accepted frames.
    #[test]
    fn udpbcast_broadcasts_until_a_frame_is_accepted() {
        let (target, a, b) = (peer(), peer(), peer());
        let mut udp = UdpBcast::new(target.local_addr().unwrap()).unwrap();
        assert!(udp.get_ref().broadcast().unwrap());
        udp.send(b"anyone?").unwrap();
        assert_eq!(got(&target).as_deref(), Some(&b"anyone?"[..]));
        let at = SocketAddr::from(([127, 0, 0, 1], udp.local_addr().unwrap().port()));
        b.send_to(b"noise", at).unwrap();
        let mut buf = [0u8; 64];
        assert_eq!(udp.recv(&mut buf, Some(Duration::from_secs(2))).unwrap(), 5);
        udp.send(b"still anyone?").unwrap();
        assert_eq!(got(&target).as_deref(), Some(&b"still anyone?"[..]));
        assert_eq!(got(&b), None, "a datagram alone made a peer");
        a.send_to(b"me", at).unwrap();
        assert_eq!(udp.recv(&mut buf, Some(Duration::from_secs(2))).unwrap(), 2);
        udp.accepted();
        udp.send(b"to a").unwrap();
        assert_eq!(got(&a).as_deref(), Some(&b"to a"[..]));
        assert_eq!(udp.peer(), a.local_addr().unwrap());
        assert_eq!(got(&target), None, "no more broadcasts once answered");
        assert_eq!(got(&b), None);
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

    /// A `udpout` socket is connected to its target: a third socket's
    /// datagram to its local port is never received, the target's is.
    #[test]
    fn udpout_ignores_third_parties() {
        let target = peer();
        let mut udp = UdpOut::new(target.local_addr().unwrap()).unwrap();
        udp.send(b"hello").unwrap();
        let mut buf = [0u8; 64];
        let (_, from) = target.recv_from(&mut buf).unwrap();
        let local = SocketAddr::from(([127, 0, 0, 1], from.port()));
        let third = peer();
        third.send_to(b"forged", local).unwrap();
        assert_eq!(
            udp.recv(&mut buf, Some(Duration::from_millis(200)))
                .unwrap(),
            0,
            "a third party's datagram was received"
        );
        target.send_to(b"reply", local).unwrap();
        assert_eq!(udp.recv(&mut buf, Some(Duration::from_secs(2))).unwrap(), 5);
        assert_eq!(&buf[..5], b"reply");
    }

    /// A link that drops its packets and never answers: sends to it cause
    /// no error, however many ICMP errors they draw.
    #[test]
    fn udpout_sends_to_a_closed_port_without_error() {
        let closed = peer().local_addr().unwrap(); // dropped: nobody there
        let mut udp = UdpOut::new(closed).unwrap();
        let mut buf = [0u8; 16];
        for _ in 0..3 {
            udp.send(b"anyone?").unwrap();
            assert_eq!(
                udp.recv(&mut buf, Some(Duration::from_millis(20))).unwrap(),
                0
            );
        }
    }

    mod connection {
        use super::super::super::test_dialect::{Ping, TestDialect};
        use super::super::super::Connection;
        use super::*;
        use crate::frame::{FrameBuf, Header, Version};
        use crate::peers::MAX_PEERS;

        fn ping(value: u32) -> FrameBuf {
            let h = Header {
                seq: value as u8,
                sysid: 1,
                compid: 1,
            };
            FrameBuf::encode(Version::V2, h, &Ping { value }, None).unwrap()
        }

        fn server() -> (Connection<TestDialect, UdpIn>, SocketAddr) {
            let udp = UdpIn::bind(local()).unwrap();
            let at = udp.local_addr().unwrap();
            (Connection::new(udp), at)
        }

        /// A stranger's 1-byte datagrams, every 10 ms, never move a
        /// `udpin` connection's replies away from the station whose frame
        /// it accepted (answering the last sender, each one did).
        #[test]
        fn one_byte_datagrams_never_redirect_a_udpin_link() {
            let (mut link, at) = server();
            let (station, stranger) = (peer(), peer());
            station.send_to(&ping(1), at).unwrap();
            assert!(link.recv(Some(Duration::from_secs(2))).unwrap().is_some());
            for i in 0..20u32 {
                stranger.send_to(&[0], at).unwrap();
                std::thread::sleep(Duration::from_millis(10));
                assert!(link
                    .recv(Some(Duration::from_millis(20)))
                    .unwrap()
                    .is_none());
                assert_eq!(link.transport().last_source(), stranger.local_addr().ok());
                link.send_raw(&ping(100 + i)).unwrap();
                assert_eq!(got(&station).as_deref(), Some(&ping(100 + i)[..]), "{i}");
            }
            assert_eq!(got(&stranger), None, "the stranger got traffic");
        }

        /// 200 strangers, each with a valid frame, arrive while a station
        /// keeps speaking: the station receives every frame sent meanwhile;
        /// 7 strangers at most (the free slots) get copies.
        #[test]
        fn a_speaking_station_keeps_its_traffic_among_200_strangers() {
            let (mut link, at) = server();
            let station = peer();
            let mut strangers = Vec::new();
            for i in 0..200u32 {
                if i % 20 == 0 {
                    station.send_to(&ping(1000 + i), at).unwrap();
                    assert!(link.recv(Some(Duration::from_secs(2))).unwrap().is_some());
                }
                let s = UdpSocket::bind(local()).unwrap();
                s.set_read_timeout(Some(Duration::from_millis(5))).unwrap();
                s.send_to(&ping(i), at).unwrap();
                assert!(link.recv(Some(Duration::from_secs(2))).unwrap().is_some());
                strangers.push(s);
                if i % 20 == 19 {
                    link.send_raw(&ping(5000 + i)).unwrap();
                    let want = ping(5000 + i);
                    assert_eq!(got(&station).as_deref(), Some(&want[..]), "after {i}");
                }
            }
            let served = strangers.iter().filter(|s| got(s).is_some()).count();
            assert!(served < MAX_PEERS, "{served} strangers got traffic");
            assert_eq!(link.transport().peers().count(), MAX_PEERS);
        }

        /// With a key, an unsigned frame (accepted, unauthenticated) makes
        /// its sender no peer; an authenticated one does.
        #[test]
        fn with_a_key_only_authenticated_frames_make_peers() {
            use crate::parser::{Parser, Unsigned};
            use crate::signing::{timestamp_now, Signer, Verifier};
            let key = [4u8; 32];
            let udp = UdpIn::bind(local()).unwrap();
            let at = udp.local_addr().unwrap();
            let parser = Parser::with_signing(Verifier::new(key), Unsigned::Accept);
            let mut link = Connection::<TestDialect, _>::with_parser(udp, parser);
            let (station, stranger) = (peer(), peer());
            stranger.send_to(&ping(1), at).unwrap();
            let f = link.recv(Some(Duration::from_secs(2))).unwrap().unwrap();
            assert!(!f.is_authenticated());
            assert_eq!(link.transport().peer(), None);
            let mut signer = Signer::new(key, 1, timestamp_now());
            let h = Header::default();
            let signed =
                FrameBuf::encode(Version::V2, h, &Ping { value: 2 }, Some(&mut signer)).unwrap();
            station.send_to(&signed, at).unwrap();
            assert!(link
                .recv(Some(Duration::from_secs(2)))
                .unwrap()
                .unwrap()
                .is_authenticated());
            assert_eq!(link.transport().peer(), station.local_addr().ok());
            assert_eq!(link.transport().peers().count(), 1);
        }
    }
}
