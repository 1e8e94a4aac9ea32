//! Running the real `fbwag cc` / `fbwag fc-sim` as processes and reading
//! what they report (`--events` JSON lines, the log on stdout).
//!
//! Every process is owned by a [`Daemon`] guard that kills it (by its pid,
//! through `Child::kill`) when dropped, also when a test panics: a failing
//! test leaves nothing running.
#![allow(dead_code)]

use serde_json::Value;
use std::fs;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

/// The signing key of the tests (any 32 bytes; the attacker never has it).
pub const KEY: &str = "5a1f0c3d9e8b7a6f5e4d3c2b1a0f9e8d7c6b5a49382716051f2e3d4c5b6a7988";

/// A free UDP port on 127.0.0.1 (bound by the system, then released).
pub fn free_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.local_addr())
        .expect("bind 127.0.0.1:0")
        .port()
}

/// `127.0.0.1:port`.
pub fn local(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

/// A fresh directory for one test's files, under cargo's target tmpdir.
pub fn scratch(name: &str) -> PathBuf {
    static N: AtomicU32 = AtomicU32::new(0);
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!(
        "adversarial-{name}-{}-{}",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed)
    ));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).expect("scratch dir");
    dir
}

/// One `fbwag` process with its events file and its log; killed on drop.
pub struct Daemon {
    pub name: String,
    child: Option<Child>,
    pub events: PathBuf,
    pub log: PathBuf,
    started: Instant,
    /// Its stdout, held open and never read ([`Daemon::spawn_unread`]).
    unread: Option<std::process::ChildStdout>,
}

/// A daemon that has exited: its status and everything it reported.
pub struct Finished {
    pub name: String,
    pub status: ExitStatus,
    pub events: Events,
    pub log: String,
}

impl Daemon {
    /// Starts `fbwag <args> --events <dir>/<name>.events`, stdout and
    /// stderr to `<dir>/<name>.log`.
    pub fn spawn(dir: &Path, name: &str, args: &[String]) -> Daemon {
        Self::spawn_with(Command::new(env!("CARGO_BIN_EXE_fbwag")), dir, name, args)
    }

    /// [`spawn`](Self::spawn) with at most `files` file descriptors open
    /// (`ulimit -n`).
    pub fn spawn_with_file_limit(dir: &Path, name: &str, args: &[String], files: u32) -> Daemon {
        let mut sh = Command::new("sh");
        sh.arg("-c")
            .arg(format!("ulimit -n {files} && exec \"$0\" \"$@\""))
            .arg(env!("CARGO_BIN_EXE_fbwag"));
        Self::spawn_with(sh, dir, name, args)
    }

    /// Starts `fbwag <args> --events -`: its log and its events go to a
    /// pipe that nothing reads (a stalled reader: the pipe fills, then
    /// every write to it blocks); stderr to `<dir>/<name>.log`. No events
    /// can be read from it.
    pub fn spawn_unread(dir: &Path, name: &str, args: &[String]) -> Daemon {
        let log = dir.join(format!("{name}.log"));
        let err = fs::File::create(&log).expect("log file");
        let mut child = Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(args)
            .args(["--events", "-"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(err)
            .spawn()
            .unwrap_or_else(|e| panic!("spawn {name}: {e}"));
        Daemon {
            name: name.into(),
            unread: child.stdout.take(),
            child: Some(child),
            events: dir.join(format!("{name}.events")),
            log,
            started: Instant::now(),
        }
    }

    /// [`spawn`](Self::spawn) with these environment variables set (a
    /// faked clock, for one).
    pub fn spawn_with_env(dir: &Path, name: &str, args: &[String], env: &[(&str, &str)]) -> Daemon {
        let mut command = Command::new(env!("CARGO_BIN_EXE_fbwag"));
        command.envs(env.iter().copied());
        Self::spawn_with(command, dir, name, args)
    }

    /// Starts `fbwag <args>` without `--events` (for a program that takes
    /// none), stdout and stderr to `<dir>/<name>.log`; its events stay empty.
    pub fn spawn_without_events(dir: &Path, name: &str, args: &[String]) -> Daemon {
        let log = dir.join(format!("{name}.log"));
        let out = fs::File::create(&log).expect("log file");
        let err = out.try_clone().expect("log file");
        let child = Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(args)
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(err)
            .spawn()
            .unwrap_or_else(|e| panic!("spawn {name}: {e}"));
        Daemon {
            name: name.into(),
            child: Some(child),
            events: dir.join(format!("{name}.events")),
            log,
            started: Instant::now(),
            unread: None,
        }
    }

    fn spawn_with(mut command: Command, dir: &Path, name: &str, args: &[String]) -> Daemon {
        let events = dir.join(format!("{name}.events"));
        let log = dir.join(format!("{name}.log"));
        let out = fs::File::create(&log).expect("log file");
        let err = out.try_clone().expect("log file");
        let child = command
            .args(args)
            .arg("--events")
            .arg(&events)
            .stdin(Stdio::null())
            .stdout(out)
            .stderr(err)
            .spawn()
            .unwrap_or_else(|e| panic!("spawn {name}: {e}"));
        Daemon {
            name: name.into(),
            child: Some(child),
            events,
            log,
            started: Instant::now(),
            unread: None,
        }
    }

    pub fn pid(&self) -> u32 {
        self.child.as_ref().map_or(0, Child::id)
    }

    /// True while the process runs.
    pub fn alive(&mut self) -> bool {
        self.child
            .as_mut()
            .is_some_and(|c| matches!(c.try_wait(), Ok(None)))
    }

    /// The events written so far.
    pub fn events_now(&self) -> Events {
        Events::read(&self.events)
    }

    /// Waits until an event satisfies `pred` (polling the file), up to
    /// `limit`; panics with the log otherwise. Used to sequence a test (a
    /// restart after the handover), never to judge it.
    pub fn wait_for(&self, what: &str, limit: Duration, pred: impl Fn(&Value) -> bool) -> Value {
        let until = Instant::now() + limit;
        loop {
            if let Some(e) = self.events_now().0.into_iter().find(|e| pred(e)) {
                return e;
            }
            assert!(
                Instant::now() < until,
                "{}: no {what} within {limit:?}\n{}",
                self.name,
                fs::read_to_string(&self.log).unwrap_or_default()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Kills the process now (a crash, a reboot) and reaps it.
    pub fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }

    /// Waits for the process to end on its own (its `--duration`), at most
    /// `limit` after it started; kills it and panics if it overruns.
    pub fn finish(mut self, limit: Duration) -> Finished {
        let mut child = self.child.take().expect("running");
        let status = loop {
            if let Some(s) = child.try_wait().expect("try_wait") {
                break s;
            }
            if self.started.elapsed() > limit {
                let _ = child.kill();
                let _ = child.wait();
                panic!(
                    "{} still running after {limit:?}\n{}",
                    self.name,
                    fs::read_to_string(&self.log).unwrap_or_default()
                );
            }
            std::thread::sleep(Duration::from_millis(20));
        };
        Finished {
            name: self.name.clone(),
            status,
            events: Events::read(&self.events),
            log: fs::read_to_string(&self.log).unwrap_or_default(),
        }
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        self.kill();
    }
}

impl Finished {
    /// Everything it said, for assertion messages.
    pub fn dump(&self) -> String {
        format!(
            "--- {} ({})\n{}--- events\n{}",
            self.name,
            self.status,
            self.log,
            self.events
                .0
                .iter()
                .map(|e| e.to_string() + "\n")
                .collect::<String>()
        )
    }

    /// Exited with status 0 after its whole `--duration` and wrote its
    /// summary: nothing ended it early.
    pub fn assert_ran_to_the_end(&self, duration_s: f64) {
        assert!(
            self.status.success(),
            "{} failed\n{}",
            self.name,
            self.dump()
        );
        let summary = self
            .events
            .last("summary")
            .unwrap_or_else(|| panic!("{}: no summary event\n{}", self.name, self.dump()));
        let t = summary["t_ms"].as_u64().unwrap_or(0);
        assert!(
            t as f64 >= duration_s * 1000.0 - 1.0,
            "{} stopped at {t} ms, before its --duration {duration_s} s\n{}",
            self.name,
            self.dump()
        );
    }

    /// What its links' parsers refused, of `kind` ("bad checksums", "bad
    /// signatures", "stale signing timestamps", "unsigned refused",
    /// "bytes dropped"), over all its links: the totals of its last status
    /// event (written at exit). Proof that an attack reached the parser.
    pub fn refused(&self, kind: &str) -> u64 {
        let key = match kind {
            "bad checksums" => "bad_checksum",
            "bad signatures" => "bad_signature",
            "stale signing timestamps" => "stale_timestamp",
            "unsigned refused" => "unsigned",
            "bytes dropped" => "bytes_dropped",
            other => panic!("no such refusal: {other}"),
        };
        let Some(status) = self.events.last("status") else {
            return 0;
        };
        status["links"].as_object().map_or(0, |links| {
            links
                .values()
                .filter_map(|l| l["refused"][key].as_u64())
                .sum()
        })
    }

    /// The FC simulator's event ids of its RC-loss notices (from its log).
    pub fn notice_events(&self) -> Vec<u64> {
        let mut ids: Vec<u64> = self
            .log
            .lines()
            .filter_map(|l| l.split_once("-> FBWAG_NOTICE status 1 event "))
            .filter_map(|(_, id)| id.trim().parse().ok())
            .collect();
        ids.dedup();
        ids
    }
}

/// A daemon's `--events` lines, in order.
#[derive(Debug, Clone, Default)]
pub struct Events(pub Vec<Value>);

impl Events {
    pub fn read(path: &Path) -> Events {
        let text = fs::read_to_string(path).unwrap_or_default();
        // A line being written when read (a live poll) is skipped.
        Events(
            text.lines()
                .filter_map(|l| serde_json::from_str(l).ok())
                .collect(),
        )
    }

    pub fn of<'a>(&'a self, event: &'a str) -> impl Iterator<Item = &'a Value> + 'a {
        self.0.iter().filter(move |e| e["event"] == event)
    }

    pub fn last(&self, event: &str) -> Option<&Value> {
        self.0.iter().rev().find(|e| e["event"] == event)
    }

    /// The FC's modes in order ("FBWA", "CIRCLE", "FBWAG", "RTL").
    pub fn modes(&self) -> Vec<String> {
        self.of("mode")
            .filter_map(|e| e["mode"].as_str().map(String::from))
            .collect()
    }

    /// The companion's control starts: the FC event ids it took over for.
    pub fn control_starts(&self) -> Vec<u64> {
        self.of("control")
            .filter(|e| e["state"] == "start")
            .filter_map(|e| e["fc_event"].as_u64())
            .collect()
    }

    pub fn summary(&self, key: &str) -> u64 {
        self.last("summary")
            .and_then(|s| s[key].as_u64())
            .unwrap_or_else(|| panic!("no summary {key} in {:?}", self.0))
    }

    /// Events after the first one satisfying `pred`.
    pub fn after(&self, pred: impl Fn(&Value) -> bool) -> Events {
        Events(
            self.0
                .iter()
                .skip_while(|e| !pred(e))
                .skip(1)
                .cloned()
                .collect(),
        )
    }
}

/// The UDP ports process `pid` has bound (from /proc: the socket inodes of
/// its file descriptors, looked up in /proc/net/udp). An `udpout` daemon's
/// ephemeral port is found this way.
pub fn udp_ports_of(pid: u32) -> Vec<u16> {
    let Ok(fds) = fs::read_dir(format!("/proc/{pid}/fd")) else {
        return Vec::new();
    };
    let inodes: Vec<String> = fds
        .filter_map(|fd| fs::read_link(fd.ok()?.path()).ok())
        .filter_map(|l| {
            let l = l.to_string_lossy().into_owned();
            Some(l.strip_prefix("socket:[")?.strip_suffix(']')?.to_string())
        })
        .collect();
    let table = fs::read_to_string("/proc/net/udp").unwrap_or_default();
    table
        .lines()
        .skip(1)
        .filter_map(|line| {
            let cols: Vec<&str> = line.split_whitespace().collect();
            let port = cols.get(1)?.rsplit(':').next()?;
            let inode = cols.get(9)?;
            inodes
                .iter()
                .any(|i| i == inode)
                .then(|| u16::from_str_radix(port, 16).ok())?
        })
        .collect()
}

/// Waits for `pid` to bind its UDP port (up to 5 s) and returns it.
pub fn udp_port_of(pid: u32) -> u16 {
    let until = Instant::now() + Duration::from_secs(5);
    loop {
        if let Some(&p) = udp_ports_of(pid).first() {
            return p;
        }
        assert!(Instant::now() < until, "process {pid} bound no UDP port");
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Arguments as owned strings.
pub fn args(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}
