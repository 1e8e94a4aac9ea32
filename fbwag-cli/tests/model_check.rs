//! `fbwag sim --model-check`: the command line of the exhaustive check of
//! the real nodes, on the smallest world of the default check (every
//! reachable state of it), its report and its JSON line. (That the quick
//! world breaks no invariant is fbwag-model/tests/quick.rs; that the
//! checker finds each fault planted in its harness, faults.rs there; the
//! default check's worlds take minutes: see docs/delegation.md.)

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

const INVARIANTS: [&str; 26] = [
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
    "who-flies-decided-on-the-ground",
];

#[test]
fn a_world_is_explored_to_its_fixpoint_and_reported_as_json() {
    let (code, r) = model_check(&["--world", "companion-silence"]);
    assert_eq!(r["violations"], serde_json::json!([]), "{r:#}");
    assert_eq!(code, Some(0));
    assert_eq!(r["fixpoint"], true, "{r:#}");
    let states = r["states"].as_u64().expect("states");
    assert!(states >= 100_000, "only {states} states explored");
    let worlds = r["worlds"].as_array().expect("worlds");
    assert_eq!(worlds.len(), 1);
    assert_eq!(worlds[0]["world"], "companion-silence");
    assert_eq!(worlds[0]["states"], r["states"]);
    // The virtual time reached: past every time-out of the FC.
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
    // This world is the one where the companion-silence time-out runs out.
    let reached: Vec<&str> = r["reached"]
        .as_array()
        .expect("reached")
        .iter()
        .filter_map(|v| v["state"].as_str())
        .collect();
    for state in [
        "companion-control",
        "companion-silence",
        "handshake-timeout",
    ] {
        assert!(reached.contains(&state), "{state} never reached: {r:#}");
    }
}

#[test]
fn an_unknown_world_is_refused_with_the_names() {
    let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["sim", "--model-check", "--world", "nowhere"])
        .output()
        .expect("fbwag runs");
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("unknown world `nowhere`") && stderr.contains("two-cycles"),
        "{stderr}"
    );
}
