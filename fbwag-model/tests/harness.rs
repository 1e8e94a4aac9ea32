//! The model's harness drives the real nodes: a scripted path reaches
//! companion control, a stranger's forgery changes nothing, equal states
//! merge, and the invariants catch the product itself misconfigured.

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
    s.fc.node.get().engine().authority()
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
    for forgery in [Forgery::Takeover, Forgery::Control] {
        let s = model
            .step(&handshake, Action::Forge(forgery), &mut None)
            .expect("a stranger may forge");
        assert_eq!(authority(&s), Authority::Handshake, "{forgery:?}");
        assert_eq!(s.ghost.broken, 0);
    }
}

#[test]
fn the_same_state_by_two_paths_is_one_state() {
    let model = DelegationModel::new(ModelConfig::default());
    // Losing either of two frames in flight, then the other, leaves the
    // same world.
    let sent = run(&model, &TAKEOVER[..4]);
    assert_eq!(sent.to_cc.len(), 2, "the notice and a heartbeat");
    let a = run(
        &model,
        &[
            &TAKEOVER[..4],
            &[Action::Lose(Party::Cc, 0), Action::Lose(Party::Cc, 0)],
        ]
        .concat(),
    );
    let b = run(
        &model,
        &[
            &TAKEOVER[..4],
            &[Action::Lose(Party::Cc, 1), Action::Lose(Party::Cc, 0)],
        ]
        .concat(),
    );
    assert_eq!(a, b);
    // Delivering the notice changes the companion: another state.
    let c = run(&model, &TAKEOVER[..5]);
    assert_ne!(a, c);
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
        fc_reboots: 1,
        cc_reboots: 0,
        dups: 0,
        forgeries: 0,
        autonomy_flips: 0,
        max_in_flight: 2,
        horizon: Duration::from_secs(4),
        fault: None,
    };
    let mut model = DelegationModel::new(world);
    model.cc.control_lease = model.cc.ack_retry_interval - Duration::from_millis(1);
    let opts = CheckOptions {
        model: world,
        depth: 14,
        threads: 2,
        stop_at_first: true,
    };
    let report = check_model(model, opts, |_, _| {});
    assert!(report.violations.is_empty(), "{report:#?}");
}
