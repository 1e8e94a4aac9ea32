//! The state machines driven directly: each rule of docs/delegation.md.

use fbwag_delegation::cc::{CcAction, CcConfig, CcInput, CcState, Companion};
use fbwag_delegation::fc::{Authority, FcAction, FcConfig, FcInput, FlightController};
use fbwag_delegation::{Moment, Peer, Status};
use std::time::Duration;

fn ms(t: u64) -> Moment {
    Moment::from_millis(t)
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
fn takeover_needs_the_right_event() {
    let mut fc = FlightController::new(FcConfig::default());
    samples(&mut fc, 0, 200, false);
    drain_fc(&mut fc);
    let ack = |timestamp| FcInput::Notice {
        status: Status::CC_TAKEOVER_CONFIRMED,
        timestamp,
    };
    fc.handle_input(ms(210), ack(99)); // another event
    assert_eq!(fc.authority(), Authority::Handshake);
    assert_eq!(fc.stats().stale_acks, 1);
    fc.handle_input(ms(212), ack(100));
    assert_eq!(fc.authority(), Authority::Companion);
    assert_eq!(
        drain_fc(&mut fc),
        vec![
            FcAction::SetAuthority(Authority::Companion),
            FcAction::AcceptOverrides(true),
            FcAction::ConfirmTakeover { event: 100 }
        ]
    );
    // In companion control, the acknowledgement repeated is confirmed
    // again; another event's is stale and confirms nothing.
    fc.handle_input(ms(300), ack(100));
    assert_eq!(
        drain_fc(&mut fc),
        [FcAction::ConfirmTakeover { event: 100 }]
    );
    fc.handle_input(ms(310), ack(99));
    assert_eq!(drain_fc(&mut fc), []);
    assert_eq!(fc.stats().stale_acks, 2);
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
            status: Status::NORMAL,
            timestamp: 400,
        },
    );
    assert_eq!(
        drain_fc(&mut fc),
        vec![FcAction::ConfirmHandBack { event: 400 }]
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
            status: Status::CC_TAKEOVER_CONFIRMED,
            timestamp: 100,
        },
    );
    drain_fc(&mut fc);
    for t in (250..1000).step_by(50) {
        fc.handle_input(ms(t), FcInput::Control);
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
            seq: 0,
            companion_control: false,
        },
    );
    assert_eq!(cc.state(), CcState::Standby);
    cc.handle_input(
        ms(100),
        CcInput::Notice {
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
        CcInput::TakeoverConfirmed {
            seq: 2,
            event: 100,
            by: None,
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
fn companion_ignores_late_frames() {
    let mut cc = Companion::new(CcConfig::default());
    let notice = |timestamp| CcInput::Notice {
        status: Status::RC_LOST,
        timestamp,
    };
    cc.handle_input(ms(100), notice(100));
    cc.handle_input(
        ms(110),
        CcInput::Heartbeat {
            seq: 12,
            companion_control: true,
        },
    );
    assert!(cc.believes_in_control(ms(110)));
    // A heartbeat sent before the takeover (seq 11 < 12) arrives late.
    cc.handle_input(
        ms(120),
        CcInput::Heartbeat {
            seq: 11,
            companion_control: false,
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
            seq: 13,
            companion_control: false,
        },
    );
    assert_eq!(cc.state(), CcState::Standby);
    // A confirmation of another event confirms nothing.
    cc.handle_input(ms(200), notice(200));
    cc.handle_input(
        ms(210),
        CcInput::TakeoverConfirmed {
            seq: 15,
            event: 100,
            by: None,
        },
    );
    assert!(!cc.believes_in_control(ms(210)));
    assert_eq!(cc.state(), CcState::Controlling);
}

/// The FC names the companion it accepted: one that sees another
/// accepted for its event stops at once, and FBWAG-mode heartbeats after
/// it renew no belief; its own name confirms as the paper's text does.
#[test]
fn a_companion_that_sees_another_accepted_stops_at_once() {
    let cfg = CcConfig::default();
    let mut cc = Companion::new(cfg);
    let lost = CcInput::Notice {
        status: Status::RC_LOST,
        timestamp: 100,
    };
    cc.handle_input(ms(100), lost);
    while cc.poll_action().is_some() {}
    let confirmed = |seq, by| CcInput::TakeoverConfirmed {
        seq,
        event: 100,
        by: Some(by),
    };
    cc.handle_input(ms(110), confirmed(2, cfg.own));
    assert!(cc.believes_in_control(ms(110)));
    let stranger = Peer::new(1, 77);
    cc.handle_input(ms(120), confirmed(3, stranger));
    let actions: Vec<_> = std::iter::from_fn(|| cc.poll_action()).collect();
    assert_eq!(
        actions,
        [
            CcAction::StopControl,
            CcAction::Superseded {
                event: 100,
                by: stranger
            }
        ]
    );
    assert_eq!(cc.state(), CcState::Standby);
    assert!(!cc.believes_in_control(ms(120)));
    cc.handle_input(
        ms(130),
        CcInput::Heartbeat {
            seq: 4,
            companion_control: true,
        },
    );
    assert!(!cc.believes_in_control(ms(130)));
    assert_eq!(cc.state(), CcState::Standby);
}

/// Found by the model check: an FC that restarts in companion control
/// numbers its frames from 0 again, so its new heartbeats look older than
/// the companion's last confirmation; they refreshed its FC-silence timer
/// and never ended its control. Once the confirmation is older than the
/// lease (no late frame is that late), a heartbeat in another mode ends
/// control whatever its sequence number.
#[test]
fn a_restarted_fcs_heartbeats_end_control_though_they_count_from_0() {
    let mut cc = Companion::new(CcConfig::default());
    let hb = |seq, companion_control| CcInput::Heartbeat {
        seq,
        companion_control,
    };
    let notice = CcInput::Notice {
        status: Status::RC_LOST,
        timestamp: 100,
    };
    cc.handle_input(ms(100), notice);
    cc.handle_input(ms(110), hb(40, true));
    // Within the lease, an older heartbeat is a late one: nothing ends.
    cc.handle_input(ms(500), hb(1, false));
    assert_eq!(cc.state(), CcState::Controlling);
    // Past the lease, it is the FC's news, however numbered; at its very
    // end, not yet.
    let lease = CcConfig::default().control_lease;
    cc.handle_input(ms(110) + lease, hb(1, false));
    assert_eq!(cc.state(), CcState::Controlling);
    cc.handle_input(ms(110) + lease + Duration::from_millis(1), hb(2, false));
    assert_eq!(cc.state(), CcState::Standby);
    // An old heartbeat of companion control confirms nothing, ever.
    cc.handle_input(
        ms(2000),
        CcInput::Notice {
            status: Status::RC_LOST,
            timestamp: 2000,
        },
    );
    cc.handle_input(ms(2010), hb(50, true));
    cc.handle_input(ms(4000), hb(45, true));
    assert!(!cc.believes_in_control(ms(4000)));
}

#[test]
fn companion_acks_are_bounded_per_event() {
    let mut cc = Companion::new(CcConfig::default());
    let mut acts = Vec::new();
    for k in 0..10u8 {
        cc.handle_input(
            ms(100 + k as u64),
            CcInput::Notice {
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

/// A retry limit of 255 (the field's maximum) must neither overflow a
/// counter nor retry forever: the handshake still ends at its timeout, and
/// the hand-back stops after 1 + 255 notices.
#[test]
fn the_largest_retry_limit_is_bounded() {
    let cfg = FcConfig {
        max_retries: 255,
        ..FcConfig::default()
    };
    cfg.validate().unwrap();
    let mut fc = FlightController::new(cfg);
    samples(&mut fc, 0, 200, false);
    let mut acts = drain_fc(&mut fc);
    acts.extend(timers(&mut fc, 600_000));
    assert_eq!(
        fc.authority(),
        Authority::Rtl,
        "the handshake timeout still ends it"
    );
    let normal = acts
        .iter()
        .filter(|a| {
            matches!(
                a,
                FcAction::SendNotice {
                    status: Status::NORMAL,
                    ..
                }
            )
        })
        .count();
    assert_eq!(normal, 256, "1 + 255 hand-back notices, then none");
    assert_eq!(fc.poll_timeout(), None);

    // Notices 1 ms apart, retry interval 1 ms: every notice is due an
    // answer (one within half a retry interval of the last is not).
    let mut cc = Companion::new(CcConfig {
        max_ack_retries: 255,
        ack_retry_interval: std::time::Duration::from_millis(1),
        ..CcConfig::default()
    });
    let mut acks = 0;
    for k in 0..400u64 {
        cc.handle_input(
            ms(100 + k),
            CcInput::Notice {
                status: Status::RC_LOST,
                timestamp: 100,
            },
        );
        acks += drain_cc(&mut cc)
            .iter()
            .filter(|a| matches!(a, CcAction::SendNotice { .. }))
            .count();
    }
    assert_eq!(acks, 256, "1 + 255 acknowledgements of one event");
}

/// What the companion does when a notice shows the FC rebooted while it
/// controlled: it ends the old boot's episode and takes over event
/// `timestamp` of the new one.
fn takeover_of_a_new_boot(timestamp: u32) -> Vec<CcAction> {
    vec![
        CcAction::StopControl,
        CcAction::FcRebooted,
        CcAction::SendNotice {
            status: Status::CC_TAKEOVER_CONFIRMED,
            timestamp,
        },
        CcAction::StartControl,
        CcAction::SendControl,
    ]
}

/// The FC reboots while the companion controls: its new boot counts events
/// from zero again. The companion recognises the new boot and hands over
/// normally instead of ignoring every notice as older than the last one.
#[test]
fn companion_recognises_an_fc_reboot() {
    let mut cc = Companion::new(CcConfig::default());
    let rc_lost = |timestamp| CcInput::Notice {
        status: Status::RC_LOST,
        timestamp,
    };
    // The first boot's event 600_000 (10 min after boot) is taken over.
    cc.handle_input(ms(1_000), rc_lost(600_000));
    assert_eq!(cc.state(), CcState::Controlling);
    drain_cc(&mut cc);
    // Its retries (same id, within its lifetime) are still the same event.
    cc.handle_input(ms(4_000), rc_lost(600_000));
    assert!(!drain_cc(&mut cc).contains(&CcAction::FcRebooted));
    // A delayed notice of an older event of the same boot is stale.
    cc.handle_input(ms(4_100), rc_lost(598_000));
    assert!(drain_cc(&mut cc).is_empty(), "stale, not a reboot");
    // The FC reboots; 2.2 s into its new boot the receiver is still lost.
    cc.handle_input(ms(9_000), rc_lost(2_200));
    let acts = drain_cc(&mut cc);
    assert_eq!(acts, takeover_of_a_new_boot(2_200));
    assert_eq!(cc.event(), Some(2_200));
    assert_eq!(cc.stats().fc_reboots, 1);
    // The new boot's retries are its own event, not another reboot.
    cc.handle_input(ms(10_000), rc_lost(2_200));
    assert!(!drain_cc(&mut cc).contains(&CcAction::FcRebooted));
}

/// A quick reboot: the new boot's RC loss comes 1.4 s into it, 200 ms of
/// its clock before the old boot's event, which is too close to tell apart
/// from a late notice of the old boot by the ids alone. The FC repeats the
/// notice of its current event every retry interval, and only of that one:
/// the second notice of the older event, a retry later, proves the new
/// boot. (Before, the companion waited until the old event was 6 s behind,
/// and the FC's 5 s handshake ended in RTL.)
#[test]
fn companion_recognises_a_quick_fc_reboot() {
    let mut cc = Companion::new(CcConfig::default());
    let rc_lost = |timestamp| CcInput::Notice {
        status: Status::RC_LOST,
        timestamp,
    };
    cc.handle_input(ms(1_000), rc_lost(1_600));
    assert_eq!(cc.state(), CcState::Controlling);
    drain_cc(&mut cc);
    // The new boot's first notice, and a duplicate of it close behind: a
    // late frame of the old boot would look the same.
    cc.handle_input(ms(2_900), rc_lost(1_400));
    cc.handle_input(ms(3_000), rc_lost(1_400));
    assert!(drain_cc(&mut cc).is_empty(), "not yet a reboot");
    assert_eq!(cc.event(), Some(1_600));
    // Its retry, a second later.
    cc.handle_input(ms(3_900), rc_lost(1_400));
    let acts = drain_cc(&mut cc);
    assert_eq!(acts, takeover_of_a_new_boot(1_400));
    assert_eq!(cc.event(), Some(1_400));
    // A late notice of another older event, once, is still stale.
    cc.handle_input(ms(4_000), rc_lost(1_300));
    assert!(drain_cc(&mut cc).is_empty(), "stale, not a reboot");
    assert_eq!(cc.stats().fc_reboots, 1);
}

#[test]
fn settings_that_cannot_work_are_refused() {
    use fbwag_delegation::ConfigError;
    let zero = std::time::Duration::ZERO;
    assert_eq!(
        FcConfig {
            retry_interval: zero,
            ..FcConfig::default()
        }
        .validate(),
        Err(ConfigError::Zero("retry_interval"))
    );
    assert_eq!(
        FcConfig {
            rc_loss_samples: 0,
            ..FcConfig::default()
        }
        .validate(),
        Err(ConfigError::Zero("rc_loss_samples"))
    );
    assert_eq!(
        CcConfig {
            control_period: std::time::Duration::from_secs(1),
            ..CcConfig::default()
        }
        .validate(),
        Err(ConfigError::Order("control_period", "control_lease"))
    );
    // The companion's heartbeat must come at least once per retry: equal
    // periods are fine, a longer heartbeat period is not.
    let retry = FcConfig::default().retry_interval;
    let heartbeat_every = |period| FcConfig {
        companion_heartbeat_period: period,
        ..FcConfig::default()
    };
    assert!(heartbeat_every(retry).validate().is_ok());
    assert_eq!(
        heartbeat_every(retry + std::time::Duration::from_millis(1)).validate(),
        Err(ConfigError::Order(
            "companion_heartbeat_period",
            "retry_interval"
        ))
    );
    assert!(FcConfig::default().validate().is_ok() && CcConfig::default().validate().is_ok());
}

/// The FC's repeated notice and the companion's own retry timer come about
/// together: one acknowledgement answers both, so the per-event bound is
/// not spent twice as fast (found live: after an FC reboot the bound ran
/// out before the FC's last notice).
#[test]
fn a_notice_just_after_an_acknowledgement_is_already_answered() {
    let mut cc = Companion::new(CcConfig::default());
    let notice = CcInput::Notice {
        status: Status::RC_LOST,
        timestamp: 100,
    };
    let mut acks = Vec::new();
    cc.handle_input(ms(100), notice);
    let mut t = 100;
    // The FC repeats at 1 s; our timer fires at 1.1 s, 2.1 s, ...: each
    // repeat lands 3 ms after our timer's acknowledgement.
    while t < 4_200 {
        if let Some(next) = cc.poll_timeout().filter(|n| *n <= ms(t)) {
            cc.handle_timeout(next);
        }
        if t % 1000 == 103 && t > 1000 {
            cc.handle_input(ms(t), notice);
        }
        acks.extend(
            drain_cc(&mut cc)
                .into_iter()
                .filter(|a| matches!(a, CcAction::SendNotice { .. }))
                .map(|_| t),
        );
        t += 1;
    }
    assert_eq!(acks, [100, 1100, 2100, 3100], "one answer per retry period");
}

fn notice(status: Status, timestamp: u32) -> CcInput {
    CcInput::Notice { status, timestamp }
}

fn sent(acts: &[CcAction]) -> Vec<(Status, u32)> {
    acts.iter()
        .filter_map(|a| match a {
            CcAction::SendNotice { status, timestamp } => Some((*status, *timestamp)),
            _ => None,
        })
        .collect()
}

/// A decline the FC did not hear is said again when the FC repeats its
/// notice, within the per-event bound; a later event, once control is
/// ready, is taken over, not declined for the old one's sake.
#[test]
fn a_decline_is_repeated_within_its_bound_and_binds_only_its_event() {
    let cfg = CcConfig::default();
    let mut cc = Companion::new(cfg);
    cc.set_control_ready(false);
    let mut declines = Vec::new();
    for k in 0..10u64 {
        cc.handle_input(ms(100 + 1000 * k), notice(Status::RC_LOST, 100));
        declines.extend(sent(&drain_cc(&mut cc)));
    }
    let bound = usize::from(cfg.max_ack_retries) + 1;
    assert_eq!(declines, vec![(Status::NORMAL, 100); bound]);
    assert_eq!(cc.state(), CcState::Standby);

    cc.set_control_ready(true);
    cc.handle_input(ms(20_000), notice(Status::RC_LOST, 20_000));
    let acts = drain_cc(&mut cc);
    assert_eq!(sent(&acts), [(Status::CC_TAKEOVER_CONFIRMED, 20_000)]);
    assert_eq!(cc.state(), CcState::Controlling);
}

/// Event numbers are the FC's milliseconds since boot: an event numbered 0
/// is one like any other, taken over when control is ready.
#[test]
fn an_event_numbered_0_is_taken_over() {
    let mut cc = Companion::new(CcConfig::default());
    cc.handle_input(ms(10), notice(Status::RC_LOST, 0));
    assert_eq!(
        sent(&drain_cc(&mut cc)),
        [(Status::CC_TAKEOVER_CONFIRMED, 0)]
    );
    assert_eq!(cc.state(), CcState::Controlling);
}

/// The FC's repeated notice half a retry interval after the last
/// acknowledgement is answered: only one closer than that shares it.
#[test]
fn a_repeated_notice_half_an_interval_later_is_answered() {
    let cfg = CcConfig::default();
    let mut cc = Companion::new(cfg);
    cc.handle_input(ms(100), notice(Status::RC_LOST, 100));
    drain_cc(&mut cc);
    let half = cfg.ack_retry_interval / 2;
    let just_before = ms(100) + (half - Duration::from_millis(1));
    cc.handle_input(just_before, notice(Status::RC_LOST, 100));
    assert!(
        sent(&drain_cc(&mut cc)).is_empty(),
        "one answer serves both"
    );
    cc.handle_input(ms(100) + half, notice(Status::RC_LOST, 100));
    assert_eq!(
        sent(&drain_cc(&mut cc)),
        [(Status::CC_TAKEOVER_CONFIRMED, 100)]
    );
}

/// A hand-back makes older events stale: a late RC-loss notice of an
/// event before it is not taken over.
#[test]
fn an_rc_loss_older_than_a_hand_back_is_stale() {
    let mut cc = Companion::new(CcConfig::default());
    cc.handle_input(ms(300), notice(Status::NORMAL, 200));
    drain_cc(&mut cc);
    cc.handle_input(ms(310), notice(Status::RC_LOST, 100));
    let acts = drain_cc(&mut cc);
    assert!(sent(&acts).is_empty(), "{acts:?}");
    assert_eq!(cc.state(), CcState::Standby);
}

/// Late notices of two different older events, half an interval apart, are
/// late frames of this boot, not a new boot repeating its event.
#[test]
fn late_notices_of_two_older_events_are_no_reboot() {
    let cfg = CcConfig::default();
    let mut cc = Companion::new(cfg);
    cc.handle_input(ms(5000), notice(Status::RC_LOST, 5000));
    drain_cc(&mut cc);
    let half = cfg.ack_retry_interval / 2;
    cc.handle_input(ms(5010), notice(Status::RC_LOST, 100));
    cc.handle_input(ms(5010) + half, notice(Status::RC_LOST, 200));
    let acts = drain_cc(&mut cc);
    assert!(!acts.contains(&CcAction::FcRebooted), "{acts:?}");
    assert_eq!(cc.state(), CcState::Controlling);
    assert_eq!(cc.event(), Some(5000));
}

/// The FC reports its debounced receiver state, and its timers run only
/// when due: a timer call between two retries sends nothing, one after the
/// last retry sends no more.
#[test]
fn the_fcs_receiver_state_shows_and_early_timer_calls_send_nothing() {
    let cfg = FcConfig::default();
    let mut fc = FlightController::new(cfg);
    samples(&mut fc, 0, 100, true);
    assert!(fc.receiver_ok());
    samples(&mut fc, 100, 300, false);
    assert!(!fc.receiver_ok());
    let first = drain_fc(&mut fc);
    assert!(first
        .iter()
        .any(|a| matches!(a, FcAction::SendNotice { .. })));
    let notices = |acts: &[FcAction]| {
        acts.iter()
            .filter(|a| matches!(a, FcAction::SendNotice { .. }))
            .count()
    };
    // Between the first notice and the first retry: nothing.
    assert!(fc.poll_timeout().is_some_and(|due| due > ms(250)));
    fc.handle_timeout(ms(250));
    assert_eq!(notices(&drain_fc(&mut fc)), 0);
    // The retries, then calls at every 100 ms to just before the deadline:
    // 1 + max_retries notices in all.
    let mut sent = 0;
    let deadline = 200 + cfg.handshake_timeout.as_millis() as u64;
    for t in (300..deadline).step_by(100) {
        fc.handle_timeout(ms(t));
        sent += notices(&drain_fc(&mut fc));
    }
    assert_eq!(sent, usize::from(cfg.max_retries));
    // The fall-back, then its hand-back notice and retries alike.
    let mut handed_back = 0;
    for t in (deadline..deadline + 10_000).step_by(100) {
        fc.handle_timeout(ms(t));
        handed_back += notices(&drain_fc(&mut fc));
    }
    assert_eq!(fc.authority(), Authority::Rtl);
    assert_eq!(handed_back, 1 + usize::from(cfg.max_retries));
    samples(&mut fc, deadline + 10_000, deadline + 10_500, true);
    assert!(fc.receiver_ok());
}

/// A late copy of the notice of an event already handed back is stale: it
/// starts no second takeover.
#[test]
fn a_late_copy_of_a_handed_back_events_notice_is_no_new_takeover() {
    let mut cc = Companion::new(CcConfig::default());
    cc.handle_input(ms(100), notice(Status::RC_LOST, 100));
    cc.handle_input(ms(900), notice(Status::NORMAL, 100));
    assert_eq!(cc.state(), CcState::Standby);
    drain_cc(&mut cc);
    cc.handle_input(ms(950), notice(Status::RC_LOST, 100));
    let acts = drain_cc(&mut cc);
    assert!(sent(&acts).is_empty(), "{acts:?}");
    assert_eq!(cc.state(), CcState::Standby);
}

/// Event ids are the FC's milliseconds since boot; only an id at or just
/// below the last one is moved past it (two events in a millisecond). An
/// event 25 days after the last keeps its own time, though the
/// milliseconds wrap at 49.7 days.
#[test]
fn an_event_weeks_after_the_last_keeps_its_own_id() {
    let mut fc = FlightController::new(FcConfig::default());
    let event = |acts: Vec<FcAction>| {
        acts.into_iter().find_map(|a| match a {
            FcAction::SendNotice { status, timestamp } if status == Status::RC_LOST => {
                Some(timestamp)
            }
            _ => None,
        })
    };
    samples(&mut fc, 0, 300, false);
    assert_eq!(event(drain_fc(&mut fc)), Some(100));
    samples(&mut fc, 300, 1000, true);
    drain_fc(&mut fc);
    let later = (1u64 << 31) + 1000;
    samples(&mut fc, later, later + 300, false);
    assert_eq!(event(drain_fc(&mut fc)), Some(later as u32 + 100));
}

/// Events in one millisecond (the receiver lost, back and lost again
/// within it) get distinct ids: the next number each (the hand-back
/// between the two losses is event 101).
#[test]
fn two_events_in_one_millisecond_get_distinct_ids() {
    let mut fc = FlightController::new(FcConfig {
        rc_loss_samples: 1,
        rc_regain_samples: 1,
        ..FcConfig::default()
    });
    let mut ids = Vec::new();
    for ok in [false, true, false] {
        fc.handle_input(ms(100), FcInput::RcSample { receiver_ok: ok });
        ids.extend(drain_fc(&mut fc).into_iter().filter_map(|a| match a {
            FcAction::SendNotice {
                status: Status::RC_LOST,
                timestamp,
            } => Some(timestamp),
            _ => None,
        }));
    }
    assert_eq!(ids, [100, 102]);
}

/// A notice is of a new FC boot when its id is further behind the newest
/// event than an event can stay live (`fc_event_lifetime`); at exactly
/// that distance it is a late frame of this boot.
#[test]
fn a_new_boot_is_an_id_behind_by_more_than_an_events_lifetime() {
    let cfg = CcConfig {
        fc_event_lifetime: Duration::from_secs(7),
        ..CcConfig::default()
    };
    let mut cc = Companion::new(cfg);
    assert_eq!(*cc.config(), cfg);
    cc.handle_input(ms(10_000), notice(Status::RC_LOST, 10_000));
    drain_cc(&mut cc);
    let lifetime = cfg.fc_event_lifetime.as_millis() as u32;
    cc.handle_input(ms(10_000), notice(Status::RC_LOST, 10_000 - lifetime));
    assert!(!drain_cc(&mut cc).contains(&CcAction::FcRebooted));
    assert_eq!(cc.event(), Some(10_000));
    cc.handle_input(ms(10_000), notice(Status::RC_LOST, 10_000 - lifetime - 1));
    assert!(drain_cc(&mut cc).contains(&CcAction::FcRebooted));
}
