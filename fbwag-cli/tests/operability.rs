//! What an operator sees of the daemons and can do with them, against the
//! real `fbwag cc`, `fbwag fc-sim` and `fbwag router` on 127.0.0.1:
//! signals, logs, health events, keys, named links.

#[path = "common/live.rs"]
mod live;

use live::*;
use std::time::{Duration, Instant};

/// Waits until `daemon`'s log holds `text` (10 s at most).
fn wait_for_log(daemon: &Daemon, text: &str) {
    let until = Instant::now() + Duration::from_secs(10);
    while !std::fs::read_to_string(&daemon.log).is_ok_and(|l| l.contains(text)) {
        assert!(
            Instant::now() < until,
            "{}: no {text:?} in its log",
            daemon.name
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// SIGINT (Ctrl-C, `kill -INT`) stops each daemon as SIGTERM and the end
/// of its run do, with its standard input not a terminal: exit status 0,
/// the summary event written, the log's last lines out. (It ended with
/// status 130 and no summary.)
#[test]
fn sigint_stops_every_daemon_as_its_end_does() {
    let dir = scratch("sigint");
    for (name, program) in [
        (
            "cc",
            args(&["cc", "--link", &format!("udpin:127.0.0.1:{}", free_port())]),
        ),
        (
            "fc",
            args(&[
                "fc-sim",
                "--link",
                &format!("udpout:127.0.0.1:{}", free_port()),
            ]),
        ),
        (
            "router",
            args(&[
                "router",
                &format!("udpin:127.0.0.1:{}", free_port()),
                &format!("udpin:127.0.0.1:{}", free_port()),
            ]),
        ),
    ] {
        let daemon = Daemon::spawn(&dir, name, &[program, args(&["--duration", "60"])].concat());
        wait_for_log(&daemon, "INFO");
        let sent = std::process::Command::new("kill")
            .args(["-INT", &daemon.pid().to_string()])
            .status()
            .unwrap();
        assert!(sent.success());
        let done = daemon.finish(Duration::from_secs(10));
        assert!(done.status.success(), "{}", done.dump());
        assert!(done.log.contains("SIGINT: stopping"), "{}", done.dump());
        assert!(done.events.last("summary").is_some(), "{}", done.dump());
    }
}

/// Every log line carries its level: on a file, after the UTC time (RFC
/// 3339); when `JOURNAL_STREAM` names the output (systemd's service
/// output), as the journal's `<N>` priority. `--log-level` keeps the
/// lines at that level and above.
#[test]
fn log_lines_carry_their_level_for_a_terminal_and_for_the_journal() {
    use std::os::unix::fs::MetadataExt;
    let dir = scratch("log-levels");
    let run = |name: &str, level: &str, journal: bool| {
        let conn = format!("udpout:127.0.0.1:{}", free_port());
        let a = args(&[
            "fc-sim",
            "--link",
            &conn,
            "--duration",
            "0.3",
            "--log-level",
            level,
        ]);
        // The daemon's output is the log file: it is the stream named.
        let log = dir.join(format!("{name}.log"));
        std::fs::write(&log, b"").unwrap();
        let meta = std::fs::metadata(&log).unwrap();
        let stream = format!("{}:{}", meta.dev(), meta.ino());
        let env: Vec<(&str, &str)> = if journal {
            vec![("JOURNAL_STREAM", stream.as_str())]
        } else {
            vec![]
        };
        let done = Daemon::spawn_with_env(&dir, name, &a, &env).finish(Duration::from_secs(10));
        assert!(done.status.success(), "{}", done.dump());
        done.log
    };
    let stamped = run("stamped", "info", false);
    let first = stamped.lines().next().unwrap_or_default();
    let (time, rest) = first.split_once(' ').unwrap_or_default();
    assert!(time.len() == 27 && time.ends_with('Z'), "{stamped}");
    assert!(
        rest.starts_with("INFO   fc: ArduPlane simulator"),
        "{stamped}"
    );
    assert!(
        stamped.lines().any(|l| l.contains(" NOTICE fc: armed")),
        "{stamped}"
    );
    let journal = run("journal", "info", true);
    assert!(journal.lines().all(|l| l.starts_with('<')), "{journal}");
    assert!(journal.contains("<6>fc: ArduPlane simulator"), "{journal}");
    assert!(journal.contains("<5>fc: armed"), "{journal}");
    let quiet = run("quiet", "warn", true);
    assert!(!quiet.contains("<6>") && !quiet.contains("<5>"), "{quiet}");
}
