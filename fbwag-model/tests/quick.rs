//! The quick world, every reachable state of it (the test command's model
//! check; `fbwag sim --model-check` runs the default check's worlds): no
//! invariant broken, and every situation the invariants speak of reached,
//! so none holds vacuously.

use fbwag_model::{check_world, worlds, CheckOptions};

#[test]
fn the_quick_world_breaks_no_invariant_in_any_reachable_state() {
    let world = worlds::quick();
    let report = check_world(&world, CheckOptions::default(), |_, _| {});
    assert!(report.violations.is_empty(), "{:#?}", report.violations);
    assert!(report.fixpoint, "{report:#?}");
    assert!(report.states >= 300_000, "only {} states", report.states);
    // Every time-out of the handshake and of companion control runs out
    // within the search: it goes well past the longest.
    assert!(
        report.virtual_time.as_secs() > 15,
        "{:?}",
        report.virtual_time
    );
    let reached: Vec<&str> = report.reached.iter().map(|(name, _)| *name).collect();
    let must = [
        "companion-control",
        "companion-believes",
        "retry",
        "handshake-timeout",
        "override-timeout",
        "ack-retry",
        "confirm-timeout",
        "fc-silent",
        "fc-silent-while-controlling",
        "lease-lapsed",
        "trusted-signed-on",
    ];
    for situation in must {
        assert!(
            reached.contains(&situation),
            "{situation} never reached: {reached:?}"
        );
    }
}
