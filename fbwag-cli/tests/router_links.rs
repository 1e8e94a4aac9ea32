//! `fbwag router` with options given per link, driven over UDP on
//! 127.0.0.1: `--peer 2:IP:PORT` pins what link 2 answers (a stranger who
//! spoke first on it gets nothing) while link 1 still answers whoever
//! spoke; `--sign-key KEY --sign-key 2:KEY2 --require-signed` verifies
//! link 2 with its own key, so a frame signed with the other links' key
//! or not signed is refused there and one signed with KEY2 goes on;
//! `--sniffer 3` sends link 3 a command addressed to a system on link 1,
//! and to its pinned reader only.

use fbwag_dialect::dialects::common::{CommandLong, MavCmd};
use fbwag_dialect::dialects::minimal::Heartbeat;
use fbwag_dialect::dialects::standard::GlobalPositionInt;
use fbwag_dialect::mavframe::signing::timestamp_now;
use fbwag_dialect::Signer;
use serde_json::Value;
use std::net::UdpSocket;
use std::process::Command;
use std::time::{Duration, Instant};

mod common;

use common::datagrams::{count, frame, receive, receive_until};
use common::{free_port, Proc};

const KEY: &str = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";
const KEY2: &str = "f0f1f2f3f4f5f6f7f8f9fafbfcfdfeff000102030405060708090a0b0c0d0e0f";

fn key_bytes(hex: &str) -> [u8; 32] {
    let mut k = [0u8; 32];
    for (i, b) in k.iter_mut().enumerate() {
        *b = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).unwrap();
    }
    k
}

fn connected(port: u16) -> UdpSocket {
    let s = UdpSocket::bind("127.0.0.1:0").unwrap();
    s.connect(("127.0.0.1", port)).unwrap();
    s
}

/// Sends `make(n)` from `from` until `to` hears one of them (the router is
/// up and answers `to` on its link), for 3 s at most.
fn until_heard(from: &UdpSocket, to: &UdpSocket, mut make: impl FnMut(u8) -> Vec<u8>) -> bool {
    let start = Instant::now();
    let mut probes = Vec::new();
    for n in 0u8.. {
        if start.elapsed() > Duration::from_secs(3) {
            return false;
        }
        let probe = make(n);
        // Refused (ICMP) until the router has bound its ports.
        let _ = from.send(&probe);
        probes.push(probe);
        // A probe heard late (a loaded machine) counts as well.
        let got = receive(to, Duration::from_millis(100));
        if probes.iter().any(|p| count(&got, p) > 0) {
            return true;
        }
    }
    false
}

#[test]
fn a_peer_pinned_on_one_link_leaves_the_others_answering_who_spoke() {
    let ports = [free_port(), free_port()];
    let pinned = UdpSocket::bind("127.0.0.1:0").unwrap();
    pinned.connect(("127.0.0.1", ports[1])).unwrap();
    let pin = pinned.local_addr().unwrap();
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("router")
            .args(ports.map(|p| format!("udpin:127.0.0.1:{p}")))
            .arg("--peer")
            .arg(format!("2:{pin}"))
            .args(["--duration", "4"]),
    );
    let (fc, stranger) = (connected(ports[0]), connected(ports[1]));
    // The stranger speaks first on link 2; link 1 answers the FC, who
    // spoke there: the pinned peer hears what the FC sends.
    let _ = stranger.send(&frame(250, 0, &Heartbeat::default(), None));
    let _ = fc.send(&frame(1, 0, &Heartbeat::default(), None));
    let heard = until_heard(&fc, &pinned, |n| {
        let _ = stranger.send(&frame(250, n, &Heartbeat::default(), None));
        frame(1, n, &Heartbeat::default(), None)
    });
    assert!(heard, "the pinned peer never heard link 1");
    let answered = until_heard(&pinned, &fc, |n| frame(255, n, &Heartbeat::default(), None));
    assert!(answered, "link 1 (no pin) never answered the FC");
    let telemetry = frame(1, 200, &GlobalPositionInt::default(), None);
    fc.send(&telemetry).unwrap();
    // At least 300 ms, longer if the telemetry is late (a loaded machine).
    let to_pinned = receive_until(
        &pinned,
        Duration::from_millis(300),
        Duration::from_secs(3),
        |d| count(d, &telemetry) > 0,
    );
    let to_stranger = receive(&stranger, Duration::from_millis(100));
    let out = router.finish(Duration::from_secs(6));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    assert_eq!(count(&to_pinned, &telemetry), 1, "{log}");
    assert!(
        to_stranger.is_empty(),
        "the stranger on link 2 got frames\n{log}"
    );
}

#[test]
fn a_link_with_its_own_key_verifies_with_it_alone() {
    let ports = [free_port(), free_port()];
    let dir = std::env::temp_dir().join(format!("fbwag-router-links-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let events = dir.join("router.jsonl");
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("router")
            .args(ports.map(|p| format!("udpin:127.0.0.1:{p}")))
            .args(["--sign-key", KEY, "--sign-key", &format!("2:{KEY2}")])
            .args(["--require-signed", "--duration", "4"])
            .arg("--events")
            .arg(&events),
    );
    let (fc, ground) = (connected(ports[0]), connected(ports[1]));
    let now = timestamp_now();
    let mut fc_signer = Signer::new(key_bytes(KEY), 1, now);
    let mut ground_signer = Signer::new(key_bytes(KEY2), 2, now);
    // Each end is answered once a frame of its own verified on its link.
    let _ = ground.send(&frame(
        255,
        0,
        &Heartbeat::default(),
        Some(&mut ground_signer),
    ));
    let _ = fc.send(&frame(1, 0, &Heartbeat::default(), Some(&mut fc_signer)));
    let heard = until_heard(&fc, &ground, |n| {
        let beat = frame(255, n, &Heartbeat::default(), Some(&mut ground_signer));
        let _ = ground.send(&beat);
        frame(1, n, &Heartbeat::default(), Some(&mut fc_signer))
    });
    assert!(heard, "link 1's signed frames never reached link 2");
    // Into link 2, signed with link 1's key: refused by the link's
    // parser; unsigned: dropped by the node (--require-signed); signed
    // with KEY2: routed.
    let mut wrong = Signer::new(key_bytes(KEY), 3, timestamp_now());
    let refused = frame(255, 100, &GlobalPositionInt::default(), Some(&mut wrong));
    let unsigned = frame(255, 101, &GlobalPositionInt::default(), None);
    let routed = frame(
        255,
        102,
        &GlobalPositionInt::default(),
        Some(&mut ground_signer),
    );
    for f in [&refused, &unsigned, &routed] {
        ground.send(f).unwrap();
    }
    let to_fc = receive_until(
        &fc,
        Duration::from_millis(300),
        Duration::from_secs(3),
        |d| count(d, &routed) > 0,
    );
    let out = router.finish(Duration::from_secs(6));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    assert_eq!(count(&to_fc, &refused), 0, "{log}");
    assert_eq!(count(&to_fc, &unsigned), 0, "{log}");
    assert_eq!(count(&to_fc, &routed), 1, "{log}");
    let summary: Value = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .find(|e| e["event"] == "summary")
        .expect("a summary event");
    let unauthenticated = summary["dropped"]["unauthenticated"].as_u64().unwrap_or(0);
    assert!(unauthenticated >= 1, "{summary}\n{log}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_sniffer_link_gets_frames_addressed_to_others() {
    let ports = [free_port(), free_port(), free_port()];
    let [fc, ground, tool, stranger] = [ports[0], ports[1], ports[2], ports[2]].map(connected);
    // The sniffer's reader pinned, as docs/deployment.md advises: a
    // stranger who speaks to the same port first reads nothing.
    let _ = stranger.send(&frame(250, 0, &Heartbeat::default(), None));
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("router")
            .args(ports.map(|p| format!("udpin:127.0.0.1:{p}")))
            .args(["--sniffer", "3", "--duration", "4"])
            .arg("--peer")
            .arg(format!("3:{}", tool.local_addr().unwrap())),
    );
    // Each speaks on its link, so each link answers it; the FC's
    // heartbeats reach the ground station once all are up.
    let heard = until_heard(&fc, &ground, |n| {
        let _ = stranger.send(&frame(250, n, &Heartbeat::default(), None));
        let _ = tool.send(&frame(254, n, &Heartbeat::default(), None));
        let _ = ground.send(&frame(255, n, &Heartbeat::default(), None));
        frame(1, n, &Heartbeat::default(), None)
    });
    assert!(heard, "link 1 never reached link 2");
    // Addressed to system 1, seen on link 1 only: without --sniffer it
    // would go there alone.
    let command = frame(
        255,
        200,
        &CommandLong {
            target_system: 1,
            command: MavCmd::COMPONENT_ARM_DISARM,
            ..CommandLong::default()
        },
        None,
    );
    ground.send(&command).unwrap();
    let to_fc = receive_until(
        &fc,
        Duration::from_millis(300),
        Duration::from_secs(3),
        |d| count(d, &command) > 0,
    );
    let to_tool = receive_until(
        &tool,
        Duration::from_millis(100),
        Duration::from_secs(3),
        |d| count(d, &command) > 0,
    );
    let to_stranger = receive(&stranger, Duration::from_millis(100));
    let out = router.finish(Duration::from_secs(6));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    assert_eq!(count(&to_fc, &command), 1, "{log}");
    assert_eq!(count(&to_tool, &command), 1, "the sniffer missed it\n{log}");
    assert!(to_stranger.is_empty(), "a stranger read the sniffer\n{log}");
    assert!(log.contains("gets every frame routed"), "{log}");
}

/// A TCP link whose server is not up when the router starts (MAVProxy
/// started later), and a serial port that is not there (a USB radio still
/// enumerating), leave the router running: the other links route, and the
/// TCP link opens once its server listens.
#[test]
fn links_not_there_at_start_are_opened_when_they_come() {
    use std::io::Read;
    let (udp, tcp) = (free_port(), free_port());
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("router")
            .arg(format!("udpin:127.0.0.1:{udp}"))
            .arg(format!("tcp:127.0.0.1:{tcp}"))
            .arg("serial:/dev/fbwag-no-such-port:57600")
            .args(["--duration", "5"]),
    );
    std::thread::sleep(Duration::from_millis(1500));
    let server = std::net::TcpListener::bind(("127.0.0.1", tcp)).unwrap();
    server.set_nonblocking(true).unwrap();
    let fc = connected(udp);
    let heartbeat = frame(1, 0, &Heartbeat::default(), None);
    let start = Instant::now();
    let mut stream = loop {
        let _ = fc.send(&heartbeat);
        if let Ok((stream, _)) = server.accept() {
            break Some(stream);
        }
        if start.elapsed() > Duration::from_secs(3) {
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    .expect("the TCP link never connected");
    stream.set_nonblocking(false).unwrap();
    stream
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 512];
    while start.elapsed() < Duration::from_secs(3)
        && !got.windows(heartbeat.len()).any(|w| w == heartbeat)
    {
        let _ = fc.send(&heartbeat);
        if let Ok(n) = stream.read(&mut buf) {
            got.extend_from_slice(&buf[..n]);
        }
    }
    let out = router.finish(Duration::from_secs(6));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    assert!(
        got.windows(heartbeat.len()).any(|w| w == heartbeat),
        "nothing routed to the TCP link\n{log}"
    );
    assert!(
        log.contains("fbwag-no-such-port"),
        "the absent port is named\n{log}"
    );
    assert!(log.contains("open again"), "{log}");
}

/// Stopped by SIGTERM (`systemctl stop`), the router ends as at the end of
/// its run: its last report, summary and saves, exit status 0. Its
/// periodic report says what each link's parser refused (here frames with
/// bad checksums), as the companion's does: a flood of garbage is seen.
#[test]
fn sigterm_ends_the_router_as_its_run_and_reports_name_refused_frames() {
    let (a, b) = (free_port(), free_port());
    let events = std::env::temp_dir().join(format!("fbwag-sigterm-{}.jsonl", std::process::id()));
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("router")
            .arg(format!("udpin:127.0.0.1:{a}"))
            .arg(format!("udpout:127.0.0.1:{b}"))
            .args(["--report", "1", "--events"])
            .arg(&events),
    );
    assert!(common::udp_port_bound(a), "the router never listened");
    // A HEARTBEAT whose checksum is wrong.
    let mut bad = vec![0xfd, 9, 0, 0, 0, 1, 1, 0, 0, 0];
    bad.extend([0; 9]);
    bad.extend([0x12, 0x34]);
    let sender = connected(a);
    for _ in 0..50 {
        sender.send(&bad).unwrap();
    }
    // The first report (after a second) names them.
    std::thread::sleep(Duration::from_millis(1600));
    let killed = Command::new("kill")
        .args(["-TERM", &router.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let out = router.finish(Duration::from_secs(10));
    let log =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}\n{log}", out.status);
    assert!(
        log.contains(&format!("udpin:127.0.0.1:{a}: link refused in the last")),
        "{log}"
    );
    assert!(log.contains("50 bad checksums"), "{log}");
    assert!(log.contains("SIGTERM: stopping"), "{log}");
    assert!(log.contains("done: 0 frames in"), "{log}");
    let summary = std::fs::read_to_string(&events).unwrap_or_default();
    let _ = std::fs::remove_file(&events);
    assert!(
        summary.lines().any(|l| l.contains("\"summary\"")),
        "{summary}"
    );
}

/// Events the output refuses (`/dev/full`: a full disk) are said on
/// standard error, and the program exits with status 2, as for any
/// output not written; routing went on meanwhile.
#[test]
fn events_that_cannot_be_written_are_said_and_fail_the_run() {
    let (a, b) = (free_port(), free_port());
    let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .arg("router")
        .arg(format!("udpin:127.0.0.1:{a}"))
        .arg(format!("udpout:127.0.0.1:{b}"))
        .args(["--duration", "0.5", "--events", "/dev/full"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("--events /dev/full: ") && err.contains(" at the end not written"),
        "{err}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("done:"));

    // A FIFO no reader ever opens: the same.
    let fifo = std::env::temp_dir().join(format!("fbwag-events-fifo-{}", std::process::id()));
    let _ = std::fs::remove_file(&fifo);
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .arg("router")
        .arg(format!("udpin:127.0.0.1:{a}"))
        .arg(format!("udpout:127.0.0.1:{b}"))
        .args(["--duration", "0.5", "--events"])
        .arg(&fifo)
        .output()
        .unwrap();
    let _ = std::fs::remove_file(&fifo);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("not written: no reader opened it"), "{err}");
}

/// mavlink-router's `SnifferSysid`, read from its own file: the link
/// system 254 speaks on gets a command addressed to system 1, which the
/// link of system 250 does not; the log says which link sniffs.
#[test]
fn the_links_a_sniffer_sysid_speaks_on_get_every_frame() {
    let ports = [free_port(), free_port(), free_port(), free_port()];
    let [fc, ground, tool, other] = ports.map(connected);
    let dir = std::env::temp_dir().join(format!("fbwag-sniffer-sysid-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let conf = dir.join("main.conf");
    let section = |name: &str, port: u16| {
        format!("[UdpEndpoint {name}]\nMode = Server\nAddress = 127.0.0.1\nPort = {port}\n")
    };
    std::fs::write(
        &conf,
        format!(
            "[General]\nSnifferSysid = 254\n{}{}{}{}",
            section("fc", ports[0]),
            section("ground", ports[1]),
            section("tool", ports[2]),
            section("other", ports[3])
        ),
    )
    .unwrap();
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(["router", "--duration", "3", "--config"])
            .arg(&conf),
    );
    let heard = until_heard(&fc, &ground, |n| {
        let _ = tool.send(&frame(254, n, &Heartbeat::default(), None));
        let _ = other.send(&frame(250, n, &Heartbeat::default(), None));
        let _ = ground.send(&frame(255, n, &Heartbeat::default(), None));
        frame(1, n, &Heartbeat::default(), None)
    });
    assert!(heard, "link fc never reached link ground");
    let command = frame(
        255,
        200,
        &CommandLong {
            target_system: 1,
            command: MavCmd::COMPONENT_ARM_DISARM,
            ..CommandLong::default()
        },
        None,
    );
    // Addressed to system 1: to the FC, the sniffer, and no one else.
    ground.send(&command).unwrap();
    let to_tool = receive_until(
        &tool,
        Duration::from_millis(200),
        Duration::from_secs(3),
        |d| count(d, &command) > 0,
    );
    let to_fc = receive(&fc, Duration::from_millis(100));
    let to_other = receive(&other, Duration::from_millis(100));
    let out = router.finish(Duration::from_secs(6));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    assert_eq!(count(&to_fc, &command), 1, "{log}");
    assert_eq!(count(&to_tool, &command), 1, "the sniffer missed it\n{log}");
    assert_eq!(count(&to_other, &command), 0, "{log}");
    assert!(
        log.contains("link tool: system 254 heard: gets every frame routed"),
        "{log}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
