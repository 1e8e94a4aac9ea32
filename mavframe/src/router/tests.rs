use super::policy::Forward;
use super::queues::{Class, Next, Packet, Queues};
use super::server::CLIENT_WRITE_TIMEOUT;
use super::*;
use crate::conn::test_dialect::{Ping, TestDialect};
use crate::frame::{FrameBuf, Header, Version};
use crate::peers::MAX_PEERS;
use crate::{Parser, ReceivedBuf};
use std::format;
use std::net::UdpSocket as StdUdp;
use std::vec::Vec;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpStream, UdpSocket};
use tokio::sync::mpsc;

/// What a test's router saw.
#[allow(clippy::large_enum_variant)]
enum Seen {
    Frame(Copy),
    Event(RouterEvent),
}

/// A frame a link received, copied.
struct Copy {
    link: LinkId,
    frame: ReceivedBuf<TestDialect>,
    source: Option<SocketAddr>,
}

/// A test's policy: what it sees goes to the test, and frames are routed
/// by [`Forward`] when it has one (else the test decides, as an owner
/// with a policy of its own).
struct Tap {
    forward: Option<Forward>,
    seen: mpsc::UnboundedSender<Seen>,
}

impl Policy<TestDialect> for Tap {
    fn link_added(&mut self, link: LinkId, config: &LinkConfig, out: &mut Out<'_>) {
        if let Some(f) = &mut self.forward {
            Policy::<TestDialect>::link_added(f, link, config, out);
        }
    }

    fn frame(&mut self, inbound: &Inbound<'_, TestDialect>, out: &mut Out<'_>) {
        let copy = Copy {
            link: inbound.link,
            frame: ReceivedBuf::from(&inbound.frame),
            source: inbound.source,
        };
        let _ = self.seen.send(Seen::Frame(copy));
        if let Some(f) = &mut self.forward {
            f.frame(inbound, out);
        }
    }

    fn event(&mut self, event: RouterEvent, out: &mut Out<'_>) {
        if let (Some(f), RouterEvent::LinkUp { link }) = (&mut self.forward, &event) {
            let up = RouterEvent::LinkUp { link: *link };
            Policy::<TestDialect>::event(f, up, out);
        }
        let _ = self.seen.send(Seen::Event(event));
    }
}

/// A router whose links answer their senders as the plain router does
/// ([`Forward`]), or (`forward` false) only whom the test names.
struct Rig {
    router: Router<TestDialect, Tap>,
    seen: mpsc::UnboundedReceiver<Seen>,
}

impl Rig {
    fn new(forward: bool) -> Rig {
        let (tx, seen) = mpsc::unbounded_channel();
        let tap = Tap {
            forward: forward.then(Forward::new),
            seen: tx,
        };
        Rig {
            router: Router::new(tap),
            seen,
        }
    }

    async fn add(&mut self, config: LinkConfig) -> LinkId {
        self.router.add(config).await.unwrap()
    }

    /// What the router saw next, within `ms`.
    async fn next(&mut self, ms: u64) -> Option<Seen> {
        tokio::time::timeout(Duration::from_millis(ms), self.seen.recv())
            .await
            .ok()
            .flatten()
    }

    /// The next frame, within 2 s.
    async fn frame(&mut self) -> Copy {
        loop {
            match self.next(2_000).await {
                Some(Seen::Frame(f)) => return f,
                Some(Seen::Event(_)) => continue,
                None => panic!("no frame"),
            }
        }
    }

    /// The next event, within `ms`.
    async fn event(&mut self, ms: u64) -> Option<RouterEvent> {
        loop {
            match self.next(ms).await? {
                Seen::Event(e) => return Some(e),
                Seen::Frame(_) => continue,
            }
        }
    }

    fn send_raw(&self, links: Links, bytes: &[u8]) {
        self.router.with(|_, out| out.send_raw(links, bytes));
    }

    fn set_peers(&self, link: LinkId, peers: &[SocketAddr]) {
        self.router.with(|_, out| out.set_peers(link, peers));
    }

    fn counters(&self, link: LinkId) -> LinkCounters {
        self.router.counters(link)
    }

    /// `copy` routed by the owner to `links` (signed again, `signed`).
    fn route(&self, copy: &Copy, links: Links, signed: bool) -> Links {
        self.router.with(|_, out| {
            let inbound = Inbound::new(copy.link, copy.frame.received(), copy.source);
            match signed {
                true => out.route_signed(&inbound, links),
                false => out.route(&inbound, links),
            }
        })
    }
}

/// Datagrams of garbage (65,507 and 20 bytes) before each frame: no
/// frame is cut short. (A receive into the room the earlier datagrams'
/// bytes left lost one 63-byte frame in 1,040 on a plain link, and
/// every frame after a large datagram.)
#[tokio::test]
async fn no_datagram_is_cut_short_after_a_large_one() {
    let probe = StdUdp::bind("127.0.0.1:0").unwrap();
    let port = probe.local_addr().unwrap().port();
    drop(probe);
    let mut rig = Rig::new(true);
    let url = format!("udpin:127.0.0.1:{port}");
    rig.add(LinkConfig::new(url.parse().unwrap())).await;
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
        let Some(Seen::Frame(copy)) = rig.next(2_000).await else {
            panic!("frame {value} lost");
        };
        assert_eq!(copy.frame.as_bytes(), &frame[..], "frame {value}");
    }
}

/// A `tcpin` link answering its senders ([`Forward`]), or (`forward`
/// false) whom the test names; its address.
async fn tcpin(forward: bool) -> (Rig, LinkId, SocketAddr) {
    let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = probe.local_addr().unwrap();
    drop(probe);
    let mut rig = Rig::new(forward);
    let link = rig
        .add(LinkConfig::new(format!("tcpin:{addr}").parse().unwrap()))
        .await;
    (rig, link, addr)
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
/// link opens once its server listens.
#[tokio::test]
async fn a_tcp_link_whose_server_comes_later_opens_then() {
    let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = probe.local_addr().unwrap();
    drop(probe);
    let mut rig = Rig::new(false);
    let tcp = LinkConfig::new(format!("tcp:{addr}").parse().unwrap());
    let link = rig.add(tcp).await;
    let serial = LinkConfig::new("serial:/dev/no-such-port:57600".parse().unwrap());
    let absent = rig.add(serial).await;
    let mut down = Vec::new();
    for _ in 0..2 {
        match rig.event(2_000).await {
            Some(RouterEvent::LinkDown { link, .. }) => down.push(link),
            _ => panic!("no LinkDown"),
        }
    }
    down.sort_unstable();
    assert_eq!(down, [link, absent]);
    let server = tokio::net::TcpListener::bind(addr).await.unwrap();
    let (mut stream, _) = tokio::time::timeout(Duration::from_secs(3), server.accept())
        .await
        .expect("the link connects within its reopening interval")
        .unwrap();
    let up = rig.event(1_000).await;
    assert!(matches!(up, Some(RouterEvent::LinkUp { link: l }) if l == link));
    rig.send_raw(Links::only(link), &ping(7));
    assert_eq!(read_for(&mut stream, 300).await.unwrap(), &ping(7)[..]);
}

/// `tcpin` under a policy that names its peers itself: nothing goes out
/// until it names a client, then only to that client (before, every
/// client got everything: a stranger that connected received the
/// companion's control).
#[tokio::test]
async fn tcpin_sends_only_to_the_policys_peer() {
    let (mut rig, link, addr) = tcpin(false).await;
    let mut peer = TcpStream::connect(addr).await.unwrap();
    let mut stranger = TcpStream::connect(addr).await.unwrap();
    peer.write_all(&ping(1)).await.unwrap();
    let copy = rig.frame().await;
    assert_eq!(copy.source, Some(peer.local_addr().unwrap()));
    rig.send_raw(Links::only(link), &ping(2));
    assert_eq!(
        read_for(&mut peer, 200).await,
        Some(Vec::new()),
        "no peer named yet"
    );
    rig.set_peers(link, &[peer.local_addr().unwrap()]);
    rig.send_raw(Links::only(link), &ping(3));
    assert_eq!(read_for(&mut peer, 300).await, Some(ping(3).to_vec()));
    assert_eq!(read_for(&mut stranger, 100).await, Some(Vec::new()));
}

/// A packet of `len` bytes of `b`.
fn packet(b: u8, len: usize) -> Packet {
    Packet::new(&std::vec![b; len], 1)
}

/// What `queues` sends next at `now` (`unpaced`: the router is gone):
/// whether the owner's, and its first byte; or how long it waits.
fn next(queues: &mut Queues, unpaced: bool) -> Result<(bool, u8), Option<Duration>> {
    match queues.next(tokio::time::Instant::now(), unpaced) {
        Next::Send(class, p) => Ok((class == Class::Own, p.bytes[0])),
        Next::Wait(wait) => Err(Some(wait)),
        Next::Idle => Err(None),
    }
}

/// A link sends its owner's frames before routed ones queued earlier,
/// each class in order; a packet a full socket sent back goes first of
/// its class.
#[tokio::test]
async fn a_link_sends_the_owners_frames_before_routed_ones() {
    let mut q = Queues::link(None);
    for b in [1u8, 2, 3] {
        assert_eq!(q.push_routed(1, packet(b, 1)), 0);
    }
    for b in [7u8, 8] {
        assert!(q.push_own(packet(b, 1)));
    }
    assert_eq!(next(&mut q, false), Ok((true, 7)));
    assert_eq!(next(&mut q, false), Ok((true, 8)));
    assert_eq!(next(&mut q, false), Ok((false, 1)));
    assert!(q.push_own(packet(9, 1)));
    assert_eq!(next(&mut q, false), Ok((true, 9)));
    q.put_back(Class::Routed, packet(1, 1));
    assert_eq!(next(&mut q, false), Ok((false, 1)), "sent back, first");
    assert_eq!(next(&mut q, false), Ok((false, 2)));
    assert_eq!(next(&mut q, false), Ok((false, 3)));
    assert_eq!(next(&mut q, false), Err(None));
    // Full: the owner's next is refused, routed frames dropped, counted.
    let mut q = Queues::new(None, 2);
    assert!(q.push_own(packet(1, 1)) && q.push_own(packet(2, 1)));
    assert!(!q.push_own(packet(3, 1)));
    assert_eq!(q.push_routed(1, packet(4, 1)), 0);
    assert_eq!(q.push_routed(1, packet(5, 1)), 0);
    assert_eq!(q.push_routed(1, Packet::new(&[6], 3)), 3);
}

/// A paced link's queues at 2,240 bytes a second (a burst and a backlog
/// of 280 bytes: one longest frame, then one every 125 ms).
fn paced() -> Queues {
    Queues::link(NonZeroU32::new(2_240))
}

/// Advances the paused clock by what `q` waits for, then takes its next.
async fn paced_next(q: &mut Queues) -> (bool, u8) {
    loop {
        match next(q, false) {
            Ok(got) => return got,
            Err(Some(wait)) => tokio::time::advance(wait).await,
            Err(None) => panic!("nothing queued"),
        }
    }
}

/// A paced link sends routed frames at its rate after a burst, and its
/// owner's frames at once while a routed one waits; once the router is
/// gone, what was routed goes unpaced.
#[tokio::test(start_paused = true)]
async fn a_paced_link_holds_routed_frames_never_its_own() {
    use tokio::time::{advance, Instant};
    let mut q = paced();
    for b in 0..5u8 {
        assert_eq!(q.push_routed(1, packet(b, 280)), 0);
    }
    let t0 = Instant::now();
    let ms = || t0.elapsed().as_millis();
    assert_eq!((next(&mut q, false), ms()), (Ok((false, 0)), 0));
    assert_eq!(next(&mut q, false), Err(Some(Duration::from_millis(125))));
    advance(Duration::from_millis(30)).await;
    assert!(q.push_own(packet(9, 1)));
    assert_eq!(
        next(&mut q, false),
        Ok((true, 9)),
        "the owner's frame at once"
    );
    assert_eq!((paced_next(&mut q).await, ms()), ((false, 1), 125));
    assert_eq!((paced_next(&mut q).await, ms()), ((false, 2), 250));
    assert_eq!(
        next(&mut q, true),
        Ok((false, 3)),
        "unpaced once the router is gone"
    );
    assert_eq!(next(&mut q, true), Ok((false, 4)));
    assert_eq!(next(&mut q, true), Err(None));
}

/// Routed frames beyond a second of the pace are dropped, the oldest
/// first, and counted: a frame routed into a flood goes within about a
/// second. The owner's frame queued while a routed one waits for the
/// pace goes first; a link that is down drops what the pace held.
#[tokio::test(start_paused = true)]
async fn a_paced_link_keeps_a_second_of_routed_frames_the_newest() {
    use tokio::time::Instant;
    let mut q = paced();
    let mut dropped = 0;
    for b in 0..100u8 {
        dropped += q.push_routed(1, packet(b, 280));
    }
    let t0 = Instant::now();
    let mut got: Vec<(u128, u8)> = Vec::new();
    while got.last().is_none_or(|g| g.1 != 200) && got.len() < 20 {
        let (own, b) = paced_next(&mut q).await;
        assert!(!own, "not a routed frame");
        got.push((t0.elapsed().as_millis(), b));
        if got.len() == 2 {
            // Queued behind a flood: goes within a second.
            dropped += q.push_routed(1, packet(200, 280));
            assert!(q.push_own(packet(9, 1)));
            assert_eq!(next(&mut q, false), Ok((true, 9)), "the owner's first");
        }
    }
    let last = got
        .iter()
        .find(|g| g.1 == 200)
        .expect("the late frame went");
    assert!(last.0 <= 1_250, "{got:?}");
    assert_eq!(
        got.len(),
        9,
        "the eight newest of the flood, the late one: {got:?}"
    );
    assert!(dropped >= 90, "{dropped} dropped, {got:?}");
    // Down: what the pace held is dropped, and counted.
    q.push_routed(1, packet(201, 280));
    q.push_routed(1, packet(202, 280));
    assert_eq!(paced_next(&mut q).await, (false, 201));
    assert_eq!(q.clear(), 1, "202, held by the pace");
    assert!(q.is_empty());
}

/// A routed frame the pace let go that the socket could not take goes
/// back ahead of the other routed frames, still after the owner's frame
/// queued meanwhile.
#[tokio::test(start_paused = true)]
async fn a_paced_link_lets_the_owners_frame_pass_a_released_one() {
    let mut q = paced();
    for b in [0u8, 1] {
        q.push_routed(1, packet(b, 280));
    }
    assert_eq!(next(&mut q, false), Ok((false, 0)));
    q.put_back(Class::Routed, packet(0, 280));
    assert!(q.push_own(packet(9, 1)));
    assert_eq!(next(&mut q, false), Ok((true, 9)), "the owner's first");
    assert_eq!(next(&mut q, false), Ok((false, 0)), "then 0, kept");
    assert_eq!(paced_next(&mut q).await, (false, 1));
}

/// A paced link serves the senders of routed frames in turn: a frame
/// from a quiet sender goes at its turn, not behind a flood from
/// another, whose oldest frames are the ones dropped.
#[tokio::test(start_paused = true)]
async fn a_paced_link_serves_a_quiet_sender_before_a_flood() {
    let mut q = paced();
    let mut dropped = 0;
    for b in 0..200u8 {
        dropped += q.push_routed(7, packet(b, 280));
    }
    dropped += q.push_routed(9, packet(255, 40));
    let mut got = Vec::new();
    while !got.contains(&255) {
        got.push(paced_next(&mut q).await.1);
        assert!(
            got.len() < 5,
            "the quiet sender waits behind the flood: {got:?}"
        );
    }
    assert!(dropped >= 190);
}

/// A client that stops reading is dropped once a write to it has
/// waited [`CLIENT_WRITE_TIMEOUT`], its queue not yet full: its task
/// ends and its socket closes. (Its task waited on it for good, with
/// the socket, and wrote on when it read again.)
#[tokio::test]
async fn tcpin_drops_a_client_that_stops_reading() {
    let (mut rig, link, addr) = tcpin(true).await;
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(4096).unwrap();
    let mut sleeper = socket.connect(addr).await.unwrap();
    sleeper.write_all(&ping(1)).await.unwrap();
    rig.frame().await;
    // 13 MB in 200 writes (fewer than the client's queue holds): far
    // more than the sockets' buffers, so the writes stall.
    let chunk = std::vec![0u8; 64 * 1024];
    let chunks = 200;
    for _ in 0..chunks {
        rig.send_raw(Links::only(link), &chunk);
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
/// first; the policy's peer and one that sent frames stay.
#[tokio::test]
async fn tcpin_evicts_idle_clients_never_the_policys_peer() {
    let (mut rig, link, addr) = tcpin(false).await;
    let mut peer = TcpStream::connect(addr).await.unwrap();
    peer.write_all(&ping(1)).await.unwrap();
    rig.frame().await;
    rig.set_peers(link, &[peer.local_addr().unwrap()]);
    let mut idle = Vec::new();
    for _ in 0..MAX_CLIENTS - 2 {
        idle.push(TcpStream::connect(addr).await.unwrap());
    }
    let mut talker = TcpStream::connect(addr).await.unwrap();
    talker.write_all(&ping(2)).await.unwrap();
    rig.frame().await;
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
    rig.send_raw(Links::only(link), &ping(3));
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
    let mut rig = Rig::new(true);
    let mut config = LinkConfig::new(format!("tcpin:{addr}").parse().unwrap());
    config.key = Some(key);
    rig.add(config).await;
    let mut signer = Signer::new(key, 1, timestamp_now());
    let h = |seq| Header {
        seq,
        sysid: 1,
        compid: 1,
    };
    let first = FrameBuf::encode(Version::V2, h(1), &Ping { value: 1 }, Some(&mut signer)).unwrap();
    let second =
        FrameBuf::encode(Version::V2, h(2), &Ping { value: 2 }, Some(&mut signer)).unwrap();
    let mut peer = TcpStream::connect(addr).await.unwrap();
    peer.write_all(&first).await.unwrap();
    peer.write_all(&second).await.unwrap();
    for want in [&first, &second] {
        let f = rig.frame().await;
        assert!(f.frame.is_authenticated());
        assert_eq!(f.frame.as_bytes(), &want[..]);
    }
    let mut replayer = TcpStream::connect(addr).await.unwrap();
    replayer.write_all(&first).await.unwrap();
    replayer.write_all(&ping(9)).await.unwrap();
    // Unsigned frames are accepted on this link, unauthenticated: so is
    // the replay (the key's frame, stale), never authenticated.
    for want in [&first[..], &ping(9)[..]] {
        let f = rig.frame().await;
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
    let (rig, link, addr) = tcpin(false).await;
    rig.set_peers(link, &[any_port]);
    let mut peer = TcpStream::connect(addr).await.unwrap();
    let mut strangers = Vec::new();
    for _ in 0..MAX_CLIENTS + 4 {
        let socket = tokio::net::TcpSocket::new_v4().unwrap();
        socket.bind("127.0.0.2:0".parse().unwrap()).unwrap();
        strangers.push(socket.connect(addr).await.unwrap());
    }
    tokio::time::sleep(Duration::from_millis(50)).await;
    rig.send_raw(Links::only(link), &ping(3));
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

/// A link `kind:addr` verifying `key`, its signing state kept in a file
/// of a fresh directory named by `name`: the router, the directory.
async fn keyed_link(
    kind: &str,
    addr: SocketAddr,
    key: [u8; 32],
    name: &str,
) -> (Rig, std::path::PathBuf) {
    let dir = std::env::temp_dir().join(format!("mavframe-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut rig = Rig::new(true);
    let mut config = LinkConfig::new(format!("{kind}:{addr}").parse().unwrap());
    (config.key, config.signing_state) = (Some(key), Some(dir.join("link.state")));
    rig.add(config).await;
    (rig, dir)
}

/// The streams saved in `dir`'s state file, if it holds one.
fn saved_streams(dir: &std::path::Path) -> Option<Vec<crate::signing::StreamState>> {
    let (file, _) = crate::signing::state::StateFile::open(dir.join("link.state")).ok()?;
    Some(file.state().streams.clone())
}

/// A `tcpin` link with a state file saves, when it ends, the verifier
/// its clients share, not the one it opened with (which had seen no
/// frame: a restart would have accepted every capture of the run).
#[tokio::test]
async fn tcpin_saves_the_shared_verifier_at_the_end() {
    let key = [6u8; 32];
    let probe = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = probe.local_addr().unwrap();
    drop(probe);
    let (mut rig, dir) = keyed_link("tcpin", addr, key, "tcpin-state").await;
    let mut peer = TcpStream::connect(addr).await.unwrap();
    peer.write_all(&signed_ping(key, 3, 7)).await.unwrap();
    assert!(rig.frame().await.frame.is_authenticated());
    rig.router.shutdown(Duration::from_secs(2)).await;
    let streams = saved_streams(&dir).unwrap();
    assert!(
        streams
            .iter()
            .any(|s| (s.link_id, s.sysid, s.compid) == (3, 7, 1)),
        "the stream the client's frame came on is saved: {streams:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A link that falls quiet right after accepting a signed frame saves
/// it within about a second, not at its next frame: killed then (a crash,
/// a power loss), a restart refuses a replay of the frame.
#[tokio::test]
async fn a_quiet_link_saves_what_it_accepted_within_a_second() {
    use crate::signing::state::SAVE_INTERVAL;
    let key = [9u8; 32];
    let probe = StdUdp::bind("127.0.0.1:0").unwrap();
    let addr = probe.local_addr().unwrap();
    drop(probe);
    let (mut rig, dir) = keyed_link("udpin", addr, key, "quiet-state").await;
    let frame = signed_ping(key, 4, 5);
    udp_socket().await.send_to(&frame, addr).await.unwrap();
    assert!(rig.frame().await.frame.is_authenticated());
    // Nothing more arrives; the router keeps running.
    tokio::time::sleep(SAVE_INTERVAL * 2 + Duration::from_millis(500)).await;
    let saved = saved_streams(&dir);
    rig.router.shutdown(Duration::from_secs(2)).await;
    let _ = std::fs::remove_dir_all(&dir);
    let streams = saved.expect("a state file, saved while the router runs");
    assert!(
        streams
            .iter()
            .any(|s| (s.link_id, s.sysid, s.compid) == (4, 5, 1)),
        "the frame's stream is saved: {streams:?}"
    );
}

/// A UDP link's receiver, blocked in the socket's receive, sees the
/// router shut down at once, not when its wait times out: its link saves
/// the signing state within a grace shorter than that wait (a receiver
/// still waiting would have its task ended first, the state unsaved).
#[tokio::test]
async fn a_udp_link_saves_its_state_within_a_short_shutdown_grace() {
    let key = [11u8; 32];
    let probe = StdUdp::bind("127.0.0.1:0").unwrap();
    let addr = probe.local_addr().unwrap();
    drop(probe);
    let (mut rig, dir) = keyed_link("udpin", addr, key, "udp-shutdown-state").await;
    udp_socket()
        .await
        .send_to(&signed_ping(key, 6, 8), addr)
        .await
        .unwrap();
    assert!(rig.frame().await.frame.is_authenticated());
    rig.router.shutdown(super::udp::HOUSEKEEPING / 2).await;
    let saved = saved_streams(&dir);
    let _ = std::fs::remove_dir_all(&dir);
    let streams = saved.expect("a state file, saved at the end");
    assert!(
        streams
            .iter()
            .any(|s| (s.link_id, s.sysid, s.compid) == (6, 8, 1)),
        "the frame's stream is saved: {streams:?}"
    );
}

/// A `udpin` link on 127.0.0.1 answering its senders ([`Forward`]), or
/// (`forward` false) whom the test names; its address.
async fn udpin(forward: bool) -> (Rig, LinkId, SocketAddr) {
    let probe = StdUdp::bind("127.0.0.1:0").unwrap();
    let addr = probe.local_addr().unwrap();
    drop(probe);
    let mut rig = Rig::new(forward);
    let link = rig
        .add(LinkConfig::new(format!("udpin:{addr}").parse().unwrap()))
        .await;
    (rig, link, addr)
}

/// A router with one link, `udpout` to `target`.
async fn udpout_to(target: &UdpSocket) -> (Rig, LinkId) {
    let mut rig = Rig::new(false);
    let url = format!("udpout:{}", target.local_addr().unwrap());
    let link = rig.add(LinkConfig::new(url.parse().unwrap())).await;
    (rig, link)
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

/// Waits (2 s at most) until `link`'s parser has dropped `bytes` bytes.
async fn dropped_bytes(rig: &Rig, link: LinkId, bytes: u64) {
    let until = tokio::time::Instant::now() + Duration::from_secs(2);
    while rig.counters(link).parser.bytes_dropped < bytes {
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
    let (mut rig, link, addr) = udpin(true).await;
    let (station, stranger) = (udp_socket().await, udp_socket().await);
    station.send_to(&ping(1), addr).await.unwrap();
    rig.frame().await;
    for i in 0..20u64 {
        stranger.send_to(&[0u8], addr).await.unwrap();
        tokio::time::sleep(Duration::from_millis(10)).await;
        dropped_bytes(&rig, link, i + 1).await;
        rig.send_raw(Links::only(link), &ping(2));
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
    let (mut rig, link, addr) = udpin(true).await;
    let station = udp_socket().await;
    let mut strangers = Vec::new();
    for i in 0..200u32 {
        if i % 20 == 0 {
            station.send_to(&ping(1000 + i), addr).await.unwrap();
            rig.frame().await;
        }
        let s = udp_socket().await;
        s.send_to(&ping(i), addr).await.unwrap();
        rig.frame().await;
        strangers.push(s);
        if i % 20 == 19 {
            rig.send_raw(Links::only(link), &ping(5000 + i));
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

/// Frames routed to a `udpout` link together (those of one datagram
/// received, or of one call of the owner's) leave together: as many whole
/// frames per datagram as fit in [`DATAGRAM_FRAMES_MAX`] bytes, every one
/// intact and in order.
#[tokio::test]
async fn udpout_sends_frames_routed_together_in_one_datagram() {
    let target = udp_socket().await;
    let (rig, link) = udpout_to(&target).await;
    let frames: Vec<FrameBuf> = (0..200).map(|i| ping(0x0101_0100 + i)).collect();
    rig.router.with(|_, out| {
        for f in &frames {
            out.send_routed(Links::only(link), f);
        }
    });
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
    let (mut rig, link) = udpout_to(&target).await;
    rig.send_raw(Links::only(link), &ping(1));
    let mut buf = [0u8; 64];
    let (_, local) = tokio::time::timeout(Duration::from_secs(2), target.recv_from(&mut buf))
        .await
        .unwrap()
        .unwrap();
    let local = SocketAddr::from(([127, 0, 0, 1], local.port()));
    let third = udp_socket().await;
    third.send_to(&ping(66), local).await.unwrap();
    target.send_to(&ping(7), local).await.unwrap();
    let f = rig.frame().await;
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
    let mut rig = Rig::new(true);
    let mut config = LinkConfig::new(format!("tcpin:{addr}").parse().unwrap());
    config.key = Some(key);
    let link = rig.add(config).await;
    let mut clients = Vec::new();
    for i in 0..MAX_CLIENTS as u8 {
        let mut c = TcpStream::connect(addr).await.unwrap();
        c.write_all(&signed_ping(key, 1, 10 + i)).await.unwrap();
        let f = rig.frame().await;
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
    rig.send_raw(Links::only(link), &ping(3));
    for (i, c) in clients.iter_mut().enumerate() {
        let mut got = [0u8; 13];
        let read = tokio::time::timeout(Duration::from_secs(2), c.read_exact(&mut got)).await;
        assert!(matches!(read, Ok(Ok(_))), "client {i} evicted");
        assert_eq!(got[..], ping(3)[..], "client {i}");
    }
    for (i, s) in flood.iter_mut().enumerate() {
        assert_eq!(read_for(s, 20).await, None, "flood connection {i} is open");
    }
    assert_eq!(rig.counters(link).refused_clients, 20);
}

/// A `tcpin` link without a key whose policy names its peer: a flood of
/// connections, each sending an unsigned frame every 10 ms, never
/// evicts that client, and gets none of its traffic.
#[tokio::test]
async fn tcpin_flood_never_evicts_the_policys_peer() {
    let (mut rig, link, addr) = tcpin(false).await;
    let mut peer = TcpStream::connect(addr).await.unwrap();
    peer.write_all(&ping(1)).await.unwrap();
    rig.frame().await;
    rig.set_peers(link, &[peer.local_addr().unwrap()]);
    let mut flood = Vec::new();
    for i in 0..MAX_CLIENTS as u32 + 8 {
        let mut s = TcpStream::connect(addr).await.unwrap();
        let _ = s.write_all(&ping(i)).await;
        flood.push(s);
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    rig.send_raw(Links::only(link), &ping(3));
    assert_eq!(read_for(&mut peer, 300).await, Some(ping(3).to_vec()));
    let mut served = 0;
    for s in &mut flood {
        served += usize::from(read_for(s, 5).await.is_some_and(|b| !b.is_empty()));
    }
    assert_eq!(served, 0, "strangers got the owner's traffic");
}

/// `udpin` under a policy that names its peers: nothing goes out until
/// it names peers, then to those only, whoever sends frames.
#[tokio::test]
async fn udpin_sends_only_to_the_policys_peers() {
    let (mut rig, link, addr) = udpin(false).await;
    let (a, b, stranger) = (udp_socket().await, udp_socket().await, udp_socket().await);
    for s in [&a, &b, &stranger] {
        s.send_to(&ping(1), addr).await.unwrap();
        rig.frame().await;
    }
    rig.send_raw(Links::only(link), &ping(2));
    assert_eq!(datagram_for(&a, 100).await, None, "no peer named yet");
    let named = [a.local_addr().unwrap(), b.local_addr().unwrap()];
    rig.set_peers(link, &named);
    rig.send_raw(Links::only(link), &ping(3));
    assert_eq!(datagram_for(&a, 500).await, Some(ping(3).to_vec()));
    assert_eq!(datagram_for(&b, 500).await, Some(ping(3).to_vec()));
    assert_eq!(datagram_for(&stranger, 50).await, None);
    rig.set_peers(link, &[b.local_addr().unwrap()]);
    rig.send_raw(Links::only(link), &ping(4));
    assert_eq!(datagram_for(&b, 500).await, Some(ping(4).to_vec()));
    assert_eq!(datagram_for(&a, 50).await, None, "one peer");
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
    let mut rig = Rig::new(true);
    let mut config = LinkConfig::new(format!("udpin:{addr}").parse().unwrap());
    config.key = Some(key);
    let link = rig.add(config).await;
    let (station, stranger) = (udp_socket().await, udp_socket().await);
    stranger.send_to(&ping(1), addr).await.unwrap();
    assert!(!rig.frame().await.frame.is_authenticated());
    rig.send_raw(Links::only(link), &ping(2));
    assert_eq!(
        datagram_for(&stranger, 100).await,
        None,
        "an unsigned sender answered"
    );
    station
        .send_to(&signed_ping(key, 1, 1), addr)
        .await
        .unwrap();
    assert!(rig.frame().await.frame.is_authenticated());
    rig.send_raw(Links::only(link), &ping(3));
    assert_eq!(datagram_for(&station, 500).await, Some(ping(3).to_vec()));
    assert_eq!(datagram_for(&stranger, 50).await, None);
}

/// `Out::route` sends a frame where the policy says, and nowhere else.
#[tokio::test]
async fn route_sends_where_the_policy_says() {
    let (mut rig, from, addr) = udpin(false).await;
    let (t1, t2) = (udp_socket().await, udp_socket().await);
    let mut outs = Vec::new();
    for t in [&t1, &t2] {
        let url = format!("udpout:{}", t.local_addr().unwrap());
        outs.push(rig.add(LinkConfig::new(url.parse().unwrap())).await);
    }
    let station = udp_socket().await;
    station.send_to(&ping(5), addr).await.unwrap();
    let copy = rig.frame().await;
    assert_eq!(copy.link, from);
    let to = rig.route(&copy, Links::only(outs[1]).union(Links::only(40)), false);
    assert_eq!(to, Links::only(outs[1]), "links that exist only");
    assert_eq!(datagram_for(&t2, 500).await, Some(ping(5).to_vec()));
    assert_eq!(datagram_for(&t1, 50).await, None);
}

/// `route_signed` frames an unsigned frame again on each link, signed
/// with that link's key and keeping the sender's header; a link
/// without a key sends it unsigned, and `route` never signs.
#[tokio::test]
async fn route_signed_signs_with_each_links_key() {
    use crate::signing::Verifier;
    let key = [7u8; 32];
    let (mut rig, _, addr) = udpin(false).await;
    let (signed_to, plain_to) = (udp_socket().await, udp_socket().await);
    let mut keyed = LinkConfig::new(
        format!("udpout:{}", signed_to.local_addr().unwrap())
            .parse()
            .unwrap(),
    );
    keyed.key = Some(key);
    let keyed = rig.add(keyed).await;
    let plain_url = format!("udpout:{}", plain_to.local_addr().unwrap());
    let plain = rig.add(LinkConfig::new(plain_url.parse().unwrap())).await;
    udp_socket().await.send_to(&ping(5), addr).await.unwrap();
    let inbound = rig.frame().await;

    rig.route(&inbound, Links::only(keyed), false);
    assert_eq!(
        datagram_for(&signed_to, 500).await,
        Some(ping(5).to_vec()),
        "route: as it came"
    );
    rig.route(&inbound, Links::only(keyed).union(Links::only(plain)), true);
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

/// [`Forward`] learns authenticated senders, and every sender of a link
/// the owner trusts, as trusted: 200 strangers' ids through another link
/// never evict that route.
#[tokio::test]
async fn forward_keeps_trusted_routes_among_200_strangers() {
    let mut router = Router::<TestDialect, _>::new(Forward::new());
    let trusted = router
        .add(LinkConfig::new("udpin:127.0.0.1:0".parse().unwrap()))
        .await
        .unwrap();
    let stranger_link = router
        .add(LinkConfig::new("udpin:127.0.0.1:0".parse().unwrap()))
        .await
        .unwrap();
    let frame = |sysid: u8| {
        let h = Header {
            seq: 0,
            sysid,
            compid: 1,
        };
        let bytes = FrameBuf::encode(Version::V2, h, &Ping { value: 1 }, None).unwrap();
        let mut parser = Parser::<TestDialect>::new();
        let mut input = &[&bytes[..], &[0xfd][..]].concat()[..];
        ReceivedBuf::from(&parser.next(&mut input).unwrap())
    };
    router.with(|forward, out| {
        forward.set_trusted(trusted, true);
        let judge = |forward: &mut Forward, out: &mut Out<'_>, link, sysid| {
            let copy = frame(sysid);
            forward.frame(&Inbound::new(link, copy.received(), None), out);
        };
        judge(forward, out, trusted, 1);
        for id in 0..200u8 {
            judge(forward, out, stranger_link, 2 + id);
        }
        assert_eq!(forward.table().links_to(1, 1), Links::only(trusted));
    });
}

/// A signed frame one link accepted is a replay on every other link with
/// the same key (one replay window per key, as MAVLink keys replay state
/// by the signature's stream wherever a frame arrives); a link with
/// another key keeps a window of its own. (With a window per link, a
/// listener that received the frame routed to it replayed it into its own
/// link, where it was authenticated again and routed on.)
#[tokio::test]
async fn links_with_one_key_share_one_replay_window() {
    let (key, other_key) = ([11u8; 32], [12u8; 32]);
    let mut rig = Rig::new(false);
    let mut addrs = Vec::new();
    for k in [key, key, other_key] {
        let probe = StdUdp::bind("127.0.0.1:0").unwrap();
        let addr = probe.local_addr().unwrap();
        drop(probe);
        let mut config = LinkConfig::new(format!("udpin:{addr}").parse().unwrap());
        config.key = Some(k);
        rig.add(config).await;
        addrs.push(addr);
    }
    let sender = udp_socket().await;
    let frame = signed_ping(key, 2, 9);
    sender.send_to(&frame, addrs[0]).await.unwrap();
    let first = rig.frame().await;
    assert!(first.frame.is_authenticated() && first.link == 0);
    // The replay into the key's other link: returned unauthenticated (the
    // links accept unsigned frames), and counted as stale.
    sender.send_to(&frame, addrs[1]).await.unwrap();
    let replay = rig.frame().await;
    assert_eq!(replay.link, 1);
    assert!(
        !replay.frame.is_authenticated(),
        "a replay was authenticated"
    );
    assert_eq!(rig.counters(1).parser.stale_timestamp, 1);
    // The same stream, signed with the other key, is that key's own.
    let theirs = signed_ping(other_key, 2, 9);
    sender.send_to(&theirs, addrs[2]).await.unwrap();
    assert!(rig.frame().await.frame.is_authenticated());
}

/// A link trusted like the key opens only on loopback addresses, checked
/// when the transport is opened (again at each reopen, once its name is
/// resolved again): a target elsewhere, or a socket listening on every
/// interface, is refused, and the link stays down (reopened every
/// second), said with the reason.
#[tokio::test]
async fn a_loopback_only_link_opens_on_loopback_addresses_only() {
    let mut rig = Rig::new(false);
    let config = |conn: &str| LinkConfig {
        loopback_only: true,
        ..LinkConfig::new(conn.parse().unwrap())
    };
    for conn in ["udpout:192.0.2.1:14550", "udpin:0.0.0.0:0"] {
        let link = rig.add(config(conn)).await;
        let Some(RouterEvent::LinkDown { link: l, error }) = rig.event(2_000).await else {
            panic!("{conn}: no LinkDown");
        };
        assert_eq!(l, link);
        assert_eq!(
            error.kind(),
            io::ErrorKind::PermissionDenied,
            "{conn}: {error}"
        );
        assert!(
            format!("{error}").contains("not a loopback address"),
            "{error}"
        );
    }
    for conn in ["udpout:127.0.0.1:14550", "udpin:127.0.0.1:0"] {
        rig.add(config(conn)).await;
    }
    assert!(rig.event(300).await.is_none(), "a loopback link went down");
}

/// A link that cannot be opened at start (a host name that does not
/// resolve, an address taken) starts down, said once, and is opened again
/// every second: the router and its other links go on. (A UDP link's
/// failure was an error of `add`, which stopped the daemons.)
#[tokio::test]
async fn a_link_that_cannot_open_starts_down_and_is_retried() {
    let taken = StdUdp::bind("127.0.0.1:0").unwrap();
    let taken_at = taken.local_addr().unwrap();
    let mut rig = Rig::new(false);
    let link = rig
        .add(LinkConfig::new(
            format!("udpin:{taken_at}").parse().unwrap(),
        ))
        .await;
    let down = rig.event(2_000).await;
    assert!(matches!(down, Some(RouterEvent::LinkDown { link: l, .. }) if l == link));
    drop(taken);
    let up = rig.event(3_000).await;
    assert!(matches!(up, Some(RouterEvent::LinkUp { link: l }) if l == link));
    let file = rig
        .router
        .add(LinkConfig::new("file:/dev/null".parse().unwrap()))
        .await;
    assert_eq!(file.expect_err("a file").kind(), io::ErrorKind::Unsupported);
}
