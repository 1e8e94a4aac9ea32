//! Ground stations nobody here wrote against `fbwag fc-sim`: MAVSDK's
//! mavsdk_server 3.17.4 and MAVProxy 1.8.75 (pinned, in target/peerenv,
//! made by scripts/peer-env.sh), on 127.0.0.1, with `fbwag cc` taking over
//! when the receiver fails.
//!
//! ```text
//! mavsdk:   fbwag fc-sim --udpout--> [hub] --> mavsdk_server (udpin) <-gRPC- interop/mavsdk_gcs_check.py
//!                                          \-> fbwag cc (udpin)
//! mavproxy: fbwag fc-sim --udpout--> MAVProxy --out--> fbwag cc (udpin)
//! ```
//!
//! The hub stands for a router (the FC's one link shared by a ground station
//! and the companion): every datagram of fc-sim goes to both, theirs go to
//! fc-sim.
//!
//! Each test starts its own processes and kills exactly those (on drop, even
//! when an assertion fails); every wait has a deadline. Without the peer
//! venv (no network for pip) the tests print why and pass without running.

use serde_json::Value;
use std::io::Write;
use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

mod common;

use common::lines::LineProc;
use common::{free_tcp_port, mavsdk_server, peer_python, repo};

/// Home of these runs (not fc-sim's default, to show --home is used).
const HOME: (f64, f64, f64) = (50.4501, 30.5234, 180.0);

/// The two chains run one at a time (two cores; mavsdk_server and MAVProxy
/// start slowly).
static SERIAL: Mutex<()> = Mutex::new(());

// --- processes -------------------------------------------------------------

fn free_udp_port() -> u16 {
    UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn fbwag() -> Command {
    Command::new(env!("CARGO_BIN_EXE_fbwag"))
}

fn home_arg() -> String {
    format!("{},{},{}", HOME.0, HOME.1, HOME.2)
}

// --- the hub -----------------------------------------------------------------

/// fc-sim's link shared by several parties: each of fc-sim's datagrams goes
/// to every party, each party's to fc-sim. Stops when dropped.
struct Hub {
    fc_port: u16,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl Hub {
    fn start(parties: &[SocketAddr]) -> Hub {
        let stop = Arc::new(AtomicBool::new(false));
        let fc_side = UdpSocket::bind("127.0.0.1:0").unwrap();
        let fc_port = fc_side.local_addr().unwrap().port();
        let fc_addr: Arc<Mutex<Option<SocketAddr>>> = Arc::default();
        let sides: Vec<(UdpSocket, SocketAddr)> = parties
            .iter()
            .map(|&p| (UdpSocket::bind("127.0.0.1:0").unwrap(), p))
            .collect();
        let mut threads = Vec::new();
        // fc-sim -> every party.
        {
            let fc_side = fc_side.try_clone().unwrap();
            let outs: Vec<(UdpSocket, SocketAddr)> = sides
                .iter()
                .map(|(s, p)| (s.try_clone().unwrap(), *p))
                .collect();
            let (stop, fc_addr) = (stop.clone(), fc_addr.clone());
            threads.push(thread::spawn(move || {
                relay(&fc_side, &stop, |bytes, from| {
                    *fc_addr.lock().unwrap() = Some(from);
                    for (s, p) in &outs {
                        // A party not listening yet: the datagram is lost,
                        // as on a radio link.
                        let _ = s.send_to(bytes, p);
                    }
                })
            }));
        }
        // Every party -> fc-sim.
        for (side, _) in sides {
            let to_fc = fc_side.try_clone().unwrap();
            let (stop, fc_addr) = (stop.clone(), fc_addr.clone());
            threads.push(thread::spawn(move || {
                relay(&side, &stop, |bytes, _| {
                    if let Some(fc) = *fc_addr.lock().unwrap() {
                        let _ = to_fc.send_to(bytes, fc);
                    }
                })
            }));
        }
        Hub {
            fc_port,
            stop,
            threads,
        }
    }
}

/// Receives on `socket` until `stop`, handing each datagram to `forward`.
fn relay(socket: &UdpSocket, stop: &AtomicBool, mut forward: impl FnMut(&[u8], SocketAddr)) {
    socket
        .set_read_timeout(Some(Duration::from_millis(50)))
        .unwrap();
    let mut buf = [0u8; 2048];
    while !stop.load(Ordering::Relaxed) {
        // Timeouts and ICMP "port unreachable" errors alike: try again.
        if let Ok((n, from)) = socket.recv_from(&mut buf) {
            forward(&buf[..n], from);
        }
    }
}

impl Drop for Hub {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

// --- what MAVSDK saw -----------------------------------------------------------

/// The JSON lines of interop/mavsdk_gcs_check.py.
struct Seen {
    lines: Vec<Value>,
}

/// One position sample.
struct Sample {
    t: f64,
    lat: f64,
    lon: f64,
    rel_alt: f64,
    heading: f64,
    custom_mode: Option<i64>,
}

impl Seen {
    fn parse(log: &str) -> Seen {
        let lines = log
            .lines()
            .filter_map(|l| serde_json::from_str::<Value>(l).ok())
            .filter(|v| v.get("what").is_some())
            .collect();
        Seen { lines }
    }

    fn of<'a>(&'a self, what: &'a str) -> impl Iterator<Item = &'a Value> + 'a {
        self.lines.iter().filter(move |v| v["what"] == what)
    }

    fn call(&self, name: &str) -> &Value {
        self.of("call")
            .find(|v| v["call"] == name)
            .unwrap_or_else(|| panic!("no result of {name}"))
    }

    /// The values of `what` lines in order, consecutive repeats dropped.
    fn changes(&self, what: &str, key: &str) -> Vec<(f64, Value)> {
        let mut out: Vec<(f64, Value)> = Vec::new();
        for v in self.of(what) {
            if out.last().is_none_or(|(_, last)| *last != v[key]) {
                out.push((v["t"].as_f64().unwrap(), v[key].clone()));
            }
        }
        out
    }

    fn samples(&self) -> Vec<Sample> {
        self.of("sample")
            .filter_map(|v| {
                Some(Sample {
                    t: v["t"].as_f64()?,
                    lat: v["lat"].as_f64()?,
                    lon: v["lon"].as_f64()?,
                    rel_alt: v["rel_alt"].as_f64()?,
                    heading: v["heading"].as_f64()?,
                    custom_mode: v["custom_mode"].as_i64(),
                })
            })
            .collect()
    }
}

/// Metres from home (flat earth: the runs stay within a few km).
fn distance_from_home(s: &Sample) -> f64 {
    let north = (s.lat - HOME.0).to_radians() * 6_371_000.0;
    let east = (s.lon - HOME.1).to_radians() * 6_371_000.0 * HOME.0.to_radians().cos();
    north.hypot(east)
}

/// Whether `items` appear in `seq` in this order (not necessarily adjacent).
fn in_order(seq: &[Value], items: &[Value]) -> bool {
    let mut it = seq.iter();
    items.iter().all(|want| it.any(|v| v == want))
}

/// Degrees turned (clockwise positive) from the first to the last heading.
fn turned(headings: &[f64]) -> f64 {
    headings
        .windows(2)
        .map(|w| (w[1] - w[0] + 540.0).rem_euclid(360.0) - 180.0)
        .sum()
}

// --- MAVSDK -----------------------------------------------------------------

/// fc-sim's schedule (seconds from its start): the receiver is lost at
/// RC_LOSS; the companion flies (its circle controller: a right turn) until
/// the test stops it COMPANION_FLIES seconds after the handover; the FC
/// falls back to RTL 1 s later; the receiver returns at RC_BACK.
const RC_LOSS: f64 = 10.0;
const COMPANION_FLIES: Duration = Duration::from_secs(10);
const RC_BACK: f64 = 42.0;
const RUN: f64 = 46.0;

struct MavsdkRun {
    seen: Seen,
    fc: String,
    events: Vec<Value>,
    all: String,
}

fn run_mavsdk(py: &Path) -> MavsdkRun {
    let (udp_mavsdk, udp_cc, grpc) = (free_udp_port(), free_udp_port(), free_tcp_port());
    let mut cc = LineProc::spawn(
        "fbwag cc",
        fbwag()
            .args(["cc", "--link", &format!("udpin:127.0.0.1:{udp_cc}")])
            .args(["--controller", "circle", "--duration", "120"]),
    );
    let mut server = LineProc::spawn(
        "mavsdk_server",
        Command::new(mavsdk_server(py))
            .args(["-p", &grpc.to_string()])
            .arg(format!("udpin://127.0.0.1:{udp_mavsdk}")),
    );
    let hub = Hub::start(&[
        SocketAddr::from(([127, 0, 0, 1], udp_cc)),
        SocketAddr::from(([127, 0, 0, 1], udp_mavsdk)),
    ]);
    let events = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ground-station-fc-events.jsonl");
    let mut fc = LineProc::spawn(
        "fbwag fc-sim",
        fbwag()
            .args([
                "fc-sim",
                "--link",
                &format!("udpout:127.0.0.1:{}", hub.fc_port),
            ])
            .args(["--pilot-mode", "manual", "--home", &home_arg()])
            .args(["--rc-loss-at", &RC_LOSS.to_string()])
            .args(["--rc-back-at", &RC_BACK.to_string()])
            .args(["--duration", &RUN.to_string()])
            .arg("--events")
            .arg(&events),
    );
    let mut check = LineProc::spawn(
        "mavsdk_gcs_check.py",
        Command::new(py)
            .arg(repo().join("interop/mavsdk_gcs_check.py"))
            .args(["--grpc-port", &grpc.to_string()])
            .args(["--seconds", &(RUN - 1.0).to_string()]),
    );
    // The companion flies for a while, then stops (its process killed):
    // the FC falls back to RTL.
    let handed_over = fc.wait_for("handover", Duration::from_secs_f64(RC_LOSS + 20.0));
    if handed_over {
        thread::sleep(COMPANION_FLIES);
    }
    cc.stop();
    let fc_exited = fc.wait_exit(Duration::from_secs_f64(RUN + 20.0));
    let check_exited = check.wait_exit(Duration::from_secs(30));
    server.stop();
    drop(hub);
    let all = format!(
        "--- fc-sim\n{}--- mavsdk_gcs_check.py\n{}--- fbwag cc\n{}--- mavsdk_server (tail)\n{}",
        fc.log,
        check.log,
        cc.log,
        tail(&server.log, 30)
    );
    assert!(handed_over, "no handover\n{all}");
    assert!(
        fc_exited && check_exited,
        "a process did not end in time\n{all}"
    );
    let events = std::fs::read_to_string(&events)
        .unwrap_or_default()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    MavsdkRun {
        seen: Seen::parse(&check.log),
        fc: fc.log.clone(),
        events,
        all,
    }
}

fn tail(s: &str, n: usize) -> String {
    let lines: Vec<&str> = s.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n") + "\n"
}

/// MAVSDK (mavsdk_server 3.17.4 from the pip package) connected to fc-sim,
/// with `fbwag cc` taking over at the receiver's loss: MAVSDK sees the
/// position at --home and moving, the pilot's mode (MANUAL) by name, the
/// takeover (UNKNOWN by name: MAVSDK 3.17.4 names neither CIRCLE nor FBWAG;
/// custom_mode 1 then 30 in the HEARTBEAT, through MAVSDK's mavlink_direct),
/// RC loss as a state (rc_status unavailable, not armable), the companion's
/// right turn on the map, RTL as RETURN_TO_LAUNCH heading home, MANUAL
/// again; and its requests answered: version, parameters (read, set, a
/// refused set), a telemetry rate, an empty mission, an RTL command denied.
#[test]
fn mavsdk_sees_position_modes_takeover_and_rtl() {
    let Some(py) = peer_python() else {
        return;
    };
    let _one_at_a_time = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let run = run_mavsdk(&py);
    let (seen, all) = (&run.seen, &run.all);
    assert_requests_answered(seen, all);
    assert_position(seen, all);
    assert_modes_and_rc_loss(seen, all);
    assert_flight_path(seen, all);
    // The parameter MAVSDK set took effect; the one that decides who
    // flies did not (fc-sim is armed).
    let set = |name: &str| {
        run.events
            .iter()
            .filter(|e| e["event"] == "param" && e["name"] == name)
            .map(|e| e["value"].clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(set("AIRSPEED_CRUISE"), [Value::from(22.0)], "{all}");
    assert!(set("FS_LONG_TIMEOUT").is_empty(), "{all}");
    assert!(run.fc.contains("FS_LONG_TIMEOUT: not while armed"), "{all}");
    assert!(
        run.fc.contains("MODE CHANGE -> MANUAL (pilot in control)"),
        "{all}"
    );
    // For interop/mavsdk-notes.md: what MAVSDK (and this run) left unserved.
    let summary = run.events.iter().find(|e| e["event"] == "summary");
    println!(
        "fc-sim did not serve: {}",
        summary.map_or(Value::Null, |s| s["not_served"].clone())
    );
}

fn assert_requests_answered(seen: &Seen, all: &str) {
    let ok = |name: &str, value: Value| {
        let c = seen.call(name);
        assert!(c["ok"] == true && c["value"] == value, "{name}: {c}\n{all}");
    };
    ok("get_version", serde_json::json!([4, 6, 0]));
    ok("get_param_int FS_SHORT_ACTN", 5.into());
    ok("set_param_float AIRSPEED_CRUISE 22", Value::Null);
    ok("get_param_float AIRSPEED_CRUISE", 22.0.into());
    ok("set_rate_position 2", Value::Null);
    ok("download_mission", 0.into());
    // Refused: FS_LONG_TIMEOUT decides who flies, and fc-sim is armed
    // (MAVSDK times out waiting for the echo of its value); the RTL
    // command is denied.
    let refused = seen.call("set_param_float FS_LONG_TIMEOUT 6");
    assert!(refused["ok"] == false, "{refused}\n{all}");
    let rtl = seen.call("return_to_launch");
    assert!(
        rtl["ok"] == false && rtl["value"].as_str().unwrap().contains("COMMAND_DENIED"),
        "{rtl}\n{all}"
    );
}

fn assert_position(seen: &Seen, all: &str) {
    let home = seen
        .of("home")
        .next()
        .unwrap_or_else(|| panic!("no home\n{all}"));
    assert!(
        (home["lat"].as_f64().unwrap() - HOME.0).abs() < 1e-6
            && (home["lon"].as_f64().unwrap() - HOME.1).abs() < 1e-6
            && (home["alt"].as_f64().unwrap() - HOME.2).abs() < 0.01,
        "{home}\n{all}"
    );
    let samples = seen.samples();
    // The first with a mode: MAVSDK may report a position before the
    // first HEARTBEAT (1 Hz) it passes on.
    let first = samples
        .iter()
        .find(|s| s.custom_mode.is_some())
        .unwrap_or_else(|| panic!("no position with a mode\n{all}"));
    // Over home at start (18 m/s for the few seconds MAVSDK takes to
    // connect), 100 m up, the pilot flying.
    assert!(distance_from_home(first) < 300.0, "{all}");
    assert_eq!(first.custom_mode, Some(0), "{all}");
    assert!((first.rel_alt - 100.0).abs() < 2.0, "{all}");
    let farthest = samples.iter().map(distance_from_home).fold(0.0, f64::max);
    assert!(
        farthest > distance_from_home(first) + 100.0,
        "not moving\n{all}"
    );
}

fn assert_modes_and_rc_loss(seen: &Seen, all: &str) {
    let modes: Vec<Value> = seen
        .changes("mode", "value")
        .into_iter()
        .map(|m| m.1)
        .collect();
    let names = ["MANUAL", "UNKNOWN", "RETURN_TO_LAUNCH", "MANUAL"].map(Value::from);
    assert!(in_order(&modes, &names), "flight modes {modes:?}\n{all}");
    let raw = seen.changes("custom_mode", "value");
    let raw_modes: Vec<Value> = raw.iter().map(|m| m.1.clone()).collect();
    let numbers = [0, 1, 30, 11, 0].map(Value::from);
    assert!(
        in_order(&raw_modes, &numbers),
        "custom_mode {raw_modes:?}\n{all}"
    );
    // RC loss shows as a state, with or before the takeover's mode change.
    let rc = seen.changes("rc", "available");
    let rc_states: Vec<Value> = rc.iter().map(|r| r.1.clone()).collect();
    assert!(
        in_order(&rc_states, &[true, false, true].map(Value::from)),
        "rc {rc_states:?}\n{all}"
    );
    let lost_at = rc.iter().find(|r| r.1 == false).unwrap().0;
    let circle_at = raw.iter().find(|m| m.1 == 1).unwrap().0;
    assert!(
        lost_at <= circle_at + 0.5,
        "rc lost {lost_at}, CIRCLE {circle_at}\n{all}"
    );
    let armable: Vec<Value> = seen
        .changes("armable", "value")
        .into_iter()
        .map(|a| a.1)
        .collect();
    assert!(
        in_order(&armable, &[true, false, true].map(Value::from)),
        "armable {armable:?}\n{all}"
    );
}

/// The map: straight north under the pilot's centred sticks; a steady right
/// turn while the companion's circle controller flies (its roll override,
/// 1650 µs, is 13.5° of bank: about 7°/s at 19.5 m/s), climbing a little on
/// its throttle; back toward home in RTL.
fn assert_flight_path(seen: &Seen, all: &str) {
    let samples = seen.samples();
    let segment = |mode: i64| -> Vec<&Sample> {
        samples
            .iter()
            .filter(|s| s.custom_mode == Some(mode))
            .collect()
    };
    let pilot: Vec<&Sample> = segment(0)
        .into_iter()
        .filter(|s| s.t < seen.changes("custom_mode", "value")[1].0)
        .collect();
    assert!(pilot.len() >= 4, "{all}");
    assert!(
        pilot.iter().all(|s| s.heading.min(360.0 - s.heading) < 0.5),
        "{all}"
    );
    let companion = segment(30);
    assert!(companion.len() >= 10, "{all}");
    // Past the first second (the bank settling from CIRCLE's).
    let steady: Vec<&Sample> = companion
        .iter()
        .copied()
        .filter(|s| s.t > companion[0].t + 1.0)
        .collect();
    let headings: Vec<f64> = steady.iter().map(|s| s.heading).collect();
    let span = steady.last().unwrap().t - steady[0].t;
    let rate = turned(&headings) / span;
    assert!(
        (4.0..10.0).contains(&rate),
        "companion turn {rate} deg/s\n{all}"
    );
    let rtl = segment(11);
    assert!(rtl.len() >= 20, "{all}");
    let start = distance_from_home(rtl[0]);
    let closest = rtl
        .iter()
        .map(|s| distance_from_home(s))
        .fold(f64::MAX, f64::min);
    assert!(
        closest < start - 100.0,
        "RTL from {start} m, closest {closest} m\n{all}"
    );
    // The companion's throttle (1600 µs, above trim) climbs a little; RTL
    // comes back to 100 m.
    let highest = samples.iter().map(|s| s.rel_alt).fold(0.0, f64::max);
    assert!(
        (101.0..110.0).contains(&highest),
        "highest {highest} m\n{all}"
    );
    assert!(samples.iter().all(|s| s.rel_alt > 98.0), "{all}");
    println!(
        "map: companion turn {rate:.1} deg/s over {span:.1} s; RTL from {start:.0} m to {closest:.0} m of home"
    );
}

// --- MAVProxy ----------------------------------------------------------------

/// MAVProxy 1.8.75 between fc-sim and `fbwag cc`, with `module load fbwag`:
/// MAVProxy names every mode itself (MANUAL, CIRCLE, RTL) and, with the
/// module, FBWAG (never Mode(30)); it fetches the 13 parameters, shows
/// FS_SHORT_ACTN 5, and its `mode RTL` is denied by fc-sim with the reason;
/// no false fence breach.
#[test]
fn mavproxy_names_the_modes_and_reads_the_failsafe_parameters() {
    let Some(py) = peer_python() else {
        return;
    };
    let _one_at_a_time = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let (p_master, p_cc) = (free_udp_port(), free_udp_port());
    let mut cc = LineProc::spawn(
        "fbwag cc",
        fbwag()
            .args(["cc", "--link", &format!("udpin:127.0.0.1:{p_cc}")])
            .args(["--controller", "circle", "--duration", "120"]),
    );
    let home = Path::new(env!("CARGO_TARGET_TMPDIR")).join("mavproxy-home-ground-station");
    std::fs::create_dir_all(&home).unwrap();
    let mut mavproxy = LineProc::spawn(
        "mavproxy.py",
        Command::new(py.with_file_name("mavproxy.py"))
            .arg(format!("--master=udpin:127.0.0.1:{p_master}"))
            .arg(format!("--out=udpout:127.0.0.1:{p_cc}"))
            .args(["--no-state", "--load-module=fbwag"])
            .env("HOME", &home)
            .env("PYTHONUNBUFFERED", "1")
            .env_remove("DISPLAY")
            .stdin(Stdio::piped()),
    );
    assert!(
        mavproxy.wait_for("Waiting for heartbeat", Duration::from_secs(40)),
        "MAVProxy did not start:\n{}",
        mavproxy.log
    );
    let mut console = mavproxy.stdin();
    let mut fc = LineProc::spawn(
        "fbwag fc-sim",
        fbwag()
            .args(["fc-sim", "--link", &format!("udpout:127.0.0.1:{p_master}")])
            .args(["--pilot-mode", "manual", "--home", &home_arg()])
            .args([
                "--rc-loss-at",
                "8",
                "--rc-back-at",
                "30",
                "--duration",
                "33",
            ]),
    );
    let mut say = |line: &str| {
        console.write_all(format!("{line}\n").as_bytes()).unwrap();
        console.flush().unwrap();
    };
    // MAVProxy tries FTP for parameters first (fc-sim has none), then the
    // parameter protocol.
    let got_params = mavproxy.wait_for("Received 13 parameters", Duration::from_secs(30));
    say("param show FS_SHORT_ACTN");
    let companion = mavproxy.wait_for("Mode FBWAG", Duration::from_secs(30));
    say("mode RTL");
    let denied = mavproxy.wait_for(
        "denied: the FBWAG engine decides modes",
        Duration::from_secs(10),
    );
    // The companion stops: RTL.
    cc.stop();
    let rtl = mavproxy.wait_for("Mode RTL", Duration::from_secs(10));
    let manual_again = mavproxy.wait_for("MANUAL>", Duration::from_secs(30));
    let fc_exited = fc.wait_exit(Duration::from_secs(40));
    mavproxy.stop();
    let all = format!(
        "--- mavproxy.py\n{}--- fc-sim\n{}--- fbwag cc\n{}",
        mavproxy.log, fc.log, cc.log
    );
    assert!(
        got_params && companion && denied && rtl && manual_again,
        "{all}"
    );
    assert!(fc_exited, "{all}");
    let log = &mavproxy.log;
    for line in [
        "Mode MANUAL",
        "fbwag: FC mode MANUAL -> CIRCLE",
        "fbwag: FC mode CIRCLE -> FBWAG (companion control)",
        "FBWAG>",
        "Mode RTL",
        "FS_SHORT_ACTN    5",
        "Got COMMAND_ACK: DO_SET_MODE: DENIED",
    ] {
        assert!(log.contains(line), "{line:?}\n{all}");
    }
    assert!(
        !log.contains("Mode(30)"),
        "MAVProxy did not name FBWAG\n{all}"
    );
    assert!(!log.contains("fence breach"), "false fence breach\n{all}");
    let shown = ["Mode ", "denied", "DENIED", "FS_SHORT_ACTN", "parameters"];
    for line in log.lines().filter(|l| shown.iter().any(|w| l.contains(w))) {
        println!("mavproxy: {line}");
    }
    // For interop/mavsdk-notes.md: what MAVProxy asked and fc-sim did not serve.
    for line in fc.log.lines().filter(|l| l.contains("not served")) {
        println!("{line}");
    }
}

// --- hostile ground stations (no peer venv needed) -------------------------

use fbwag_dialect::dialects::common::{
    CommandLong, MavCmd, MavDataStream, ParamRequestList, ParamRequestRead, ParamSet,
    RequestDataStream, SetMode,
};
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::mavframe::signing::timestamp_now;
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Header, Message, Parser, Signer, Unsigned, Verifier, Version};

/// A MAVLink sender with its own sequence and, optionally, a signing key.
struct Sender {
    sysid: u8,
    compid: u8,
    seq: u8,
    signer: Option<Signer>,
}

impl Sender {
    fn new(sysid: u8, compid: u8, key: Option<[u8; 32]>) -> Self {
        Sender {
            sysid,
            compid,
            seq: 0,
            signer: key.map(|k| Signer::new(k, 0, timestamp_now())),
        }
    }

    fn frame(&mut self, msg: &dyn Encode) -> Vec<u8> {
        let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
        let h = Header {
            seq: self.seq,
            sysid: self.sysid,
            compid: self.compid,
        };
        self.seq = self.seq.wrapping_add(1);
        if let Some(s) = &mut self.signer {
            s.advance_to(timestamp_now());
        }
        let n = encode(Version::V2, h, msg, self.signer.as_mut(), &mut buf).unwrap();
        buf[..n].to_vec()
    }
}

fn command(command: MavCmd, param1: f32, param2: f32) -> CommandLong {
    CommandLong {
        target_system: 1,
        target_component: 1,
        command,
        param1,
        param2,
        ..Default::default()
    }
}

/// The requests of the flood, in turn: the fastest telemetry, the
/// parameter list, a mode change (RTL), an unknown command, SET_MODE,
/// parameters that do not exist (more names than fc-sim counts by name),
/// and bytes that are no frame.
fn flood_frame(gcs: &mut Sender, k: u32) -> Vec<u8> {
    match k % 8 {
        0 => gcs.frame(&RequestDataStream {
            target_system: 1,
            target_component: 1,
            req_stream_id: MavDataStream::ALL,
            req_message_rate: u16::MAX,
            start_stop: 1,
        }),
        1 => gcs.frame(&command(MavCmd::SET_MESSAGE_INTERVAL, 30.0, 1.0)),
        2 => gcs.frame(&ParamRequestList {
            target_system: 1,
            target_component: 1,
        }),
        3 => gcs.frame(&command(MavCmd::DO_SET_MODE, 1.0, 11.0)),
        4 => gcs.frame(&command(MavCmd(31_000 + (k % 97) as u16), 0.0, 0.0)),
        5 => gcs.frame(&SetMode {
            target_system: 1,
            custom_mode: 11,
            ..Default::default()
        }),
        6 => gcs.frame(&ParamRequestRead {
            target_system: 1,
            target_component: 1,
            param_id: chars(&format!("NOPE_{k}")),
            param_index: -1,
        }),
        _ => vec![
            0xFD, 0x09, 0x00, 0x00, 0x00, 0xFF, 0xBE, 0x4C, 0x00, 0x00, 0x55,
        ],
    }
}

/// Per message name, how many fc-sim sent.
fn count_frames(bytes: &[Vec<u8>], parser: &mut Parser) -> BTreeMapCount {
    let mut counts = BTreeMapCount::new();
    for chunk in bytes {
        let mut input = &chunk[..];
        while let Some(r) = parser.next(&mut input) {
            let name = r.meta().map_or("?", |m| m.name);
            *counts.entry(name).or_insert(0) += 1;
        }
    }
    counts
}

type BTreeMapCount = std::collections::BTreeMap<&'static str, u32>;

/// A ground station (anyone, unsigned) floods fc-sim with requests while the
/// receiver fails and `fbwag cc` takes over: the handover happens as
/// without it, no mode is changed by the flood, and fc-sim's output stays
/// within its caps (ATTITUDE 50 Hz, other telemetry 10 Hz, one parameter
/// list at a time, one answer per command).
#[test]
fn a_request_flood_neither_stops_the_handover_nor_multiplies_the_telemetry() {
    let _one_at_a_time = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let cc_port = free_udp_port();
    let mut cc = LineProc::spawn(
        "fbwag cc",
        fbwag().args([
            "cc",
            "--link",
            &format!("udpin:127.0.0.1:{cc_port}"),
            "--duration",
            "30",
        ]),
    );
    let gcs = UdpSocket::bind("127.0.0.1:0").unwrap();
    let hub = Hub::start(&[
        SocketAddr::from(([127, 0, 0, 1], cc_port)),
        gcs.local_addr().unwrap(),
    ]);
    let events = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ground-station-flood-events.jsonl");
    let mut fc = LineProc::spawn(
        "fbwag fc-sim",
        fbwag()
            .args([
                "fc-sim",
                "--link",
                &format!("udpout:127.0.0.1:{}", hub.fc_port),
            ])
            .args(["--rc-loss-at", "2", "--rc-back-at", "6", "--duration", "7"])
            .arg("--events")
            .arg(&events),
    );
    // The flood: 8 datagrams every 2 ms (4000 a second) for 6 s, sent into
    // the hub as a party, and everything fc-sim sends meanwhile.
    // A party reaches fc-sim by answering the hub socket fc-sim's frames
    // come from.
    gcs.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let mut buf = [0u8; 2048];
    let (_, to_fc) = gcs.recv_from(&mut buf).expect("fc-sim's first frame");
    gcs.set_nonblocking(true).unwrap();
    let mut sender = Sender::new(255, 190, None);
    let (mut received, mut sent) = (Vec::new(), 0u32);
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(6) {
        for _ in 0..8 {
            let _ = gcs.send_to(&flood_frame(&mut sender, sent), to_fc);
            sent += 1;
        }
        while let Ok((n, _)) = gcs.recv_from(&mut buf) {
            received.push(buf[..n].to_vec());
        }
        thread::sleep(Duration::from_millis(2));
    }
    let fc_exited = fc.wait_exit(Duration::from_secs(20));
    cc.stop();
    drop(hub);
    let all = format!("--- fc-sim\n{}--- fbwag cc\n{}", fc.log, cc.log);
    assert!(fc_exited, "{all}");
    let events: Vec<Value> = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .filter_map(|l| serde_json::from_str(l).ok())
        .collect();
    let modes: Vec<&str> = events
        .iter()
        .filter(|e| e["event"] == "mode")
        .filter_map(|e| e["mode"].as_str())
        .collect();
    assert_eq!(modes, ["FBWA", "CIRCLE", "FBWAG", "FBWA"], "{all}");
    let handover = events.iter().find(|e| e["event"] == "handover").unwrap();
    let summary = events.iter().find(|e| e["event"] == "summary").unwrap();
    // Named kinds of what was not served are bounded (64, then "(other)").
    let not_served = summary["not_served"].as_object().unwrap();
    assert!(
        not_served.len() <= 65 && not_served.contains_key("(other)"),
        "{summary}"
    );
    let counts = count_frames(&received, &mut Parser::new());
    let secs = start.elapsed().as_secs_f64();
    let per_s = |name: &str| f64::from(*counts.get(name).unwrap_or(&0)) / secs;
    println!(
        "flood: {sent} datagrams in {secs:.1} s; handover {} ms; fc-sim sent meanwhile: {counts:?}",
        handover["ms"]
    );
    assert!(per_s("ATTITUDE") <= 55.0, "{counts:?}");
    for telemetry in [
        "GLOBAL_POSITION_INT",
        "VFR_HUD",
        "SYS_STATUS",
        "RC_CHANNELS",
        "GPS_RAW_INT",
    ] {
        assert!(per_s(telemetry) <= 11.0, "{telemetry}: {counts:?}");
    }
    assert!(per_s("PARAM_VALUE") <= 101.0, "{counts:?}");
    // One COMMAND_ACK per command at most (4 of every 8 datagrams are
    // COMMAND_LONG or SET_MODE), and denials said at most 5 times per 10 s.
    assert!(
        *counts.get("COMMAND_ACK").unwrap_or(&0) <= sent / 2,
        "{counts:?}"
    );
    assert!(
        *counts.get("STATUSTEXT").unwrap_or(&0) <= 5 + 4,
        "{counts:?}"
    );
}

const KEY: [u8; 32] = [0x3c; 32];
const KEY_HEX: &str = "3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c3c";

/// Sends `frames` to fc-sim and collects what it sends back for `wait`.
fn exchange(
    socket: &UdpSocket,
    to: SocketAddr,
    frames: &[Vec<u8>],
    wait: Duration,
) -> Vec<Message> {
    for f in frames {
        socket.send_to(f, to).unwrap();
    }
    let mut parser = Parser::with_signing(
        Verifier::with_timestamp(KEY, timestamp_now()),
        Unsigned::Accept,
    );
    let mut out = Vec::new();
    let end = Instant::now() + wait;
    let mut buf = [0u8; 2048];
    while Instant::now() < end {
        if let Ok((n, _)) = socket.recv_from(&mut buf) {
            let mut input = &buf[..n];
            while let Some(r) = parser.next(&mut input) {
                out.extend(r.message());
            }
        }
    }
    out
}

/// With --require-signed, fc-sim serves ground-station requests only from
/// frames whose signature verified, as ArduPilot on a signed link: an
/// unsigned parameter write (here: trusting another companion) and unsigned
/// requests get no answer and change nothing; the same requests signed are
/// served, and the signed write takes effect.
#[test]
fn with_require_signed_only_signed_requests_are_served() {
    let _one_at_a_time = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
    socket
        .set_read_timeout(Some(Duration::from_millis(50)))
        .unwrap();
    let events = Path::new(env!("CARGO_TARGET_TMPDIR")).join("ground-station-signed-events.jsonl");
    let mut fc = LineProc::spawn(
        "fbwag fc-sim",
        fbwag()
            .args([
                "fc-sim",
                "--link",
                &format!("udpout:{}", socket.local_addr().unwrap()),
            ])
            .args(["--sign-key", KEY_HEX, "--require-signed", "--duration", "5"])
            // On the ground: the FC's delegation settings may be written.
            .args(["--arm-at", "100"])
            .arg("--events")
            .arg(&events),
    );
    let mut buf = [0u8; 2048];
    let (_, fc_addr) = socket.recv_from(&mut buf).expect("fc-sim's first frame");
    let write = |id: &str, value: f32| ParamSet {
        target_system: 1,
        target_component: 1,
        param_id: chars(id),
        param_value: value,
        ..Default::default()
    };
    let read = ParamRequestRead {
        target_system: 1,
        target_component: 1,
        param_id: chars("FBWAG_CC_SYSID"),
        param_index: -1,
    };
    let version = command(MavCmd::REQUEST_MESSAGE, 148.0, 0.0);
    let requests = |gcs: &mut Sender| {
        vec![
            gcs.frame(&write("FBWAG_CC_SYSID", 42.0)),
            gcs.frame(&read),
            gcs.frame(&version),
        ]
    };
    let answers = |msgs: &[Message]| -> Vec<String> {
        msgs.iter()
            .filter(|m| {
                matches!(
                    m,
                    Message::ParamValue(_) | Message::AutopilotVersion(_) | Message::CommandAck(_)
                )
            })
            .map(|m| format!("{m:?}"))
            .collect()
    };
    let unsigned = exchange(
        &socket,
        fc_addr,
        &requests(&mut Sender::new(255, 190, None)),
        Duration::from_millis(1000),
    );
    let signed = exchange(
        &socket,
        fc_addr,
        &requests(&mut Sender::new(255, 190, Some(KEY))),
        Duration::from_millis(1000),
    );
    let fc_exited = fc.wait_exit(Duration::from_secs(15));
    let all = format!("--- fc-sim\n{}", fc.log);
    assert!(fc_exited, "{all}");
    assert_eq!(answers(&unsigned), Vec::<String>::new(), "{all}");
    let values: Vec<f32> = signed
        .iter()
        .filter_map(|m| match m {
            Message::ParamValue(p) if p.param_id == chars::<16>("FBWAG_CC_SYSID") => {
                Some(p.param_value)
            }
            _ => None,
        })
        .collect();
    // The write's echo and the read: the signed write took effect.
    assert_eq!(values, [42.0, 42.0], "{all}");
    assert!(
        signed
            .iter()
            .any(|m| matches!(m, Message::AutopilotVersion(_))),
        "{all}"
    );
    let summary: Value = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .find(|e| e["event"] == "summary")
        .unwrap();
    assert_eq!(summary["gcs_unsigned_refused"], 3, "{summary}");
    assert!(
        fc.log
            .contains("parameter FBWAG_CC_SYSID = 42 (set by 255/190)"),
        "{all}"
    );
}
