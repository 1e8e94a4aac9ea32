//! `fbwag sim --model-check`: the exhaustive check of the real nodes finds
//! no violation within its default depth. (That it finds each fault planted
//! in its harness is fbwag-model/tests/faults.rs.)

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

const INVARIANTS: [&str; 8] = [
    "single-controller",
    "trusted-control-only",
    "rc-loss-answered-in-time",
    "pilot-back-in-time",
    "no-wait-forever",
    "belief-bounded",
    "bounded-notices",
    "no-stale-takeover",
];

#[test]
fn the_default_check_explores_100_000_states_without_a_violation() {
    let (code, r) = model_check(&[]);
    assert_eq!(r["violations"], serde_json::json!([]), "{r:#}");
    assert_eq!(code, Some(0));
    let states = r["states"].as_u64().expect("states");
    assert!(states >= 100_000, "only {states} states explored");
    assert!(r["depth"].as_u64().expect("depth") >= 8);
    let names: Vec<&str> = r["invariants"]
        .as_array()
        .expect("invariants")
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    assert_eq!(names, INVARIANTS);
    // Not vacuous: the search reaches companion control, the companion's
    // confirmed belief and the RTL fallback.
    let reached: Vec<&str> = r["reached"]
        .as_array()
        .expect("reached")
        .iter()
        .filter_map(|v| v["state"].as_str())
        .collect();
    for state in ["companion-control", "companion-believes", "rtl-fallback"] {
        assert!(reached.contains(&state), "{state} never reached: {r:#}");
    }
}
