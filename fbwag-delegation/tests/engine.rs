//! The protocol engines driven with real frames (encoded, optionally
//! signed, parsed by the runtime's parser): the trust rule, which messages
//! are inputs, which control is applied, the companion's gate on control.

use fbwag_delegation::cc::{CcConfig, CcState};
use fbwag_delegation::control::{Control, Controller, WingsLevel};
use fbwag_delegation::engine::{CcEngine, CcOutput, ControlVerdict, FcEngine, FcOutput, Verdict};
use fbwag_delegation::fc::{Authority, FcConfig};
use fbwag_delegation::{wire, Moment, Peer, Status, TEXT_CC_TOOK_OVER};
use fbwag_dialect::dialects::common::{ManualControl, SetAttitudeTarget};
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Header, Message, Parser, Signer, Unsigned, Verifier, Version};

const FC: Peer = Peer::new(1, 1);
const CC: Peer = Peer::new(1, 191);
const GCS: Peer = Peer::new(255, 190);
const KEY: [u8; 32] = [7; 32];

fn ms(t: u64) -> Moment {
    Moment::from_millis(t)
}

/// A sender: its ids, sequence numbers and optional signing key.
struct Sender {
    id: Peer,
    seq: u8,
    signer: Option<Signer>,
}

impl Sender {
    fn new(id: Peer, key: Option<[u8; 32]>) -> Self {
        Sender {
            id,
            seq: 0,
            signer: key.map(|k| Signer::new(k, 0, 1_000)),
        }
    }

    fn frame(&mut self, msg: &dyn Encode) -> Vec<u8> {
        let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
        let h = Header {
            seq: self.seq,
            sysid: self.id.sysid,
            compid: self.id.compid,
        };
        self.seq = self.seq.wrapping_add(1);
        let n = encode(Version::V2, h, msg, self.signer.as_mut(), &mut buf).unwrap();
        buf[..n].to_vec()
    }
}

/// Parses `bytes` as a receiver with `key` would (unsigned frames pass,
/// marked unauthenticated) and feeds every frame to `feed`.
fn deliver(
    parser: &mut Parser,
    bytes: &[u8],
    mut feed: impl FnMut(&fbwag_dialect::Frame<&[u8]>, bool),
) {
    let mut input = bytes;
    while let Some(r) = parser.next(&mut input) {
        feed(&r.frame(), r.is_authenticated());
    }
}

fn signing_parser() -> Parser {
    Parser::with_signing(Verifier::new(KEY), Unsigned::Accept)
}

fn fc_outputs(fc: &mut FcEngine) -> Vec<FcOutput> {
    std::iter::from_fn(|| fc.poll_output()).collect()
}

fn cc_outputs(cc: &mut CcEngine) -> Vec<CcOutput> {
    std::iter::from_fn(|| cc.poll_output()).collect()
}

/// Runs the FC's timers up to `to`, returning the outputs.
fn run_fc(fc: &mut FcEngine, to: Moment) -> Vec<FcOutput> {
    let mut out = Vec::new();
    while let Some(t) = fc.poll_timeout().filter(|t| *t <= to) {
        fc.handle_timeout(t);
        out.extend(fc_outputs(fc));
    }
    out
}

/// The event id of the FC's first status-1 notice in `outputs`.
fn rc_lost_event(outputs: &[FcOutput]) -> u32 {
    outputs
        .iter()
        .find_map(|o| match o {
            FcOutput::Transmit(Message::FbwagNotice(n)) if n.failsafe_status == Status::RC_LOST => {
                Some(n.timestamp)
            }
            _ => None,
        })
        .expect("a status 1 notice")
}

/// An FC (signing required) brought into the handshake; returns it, its
/// parser and the event id.
fn fc_in_handshake() -> (FcEngine, Parser, u32) {
    let cfg = FcConfig {
        require_signed: true,
        ..FcConfig::default()
    };
    let mut fc = FcEngine::new(cfg, Moment::ZERO).unwrap();
    fc.set_receiver_ok(false);
    let out = run_fc(&mut fc, ms(250));
    assert_eq!(fc.authority(), Authority::Handshake);
    let event = rc_lost_event(&out);
    (fc, signing_parser(), event)
}

fn ack(event: u32) -> Message {
    Message::FbwagNotice(wire::notice(FC, Status::CC_TAKEOVER_CONFIRMED, event))
}

#[test]
fn takeover_counts_only_from_the_companion_signed() {
    let (mut fc, mut parser, event) = fc_in_handshake();
    let mut verdicts = Vec::new();
    // Unsigned as the companion, signed as a ground station with the key,
    // unsigned as a ground station: none takes over.
    let mut forged = Vec::new();
    forged.extend(Sender::new(CC, None).frame(&ack(event)));
    forged.extend(Sender::new(GCS, Some(KEY)).frame(&ack(event)));
    forged.extend(Sender::new(GCS, None).frame(&ack(event)));
    deliver(&mut parser, &forged, |f, auth| {
        verdicts.push(fc.handle_frame(ms(260), f, auth))
    });
    assert_eq!(verdicts, [Verdict::Untrusted; 3]);
    assert_eq!(fc.authority(), Authority::Handshake);
    assert_eq!(fc.stats().untrusted_notices, 3);
    // The companion, signed: takes over.
    let real = Sender::new(CC, Some(KEY)).frame(&ack(event));
    deliver(&mut parser, &real, |f, auth| {
        assert_eq!(fc.handle_frame(ms(270), f, auth), Verdict::Trusted)
    });
    assert_eq!(fc.authority(), Authority::Companion);
}

/// Control is applied only from the trusted companion, addressed to this
/// FC, in companion control: every control message, every way to get it
/// wrong.
#[test]
fn control_is_applied_only_when_trusted_addressed_and_delegated() {
    let (mut fc, mut parser, event) = fc_in_handshake();
    let mut cc = Sender::new(CC, Some(KEY));
    let override_ = Control::rc(FC, [1600, 1400, 1700, 1500, 0, 0, 0, 0]).to_message();
    // Before companion control: the companion's own control is not applied.
    deliver(&mut parser, &cc.frame(&override_), |f, a| {
        let _ = fc.handle_frame(ms(255), f, a);
    });
    assert!(fc_outputs(&mut fc)
        .iter()
        .all(|o| !matches!(o, FcOutput::ApplyControl { .. })));
    assert_eq!(fc.stats().controls_outside_companion, 1);
    deliver(&mut parser, &cc.frame(&ack(event)), |f, a| {
        let _ = fc.handle_frame(ms(260), f, a);
    });
    fc_outputs(&mut fc);
    assert_eq!(fc.authority(), Authority::Companion);

    let attitude = Control::Attitude(SetAttitudeTarget {
        thrust: 0.6,
        q: [1.0, 0.0, 0.0, 0.0],
        ..Default::default()
    })
    .addressed_to(FC)
    .to_message();
    let manual = Control::Manual(ManualControl {
        y: 300,
        z: 500,
        ..Default::default()
    })
    .addressed_to(FC)
    .to_message();
    let elsewhere = Control::rc(Peer::new(2, 1), [1000; 8]).to_message();
    let mut stream = Vec::new();
    stream.extend(cc.frame(&override_)); // applied
    stream.extend(cc.frame(&attitude)); // applied
    stream.extend(cc.frame(&manual)); // applied
    stream.extend(cc.frame(&elsewhere)); // another system: not applied
    stream.extend(Sender::new(CC, None).frame(&override_)); // unsigned: not
    stream.extend(Sender::new(GCS, Some(KEY)).frame(&override_)); // a GCS: not
    deliver(&mut parser, &stream, |f, a| {
        let _ = fc.handle_frame(ms(300), f, a);
    });
    let applied: Vec<_> = fc_outputs(&mut fc)
        .into_iter()
        .filter_map(|o| match o {
            FcOutput::ApplyControl { from, control } => Some((from, control)),
            _ => None,
        })
        .collect();
    assert_eq!(applied.len(), 3, "{applied:?}");
    assert!(applied
        .iter()
        .all(|(from, _)| from.peer == CC && from.authenticated));
    let names: Vec<_> = applied.iter().map(|(_, c)| c.name()).collect();
    assert_eq!(
        names,
        [
            "RC_CHANNELS_OVERRIDE",
            "SET_ATTITUDE_TARGET",
            "MANUAL_CONTROL"
        ]
    );
    let s = fc.stats();
    assert_eq!(
        (
            s.controls_applied,
            s.controls_misaddressed,
            s.controls_untrusted
        ),
        (3, 1, 2)
    );
    // The receiver returns: control is released and no longer applied.
    fc.set_receiver_ok(true);
    let out = run_fc(&mut fc, ms(600));
    assert!(out.contains(&FcOutput::ReleaseControl));
    assert_eq!(fc.authority(), Authority::Pilot);
    deliver(&mut parser, &cc.frame(&override_), |f, a| {
        let _ = fc.handle_frame(ms(610), f, a);
    });
    assert!(fc_outputs(&mut fc)
        .iter()
        .all(|o| !matches!(o, FcOutput::ApplyControl { .. })));
}

/// Trusted control is also the FC's proof of the companion's life: a
/// stream of it keeps companion control, its absence ends it (RTL).
#[test]
fn the_control_stream_keeps_companion_control() {
    let (mut fc, mut parser, event) = fc_in_handshake();
    let mut cc = Sender::new(CC, Some(KEY));
    deliver(&mut parser, &cc.frame(&ack(event)), |f, a| {
        let _ = fc.handle_frame(ms(260), f, a);
    });
    let control = Control::rc(FC, [1500; 8]).to_message();
    let mut t = 300;
    while t < 3000 {
        run_fc(&mut fc, ms(t));
        deliver(&mut parser, &cc.frame(&control), |f, a| {
            let _ = fc.handle_frame(ms(t), f, a);
        });
        t += 50;
    }
    fc_outputs(&mut fc);
    assert_eq!(fc.authority(), Authority::Companion);
    run_fc(&mut fc, ms(4100));
    assert_eq!(fc.authority(), Authority::Rtl, "no control for 1 s");
}

/// An FC whose override time-out (4 s) is above its companion-silence
/// one (3 s), in companion control from 260 ms on the signed
/// acknowledgement of `cc`.
fn fc_controlled_with_long_override(cc: &mut Sender) -> (FcEngine, Parser) {
    let cfg = FcConfig {
        require_signed: true,
        override_timeout: std::time::Duration::from_secs(4),
        ..FcConfig::default()
    };
    let mut fc = FcEngine::new(cfg, Moment::ZERO).unwrap();
    fc.set_receiver_ok(false);
    let event = rc_lost_event(&run_fc(&mut fc, ms(250)));
    let mut parser = signing_parser();
    deliver(&mut parser, &cc.frame(&ack(event)), |f, a| {
        let _ = fc.handle_frame(ms(260), f, a);
    });
    assert_eq!(fc.authority(), Authority::Companion);
    (fc, parser)
}

/// Only the companion's trusted frames prove it alive: a stranger's
/// unsigned heartbeats with its ids never hold companion control past the
/// companion-silence time-out. (With the override time-out above it, as a
/// user may set them, that time-out is the one that ends control.)
#[test]
fn a_strangers_heartbeats_never_prove_the_companion_alive() {
    let (mut fc, mut parser) = fc_controlled_with_long_override(&mut Sender::new(CC, Some(KEY)));
    let mut stranger = Sender::new(CC, None);
    let heartbeat = Message::Heartbeat(Default::default());
    for t in (300..3400).step_by(100) {
        run_fc(&mut fc, ms(t));
        deliver(&mut parser, &stranger.frame(&heartbeat), |f, a| {
            assert_eq!(fc.handle_frame(ms(t), f, a), Verdict::Untrusted);
        });
    }
    run_fc(&mut fc, ms(3400));
    assert_eq!(
        fc.authority(),
        Authority::Rtl,
        "silent for 3 s since 260 ms"
    );
}

/// The companion's own signed heartbeats do prove it alive: with the
/// override time-out above the companion-silence one, companion control
/// without control lasts until the override time-out, not the silence.
#[test]
fn the_companions_heartbeats_prove_it_alive() {
    let mut cc = Sender::new(CC, Some(KEY));
    let (mut fc, mut parser) = fc_controlled_with_long_override(&mut cc);
    let heartbeat = Message::Heartbeat(Default::default());
    for t in (300..3600).step_by(500) {
        run_fc(&mut fc, ms(t));
        deliver(&mut parser, &cc.frame(&heartbeat), |f, a| {
            assert_eq!(fc.handle_frame(ms(t), f, a), Verdict::Trusted);
        });
    }
    run_fc(&mut fc, ms(3600));
    assert_eq!(fc.authority(), Authority::Companion, "heard at 3.3 s");
    run_fc(&mut fc, ms(4300));
    assert_eq!(fc.authority(), Authority::Rtl, "no control for 4 s");
}

/// The FC's heartbeat says its mode; in companion control it is the 5 Hz
/// confirmation stream.
#[test]
fn fc_heartbeats_carry_the_mode_and_speed_up_in_companion_control() {
    let (mut fc, mut parser, event) = fc_in_handshake();
    deliver(
        &mut parser,
        &Sender::new(CC, Some(KEY)).frame(&ack(event)),
        |f, a| {
            let _ = fc.handle_frame(ms(260), f, a);
        },
    );
    // (Before 1.26 s: without control the FC falls back after 1 s.)
    let beats: Vec<u32> = run_fc(&mut fc, ms(1200))
        .into_iter()
        .filter_map(|o| match o {
            FcOutput::Transmit(Message::Heartbeat(h)) => Some(h.custom_mode),
            _ => None,
        })
        .collect();
    assert!(beats.len() >= 5, "{beats:?}");
    assert!(beats.iter().all(|&m| m == fbwag_delegation::mode::FBWAG));
}

/// A companion engine that has heard the FC and been asked to take over.
fn cc_controlling(require_signed: bool) -> (CcEngine, Parser, Sender, u32) {
    let cfg = CcConfig {
        require_signed,
        ..CcConfig::default()
    };
    let mut cc = CcEngine::new(cfg, Moment::ZERO).unwrap();
    let mut parser = signing_parser();
    let mut fc = Sender::new(FC, Some(KEY));
    let hb = Message::Heartbeat(wire::fc_heartbeat(Authority::Pilot));
    let notice = Message::FbwagNotice(wire::notice(FC, Status::RC_LOST, 5000));
    let mut bytes = fc.frame(&hb);
    bytes.extend(fc.frame(&notice));
    deliver(&mut parser, &bytes, |f, a| {
        assert_eq!(cc.handle_frame(ms(100), f, a), Verdict::Trusted)
    });
    (cc, parser, fc, 5000)
}

#[test]
fn companion_takes_over_answers_and_asks_its_controller() {
    let (mut cc, _, _, event) = cc_controlling(true);
    let out = cc_outputs(&mut cc);
    assert_eq!(out[0], CcOutput::FcFound);
    assert!(
        out.contains(&CcOutput::Transmit(Message::FbwagNotice(wire::notice(
            FC,
            Status::CC_TAKEOVER_CONFIRMED,
            event
        ))))
    );
    assert!(out.contains(&CcOutput::ControlStarted { event }));
    assert!(out.contains(&CcOutput::ControlDue));
    // While controlling, control is forwarded, re-addressed to the FC.
    let mut wings = WingsLevel { throttle: 1600 };
    let control = Control::rc(Peer::new(9, 9), [1500; 8]);
    assert_eq!(
        cc.submit_control(ms(101), control),
        ControlVerdict::Forwarded
    );
    match cc.poll_output() {
        Some(CcOutput::Transmit(Message::RcChannelsOverride(m))) => {
            assert_eq!((m.target_system, m.target_component), (FC.sysid, FC.compid))
        }
        other => panic!("{other:?}"),
    }
    let _ = cc.submit_control(ms(102), wings.control(ms(102), FC));
    assert_eq!(cc.stats().controls_forwarded, 2);
}

/// The FC's confirmation STATUSTEXT becomes the typed confirmation of the
/// event it names; a forged or unsigned one confirms nothing.
#[test]
fn the_takeover_text_confirms_only_from_the_fc() {
    let (mut cc, mut parser, mut fc, event) = cc_controlling(true);
    cc_outputs(&mut cc);
    let text = Message::Statustext(wire::status_text(TEXT_CC_TOOK_OVER, event));
    let forged = Sender::new(FC, None).frame(&text);
    deliver(&mut parser, &forged, |f, a| {
        assert_eq!(cc.handle_frame(ms(110), f, a), Verdict::Untrusted)
    });
    assert!(!cc.machine().believes_in_control(ms(110)));
    deliver(&mut parser, &fc.frame(&text), |f, a| {
        assert_eq!(cc.handle_frame(ms(120), f, a), Verdict::Trusted)
    });
    assert!(cc.machine().believes_in_control(ms(120)));
    // Another text with the same id confirms nothing.
    let (mut cc2, mut parser2, mut fc2, _) = cc_controlling(true);
    let other = Message::Statustext(wire::status_text("FBWAG-ACK: CC has taken", event));
    deliver(&mut parser2, &fc2.frame(&other), |f, a| {
        let _ = cc2.handle_frame(ms(120), f, a);
    });
    assert!(!cc2.machine().believes_in_control(ms(120)));
}

#[test]
fn companion_drops_control_when_not_in_control() {
    let mut cc = CcEngine::new(CcConfig::default(), Moment::ZERO).unwrap();
    let control = Control::rc(FC, [1500; 8]);
    assert_eq!(
        cc.submit_control(ms(1), control),
        ControlVerdict::NotInControl
    );
    // The hand-back ends control: later control is dropped and counted.
    let (mut cc, mut parser, mut fc, _) = cc_controlling(false);
    cc_outputs(&mut cc);
    let normal = Message::FbwagNotice(wire::notice(FC, Status::NORMAL, 9000));
    deliver(&mut parser, &fc.frame(&normal), |f, a| {
        let _ = cc.handle_frame(ms(9000), f, a);
    });
    assert!(cc_outputs(&mut cc).contains(&CcOutput::ControlStopped));
    assert_eq!(cc.state(), CcState::Standby);
    assert_eq!(
        cc.submit_control(ms(9001), control),
        ControlVerdict::NotInControl
    );
    assert_eq!(cc.stats().controls_dropped, 1);
}

#[test]
fn companion_ignores_strangers_and_unsigned_frames_when_signing_is_required() {
    let mut cc = CcEngine::new(
        CcConfig {
            require_signed: true,
            ..CcConfig::default()
        },
        Moment::ZERO,
    )
    .unwrap();
    let mut parser = signing_parser();
    let notice = Message::FbwagNotice(wire::notice(FC, Status::RC_LOST, 5000));
    let mut bytes = Sender::new(FC, None).frame(&notice);
    bytes.extend(Sender::new(GCS, Some(KEY)).frame(&notice));
    deliver(&mut parser, &bytes, |f, a| {
        assert_eq!(cc.handle_frame(ms(100), f, a), Verdict::Untrusted)
    });
    assert_eq!(cc.state(), CcState::Idle, "not even liveness");
    assert!(cc_outputs(&mut cc).is_empty());
    assert_eq!(cc.stats().untrusted_notices, 2);
}

/// FC liveness as events: found once, at its first trusted frame (not at
/// each later one), lost after its timeout.
#[test]
fn fc_liveness_events() {
    let (mut cc, mut parser, mut fc, _) = cc_controlling(false);
    assert_eq!(cc.poll_output(), Some(CcOutput::FcFound));
    let found = |out: Vec<CcOutput>| out.iter().filter(|o| **o == CcOutput::FcFound).count();
    assert_eq!(found(cc_outputs(&mut cc)), 0, "the notice after it");
    let hb = Message::Heartbeat(wire::fc_heartbeat(Authority::Pilot));
    deliver(&mut parser, &fc.frame(&hb), |f, a| {
        let _ = cc.handle_frame(ms(200), f, a);
    });
    assert_eq!(found(cc_outputs(&mut cc)), 0, "a later heartbeat");
    let mut lost = false;
    while let Some(t) = cc.poll_timeout().filter(|t| *t <= ms(20_000)) {
        cc.handle_timeout(t);
        lost |= cc_outputs(&mut cc).contains(&CcOutput::FcLost);
    }
    assert!(lost);
    assert_eq!(cc.state(), CcState::Idle);
}

/// The companion's heartbeat: 1 Hz, as an onboard controller.
#[test]
fn companion_heartbeat_is_1_hz() {
    let mut cc = CcEngine::new(CcConfig::default(), ms(5)).unwrap();
    let mut beats = 0;
    while let Some(t) = cc.poll_timeout().filter(|t| *t <= ms(10_000)) {
        cc.handle_timeout(t);
        for o in cc_outputs(&mut cc) {
            if let CcOutput::Transmit(Message::Heartbeat(h)) = o {
                assert_eq!(
                    h.r#type,
                    fbwag_dialect::dialects::minimal::MavType::ONBOARD_CONTROLLER
                );
                beats += 1;
            }
        }
    }
    assert_eq!(beats, 10, "at 5 ms, 1.005 s, … 9.005 s");
}
