//! `fbwag router` with a swarm behind the vehicle: HEARTBEATs of 1,000
//! other senders (250 systems of 4 components) arriving on the vehicle's
//! link do not make the router forget the vehicle, and every command a
//! ground station addresses to it arrives. The vehicle speaks first and
//! the swarm after it, so a table that evicts the least recently seen
//! sender when it holds fewer than 1,001 would forget the vehicle and
//! route none of the commands.

use fbwag_dialect::dialects::common::{CommandLong, MavCmd};
use fbwag_dialect::dialects::minimal::Heartbeat;
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Dialect, Header, Message, Received, Version};
use std::collections::HashSet;
use std::net::UdpSocket;
use std::process::Command;
use std::time::{Duration, Instant};

mod common;

use common::{free_port, Proc};

const VEHICLE: (u8, u8) = (1, 1);
const GCS: (u8, u8) = (255, 190);
const COMMANDS: u16 = 200;

/// The swarm's senders: systems 2–251, components 1–4.
fn swarm() -> impl Iterator<Item = (u8, u8)> {
    (2..=251u8).flat_map(|s| (1..=4u8).map(move |c| (s, c)))
}

/// One MAVLink 2 frame of `msg` from `from`.
fn frame(from: (u8, u8), seq: u8, msg: &dyn Encode) -> Vec<u8> {
    let mut buf = [0u8; 300];
    let header = Header {
        seq,
        sysid: from.0,
        compid: from.1,
    };
    let n = encode(Version::V2, header, msg, None, &mut buf).expect("encode");
    buf[..n].to_vec()
}

/// A socket on 127.0.0.1 that sends to the router's `port`.
fn socket_to(port: u16) -> UdpSocket {
    let s = UdpSocket::bind("127.0.0.1:0").expect("bind");
    s.connect(("127.0.0.1", port)).expect("connect");
    s.set_read_timeout(Some(Duration::from_millis(5)))
        .expect("timeout");
    s
}

/// Hands `seen` every frame of the datagrams `socket` holds now, waiting
/// 5 ms at most for the first.
fn drain(socket: &UdpSocket, mut seen: impl FnMut(&Received<'_, Dialect>)) {
    let mut parser = fbwag_dialect::Parser::new();
    let mut buf = [0u8; 2048];
    while let Ok(n) = socket.recv(&mut buf) {
        let mut input = &buf[..n];
        while let Some(r) = parser.next(&mut input) {
            seen(&r);
        }
    }
}

/// Both ends speak until the ground station hears the vehicle through the
/// router: it is up, and each socket is a peer of its link.
fn connect(vehicle: &UdpSocket, gcs: &UdpSocket) -> bool {
    let deadline = Instant::now() + Duration::from_secs(10);
    let mut heard = false;
    while !heard && Instant::now() < deadline {
        let _ = gcs.send(&frame(GCS, 0, &Heartbeat::default()));
        let _ = vehicle.send(&frame(VEHICLE, 0, &Heartbeat::default()));
        std::thread::sleep(Duration::from_millis(50));
        drain(gcs, |r| {
            let h = r.frame().header();
            heard |= (h.sysid, h.compid) == VEHICLE;
        });
    }
    heard
}

/// Sends the swarm's HEARTBEATs into the vehicle's link, in bursts of
/// 50, again for each sender the ground station has not heard yet, until
/// it has heard all of them: the router learned every sender. Returns how
/// many it heard.
fn flood(vehicle: &UdpSocket, gcs: &UdpSocket) -> usize {
    let mut heard = HashSet::new();
    let deadline = Instant::now() + Duration::from_secs(20);
    while heard.len() < 1_000 && Instant::now() < deadline {
        let missing: Vec<_> = swarm().filter(|s| !heard.contains(s)).collect();
        for burst in missing.chunks(50) {
            for &from in burst {
                let _ = vehicle.send(&frame(from, 0, &Heartbeat::default()));
            }
            drain(gcs, |r| {
                let h = r.frame().header();
                heard.insert((h.sysid, h.compid));
            });
        }
        drain(gcs, |r| {
            let h = r.frame().header();
            heard.insert((h.sysid, h.compid));
        });
    }
    heard.retain(|s| swarm().any(|w| w == *s));
    heard.len()
}

/// The ground station sends `COMMANDS` COMMAND_LONGs to the vehicle
/// (param1 numbers them), one a millisecond; the numbers the vehicle
/// received within 10 s.
fn command(vehicle: &UdpSocket, gcs: &UdpSocket) -> HashSet<u16> {
    let mut got = HashSet::new();
    let take = |got: &mut HashSet<u16>, r: &Received<'_, Dialect>| {
        if let Some(Message::CommandLong(c)) = r.message() {
            let h = r.frame().header();
            if (h.sysid, h.compid) == GCS && (c.target_system, c.target_component) == VEHICLE {
                got.insert(c.param1 as u16);
            }
        }
    };
    for i in 0..COMMANDS {
        let cmd = CommandLong {
            target_system: VEHICLE.0,
            target_component: VEHICLE.1,
            command: MavCmd::REQUEST_MESSAGE,
            param1: f32::from(i),
            ..Default::default()
        };
        let _ = gcs.send(&frame(GCS, i as u8, &cmd));
        std::thread::sleep(Duration::from_millis(1));
        drain(vehicle, |r| take(&mut got, r));
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while got.len() < usize::from(COMMANDS) && Instant::now() < deadline {
        drain(vehicle, |r| take(&mut got, r));
    }
    got
}

#[test]
fn a_swarm_behind_the_vehicle_does_not_make_the_router_forget_it() {
    let (a, b) = (free_port(), free_port());
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("router")
            .arg(format!("udpin:127.0.0.1:{a}"))
            .arg(format!("udpin:127.0.0.1:{b}"))
            .args(["--duration", "60", "--report", "1"]),
    );
    let (vehicle, gcs) = (socket_to(a), socket_to(b));
    let up = connect(&vehicle, &gcs);
    let swarm_heard = if up { flood(&vehicle, &gcs) } else { 0 };
    let got = if up {
        command(&vehicle, &gcs)
    } else {
        HashSet::new()
    };
    let out = router.finish(Duration::ZERO);
    let log = format!(
        "--- router stdout\n{}\n--- stderr\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(up, "the ground station never heard the vehicle\n{log}");
    assert_eq!(swarm_heard, 1_000, "the swarm's senders routed\n{log}");
    assert_eq!(
        got.len(),
        usize::from(COMMANDS),
        "commands that reached the vehicle\n{log}"
    );
}
