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
/// status 130 and no summary.) The companion hears an FC first: without
/// one, its run ends with status 1.
#[test]
fn sigint_stops_every_daemon_as_its_end_does() {
    let dir = scratch("sigint");
    let cc_port = free_port();
    let fc_args = args(&["fc-sim", "--link", &format!("udpout:127.0.0.1:{cc_port}")]);
    for (name, program) in [
        (
            "cc",
            args(&["cc", "--link", &format!("udpin:127.0.0.1:{cc_port}")]),
        ),
        ("fc", fc_args.clone()),
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
        let _fc = (name == "cc").then(|| {
            let fc = Daemon::spawn(
                &dir,
                "fc-of-cc",
                &[fc_args.clone(), args(&["--duration", "60"])].concat(),
            );
            wait_for_log(&daemon, "FC found");
            fc
        });
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

/// The status event of `f` last written: its `links` object.
fn last_links(f: &Finished) -> serde_json::Value {
    let status = f.events.last("status");
    let status = status.unwrap_or_else(|| panic!("{}: no status event\n{}", f.name, f.dump()));
    status["links"].clone()
}

/// A wrong key on one side: both sides' status events count bad
/// signatures on their link within one report period, and the companion,
/// which never heard its FC, exits with status 1 and a line naming the
/// link. (The summaries showed every count at 0, and `fbwag cc` exited 0
/// as if idle.)
#[test]
fn a_wrong_key_shows_as_bad_signatures_on_both_sides() {
    let dir = scratch("wrong-key");
    let port = free_port();
    let other = "11".repeat(32);
    let fc = Daemon::spawn(
        &dir,
        "fc",
        &args(&[
            "fc-sim",
            "--link",
            &format!("cc=udpin:127.0.0.1:{port}"),
            "--sign-key",
            KEY,
            "--require-signed",
            "--report",
            "1",
            "--duration",
            "2.5",
        ]),
    );
    let cc = Daemon::spawn(
        &dir,
        "cc",
        &args(&[
            "cc",
            "--link",
            &format!("fc=udpout:127.0.0.1:{port}"),
            "--sign-key",
            &other,
            "--require-signed",
            "--report",
            "1",
            "--duration",
            "2.5",
        ]),
    );
    let (fc, cc) = (
        fc.finish(Duration::from_secs(20)),
        cc.finish(Duration::from_secs(20)),
    );
    let all = format!("{}\n{}", fc.dump(), cc.dump());
    for (f, name) in [(&fc, "cc"), (&cc, "fc")] {
        let link = &last_links(f)[name];
        let bad = link["refused"]["bad_signature"].as_u64().unwrap_or(0);
        assert!(bad >= 1, "{}: {link}\n{all}", f.name);
        let first = f.events.of("status").next().expect("a status");
        assert!(
            first["t_ms"].as_u64().unwrap_or(u64::MAX) <= 1500,
            "{first}"
        );
    }
    assert_eq!(cc.status.code(), Some(1), "{all}");
    assert!(
        cc.log
            .contains("ERROR  cc: the FC (1/1) was never heard on its link fc"),
        "{all}"
    );
    assert_eq!(
        cc.events.last("status").unwrap()["fc"],
        "never heard",
        "{all}"
    );
}

/// Ground-side links that cannot open (a host name that does not
/// resolve, a port another program holds) leave the companion running:
/// each is said once, retried every second (its name resolved again),
/// said again when it opens, and the handover on the FC link goes on.
/// (An --out whose name did not resolve stopped `fbwag cc` at start with
/// status 2: the companion never took over.)
#[test]
fn a_ground_link_that_cannot_open_never_stops_the_delegation() {
    let dir = scratch("ground-fault");
    let (port, held) = (
        free_port(),
        std::net::UdpSocket::bind("127.0.0.1:0").unwrap(),
    );
    let taken = held.local_addr().unwrap().port();
    let cc = Daemon::spawn(
        &dir,
        "cc",
        &args(&[
            "cc",
            "--link",
            &format!("udpin:127.0.0.1:{port}"),
            "--out",
            "gcs=udpout:no-such-host.invalid:14550",
            "--out",
            &format!("mavproxy=udpin:127.0.0.1:{taken}"),
            "--report",
            "1",
            "--duration",
            "4.5",
        ]),
    );
    let fc = Daemon::spawn(
        &dir,
        "fc",
        &args(&[
            "fc-sim",
            "--link",
            &format!("udpout:127.0.0.1:{port}"),
            "--rc-loss-at",
            "2",
            "--duration",
            "4",
        ]),
    );
    std::thread::sleep(Duration::from_millis(1500));
    drop(held);
    let (fc, cc) = (
        fc.finish(Duration::from_secs(20)),
        cc.finish(Duration::from_secs(20)),
    );
    let all = format!("{}\n{}", fc.dump(), cc.dump());
    assert!(cc.status.success(), "{all}");
    assert!(fc.events.of("handover").count() == 1, "{all}");
    let link_events = |name: &str| -> Vec<String> {
        cc.events
            .of("link")
            .filter(|e| e["link"] == name)
            .map(|e| e["state"].as_str().unwrap_or_default().to_string())
            .collect()
    };
    let gcs = link_events("gcs");
    assert_eq!(gcs.first().map(String::as_str), Some("failed"), "{all}");
    assert!(
        gcs.iter().skip(1).all(|s| s == "retrying"),
        "{gcs:?}\n{all}"
    );
    let mavproxy = link_events("mavproxy");
    assert_eq!(
        mavproxy.first().map(String::as_str),
        Some("failed"),
        "{all}"
    );
    assert!(
        mavproxy.contains(&"recovered".to_string()),
        "{mavproxy:?}\n{all}"
    );
    assert_eq!(
        cc.log.matches("link gcs failed").count(),
        1,
        "said once\n{all}"
    );
    assert!(cc.log.contains("link mavproxy open again"), "{all}");
    let links = last_links(&cc);
    assert_eq!(
        (
            links["gcs"]["up"].as_bool(),
            links["mavproxy"]["up"].as_bool()
        ),
        (Some(false), Some(true)),
        "{links}"
    );
}

/// `fbwag key new`: 64 hex digits, mode 600, never over an existing file;
/// a key file others may read is refused with the chmod that fixes it.
#[test]
fn a_new_key_is_the_owners_alone_and_never_overwritten() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scratch("key-new");
    let path = dir.join("key");
    let fbwag = |a: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(a)
            .output()
            .unwrap()
    };
    let made = fbwag(&["key", "new", &path.display().to_string()]);
    assert!(made.status.success(), "{made:?}");
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.trim().len() == 64 && text.trim().bytes().all(|b| b.is_ascii_hexdigit()));
    let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode, 0o600);
    let again = fbwag(&["key", "new", &path.display().to_string()]);
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("never overwritten"));
    assert_eq!(std::fs::read_to_string(&path).unwrap(), text, "kept");
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o640)).unwrap();
    let key = format!("@{}", path.display());
    let cc = fbwag(&[
        "cc",
        "--link",
        "udpout:127.0.0.1:9",
        "--sign-key",
        &key,
        "--duration",
        "0",
    ]);
    let err = String::from_utf8_lossy(&cc.stderr);
    assert_eq!(cc.status.code(), Some(2), "{err}");
    assert!(
        err.contains(&format!("(mode 640): chmod 600 {}", path.display())),
        "{err}"
    );
}

/// `fbwag key push` sets a disarmed FC's key with SETUP_SIGNING; from then
/// on the FC signs with it and counts only frames signed with it; an
/// armed FC refuses a new key, and `push` says so with status 1. The key
/// is kept next to the FC's signing state and taken again at its restart.
#[test]
fn key_push_sets_a_disarmed_fcs_key_and_an_armed_fc_refuses_it() {
    let dir = scratch("key-push");
    let state = dir.join("fc.state").display().to_string();
    let fc_at = |arm_at: &str, port: u16, extra: &[&str]| {
        let conn = format!("udpout:127.0.0.1:{port}");
        let a = [
            args(&[
                "fc-sim",
                "--link",
                &conn,
                "--arm-at",
                arm_at,
                "--duration",
                "6",
            ]),
            args(&["--signing-state", &state]),
            args(extra),
        ];
        Daemon::spawn(&dir, &format!("fc-{arm_at}-{port}"), &a.concat())
    };
    let push = |port: u16| {
        std::process::Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(["key", "push", "--link", &format!("udpin:127.0.0.1:{port}")])
            .args(["--sign-key", "passphrase:fbwag-bench", "--timeout", "4"])
            .output()
            .unwrap()
    };
    // Armed: refused.
    let port = free_port();
    let armed = fc_at("0", port, &[]);
    let out = push(port);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    drop(armed);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("signing: not while armed"), "{err}");
    // Disarmed: taken, on every link at once, and kept.
    let port = free_port();
    let disarmed = fc_at("100", port, &[]);
    let out = push(port);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    let done = disarmed.finish(Duration::from_secs(20));
    assert_eq!(out.status.code(), Some(0), "{err}\n{}", done.dump());
    assert!(err.contains("signs with the new key"), "{err}");
    assert!(
        done.log
            .contains("signing: on (SETUP_SIGNING from 255/190)"),
        "{}",
        done.dump()
    );
    assert!(std::path::Path::new(&format!("{state}.key")).exists());
    // Restarted without --sign-key: the kept key, signed frames only.
    let port = free_port();
    let listener = std::net::UdpSocket::bind(("127.0.0.1", port)).unwrap();
    listener
        .set_read_timeout(Some(Duration::from_secs(3)))
        .unwrap();
    let again = fc_at("100", port, &[]);
    let mut buf = [0u8; 512];
    let (n, _) = listener.recv_from(&mut buf).expect("the FC's first frame");
    drop(again);
    // MAVLink 2, the signed flag: the kept key signs.
    assert_eq!((buf[0], buf[2] & 1), (0xfd, 1), "{:?}", &buf[..n]);
}
