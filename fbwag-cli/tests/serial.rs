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
