//! mavframe's connections on the FBWAG dialect: connection strings, and
//! frames over UDP (in and out), TCP (client and server) on 127.0.0.1.
//! Ports are chosen by the system (bind to port 0, read the port back);
//! every wait is bounded (2 s at most).
// The transports exist with std only (mavframe's `std`, enabled by ours).
#![cfg(feature = "std")]

use fbwag_dialect::dialects::minimal::Heartbeat;
use fbwag_dialect::mavframe::conn::{
    AnyTransport, Connection, Endpoint, ParseEndpointError, Transport, DEFAULT_BAUD,
    MAX_PENDING_OUTPUT,
};
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::mavframe::frame::{encode, Header, Version};
use fbwag_dialect::mavframe::parser::{Parser, Unsigned};
use fbwag_dialect::mavframe::{Signer, Verifier};
use fbwag_dialect::{Dialect, FbwagFailsafeStatus, FbwagNotice, Message};
use std::collections::BTreeSet;
use std::io::{self, Read, Write};
use std::net::{Ipv4Addr, SocketAddr, TcpListener, TcpStream};
use std::thread;
use std::time::{Duration, Instant};

/// The longest any test waits for something that should come.
const LIMIT: Option<Duration> = Some(Duration::from_secs(2));
/// How long to wait for something that should not come.
const QUIET: Option<Duration> = Some(Duration::from_millis(150));

type Link = Connection<Dialect>;

fn notice(timestamp: u32) -> FbwagNotice {
    FbwagNotice {
        system_id: 1,
        component_id: 1,
        failsafe_status: FbwagFailsafeStatus::RC_LOST,
        text: chars("FBWAG"),
        timestamp,
    }
}

fn localhost(port: u16) -> SocketAddr {
    SocketAddr::from((Ipv4Addr::LOCALHOST, port))
}

fn open(s: &str) -> Link {
    Link::open(&s.parse().unwrap()).unwrap()
}

fn port_of(link: &Link) -> u16 {
    link.transport().local_addr().unwrap().port()
}

/// Waits for the next frame, failing the test after [`LIMIT`].
fn expect_frame<T: Transport>(
    link: &mut Connection<Dialect, T>,
) -> fbwag_dialect::mavframe::ReceivedBuf<Dialect> {
    link.recv(LIMIT)
        .unwrap()
        .expect("no frame within the time limit")
}

fn expect_notice(link: &mut Link) -> (Header, FbwagNotice) {
    let f = expect_frame(link);
    match f.message() {
        Some(Message::FbwagNotice(n)) => (f.header(), n),
        other => panic!("expected FBWAG_NOTICE, got {other:?}"),
    }
}

fn frame_bytes(seq: u8, sysid: u8, timestamp: u32) -> Vec<u8> {
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    let h = Header {
        seq,
        sysid,
        compid: 1,
    };
    let n = encode(Version::V2, h, &notice(timestamp), None, &mut buf).unwrap();
    buf[..n].to_vec()
}

// ---------------------------------------------------------------- endpoints

#[test]
fn endpoints_parse_every_scheme() {
    let cases: [(&str, Endpoint); 11] = [
        (
            "udpin:0.0.0.0:14550",
            Endpoint::UdpIn("0.0.0.0:14550".parse::<SocketAddr>().unwrap().into()),
        ),
        (
            "udpout:127.0.0.1:14550",
            Endpoint::UdpOut(localhost(14550).into()),
        ),
        ("tcp:127.0.0.1:5760", Endpoint::Tcp(localhost(5760).into())),
        (
            "tcpin:0.0.0.0:5760",
            Endpoint::TcpIn("0.0.0.0:5760".parse::<SocketAddr>().unwrap().into()),
        ),
        (
            "udpin:[::1]:14550",
            Endpoint::UdpIn("[::1]:14550".parse::<SocketAddr>().unwrap().into()),
        ),
        ("tcpin:127.0.0.1:0", Endpoint::TcpIn(localhost(0).into())),
        (
            "serial:/dev/serial0:460800",
            Endpoint::Serial {
                path: "/dev/serial0".into(),
                baud: 460_800,
            },
        ),
        (
            "serial:COM3:115200",
            Endpoint::Serial {
                path: "COM3".into(),
                baud: 115_200,
            },
        ),
        // The last ':'-part is the baud when all digits…
        (
            "serial:/dev/odd:name:921600",
            Endpoint::Serial {
                path: "/dev/odd:name".into(),
                baud: 921_600,
            },
        ),
        // …a path keeps its ':' otherwise, with the default baud.
        (
            "serial:/dev/odd:name",
            Endpoint::Serial {
                path: "/dev/odd:name".into(),
                baud: 57_600,
            },
        ),
        (
            "serial:/dev/ttyUSB0",
            Endpoint::Serial {
                path: "/dev/ttyUSB0".into(),
                baud: DEFAULT_BAUD,
            },
        ),
    ];
    for (s, want) in cases {
        let got: Endpoint = s.parse().unwrap_or_else(|e| panic!("{s}: {e}"));
        assert_eq!(got, want, "{s}");
        // Display round-trips, to the same endpoint.
        let shown = got.to_string();
        assert_eq!(shown.parse::<Endpoint>().unwrap(), got, "{s} -> {shown}");
        // Canonical strings display as written; the others gain the baud.
        if s.starts_with("serial:") && shown != s {
            assert_eq!(shown, format!("{s}:57600"));
        } else {
            assert_eq!(shown, s);
        }
    }
}

#[test]
fn udp_is_an_alias_of_udpin_and_displays_as_udpin() {
    let e: Endpoint = "udp:0.0.0.0:14550".parse().unwrap();
    assert_eq!(
        e,
        Endpoint::UdpIn("0.0.0.0:14550".parse::<SocketAddr>().unwrap().into())
    );
    assert_eq!(e.to_string(), "udpin:0.0.0.0:14550");
    assert_eq!(e.scheme(), "udpin");
}

#[test]
fn serial_paths_with_colons_and_digits_round_trip() {
    // A path whose own last part is digits only survives Display, which
    // always writes the baud.
    let e = Endpoint::Serial {
        path: "/dev/weird:5".into(),
        baud: 57_600,
    };
    assert_eq!(e.to_string(), "serial:/dev/weird:5:57600");
    assert_eq!(e.to_string().parse::<Endpoint>().unwrap(), e);
}

#[test]
fn bad_endpoints_say_which_part_is_wrong() {
    let cases = [
        (
            "",
            "`` has no scheme: expected SCHEME:ADDRESS with SCHEME one of udpin, udp, udpout, \
             udpbcast, tcp, tcpout, tcpin, serial, file (e.g. udpin:0.0.0.0:14550)",
        ),
        (
            "/dev/ttyUSB0",
            "`/dev/ttyUSB0` has no scheme: expected SCHEME:ADDRESS with SCHEME one of udpin, \
             udp, udpout, udpbcast, tcp, tcpout, tcpin, serial, file (e.g. udpin:0.0.0.0:14550)",
        ),
        (
            "udpmcast:0.0.0.0:14550",
            "unknown scheme `udpmcast`: expected one of udpin, udp, udpout, udpbcast, tcp, tcpout, tcpin, serial, file",
        ),
        (
            "UDPIN:0.0.0.0:14550",
            "unknown scheme `UDPIN`: expected one of udpin, udp, udpout, udpbcast, tcp, tcpout, tcpin, serial, file",
        ),
        (
            "udpin:0.0.0.0",
            "udpin: address `0.0.0.0` has no port: expected HOST:PORT, e.g. 0.0.0.0:14550",
        ),
        (
            "tcp:",
            "tcp: address `` has no port: expected HOST:PORT, e.g. 127.0.0.1:5760",
        ),
        (
            "tcp:local_host:5760",
            "tcp: host `local_host` is neither an IP address nor a host name: expected IPv4 \
             such as 127.0.0.1, IPv6 in brackets such as [::1], or a name such as localhost",
        ),
        (
            "udpin:::1:14550",
            "udpin: host `::1` is neither an IP address nor a host name: expected IPv4 \
             such as 127.0.0.1, IPv6 in brackets such as [::1], or a name such as localhost",
        ),
        (
            "udpout:256.0.0.1:14550",
            "udpout: host `256.0.0.1` is neither an IP address nor a host name: expected IPv4 \
             such as 127.0.0.1, IPv6 in brackets such as [::1], or a name such as localhost",
        ),
        (
            "tcpin:0.0.0.0:65536",
            "tcpin: port `65536` is not a number in 0..=65535",
        ),
        (
            "udp:0.0.0.0:+14550",
            "udp: port `+14550` is not a number in 0..=65535",
        ),
        (
            "udpin:0.0.0.0:",
            "udpin: port `` is not a number in 0..=65535",
        ),
        (
            "udpout:127.0.0.1:0",
            "udpout: port 0 cannot be sent to: expected a port in 1..=65535",
        ),
        (
            "tcp:127.0.0.1:0",
            "tcp: port 0 cannot be sent to: expected a port in 1..=65535",
        ),
        (
            "serial:",
            "serial: missing device path: expected serial:PATH[:BAUD], e.g. \
             serial:/dev/serial0:57600",
        ),
        (
            "serial::57600",
            "serial: missing device path: expected serial:PATH[:BAUD], e.g. \
             serial:/dev/serial0:57600",
        ),
        (
            "serial:/dev/ttyUSB0:",
            "serial: empty baud rate after the last ':': expected serial:PATH[:BAUD], e.g. \
             serial:/dev/serial0:57600",
        ),
        (
            "serial:/dev/ttyUSB0:0",
            "serial: baud rate `0` is not in 1..=4294967295",
        ),
        (
            "serial:/dev/ttyUSB0:99999999999",
            "serial: baud rate `99999999999` is not in 1..=4294967295",
        ),
    ];
    for (s, msg) in cases {
        let err = s.parse::<Endpoint>().unwrap_err();
        assert_eq!(err.to_string(), msg, "{s:?}");
    }
    // The variants carry the parts, for programs that react to them.
    assert_eq!(
        "tcp:127.0.0.1:x".parse::<Endpoint>().unwrap_err(),
        ParseEndpointError::InvalidPort {
            scheme: "tcp".into(),
            port: "x".into()
        }
    );
}

#[test]
fn bad_endpoint_strings_never_panic() {
    // Every prefix of some strings, and some awkward bytes.
    let samples = [
        "serial:/dev/ttyUSB0:57600",
        "udpin:[::ffff:127.0.0.1]:14550",
        "tcpin:[fe80::1%eth0]:5760",
        "udp:[]:1",
        "udp:[::1:1",
        "tcp:1.2.3.4:5:6",
        "serial:é:ü:9",
    ];
    for s in samples {
        for end in (0..=s.len()).filter(|&i| s.is_char_boundary(i)) {
            let _ = s[..end].parse::<Endpoint>();
        }
    }
}

#[test]
fn serial_endpoint_without_a_device_fails_to_open() {
    let e: Endpoint = "serial:/dev/mavframe-no-such-device:57600".parse().unwrap();
    let err = Link::open(&e).unwrap_err();
    // Without mavframe's `serial` feature the endpoint is refused outright;
    // with it, the device is missing.
    if err.kind() == io::ErrorKind::Unsupported {
        assert_eq!(
            err.to_string(),
            "serial endpoints need mavframe's `serial` feature"
        );
    }
}

// ---------------------------------------------------------------------- UDP

#[test]
fn udpin_and_udpout_exchange_notices_and_replies_go_to_every_station_that_spoke() {
    let mut server = open("udpin:127.0.0.1:0");
    let port = port_of(&server);
    let mut a = Link::open(&Endpoint::UdpOut(localhost(port).into())).unwrap();
    let mut b = Link::open(&Endpoint::UdpOut(localhost(port).into())).unwrap();

    // Before anyone spoke the server has nobody to answer: dropped, no error.
    server.send_auto(1, 1, &notice(0)).unwrap();
    let AnyTransport::UdpIn(udp) = server.transport() else {
        unreachable!()
    };
    assert_eq!(udp.peer(), None);

    a.send_auto(10, 1, &notice(1)).unwrap();
    let (h, n) = expect_notice(&mut server);
    assert_eq!((h.sysid, n), (10, notice(1)));
    server.send_auto(1, 1, &notice(2)).unwrap();
    let (h, n) = expect_notice(&mut a);
    assert_eq!((h.sysid, h.seq, n), (1, 1, notice(2)));

    // B speaks: replies go to both stations, A not displaced.
    b.send_auto(20, 1, &notice(3)).unwrap();
    let (h, _) = expect_notice(&mut server);
    assert_eq!(h.sysid, 20);
    server.send_auto(1, 1, &notice(4)).unwrap();
    assert_eq!(expect_notice(&mut b).1, notice(4));
    assert_eq!(expect_notice(&mut a).1, notice(4));

    // Garbage from a third socket (no frame) makes it no peer.
    let stranger = std::net::UdpSocket::bind(localhost(0)).unwrap();
    stranger.send_to(b"\x00", localhost(port)).unwrap();
    assert!(server.recv(QUIET).unwrap().is_none());
    server.send_auto(1, 1, &notice(5)).unwrap();
    assert_eq!(expect_notice(&mut a).1, notice(5));
    stranger.set_read_timeout(QUIET).unwrap();
    assert!(
        stranger.recv(&mut [0u8; 64]).is_err(),
        "the stranger got traffic"
    );
    assert_eq!(server.stats().frames, 2);
    assert_eq!(server.stats().seq_lost, 0);
}

#[test]
fn udp_carries_mavlink1_heartbeats_and_counts_garbage() {
    let mut server = open("udpin:127.0.0.1:0");
    let mut client = Link::open(&Endpoint::UdpOut(localhost(port_of(&server)).into())).unwrap();
    client.set_version(Version::V1);
    client.send_auto(5, 6, &Heartbeat::default()).unwrap();
    let f = expect_frame(&mut server);
    assert_eq!(f.frame().version(), Version::V1);
    assert_eq!(f.message(), Some(Message::Heartbeat(Heartbeat::default())));
    assert_eq!(f.meta().map(|m| m.name), Some("HEARTBEAT"));

    // Garbage before a frame in one datagram is skipped and counted.
    let mut bytes = b"noise".to_vec();
    bytes.extend(frame_bytes(0, 7, 42));
    client.send_raw(&bytes).unwrap();
    assert_eq!(expect_notice(&mut server).1, notice(42));
    assert_eq!(server.stats().bytes_dropped, 5);
}

#[test]
fn recv_waits_no_longer_than_asked() {
    let mut udp = open("udpin:127.0.0.1:0");
    let t = Instant::now();
    assert!(udp.recv(Some(Duration::ZERO)).unwrap().is_none());
    assert!(t.elapsed() < Duration::from_millis(500));
    let t = Instant::now();
    assert!(udp
        .recv(Some(Duration::from_millis(100)))
        .unwrap()
        .is_none());
    let waited = t.elapsed();
    assert!(waited >= Duration::from_millis(100), "{waited:?}");
    assert!(waited < Duration::from_millis(1500), "{waited:?}");

    let mut server = open("tcpin:127.0.0.1:0");
    let mut client = Link::open(&Endpoint::Tcp(localhost(port_of(&server)).into())).unwrap();
    for link in [&mut server, &mut client] {
        let t = Instant::now();
        assert!(link.recv(Some(Duration::ZERO)).unwrap().is_none());
        assert!(link
            .recv(Some(Duration::from_millis(50)))
            .unwrap()
            .is_none());
        let waited = t.elapsed();
        assert!(waited >= Duration::from_millis(50), "{waited:?}");
        assert!(waited < Duration::from_millis(1500), "{waited:?}");
    }
    // A zero-timeout receive leaves the client able to send whole frames.
    client.send_auto(3, 1, &notice(9)).unwrap();
    assert_eq!(expect_notice(&mut server).1, notice(9));
}

// ---------------------------------------------------------------------- TCP

#[test]
fn tcpin_serves_two_clients_both_ways() {
    let mut server = open("tcpin:127.0.0.1:0");
    let port = port_of(&server);
    let mut a = Link::open(&Endpoint::Tcp(localhost(port).into())).unwrap();
    let mut b = Link::open(&Endpoint::Tcp(localhost(port).into())).unwrap();

    a.send_auto(10, 1, &notice(1)).unwrap();
    b.send_auto(20, 1, &notice(2)).unwrap();
    let mut senders = BTreeSet::new();
    for _ in 0..2 {
        let (h, n) = expect_notice(&mut server);
        assert_eq!(n.timestamp, u32::from(h.sysid) / 10);
        senders.insert(h.sysid);
    }
    assert_eq!(senders, BTreeSet::from([10, 20]));
    let AnyTransport::TcpIn(tcp) = server.transport() else {
        unreachable!()
    };
    assert_eq!(tcp.clients().count(), 2);

    // One send reaches every client.
    server.send_auto(1, 1, &notice(3)).unwrap();
    assert_eq!(expect_notice(&mut a).1, notice(3));
    assert_eq!(expect_notice(&mut b).1, notice(3));

    // A client that leaves is dropped; the other is still served.
    drop(a);
    let deadline = Instant::now() + Duration::from_secs(2);
    loop {
        assert!(server
            .recv(Some(Duration::from_millis(20)))
            .unwrap()
            .is_none());
        let AnyTransport::TcpIn(tcp) = server.transport() else {
            unreachable!()
        };
        if tcp.clients().count() == 1 {
            break;
        }
        assert!(Instant::now() < deadline, "closed client not dropped");
    }
    server.send_auto(1, 1, &notice(4)).unwrap();
    assert_eq!(expect_notice(&mut b).1, notice(4));
    b.send_auto(20, 1, &notice(5)).unwrap();
    assert_eq!(expect_notice(&mut server).1, notice(5));
}

#[test]
fn tcp_frames_split_across_writes_still_parse() {
    // Three frames cut at every awkward place (inside the header, the
    // payload, the checksum), written with pauses so reads see the pieces.
    let mut bytes = Vec::new();
    for seq in 0..3 {
        bytes.extend(frame_bytes(seq, 9, 100 + u32::from(seq)));
    }
    let write_split = |stream: &mut TcpStream| {
        stream.set_nodelay(true).unwrap();
        for piece in bytes.chunks(7) {
            stream.write_all(piece).unwrap();
            thread::sleep(Duration::from_millis(3));
        }
    };

    // Into a tcpin server, from a plain socket.
    let mut server = open("tcpin:127.0.0.1:0");
    let mut raw = TcpStream::connect(localhost(port_of(&server))).unwrap();
    thread::scope(|s| {
        s.spawn(|| write_split(&mut raw));
        for seq in 0..3 {
            let (h, n) = expect_notice(&mut server);
            assert_eq!((h.seq, n.timestamp), (seq, 100 + u32::from(seq)));
        }
    });
    assert_eq!(server.stats().bytes_dropped, 0);

    // Into a tcp client, from a plain listener.
    let listener = TcpListener::bind(localhost(0)).unwrap();
    let port = listener.local_addr().unwrap().port();
    let mut client = Link::open(&Endpoint::Tcp(localhost(port).into())).unwrap();
    let (mut peer, _) = listener.accept().unwrap();
    thread::scope(|s| {
        s.spawn(|| write_split(&mut peer));
        for seq in 0..3 {
            let (h, n) = expect_notice(&mut client);
            assert_eq!((h.seq, n.timestamp), (seq, 100 + u32::from(seq)));
        }
    });

    // The client's own frames arrive whole at the plain peer.
    client.send_auto(4, 2, &notice(7)).unwrap();
    peer.set_read_timeout(LIMIT).unwrap();
    let mut got = [0u8; 64];
    let mut n = 0;
    while n < 24 {
        n += peer.read(&mut got[n..]).unwrap();
    }
    let mut parser = Parser::<Dialect>::new();
    let mut input = &got[..n];
    let f = parser.next(&mut input).unwrap();
    assert_eq!(
        f.frame().header(),
        Header {
            seq: 0,
            sysid: 4,
            compid: 2
        }
    );
    assert_eq!(f.message(), Some(Message::FbwagNotice(notice(7))));

    // The peer closing is an error, not a silent timeout.
    drop(peer);
    let err = client.recv(LIMIT).unwrap_err();
    assert_eq!(err.kind(), io::ErrorKind::UnexpectedEof);
}

#[test]
fn tcpin_keeps_split_frames_of_two_clients_apart() {
    // A's frame arrives in two pieces with B's whole frame in between: the
    // server must not parse A's first piece followed by B's bytes.
    let mut server = open("tcpin:127.0.0.1:0");
    let port = port_of(&server);
    let mut a = TcpStream::connect(localhost(port)).unwrap();
    let mut b = TcpStream::connect(localhost(port)).unwrap();
    a.set_nodelay(true).unwrap();
    b.set_nodelay(true).unwrap();
    let frame_a = frame_bytes(0, 10, 1);
    let frame_b = frame_bytes(0, 20, 2);
    a.write_all(&frame_a[..9]).unwrap();
    // The server reads A's piece and holds it: no frame yet.
    assert!(server.recv(QUIET).unwrap().is_none());
    b.write_all(&frame_b).unwrap();
    let (h, n) = expect_notice(&mut server);
    assert_eq!((h.sysid, n), (20, notice(2)));
    a.write_all(&frame_a[9..]).unwrap();
    let (h, n) = expect_notice(&mut server);
    assert_eq!((h.sysid, n), (10, notice(1)));
    let stats = server.stats();
    assert_eq!(
        (stats.frames, stats.bad_crc, stats.bytes_dropped),
        (2, 0, 0)
    );
}

#[test]
fn tcpin_drops_a_client_that_stops_reading_without_blocking() {
    let mut server = open("tcpin:127.0.0.1:0");
    let stalled = TcpStream::connect(localhost(port_of(&server))).unwrap();
    // Flood it (16 KiB at a time, to keep the test short): the socket
    // buffers fill, the server's pending output passes its cap and the
    // client is dropped, while every send returns at once.
    let block = vec![0x55u8; 16 * 1024];
    let started = Instant::now();
    let mut sends = 0u32;
    loop {
        server.send_raw(&block).unwrap();
        sends += 1;
        let AnyTransport::TcpIn(tcp) = server.transport() else {
            unreachable!()
        };
        if tcp.clients().count() == 0 {
            break;
        }
        assert!(
            started.elapsed() < Duration::from_secs(2),
            "stalled client still connected after {sends} sends"
        );
    }
    assert!(sends > MAX_PENDING_OUTPUT as u32 / 16 / 1024, "{sends}");
    drop(stalled);
}

// ------------------------------------------------------------------ signing

#[test]
fn signed_frames_are_verified_and_unsigned_ones_refused() {
    let key = [7u8; 32];
    let server_parser = Parser::<Dialect>::with_signing(Verifier::new(key), Unsigned::Refuse);
    let AnyTransport::UdpIn(udp) =
        fbwag_dialect::mavframe::conn::open(&"udpin:127.0.0.1:0".parse().unwrap()).unwrap()
    else {
        unreachable!()
    };
    let port = udp.local_addr().unwrap().port();
    let mut server = Connection::<Dialect, _>::with_parser(udp, server_parser);
    let mut client = Link::open(&Endpoint::UdpOut(localhost(port).into())).unwrap();

    client.send_auto(1, 1, &notice(1)).unwrap();
    client.set_signer(Some(Signer::new(key, 3, 0)));
    client.send_auto(1, 1, &notice(2)).unwrap();
    let f = expect_frame(&mut server);
    assert!(f.is_authenticated() && f.frame().is_signed());
    assert_eq!(f.message(), Some(Message::FbwagNotice(notice(2))));
    assert_eq!(server.stats().unsigned_rejected, 1);
    // The signer keeps up with the clock (timestamps since 2015).
    let ts = f.frame().signature().unwrap().timestamp();
    assert!(ts > 10 * 365 * 24 * 3600 * 100_000, "{ts}");
    assert_eq!(client.signer().unwrap().timestamp(), ts + 1);
}

// ------------------------------------------------------------- sequencing

#[test]
fn send_auto_numbers_frames_and_gaps_show_in_link_stats() {
    let mut server = open("udpin:127.0.0.1:0");
    let mut client = Link::open(&Endpoint::UdpOut(localhost(port_of(&server)).into())).unwrap();
    client.set_next_seq(254);
    for t in 0..3 {
        client.send_auto(42, 1, &notice(t)).unwrap();
    }
    let seqs: Vec<u8> = (0..3)
        .map(|_| expect_frame(&mut server).header().seq)
        .collect();
    assert_eq!(seqs, [254, 255, 0]);
    client.set_next_seq(5); // skips 1..=4
    client.send_auto(42, 1, &notice(3)).unwrap();
    expect_frame(&mut server);
    let link = server.links().iter().find(|l| l.sysid == 42).unwrap();
    assert_eq!((link.received, link.lost, link.gaps), (4, 4, 1));
    assert_eq!(server.stats().seq_lost, 4);
}
