//! `fbwag sim` from the command line.

use std::process::Command;

fn sim(args: &[&str]) -> (String, String, bool) {
    let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .arg("sim")
        .args(args)
        .output()
        .expect("fbwag sim");
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
        out.status.success(),
    )
}

#[test]
fn scenario_json_has_the_documented_keys_and_is_reproducible() {
    let args = [
        "--scenario",
        "message-loss",
        "--loss",
        "0.5",
        "--trials",
        "300",
        "--seed",
        "7",
        "--json",
    ];
    let (a, err, ok) = sim(&args);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(a.trim()).expect("one JSON object");
    for key in [
        "scenario",
        "trials",
        "success_rate",
        "p50_ms",
        "p95_ms",
        "max_ms",
        "fallbacks",
        "false_takeovers",
    ] {
        assert!(v.get(key).is_some(), "missing {key} in {a}");
    }
    assert_eq!(v["scenario"], "message-loss");
    assert_eq!(v["trials"], 300);
    assert_eq!(v["false_takeovers"], 0);
    let (b, _, _) = sim(&args);
    assert_eq!(a, b, "same seed, same output");
}

#[test]
fn table1_prints_the_paper_beside_ours() {
    let (out, err, ok) = sim(&["--table1", "--trials", "200"]);
    assert!(ok, "{err}");
    for row in [
        "Normal RC Operation",
        "RC Loss → CC Takeover",
        "Message Loss (Retry)",
        "CC Failure (Failsafe to RTL)",
        "80% (4/5)",
        "Invariant violations: 0.",
    ] {
        assert!(out.contains(row), "missing {row:?}:\n{out}");
    }
}

#[test]
fn sweep_writes_a_table_and_an_svg() {
    let dir = std::env::temp_dir().join(format!("fbwag-sweep-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let svg = dir.join("sweep.svg");
    let (out, err, ok) = sim(&["--sweep", "--trials", "50", "--svg", svg.to_str().unwrap()]);
    assert!(ok, "{err}");
    assert_eq!(out.lines().count(), 11, "header + 10 loss rates:\n{out}");
    let chart = std::fs::read_to_string(&svg).unwrap();
    assert!(
        chart.starts_with("<svg")
            && chart.contains("polyline")
            && chart.trim_end().ends_with("</svg>")
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_arguments_are_explained() {
    let (_, err, ok) = sim(&["--scenario", "nope"]);
    assert!(!ok);
    assert!(
        err.contains("unknown scenario `nope`; one of: normal-rc, rc-loss"),
        "{err}"
    );
    let (_, err, ok) = sim(&[]);
    assert!(!ok);
    assert!(err.contains("--table1, --sweep, or --scenario"), "{err}");
}
