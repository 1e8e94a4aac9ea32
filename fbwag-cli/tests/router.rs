//! `fbwag router` in a companion's stack: fc-sim on one link, `fbwag cc` on
//! another, a pymavlink ground station and another pymavlink program on two
//! more. The handover works through the router; the ground station sees
//! the delegation; addressed frames reach only their addressee; nothing
//! comes back to its sender.

use serde_json::Value;
use std::process::Command;
use std::time::Duration;

mod common;

use common::{free_port, python, repo, Proc};

#[test]
fn a_ground_station_and_the_companion_share_the_fc_through_the_router() {
    let py = python();
    let [fc, cc, gcs, other] = [free_port(), free_port(), free_port(), free_port()];
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("router")
            .args([fc, cc, gcs, other].map(|p| format!("udpin:127.0.0.1:{p}")))
            .args(["--duration", "9"]),
    );
    std::thread::sleep(Duration::from_millis(200));
    let companion = Proc::spawn(Command::new(env!("CARGO_BIN_EXE_fbwag")).args([
        "cc",
        "--link",
        &format!("udpout:127.0.0.1:{cc}"),
        "--duration",
        "8.5",
    ]));
    let peers = Proc::spawn(
        Command::new(&py)
            .arg(repo().join("interop/gcs_check.py"))
            .arg(format!("udpout:127.0.0.1:{gcs}"))
            .arg(format!("udpout:127.0.0.1:{other}"))
            .args(["--seconds", "8"]),
    );
    let dir = std::env::temp_dir().join(format!("fbwag-router-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let events = dir.join("fc.jsonl");
    let fc = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["fc-sim", "--link", &format!("udpout:127.0.0.1:{fc}")])
        .args([
            "--rc-loss-at",
            "3",
            "--rc-back-at",
            "6",
            "--duration",
            "7.5",
        ])
        .arg("--events")
        .arg(&events)
        .output()
        .unwrap();
    let peers = peers.finish(Duration::from_secs(10));
    let companion = companion.finish(Duration::from_secs(5));
    let router = router.finish(Duration::from_secs(5));
    let router_log = String::from_utf8_lossy(&router.stdout);
    let report = format!(
        "--- fc-sim\n{}\n--- router\n{router_log}\n--- peers\n{}{}",
        String::from_utf8_lossy(&fc.stdout),
        String::from_utf8_lossy(&peers.stdout),
        String::from_utf8_lossy(&peers.stderr)
    );
    assert!(fc.status.success(), "{report}");
    // Neither daemon failed: both ran out their duration.
    assert!(
        router.status.success() && companion.status.success(),
        "{report}"
    );
    let fc_events: Vec<Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    // The handover, through the router.
    let modes: Vec<&str> = fc_events
        .iter()
        .filter(|e| e["event"] == "mode")
        .map(|e| e["mode"].as_str().unwrap())
        .collect();
    assert_eq!(modes, ["FBWA", "CIRCLE", "FBWAG", "FBWA"], "{report}");
    assert!(fc_events
        .iter()
        .any(|e| e["event"] == "control_applied" && e["sysid"] == 1 && e["compid"] == 191));
    let p: Value = serde_json::from_str(
        String::from_utf8_lossy(&peers.stdout)
            .lines()
            .last()
            .unwrap_or("{}"),
    )
    .unwrap();
    // The ground station sees the delegation: the FC's notices, the
    // companion's answers, the FC's modes.
    let notices = p["notices"].as_array().unwrap();
    for (src, status) in [((1, 1), 1), ((1, 191), 2), ((1, 1), 0)] {
        assert!(
            notices
                .iter()
                .any(|n| n[0] == src.0 && n[1] == src.1 && n[2] == status),
            "no notice {status} from {src:?}: {notices:?}\n{report}"
        );
    }
    let fc_modes: Vec<u64> = p["fc_modes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_u64().unwrap())
        .collect();
    assert!(fc_modes.contains(&30), "{fc_modes:?}");
    // Addressed frames: the command to 7/7 reached it; the one to 9/9
    // (never seen) reached nobody; the companion's overrides, addressed to
    // the FC, reached neither the ground station nor the other program.
    let commands = p["commands_at_other"].as_array().unwrap();
    assert_eq!(commands.len(), 1, "{commands:?}\n{report}");
    assert_eq!(
        (commands[0][0].as_u64(), commands[0][1].as_u64()),
        (Some(7), Some(7))
    );
    assert_eq!(p["overrides_at"]["gcs"], 0, "{report}");
    assert_eq!(p["overrides_at"]["other"], 0, "{report}");
    // Nothing came back to its sender.
    assert_eq!(p["echoes"], 0, "{report}");
    let _ = std::fs::remove_dir_all(&dir);
}
