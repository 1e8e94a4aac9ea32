//! The state machines driven directly: each rule of docs/delegation.md.

use fbwag_delegation::cc::{CcAction, CcConfig, CcInput, CcState, Companion};
use fbwag_delegation::fc::{Authority, FcAction, FcConfig, FcInput, FlightController};
use fbwag_delegation::{mode, Instant, Origin, Peer, Status, TEXT_CC_TOOK_OVER, TEXT_RC_TOOK_OVER};

fn ms(t: u64) -> Instant {
    Instant::from_millis(t)
}

fn cc_origin(seq: u8) -> Origin {
    Origin {
        peer: Peer::new(1, 191),
        authenticated: false,
        seq,
    }
}

fn fc_origin(seq: u8) -> Origin {
    Origin {
        peer: Peer::new(1, 1),
        authenticated: false,
        seq,
    }
}

fn drain_fc(fc: &mut FlightController) -> Vec<FcAction> {
    std::iter::from_fn(|| fc.poll_action()).collect()
}

fn drain_cc(cc: &mut Companion) -> Vec<CcAction> {
    std::iter::from_fn(|| cc.poll_action()).collect()
}

/// Feeds receiver samples every 100 ms from `from` to `to` (exclusive).
fn samples(fc: &mut FlightController, from: u64, to: u64, ok: bool) {
    let mut t = from;
    while t < to {
        fc.handle_input(ms(t), FcInput::RcSample { receiver_ok: ok });
        t += 100;
    }
}

/// Runs the FC's timers up to `to`, draining actions after each (the
/// contract: drain after every call); returns them.
fn timers(fc: &mut FlightController, to: u64) -> Vec<FcAction> {
    let mut acts = Vec::new();
    while let Some(t) = fc.poll_timeout() {
        if t > ms(to) {
            break;
        }
        fc.handle_timeout(t);
        acts.extend(drain_fc(fc));
    }
    acts
}

#[test]
fn two_bad_samples_start_the_handshake() {
    let mut fc = FlightController::new(FcConfig::default());
    fc.handle_input(ms(1000), FcInput::RcSample { receiver_ok: false });
    assert!(drain_fc(&mut fc).is_empty(), "one bad sample is not a loss");
    fc.handle_input(ms(1100), FcInput::RcSample { receiver_ok: false });
    assert_eq!(
        drain_fc(&mut fc),
        vec![
            FcAction::SetAuthority(Authority::Handshake),
            FcAction::SendNotice {
                status: Status::RC_LOST,
                timestamp: 1100
            }
        ]
    );
    // A single good sample between bad ones does not count as return.
    let mut fc = FlightController::new(FcConfig::default());
    samples(&mut fc, 0, 200, false);
    fc.handle_input(ms(200), FcInput::RcSample { receiver_ok: true });
    fc.handle_input(ms(300), FcInput::RcSample { receiver_ok: false });
    assert_eq!(fc.authority(), Authority::Handshake);
}

#[test]
fn takeover_needs_the_right_event_and_sender() {
    let mut fc = FlightController::new(FcConfig::default());
    samples(&mut fc, 0, 200, false);
    drain_fc(&mut fc);
    let ack = |from, timestamp| FcInput::Notice {
        from,
        status: Status::CC_TAKEOVER_CONFIRMED,
        timestamp,
    };
    fc.handle_input(ms(210), ack(cc_origin(0), 99)); // another event
    fc.handle_input(
        ms(211),
        ack(
            Origin {
                peer: Peer::new(255, 190),
                authenticated: false,
                seq: 0,
            },
            100,
        ),
    ); // a ground station
    assert_eq!(fc.authority(), Authority::Handshake);
    assert_eq!((fc.stats().stale_acks, fc.stats().rejected_senders), (1, 1));
    fc.handle_input(ms(212), ack(cc_origin(1), 100));
    assert_eq!(fc.authority(), Authority::Companion);
    assert_eq!(
        drain_fc(&mut fc),
        vec![
            FcAction::SetAuthority(Authority::Companion),
            FcAction::AcceptOverrides(true),
            FcAction::SendStatusText {
                text: TEXT_CC_TOOK_OVER,
                event: 100
            }
        ]
    );
}

#[test]
fn signed_only_takeover_when_required() {
    let mut fc = FlightController::new(FcConfig {
        require_signed: true,
        ..FcConfig::default()
    });
    samples(&mut fc, 0, 200, false);
    let ack = |authenticated| FcInput::Notice {
        from: Origin {
            peer: Peer::new(1, 191),
            authenticated,
            seq: 0,
        },
        status: Status::CC_TAKEOVER_CONFIRMED,
        timestamp: 100,
    };
    fc.handle_input(ms(210), ack(false));
    assert_eq!(
        fc.authority(),
        Authority::Handshake,
        "a spoofed (unsigned) status 2 never takes control"
    );
    fc.handle_input(ms(220), ack(true));
    assert_eq!(fc.authority(), Authority::Companion);
}

#[test]
fn retries_are_bounded_then_rtl_with_hand_back_notice() {
    let mut fc = FlightController::new(FcConfig::default());
    samples(&mut fc, 0, 200, false);
    let mut acts = drain_fc(&mut fc);
    acts.extend(timers(&mut fc, 10_000));
    let notices: Vec<_> = acts
        .into_iter()
        .filter_map(|a| match a {
            FcAction::SendNotice { status, timestamp } => Some((status, timestamp)),
            _ => None,
        })
        .collect();
    let lost: Vec<_> = notices
        .iter()
        .filter(|(s, _)| *s == Status::RC_LOST)
        .collect();
    assert_eq!(
        lost.len(),
        4,
        "1 + 3 retries, all for event 100: {notices:?}"
    );
    assert!(lost.iter().all(|(_, t)| *t == 100));
    assert_eq!(fc.authority(), Authority::Rtl);
    // RTL at 5 s after the first notice; status 0 tells the companion.
    let normal: Vec<_> = notices
        .iter()
        .filter(|(s, _)| *s == Status::NORMAL)
        .collect();
    assert_eq!(normal.first().map(|(_, t)| *t), Some(5100));
    assert!(normal.len() <= 4, "hand-back retries are bounded too");
    assert_eq!(fc.poll_timeout(), None, "no endless retry");
}

#[test]
fn rc_return_hands_back_and_overrides_stop_counting() {
    let mut fc = FlightController::new(FcConfig::default());
    samples(&mut fc, 0, 200, false);
    fc.handle_input(
        ms(205),
        FcInput::Notice {
            from: cc_origin(0),
            status: Status::CC_TAKEOVER_CONFIRMED,
            timestamp: 100,
        },
    );
    drain_fc(&mut fc);
    samples(&mut fc, 300, 500, true);
    assert_eq!(fc.authority(), Authority::Pilot);
    let acts = drain_fc(&mut fc);
    assert_eq!(
        acts[0],
        FcAction::AcceptOverrides(false),
        "overrides off before anything else"
    );
    assert!(acts.contains(&FcAction::SendNotice {
        status: Status::NORMAL,
        timestamp: 400
    }));
    fc.handle_input(
        ms(450),
        FcInput::Notice {
            from: cc_origin(1),
            status: Status::NORMAL,
            timestamp: 400,
        },
    );
    assert_eq!(
        drain_fc(&mut fc),
        vec![FcAction::SendStatusText {
            text: TEXT_RC_TOOK_OVER,
            event: 400
        }]
    );
    assert_eq!(
        fc.poll_timeout(),
        None,
        "hand-back acknowledged: nothing pending"
    );
}

#[test]
fn silent_companion_means_rtl() {
    let mut fc = FlightController::new(FcConfig::default());
    samples(&mut fc, 0, 200, false);
    fc.handle_input(
        ms(205),
        FcInput::Notice {
            from: cc_origin(0),
            status: Status::CC_TAKEOVER_CONFIRMED,
            timestamp: 100,
        },
    );
    drain_fc(&mut fc);
    for t in (250..1000).step_by(50) {
        fc.handle_input(ms(t), FcInput::Control { from: cc_origin(0) });
    }
    timers(&mut fc, 1900);
    assert_eq!(
        fc.authority(),
        Authority::Companion,
        "overrides until 0.95 s keep control until 1.95 s"
    );
    timers(&mut fc, 2000);
    assert_eq!(fc.authority(), Authority::Rtl);
}

#[test]
fn companion_acks_streams_and_stops_on_hand_back() {
    let mut cc = Companion::new(CcConfig::default());
    cc.handle_input(
        ms(0),
        CcInput::Heartbeat {
            from: fc_origin(0),
            custom_mode: mode::FBWA,
        },
    );
    assert_eq!(cc.state(), CcState::Standby);
    cc.handle_input(
        ms(100),
        CcInput::Notice {
            from: fc_origin(1),
            status: Status::RC_LOST,
            timestamp: 100,
        },
    );
    assert_eq!(
        drain_cc(&mut cc),
        vec![
            CcAction::SendNotice {
                status: Status::CC_TAKEOVER_CONFIRMED,
                timestamp: 100
            },
            CcAction::StartControl,
            CcAction::SendControl
        ]
    );
    assert!(
        !cc.believes_in_control(ms(100)),
        "not before the FC confirms"
    );
    cc.handle_input(
        ms(110),
        CcInput::StatusText {
            from: fc_origin(2),
            text: TEXT_CC_TOOK_OVER,
            id: 100,
        },
    );
    assert!(cc.believes_in_control(ms(110)));
    assert!(
        !cc.believes_in_control(ms(900)),
        "the lease (750 ms) lapses without confirmations"
    );
    // The control stream: every 50 ms.
    let mut sent = 0;
    while let Some(t) = cc.poll_timeout() {
        if t > ms(600) {
            break;
        }
        cc.handle_timeout(t);
        sent += drain_cc(&mut cc)
            .iter()
            .filter(|a| **a == CcAction::SendControl)
            .count();
    }
    assert_eq!(sent, 10, "100 ms … 600 ms at 20 Hz");
    cc.handle_input(
        ms(700),
        CcInput::Notice {
            from: fc_origin(3),
            status: Status::NORMAL,
            timestamp: 700,
        },
    );
    assert_eq!(
        drain_cc(&mut cc),
        vec![
            CcAction::StopControl,
            CcAction::SendNotice {
                status: Status::NORMAL,
                timestamp: 700
            }
        ]
    );
    assert_eq!(cc.state(), CcState::Standby);
}

#[test]
fn companion_ignores_late_frames_and_strangers() {
    let mut cc = Companion::new(CcConfig::default());
    let notice = |seq, timestamp| CcInput::Notice {
        from: fc_origin(seq),
        status: Status::RC_LOST,
        timestamp,
    };
    cc.handle_input(ms(100), notice(10, 100));
    cc.handle_input(
        ms(110),
        CcInput::Heartbeat {
            from: fc_origin(12),
            custom_mode: mode::FBWAG,
        },
    );
    assert!(cc.believes_in_control(ms(110)));
    // A heartbeat sent before the takeover (seq 11 < 12) arrives late.
    cc.handle_input(
        ms(120),
        CcInput::Heartbeat {
            from: fc_origin(11),
            custom_mode: mode::CIRCLE,
        },
    );
    assert_eq!(
        cc.state(),
        CcState::Controlling,
        "a late heartbeat ends nothing"
    );
    // A newer one in RTL does.
    cc.handle_input(
        ms(130),
        CcInput::Heartbeat {
            from: fc_origin(13),
            custom_mode: mode::RTL,
        },
    );
    assert_eq!(cc.state(), CcState::Standby);
    // A confirmation of another event confirms nothing.
    cc.handle_input(ms(200), notice(14, 200));
    cc.handle_input(
        ms(210),
        CcInput::StatusText {
            from: fc_origin(15),
            text: TEXT_CC_TOOK_OVER,
            id: 100,
        },
    );
    assert!(!cc.believes_in_control(ms(210)));
    // Someone else's notice is ignored.
    let before = *cc.stats();
    cc.handle_input(
        ms(300),
        CcInput::Notice {
            from: Origin {
                peer: Peer::new(9, 9),
                authenticated: false,
                seq: 0,
            },
            status: Status::NORMAL,
            timestamp: 300,
        },
    );
    assert_eq!(cc.stats().rejected_senders, before.rejected_senders + 1);
    assert_eq!(cc.state(), CcState::Controlling);
}

#[test]
fn companion_acks_are_bounded_per_event() {
    let mut cc = Companion::new(CcConfig::default());
    let mut acts = Vec::new();
    for k in 0..10u8 {
        cc.handle_input(
            ms(100 + k as u64),
            CcInput::Notice {
                from: fc_origin(k),
                status: Status::RC_LOST,
                timestamp: 100,
            },
        );
        acts.extend(drain_cc(&mut cc));
    }
    let mut t = 110;
    while t < 20_000 {
        cc.handle_timeout(ms(t));
        acts.extend(drain_cc(&mut cc));
        if t == 5060 {
            assert_eq!(cc.state(), CcState::Controlling);
        }
        if t == 5160 {
            assert_ne!(
                cc.state(),
                CcState::Controlling,
                "never confirmed: gives up after 5 s"
            );
            assert!(acts.contains(&CcAction::StopControl));
        }
        t += 50;
    }
    let acks = acts
        .iter()
        .filter(|a| matches!(a, CcAction::SendNotice { .. }))
        .count();
    assert_eq!(acks, 4, "1 + 3 per event, however often asked");
    assert_eq!(cc.state(), CcState::Idle, "then forgets a silent FC");
}
