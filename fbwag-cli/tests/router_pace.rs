//! `fbwag router --routed-rate LINK:RATE`: what is routed to a slow link
//! is paced (at most a second of it held back, the oldest dropped), and
//! only there; a rate for a link not given is refused.

use fbwag_dialect::dialects::minimal::Heartbeat;
use fbwag_dialect::{encode, Header, Version};
use std::net::UdpSocket;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;

use common::free_port;

const FRAMES: usize = 300;
/// A MAVLink 2 HEARTBEAT's frame: 10 + 9 + 2 bytes.
const HEARTBEAT_LEN: usize = 21;

/// Frames that reach a sink behind `fbwag router udpin:A udpout:B`
/// within `within` of a burst of FRAMES heartbeats (21 bytes each) sent
/// to A; `pace`: the router's extra arguments.
fn delivered(pace: &[&str], within: Duration) -> usize {
    // The sink takes a port of its own: a port free_port saw free can be
    // taken by a test running alongside before this one binds it.
    let sink = UdpSocket::bind("127.0.0.1:0").unwrap();
    let (a, b) = (free_port(), sink.local_addr().unwrap().port());
    let mut router = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args([
            "router",
            &format!("udpin:127.0.0.1:{a}"),
            &format!("udpout:127.0.0.1:{b}"),
        ])
        .args(pace)
        .args(["--duration", "20"])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let source = UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut buf = [0u8; 2048];
    // One frame first, until the router is up and routing.
    sink.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let up = (0..100).any(|_| {
        source.send_to(&heartbeat(255), ("127.0.0.1", a)).unwrap();
        sink.recv(&mut buf).is_ok()
    });
    assert!(up, "the router never routed");
    std::thread::sleep(Duration::from_millis(1500)); // the pace's bucket refills
    while sink.recv(&mut buf).is_ok() {}
    // 10,000 frames a second: quick, and no input socket overflows. The
    // sink reads meanwhile (a datagram a frame overflows a socket buffer
    // that nobody reads).
    let start = Instant::now();
    let burst = std::thread::spawn(move || {
        for seq in 0..FRAMES {
            source
                .send_to(&heartbeat(seq as u8), ("127.0.0.1", a))
                .unwrap();
            if seq % 10 == 9 {
                std::thread::sleep(Duration::from_millis(1));
            }
        }
    });
    let mut frames = 0;
    while let Some(left) = within.checked_sub(start.elapsed()) {
        sink.set_read_timeout(Some(left.max(Duration::from_millis(1))))
            .unwrap();
        match sink.recv(&mut buf) {
            Ok(n) => frames += n / HEARTBEAT_LEN,
            Err(_) => break,
        }
    }
    burst.join().unwrap();
    let _ = router.kill();
    let _ = router.wait();
    frames
}

fn heartbeat(seq: u8) -> Vec<u8> {
    let mut buf = [0u8; 280];
    let h = Header {
        seq,
        sysid: 1,
        compid: 1,
    };
    let n = encode(Version::V2, h, &Heartbeat::default(), None, &mut buf).unwrap();
    buf[..n].to_vec()
}

#[test]
fn a_paced_link_gets_its_rate_and_an_unpaced_one_everything() {
    let all = delivered(&[], Duration::from_secs(2));
    assert_eq!(all, FRAMES, "unpaced, every frame arrives");
    // 2,000 B/s: about 95 heartbeats a second after a burst of 280 bytes;
    // a second's worth held back, the rest dropped.
    let paced = delivered(&["--routed-rate", "2:2000"], Duration::from_secs(1));
    assert!((1..=150).contains(&paced), "{paced} in the first second");
    let later = delivered(&["--routed-rate", "2:2000"], Duration::from_secs(4));
    assert!(
        later < FRAMES,
        "{later}: some were dropped, not all held back"
    );
    let only_there = delivered(&["--routed-rate", "1:2000"], Duration::from_secs(2));
    assert_eq!(only_there, FRAMES, "a pace on link 1 leaves link 2 alone");
}

#[test]
fn a_rate_for_a_link_not_given_is_refused() {
    for (rate, says) in [
        ("3:2000", "link 3: there are 2 links"),
        ("2", "expected LINK:RATE"),
        ("2:5", "bytes a second"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(["router", "udpin:127.0.0.1:0", "udpout:127.0.0.1:9"])
            .args(["--routed-rate", rate, "--duration", "1"])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.code() == Some(2) && err.contains(says),
            "{rate}: {err}"
        );
    }
}
