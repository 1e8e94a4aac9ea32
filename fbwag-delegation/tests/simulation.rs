//! The protocol in the simulator: every scenario's success criterion, the
//! invariants on every trial, and exhaustively over every drop pattern of
//! the first 12 frames of a handover.

use fbwag_delegation::fc::Authority;
use fbwag_delegation::sim::link::{GilbertElliott, LinkModel};
use fbwag_delegation::sim::report::{run_many, sweep, Losses};
use fbwag_delegation::sim::{run, Scenario, Trial};
use std::time::Duration;

#[test]
fn every_scenario_meets_its_criterion_without_violations() {
    for s in Scenario::ALL {
        let loss = if s == Scenario::MessageLoss { 0.5 } else { 0.0 };
        let row = run_many(s, loss, 500, 11, |seed| Trial::new(s, loss, seed));
        assert!(
            row.violations.is_empty(),
            "{}: {:?}",
            s.name(),
            row.violations
        );
        assert_eq!(row.false_takeovers, 0, "{}", s.name());
        let floor = if s == Scenario::MessageLoss {
            0.75
        } else {
            1.0
        };
        assert!(
            row.success_rate() >= floor,
            "{}: success {}",
            s.name(),
            row.success_rate()
        );
    }
}

#[test]
fn takeover_is_fast_on_a_clean_link() {
    let row = run_many(Scenario::RcLoss, 0.0, 2000, 3, |seed| {
        Trial::new(Scenario::RcLoss, 0.0, seed)
    });
    // Two receiver samples at 10 Hz (≤ 200 ms) plus one round trip.
    assert!(
        row.quantile_ms(1.0).unwrap() < 300.0,
        "max {:?} ms",
        row.quantile_ms(1.0)
    );
    assert_eq!(row.fallbacks, 0);
}

#[test]
fn harsh_links_break_no_invariant() {
    let harsh = LinkModel {
        latency: Duration::from_millis(40),
        jitter: Duration::from_millis(60),
        loss: 0.1,
        burst: Some(GilbertElliott::with_mean(0.2, 6.0)),
        duplicate: 0.1,
        reorder: 0.1,
        reorder_delay: Duration::from_millis(80),
    };
    for s in Scenario::ALL {
        let row = run_many(s, 0.3, 300, 21, |seed| Trial {
            downlink: harsh,
            uplink: harsh,
            ..Trial::new(s, 0.3, seed)
        });
        assert!(
            row.violations.is_empty(),
            "{}: {:?}",
            s.name(),
            row.violations
        );
        assert_eq!(row.false_takeovers, 0, "{}", s.name());
    }
}

#[test]
fn every_drop_pattern_of_the_first_12_frames_of_a_handover() {
    let mut outcomes = [0u32; 2];
    for mask in 0u16..(1 << 12) {
        for seed in [1, 2] {
            let trial = Trial {
                drop_pattern: Some(mask),
                ..Trial::new(Scenario::RcLoss, 0.0, seed)
            };
            let o = run(&trial);
            assert!(
                o.violations.is_empty(),
                "mask {mask:012b} seed {seed}: {:?}",
                o.violations
            );
            // RC stays lost: the FC ends in companion control or RTL, never
            // in the handshake, never with the pilot.
            match o.final_authority {
                Authority::Companion => outcomes[0] += 1,
                Authority::Rtl => outcomes[1] += 1,
                other => panic!("mask {mask:012b}: ended in {other:?}"),
            }
        }
    }
    // The four notices (first + 3 retries) lie within the first 12 frames:
    // RTL exactly when all four are dropped (1 pattern in 16), companion
    // control otherwise.
    assert_eq!(outcomes, [7680, 512]);
}

#[test]
fn trials_are_deterministic_and_rows_independent_of_threads() {
    let a = run(&Trial::new(Scenario::MessageLoss, 0.5, 77));
    let b = run(&Trial::new(Scenario::MessageLoss, 0.5, 77));
    assert_eq!(
        (a.success, a.response, a.frames),
        (b.success, b.response, b.frames)
    );
    let r1 = run_many(Scenario::MessageLoss, 0.5, 64, 5, |s| {
        Trial::new(Scenario::MessageLoss, 0.5, s)
    });
    let r2 = run_many(Scenario::MessageLoss, 0.5, 64, 5, |s| {
        Trial::new(Scenario::MessageLoss, 0.5, s)
    });
    assert_eq!((r1.successes, &r1.responses), (r2.successes, &r2.responses));
}

#[test]
fn traces_tell_the_story() {
    let trial = Trial {
        trace: true,
        ..Trial::new(Scenario::RcLoss, 0.0, 1)
    };
    let t = run(&trial).trace.join("\n");
    for step in [
        "receiver lost",
        "FC -> notice status 1",
        "CC -> notice status 2",
        "FC authority -> Companion",
        "CC has taken over",
    ] {
        assert!(t.contains(step), "missing {step:?} in\n{t}");
    }
}

#[test]
fn a_bursty_sweep_uses_the_burst_length_it_is_given() {
    let s = Scenario::MessageLoss;
    let (trials, seed, loss) = (40, 5, 0.5);
    let rows = sweep(s, trials, seed, Losses::Bursty { mean_burst: 3.0 });
    assert_eq!(rows[5].loss, loss);
    let with = |burst: f64| {
        run_many(s, loss, trials, seed, |seed| {
            Trial::new(s, loss, seed).bursty(loss, burst)
        })
    };
    let (three, eight) = (with(3.0), with(8.0));
    let key = |r: &fbwag_delegation::sim::report::Row| (r.frames, r.responses.clone());
    assert_eq!(key(&rows[5]), key(&three));
    assert_ne!(
        key(&three),
        key(&eight),
        "the burst length must matter here"
    );
}

/// Every stranger of the scenario was there and turned away by the
/// companion's node, for the reason the policy gives.
#[test]
fn strangers_are_turned_away_and_the_autonomy_flies() {
    use fbwag_delegation::node::DropReason;
    let s = Scenario::Strangers;
    let row = run_many(s, 0.0, 500, 1001, |seed| Trial::new(s, 0.0, seed));
    assert!(row.violations.is_empty(), "{:?}", row.violations);
    assert_eq!(row.success_rate(), 1.0);
    assert_eq!((row.false_takeovers, row.fallbacks), (0, 0));
    // Two receiver samples at 10 Hz plus one round trip, strangers or not.
    assert!(row.quantile_ms(1.0).unwrap() < 300.0);
    let o = run(&Trial::new(s, 0.0, 7));
    for reason in [
        DropReason::OwnIds,
        DropReason::Impersonation,
        DropReason::Unauthenticated,
        DropReason::NotPeer,
        DropReason::Gated,
    ] {
        assert!(
            o.cc_drops.get(reason) > 0,
            "no {} drop: {:?}",
            reason.name(),
            o.cc_drops
        );
    }
    // The companion let no stranger through: the FC's node had nothing
    // to drop.
    assert_eq!(o.fc_drops.total(), 0, "{:?}", o.fc_drops);
}

#[test]
fn strangers_on_lossy_links_break_no_invariant() {
    let s = Scenario::Strangers;
    for (loss, burst) in [(0.2, None), (0.5, Some(4.0))] {
        let row = run_many(s, loss, 150, 202, |seed| {
            let t = Trial::new(s, loss, seed);
            burst.map_or(t, |b| t.bursty(loss, b))
        });
        assert!(
            row.violations.is_empty(),
            "loss {loss}: {:?}",
            row.violations
        );
        assert_eq!(row.false_takeovers, 0);
        assert!(
            row.success_rate() > 0.5,
            "loss {loss}: {}",
            row.success_rate()
        );
    }
}

#[test]
fn a_silent_autonomy_declines_and_the_fc_returns_home_at_once() {
    let s = Scenario::SilentAutonomy;
    let row = run_many(s, 0.0, 1000, 303, |seed| Trial::new(s, 0.0, seed));
    assert!(row.violations.is_empty(), "{:?}", row.violations);
    assert_eq!(row.success_rate(), 1.0);
    assert_eq!((row.false_takeovers, row.fallbacks), (0, 1000));
    // RTL one round trip after the first notice: far from the 5 s of a
    // companion that never answers.
    assert!(row.quantile_ms(1.0).unwrap() < 300.0);
    let trial = Trial {
        trace: true,
        ..Trial::new(s, 0.0, 1)
    };
    let t = run(&trial).trace.join("\n");
    for step in [
        "CC: autonomy silent",
        "FC -> notice status 1",
        "CC declines event",
        "CC -> notice status 0",
        "FC authority -> Rtl",
    ] {
        assert!(t.contains(step), "missing {step:?} in\n{t}");
    }
    assert!(!t.contains("FC authority -> Companion"), "{t}");
}

#[test]
fn a_silent_autonomy_with_the_fallback_flies_wings_level() {
    let s = Scenario::SilentAutonomyFallback;
    let row = run_many(s, 0.0, 1000, 404, |seed| Trial::new(s, 0.0, seed));
    assert!(row.violations.is_empty(), "{:?}", row.violations);
    assert_eq!(row.success_rate(), 1.0);
    assert_eq!((row.false_takeovers, row.fallbacks), (0, 0));
    assert!(row.quantile_ms(1.0).unwrap() < 300.0);
}
