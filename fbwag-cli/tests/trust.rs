//! Attacks on what the daemons trust, against the real `fbwag cc`,
//! `fbwag fc-sim` and `fbwag router` processes on 127.0.0.1. Each test
//! asserts that its attack fails:
//!
//! - forged FC telemetry (unsigned, the FC's ids) sent to the companion's
//!   FC link never reaches the autonomy program or a ground station;
//! - strangers on the router's listening ports neither take the answers
//!   meant for the companion nor evict its connection;
//! - a clock an hour, 70 s or 56 years off (libfaketime) does not stop a
//!   signed handover;
//! - quick restarts never push a signer's saved timestamp ahead of the
//!   clock, and a correctly clocked sender is still accepted after them;
//! - a silent autonomy program never leaves the FC in companion control
//!   without control; `--autonomy-peer` pins the program;
//! - strangers on a ground station's port neither crowd it out, nor evict
//!   the FC's route, nor get routed through an `udpout` link;
//! - the daemons count what they drop, by reason, in their summaries.
//!
//! Each test runs a few seconds; test sockets play the autonomy program
//! and the ground station (`common/station.rs`).

#[path = "common/attack.rs"]
mod attack;
#[path = "common/live.rs"]
mod live;
#[path = "common/station.rs"]
mod station;

use attack::{frame, is_attackers, key_bytes, Attacker, OnPath, CC, FC, GCS, MARK};
use fbwag_delegation::fc::Authority;
use fbwag_delegation::{wire, Peer, Status};
use fbwag_dialect::dialects::common::{ParamRequestRead, ParamSet, RcChannelsOverride};
use fbwag_dialect::dialects::standard::GlobalPositionInt;
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::mavframe::signing::timestamp_now;
use fbwag_dialect::Signer;
use live::*;
use rand_pcg::Pcg64;
use serde_json::Value;
use station::*;
use std::path::Path;
use std::sync::Mutex;
use std::time::{Duration, Instant};

/// The reason the summaries give (`"dropped": {REASON: N, ...}`) for
/// frames dropped because signing is required and they were not signed.
const UNAUTHENTICATED: &str = "unauthenticated";

/// libfaketime's preload library (Debian's package `libfaketime`;
/// scripts/test.sh installs it).
const LIBFAKETIME: &str = "/usr/lib/x86_64-linux-gnu/faketime/libfaketime.so.1";

/// The autonomy program's ids (any but the FC's and the companion's).
const AUTONOMY: Peer = Peer::new(1, 42);

/// The latitude of every forged GLOBAL_POSITION_INT (fc-sim flies near
/// -35.36°): a frame carrying it came from the forger.
const FORGED_LAT: i32 = 123_456_789;

/// Message ids read off the wire.
const PARAM_VALUE: u32 = 22;
const GLOBAL_POSITION_INT: u32 = 33;

/// CHAN1 of the autonomy program's control: applied, it came from there.
const AUTONOMY_CHAN1: u16 = 1234;

/// Timed tests one at a time (a handover within 300 ms, a share of the
/// telemetry): the other tests' floods share the machine's two cores.
static TIMED: Mutex<()> = Mutex::new(());

fn timed() -> std::sync::MutexGuard<'static, ()> {
    TIMED.lock().unwrap_or_else(|e| e.into_inner())
}

fn udpin(port: u16) -> String {
    format!("udpin:127.0.0.1:{port}")
}

fn udpout(port: u16) -> String {
    format!("udpout:127.0.0.1:{port}")
}

fn signed() -> Vec<String> {
    args(&["--sign-key", KEY, "--require-signed"])
}

/// `fbwag cc`'s autonomy link listening on port `aut`, pinned to the
/// program sending from port `program`.
fn pinned_autonomy(aut: u16, program: u16) -> Vec<String> {
    args(&[
        "--autonomy",
        &udpin(aut),
        "--autonomy-peer",
        &format!("127.0.0.1:{program}"),
    ])
}

fn with(mut a: Vec<String>, more: &[&str]) -> Vec<String> {
    a.extend(args(more));
    a
}

/// Which end of the FC link listens.
#[derive(Clone, Copy, Debug)]
enum FcLink {
    /// `fbwag cc --link udpin`, fc-sim `udpout` to it.
    CcListens,
    /// fc-sim `--link udpin`, `fbwag cc --link udpout` to it.
    FcListens,
    /// `fbwag cc --link udpin` on port `cc`, fc-sim `udpout` to port
    /// `fc_to` (a relay's, which carries its frames to `cc`).
    Relayed { cc: u16, fc_to: u16 },
}

/// A companion and an FC on one link.
struct Pair {
    cc: Daemon,
    fc: Daemon,
    /// The port the companion's FC link receives on (its `udpin` port, or
    /// its `udpout` socket's).
    cc_fc_port: u16,
}

/// How a [`Pair`] runs: each side's arguments after `--link` and its
/// environment; `cc_ports` are the companion's other UDP ports (to tell
/// its FC link's `udpout` socket from them).
#[derive(Default)]
struct Sides<'a> {
    cc: Vec<String>,
    fc: Vec<String>,
    cc_env: &'a [(&'a str, &'a str)],
    fc_env: &'a [(&'a str, &'a str)],
    cc_ports: &'a [u16],
}

impl Pair {
    fn start(dir: &Path, link: FcLink, s: Sides) -> Pair {
        let port = match link {
            FcLink::Relayed { cc, .. } => cc,
            _ => free_port(),
        };
        let (cc_link, fc_link) = match link {
            FcLink::CcListens => (udpin(port), udpout(port)),
            FcLink::FcListens => (udpout(port), udpin(port)),
            FcLink::Relayed { fc_to, .. } => (udpin(port), udpout(fc_to)),
        };
        let cc_args = [args(&["cc", "--link", &cc_link]), s.cc].concat();
        let fc_args = [args(&["fc-sim", "--link", &fc_link]), s.fc].concat();
        let (cc, fc) = match link {
            FcLink::FcListens => {
                let fc = Daemon::spawn_with_env(dir, "fc", &fc_args, s.fc_env);
                std::thread::sleep(Duration::from_millis(100));
                (Daemon::spawn_with_env(dir, "cc", &cc_args, s.cc_env), fc)
            }
            _ => {
                let cc = Daemon::spawn_with_env(dir, "cc", &cc_args, s.cc_env);
                (cc, Daemon::spawn_with_env(dir, "fc", &fc_args, s.fc_env))
            }
        };
        let cc_fc_port = match link {
            FcLink::FcListens => other_udp_port(cc.pid(), s.cc_ports),
            _ => port,
        };
        Pair { cc, fc, cc_fc_port }
    }

    /// Waits for both to end on their own.
    fn finish(self) -> (Finished, Finished) {
        let limit = Duration::from_secs(30);
        let fc = self.fc.finish(limit);
        (fc, self.cc.finish(limit))
    }
}

/// The UDP port of process `pid` that is none of `known` (an `udpout`
/// link's socket), waiting up to 5 s for it.
fn other_udp_port(pid: u32, known: &[u16]) -> u16 {
    let until = Instant::now() + Duration::from_secs(5);
    loop {
        let ports = udp_ports_of(pid);
        if let Some(&p) = ports.iter().find(|p| !known.contains(p)) {
            return p;
        }
        assert!(Instant::now() < until, "process {pid} bound no other port");
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn dump(list: &[&Finished]) -> String {
    list.iter().map(|f| f.dump()).collect::<Vec<_>>().join("\n")
}

/// The FC handed over within `within_ms` of the receiver loss and kept
/// companion control to its end (no RTL, no pilot).
fn assert_handover_held(fc: &Finished, within_ms: u64, all: &str) {
    let ms = fc
        .events
        .last("handover")
        .map(|e| e["ms"].as_u64().unwrap_or(u64::MAX));
    let ms = ms.unwrap_or_else(|| panic!("no handover\n{all}"));
    assert!(
        ms <= within_ms,
        "handover {ms} ms after the receiver loss, over {within_ms} ms\n{all}"
    );
    let modes = fc.events.modes();
    assert!(
        modes
            .iter()
            .skip_while(|m| *m != "FBWAG")
            .all(|m| m == "FBWAG"),
        "companion control did not hold: {modes:?}\n{all}"
    );
}

/// Every control applied came from the companion, signed.
fn assert_controls_signed_from_companion(fc: &Finished, all: &str) {
    for e in fc.events.of("control_applied") {
        assert!(
            e["sysid"] == CC.sysid && e["compid"] == CC.compid && e["authenticated"] == true,
            "control applied from a stranger or unsigned: {e}\n{all}"
        );
    }
}

/// The channels of each `control_applied`, in order.
fn applied_channels(fc: &Finished) -> Vec<Vec<u64>> {
    fc.events
        .of("control_applied")
        .map(|e| {
            e["channels"]
                .as_array()
                .map(|a| a.iter().filter_map(Value::as_u64).collect())
                .unwrap_or_default()
        })
        .collect()
}

/// `n` in the summary's `dropped` object of `reason` (0 when absent).
fn dropped(f: &Finished, reason: &str) -> u64 {
    let summary = f.events.last("summary");
    let summary = summary.unwrap_or_else(|| panic!("{}: no summary\n{}", f.name, f.dump()));
    summary["dropped"][reason].as_u64().unwrap_or(0)
}

fn heartbeat_of(who: Peer) -> Beat {
    Box::new(move |n| vec![frame(who, n as u8, &wire::cc_heartbeat(), None)])
}

/// An RC override to the FC with CHAN1 `chan1` (the rest centred).
fn override_chan1(chan1: u16) -> RcChannelsOverride {
    RcChannelsOverride {
        target_system: FC.sysid,
        target_component: FC.compid,
        chan1_raw: chan1,
        chan2_raw: 1500,
        chan3_raw: 1500,
        chan4_raw: 1500,
        ..Default::default()
    }
}

// ---------------------------------------------------------------------------
// 1. Forged FC telemetry through the companion.

/// An unsigned frame as the FC: a GLOBAL_POSITION_INT at [`FORGED_LAT`],
/// or a HEARTBEAT claiming companion control.
fn forged_fc_frame(n: u64) -> Vec<u8> {
    if n % 2 == 0 {
        let position = GlobalPositionInt {
            time_boot_ms: n as u32,
            lat: FORGED_LAT,
            lon: -98_765_432,
            alt: 1_000_000,
            relative_alt: 900_000,
            ..Default::default()
        };
        frame(FC, n as u8, &position, None)
    } else {
        frame(FC, n as u8, &wire::fc_heartbeat(Authority::Companion), None)
    }
}

/// What `who` received of the FC: enough of its frames, every one signed
/// (the FC's frames routed byte for byte), none forged.
fn assert_only_the_fcs_signed_frames(who: &str, st: &Station, all: &str) {
    let frames: Vec<RawFrame> = st
        .frames()
        .into_iter()
        .map(|(_, f)| f)
        .filter(|f| f.from(FC.sysid, FC.compid))
        .collect();
    assert!(
        frames.len() >= 20,
        "the {who} got {} of the FC's frames: not routed\n{all}",
        frames.len()
    );
    let unsigned = frames.iter().filter(|f| !f.is_signed()).count();
    let forged = frames
        .iter()
        .filter(|f| f.msgid == GLOBAL_POSITION_INT && f.i32_at(4) == FORGED_LAT)
        .count();
    assert!(
        unsigned == 0 && forged == 0,
        "the {who} got {unsigned} unsigned frames as the FC ({forged} forged positions) of {}\n{all}",
        frames.len()
    );
}

/// Where the forger of [`forged_telemetry`] sends from.
#[derive(Clone, Copy, Debug)]
enum Forger {
    /// Its own socket, to the companion's FC link port (`link` set up so).
    Stranger(FcLink),
    /// The path between the daemons (an [`OnPath`] relay): its frames come
    /// from the FC's address, and only signing tells them from the FC's.
    OnPath,
}

/// Unsigned frames as the FC, `per_datagram` to a datagram.
fn forged_datagram(per_datagram: u64) -> impl FnMut(&mut Pcg64, u64) -> Vec<u8> + Send {
    move |_, n| {
        (0..per_datagram)
            .flat_map(|i| forged_fc_frame(n * per_datagram + i))
            .collect()
    }
}

/// A signed pair, the companion with an autonomy program and a ground
/// station (test sockets that speak first, then read), and a forger
/// sending `per_datagram` unsigned frames as the FC per datagram, `per_sec`
/// datagrams a second, to the companion's FC link.
fn forged_telemetry(forger: Forger, per_datagram: u64, per_sec: f64) {
    let dir = scratch("forged-telemetry");
    let (aut, gcs, program) = (free_port(), free_port(), free_port());
    let autonomy = Station::start(
        program,
        Some(local(aut)),
        Duration::from_millis(200),
        heartbeat_of(AUTONOMY),
    );
    let ground = Station::start(
        0,
        Some(local(gcs)),
        Duration::from_secs(1),
        heartbeat_of(GCS),
    );
    let cc = [pinned_autonomy(aut, program), args(&["--out", &udpin(gcs)])];
    let sides = Sides {
        cc: [cc.concat(), signed(), args(&["--duration", "4.5"])].concat(),
        fc: with(signed(), &["--duration", "4"]),
        cc_ports: &[aut, gcs],
        ..Sides::default()
    };
    let forge = forged_datagram(per_datagram);
    let (pair, sent) = match forger {
        Forger::Stranger(link) => {
            let pair = Pair::start(&dir, link, sides);
            let to = local(pair.cc_fc_port);
            let forger = Attacker::start(&[to], per_sec, 1, forge);
            (pair.finish(), forger.stop())
        }
        Forger::OnPath => {
            let cc = free_port();
            let relay = OnPath::start(local(cc), per_sec, 1, forge);
            let fc_to = relay.fc_side.port();
            let pair = Pair::start(&dir, FcLink::Relayed { cc, fc_to }, sides);
            (pair.finish(), relay.stop())
        }
    };
    let (fc, cc) = pair;
    let all = dump(&[&fc, &cc]);
    fc.assert_ran_to_the_end(4.0);
    cc.assert_ran_to_the_end(4.5);
    assert!(sent.datagrams as f64 > per_sec * 2.0, "{sent:?}");
    assert_only_the_fcs_signed_frames("autonomy program", &autonomy, &all);
    assert_only_the_fcs_signed_frames("ground station", &ground, &all);
}

/// The companion listens (`udpin`): the forger sends to its port.
#[test]
fn forged_fc_telemetry_never_reaches_the_autonomy_or_the_ground_station() {
    forged_telemetry(Forger::Stranger(FcLink::CcListens), 1, 200.0);
}

/// The companion sends to a listening FC (`udpout`): the forger sends to
/// the companion's socket, from another port than the FC's.
#[test]
fn forged_fc_telemetry_to_the_companions_udpout_socket_goes_nowhere() {
    forged_telemetry(Forger::Stranger(FcLink::FcListens), 1, 200.0);
}

/// The forger on the path, sending from the FC's address.
#[test]
fn forged_fc_telemetry_from_the_fcs_address_never_reaches_the_autonomy_or_the_ground_station() {
    forged_telemetry(Forger::OnPath, 1, 200.0);
}

/// Datagrams of 40 forged frames, 250 a second (10,000 frames a second).
#[test]
fn a_flood_of_forged_fc_telemetry_never_reaches_the_autonomy_or_the_ground_station() {
    forged_telemetry(Forger::Stranger(FcLink::CcListens), 40, 250.0);
}

// ---------------------------------------------------------------------------
// 2. The router's listening ports.

/// The router, the companion and the FC of [`router_chain`], and the
/// router's two ports (the FC's, the companion's).
struct Chain {
    router: Daemon,
    cc: Daemon,
    fc: Daemon,
    ports: [u16; 2],
}

/// fc-sim and `fbwag cc` (both signed) through `fbwag router <router_args>`
/// (with `--events` when `events`): fc-sim sends to the router's first
/// `udpin` port, the companion to its second; the receiver lost at
/// `rc_loss_at` s.
fn router_chain(dir: &Path, router_args: &[String], events: bool, rc_loss_at: &str) -> Chain {
    let ports = [free_port(), free_port()];
    let a = args(&[
        "router",
        &udpin(ports[0]),
        &udpin(ports[1]),
        "--duration",
        "6",
    ]);
    let a = [a, router_args.to_vec()].concat();
    let mut router = if events {
        Daemon::spawn(dir, "router", &a)
    } else {
        Daemon::spawn_without_events(dir, "router", &a)
    };
    wait_bound(&mut router, &ports);
    let cc = args(&["cc", "--link", &udpout(ports[1]), "--duration", "5.5"]);
    let cc = Daemon::spawn(dir, "cc", &[cc, signed()].concat());
    let fc = args(&[
        "fc-sim",
        "--link",
        &udpout(ports[0]),
        "--rc-loss-at",
        rc_loss_at,
    ]);
    let fc = Daemon::spawn(
        dir,
        "fc",
        &[fc, with(signed(), &["--duration", "5"])].concat(),
    );
    Chain {
        router,
        cc,
        fc,
        ports,
    }
}

impl Chain {
    /// Waits for all three to end on their own: the FC, the companion, the
    /// router.
    fn finish(self) -> [Finished; 3] {
        let limit = Duration::from_secs(20);
        let fc = self.fc.finish(limit);
        let cc = self.cc.finish(limit);
        [fc, cc, self.router.finish(limit)]
    }
}

/// Waits up to 5 s for `d` to bind every port of `ports` (panics with its
/// log otherwise: it did not start).
fn wait_bound(d: &mut Daemon, ports: &[u16]) {
    let until = Instant::now() + Duration::from_secs(5);
    while !ports.iter().all(|p| udp_ports_of(d.pid()).contains(p)) {
        let (alive, log) = (d.alive(), std::fs::read_to_string(&d.log));
        let log = log.unwrap_or_default();
        assert!(alive, "{} exited\n{log}", d.name);
        assert!(
            Instant::now() < until,
            "{} did not bind {ports:?}\n{log}",
            d.name
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A stranger sends a byte every 10 ms to each of the router's `udpin`
/// ports while the FC and the companion use them: the router never sends
/// it the FC's frames, and the handover through the router happens.
#[test]
fn one_byte_datagrams_never_take_the_routers_answers() {
    let dir = scratch("router-udpin");
    let chain = router_chain(&dir, &[], false, "2.5");
    chain
        .cc
        .wait_for("the FC through the router", Duration::from_secs(5), |e| {
            e["event"] == "fc" && e["state"] == "found"
        });
    let byte = || -> Beat { Box::new(|n| vec![vec![n as u8]]) };
    let every = Duration::from_millis(10);
    let strangers = chain
        .ports
        .map(|p| Station::start(0, Some(local(p)), every, byte()));
    let [fc, cc, router] = chain.finish();
    let all = dump(&[&fc, &cc, &router]);
    fc.assert_ran_to_the_end(5.0);
    for s in &strangers {
        let fcs = s
            .frames()
            .iter()
            .filter(|(_, f)| f.from(FC.sysid, FC.compid))
            .count();
        assert_eq!(fcs, 0, "a stranger got {fcs} of the FC's frames\n{all}");
    }
    assert_handover_held(&fc, 1000, &all);
}

/// The companion on the router's `tcpin` port (router and companion
/// signed, `--require-signed`), and a new client every 50 ms (40 kept
/// open, past the 32 a `tcpin` link serves), each sending one unsigned
/// HEARTBEAT as the companion: the companion's connection is never
/// evicted, and the FC hands over within 300 ms of its receiver loss.
#[test]
fn tcp_clients_never_evict_the_signed_companion_from_the_router() {
    let _one = timed();
    let dir = scratch("router-tcpin");
    let (to_fc, tcp) = (free_port(), free_port());
    let mut a = args(&["router", &udpin(to_fc), &format!("tcpin:127.0.0.1:{tcp}")]);
    a.extend([signed(), args(&["--duration", "6.5"])].concat());
    let mut router = Daemon::spawn_without_events(&dir, "router", &a);
    wait_bound(&mut router, &[to_fc]);
    let link = format!("tcp:127.0.0.1:{tcp}");
    let cc = Daemon::spawn(
        &dir,
        "cc",
        &[args(&["cc", "--link", &link, "--duration", "6"]), signed()].concat(),
    );
    let fc = args(&["fc-sim", "--link", &udpout(to_fc), "--rc-loss-at", "3.5"]);
    let fc = Daemon::spawn(
        &dir,
        "fc",
        &[fc, with(signed(), &["--duration", "5.5"])].concat(),
    );
    cc.wait_for("the FC through the router", Duration::from_secs(5), |e| {
        e["event"] == "fc" && e["state"] == "found"
    });
    let hello = frame(CC, 0, &wire::cc_heartbeat(), None);
    let crowd = TcpCrowd::start(local(tcp), Duration::from_millis(50), 40, hello);
    let (fc, cc) = (
        fc.finish(Duration::from_secs(20)),
        cc.finish(Duration::from_secs(20)),
    );
    let connected = crowd.stop();
    let router = router.finish(Duration::from_secs(20));
    let all = dump(&[&fc, &cc, &router]);
    assert!(connected > 40, "only {connected} clients connected\n{all}");
    fc.assert_ran_to_the_end(5.5);
    // Once connected (the router's listener may come up after the
    // companion's first try), the companion's link never fails again.
    let states: Vec<_> = cc.events.of("link").map(|e| e["state"].clone()).collect();
    let connected_at = states.iter().position(|s| s == "open" || s == "recovered");
    assert!(
        connected_at.is_some_and(|i| states[i..].iter().all(|s| s != "failed"))
            && cc.events.of("fc").all(|e| e["state"] != "lost"),
        "the companion lost its connection: {states:?}\n{all}"
    );
    assert_handover_held(&fc, 300, &all);
}

// ---------------------------------------------------------------------------
// 3. Clocks off.

/// The environment that runs a program on a clock `faketime` off (in
/// libfaketime's FAKETIME syntax), its monotonic clock (tokio's timers)
/// left true; None, with the reason printed, when libfaketime is missing.
fn faked_clock(faketime: &str) -> Option<[(&str, &str); 4]> {
    if !Path::new(LIBFAKETIME).exists() {
        use std::io::Write;
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED: {LIBFAKETIME} is missing (apt-get install libfaketime; scripts/test.sh does)"
        );
        return None;
    }
    Some([
        ("LD_PRELOAD", LIBFAKETIME),
        ("FAKETIME", faketime),
        ("FAKETIME_DONT_FAKE_MONOTONIC", "1"),
        ("FAKETIME_DONT_RESET", "1"),
    ])
}

/// The signing timestamp `fbwag encode` puts on a frame by default (the
/// clock) under `env`: proof that the faked clock reaches the binary.
fn signing_clock_under(env: &[(&str, &str)]) -> u64 {
    use std::io::Write;
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(["encode", "--sign-key", KEY])
        .envs(env.iter().copied())
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .spawn()
        .expect("fbwag encode");
    let line = br#"{"name":"HEARTBEAT","fields":{}}"#;
    child.stdin.take().unwrap().write_all(line).unwrap();
    let out = child.wait_with_output().expect("fbwag encode");
    let frames = frames_in(&out.stdout);
    let sig = frames
        .first()
        .map(|f| f.signature.clone())
        .unwrap_or_default();
    assert_eq!(
        sig.len(),
        SIGNATURE_LEN,
        "fbwag encode signed nothing: {out:?}"
    );
    let mut ts = [0u8; 8];
    ts[..6].copy_from_slice(&sig[1..7]);
    u64::from_le_bytes(ts)
}

/// A signed pair (`--require-signed`) with one side's clock `faketime`
/// off (`skewed_fc`: the FC's, else the companion's): the handover
/// happens within a second of the receiver loss, and holds.
fn skewed(skewed_fc: bool, faketime: &str, expected_offset_s: Option<i64>) {
    let Some(env) = faked_clock(faketime) else {
        return;
    };
    // The faked clock reaches the program: its signing clock is off by
    // what FAKETIME says (1970 reads as 0, before MAVLink's 2015 epoch).
    let ts = signing_clock_under(&env) as i64;
    let off = (ts - timestamp_now() as i64) / 100_000;
    match expected_offset_s {
        Some(o) => assert!(
            (off - o).abs() <= 5,
            "FAKETIME={faketime}: clock off by {off} s"
        ),
        None => assert_eq!(ts, 0, "FAKETIME={faketime}: signing clock {ts}"),
    }
    let _one = timed();
    let dir = scratch("skew");
    let sides = Sides {
        cc: with(signed(), &["--duration", "4"]),
        fc: with(signed(), &["--rc-loss-at", "1.5", "--duration", "3.5"]),
        cc_env: if skewed_fc { &[] } else { &env[..] },
        fc_env: if skewed_fc { &env[..] } else { &[] },
        ..Sides::default()
    };
    let (fc, cc) = Pair::start(&dir, FcLink::CcListens, sides).finish();
    let all = dump(&[&fc, &cc]);
    fc.assert_ran_to_the_end(3.5);
    assert_handover_held(&fc, 1000, &all);
    assert_controls_signed_from_companion(&fc, &all);
}

#[test]
fn a_companion_clock_an_hour_behind_still_hands_over() {
    skewed(false, "-1h", Some(-3600));
}

#[test]
fn a_companion_clock_an_hour_ahead_still_hands_over() {
    skewed(false, "+1h", Some(3600));
}

#[test]
fn a_companion_clock_70_s_behind_still_hands_over() {
    skewed(false, "-70s", Some(-70));
}

#[test]
fn a_companion_clock_at_1970_still_hands_over() {
    skewed(false, "@1970-01-01 00:00:00", None);
}

#[test]
fn an_fc_clock_an_hour_behind_still_hands_over() {
    skewed(true, "-1h", Some(-3600));
}

#[test]
fn an_fc_clock_an_hour_ahead_still_hands_over() {
    skewed(true, "+1h", Some(3600));
}

// ---------------------------------------------------------------------------
// 4. The signing state file.

/// How far a signer's saved timestamp may be ahead of the clock after
/// clean exits (10 µs units: 5 s).
const MAX_SIGNER_LEAD: u64 = 500_000;

/// The `signer` line's value of a signing state file.
fn saved_signer(path: &Path) -> u64 {
    let text = std::fs::read_to_string(path).expect("signing state file");
    text.lines()
        .find_map(|l| l.strip_prefix("signer "))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("no signer timestamp in\n{text}"))
}

/// fc-sim started, then restarted 7 times, quickly, with
/// `--signing-state`, talking to a companion each time (each restart
/// added 10 s to the signer's timestamp: the eighth run signed 70 s ahead
/// of the clock, and the companion's notion of now went with it, past the
/// minute a new stream may lag): its saved timestamp stays within
/// [`MAX_SIGNER_LEAD`] of the clock, and a correctly clocked new sender
/// (the FC's ids on another signing link) is still accepted by the
/// companion, which takes over for its RC loss.
#[test]
fn quick_restarts_never_push_the_signer_ahead_of_the_clock() {
    let dir = scratch("restarts");
    let state = dir.join("fc.state").display().to_string();
    let port = free_port();
    let cc = [
        args(&["cc", "--link", &udpin(port), "--duration", "12"]),
        signed(),
    ]
    .concat();
    let cc = Daemon::spawn(&dir, "cc", &cc);
    let fc = [
        args(&["fc-sim", "--link", &udpout(port), "--duration", "0.3"]),
        signed(),
        args(&["--signing-state", &state]),
    ]
    .concat();
    for run in 0..8 {
        let f = Daemon::spawn(&dir, &format!("fc{run}"), &fc).finish(Duration::from_secs(10));
        assert!(f.status.success(), "{}", f.dump());
    }
    let lead = saved_signer(Path::new(&state)).saturating_sub(timestamp_now());
    assert!(
        lead <= MAX_SIGNER_LEAD,
        "the saved signer is {:.1} s ahead of the clock",
        lead as f64 / 1e5
    );
    cc.wait_for("the FC", Duration::from_secs(2), |e| e["event"] == "fc");
    // The new sender: signing link 9, the clock's timestamps.
    let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut signer = Signer::new(attack::key_bytes(KEY), 9, timestamp_now());
    let event = 4242;
    let taken = |cc: &Daemon| cc.events_now().control_starts().contains(&u64::from(event));
    let until = Instant::now() + Duration::from_secs(3);
    for n in 0u8.. {
        if taken(&cc) || Instant::now() > until {
            break;
        }
        let hb = frame(
            FC,
            n,
            &wire::fc_heartbeat(Authority::Handshake),
            Some(&mut signer),
        );
        let loss = frame(
            FC,
            n,
            &wire::notice(FC, Status::RC_LOST, event),
            Some(&mut signer),
        );
        for f in [hb, loss] {
            socket.send_to(&f, local(port)).unwrap();
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let accepted = taken(&cc);
    let log = std::fs::read_to_string(&cc.log).unwrap_or_default();
    assert!(
        accepted,
        "the companion refused a correctly clocked sender\n{log}"
    );
}

// ---------------------------------------------------------------------------
// 5. A silent autonomy program.

/// `fbwag cc --autonomy` with nothing on that port (the default
/// `--autonomy-fallback decline`): the companion declines the takeover,
/// and the FC goes from CIRCLE to RTL at once, never to FBWAG.
#[test]
fn a_silent_autonomy_declines_and_the_fc_returns_home_at_once() {
    let _one = timed();
    let dir = scratch("silent-decline");
    // Pinned to a port nobody sends from.
    let (aut, program) = (free_port(), free_port());
    let sides = Sides {
        cc: [
            pinned_autonomy(aut, program),
            args(&["--duration", "4"]),
            signed(),
        ]
        .concat(),
        fc: with(signed(), &["--rc-loss-at", "1.5", "--duration", "3.5"]),
        ..Sides::default()
    };
    let (fc, cc) = Pair::start(&dir, FcLink::CcListens, sides).finish();
    let all = dump(&[&fc, &cc]);
    fc.assert_ran_to_the_end(3.5);
    let lost = |e: &Value| e["event"] == "receiver" && e["state"] == "lost";
    let lost_at = fc
        .events
        .0
        .iter()
        .find(|e| lost(e))
        .map(|e| e["t_ms"].as_u64().unwrap_or(0));
    let lost_at = lost_at.unwrap_or_else(|| panic!("no receiver loss\n{all}"));
    let outage = fc.events.after(lost);
    assert_eq!(outage.modes(), ["CIRCLE", "RTL"], "{all}");
    let rtl = outage.of("mode").find(|e| e["mode"] == "RTL").unwrap();
    let rtl_after = rtl["t_ms"].as_u64().unwrap_or(u64::MAX) - lost_at;
    assert!(
        rtl_after <= 700,
        "RTL {rtl_after} ms after the receiver loss\n{all}"
    );
    assert_eq!(fc.events.of("control_applied").count(), 0, "{all}");
    assert!(cc.events.control_starts().is_empty(), "{all}");
    let declined = cc
        .events
        .of("takeover")
        .any(|e| e["decision"] == "declined" && e["reason"] == "autonomy silent");
    assert!(declined, "no declined takeover event\n{all}");
}

/// `--autonomy-fallback wings-level`: the companion takes over and flies
/// wings level while the autonomy is silent, then the autonomy's control
/// once it speaks; companion control holds throughout.
#[test]
fn a_silent_autonomy_with_the_wings_level_fallback_is_flown_for() {
    let dir = scratch("silent-wings-level");
    let (aut, program) = (free_port(), free_port());
    let cc = [
        pinned_autonomy(aut, program),
        args(&["--autonomy-fallback", "wings-level"]),
    ];
    let sides = Sides {
        cc: [cc.concat(), signed(), args(&["--duration", "5"])].concat(),
        fc: with(signed(), &["--rc-loss-at", "1", "--duration", "4.5"]),
        ..Sides::default()
    };
    let pair = Pair::start(&dir, FcLink::CcListens, sides);
    pair.fc.wait_for("handover", Duration::from_secs(5), |e| {
        e["event"] == "handover"
    });
    std::thread::sleep(Duration::from_millis(700));
    let speaks: Beat = Box::new(|n| {
        vec![
            frame(AUTONOMY, n as u8, &wire::cc_heartbeat(), None),
            frame(AUTONOMY, n as u8, &override_chan1(AUTONOMY_CHAN1), None),
        ]
    });
    let _autonomy = Station::start(program, Some(local(aut)), Duration::from_millis(50), speaks);
    let (fc, cc) = pair.finish();
    let all = dump(&[&fc, &cc]);
    fc.assert_ran_to_the_end(4.5);
    assert_handover_held(&fc, 1000, &all);
    assert_controls_signed_from_companion(&fc, &all);
    let chan1: Vec<u64> = applied_channels(&fc).iter().map(|c| c[0]).collect();
    let first = chan1.iter().position(|&c| c == u64::from(AUTONOMY_CHAN1));
    let first = first.unwrap_or_else(|| panic!("the autonomy's control never applied\n{all}"));
    assert!(
        first >= 5,
        "{first} controls applied before the autonomy spoke\n{all}"
    );
    let later = &chan1[first..];
    let theirs = later
        .iter()
        .filter(|&&c| c == u64::from(AUTONOMY_CHAN1))
        .count();
    assert!(
        theirs >= 10 && later.len() - theirs <= 2,
        "after the autonomy spoke: {later:?}\n{all}"
    );
}

/// `--autonomy-peer` names the autonomy program's address: a second
/// program on another port streaming control (the attacker's [`MARK`]
/// channels) is dropped; only the named program's control is applied.
#[test]
fn the_autonomy_peer_flag_pins_the_autonomy_program() {
    let dir = scratch("autonomy-peer");
    let (aut, program) = (free_port(), free_port());
    let control = |who: Peer, chan1: u16| -> Beat {
        Box::new(move |n| {
            vec![
                frame(who, n as u8, &wire::cc_heartbeat(), None),
                frame(who, n as u8, &override_chan1(chan1), None),
            ]
        })
    };
    let every = Duration::from_millis(50);
    let _program = Station::start(
        program,
        Some(local(aut)),
        every,
        control(AUTONOMY, AUTONOMY_CHAN1),
    );
    let intruder = Peer::new(1, 43);
    let _intruder = Station::start(
        0,
        Some(local(aut)),
        Duration::from_millis(20),
        control(intruder, MARK[0]),
    );
    let cc = [
        args(&[
            "--autonomy",
            &udpin(aut),
            "--autonomy-peer",
            &format!("127.0.0.1:{program}"),
        ]),
        signed(),
        args(&["--duration", "4"]),
    ];
    let sides = Sides {
        cc: cc.concat(),
        fc: with(signed(), &["--rc-loss-at", "1", "--duration", "3.5"]),
        ..Sides::default()
    };
    let (fc, cc) = Pair::start(&dir, FcLink::CcListens, sides).finish();
    let all = dump(&[&fc, &cc]);
    fc.assert_ran_to_the_end(3.5);
    assert_handover_held(&fc, 1000, &all);
    let applied = applied_channels(&fc);
    assert!(
        applied.len() >= 10,
        "{} controls applied\n{all}",
        applied.len()
    );
    for ch in &applied {
        assert!(
            ch[0] == u64::from(AUTONOMY_CHAN1) && !is_attackers(ch),
            "control not from the named program: {ch:?}\n{all}"
        );
    }
}

// ---------------------------------------------------------------------------
// 6. Strangers on a ground station's port.

/// The FC's frames `st` received in `from..to` (its clock).
fn fc_frames_between(st: &Station, from: Duration, to: Duration) -> usize {
    st.frames()
        .iter()
        .filter(|(at, f)| *at >= from && *at < to && f.from(FC.sysid, FC.compid))
        .count()
}

/// Waits up to `limit` for `st` to receive a frame of the FC.
fn wait_for_fc(st: &Station, limit: Duration, what: &str) {
    let until = Instant::now() + limit;
    while st
        .frames()
        .iter()
        .all(|(_, f)| !f.from(FC.sysid, FC.compid))
    {
        assert!(
            Instant::now() < until,
            "{what}: no frame of the FC within {limit:?}"
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A ground station on `--out udpin` (a HEARTBEAT a second as 255/190),
/// then a stranger sending a byte every 10 ms to the same port: the
/// station gets at least 90 % of the FC's frames it got before, and the
/// stranger none.
#[test]
fn one_byte_datagrams_never_crowd_out_the_ground_station() {
    let _one = timed();
    let dir = scratch("gcs-bytes");
    let gcs = free_port();
    let ground = Station::start(
        0,
        Some(local(gcs)),
        Duration::from_secs(1),
        heartbeat_of(GCS),
    );
    let sides = Sides {
        cc: [args(&["--out", &udpin(gcs), "--duration", "8"]), signed()].concat(),
        fc: with(signed(), &["--duration", "7.5"]),
        ..Sides::default()
    };
    let pair = Pair::start(&dir, FcLink::CcListens, sides);
    wait_for_fc(&ground, Duration::from_secs(5), "the ground station");
    let window = Duration::from_millis(2500);
    let quiet = ground.elapsed() + Duration::from_millis(300);
    std::thread::sleep(window + Duration::from_millis(300));
    let byte: Beat = Box::new(|n| vec![vec![n as u8]]);
    let stranger = Station::start(0, Some(local(gcs)), Duration::from_millis(10), byte);
    let attacked = ground.elapsed() + Duration::from_millis(300);
    std::thread::sleep(window + Duration::from_millis(300));
    let before = fc_frames_between(&ground, quiet, quiet + window);
    let during = fc_frames_between(&ground, attacked, attacked + window);
    let stolen = stranger
        .frames()
        .iter()
        .filter(|(_, f)| f.from(FC.sysid, FC.compid))
        .count();
    drop(stranger);
    let (fc, cc) = pair.finish();
    let all = dump(&[&fc, &cc]);
    println!("the FC's frames at the ground station: {before} without the stranger, {during} with");
    assert!(
        before >= 20,
        "only {before} frames of the FC before the stranger\n{all}"
    );
    assert!(
        during * 10 >= before * 9,
        "the ground station got {during} frames of the FC with the stranger, {before} without\n{all}"
    );
    assert_eq!(stolen, 0, "the stranger got the FC's frames\n{all}");
}

/// HEARTBEATs of 200 system ids (2,000 a second) into the companion's FC
/// link port and into its ground station's port, while the station asks
/// the FC for a parameter every 50 ms (unsigned pair: fc-sim serves any
/// station): at least 95 % are answered (the FC's route is never evicted,
/// the station never crowded out).
#[test]
fn heartbeats_of_200_strangers_never_cut_the_station_off_the_fc() {
    let _one = timed();
    let dir = scratch("gcs-200-ids");
    let gcs = free_port();
    let ground = Station::start(
        0,
        Some(local(gcs)),
        Duration::from_secs(1),
        heartbeat_of(GCS),
    );
    let sides = Sides {
        cc: args(&["--out", &udpin(gcs), "--duration", "7"]),
        fc: args(&["--duration", "6.5"]),
        ..Sides::default()
    };
    let pair = Pair::start(&dir, FcLink::CcListens, sides);
    wait_for_fc(&ground, Duration::from_secs(5), "the ground station");
    let strangers = |_: &mut rand_pcg::Pcg64, n: u64| {
        let who = Peer::new(2 + (n % 200) as u8, 1);
        frame(who, (n / 200) as u8, &wire::cc_heartbeat(), None)
    };
    let flood = Attacker::start(&[local(pair.cc_fc_port), local(gcs)], 2000.0, 0, strangers);
    std::thread::sleep(Duration::from_millis(500));
    let asked_from = ground.elapsed();
    let mut asked = 0u32;
    for n in 0..60u8 {
        let read = ParamRequestRead {
            target_system: FC.sysid,
            target_component: FC.compid,
            param_id: [0; 16],
            param_index: i16::from(n % 12),
        };
        asked += u32::from(ground.send(&frame(GCS, n, &read, None)));
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_millis(500));
    let sent = flood.stop();
    let answered = ground
        .frames()
        .iter()
        .filter(|(at, f)| {
            *at >= asked_from && f.from(FC.sysid, FC.compid) && f.msgid == PARAM_VALUE
        })
        .count() as u32;
    let (fc, cc) = pair.finish();
    let all = dump(&[&fc, &cc]);
    println!("{answered} of {asked} parameter requests answered");
    assert!(sent.datagrams > 4000, "{sent:?}");
    assert!(asked == 60, "{asked} requests sent");
    assert!(
        answered * 100 >= asked * 95,
        "{answered} of {asked} parameter requests answered\n{all}"
    );
}

/// `--out udpout` to a ground station: frames sent to the companion's
/// socket of that link from another address (a PARAM_SET as the station,
/// 100 a second) are not routed to the FC; the station's own are.
#[test]
fn forged_frames_to_the_companions_udpout_socket_are_not_routed() {
    let dir = scratch("gcs-udpout");
    let ground = Station::listen(0);
    let gcs = ground.addr.port();
    let sides = Sides {
        cc: args(&["--out", &udpout(gcs), "--duration", "4"]),
        fc: args(&["--duration", "3.5"]),
        ..Sides::default()
    };
    let pair = Pair::start(&dir, FcLink::CcListens, sides);
    wait_for_fc(&ground, Duration::from_secs(5), "the ground station");
    // The companion's socket: where the station hears the FC from.
    let socket = ground.received()[0].from;
    let set = |value: f32| ParamSet {
        target_system: FC.sysid,
        target_component: FC.compid,
        param_id: chars("AIRSPEED_CRUISE"),
        param_value: value,
        ..Default::default()
    };
    let forged = frame(GCS, 0, &set(25.0), None);
    let forger = Attacker::start(&[socket], 100.0, 0, move |_, _| forged.clone());
    std::thread::sleep(Duration::from_millis(1000));
    for n in 0..3 {
        assert!(ground.send(&frame(GCS, n, &set(20.0), None)));
        std::thread::sleep(Duration::from_millis(200));
    }
    let (fc, cc) = pair.finish();
    let sent = forger.stop();
    let all = dump(&[&fc, &cc]);
    assert!(sent.datagrams > 100, "{sent:?}");
    let set_to = |v: f64| {
        fc.events
            .of("param")
            .filter(|e| e["value"].as_f64() == Some(v))
            .count()
    };
    assert!(
        set_to(20.0) > 0,
        "the station's own PARAM_SET was not routed\n{all}"
    );
    assert_eq!(
        set_to(25.0),
        0,
        "the forged PARAM_SET was routed to the FC\n{all}"
    );
}

// ---------------------------------------------------------------------------
// 7. Drops by reason.

/// A signed pair and a forger on the path between them sending unsigned
/// frames as the FC, from the FC's address (so they are the peer's, but
/// for the signature): the companion's summary counts them as
/// [`UNAUTHENTICATED`] drops.
#[test]
fn the_companion_counts_unsigned_frames_as_the_fc_as_unauthenticated() {
    let dir = scratch("cc-drops");
    let cc = free_port();
    let relay = OnPath::start(local(cc), 200.0, 0, forged_datagram(1));
    let fc_to = relay.fc_side.port();
    let sides = Sides {
        cc: with(signed(), &["--duration", "3"]),
        fc: with(signed(), &["--duration", "2.5"]),
        ..Sides::default()
    };
    let (fc, cc) = Pair::start(&dir, FcLink::Relayed { cc, fc_to }, sides).finish();
    let sent = relay.stop();
    assert!(sent.datagrams > 200, "{sent:?}");
    let n = dropped(&cc, UNAUTHENTICATED);
    assert!(
        n > 100,
        "{n} dropped as {UNAUTHENTICATED:?}\n{}",
        dump(&[&fc, &cc])
    );
}

/// The same through `fbwag router --sign-key --require-signed`: its
/// summary counts the forger's frames as [`UNAUTHENTICATED`] drops, and
/// the handover through it happens.
#[test]
fn the_router_counts_unsigned_frames_as_the_fc_as_unauthenticated() {
    let dir = scratch("router-drops");
    let chain = router_chain(&dir, &signed(), true, "2.5");
    let to_fc = local(chain.ports[0]);
    let forger = Attacker::start(&[to_fc], 200.0, 0, |_, n| forged_fc_frame(n));
    let [fc, cc, router] = chain.finish();
    let sent = forger.stop();
    let all = dump(&[&fc, &cc, &router]);
    assert!(sent.datagrams > 200, "{sent:?}");
    let n = dropped(&router, UNAUTHENTICATED);
    assert!(n > 100, "{n} dropped as {UNAUTHENTICATED:?}\n{all}");
    assert_handover_held(&fc, 1000, &all);
}

// ---------------------------------------------------------------------------
// 8. Trust at the edges: no frame chooses who flies; beacons, restarts,
//    the autonomy's port and replays that no stranger can turn.

/// FBWAG_NOTICE's id and its `failsafe_status` offset (after the u32
/// timestamp and the two ids).
const FBWAG_NOTICE: u32 = 15001;
const NOTICE_STATUS_AT: usize = 6;

/// The event of the first RC-loss notice of the FC `st` received, waiting
/// up to `limit`.
fn rc_loss_event(st: &Station, limit: Duration) -> Option<u32> {
    let until = Instant::now() + limit;
    while Instant::now() < until {
        let event = st.frames().iter().find_map(|(_, f)| {
            let lost = f.payload.get(NOTICE_STATUS_AT) == Some(&1);
            (f.from(FC.sysid, FC.compid) && f.msgid == FBWAG_NOTICE && lost).then(|| f.u32_at(0))
        });
        if event.is_some() {
            return event;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    None
}

/// A local process that binds the `--trusted-out` port first (deploy/
/// cc.toml's, free while MAVSDK is not running) tries what would make it
/// fly: PARAM_SETs naming it the FC's companion (FBWAG_CC_COMPID = 77,
/// FBWAG_CC_SYSID = 77) and keeping the failsafe off (FS_SHORT_TIMEOUT
/// 25.5), then at the RC loss an acknowledgement as 1/77 and its control.
/// The companion signs none of the parameters on (counted `protected`),
/// the FC changes none, the takeover is the companion's, every control
/// applied is the companion's, and the FC's confirmation names it. (The
/// FC accepted the writes, then 1/77's takeover and 220 of its overrides,
/// while the companion believed for 11 s that it flew.)
#[test]
fn a_frame_on_the_trusted_link_never_changes_who_flies() {
    let _one = timed();
    let dir = scratch("who-flies");
    let squatter = Station::listen(0);
    let sides = Sides {
        cc: [
            signed(),
            args(&["--trusted-out", &udpout(squatter.addr.port())]),
            args(&["--duration", "6"]),
        ]
        .concat(),
        fc: with(signed(), &["--rc-loss-at", "3", "--duration", "5.5"]),
        ..Sides::default()
    };
    let pair = Pair::start(&dir, FcLink::CcListens, sides);
    wait_for_fc(&squatter, Duration::from_secs(5), "the squatter");
    let intruder = Peer::new(1, 77);
    let set = |name: &str, value: f32| ParamSet {
        target_system: FC.sysid,
        target_component: FC.compid,
        param_id: chars(name),
        param_value: value,
        ..Default::default()
    };
    let writes = [
        set("FBWAG_CC_COMPID", 77.0),
        set("FBWAG_CC_SYSID", 77.0),
        set("FS_SHORT_TIMEOUT", 25.5),
    ];
    for (n, w) in writes.iter().enumerate() {
        assert!(squatter.send(&frame(GCS, n as u8, w, None)));
    }
    let event = rc_loss_event(&squatter, Duration::from_secs(6));
    let event = event.unwrap_or_else(|| panic!("no RC-loss notice reached the squatter"));
    let ack = wire::notice(FC, Status::CC_TAKEOVER_CONFIRMED, event);
    for n in 0..20u8 {
        squatter.send(&frame(intruder, n, &ack, None));
        squatter.send(&frame(intruder, n, &override_chan1(MARK[0]), None));
        std::thread::sleep(Duration::from_millis(50));
    }
    let (fc, cc) = pair.finish();
    let all = dump(&[&fc, &cc]);
    assert_eq!(fc.events.of("param").count(), 0, "{all}");
    assert!(dropped(&cc, "protected") >= 3 + 20, "{all}");
    assert_handover_held(&fc, 1000, &all);
    assert_controls_signed_from_companion(&fc, &all);
    assert!(
        fc.log.contains("FBWAG-ACK: CC has taken over! 1/191"),
        "the FC's confirmation names the companion\n{all}"
    );
}

/// A keyless replayer of one old signed heartbeat of the companion, 100
/// datagrams a second to the FC's listening port, with the companion an
/// hour behind (a board without a real-time clock, and no state file):
/// the companion still gets the FC's time beacon and hands over. (The
/// replayer took the one beacon a second: every handover ended in RTL.)
#[test]
fn a_replayer_never_steals_the_time_beacon_of_a_companion_behind() {
    let Some(env) = faked_clock("-1h") else {
        return;
    };
    let _one = timed();
    let dir = scratch("beacon-theft");
    let port = free_port();
    // Signed with the key two minutes ago (recorded then): stale, as the
    // companion's own frames are until it adopts the FC's time.
    let mut signer = Signer::new(key_bytes(KEY), 0, timestamp_now() - 12_000_000);
    let old = frame(CC, 0, &wire::cc_heartbeat(), Some(&mut signer));
    let replayer = Attacker::start(&[local(port)], 100.0, 0, move |_, _| old.clone());
    let fc = Daemon::spawn(
        &dir,
        "fc",
        &[
            args(&["fc-sim", "--link", &udpin(port)]),
            with(signed(), &["--rc-loss-at", "3", "--duration", "5"]),
        ]
        .concat(),
    );
    // Half a second out of phase with the FC's start: a beacon a second
    // for whoever asks first goes to the replayer, every time.
    std::thread::sleep(Duration::from_millis(500));
    let cc = Daemon::spawn_with_env(
        &dir,
        "cc",
        &[
            args(&["cc", "--link", &udpout(port)]),
            with(signed(), &["--duration", "5.5"]),
        ]
        .concat(),
        &env,
    );
    let (fc, cc) = (
        fc.finish(Duration::from_secs(30)),
        cc.finish(Duration::from_secs(30)),
    );
    let sent = replayer.stop();
    let all = dump(&[&fc, &cc]);
    assert!(sent.datagrams > 300, "{sent:?}");
    fc.assert_ran_to_the_end(5.0);
    assert_handover_held(&fc, 1000, &all);
    assert_controls_signed_from_companion(&fc, &all);
}

/// A signed pair, one side an hour behind without a state file; that side
/// restarts on a new port while the other side's link still answers the
/// old one. It is trusted again at its next frames (the other side's time
/// beacon goes to its new address) and the next RC loss is handed over.
/// The companion restarting behind a listening FC, and the FC restarting
/// behind a listening companion. (The listening side sent no beacon while
/// it answered the dead address, refused every frame as stale, and every
/// later RC loss ended in RTL.)
#[test]
fn a_skewed_peer_that_restarts_on_a_new_port_is_trusted_again() {
    let Some(env) = faked_clock("-1h") else {
        return;
    };
    let _one = timed();
    for restarting_fc in [false, true] {
        let dir = scratch("skewed-restart");
        let port = free_port();
        let side = |program: &str, conn: String, more: &[&str]| {
            [args(&[program, "--link", &conn]), with(signed(), more)].concat()
        };
        // The listener runs 7 s; the other side restarts 2.5 s in, and
        // the FC's receiver fails 5 s in (its own clock starts with it).
        let (listener, first, second) = if restarting_fc {
            (
                side("cc", udpin(port), &["--duration", "7"]),
                side("fc-sim", udpout(port), &["--duration", "30"]),
                side(
                    "fc-sim",
                    udpout(port),
                    &["--rc-loss-at", "2.5", "--duration", "4.5"],
                ),
            )
        } else {
            (
                side(
                    "fc-sim",
                    udpin(port),
                    &["--rc-loss-at", "5", "--duration", "7"],
                ),
                side("cc", udpout(port), &["--duration", "30"]),
                side("cc", udpout(port), &["--duration", "4.5"]),
            )
        };
        let listener = Daemon::spawn(&dir, "listener", &listener);
        let mut first = Daemon::spawn_with_env(&dir, "first", &first, &env);
        std::thread::sleep(Duration::from_millis(2500));
        first.kill();
        let second = Daemon::spawn_with_env(&dir, "second", &second, &env);
        let (listener, second) = (
            listener.finish(Duration::from_secs(30)),
            second.finish(Duration::from_secs(30)),
        );
        let all = dump(&[&listener, &second]);
        let fc = if restarting_fc { &second } else { &listener };
        assert_handover_held(fc, 1000, &all);
        assert_controls_signed_from_companion(fc, &all);
    }
}

/// A listening autonomy link names its program or admits anyone on
/// purpose: without `--autonomy-peer` (or with port 0, any program of the
/// host) `fbwag cc` refuses to start, saying why; `any` is taken.
#[test]
fn a_listening_autonomy_link_must_name_its_program() {
    let run = |extra: &[&str]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(["cc", "--link", "udpout:127.0.0.1:9", "--duration", "0.2"])
            .args(["--autonomy", "udpin:127.0.0.1:0"])
            .args(extra)
            .output()
            .expect("fbwag cc");
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        (out.status.code(), err)
    };
    let (code, err) = run(&[]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--autonomy-peer IP:PORT"), "{err}");
    let (code, err) = run(&["--autonomy-peer", "127.0.0.1:0"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("port 0 admits every program"), "{err}");
    // Taken: the companion runs (and, no FC being there, ends with 1).
    let (code, err) = run(&["--autonomy-peer", "any"]);
    assert_eq!(code, Some(1), "{err}");
}

/// A local program that speaks first on the autonomy's port, and keeps
/// speaking, never flies: the link is pinned to the autonomy's port. The
/// autonomy restarts (the same port) half a second before the RC loss:
/// it is heard at once, the takeover is not declined, and every control
/// applied is its own. (Unpinned, the squatter flew the takeover; after
/// the autonomy restarted on a new port it counted as silent for 2.5 s,
/// an RC loss then was declined, and the squatter took the slot.)
#[test]
fn a_squatter_never_flies_and_a_pinned_autonomy_is_heard_again_at_once() {
    let _one = timed();
    let dir = scratch("autonomy-squatter");
    let (aut, program) = (free_port(), free_port());
    let control = |who: Peer, chan1: u16| -> Beat {
        Box::new(move |n| {
            vec![
                frame(who, n as u8, &wire::cc_heartbeat(), None),
                frame(who, n as u8, &override_chan1(chan1), None),
            ]
        })
    };
    let every = Duration::from_millis(50);
    let squatter = Station::start(
        0,
        Some(local(aut)),
        every,
        control(Peer::new(1, 43), MARK[0]),
    );
    std::thread::sleep(Duration::from_millis(300));
    let sides = Sides {
        cc: [
            pinned_autonomy(aut, program),
            signed(),
            args(&["--duration", "5.5"]),
        ]
        .concat(),
        fc: with(signed(), &["--rc-loss-at", "3", "--duration", "5"]),
        ..Sides::default()
    };
    let pair = Pair::start(&dir, FcLink::CcListens, sides);
    let first = Station::start(
        program,
        Some(local(aut)),
        every,
        control(AUTONOMY, AUTONOMY_CHAN1),
    );
    std::thread::sleep(Duration::from_millis(2300));
    drop(first);
    std::thread::sleep(Duration::from_millis(200));
    let _again = Station::start(
        program,
        Some(local(aut)),
        every,
        control(AUTONOMY, AUTONOMY_CHAN1),
    );
    let (fc, cc) = pair.finish();
    drop(squatter);
    let all = dump(&[&fc, &cc]);
    assert_handover_held(&fc, 1000, &all);
    assert_controls_signed_from_companion(&fc, &all);
    let chan1: Vec<u64> = applied_channels(&fc).iter().map(|c| c[0]).collect();
    assert!(
        !chan1.is_empty() && chan1.iter().all(|&c| c == u64::from(AUTONOMY_CHAN1)),
        "applied: {chan1:?}\n{all}"
    );
    assert!(
        cc.events
            .of("takeover")
            .all(|e| e["decision"] != "declined"),
        "{all}"
    );
}

/// `fbwag router` with the key on every link: a keyless listener on a
/// ground link (udpout to it) receives the companion's signed frames and
/// replays each back into that link. The replays are refused (the links
/// share one replay window per key) and never reach the FC's link. (With
/// a window per link all 15 were accepted and routed to the FC.)
#[test]
fn the_routers_links_share_one_replay_window() {
    use std::net::UdpSocket;
    let dir = scratch("router-replay");
    let (from_cc, listener, fc) = (free_port(), free_port(), Station::listen(0));
    let replayer = UdpSocket::bind(local(listener)).unwrap();
    replayer
        .set_read_timeout(Some(Duration::from_millis(20)))
        .unwrap();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop2 = stop.clone();
    let replays = std::thread::spawn(move || {
        let (mut buf, mut n) = ([0u8; 2048], 0u32);
        while !stop2.load(std::sync::atomic::Ordering::Relaxed) {
            if let Ok((len, from)) = replayer.recv_from(&mut buf) {
                n += u32::from(replayer.send_to(&buf[..len], from).is_ok());
            }
        }
        n
    });
    let router = Daemon::spawn(
        &dir,
        "router",
        &[
            args(&["router", &udpin(from_cc), &udpout(listener)]),
            args(&[&udpout(fc.addr.port())]),
            with(signed(), &["--duration", "3"]),
        ]
        .concat(),
    );
    assert!(
        common_udp_bound(from_cc),
        "the router never listened on {from_cc}"
    );
    let cc = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let mut signer = Signer::new(key_bytes(KEY), 0, timestamp_now());
    for n in 0..15u8 {
        let hb = frame(CC, n, &wire::cc_heartbeat(), Some(&mut signer));
        cc.send_to(&hb, local(from_cc)).unwrap();
        std::thread::sleep(Duration::from_millis(100));
    }
    let router = router.finish(Duration::from_secs(10));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let replayed = replays.join().unwrap();
    let to_fc = fc
        .frames()
        .iter()
        .filter(|(_, f)| f.from(CC.sysid, CC.compid))
        .count();
    let all = router.dump();
    assert!(replayed >= 15, "{replayed} replays\n{all}");
    assert_eq!(to_fc, 15, "each frame once, no replay\n{all}");
}

/// Whether something bound UDP `port` on 127.0.0.1 within 10 s.
fn common_udp_bound(port: u16) -> bool {
    let until = Instant::now() + Duration::from_secs(10);
    while Instant::now() < until {
        if std::net::UdpSocket::bind(local(port)).is_err() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}
