//! The autonomy gateway of `fbwag cc`: a user's pymavlink program (no key,
//! no handshake of its own) streams RC overrides through a whole RC loss →
//! companion control → pilot cycle; the FC applies them, from the
//! companion's ids and signed with its key, only in companion control, and
//! the companion drops them whenever it does not hold control.

use serde_json::Value;
use std::process::{Command, Stdio};
use std::time::Duration;

mod common;

use common::{free_port, python, repo};

fn events(path: &std::path::Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn the_autonomy_flies_only_while_the_companion_holds_control() {
    let py = python();
    let (fc_port, autonomy_port, program) = (free_port(), free_port(), free_port());
    let dir = std::env::temp_dir().join(format!("fbwag-autonomy-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (fc_events, cc_events) = (dir.join("fc.jsonl"), dir.join("cc.jsonl"));
    let key = "11".repeat(32);
    let mut cc = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["cc", "--link", &format!("udpin:127.0.0.1:{fc_port}")])
        .args(["--autonomy", &format!("udpin:127.0.0.1:{autonomy_port}")])
        .args(["--autonomy-peer", &format!("127.0.0.1:{program}")])
        .args(["--sign-key", &key, "--require-signed", "--duration", "12"])
        .arg("--events")
        .arg(&cc_events)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let mut autonomy = Command::new(&py)
        .arg(repo().join("interop/autonomy.py"))
        .arg(format!("udpout:127.0.0.1:{autonomy_port}"))
        .args(["--seconds", "10", "--chan1", "1234"])
        .args(["--source-port", &program.to_string()])
        .args(["--attitude-hz", "40"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The FC's timeline starts once the autonomy is up: the companion
    // learns its address from its first heartbeat, and notices sent before
    // that reach nobody (a loaded machine took over 2 s to start Python,
    // and the takeover notice went by).
    let stdout = std::io::BufReader::new(autonomy.stdout.take().unwrap());
    let (up_tx, up_rx) = std::sync::mpsc::channel();
    let reader = std::thread::spawn(move || {
        let mut lines = Vec::new();
        for line in std::io::BufRead::lines(stdout).map_while(Result::ok) {
            if line == "autonomy: up" {
                let _ = up_tx.send(());
            }
            lines.push(line);
        }
        lines.join("\n")
    });
    up_rx
        .recv_timeout(Duration::from_secs(30))
        .expect("the autonomy program did not start within 30 s");
    std::thread::sleep(Duration::from_millis(200));
    // The FC: receiver lost at 2 s, back at 5 s.
    let fc = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["fc-sim", "--link", &format!("udpout:127.0.0.1:{fc_port}")])
        .args(["--sign-key", &key, "--require-signed"])
        .args(["--rc-loss-at", "2", "--rc-back-at", "5", "--duration", "7"])
        .arg("--events")
        .arg(&fc_events)
        .output()
        .unwrap();
    let autonomy = autonomy.wait_with_output().unwrap();
    let autonomy_stdout = reader.join().unwrap();
    // The daemon ends on its own (its summary is written at exit); killed
    // only if it overstays.
    for _ in 0..50 {
        if cc.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let _ = cc.kill();
    let cc = cc.wait_with_output().unwrap();
    let report = format!(
        "--- fc-sim\n{}\n--- cc\n{}\n--- autonomy\n{}{}",
        String::from_utf8_lossy(&fc.stdout),
        String::from_utf8_lossy(&cc.stdout),
        autonomy_stdout,
        String::from_utf8_lossy(&autonomy.stderr)
    );
    assert!(fc.status.success(), "{report}");
    let fc_events = events(&fc_events);
    // Companion control happened, and ended with the pilot.
    let modes: Vec<&str> = fc_events
        .iter()
        .filter(|e| e["event"] == "mode")
        .map(|e| e["mode"].as_str().unwrap())
        .collect();
    assert_eq!(modes, ["FBWA", "CIRCLE", "FBWAG", "FBWA"], "{report}");
    // Every control applied came from the autonomy (its CHAN1) through the
    // companion (its ids, signed), inside companion control.
    let mut mode = "FBWA";
    let mut applied = 0;
    for e in &fc_events {
        match e["event"].as_str().unwrap() {
            "mode" => mode = e["mode"].as_str().unwrap(),
            "control_applied" => {
                applied += 1;
                assert_eq!(
                    mode, "FBWAG",
                    "applied outside companion control: {e}\n{report}"
                );
                assert_eq!(
                    (e["sysid"].as_u64(), e["compid"].as_u64()),
                    (Some(1), Some(191))
                );
                assert_eq!(e["authenticated"], true, "{e}");
                assert_eq!(e["channels"][0], 1234, "the autonomy's own control: {e}");
            }
            _ => {}
        }
    }
    assert!(
        applied > 20,
        "the autonomy flew for 3 s at 20 Hz: {applied}\n{report}"
    );
    // The companion dropped the autonomy's control before the takeover and
    // after the hand-back (2 s and 2 s at 20 Hz).
    assert!(cc.status.success(), "{report}");
    let s = events(&cc_events)
        .into_iter()
        .find(|e| e["event"] == "summary")
        .expect("the companion's summary");
    assert!(
        s["controls_dropped"].as_u64().unwrap() > 40,
        "{s}\n{report}"
    );
    assert!(s["controls_forwarded"].as_u64().unwrap() > 20, "{s}");
    // The autonomy saw its FC's mode and the takeover notices.
    let result: Value =
        serde_json::from_str(autonomy_stdout.lines().last().unwrap_or("{}")).unwrap();
    let seen: Vec<u64> = result["modes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m.as_u64().unwrap())
        .collect();
    assert!(
        seen.contains(&30),
        "the autonomy saw FBWAG: {seen:?}\n{report}"
    );
    let notices = result["notices"].as_array().unwrap();
    assert!(
        notices
            .iter()
            .any(|n| n[0] == 1 && n[1] == 191 && n[2] == 2),
        "the autonomy saw the companion take over: {notices:?}"
    );
    // It asked for ATTITUDE at 40 Hz (10 by default): the companion signed
    // the request on to the FC, which sent it so.
    let hz = result["attitude_hz"].as_f64().unwrap_or(0.0);
    assert!(hz >= 30.0, "ATTITUDE at {hz} Hz\n{report}");
    let _ = std::fs::remove_dir_all(&dir);
}
