//! Every numeric argument of every subcommand refuses NaN, infinities,
//! negative and out-of-range values while the command line is parsed: exit
//! status 2 and a message naming the argument, never a panic (exit 101), a
//! silent run with a meaningless value, or a run that never ends.
//!
//! Each run has a deadline and is killed past it: a value that slipped
//! through would start a daemon or a simulation. The deadline is a guard,
//! not a measurement: a refused value exits at once.

use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const DEADLINE: Duration = Duration::from_secs(20);
const KEY: &str = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";

/// (the command before the argument, the argument, values to refuse)
type Case = (
    &'static [&'static str],
    &'static str,
    &'static [&'static str],
);

const SECONDS_BAD: &[&str] = &[
    "NaN", "inf", "-inf", "-1", "-0.001", "1e300", "1000001", "x",
];
const SHARE_BAD: &[&str] = &["NaN", "inf", "-0.1", "1.01", "-1"];
const ID_BAD: &[&str] = &["0", "-1", "256"];

const CC: &[&str] = &["cc", "--link", "udpin:127.0.0.1:0"];
const FC: &[&str] = &["fc-sim", "--link", "udpout:127.0.0.1:9"];
const DEMO: &[&str] = &["demo"];
const SIM: &[&str] = &["sim", "--scenario", "normal-rc"];
const ENCODE: &[&str] = &["encode", "--sign-key", KEY];

const CASES: &[Case] = &[
    (
        CC,
        "--rate",
        &["NaN", "inf", "-inf", "-1", "0", "0.5", "101", "1e300"],
    ),
    (CC, "--duration", SECONDS_BAD),
    (CC, "--throttle", &["0", "-1", "799", "2201", "65535"]),
    (CC, "--sysid", ID_BAD),
    (CC, "--compid", ID_BAD),
    (CC, "--fc-sysid", ID_BAD),
    (CC, "--fc-compid", ID_BAD),
    (
        CC,
        "--routed-rate",
        &["0", "-1", "59", "100000001", "NaN", "inf", "1.5", "of"],
    ),
    (
        CC,
        "--sign-key",
        &[
            "abc",
            "0g0102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f",
        ],
    ),
    (FC, "--rc-loss-at", SECONDS_BAD),
    (FC, "--rc-back-at", SECONDS_BAD),
    (FC, "--duration", SECONDS_BAD),
    (FC, "--cc-sysid", ID_BAD),
    (FC, "--cc-compid", ID_BAD),
    (FC, "--sysid", ID_BAD),
    (FC, "--compid", ID_BAD),
    (DEMO, "--loss", SHARE_BAD),
    (DEMO, "--lost-for", SECONDS_BAD),
    (DEMO, "--back-for", SECONDS_BAD),
    (DEMO, "--cycles", &["0", "-1", "1001", "x"]),
    (SIM, "--loss", SHARE_BAD),
    (SIM, "--burst", &["NaN", "inf", "-1", "0", "0.5", "1e7"]),
    (SIM, "--trials", &["0", "-1", "1000001", "4294967295"]),
    // Trial k runs seed + k: this seed overflowed (a panic) with 2 trials.
    (SIM, "--seed", &["18446744073709551615", "-1"]),
    // A timestamp past 48 bits was cut silently; u64::MAX overflowed (a
    // panic) at the first frame signed.
    (
        ENCODE,
        "--sign-timestamp",
        &["281474976710656", "18446744073709551615", "-1"],
    ),
];

/// Waits for `child` until the deadline; `None` if it had to be killed.
fn wait_bounded(mut child: Child, started: Instant) -> Option<std::process::Output> {
    loop {
        if child.try_wait().expect("wait").is_some() {
            return Some(child.wait_with_output().expect("output"));
        }
        if started.elapsed() > DEADLINE {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn every_bad_numeric_argument_is_refused_at_parse_time() {
    let runs: Vec<(String, String, Child)> = CASES
        .iter()
        .flat_map(|(before, arg, values)| values.iter().map(move |v| (*before, *arg, *v)))
        .flat_map(|(before, arg, value)| {
            // `--arg value` and `--arg=value` must both reach the validator
            // (clap takes a bare `-1` for a flag unless told otherwise).
            [
                vec![arg.to_string(), value.to_string()],
                vec![format!("{arg}={value}")],
            ]
            .map(|form| (before, arg, form))
        })
        .map(|(before, arg, form)| {
            let mut cmd = Command::new(env!("CARGO_BIN_EXE_fbwag"));
            cmd.args(before).args(&form);
            if before == SIM {
                cmd.args(["--trials", "2"]);
            }
            let child = cmd
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .expect("run fbwag");
            (
                format!("{} {}", before.join(" "), form.join(" ")),
                format!("'{arg} <"),
                child,
            )
        })
        .collect();
    // All at once, so a regression costs one deadline, not one per value.
    let started = Instant::now();
    let mut failures = Vec::new();
    for (what, arg, child) in runs {
        let Some(out) = wait_bounded(child, started) else {
            failures.push(format!("{what}: still running after {DEADLINE:?}"));
            continue;
        };
        let err = String::from_utf8_lossy(&out.stderr);
        let refused = out.status.code() == Some(2)
            && err.contains("error: invalid value")
            && err.contains(&arg);
        if !refused {
            failures.push(format!(
                "{what}: exit {:?}: {}",
                out.status.code(),
                err.trim()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "not refused at parse time:\n{}",
        failures.join("\n")
    );
}

#[test]
fn values_at_the_bounds_are_accepted() {
    for args in [
        &[
            "sim",
            "--scenario",
            "normal-rc",
            "--trials",
            "1",
            "--loss",
            "1",
            "--burst",
            "1",
        ][..],
        &[
            "sim",
            "--scenario",
            "normal-rc",
            "--trials",
            "1",
            "--seed",
            "18446744073708551615",
        ],
        &[
            "demo",
            "--cycles",
            "1",
            "--lost-for",
            "0",
            "--back-for",
            "0",
            "--loss",
            "0",
        ],
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(args)
            .stdin(Stdio::null())
            .output()
            .expect("run fbwag");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !err.contains("invalid value") && out.status.code() != Some(101),
            "{args:?}: {err}"
        );
    }
}

/// A signing state file that cannot be written stops `cc` and `fc-sim` at
/// start, naming it: each save would fail, and a restart would begin from
/// the clock, open to replays (it failed silently at every save).
#[test]
fn a_signing_state_file_that_cannot_be_written_is_refused_at_start() {
    let dir = std::env::temp_dir().join(format!("fbwag-state-{}", std::process::id()));
    let path = dir.join("no-such-dir").join("state");
    let path = path.to_str().unwrap();
    for daemon in [CC, FC] {
        let started = Instant::now();
        let child = Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(daemon)
            .args([
                "--sign-key",
                KEY,
                "--signing-state",
                path,
                "--duration",
                "5",
            ])
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let out = wait_bounded(child, started).expect("still running");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{daemon:?} ran");
        assert!(
            err.contains(path) && err.contains("cannot be written"),
            "{daemon:?}: {err}"
        );
    }
}

/// `--events` naming a FIFO nobody reads yet: the daemon starts and runs
/// its whole time (opening a FIFO for writing waits for a reader, and it
/// was opened before anything else: the daemon hung there, links never
/// opened); a reader that comes later reads its events. With no reader
/// ever, the events are lost: said, and the run exits 2.
#[cfg(unix)]
#[test]
fn events_to_a_fifo_without_a_reader_never_hold_a_daemon() {
    use std::io::Read;
    let dir = std::env::temp_dir().join(format!("fbwag-fifo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let started = Instant::now();
    // The three side by side: a CC and a FC nobody reads, a FC read late.
    let runs: Vec<_> = [(CC, false), (FC, false), (FC, true)]
        .into_iter()
        .enumerate()
        .map(|(i, (daemon, read_later))| {
            let fifo = dir.join(format!("events-{i}"));
            let _ = std::fs::remove_file(&fifo);
            let made = Command::new("mkfifo").arg(&fifo).status().expect("mkfifo");
            assert!(made.success());
            let child = Command::new(env!("CARGO_BIN_EXE_fbwag"))
                .args(daemon)
                .args(["--duration", "1.5", "--events"])
                .arg(&fifo)
                .stdin(Stdio::null())
                .stdout(Stdio::piped())
                .stderr(Stdio::piped())
                .spawn()
                .unwrap();
            let reader = read_later.then(|| {
                std::thread::spawn(move || {
                    std::thread::sleep(Duration::from_millis(500));
                    let mut text = String::new();
                    std::fs::File::open(fifo)
                        .unwrap()
                        .read_to_string(&mut text)
                        .unwrap();
                    text
                })
            });
            (daemon, child, reader)
        })
        .collect();
    for (daemon, child, reader) in runs {
        let out = wait_bounded(child, started).expect("the daemon hung");
        let log = String::from_utf8_lossy(&out.stdout);
        let err = String::from_utf8_lossy(&out.stderr);
        let read = reader.is_some();
        assert_eq!(
            out.status.code(),
            Some(if read { 0 } else { 2 }),
            "{daemon:?}: {log}{err}"
        );
        assert_eq!(
            err.contains("no reader opened it"),
            !read,
            "{daemon:?}: {err}"
        );
        assert!(
            started.elapsed() >= Duration::from_millis(1500) && log.contains("127.0.0.1"),
            "{daemon:?} did not run: {log}"
        );
        if let Some(reader) = reader {
            let text = reader.join().unwrap();
            assert!(
                text.contains("\"event\":\"summary\""),
                "events read: {text}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Arguments refused after parsing (connection strings, receiver failures
/// that do not pair up, unknown scenarios, unreadable input) exit with
/// status 2 and an `error:` line naming what was refused; work done on
/// input with problems exits with 1; `fbwag --help` lists the statuses.
#[test]
fn refusals_after_parsing_exit_2_and_flagged_input_exits_1() {
    const NO_RUN: &[&str] = &["--duration", "1"];
    let cases: &[(&[&str], &str, i32, &str)] = &[
        (
            &["cc", "--link", "bogus"],
            "",
            2,
            "invalid value 'bogus' for '--link <CONN>'",
        ),
        (
            &["cc", "--link", "udpin:127.0.0.1:0", "--out", "nope"],
            "",
            2,
            "invalid value 'nope' for '--out <CONN>'",
        ),
        (
            &["cc", "--link", "udpin:127.0.0.1:0", "--autonomy", "x:1"],
            "",
            2,
            "invalid value 'x:1' for '--autonomy <CONN>'",
        ),
        (&["fc-sim", "--link", "udp"], "", 2, "error: --link: "),
        (
            &["cc", "--link", "fc=serial:/dev/ttyAMA0"],
            "",
            2,
            "serial:/dev/ttyAMA0 gives no baud rate: add the rate",
        ),
        (
            &["router", "udpin:127.0.0.1:0", "serial:/dev/ttyUSB0"],
            "",
            2,
            "e.g. serial:/dev/ttyUSB0:921600",
        ),
        (
            &[
                "fc-sim",
                "--link",
                "udpout:127.0.0.1:9",
                "--rc-back-at",
                "3",
            ],
            "",
            2,
            "error: 0 --rc-loss-at and 1 --rc-back-at",
        ),
        (
            &["router", "udpin:127.0.0.1:0", "nope"],
            "",
            2,
            "invalid value 'nope' for '<CONN>...'",
        ),
        (
            &["sim", "--scenario", "nope"],
            "",
            2,
            "unknown scenario `nope`",
        ),
        (&["sim"], "", 2, "error: say what to run"),
        (
            &["decode", "--hex"],
            "0z",
            2,
            "error: byte 0x7a is not a hex digit",
        ),
        (
            &["decode", "--hex"],
            "fd0",
            2,
            "error: odd number of hex digits (3)",
        ),
        (
            &["decode", "/nonexistent/fbwag"],
            "",
            2,
            "error: cannot open /nonexistent/fbwag: No such file",
        ),
        (&["decode", "--hex"], "00ff", 1, "2 bytes dropped"),
        (&["encode"], "{}\n", 1, "line 1: "),
    ];
    for (args, stdin, code, says) in cases {
        let daemon = matches!(args[0], "cc" | "fc-sim" | "router");
        let mut child = Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(*args)
            .args(if daemon { NO_RUN } else { &[] })
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("run fbwag");
        use std::io::Write;
        let mut input = child.stdin.take().unwrap();
        input.write_all(stdin.as_bytes()).unwrap();
        drop(input);
        let out = wait_bounded(child, Instant::now()).expect("still running");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.code() == Some(*code) && err.contains(says),
            "{args:?}: exit {:?}, expected {code} and `{says}`: {err}",
            out.status.code()
        );
    }
    let help = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .arg("--help")
        .output()
        .expect("run fbwag");
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        ["Exit status:", "\n  0  ", "\n  1  ", "\n  2  "]
            .iter()
            .all(|s| help.contains(s)),
        "{help}"
    );
}
