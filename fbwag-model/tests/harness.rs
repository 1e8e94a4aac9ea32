//! The model's harness drives the real nodes: a scripted path reaches
//! companion control, a stranger's forgery changes nothing, states equal
//! but for when they happen are one state, and the invariants catch the
//! product itself misconfigured.

use core::time::Duration;
use fbwag_delegation::fc::Authority;
use fbwag_model::state::Party;
use fbwag_model::{
    check_model, Action, CheckOptions, DelegationModel, Forgery, ModelConfig, State,
};

fn run(model: &DelegationModel, actions: &[Action]) -> State {
    let mut s = model.initial();
    for a in actions {
        s = model
            .step(&s, *a, &mut None)
            .unwrap_or_else(|| panic!("{a:?} does not apply"));
    }
    s
}

fn authority(s: &State) -> Authority {
    s.fc.node.engine().authority()
}

/// The receiver fails before the first sample; the FC's second sample
/// (0.5 s) starts the handshake; the notice and the acknowledgement arrive.
const TAKEOVER: [Action; 6] = [
    Action::RcLost,
    Action::TickFc,
    Action::TickCc,
    Action::TickFc,
    Action::Deliver(Party::Cc, 0),
    Action::Deliver(Party::Fc, 0),
];

#[test]
fn a_scripted_takeover_reaches_companion_control_through_signed_frames() {
    let model = DelegationModel::new(ModelConfig::default());
    let s = run(&model, &TAKEOVER[..4]);
    assert_eq!(authority(&s), Authority::Handshake);
    assert_eq!(s.now.0, 500_000);
    let s = run(&model, &TAKEOVER);
    assert_eq!(authority(&s), Authority::Companion);
    assert_eq!(s.ghost.broken, 0);
}

#[test]
fn a_forged_takeover_and_forged_control_change_nothing() {
    let model = DelegationModel::new(ModelConfig::default());
    let handshake = run(&model, &TAKEOVER[..4]);
    for forgery in Forgery::ALL {
        let s = model
            .step(&handshake, Action::Forge(forgery), &mut None)
            .expect("a stranger may forge");
        assert_eq!(authority(&s), Authority::Handshake, "{forgery:?}");
        assert_eq!(s.ghost.broken, 0, "{forgery:?}");
    }
}

#[test]
fn a_replay_of_a_captured_frame_is_refused_and_changes_nothing() {
    let model = DelegationModel::new(ModelConfig::default());
    // The FC's notice reaches the companion: the stranger captured it.
    let delivered = run(&model, &TAKEOVER[..5]);
    assert_eq!(delivered.ghost.recordings.len(), 1);
    let replayed = model
        .step(&delivered, Action::Replay(0), &mut None)
        .expect("the capture can be replayed");
    assert_eq!(replayed.ghost.broken, 0);
    assert!(!replayed.ghost.gap);
    assert_eq!(
        replayed, delivered,
        "the replay was refused: nothing changed"
    );
}

/// The documented gap of the threat model: a side restarted without its
/// signing state file authenticates, once per stream, a frame captured
/// before; with the state kept, the replay is refused.
#[test]
fn a_replay_into_a_restart_without_its_signing_state_is_the_documented_gap() {
    let model = DelegationModel::new(ModelConfig::default());
    let captured = [Action::TickFc, Action::Deliver(Party::Cc, 0)];
    for kept in [true, false] {
        let restart = Action::RebootCc { signing_kept: kept };
        let s = run(&model, &[&captured[..], &[restart]].concat());
        assert_eq!(
            s.ghost.recordings.len(),
            1,
            "the FC's heartbeat was captured"
        );
        let replayed = model
            .step(&s, Action::Replay(0), &mut None)
            .expect("the capture can be replayed");
        assert_eq!(replayed.ghost.gap, !kept, "signing state kept: {kept}");
        assert_eq!(replayed.ghost.broken, 0);
    }
}

/// The same situation later is the same state: a pilot flying with the
/// receiver working comes back to the state it was in, a second later.
#[test]
fn a_state_like_an_earlier_one_but_later_is_the_same_state() {
    let model = DelegationModel::new(ModelConfig::default());
    let mut s = model.initial();
    let mut seen = vec![s.clone()];
    let repeat = loop {
        let t = s.now;
        s = model.step(&s, Action::TickFc, &mut None).expect("a tick");
        // Every frame arrives before the clock moves on.
        while !s.to_cc.is_empty() || !s.to_fc.is_empty() {
            let to = if s.to_cc.is_empty() {
                Party::Fc
            } else {
                Party::Cc
            };
            s = model
                .step(&s, Action::Deliver(to, 0), &mut None)
                .expect("a delivery");
        }
        while s.earliest() == Some(s.now) {
            s = model.step(&s, Action::TickCc, &mut None).expect("a tick");
        }
        if let Some(i) = seen.iter().position(|e| *e == s) {
            break (seen[i].now, s.now, t);
        }
        seen.push(s.clone());
        assert!(s.now.0 < 20_000_000, "no state came back");
    };
    let (first, again, _) = repeat;
    assert!(again > first, "{repeat:?}");
    assert_eq!(authority(&s), Authority::Pilot);
}

/// The checker found, with the real engine and no fault planted, that a
/// lease longer than the retry interval let the companion believe it
/// controlled long after the FC had taken control back (a restarted FC):
/// the product now refuses such settings, and the longest lease it accepts
/// keeps `belief-bounded` in the same world.
#[test]
fn the_longest_lease_the_companion_accepts_keeps_its_belief_bounded() {
    let long = fbwag_delegation::cc::CcConfig {
        control_lease: Duration::from_secs(3),
        ..Default::default()
    };
    assert_eq!(
        long.validate(),
        Err(fbwag_delegation::ConfigError::Order(
            "control_lease",
            "ack_retry_interval"
        ))
    );
    let world = ModelConfig {
        rc_flips: 1,
        rc_back_in_rtl: false,
        fc_reboots: 1,
        fc_reboot_window: Duration::from_secs(2),
        cc_reboots: 0,
        dups: 0,
        stranger: false,
        autonomy_flips: 0,
        max_in_flight: 2,
        horizon: None,
        fault: None,
    };
    let mut model = DelegationModel::new(world);
    model.cc.control_lease = model.cc.ack_retry_interval - Duration::from_millis(1);
    let opts = CheckOptions {
        model: world,
        depth: Some(14),
        threads: 2,
        stop_at_first: true,
    };
    let report = check_model(model, opts, |_, _| {});
    assert!(report.violations.is_empty(), "{report:#?}");
}
