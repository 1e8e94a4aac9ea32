//! `fbwag router` and `fbwag cc` with `--filter-in/--filter-out/--dedup`,
//! driven over UDP on 127.0.0.1: a message id blocked out of a link never
//! reaches it, the source a link's in-filter allows does, one it does not
//! is dropped and counted; a frame sent over two links at once arrives
//! once, and the same frame sent after the window arrives again; the
//! companion's ground links are filtered both ways while its own frames
//! still reach the FC, and a `--trusted-out` link, counted after the
//! `--out` links, is filtered too.

use fbwag_dialect::dialects::common::{Attitude, SysStatus};
use fbwag_dialect::dialects::minimal::Heartbeat;
use fbwag_dialect::dialects::standard::GlobalPositionInt;
use fbwag_dialect::mavframe::Encode;
use serde_json::Value;
use std::net::UdpSocket;
use std::process::Command;
use std::time::{Duration, Instant};

mod common;

use common::datagrams::{self, count, receive, receive_until};
use common::{free_port, Proc};

/// `msg` framed, unsigned.
fn frame(sysid: u8, seq: u8, msg: &(impl Encode + ?Sized)) -> Vec<u8> {
    datagrams::frame(sysid, seq, msg, None)
}

#[test]
fn filters_and_dedup_shape_what_the_router_forwards() {
    let ports = [free_port(), free_port(), free_port()];
    let dir = std::env::temp_dir().join(format!("fbwag-filters-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let events = dir.join("router.jsonl");
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("router")
            .args(ports.map(|p| format!("udpin:127.0.0.1:{p}")))
            .args(["--filter-in", "1:allow-sys=1"])
            .args(["--filter-out", "3:block-msg=ATTITUDE"])
            .args(["--dedup", "300", "--duration", "4"])
            .arg("--events")
            .arg(&events),
    );
    let socket = || UdpSocket::bind("127.0.0.1:0").unwrap();
    let [one, two, ground] = [socket(), socket(), socket()];
    for (s, port) in [&one, &two, &ground].into_iter().zip(ports) {
        s.connect(("127.0.0.1", port)).unwrap();
    }
    // The ground end speaks first: link 3 answers it from then on.
    let start = Instant::now();
    let mut heard = false;
    let mut probes = Vec::new();
    // Each try's frames differ (sequence numbers), so none is a copy.
    for seq in 100..130 {
        if heard || start.elapsed() > Duration::from_secs(3) {
            break;
        }
        // Refused (ICMP) until the router has bound its ports.
        let _ = ground.send(&frame(250, seq, &Heartbeat::default()));
        let probe = frame(1, seq, &Heartbeat::default());
        let _ = one.send(&probe);
        probes.push(probe);
        // A probe heard late (a loaded machine) counts as well.
        let got = receive(&ground, Duration::from_millis(100));
        heard = probes.iter().any(|p| count(&got, p) > 0);
    }
    assert!(heard, "the router never answered link 3");
    let attitude = frame(1, 1, &Attitude::default());
    let allowed = frame(1, 2, &GlobalPositionInt::default());
    let stranger = frame(7, 3, &GlobalPositionInt::default());
    let twice = frame(1, 4, &SysStatus::default());
    one.send(&attitude).unwrap();
    one.send(&allowed).unwrap();
    one.send(&stranger).unwrap();
    // The same frame over two links at once, as redundant radios deliver.
    one.send(&twice).unwrap();
    two.send(&twice).unwrap();
    // The router took them before they came out (late on a loaded
    // machine): 500 ms after that, past the 300 ms window, the same bytes
    // go on again.
    let mut early = receive_until(&ground, Duration::ZERO, Duration::from_secs(3), |d| {
        count(d, &allowed) > 0 && count(d, &twice) > 0
    });
    early.extend(receive(&ground, Duration::from_millis(500)));
    two.send(&twice).unwrap();
    let late = receive_until(
        &ground,
        Duration::from_millis(300),
        Duration::from_secs(3),
        |d| count(d, &twice) > 0,
    );
    let out = router.finish(Duration::from_secs(6));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    assert_eq!(count(&early, &attitude), 0, "blocked out of link 3\n{log}");
    assert_eq!(count(&early, &allowed), 1, "an allowed source\n{log}");
    assert_eq!(count(&early, &stranger), 0, "refused in on link 1\n{log}");
    assert_eq!(count(&early, &twice), 1, "sent twice at once\n{log}");
    assert_eq!(
        count(&late, &twice),
        1,
        "sent again after the window\n{log}"
    );
    assert!(log.contains("filter out to udpin:127.0.0.1"), "{log}");
    let summary: Value = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .find(|e| e["event"] == "summary")
        .expect("a summary");
    assert_eq!(summary["dropped"]["filtered"], 1, "{summary}");
    assert_eq!(summary["dropped"]["duplicate"], 1, "{summary}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_filter_text_is_refused_with_exit_status_2() {
    let port = free_port();
    let link = format!("udpin:127.0.0.1:{port}");
    for (args, says) in [
        (["--filter-in", "block-msg=0"], "expected LINK:RULE"),
        (["--filter-in", "0:block-msg=0"], "expected LINK:RULE"),
        (["--filter-out", "3:block-msg=0"], "there are 2 links"),
        (["--filter-out", "1:block-msg=NOPE"], "message name"),
        (
            ["--filter-out", "1:block-sys=256"],
            "'1:block-sys=256' for '--filter-out <LINK:RULE>': an id is at most 255",
        ),
        (
            ["--filter-in", "1:allow-msg=99999999999"],
            "'1:allow-msg=99999999999' for '--filter-in <LINK:RULE>': an id is at most 16777215",
        ),
        (["--filter-out", "1:drop-sys=1"], "a rule is allow-msg"),
        (["--dedup", "-5"], "milliseconds from 0 to 60000"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(["router", &link, &link])
            .args(args)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}

/// Connects `fc` to the companion (its heartbeat says where it is), then a
/// station of system `sysid` to the companion's listening `port`: the
/// station, once the FC's heartbeat reached it (within 3 s).
fn station_heard(fc: &UdpSocket, port: u16, sysid: u8) -> Option<UdpSocket> {
    fc.set_read_timeout(Some(Duration::from_secs(3))).unwrap();
    let mut buf = [0u8; 2048];
    let (_, companion) = fc.recv_from(&mut buf).expect("the companion's heartbeat");
    fc.connect(companion).unwrap();
    let station = UdpSocket::bind("127.0.0.1:0").unwrap();
    station.connect(("127.0.0.1", port)).unwrap();
    let start = Instant::now();
    let mut sent = Vec::new();
    for seq in 0..30 {
        if start.elapsed() > Duration::from_secs(3) {
            break;
        }
        let _ = station.send(&frame(sysid, seq, &Heartbeat::default()));
        let fc_heartbeat = frame(1, seq, &Heartbeat::default());
        fc.send(&fc_heartbeat).unwrap();
        sent.push(fc_heartbeat);
        // One heard late (a loaded machine) counts as well.
        let got = receive(&station, Duration::from_millis(100));
        if sent.iter().any(|hb| count(&got, hb) > 0) {
            return Some(station);
        }
    }
    None
}

#[test]
fn the_companions_out_links_are_filtered_and_its_fc_link_is_not() {
    use fbwag_dialect::dialects::common::{CommandLong, ParamRequestList};
    let fc = UdpSocket::bind("127.0.0.1:0").unwrap();
    let ground_port = free_port();
    let dir = std::env::temp_dir().join(format!("fbwag-cc-filters-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let events = dir.join("cc.jsonl");
    let cc = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("cc")
            .arg("--link")
            .arg(format!("udpout:{}", fc.local_addr().unwrap()))
            .arg("--out")
            .arg(format!("udpin:127.0.0.1:{ground_port}"))
            .args(["--filter-in", "1:block-msg=COMMAND_LONG"])
            .args(["--filter-out", "1:block-msg=ATTITUDE"])
            .args(["--duration", "4"])
            .arg("--events")
            .arg(&events),
    );
    let ground = station_heard(&fc, ground_port, 255)
        .expect("the FC's heartbeat never reached the ground link");
    let attitude = frame(1, 50, &Attitude::default());
    let position = frame(1, 51, &GlobalPositionInt::default());
    fc.send(&attitude).unwrap();
    fc.send(&position).unwrap();
    // At least 300 ms, longer if the position is late (a loaded machine).
    let at_ground = receive_until(
        &ground,
        Duration::from_millis(300),
        Duration::from_secs(3),
        |d| count(d, &position) > 0,
    );
    let to_fc = CommandLong {
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let command = frame(255, 60, &to_fc);
    let request = frame(
        255,
        61,
        &ParamRequestList {
            target_system: 1,
            target_component: 1,
        },
    );
    ground.send(&command).unwrap();
    ground.send(&request).unwrap();
    // The companion's own heartbeat (1/191) still reaches the FC link.
    let own = |at_fc: &[Vec<u8>]| {
        at_fc
            .iter()
            .filter(|d| d.len() > 8 && d[0] == 0xfd && d[5] == 1 && d[6] == 191)
            .count()
    };
    let at_fc = receive_until(
        &fc,
        Duration::from_millis(1200),
        Duration::from_secs(3),
        |d| count(d, &request) > 0 && own(d) > 0,
    );
    let out = cc.finish(Duration::from_secs(6));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    assert_eq!(count(&at_ground, &attitude), 0, "blocked out\n{log}");
    assert_eq!(count(&at_ground, &position), 1, "{log}");
    assert_eq!(count(&at_fc, &command), 0, "blocked in\n{log}");
    assert_eq!(count(&at_fc, &request), 1, "{log}");
    assert!(own(&at_fc) >= 1, "{log}");
    let summary: Value = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .find(|e| e["event"] == "summary")
        .expect("a summary");
    assert_eq!(summary["dropped"]["filtered"], 1, "{summary}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The message ids of the MAVLink 2 frames in `datagrams` (signed or not).
fn message_ids(datagrams: &[Vec<u8>]) -> Vec<u32> {
    let mut ids = Vec::new();
    for d in datagrams {
        let mut at = 0;
        while d.len() >= at + 12 && d[at] == 0xfd {
            ids.push(u32::from_le_bytes([d[at + 7], d[at + 8], d[at + 9], 0]));
            let signature = if d[at + 2] & 1 == 1 { 13 } else { 0 };
            at += 12 + usize::from(d[at + 1]) + signature;
        }
    }
    ids
}

#[test]
fn a_trusted_out_link_is_filtered_counted_after_the_out_links() {
    use fbwag_dialect::dialects::common::{CommandLong, ParamRequestList};
    let key = "00".repeat(32);
    let fc = UdpSocket::bind("127.0.0.1:0").unwrap();
    let (ground_port, tool_port) = (free_port(), free_port());
    let cc = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("cc")
            .arg("--link")
            .arg(format!("udpout:{}", fc.local_addr().unwrap()))
            .args(["--sign-key", &key])
            .arg("--out")
            .arg(format!("udpin:127.0.0.1:{ground_port}"))
            .arg("--trusted-out")
            .arg(format!("udpin:127.0.0.1:{tool_port}"))
            .args(["--filter-in", "2:block-msg=COMMAND_LONG"])
            .args(["--duration", "4"]),
    );
    // An unsigned tool (MAVSDK, say) on the trusted link.
    let tool = station_heard(&fc, tool_port, 245)
        .expect("the FC's heartbeat never reached the trusted link");
    let command = CommandLong {
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let request = ParamRequestList {
        target_system: 1,
        target_component: 1,
    };
    tool.send(&frame(245, 60, &command)).unwrap();
    tool.send(&frame(245, 61, &request)).unwrap();
    let at_fc = receive_until(
        &fc,
        Duration::from_millis(1200),
        Duration::from_secs(3),
        |d| message_ids(d).contains(&ParamRequestList::ID),
    );
    let at_fc = message_ids(&at_fc);
    let out = cc.finish(Duration::from_secs(6));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    // Both would go on, signed on the way; the filter keeps the command.
    assert!(at_fc.contains(&ParamRequestList::ID), "{at_fc:?}\n{log}");
    assert!(!at_fc.contains(&CommandLong::ID), "{at_fc:?}\n{log}");
}
