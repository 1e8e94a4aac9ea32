//! Interop with the real client library over UDP on 127.0.0.1: a pymavlink
//! 2.4.50 companion (the paper's Fig. 8 listener, written anew, on
//! pymavlink's own generated FBWAG dialect) drives `fbwag fc-sim` into
//! companion control and back; `fbwag cc` answers a pymavlink-scripted FC.

use std::process::{Command, Stdio};

mod common;

use common::{free_port, python, repo};

#[test]
fn pymavlink_companion_drives_fc_sim_into_companion_control_and_back() {
    let py = python();
    let port = free_port();
    let cc = Command::new(&py)
        .arg(repo().join("interop/cc_listener.py"))
        .arg(format!("udpin:127.0.0.1:{port}"))
        .args(["--seconds", "8"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("cc_listener.py");
    // Start the FC once the listener has bound (it says so): pymavlink's
    // imports take seconds on a loaded machine, and a notice sent before
    // is lost.
    let mut cc = cc;
    let mut cc_out = std::io::BufReader::new(cc.stdout.take().unwrap());
    let mut seen = String::new();
    while !seen.contains("Waiting for heartbeat") {
        use std::io::BufRead;
        if cc_out.read_line(&mut seen).unwrap_or(0) == 0 {
            panic!("cc_listener.py ended before binding:\n{seen}");
        }
    }
    let fc = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args([
            "fc-sim",
            "--link",
            &format!("udpout:127.0.0.1:{port}"),
            "--rc-loss-at",
            "1",
            "--rc-back-at",
            "4",
            "--duration",
            "6",
        ])
        .output()
        .expect("fbwag fc-sim");
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut cc_out, &mut rest).unwrap();
    let cc = cc.wait_with_output().unwrap();
    let fc_log = String::from_utf8_lossy(&fc.stdout);
    let cc_log = format!("{seen}{rest}");
    let both = format!(
        "--- fbwag fc-sim\n{fc_log}\n--- pymavlink companion\n{cc_log}{}",
        String::from_utf8_lossy(&cc.stderr)
    );
    assert!(fc.status.success(), "{both}");
    let order = [
        "MODE CHANGE -> CIRCLE",
        "MODE CHANGE -> FBWAG (companion control)",
        "MODE CHANGE -> FBWA (pilot in control)",
        "RC has taken over",
    ];
    let mut at = 0;
    for step in order {
        let found = fc_log[at..]
            .find(step)
            .unwrap_or_else(|| panic!("{step:?} missing or out of order\n{both}"));
        at += found;
    }
    assert!(!fc_log.contains("RTL"), "no fallback expected\n{both}");
    assert!(
        cc_log.contains("done: 1 takeover(s), 1 hand-back(s)"),
        "{both}"
    );
}

#[test]
fn fbwag_cc_answers_a_pymavlink_flight_controller() {
    let py = python();
    let port = free_port();
    let cc = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args([
            "cc",
            "--link",
            &format!("udpin:127.0.0.1:{port}"),
            "--duration",
            "12",
            "--exit-after-handback",
        ])
        .stdout(Stdio::piped())
        .spawn()
        .expect("fbwag cc");
    std::thread::sleep(std::time::Duration::from_millis(300));
    let fc = Command::new(&py)
        .arg(repo().join("interop/fc_script.py"))
        .arg(format!("udpout:127.0.0.1:{port}"))
        .output()
        .expect("fc_script.py");
    let cc = cc.wait_with_output().unwrap();
    let report = format!(
        "--- pymavlink FC\n{}{}\n--- fbwag cc\n{}",
        String::from_utf8_lossy(&fc.stdout),
        String::from_utf8_lossy(&fc.stderr),
        String::from_utf8_lossy(&cc.stdout)
    );
    assert!(fc.status.success(), "{report}");
    assert!(
        String::from_utf8_lossy(&fc.stdout).contains("0 check(s) failed"),
        "{report}"
    );
    assert!(cc.status.success(), "{report}");
}

#[test]
fn demo_hands_over_through_a_lossy_relay() {
    let run = || {
        let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(["demo", "--loss", "0.2", "--cycles", "2"])
            .args(["--lost-for", "3.5", "--back-for", "1", "--seed", "3"])
            .output()
            .expect("fbwag demo");
        let log = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(out.status.success(), "{log}");
        log
    };
    let log = run();
    assert!(
        log.contains("MODE CHANGE -> FBWA (pilot in control)"),
        "RC came back: {log}"
    );
    // Both failures handed over, and the summary says so.
    let summary = log
        .lines()
        .find(|l| l.starts_with("handovers (receiver failure → companion control): 2 of 2"))
        .unwrap_or_else(|| panic!("{log}"));
    assert!(
        summary.contains("p50") && summary.contains("max"),
        "{summary}"
    );
    // The same seed loses the same frames: the same handovers, up to
    // scheduling jitter (a lost frame costs a 1 s retry, far above it).
    let again = run();
    let seconds = |log: &str| -> Vec<u64> {
        log.lines()
            .filter_map(|l| l.split_once("handover ").map(|(_, r)| r))
            .filter_map(|r| r.split(' ').next()?.parse::<u64>().ok())
            .map(|ms| (ms + 500) / 1000)
            .collect()
    };
    assert_eq!(seconds(&log), seconds(&again), "{log}\n{again}");
}
