//! `serial:` works in the `fbwag` the README builds: `fbwag cc` on one end
//! of a pseudo-terminal pair answers a flight controller on the other.
#![cfg(unix)]

use fbwag_delegation::{wire, Peer, Status};
use fbwag_dialect::mavframe::conn::{Serial, Transport};
use fbwag_dialect::{encode, Header, Message, Parser, Version};
use serialport::{SerialPort, TTYPort};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[test]
fn fbwag_cc_answers_over_a_serial_line() {
    let (fc_end, cc_end) = match TTYPort::pair() {
        Ok(pair) => pair,
        Err(e) => {
            eprintln!("skipped: no pseudo-terminal here ({e})");
            return;
        }
    };
    let path = cc_end.name().expect("the pty's path");
    // fbwag cc opens the path itself.
    drop(cc_end);
    let cc = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["cc", "--link", &format!("serial:{path}:57600")])
        .args(["--duration", "8", "--exit-after-handback"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut fc = Serial::from_port(Box::new(fc_end));
    let mut parser = Parser::new();
    let mut seq = 0u8;
    let mut send = |fc: &mut Serial, msg: Message| {
        let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
        let h = Header {
            seq,
            sysid: 1,
            compid: 1,
        };
        seq = seq.wrapping_add(1);
        let n = encode(Version::V2, h, &msg, None, &mut buf).unwrap();
        // Until fbwag cc has opened its end, a write fails (no reader).
        let _ = fc.send(&buf[..n]);
    };
    let start = Instant::now();
    let mut answered = None;
    let mut buf = [0u8; 512];
    let mut next_notice = Instant::now();
    while answered.is_none() && start.elapsed() < Duration::from_secs(6) {
        if Instant::now() >= next_notice {
            next_notice += Duration::from_millis(500);
            let fc_id = Peer::new(1, 1);
            let hb = wire::fc_heartbeat(fbwag_delegation::fc::Authority::Handshake);
            send(&mut fc, Message::Heartbeat(hb));
            send(
                &mut fc,
                Message::FbwagNotice(wire::notice(fc_id, Status::RC_LOST, 4242)),
            );
        }
        let n = fc
            .recv(&mut buf, Some(Duration::from_millis(50)))
            .unwrap_or(0);
        let mut input = &buf[..n];
        while let Some(r) = parser.next(&mut input) {
            if let Some(Message::FbwagNotice(n)) = r.message() {
                let h = r.frame().header();
                answered = Some((h.sysid, h.compid, n.failsafe_status, n.timestamp));
            }
        }
    }
    // Hand back, so the daemon exits.
    send(
        &mut fc,
        Message::FbwagNotice(wire::notice(Peer::new(1, 1), Status::NORMAL, 5000)),
    );
    let out = cc.wait_with_output().unwrap();
    let log = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        answered,
        Some((1, 191, Status::CC_TAKEOVER_CONFIRMED, 4242)),
        "{log}"
    );
    assert!(out.status.success(), "{log}");
}

/// mavlink-router's `FlowControl = true` on a UART endpoint, read from
/// its own file: the router opens the serial line with RTS/CTS on (as
/// `stty` reads the line's settings), and routes what comes in on it.
/// `--flow-control` on a link that is no serial port is refused.
#[test]
fn flow_control_turns_rts_cts_on_for_the_serial_link() {
    let (radio_end, router_end) = match TTYPort::pair() {
        Ok(pair) => pair,
        Err(e) => {
            eprintln!("skipped: no pseudo-terminal here ({e})");
            return;
        }
    };
    let path = router_end.name().expect("the pty's path");
    drop(router_end);
    let sink = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let port = sink.local_addr().unwrap().port();
    let dir = std::env::temp_dir().join(format!("fbwag-flow-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let conf = dir.join("main.conf");
    std::fs::write(
        &conf,
        format!(
            "[UartEndpoint radio]\nDevice = {path}\nBaud = 57600\nFlowControl = true\n\
             [UdpEndpoint gcs]\nMode = Normal\nAddress = 127.0.0.1\nPort = {port}\n"
        ),
    )
    .unwrap();
    let router = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["router", "--duration", "2", "--config"])
        .arg(&conf)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let settings = || {
        let out = Command::new("stty").args(["-F", &path, "-a"]).output();
        out.map(|o| String::from_utf8_lossy(&o.stdout).into_owned())
            .unwrap_or_default()
    };
    let start = Instant::now();
    let mut seen = String::new();
    while start.elapsed() < Duration::from_secs(2) {
        seen = settings();
        if seen.split_whitespace().any(|w| w == "crtscts") {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let mut radio = Serial::from_port(Box::new(radio_end));
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    let h = Header {
        seq: 0,
        sysid: 1,
        compid: 1,
    };
    let hb = Message::Heartbeat(wire::fc_heartbeat(fbwag_delegation::fc::Authority::Pilot));
    let n = encode(Version::V2, h, &hb, None, &mut buf).unwrap();
    radio.send(&buf[..n]).unwrap();
    sink.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
    let mut got = [0u8; 512];
    let routed = sink.recv(&mut got).map(|m| got[..m].to_vec());
    let out = router.wait_with_output().unwrap();
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(
        seen.split_whitespace().any(|w| w == "crtscts"),
        "RTS/CTS off: {seen}\n{log}"
    );
    assert!(log.contains("link 1 radio: serial:"), "{log}");
    assert!(log.contains(", RTS/CTS"), "{log}");
    assert_eq!(routed.ok().as_deref(), Some(&buf[..n]), "{log}");
    assert!(out.status.success(), "{log}");
    let refused = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["router", "udpin:127.0.0.1:1", "udpin:127.0.0.1:2"])
        .args(["--flow-control", "2", "--print-config"])
        .output()
        .unwrap();
    assert_eq!(refused.status.code(), Some(2));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("is no serial port"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
