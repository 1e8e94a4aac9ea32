//! What the simulator proves is what the live program runs: one scripted
//! peer (a signed companion that acknowledges, streams every kind of control
//! and once a misaddressed one, plus an attacker streaming unsigned control
//! as the companion and as a ground station) is played against the FC
//! engine on a virtual clock, as the simulator drives it, and against the
//! real `fbwag fc-sim` over UDP. Both must change modes in the same order
//! and apply the same kinds of control from the same senders, and neither
//! may apply the attacker's.

use fbwag_delegation::control::Control;
use fbwag_delegation::engine::{FcEngine, FcOutput};
use fbwag_delegation::fc::{Authority, FcConfig};
use fbwag_delegation::{wire, Moment, Peer, Status};
use fbwag_dialect::dialects::common::{ManualControl, SetAttitudeTarget};
use fbwag_dialect::mavframe::signing::timestamp_now;
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{
    encode, Frame, Header, Message, MessageView, Parser, Signer, Unsigned, Verifier, Version,
};
use std::collections::BTreeSet;
use std::net::UdpSocket;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant as WallInstant};

const FC: Peer = Peer::new(1, 1);
const CC: Peer = Peer::new(1, 191);
const GCS: Peer = Peer::new(255, 190);
const KEY: [u8; 32] = [0x5a; 32];
const KEY_HEX: &str = "5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a5a";
/// Receiver lost at 1 s, back at 3 s; the run ends at 4 s.
const RC_LOSS_MS: u64 = 1000;
const RC_BACK_MS: u64 = 3000;
const END_MS: u64 = 4000;

/// Who sends a frame of the script: the companion, or the attacker (from
/// its own socket in the live run).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Who {
    Companion,
    Attacker,
}

struct Sender {
    id: Peer,
    seq: u8,
    signer: Option<Signer>,
}

impl Sender {
    fn frame(&mut self, msg: &dyn Encode) -> Vec<u8> {
        let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
        let h = Header {
            seq: self.seq,
            sysid: self.id.sysid,
            compid: self.id.compid,
        };
        self.seq = self.seq.wrapping_add(1);
        if let Some(s) = &mut self.signer {
            s.advance_to(timestamp_now());
        }
        let n = encode(Version::V2, h, msg, self.signer.as_mut(), &mut buf).unwrap();
        buf[..n].to_vec()
    }
}

/// The scripted peer: reacts to the FC's notices, sends on a schedule.
struct Script {
    cc: Sender,
    forged_cc: Sender,
    forged_gcs: Sender,
    controlling: bool,
    next_heartbeat: u64,
    next_control: u64,
    next_attack: u64,
    sent: u64,
}

impl Script {
    fn new() -> Self {
        let sender = |id, key: Option<[u8; 32]>| Sender {
            id,
            seq: 0,
            signer: key.map(|k| Signer::new(k, 0, timestamp_now())),
        };
        Script {
            cc: sender(CC, Some(KEY)),
            forged_cc: sender(CC, None),
            forged_gcs: sender(GCS, None),
            controlling: false,
            next_heartbeat: 0,
            next_control: 0,
            next_attack: 500,
            sent: 0,
        }
    }

    /// The control of the `k`-th message: each kind in turn, every tenth
    /// addressed to another system.
    fn control(k: u64) -> Message {
        let fc = if k % 10 == 9 { Peer::new(2, 1) } else { FC };
        match k % 3 {
            0 => Control::rc(fc, [1600, 1500, 1650, 1500, 0, 0, 0, 0]),
            1 => Control::Attitude(SetAttitudeTarget {
                q: [1.0, 0.0, 0.0, 0.0],
                thrust: 0.5,
                ..Default::default()
            })
            .addressed_to(fc),
            _ => Control::Manual(ManualControl {
                y: 200,
                z: 600,
                ..Default::default()
            })
            .addressed_to(fc),
        }
        .to_message()
    }

    /// What the FC said: notices are answered, echoing their event.
    fn on_fc(&mut self, frame: &Frame<&[u8]>) -> Vec<(Who, Vec<u8>)> {
        let Some(MessageView::FbwagNotice(n)) = MessageView::new(frame.msg_id(), frame.payload())
        else {
            return Vec::new();
        };
        let (status, event) = (n.failsafe_status(), n.timestamp());
        let answer = match status {
            Status::RC_LOST => {
                self.controlling = true;
                Status::CC_TAKEOVER_CONFIRMED
            }
            Status::NORMAL => {
                self.controlling = false;
                Status::NORMAL
            }
            _ => return Vec::new(),
        };
        let ack = Message::FbwagNotice(wire::notice(FC, answer, event));
        vec![(Who::Companion, self.cc.frame(&ack))]
    }

    /// What is due at `t` ms.
    fn due(&mut self, t: u64) -> Vec<(Who, Vec<u8>)> {
        let mut out = Vec::new();
        if t >= self.next_heartbeat {
            self.next_heartbeat += 1000;
            let hb = Message::Heartbeat(wire::cc_heartbeat());
            out.push((Who::Companion, self.cc.frame(&hb)));
        }
        if self.controlling && t >= self.next_control {
            self.next_control = t + 50;
            self.sent += 1;
            out.push((Who::Companion, self.cc.frame(&Self::control(self.sent))));
        }
        if (500..END_MS - 300).contains(&t) && t >= self.next_attack {
            self.next_attack = t + 20;
            // Hard over, unsigned, in turn as the companion and as a GCS.
            let k = t / 20;
            let forged = Self::control(k);
            let sender = if k % 2 == 0 {
                &mut self.forged_cc
            } else {
                &mut self.forged_gcs
            };
            out.push((Who::Attacker, sender.frame(&forged)));
        }
        out
    }
}

/// What an FC did: its mode changes and the kinds of control it applied.
#[derive(Debug, PartialEq, Eq)]
struct Behaviour {
    modes: Vec<String>,
    applied: BTreeSet<(u8, u8, bool, String)>,
}

fn mode_name(a: Authority) -> String {
    match wire::custom_mode(a) {
        fbwag_delegation::mode::FBWA => "FBWA",
        fbwag_delegation::mode::CIRCLE => "CIRCLE",
        fbwag_delegation::mode::FBWAG => "FBWAG",
        fbwag_delegation::mode::RTL => "RTL",
        _ => "?",
    }
    .to_string()
}

/// The script against the FC engine on a virtual clock (1 ms steps), with
/// frames parsed as a signing link parses them: the simulator's way.
fn virtual_run() -> Behaviour {
    let cfg = FcConfig {
        require_signed: true,
        ..FcConfig::default()
    };
    let mut fc = FcEngine::new(cfg, Moment::ZERO).unwrap();
    let mut parser = Parser::with_signing(
        Verifier::with_timestamp(KEY, timestamp_now()),
        Unsigned::Accept,
    );
    let mut fc_out = Sender {
        id: FC,
        seq: 0,
        signer: Some(Signer::new(KEY, 0, timestamp_now())),
    };
    let mut script = Script::new();
    let mut behaviour = Behaviour {
        modes: Vec::new(),
        applied: BTreeSet::new(),
    };
    for t in 0..END_MS {
        let now = Moment::from_millis(t);
        fc.set_receiver_ok(!(RC_LOSS_MS..RC_BACK_MS).contains(&t));
        if fc.poll_timeout().is_some_and(|d| d <= now) {
            fc.handle_timeout(now);
        }
        let mut incoming = script.due(t);
        while let Some(out) = fc.poll_output() {
            match out {
                FcOutput::Transmit(msg) => {
                    let bytes = fc_out.frame(&msg);
                    let frame = Frame::new_checked(&bytes[..]).unwrap();
                    incoming.extend(script.on_fc(&frame));
                }
                FcOutput::SetMode(a) => behaviour.modes.push(mode_name(a)),
                FcOutput::ApplyControl { from, control } => {
                    behaviour.applied.insert((
                        from.peer.sysid,
                        from.peer.compid,
                        from.authenticated,
                        control.name().to_string(),
                    ));
                }
                FcOutput::ReleaseControl => {}
                other => panic!("an output this test does not know: {other:?}"),
            }
        }
        for (_, bytes) in incoming {
            let mut input = &bytes[..];
            while let Some(r) = parser.next(&mut input) {
                let _ = fc.handle_frame(now, &r.frame(), r.is_authenticated());
            }
        }
    }
    behaviour
}

struct Kill(Child);

impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// The script against `fbwag fc-sim` over UDP in real time; its behaviour
/// read from its `--events`.
fn live_run() -> Behaviour {
    let companion = UdpSocket::bind("127.0.0.1:0").unwrap();
    let attacker = UdpSocket::bind("127.0.0.1:0").unwrap();
    companion.set_nonblocking(true).unwrap();
    let port = UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dir = std::env::temp_dir().join(format!("fbwag-parity-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let events = dir.join("fc.jsonl");
    let child = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["fc-sim", "--link", &format!("udpin:127.0.0.1:{port}")])
        .args(["--sign-key", KEY_HEX, "--require-signed"])
        .args(["--rc-loss-at", &format!("{}", RC_LOSS_MS as f64 / 1000.0)])
        .args(["--rc-back-at", &format!("{}", RC_BACK_MS as f64 / 1000.0)])
        .args(["--duration", &format!("{}", END_MS as f64 / 1000.0)])
        .arg("--events")
        .arg(&events)
        .stdout(Stdio::null())
        .spawn()
        .unwrap();
    let mut child = Kill(child);
    let fc_addr = format!("127.0.0.1:{port}");
    let mut parser = Parser::with_signing(
        Verifier::with_timestamp(KEY, timestamp_now()),
        Unsigned::Refuse,
    );
    let mut script = Script::new();
    // fc-sim's clock starts when it starts: close enough (a few ms) for a
    // schedule in hundreds of ms; the comparison is of orders and kinds.
    let start = WallInstant::now();
    let mut buf = [0u8; 2048];
    while child.0.try_wait().unwrap().is_none() {
        let t = start.elapsed().as_millis() as u64;
        let mut outgoing = script.due(t);
        while let Ok((n, _)) = companion.recv_from(&mut buf) {
            let mut input = &buf[..n];
            while let Some(r) = parser.next(&mut input) {
                outgoing.extend(script.on_fc(&r.frame()));
            }
        }
        for (who, bytes) in outgoing {
            let socket = if who == Who::Companion {
                &companion
            } else {
                &attacker
            };
            let _ = socket.send_to(&bytes, &fc_addr);
        }
        assert!(t < END_MS + 5000, "fc-sim did not end");
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(child.0.wait().unwrap().success());
    let text = std::fs::read_to_string(&events).unwrap();
    let mut behaviour = Behaviour {
        modes: Vec::new(),
        applied: BTreeSet::new(),
    };
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        match v["event"].as_str().unwrap() {
            "mode" => behaviour
                .modes
                .push(v["mode"].as_str().unwrap().to_string()),
            "control_applied" => {
                behaviour.applied.insert((
                    v["sysid"].as_u64().unwrap() as u8,
                    v["compid"].as_u64().unwrap() as u8,
                    v["authenticated"].as_bool().unwrap(),
                    v["message"].as_str().unwrap().to_string(),
                ));
            }
            _ => {}
        }
    }
    // fc-sim also reports its mode at start; the engine reports changes.
    assert_eq!(behaviour.modes.first().map(String::as_str), Some("FBWA"));
    behaviour.modes.remove(0);
    let _ = std::fs::remove_dir_all(&dir);
    behaviour
}

#[test]
fn the_simulated_and_the_live_fc_behave_alike() {
    let simulated = virtual_run();
    let expected_applied: BTreeSet<_> = [
        "MANUAL_CONTROL",
        "RC_CHANNELS_OVERRIDE",
        "SET_ATTITUDE_TARGET",
    ]
    .into_iter()
    .map(|m| (CC.sysid, CC.compid, true, m.to_string()))
    .collect();
    assert_eq!(simulated.modes, ["CIRCLE", "FBWAG", "FBWA"]);
    assert_eq!(simulated.applied, expected_applied);
    let live = live_run();
    assert_eq!(live, simulated);
}
