//! `fbwag sim --model-check`: the exhaustive check of the real nodes
//! finds no violation in the quick world, every reachable state of it.
//! (That it finds each fault planted in its harness is
//! fbwag-model/tests/faults.rs; the default check's worlds take ten
//! minutes, a separate command: see docs/delegation.md.)

use std::process::Command;

/// Runs `fbwag sim --model-check --json ARGS`: exit code and the last
/// line's JSON object.
fn model_check(args: &[&str]) -> (Option<i32>, serde_json::Value) {
    let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["sim", "--model-check", "--json"])
        .args(args)
        .output()
        .expect("fbwag runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let last = stdout.lines().last().unwrap_or_default();
    let report = serde_json::from_str(last)
        .unwrap_or_else(|e| panic!("last line is not JSON ({e}): {stdout}"));
    (out.status.code(), report)
}

const INVARIANTS: [&str; 25] = [
    "single-controller",
    "trusted-control-only",
    "no-stale-takeover",
    "stale-ack-changes-nothing",
    "decline-falls-back",
    "leaves-with-notice",
    "notices-are-events",
    "bounded-notices",
    "notices-end",
    "no-takeover-while-silent",
    "silent-autonomy-holds-nothing",
    "unsigned-changes-nothing",
    "unauthenticated-stays-out",
    "peer-only-by-signature",
    "no-replay",
    "signer-never-goes-back",
    "rc-loss-answered-in-time",
    "pilot-back-in-time",
    "no-wait-forever",
    "never-without-control",
    "companion-heard",
    "belief-bounded",
    "belief-from-confirmation",
    "companion-stops",
    "companion-hears-fc",
];

#[test]
fn the_quick_world_has_no_violation_in_any_reachable_state() {
    let (code, r) = model_check(&["--world", "quick"]);
    assert_eq!(r["violations"], serde_json::json!([]), "{r:#}");
    assert_eq!(code, Some(0));
    assert_eq!(r["fixpoint"], true, "{r:#}");
    let states = r["states"].as_u64().expect("states");
    assert!(states >= 100_000, "only {states} states explored");
    // Every time-out of the FC's handshake and companion control runs
    // out within the search: it goes well past the longest.
    let virtual_seconds = r["virtual_seconds"].as_f64().expect("virtual time");
    assert!(
        virtual_seconds > 15.0,
        "virtual time only to {virtual_seconds} s"
    );
    let names: Vec<&str> = r["invariants"]
        .as_array()
        .expect("invariants")
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    assert_eq!(names, INVARIANTS);
    // Not vacuous: the search reaches companion control, the companion's
    // confirmed belief, the retries and each time-out.
    let reached: Vec<&str> = r["reached"]
        .as_array()
        .expect("reached")
        .iter()
        .filter_map(|v| v["state"].as_str())
        .collect();
    let must = [
        "companion-control",
        "companion-believes",
        "retry",
        "handshake-timeout",
        "override-timeout",
        "ack-retry",
        "confirm-timeout",
        "fc-silent-while-controlling",
        "lease-lapsed",
    ];
    for state in must {
        assert!(reached.contains(&state), "{state} never reached: {r:#}");
    }
}
