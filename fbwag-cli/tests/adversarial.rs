//! The live programs under attack: real `fbwag cc` and `fbwag fc-sim`
//! processes over 127.0.0.1, attacked while the receiver fails and control
//! is handed to the companion. Each test asserts safety outcomes from the
//! daemons' `--events` (and log), never timings:
//!
//! - no control is applied unless it came, signed when signing is on, from
//!   the companion, and never the attacker's;
//! - the companion takes over only for the real FC's events;
//! - the handover happens and companion control holds (no RTL) under every
//!   flood the daemons can keep up with;
//! - no daemon answers an attacker on a port of its own;
//! - no daemon exits before its `--duration`, and each writes its summary;
//! - what an attack makes a daemon log is rate-limited.
//!
//! Timed figures (handover under each flood, parser MB/s) are in
//! benches/scripts/handover_under_flood.sh and BENCHMARKS.md.
//!
//! Where the attacker stands decides what it reaches (docs/delegation.md,
//! "The node: every frame's fate, decided once"), and each test says which
//! of these it attacks from, and asserts that the attack got as far as it
//! can:
//!
//! - a port of its own, to a daemon that listens (`udpin`): its bytes reach
//!   the link's parser, which refuses garbage and bad or stale signatures;
//!   its frames are dropped by the node before the engine (`not_peer`),
//!   unless they may make their source the peer (a verified frame; without
//!   signing, the peer's ids while the link has no peer or its peer has
//!   been silent 3 s);
//! - a port of its own, to a daemon's `udpout` socket: nothing reaches it
//!   (the socket is connected to its target, and the system drops every
//!   other sender's datagrams);
//! - the path between the daemons ([`OnPath`]), or the address a daemon
//!   sends to: its frames come from the peer's address and reach the
//!   engine; only signing tells them apart (`unauthenticated`).
//!
//! The set-ups: a pair where the CC listens and the FC sends to it; the
//! same the other way round ([`Listens`]); both at once, where an attack
//! must reach each daemon's parser and show that each `udpout` socket
//! heard nothing of it; and a pair through an on-path relay. Floods share
//! the machine's two cores with the daemons: one flood at a time (the
//! `HEAVY` lock). Garbage floods run at a quarter of what the binary under
//! test parses of them (measured first, so they load an unoptimised build
//! and, later, a faster parser alike), except one that is over capacity on
//! purpose; small-datagram floods at fixed rates.

#[path = "common/attack.rs"]
mod attack;
#[path = "common/live.rs"]
mod live;

use attack::*;
use fbwag_delegation::{wire, Status};
use live::*;
use std::sync::Mutex;
use std::time::Duration;

/// One flood at a time.
static HEAVY: Mutex<()> = Mutex::new(());

fn heavy() -> std::sync::MutexGuard<'static, ()> {
    HEAVY.lock().unwrap_or_else(|e| e.into_inner())
}

/// How a pair is run.
#[derive(Clone)]
struct Setup {
    signed: bool,
    rc_loss_at: f64,
    rc_back_at: Option<f64>,
    /// The FC's run; the CC runs half a second longer (it starts first).
    duration: f64,
    cc_args: Vec<String>,
}

impl Setup {
    /// Signed both ways, RC lost at 1 s; long enough that the daemons log
    /// their parser counters once (at 5 s), which proves an attack arrived.
    fn signed() -> Setup {
        Setup {
            signed: true,
            rc_loss_at: 1.0,
            rc_back_at: None,
            duration: 5.5,
            cc_args: Vec::new(),
        }
    }

    fn unsigned() -> Setup {
        Setup {
            signed: false,
            ..Setup::signed()
        }
    }

    fn signing_args(&self) -> Vec<String> {
        if self.signed {
            args(&["--sign-key", KEY, "--require-signed"])
        } else {
            Vec::new()
        }
    }

    fn cc_duration(&self) -> f64 {
        self.duration + 0.5
    }
}

fn udpin(port: u16) -> String {
    format!("udpin:127.0.0.1:{port}")
}

fn udpout(port: u16) -> String {
    format!("udpout:127.0.0.1:{port}")
}

/// A CC listening on `cc_port`.
fn cc_args(cc_port: u16, s: &Setup, duration: f64) -> Vec<String> {
    cc_args_on(&udpin(cc_port), s, duration)
}

fn cc_args_on(link: &str, s: &Setup, duration: f64) -> Vec<String> {
    let mut a = args(&["cc", "--link", link]);
    a.extend(args(&["--duration", &duration.to_string()]));
    a.extend(s.signing_args());
    a.extend(s.cc_args.iter().cloned());
    a
}

/// An FC sending to port `to`.
fn fc_args(to: u16, s: &Setup, rc_loss_at: f64, duration: f64) -> Vec<String> {
    fc_args_on(&udpout(to), s, rc_loss_at, duration)
}

fn fc_args_on(link: &str, s: &Setup, rc_loss_at: f64, duration: f64) -> Vec<String> {
    let mut a = args(&["fc-sim", "--link", link]);
    a.extend(args(&["--rc-loss-at", &rc_loss_at.to_string()]));
    a.extend(args(&["--duration", &duration.to_string()]));
    if let Some(b) = s.rc_back_at {
        a.extend(args(&["--rc-back-at", &b.to_string()]));
    }
    a.extend(s.signing_args());
    a
}

/// Which daemon of a pair listens (`udpin`, answering only the peer its
/// node admits); the other sends to it (`udpout`, its socket connected to
/// the listener).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Listens {
    Cc,
    Fc,
}

/// A CC and an FC talking over loopback.
struct Pair {
    cc: Daemon,
    fc: Daemon,
    /// The CC's port: its `udpin` port, or its `udpout` socket's.
    cc_port: u16,
    /// The FC's port: its `udpout` socket's, or its `udpin` port.
    fc_port: u16,
    listens: Listens,
    setup: Setup,
}

impl Pair {
    /// The CC listens, the FC sends to it.
    fn start(dir: &std::path::Path, s: &Setup) -> Pair {
        Pair::start_with(dir, s, Listens::Cc)
    }

    fn start_with(dir: &std::path::Path, s: &Setup, listens: Listens) -> Pair {
        let (cc, fc, cc_port, fc_port) = match listens {
            Listens::Cc => {
                let cc_port = free_port();
                let cc = Daemon::spawn(dir, "cc", &cc_args(cc_port, s, s.cc_duration()));
                let fc = Daemon::spawn(dir, "fc", &fc_args(cc_port, s, s.rc_loss_at, s.duration));
                let fc_port = udp_port_of(fc.pid());
                (cc, fc, cc_port, fc_port)
            }
            Listens::Fc => {
                let fc_port = free_port();
                let fa = fc_args_on(&udpin(fc_port), s, s.rc_loss_at, s.duration);
                let fc = Daemon::spawn(dir, "fc-udpin", &fa);
                assert_eq!(udp_port_of(fc.pid()), fc_port);
                let ca = cc_args_on(&udpout(fc_port), s, s.cc_duration());
                let cc = Daemon::spawn(dir, "cc-udpout", &ca);
                let cc_port = udp_port_of(cc.pid());
                (cc, fc, cc_port, fc_port)
            }
        };
        Pair {
            cc,
            fc,
            cc_port,
            fc_port,
            listens,
            setup: s.clone(),
        }
    }

    /// Two pairs, one listening each way: an attack on all four ports
    /// reaches each daemon's parser once (where it listens), and shows what
    /// each `udpout` socket hears of it.
    fn both_ways(dir: &std::path::Path, s: &Setup) -> [Pair; 2] {
        [
            Pair::start_with(dir, s, Listens::Cc),
            Pair::start_with(dir, s, Listens::Fc),
        ]
    }

    /// The CC listens, and the FC sends to it through an [`OnPath`] relay
    /// that sends `gen`'s datagrams to both, `per_sec` a second each.
    fn start_on_path(
        dir: &std::path::Path,
        s: &Setup,
        per_sec: f64,
        seed: u64,
        gen: impl FnMut(&mut rand_pcg::Pcg64, u64) -> Vec<u8> + Send + 'static,
    ) -> (Pair, OnPath) {
        let cc_port = free_port();
        let cc = Daemon::spawn(dir, "cc", &cc_args(cc_port, s, s.cc_duration()));
        let on_path = OnPath::start(local(cc_port), per_sec, seed, gen);
        let to = on_path.fc_side.port();
        let fc = Daemon::spawn(dir, "fc", &fc_args(to, s, s.rc_loss_at, s.duration));
        let fc_port = udp_port_of(fc.pid());
        let pair = Pair {
            cc,
            fc,
            cc_port,
            fc_port,
            listens: Listens::Cc,
            setup: s.clone(),
        };
        (pair, on_path)
    }

    fn targets(&self) -> [std::net::SocketAddr; 2] {
        [local(self.cc_port), local(self.fc_port)]
    }

    /// Waits for both to end on their own.
    fn finish(self) -> (Finished, Finished) {
        let limit = Duration::from_secs_f64(self.setup.cc_duration() + 10.0);
        let fc = self.fc.finish(limit);
        let cc = self.cc.finish(limit);
        (fc, cc)
    }

    /// [`finish`](Self::finish), keeping which one listened.
    fn run(self) -> Run {
        let listens = self.listens;
        let (fc, cc) = self.finish();
        Run { fc, cc, listens }
    }
}

/// What a pair reported.
struct Run {
    fc: Finished,
    cc: Finished,
    listens: Listens,
}

impl Run {
    /// The daemon that listened: the one a stranger's datagrams reach.
    fn listener(&self) -> &Finished {
        match self.listens {
            Listens::Cc => &self.cc,
            Listens::Fc => &self.fc,
        }
    }

    /// The daemon that sent to it (`udpout`).
    fn sender(&self) -> &Finished {
        match self.listens {
            Listens::Cc => &self.fc,
            Listens::Fc => &self.cc,
        }
    }

    fn dump(&self) -> String {
        format!("{}\n{}", self.fc.dump(), self.cc.dump())
    }
}

/// Every port of `pairs`.
fn ports_of(pairs: &[Pair]) -> Vec<std::net::SocketAddr> {
    pairs.iter().flat_map(Pair::targets).collect()
}

/// Frames the node of `d` dropped for `reason` (its summary's `dropped`).
fn dropped(d: &Finished, reason: &str) -> u64 {
    d.events
        .last("summary")
        .and_then(|e| e["dropped"][reason].as_u64())
        .unwrap_or_else(|| {
            panic!(
                "{}: no dropped.{reason} in its summary\n{}",
                d.name,
                d.dump()
            )
        })
}

/// A `udpout` daemon whose port was attacked from another port heard none
/// of it: its socket is connected to its target, so the system drops every
/// other sender's datagrams. Its parser refused nothing, its node dropped
/// nothing.
fn assert_heard_nothing(d: &Finished, all: &str) {
    let name = &d.name;
    for kind in [
        "bad checksums",
        "bad signatures",
        "stale signing timestamps",
        "unsigned refused",
        "bytes dropped",
    ] {
        assert_eq!(
            d.refused(kind),
            0,
            "{name}: its udpout socket heard the attacker ({kind})\n{all}"
        );
    }
    for reason in [
        "own_ids",
        "impersonation",
        "unauthenticated",
        "not_peer",
        "gated",
    ] {
        assert_eq!(dropped(d, reason), 0, "{name}: dropped {reason}\n{all}");
    }
}

/// Whether `d`'s links ever answered an address `which` picks (its
/// "<link>: answering <addr>, <addr>" lines).
fn answered(d: &Finished, which: impl Fn(&str) -> bool) -> bool {
    d.log
        .lines()
        .filter_map(|l| l.split_once(": answering "))
        .flat_map(|(_, list)| list.split(", "))
        .any(|a| which(a.trim()))
}

/// Lines `d` logged about frames its node dropped (rate-limited).
fn drop_lines(d: &Finished) -> usize {
    d.log.lines().filter(|l| l.contains(": dropped ")).count()
}

/// Datagrams listening daemon `d` may have sent one replayer: stale
/// frames with its peer's ids that the key signed get their source the
/// node's signed heartbeat (its time beacon), once a second at most to
/// each address (docs/delegation.md, "Signing time"), and nothing else:
/// at most one a second of its run.
fn beacons_at_most(d: &Finished) -> u64 {
    let ms = d.events.last("summary").and_then(|e| e["t_ms"].as_u64());
    let ms = ms.unwrap_or_else(|| panic!("{} has no summary\n{}", d.name, d.dump()));
    ms / 1000 + 1
}

/// The outcome every attacked run must have: both ran their whole time;
/// the FC handed over, and companion control held (no RTL after it); every
/// control applied came from the companion (signed when signing is on) and
/// none is the attacker's; the companion took over only for the FC's real
/// events.
fn assert_safe_handover(fc: &Finished, cc: &Finished, s: &Setup) {
    let both = format!("{}\n{}", fc.dump(), cc.dump());
    fc.assert_ran_to_the_end(s.duration);
    cc.assert_ran_to_the_end(s.cc_duration());
    assert!(fc.events.last("handover").is_some(), "no handover\n{both}");
    let modes = fc.events.modes();
    let after = modes.iter().skip_while(|m| *m != "FBWAG");
    assert!(
        after.clone().all(|m| m == "FBWAG"),
        "companion control did not hold: {modes:?}\n{both}"
    );
    assert_controls_from_companion(fc, s.signed, &both);
    let real = fc.notice_events();
    let starts = cc.events.control_starts();
    assert!(!starts.is_empty(), "the companion never took over\n{both}");
    for e in &starts {
        assert!(
            real.contains(e),
            "takeover for event {e}, not one of the FC's {real:?}\n{both}"
        );
    }
}

/// No `control_applied` is unauthenticated (when signing is on), from
/// anyone but the companion, or the attacker's.
fn assert_controls_from_companion(fc: &Finished, signed: bool, both: &str) {
    for e in fc.events.of("control_applied") {
        assert!(
            e["sysid"] == CC.sysid && e["compid"] == CC.compid,
            "control applied from a stranger: {e}\n{both}"
        );
        if signed {
            assert_eq!(
                e["authenticated"], true,
                "unsigned control applied: {e}\n{both}"
            );
        }
        let ch: Vec<u64> = e["channels"]
            .as_array()
            .map(|a| a.iter().filter_map(|v| v.as_u64()).collect())
            .unwrap_or_default();
        assert!(
            !is_attackers(&ch),
            "the attacker's control applied: {e}\n{both}"
        );
    }
}

// ---------------------------------------------------------------------------
// Floods into both daemons' ports.

/// Datagrams of a flood's garbage.
const FLOOD_DATAGRAM: usize = 1024;
/// Bytes/s per port at most (what the test's sender thread keeps up
/// comfortably; well inside what the daemons parse of random bytes).
const FLOOD_MAX_RATE: f64 = 2.0e6;

/// A quarter of what the binary parses of `kind`, per port, in datagrams/s.
fn flood_rate(dir: &std::path::Path, kind: Garbage) -> f64 {
    let mut rng = rand::SeedableRng::seed_from_u64(1);
    let sample: Vec<u8> = (0..64)
        .flat_map(|_| kind.datagram(&mut rng, FLOOD_DATAGRAM))
        .collect();
    let bytes = (parse_rate(dir, &sample) / 4.0).min(FLOOD_MAX_RATE);
    let per_sec = (bytes / FLOOD_DATAGRAM as f64).max(5.0);
    println!("{kind:?}: {per_sec:.0} datagrams/s of {FLOOD_DATAGRAM} bytes per port");
    per_sec
}

/// A flood from a port of its own into both pairs of [`Pair::both_ways`]:
/// it reaches each listening daemon's parser, and neither `udpout` socket.
fn flood(kind: Garbage, per_sec: f64, len: usize) {
    let dir = scratch(&format!("{kind:?}"));
    let s = Setup::signed();
    let pairs = Pair::both_ways(&dir, &s);
    let attacker = Attacker::start(&ports_of(&pairs), per_sec, 7, move |rng, _| {
        kind.datagram(rng, len)
    });
    let runs = pairs.map(Pair::run);
    let sent = attacker.stop();
    assert!(sent.datagrams > 0, "nothing sent");
    for run in &runs {
        assert_safe_handover(&run.fc, &run.cc, &s);
        let all = run.dump();
        let listener = run.listener();
        assert!(
            listener.refused("bytes dropped") > 0,
            "flood not seen by {}\n{all}",
            listener.name
        );
        assert_heard_nothing(run.sender(), &all);
    }
    assert_eq!(sent.received, 0, "a daemon answered the attacker");
}

/// 1 KB datagrams of random bytes.
#[test]
fn flood_of_random_bytes() {
    let _one = heavy();
    let rate = flood_rate(&scratch("rate"), Garbage::Random);
    flood(Garbage::Random, rate, FLOOD_DATAGRAM);
}

/// 1 KB datagrams of random bytes, half of them 0xFD/0xFE: candidate
/// frames everywhere.
#[test]
fn flood_of_start_byte_dense_garbage() {
    let _one = heavy();
    let rate = flood_rate(&scratch("rate"), Garbage::StartDense);
    flood(Garbage::StartDense, rate, FLOOD_DATAGRAM);
}

/// 1 KB datagrams of the parser's long-known worst pattern
/// (`fefefefdfd0000fe00fe`: every start byte opens a candidate that fails
/// only at its checksum).
#[test]
fn flood_of_the_worst_parser_pattern() {
    let _one = heavy();
    let rate = flood_rate(&scratch("rate"), Garbage::Worst);
    flood(Garbage::Worst, rate, FLOOD_DATAGRAM);
}

/// 300-byte datagrams of the parser's worst input known (`FOUND_K`): at
/// a signed pair its frames are unsigned and refused whole, and each
/// datagram cuts the long candidates' frames. Same bytes per second as a
/// quarter of what the daemons parse of it.
#[test]
fn flood_of_the_worst_input_known_in_small_datagrams() {
    let _one = heavy();
    let per_1k = flood_rate(&scratch("rate"), Garbage::FoundK);
    flood(Garbage::FoundK, per_1k * FLOOD_DATAGRAM as f64 / 300.0, 300);
}

/// 10-byte headers announcing 200–255 payload bytes, one per datagram, at
/// 2,000 datagrams/s per port: a parser that keeps a partial frame across
/// datagrams lets each hold the next real frame back, and mixes up which
/// sender a frame came from.
#[test]
fn flood_of_false_headers() {
    let _one = heavy();
    flood(Garbage::FalseHeader, 2000.0, 10);
}

/// Valid frames from strangers at 2,000/s per port, from a port of their
/// own: notices, takeover acknowledgements, control and FBWAG heartbeats
/// from other ids, and the right ids signed with a wrong key (a SHA-256
/// each for the receiver). A listening daemon's parser refuses the wrong
/// signatures, and its node drops the rest before the engine (`not_peer`):
/// the engine sees none of it. The `udpout` sockets hear nothing.
#[test]
fn flood_of_valid_frames_from_strangers() {
    let _one = heavy();
    let dir = scratch("strangers");
    let s = Setup::signed();
    let pairs = Pair::both_ways(&dir, &s);
    let attacker = Attacker::start(&ports_of(&pairs), 2000.0, 11, stranger_frame);
    let runs = pairs.map(Pair::run);
    let sent = attacker.stop();
    for run in &runs {
        assert_safe_handover(&run.fc, &run.cc, &s);
        let all = run.dump();
        let listener = run.listener();
        assert!(listener.refused("bad signatures") > 0, "{all}");
        assert!(dropped(listener, "not_peer") > 0, "{all}");
        assert_eq!(listener.events.summary("untrusted_frames"), 0, "{all}");
        assert_heard_nothing(run.sender(), &all);
    }
    // Its peer's ids signed with another key, before the peer is heard,
    // look like a peer with the wrong key: a listener answers them with its
    // own heartbeat, once a second at most, so that the mismatch shows on
    // both sides (the node's tests: only while it has no peer). Nothing
    // else, ever.
    let most: u64 = runs.iter().map(|r| beacons_at_most(r.listener())).sum();
    assert_eq!(
        sent.received, sent.heartbeats,
        "a daemon answered the attacker: {sent:?}"
    );
    assert!(sent.received <= most, "{sent:?}, over {most} beacons");
}

/// Datagrams of 64 KB of the worst parser pattern into a listening FC's
/// port, 5 a second: far more than the test build parses (the flood is
/// over capacity, so the companion's frames may be lost with it). Whatever
/// the link delivers, the FC's own timers must run: it notices the receiver
/// loss, and ends its run either in companion control or fallen back to
/// RTL (5 s after its first notice, well before the end of its 8 s), never
/// still in the handshake or with the pilot's failed receiver.
#[test]
fn large_worst_pattern_datagrams_do_not_stall_the_fc_timers() {
    let _one = heavy();
    let dir = scratch("large-worst");
    let s = Setup {
        duration: 8.0,
        ..Setup::signed()
    };
    let pair = Pair::start_with(&dir, &s, Listens::Fc);
    let big = Garbage::Worst.datagram(&mut rand::SeedableRng::seed_from_u64(0), 65_000);
    let attacker = Attacker::start(&[local(pair.fc_port)], 5.0, 0, move |_, _| big.clone());
    let (fc, cc) = pair.finish();
    let sent = attacker.stop();
    let both = format!("{}\n{}", fc.dump(), cc.dump());
    fc.assert_ran_to_the_end(s.duration);
    cc.assert_ran_to_the_end(s.cc_duration());
    assert_eq!(sent.received, 0, "{both}");
    assert!(
        fc.refused("bytes dropped") > 0,
        "the datagrams never reached the FC's parser\n{both}"
    );
    let modes = fc.events.modes();
    assert!(
        modes.contains(&"CIRCLE".into()),
        "receiver loss not acted on\n{both}"
    );
    let last = modes.last().map(String::as_str);
    assert!(
        matches!(last, Some("FBWAG" | "RTL")),
        "ended in {last:?}\n{both}"
    );
    assert_controls_from_companion(&fc, true, &both);
}

// ---------------------------------------------------------------------------
// Spoofed frames without the key.

/// Unsigned forgeries: to the FC, takeover acknowledgements for every event
/// id around the RC loss and control of all three kinds, as the companion
/// and as a ground station; to the CC, RC-loss notices, FBWAG heartbeats and
/// takeover confirmations as the FC.
fn forgeries(rc_loss_ms: u32) -> impl FnMut(&mut rand_pcg::Pcg64, u64) -> Vec<u8> + Send {
    use rand::Rng;
    move |rng, n| {
        let seq = n as u8;
        let who = if n % 2 == 0 { CC } else { GCS };
        // Sweeps every event id the FC can use (its ms at the second bad
        // receiver sample, 100–200 ms after the loss; 50–350 ms covers a
        // slow machine), one id per 8 datagrams, acknowledged as the
        // companion and as a ground station alike.
        let guess = rc_loss_ms + 50 + (n / 8 % 300) as u32;
        match n % 8 {
            0 | 1 => frame(
                [CC, GCS][(n % 8) as usize],
                seq,
                &wire::notice(FC, Status::CC_TAKEOVER_CONFIRMED, guess),
                None,
            ),
            2..=4 => frame(who, seq, controls()[(n % 3) as usize].as_ref(), None),
            5 => frame(FC, seq, &wire::notice(FC, Status::RC_LOST, rng.gen()), None),
            6 => frame(
                FC,
                seq,
                &wire::fc_heartbeat(fbwag_delegation::fc::Authority::Companion),
                None,
            ),
            _ => frame(
                FC,
                seq,
                &wire::status_text(fbwag_delegation::TEXT_CC_TOOK_OVER, guess),
                None,
            ),
        }
    }
}

/// With signing required, unsigned forgeries change nothing: the real
/// companion takes over for the real event, and only its signed control is
/// applied. They are sent both from a port of the attacker's own (the CC's
/// node drops them, `not_peer`; the FC's `udpout` socket never hears them)
/// and on the path, from the addresses the daemons take for their peers:
/// those reach both engines, which trust none of them (`unauthenticated`).
#[test]
fn spoofed_unsigned_frames_with_signing_required() {
    let dir = scratch("spoof-signed");
    let s = Setup::signed();
    let (pair, on_path) = Pair::start_on_path(&dir, &s, 1000.0, 3, forgeries(1000));
    let attacker = Attacker::start(&pair.targets(), 1000.0, 4, forgeries(1000));
    let (fc, cc) = pair.finish();
    let (sent, injected) = (attacker.stop(), on_path.stop());
    assert_safe_handover(&fc, &cc, &s);
    let both = format!("{}\n{}", fc.dump(), cc.dump());
    assert_eq!(sent.received, 0, "a daemon answered the attacker\n{both}");
    assert!(dropped(&cc, "not_peer") > 0, "{both}");
    assert!(fc.events.summary("untrusted_notices") > 0, "{both}");
    assert!(fc.events.summary("controls_untrusted") > 0, "{both}");
    assert!(cc.events.summary("untrusted_notices") > 0, "{both}");
    for d in [&fc, &cc] {
        assert!(dropped(d, "unauthenticated") > 0, "{}\n{both}", d.name);
    }
    // Thousands of forgeries, a few log lines: the dropped-frame log is
    // rate-limited per window (the counts are in the events' summary).
    assert!(
        sent.datagrams > 2000 && injected.datagrams > 2000,
        "{sent:?} {injected:?}"
    );
    for d in [&fc, &cc] {
        let lines = drop_lines(d);
        assert!(
            lines <= 40,
            "{}: {lines} lines about dropped frames\n{both}",
            d.name
        );
    }
}

/// No companion at all, signing required, and the attacker at the address
/// the FC sends to (its `udpout` target, where the companion would be):
/// its frames reach the FC's engine, but forged acknowledgements of every
/// event id and forged control never give it companion control; the FC
/// falls back to RTL when the handshake times out.
#[test]
fn spoofed_takeover_without_the_key_ends_in_rtl() {
    let dir = scratch("spoof-alone");
    let s = Setup {
        rc_loss_at: 0.5,
        duration: 6.5,
        ..Setup::signed()
    };
    let attacker = Attacker::start(&[], 3000.0, 5, forgeries(500));
    let to = attacker.addr.port();
    let fc = Daemon::spawn(&dir, "fc", &fc_args(to, &s, s.rc_loss_at, s.duration));
    attacker.add_target(local(udp_port_of(fc.pid())));
    let fc = fc.finish(Duration::from_secs(20));
    attacker.stop();
    fc.assert_ran_to_the_end(s.duration);
    let modes = fc.events.modes();
    assert!(!modes.contains(&"FBWAG".into()), "{}", fc.dump());
    assert_eq!(
        modes.last().map(String::as_str),
        Some("RTL"),
        "{}",
        fc.dump()
    );
    assert_eq!(fc.events.of("control_applied").count(), 0, "{}", fc.dump());
    assert!(fc.events.summary("untrusted_notices") > 0, "{}", fc.dump());
    assert!(dropped(&fc, "unauthenticated") > 0, "{}", fc.dump());
}

/// The threat model without signing, as it stands (docs/delegation.md):
/// anyone the FC's link hears who spoofs the companion's ids can take
/// control. An FC listening (`udpin`) with no companion yet takes the
/// first source of the companion's ids for its peer: the attacker's forged
/// acknowledgements and overrides put it in companion control flying the
/// attacker's channels, and it answers the attacker. Spoofing a ground
/// station's ids achieves nothing: only the configured companion's control
/// is applied. An FC sending (`udpout`) hears only its target: the same
/// attacker, on a port of its own, never reaches it: it is still asking
/// for a companion when its run ends (the companion's place, its target
/// address, is what the attacker would need). This test pins the behaviour
/// so that a change in it is noticed and documented.
#[test]
fn without_signing_spoofing_the_companion_ids_takes_control() {
    let dir = scratch("spoof-unsigned");
    let s = Setup {
        rc_loss_at: 0.5,
        duration: 3.5,
        ..Setup::unsigned()
    };
    let port = free_port();
    let fa = fc_args_on(&udpin(port), &s, s.rc_loss_at, s.duration);
    let listening = Daemon::spawn(&dir, "fc-udpin", &fa);
    assert_eq!(udp_port_of(listening.pid()), port);
    let fa = fc_args(free_port(), &s, s.rc_loss_at, s.duration);
    let sending = Daemon::spawn(&dir, "fc-udpout", &fa);
    let targets = [local(port), local(udp_port_of(sending.pid()))];
    let attacker = Attacker::start(&targets, 3000.0, 5, forgeries(500));
    let addr = attacker.addr.to_string();
    let listening = listening.finish(Duration::from_secs(20));
    let sending = sending.finish(Duration::from_secs(20));
    let sent = attacker.stop();
    let both = format!("{}\n{}", listening.dump(), sending.dump());
    listening.assert_ran_to_the_end(s.duration);
    sending.assert_ran_to_the_end(s.duration);
    // Listening: taken over.
    assert!(listening.events.modes().contains(&"FBWAG".into()), "{both}");
    let applied: Vec<_> = listening.events.of("control_applied").collect();
    assert!(
        applied.iter().any(|e| {
            let ch: Vec<u64> = e["channels"]
                .as_array()
                .map(|a| a.iter().filter_map(|v| v.as_u64()).collect())
                .unwrap_or_default();
            is_attackers(&ch) && e["authenticated"] == false
        }),
        "{both}"
    );
    assert!(
        applied
            .iter()
            .all(|e| e["sysid"] == CC.sysid && e["compid"] == CC.compid),
        "a ground station's control was applied\n{both}"
    );
    assert!(
        sent.received > 0,
        "the FC never answered the attacker\n{both}"
    );
    assert!(answered(&listening, |a| a == addr), "{both}");
    // Sending: never reached, still asking for a companion at its end.
    assert_eq!(sending.events.modes(), ["FBWA", "CIRCLE"], "{both}");
    assert_eq!(sending.events.of("control_applied").count(), 0, "{both}");
    assert_heard_nothing(&sending, &both);
}

/// A reader of the FC's log and events that stops reading (a full pipe)
/// while a flood of control makes it write an event per frame: the FC
/// runs on, sending telemetry to the end of its run, and exits on time.
/// (Its writes blocked the thread its timers and links run on: it froze
/// about 0.5 s into companion control, and ran past its end.) The flood
/// comes from the FC's `udpout` target, the only address it hears: a
/// socket of the test's own, which also reads what the FC sends.
#[test]
fn a_stalled_reader_of_the_logs_never_stops_a_daemon() {
    use rand::SeedableRng;
    let _heavy = heavy();
    let dir = scratch("stalled-reader");
    let s = Setup {
        rc_loss_at: 0.5,
        duration: 3.5,
        ..Setup::unsigned()
    };
    let target = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    target.set_nonblocking(true).unwrap();
    let to = target.local_addr().unwrap().port();
    let fc = Daemon::spawn_unread(&dir, "fc", &fc_args(to, &s, s.rc_loss_at, s.duration));
    let fc_addr = local(udp_port_of(fc.pid()));
    let (mut forge, mut rng) = (forgeries(500), rand_pcg::Pcg64::seed_from_u64(5));
    let mut parser = fbwag_dialect::Parser::new();
    let (mut last, mut taken_over, mut n) = (Duration::ZERO, false, 0u64);
    let mut buf = [0u8; 2048];
    let started = std::time::Instant::now();
    while started.elapsed() < Duration::from_secs_f64(s.duration + 1.0) {
        // 3,000 forgeries a second.
        while n < (started.elapsed().as_secs_f64() * 3000.0) as u64 {
            let _ = target.send_to(&forge(&mut rng, n), fc_addr);
            n += 1;
        }
        while let Ok(len) = target.recv(&mut buf) {
            last = started.elapsed();
            let mut input = &buf[..len];
            while let Some(r) = parser.next(&mut input) {
                if let Some(fbwag_dialect::Message::Heartbeat(h)) = r.message() {
                    taken_over |= h.custom_mode == fbwag_delegation::mode::FBWAG;
                }
            }
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    let fc = fc.finish(Duration::from_secs(20));
    assert!(fc.status.success(), "{}", fc.dump());
    // The forged takeover reached it: it flew the forged control, an event
    // a frame.
    assert!(
        taken_over,
        "the FC never reported companion control\n{}",
        fc.dump()
    );
    assert!(
        last > Duration::from_secs_f64(s.duration - 1.0),
        "the FC fell silent at {last:?} of its {} s\n{}",
        s.duration,
        fc.dump()
    );
}

/// Without signing, frames with the peer's ids are trusted, and the
/// daemons log the notices (and the FC's texts) they hear: a flood of
/// them, 2,000 a second each way, wrote about 8,000 lines to each log in
/// 4 s. Now at most 20 such lines a second are logged, then a count. The
/// same for the FC's mode changes the companion reports (spoofed
/// heartbeats flapping the mode at 500 a second wrote a line and an event
/// each). The flood comes on the path, from the addresses the daemons
/// take for their peers (from a port of its own, the CC's node would drop
/// it, and the FC's `udpout` socket never hear it).
#[test]
fn a_flood_of_trusted_looking_notices_does_not_flood_the_logs() {
    let _heavy = heavy();
    let dir = scratch("log-flood");
    let s = Setup {
        duration: 4.0,
        ..Setup::unsigned()
    };
    let (pair, on_path) = Pair::start_on_path(&dir, &s, 2000.0, 11, |_, n| {
        if n % 2 == 0 {
            // To the FC, as the companion: a confirmation of no event.
            frame(
                CC,
                n as u8,
                &wire::notice(FC, Status::CC_TAKEOVER_CONFIRMED, 7),
                None,
            )
        } else if n % 4 == 1 {
            // To the companion, as the FC: a hand-back it answered long ago.
            frame(FC, n as u8, &wire::notice(FC, Status::NORMAL, 3), None)
        } else {
            // To the companion, as the FC: a mode change at every frame.
            use fbwag_delegation::fc::Authority;
            let by = [Authority::Pilot, Authority::Companion][(n / 4 % 2) as usize];
            frame(FC, n as u8, &wire::fc_heartbeat(by), None)
        }
    });
    let (fc, cc) = pair.finish();
    let sent = on_path.stop();
    let both = format!("{}\n{}", fc.dump(), cc.dump());
    fc.assert_ran_to_the_end(s.duration);
    cc.assert_ran_to_the_end(s.cc_duration());
    assert!(sent.datagrams > 4000, "{sent:?}");
    for d in [&fc, &cc] {
        let lines = d.log.lines().count();
        assert!(lines < 400, "{}: {lines} lines\n{both}", d.name);
    }
    assert!(fc.log.contains("notices suppressed"), "{both}");
    let modes = cc.events.of("fc_mode").count();
    assert!(modes < 200, "{modes} mode changes reported\n{both}");
}

/// A TCP relay that accepts one connection and carries it to `to` at about
/// `bytes_per_sec` each way: a link of a real serial speed, whose far end
/// holds `far_buffer` bytes (a UART's few KiB), or what the system's
/// receive buffer grows to (`None`: past 100 KiB, seconds of such a link,
/// out of the sender's reach, as a modem's). Ends when either side closes.
fn slow_relay(to: std::net::SocketAddr, bytes_per_sec: f64, far_buffer: Option<usize>) -> u16 {
    use socket2::{Domain, Socket, Type};
    use std::io::{Read, Write};
    let socket = Socket::new(Domain::IPV4, Type::STREAM, None).unwrap();
    if let Some(bytes) = far_buffer {
        socket.set_recv_buffer_size(bytes).unwrap();
    }
    socket.bind(&local(0).into()).unwrap();
    socket.listen(1).unwrap();
    let listener: std::net::TcpListener = socket.into();
    let port = listener.local_addr().unwrap().port();
    std::thread::spawn(move || {
        let Ok((near, _)) = listener.accept() else {
            return;
        };
        let Ok(far) = std::net::TcpStream::connect(to) else {
            return;
        };
        for (mut from, mut into) in [
            (near.try_clone().unwrap(), far.try_clone().unwrap()),
            (far, near),
        ] {
            std::thread::spawn(move || {
                let mut buf = [0u8; 512];
                while let Ok(n @ 1..) = from.read(&mut buf) {
                    if into.write_all(&buf[..n]).is_err() {
                        break;
                    }
                    std::thread::sleep(Duration::from_secs_f64(n as f64 / bytes_per_sec));
                }
                let _ = into.shutdown(std::net::Shutdown::Both);
            });
        }
    });
    port
}

/// A signed FC (`tcpin`) and CC (`tcp:` through [`slow_relay`] carrying
/// `link_rate` bytes a second, its far end holding `far_buffer`), the RC
/// lost at 3 s, and a ground station's broadcast heartbeats, 58.8 KB
/// datagrams twice a second, sent into the CC's `--out` link, which routes
/// them to the FC: the handover must happen and companion control hold.
/// Returns the CC's run.
fn handover_with_a_flood_routed_to_a_slow_link(
    name: &str,
    link_rate: f64,
    far_buffer: Option<usize>,
) -> Finished {
    let _heavy = heavy();
    let dir = scratch(name);
    let s = Setup {
        rc_loss_at: 3.0,
        duration: 6.0,
        ..Setup::signed()
    };
    let fc_port = free_port();
    let mut fc_a = args(&["fc-sim", "--link", &format!("tcpin:127.0.0.1:{fc_port}")]);
    fc_a.extend(args(&["--rc-loss-at", "3", "--duration", "6"]));
    fc_a.extend(s.signing_args());
    let fc = Daemon::spawn(&dir, "fc", &fc_a);
    std::thread::sleep(Duration::from_millis(300));
    let relay = slow_relay(local(fc_port), link_rate, far_buffer);
    let out_port = free_port();
    let mut cc_a = args(&["cc", "--link", &format!("tcp:127.0.0.1:{relay}")]);
    cc_a.extend(args(&["--out", &format!("udpin:127.0.0.1:{out_port}")]));
    cc_a.extend(args(&["--duration", &s.cc_duration().to_string()]));
    cc_a.extend(s.signing_args());
    let cc = Daemon::spawn(&dir, "cc", &cc_a);
    std::thread::sleep(Duration::from_millis(500));
    let hb = frame(GCS, 0, &wire::cc_heartbeat(), None);
    let datagram: Vec<u8> = hb.iter().copied().cycle().take(hb.len() * 2800).collect();
    let attacker = Attacker::start(&[local(out_port)], 2.0, 0, move |_, _| datagram.clone());
    let limit = Duration::from_secs_f64(s.cc_duration() + 10.0);
    let (fc, cc) = (fc.finish(limit), cc.finish(limit));
    let sent = attacker.stop();
    assert!(sent.datagrams >= 8, "{sent:?}");
    assert_safe_handover(&fc, &cc, &s);
    cc
}

/// The flood at 2.5 times what a TCP link of about 460,800 baud (46 KB/s)
/// carries, its far end a UART's 4 KiB. (The flood and the CC's own frames
/// shared one queue, and the kernel's send buffer grew to megabytes of
/// flood: the CC's acknowledgement never reached the FC, which fell back to
/// RTL.)
#[test]
fn a_flood_routed_to_a_slow_fc_link_never_crowds_out_the_protocol() {
    handover_with_a_flood_routed_to_a_slow_link("slow-link", 46_000.0, Some(4096));
}

/// The flood routed to a slower link (20 KB/s, about 230,400 baud) whose
/// far end buffers what it is sent, as a radio modem or a serial bridge
/// does: the CC paces what it routes to the FC link (8 KB/s by default,
/// below the link's rate), so that buffer never fills ahead of its
/// acknowledgement. (Unpaced, `--routed-rate off`, the buffer held seconds
/// of the flood and the FC fell back to RTL.)
#[test]
fn a_flood_routed_to_a_slow_link_never_fills_its_far_end() {
    let cc = handover_with_a_flood_routed_to_a_slow_link("slow-modem", 20_000.0, None);
    assert!(cc.log.contains("at most 8000 bytes/s"), "{}", cc.dump());
}

// ---------------------------------------------------------------------------
// Replayed frames.

/// The throttle of the captured run's companion: a control applied with
/// it was replayed.
const CAPTURED_THROTTLE: u64 = 1234;

/// A signed run through a tap, its companion flying at
/// [`CAPTURED_THROTTLE`], the RC lost at 2 s (so its event id is later
/// than the next run's: a replay accepted would make the real RC loss
/// look stale). Returns every datagram both ways.
fn capture_run(dir: &std::path::Path) -> Capture {
    let state = dir.join("cc.state");
    let s = Setup {
        rc_loss_at: 2.0,
        duration: 3.2,
        cc_args: args(&[
            "--throttle",
            &CAPTURED_THROTTLE.to_string(),
            "--signing-state",
            &state.display().to_string(),
        ]),
        ..Setup::signed()
    };
    let cc_port = free_port();
    let tap = Tap::start(local(cc_port));
    let cc = Daemon::spawn(dir, "cc1", &cc_args(cc_port, &s, s.cc_duration()));
    let fc = Daemon::spawn(
        dir,
        "fc1",
        &fc_args(tap.fc_side.port(), &s, s.rc_loss_at, s.duration),
    );
    let fc = fc.finish(Duration::from_secs(15));
    let cc = cc.finish(Duration::from_secs(15));
    let capture = tap.stop();
    assert!(
        fc.events.last("handover").is_some(),
        "the captured run has no takeover\n{}\n{}",
        fc.dump(),
        cc.dump()
    );
    capture
}

/// Replays the datagrams of `capture` going `dir`, over and over, to
/// `targets` (500 a second each).
fn replay(capture: &Capture, dir: Dir, targets: &[std::net::SocketAddr]) -> Attacker {
    let frames: Vec<Vec<u8>> = capture
        .iter()
        .filter(|(d, _)| *d == dir)
        .map(|(_, b)| b.clone())
        .collect();
    assert!(!frames.is_empty(), "nothing captured going {dir:?}");
    Attacker::start(targets, 500.0, 0, move |_, n| {
        frames[n as usize % frames.len()].clone()
    })
}

fn assert_no_replayed_control(fc: &Finished) {
    for e in fc.events.of("control_applied") {
        assert_ne!(
            e["channels"][2],
            CAPTURED_THROTTLE,
            "replayed control applied: {e}\n{}",
            fc.dump()
        );
    }
}

/// A signed run's capture replayed into new signed pairs, one
/// listening each way, once the FC has been heard, from a port of the
/// attacker's own: the captured frames are older than what the real peers
/// sent, so the listening daemon's verifier refuses them (stale signing
/// timestamps; their source gets the daemon's time beacon, once a second
/// at most), and the `udpout` sockets never hear them; the real handover
/// happens for the real event, and no captured control is applied.
#[test]
fn replayed_capture_is_refused_once_the_peers_have_spoken() {
    let dir = scratch("replay");
    let capture = capture_run(&dir);
    let s = Setup::signed();
    let pairs = Pair::both_ways(&dir, &s);
    for pair in &pairs {
        pair.cc.wait_for("FC found", Duration::from_secs(5), |e| {
            e["event"] == "fc" && e["state"] == "found"
        });
    }
    let ccs: Vec<_> = pairs.iter().map(|p| local(p.cc_port)).collect();
    let fcs: Vec<_> = pairs.iter().map(|p| local(p.fc_port)).collect();
    let to_cc = replay(&capture, Dir::FcToCc, &ccs);
    let to_fc = replay(&capture, Dir::CcToFc, &fcs);
    let runs = pairs.map(Pair::run);
    let (a, b) = (to_cc.stop(), to_fc.stop());
    let mut beacons = 0;
    for run in &runs {
        assert_safe_handover(&run.fc, &run.cc, &s);
        assert_no_replayed_control(&run.fc);
        let all = run.dump();
        let refused = run.listener().refused("stale signing timestamps");
        assert!(refused > 0, "{all}");
        assert_heard_nothing(run.sender(), &all);
        beacons += beacons_at_most(run.listener());
    }
    // The replayer's address got time beacons, one a second at most, and
    // nothing else (it never became a peer: the handovers held).
    assert!(
        a.received + b.received <= beacons,
        "{} datagrams to the replayer, over {beacons} beacons",
        a.received + b.received
    );
}

/// SIGTERM (and SIGINT) stop a daemon as the end of its run does, saving
/// its signing state: an RC-loss notice it took just before is a replay
/// once it is restarted on that state. (Killed by the signal, it skipped
/// that save, and the periodic one comes at most once a second: the replay
/// was taken, and the companion took over for it again.)
#[test]
fn a_cc_stopped_by_sigterm_saves_its_signing_state() {
    let dir = scratch("sigterm");
    let state = dir.join("cc.state").display().to_string();
    let cc_port = free_port();
    let s = Setup {
        cc_args: args(&["--signing-state", &state]),
        ..Setup::signed()
    };
    let fc_socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let now = fbwag_dialect::mavframe::signing::timestamp_now();
    let mut signer = fbwag_dialect::Signer::new(key_bytes(KEY), 0, now);
    let cc = Daemon::spawn(&dir, "cc", &cc_args(cc_port, &s, 30.0));
    let send = |frame: &[u8]| fc_socket.send_to(frame, local(cc_port)).unwrap();
    let heartbeat = wire::fc_heartbeat(fbwag_delegation::fc::Authority::Pilot);
    // Until the CC has its first save behind it (it found the FC)...
    let until = std::time::Instant::now() + Duration::from_secs(10);
    while !cc.events_now().0.iter().any(|e| e["event"] == "fc") {
        assert!(
            std::time::Instant::now() < until,
            "the CC never found the FC"
        );
        send(&frame(FC, 0, &heartbeat, Some(&mut signer)));
        std::thread::sleep(Duration::from_millis(200));
    }
    // ...then, within a second of a save, the RC loss.
    std::thread::sleep(Duration::from_millis(1200));
    send(&frame(FC, 1, &heartbeat, Some(&mut signer)));
    let loss = frame(
        FC,
        2,
        &wire::notice(FC, Status::RC_LOST, 777),
        Some(&mut signer),
    );
    send(&loss);
    cc.wait_for("takeover", Duration::from_secs(5), |e| {
        e["event"] == "control" && e["state"] == "start"
    });
    let killed = std::process::Command::new("kill")
        .args(["-TERM", &cc.pid().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let first = cc.finish(Duration::from_secs(40));
    assert!(first.status.success(), "{}", first.dump());
    assert!(first.log.contains("SIGTERM: stopping"), "{}", first.dump());
    assert!(first.events.last("summary").is_some(), "{}", first.dump());
    let again = Daemon::spawn(&dir, "cc-again", &cc_args(cc_port, &s, 2.0));
    // Once it listens (its first line names its link), the replay.
    let until = std::time::Instant::now() + Duration::from_secs(10);
    while !std::fs::read_to_string(&again.log).is_ok_and(|l| l.contains("FC link")) {
        assert!(
            std::time::Instant::now() < until,
            "the CC did not start again"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    fc_socket.send_to(&loss, local(cc_port)).unwrap();
    let again = again.finish(Duration::from_secs(15));
    assert!(
        again.events.control_starts().is_empty(),
        "the replayed notice was taken\n{}",
        again.dump()
    );
}

/// The same capture replayed into the CC restarted (a companion reboot)
/// before the FC speaks again. Signing lets a new stream start up to one
/// minute behind the newest timestamp the receiver knows, so a verifier
/// that knew only the clock accepted the seconds-old capture: the CC took
/// over for the captured event, answered the replayer, and the captured
/// event id (later than the real one) made the real RC loss look stale.
/// With its signing state file (`--signing-state`), the restarted CC knows
/// the FC's stream up to the last frame it accepted, and refuses the
/// capture (stale signing timestamps). Until the FC speaks, the CC answers
/// the replayer only with its time beacon (its signed heartbeat, once a
/// second at most), and the replayer never becomes its peer. The capture's
/// other half, replayed to the FC's `udpout` port, never reaches it.
#[test]
fn replayed_capture_into_a_restarted_cc() {
    let dir = scratch("replay-fresh");
    let capture = capture_run(&dir);
    let state = dir.join("cc.state");
    let s = Setup {
        cc_args: args(&["--signing-state", &state.display().to_string()]),
        ..Setup::signed()
    };
    let cc_port = free_port();
    let cc = Daemon::spawn(&dir, "cc", &cc_args(cc_port, &s, s.cc_duration()));
    let to_cc = replay(&capture, Dir::FcToCc, &[local(cc_port)]);
    let replayer = to_cc.addr.to_string();
    // The replayer is heard first, as after a companion reboot.
    std::thread::sleep(Duration::from_millis(300));
    let fc = Daemon::spawn(&dir, "fc", &fc_args(cc_port, &s, s.rc_loss_at, s.duration));
    let to_fc = replay(&capture, Dir::CcToFc, &[local(udp_port_of(fc.pid()))]);
    let fc = fc.finish(Duration::from_secs(20));
    let cc = cc.finish(Duration::from_secs(20));
    let (a, b) = (to_cc.stop(), to_fc.stop());
    assert_safe_handover(&fc, &cc, &s);
    assert_no_replayed_control(&fc);
    let both = format!("{}\n{}", fc.dump(), cc.dump());
    assert!(!answered(&cc, |x| x == replayer), "{both}");
    assert!(
        a.received <= beacons_at_most(&cc),
        "the CC answered the replayer: {a:?}\n{both}"
    );
    assert_eq!(b.received, 0, "the FC answered the replayer\n{both}");
    assert!(cc.refused("stale signing timestamps") > 0, "{both}");
    assert_heard_nothing(&fc, &both);
}

/// Frames signed with the right key two minutes ago (what a capture of an
/// earlier flight holds), sent from the start, from a port of the
/// attacker's own, into new signed pairs, one listening each way: RC-loss
/// notices as the FC to the CCs, takeover acknowledgements and control as
/// the companion to the FCs. A fresh verifier starts from the clock, so
/// they are older than any new stream may start: the listening daemon
/// refuses them all (stale signing timestamps), and the `udpout` sockets
/// never hear them. Until its peer speaks, a listening daemon answers the
/// attacker only with its time beacon (its signed heartbeat, once a second
/// at most), and the attacker never becomes its peer.
#[test]
fn frames_signed_minutes_ago_are_refused_by_fresh_daemons() {
    let dir = scratch("old-signed");
    let s = Setup::signed();
    let key = key_bytes(KEY);
    // 10 µs units: 120 s ago, advancing as a real signer would.
    let then = fbwag_dialect::mavframe::signing::timestamp_now() - 120 * 100_000;
    let old_fc = move |_: &mut rand_pcg::Pcg64, n: u64| {
        let mut signer = fbwag_dialect::Signer::new(key, 0, then + n);
        let status = [Status::RC_LOST, Status::NORMAL][(n % 2) as usize];
        let msg = wire::notice(FC, status, 700 + (n as u32 % 2000));
        frame(FC, n as u8, &msg, Some(&mut signer))
    };
    let old_cc = move |_: &mut rand_pcg::Pcg64, n: u64| {
        let mut signer = fbwag_dialect::Signer::new(key, 0, then + n);
        if n % 2 == 0 {
            let ack = wire::notice(FC, Status::CC_TAKEOVER_CONFIRMED, 900 + (n as u32 % 600));
            frame(CC, n as u8, &ack, Some(&mut signer))
        } else {
            frame(CC, n as u8, controls()[0].as_ref(), Some(&mut signer))
        }
    };
    let pairs = Pair::both_ways(&dir, &s);
    let ccs: Vec<_> = pairs.iter().map(|p| local(p.cc_port)).collect();
    let fcs: Vec<_> = pairs.iter().map(|p| local(p.fc_port)).collect();
    let to_cc = Attacker::start(&ccs, 500.0, 0, old_fc);
    let to_fc = Attacker::start(&fcs, 500.0, 0, old_cc);
    let attackers = [to_cc.addr.to_string(), to_fc.addr.to_string()];
    let runs = pairs.map(Pair::run);
    let (a, b) = (to_cc.stop(), to_fc.stop());
    let mut beacons = 0;
    for run in &runs {
        assert_safe_handover(&run.fc, &run.cc, &s);
        let all = run.dump();
        let listener = run.listener();
        let refused = listener.refused("stale signing timestamps");
        assert!(refused > 0, "{all}");
        assert!(
            !answered(listener, |x| attackers.iter().any(|a| a == x)),
            "{all}"
        );
        assert_heard_nothing(run.sender(), &all);
        beacons += beacons_at_most(listener);
    }
    assert!(
        a.received + b.received <= beacons,
        "a daemon answered the attacker: {a:?} {b:?}"
    );
}

// ---------------------------------------------------------------------------
// A datagram from source port 0.

/// Datagrams from source port 0 (which no socket can answer) to both
/// daemons, from before the FC starts to the end: garbage, and valid frames
/// with the peer's ids (signing off, so the engine trusts them). Both
/// daemons stay up to their end, the CC answers the real FC (the link
/// never takes port 0 for its peer: before, port 0 speaking first as the
/// FC left the real FC unanswered), and the handover happens. (The FC's
/// `udpout` socket never hears them: it hears only the CC.)
#[test]
fn datagrams_from_source_port_zero() {
    let dir = scratch("port-zero");
    let probe = send_from_port_zero(local(free_port()), b"probe");
    if let Err(e) = probe {
        println!("skipped: no raw socket to send from port 0 ({e}); run as root to include it");
        return;
    }
    let s = Setup::unsigned();
    let cc_port = free_port();
    let cc = Daemon::spawn(&dir, "cc", &cc_args(cc_port, &s, s.cc_duration()));
    // Garbage, a byte, and a frame the receiver trusts (the peer's ids,
    // signing off) but that changes nothing in the protocol: the FC's
    // ATTITUDE (mere liveness for the CC), the companion's HEARTBEAT.
    let burst = |to: u16, peer: fbwag_delegation::Peer, n: u64| {
        let trusted = if peer == FC {
            let att = fbwag_dialect::dialects::common::Attitude::default();
            frame(FC, n as u8, &att, None)
        } else {
            frame(CC, n as u8, &wire::cc_heartbeat(), None)
        };
        for payload in [&b"\xfd\x09\x00\x00"[..], &[0u8; 1][..], &trusted[..]] {
            send_from_port_zero(local(to), payload).expect("raw send");
        }
    };
    // Port 0 speaks first, as the FC (once the CC is listening).
    assert_eq!(udp_port_of(cc.pid()), cc_port);
    for n in 0..5 {
        burst(cc_port, FC, n);
    }
    std::thread::sleep(Duration::from_millis(200));
    let fc = Daemon::spawn(&dir, "fc", &fc_args(cc_port, &s, s.rc_loss_at, s.duration));
    let fc_port = udp_port_of(fc.pid());
    let until = std::time::Instant::now() + Duration::from_secs_f64(s.duration);
    let mut n = 5;
    while std::time::Instant::now() < until {
        burst(cc_port, FC, n);
        burst(fc_port, CC, n);
        n += 1;
        std::thread::sleep(Duration::from_millis(100));
    }
    let pair = Pair {
        cc,
        fc,
        cc_port,
        fc_port,
        listens: Listens::Cc,
        setup: s.clone(),
    };
    let (fc, cc) = pair.finish();
    assert_safe_handover(&fc, &cc, &s);
    assert!(
        answered(&cc, |a| a == local(fc_port).to_string()),
        "the CC never answered the FC\n{}",
        cc.dump()
    );
    assert!(
        !answered(&cc, |a| a.ends_with(":0")),
        "the CC took port 0 for its peer\n{}",
        cc.dump()
    );
}

// ---------------------------------------------------------------------------
// Hijacking the CC's `udpin` peer.

/// A third process sends to the CC's port from before the FC starts:
/// garbage, one-byte datagrams, and valid unsigned frames with the FC's ids
/// (heartbeats, RC-loss notices). With signing required, none of it is
/// trusted: the CC's node drops the frames before the engine (`not_peer`:
/// an unsigned frame never makes its source the peer), the CC never answers
/// the attacker, its frames keep going to the real FC, which hands over and
/// keeps companion control.
#[test]
fn peer_hijack_with_signing_required() {
    let dir = scratch("hijack-signed");
    let s = Setup::signed();
    let cc_port = free_port();
    let cc = Daemon::spawn(&dir, "cc", &cc_args(cc_port, &s, s.cc_duration()));
    let attacker = Attacker::start(&[local(cc_port)], 500.0, 9, hijacker);
    std::thread::sleep(Duration::from_millis(300));
    let fc = Daemon::spawn(&dir, "fc", &fc_args(cc_port, &s, s.rc_loss_at, s.duration));
    let fc_port = udp_port_of(fc.pid());
    let pair = Pair {
        cc,
        fc,
        cc_port,
        fc_port,
        listens: Listens::Cc,
        setup: s.clone(),
    };
    let (fc, cc) = pair.finish();
    let addr = attacker.addr.to_string();
    let sent = attacker.stop();
    assert_safe_handover(&fc, &cc, &s);
    let both = format!("{}\n{}", fc.dump(), cc.dump());
    assert_eq!(sent.received, 0, "the CC answered the attacker\n{both}");
    assert!(!answered(&cc, |a| a == addr), "{both}");
    assert!(dropped(&cc, "not_peer") > 0, "{both}");
    assert_eq!(cc.events.summary("untrusted_notices"), 0, "{both}");
}

/// An FC on `tcpin` with few file descriptors (`ulimit -n 36`), and 100
/// idle connections held open before the companion connects. Before, the
/// FC accepted until it ran out of descriptors, then retried the failing
/// accept at 100 % CPU: the companion's connection waited in the backlog
/// for good, and the FC fell back to RTL. Now at most 32 clients are kept,
/// idle ones are evicted first, and the handover happens.
#[test]
fn idle_connections_to_a_tcpin_fc_never_lock_the_companion_out() {
    let _heavy = heavy();
    let dir = scratch("tcpin-exhaust");
    let s = Setup::signed();
    let port = free_port();
    let mut fc_args = args(&["fc-sim", "--link", &format!("tcpin:127.0.0.1:{port}")]);
    fc_args.extend(args(&[
        "--rc-loss-at",
        "2",
        "--duration",
        &s.duration.to_string(),
    ]));
    fc_args.extend(s.signing_args());
    let fc = Daemon::spawn_with_file_limit(&dir, "fc", &fc_args, 36);
    let mut idle = Vec::new();
    for _ in 0..50 {
        match std::net::TcpStream::connect(local(port)) {
            Ok(c) => idle.push(c),
            Err(_) => std::thread::sleep(Duration::from_millis(20)),
        }
    }
    while idle.len() < 100 {
        idle.push(std::net::TcpStream::connect(local(port)).expect("connect"));
    }
    let mut cc_args = args(&["cc", "--link", &format!("tcp:127.0.0.1:{port}")]);
    cc_args.extend(args(&["--duration", &s.cc_duration().to_string()]));
    cc_args.extend(s.signing_args());
    let cc = Daemon::spawn(&dir, "cc", &cc_args);
    let limit = Duration::from_secs_f64(s.cc_duration() + 10.0);
    let (fc, cc) = (fc.finish(limit), cc.finish(limit));
    drop(idle);
    assert_safe_handover(&fc, &cc, &s);
}

/// The attacker of the hijack tests: garbage, one-byte datagrams, and the
/// FC's heartbeats and notices, unsigned.
fn hijacker(rng: &mut rand_pcg::Pcg64, n: u64) -> Vec<u8> {
    use rand::Rng;
    match n % 5 {
        0 => Garbage::Random.datagram(rng, 64),
        1 => vec![rng.gen()],
        2 | 3 => frame(
            FC,
            n as u8,
            &wire::fc_heartbeat(fbwag_delegation::fc::Authority::Handshake),
            None,
        ),
        _ => frame(
            FC,
            n as u8,
            &wire::notice(FC, Status::RC_LOST, rng.gen()),
            None,
        ),
    }
}

/// Without signing, ids are all there is: a third process that spoofs the
/// FC's ids and speaks first becomes the CC's peer, receives the CC's
/// frames, and keeps the real FC unanswered for as long as it keeps
/// talking (a peer moves only after 3 s of silence: the real FC's frames
/// are dropped, `not_peer`), so the FC gets no companion and falls back to
/// RTL. This pins the documented limit of unsigned operation (use
/// --require-signed, or --peer, below).
#[test]
fn without_signing_a_spoofed_fc_captures_the_cc_answers() {
    let dir = scratch("hijack-unsigned");
    let s = Setup {
        duration: 7.5,
        ..Setup::unsigned()
    };
    let cc_port = free_port();
    let cc = Daemon::spawn(&dir, "cc", &cc_args(cc_port, &s, s.cc_duration()));
    let spoof = |_: &mut rand_pcg::Pcg64, n: u64| {
        let hb = wire::fc_heartbeat(fbwag_delegation::fc::Authority::Pilot);
        frame(FC, n as u8, &hb, None)
    };
    let attacker = Attacker::start(&[local(cc_port)], 20.0, 0, spoof);
    let addr = attacker.addr.to_string();
    std::thread::sleep(Duration::from_millis(300));
    let fc = Daemon::spawn(&dir, "fc", &fc_args(cc_port, &s, s.rc_loss_at, s.duration));
    let fc_addr = local(udp_port_of(fc.pid())).to_string();
    let fc = fc.finish(Duration::from_secs(20));
    let cc = cc.finish(Duration::from_secs(20));
    let sent = attacker.stop();
    let both = format!("{}\n{}", fc.dump(), cc.dump());
    fc.assert_ran_to_the_end(s.duration);
    cc.assert_ran_to_the_end(s.cc_duration());
    assert!(!answered(&cc, |a| a == fc_addr), "{both}");
    assert!(
        sent.received > 0 && answered(&cc, |a| a == addr),
        "the CC never answered the spoofer\n{both}"
    );
    assert!(dropped(&cc, "not_peer") > 0, "{both}");
    assert!(fc.events.last("handover").is_none(), "{both}");
    assert_eq!(
        fc.events.modes().last().map(String::as_str),
        Some("RTL"),
        "{both}"
    );
}

/// Without signing, a forged FC reboot from a third port while the real FC
/// talks: a hand-back notice of a far newer event, then one of event 0 (a
/// new boot, by the CC's rules), then heartbeats of an FC in companion
/// control. The CC's node drops all of it (`not_peer`: the real FC is its
/// peer, and speaking), so the CC never sees the forged reboot, never
/// answers the forger, and the real FC hands over. (Before, the CC took the
/// forgery for a reboot; earlier still, it forgot its peer at every reboot
/// it recognised, so the forger's frame moved the answers to it at once:
/// the real FC's RC loss went unanswered, and it fell back to RTL.)
#[test]
fn without_signing_a_forged_fc_reboot_is_never_seen() {
    let dir = scratch("forged-reboot");
    let s = Setup {
        rc_loss_at: 2.0,
        duration: 4.0,
        ..Setup::unsigned()
    };
    let pair = Pair::start(&dir, &s);
    std::thread::sleep(Duration::from_millis(800));
    let forger = |_: &mut rand_pcg::Pcg64, n: u64| match n {
        0 | 1 => {
            let event = [100_000_000, 0][n as usize];
            frame(FC, n as u8, &wire::notice(FC, Status::NORMAL, event), None)
        }
        _ => {
            let by = fbwag_delegation::fc::Authority::Companion;
            frame(FC, n as u8, &wire::fc_heartbeat(by), None)
        }
    };
    let attacker = Attacker::start(&[local(pair.cc_port)], 5.0, 0, forger);
    let (fc, cc) = pair.finish();
    let sent = attacker.stop();
    let both = format!("{}\n{}", fc.dump(), cc.dump());
    assert!(sent.datagrams >= 10, "{sent:?}");
    assert!(
        !cc.log.contains("FC rebooted"),
        "forged reboot taken\n{both}"
    );
    assert!(dropped(&cc, "not_peer") >= sent.datagrams, "{both}");
    assert_eq!(sent.received, 0, "the CC answered the forger\n{both}");
    assert_safe_handover(&fc, &cc, &s);
}

/// The same spoofer against a CC given `--peer` (the FC listening on a
/// known port): without signing, `--peer` pins both whom the CC answers
/// and whom it hears. The spoofed heartbeats (flying FBWA, i.e. "not in
/// companion control") come from another address, and the CC's node drops
/// them (`not_peer`): the real FC hands over, and companion control holds.
/// (Before, they were believed: the CC stopped its control and the FC fell
/// back to RTL.) An attacker who can send from the FC's own address (on
/// the path, or forging source addresses) can still end the delegation
/// this way; only signing stops that.
#[test]
fn without_signing_the_peer_flag_keeps_a_spoofer_out() {
    let dir = scratch("hijack-peer");
    let s = Setup::unsigned();
    let (cc_port, fc_port) = (free_port(), free_port());
    let mut ca = cc_args(cc_port, &s, s.cc_duration());
    ca.extend(args(&["--peer", &local(fc_port).to_string()]));
    let cc = Daemon::spawn(&dir, "cc", &ca);
    // Sequence numbers spread over the whole range: half of them are
    // "newer" than the FC's last confirmation whatever its sequence.
    let spoof = |_: &mut rand_pcg::Pcg64, n: u64| {
        let hb = wire::fc_heartbeat(fbwag_delegation::fc::Authority::Pilot);
        frame(FC, (n * 97) as u8, &hb, None)
    };
    let attacker = Attacker::start(&[local(cc_port)], 20.0, 0, spoof);
    std::thread::sleep(Duration::from_millis(300));
    let fa = fc_args_on(&udpin(fc_port), &s, s.rc_loss_at, s.duration);
    let fc = Daemon::spawn(&dir, "fc", &fa);
    let fc = fc.finish(Duration::from_secs(20));
    let cc = cc.finish(Duration::from_secs(20));
    let sent = attacker.stop();
    let both = format!("{}\n{}", fc.dump(), cc.dump());
    assert_safe_handover(&fc, &cc, &s);
    let stops = cc.events.of("control").filter(|e| e["state"] == "stop");
    assert_eq!(stops.count(), 0, "{both}");
    assert_eq!(sent.received, 0, "the CC answered the spoofer\n{both}");
    assert!(dropped(&cc, "not_peer") > 0, "{both}");
}

// ---------------------------------------------------------------------------
// Restarts.

/// fc-sim killed while the CC is in control and started again (an FC
/// reboot), its new RC loss earlier in its boot than the old one: the CC
/// recognises the new boot (its event ids went back), answers it, and
/// the new FC hands over to it. Signed, the new FC's frames move the CC's
/// answers to its new port at once.
#[test]
fn fc_reboot_while_the_cc_controls() {
    fc_reboot(Setup::signed(), 6.5, 0.3, 4.0);
}

/// A quick reboot: the new boot loses the receiver 1.4 s into it, a few
/// hundred milliseconds of its clock before the old boot's event, too close
/// to tell from a late notice by the ids alone. The CC recognises the new
/// boot when the FC repeats the notice a retry later, and the handover
/// happens (before, it waited until the old event was 6 s behind, and the
/// new FC fell back to RTL at the end of its 5 s handshake).
#[test]
fn quick_fc_reboot_while_the_cc_controls() {
    fc_reboot(Setup::signed(), 1.6, 1.4, 8.0);
}

/// The same unsigned: the CC moves its answers to the rebooted FC's new
/// port only once the old port has been silent for 3 s (PEER_SILENCE),
/// which is inside the new FC's 5 s handshake: until the move it
/// acknowledges the new boot's notices to the dead port, and its per-event
/// budget of acknowledgements (one per retry interval, whether its own
/// timer or the FC's repeated notice asks) lasts until the FC's notices
/// after the move are answered, so the handover still happens.
#[test]
fn fc_reboot_while_the_cc_controls_unsigned() {
    fc_reboot(Setup::unsigned(), 6.5, 0.3, 4.0);
}

/// fc-sim losing the receiver `loss1` s into its run, killed in control
/// and started again to lose it `loss2` s into its `run2` s run.
fn fc_reboot(signing: Setup, loss1: f64, loss2: f64, run2: f64) {
    let dir = scratch("fc-reboot");
    let s = Setup {
        rc_loss_at: loss1,
        duration: 30.0,
        ..signing
    };
    let cc_port = free_port();
    let cc_time = loss1 + run2 + 9.0;
    let cc = Daemon::spawn(&dir, "cc", &cc_args(cc_port, &s, cc_time));
    let mut fc1 = Daemon::spawn(&dir, "fc1", &fc_args(cc_port, &s, s.rc_loss_at, s.duration));
    fc1.wait_for("handover", Duration::from_secs(10), |e| {
        e["event"] == "handover"
    });
    std::thread::sleep(Duration::from_millis(500));
    fc1.kill();
    let s2 = Setup {
        rc_loss_at: loss2,
        duration: run2,
        ..s.clone()
    };
    let fc2 = Daemon::spawn(
        &dir,
        "fc2",
        &fc_args(cc_port, &s2, s2.rc_loss_at, s2.duration),
    );
    let fc2 = fc2.finish(Duration::from_secs(15));
    let cc = cc.finish(Duration::from_secs_f64(cc_time + 10.0));
    let both = format!("{}\n{}", fc2.dump(), cc.dump());
    cc.assert_ran_to_the_end(cc_time);
    fc2.assert_ran_to_the_end(s2.duration);
    // The CC's story: control for the first boot, the reboot, control for
    // the second boot's event.
    let ev = &cc.events;
    let rebooted =
        ev.0.iter()
            .position(|e| e["event"] == "fc" && e["state"] == "rebooted");
    let rebooted = rebooted.unwrap_or_else(|| panic!("no reboot recognised\n{both}"));
    let before = Events(ev.0[..rebooted].to_vec()).control_starts();
    let after = Events(ev.0[rebooted..].to_vec()).control_starts();
    assert_eq!(before.len(), 1, "{both}");
    assert_eq!(after, fc2.notice_events(), "{both}");
    assert!(fc2.events.last("handover").is_some(), "{both}");
    assert_controls_from_companion(&fc2, s.signed, &both);
    let modes = fc2.events.modes();
    assert!(
        modes
            .iter()
            .skip_while(|m| *m != "FBWAG")
            .all(|m| m == "FBWAG"),
        "{both}"
    );
}

/// `fbwag cc` killed while in control and started again on the same port:
/// the FC falls back to RTL (no control for 1 s) and stays there, as the
/// spec says (only a new RC loss starts a new delegation); the new CC
/// acknowledges the FC's notices, takes over nothing, and no control is
/// applied after the fallback. The pilot gets the aircraft back when the
/// receiver returns.
#[test]
fn cc_restart_while_in_control() {
    let dir = scratch("cc-restart");
    let s = Setup {
        rc_back_at: Some(5.0),
        duration: 6.5,
        ..Setup::signed()
    };
    let cc_port = free_port();
    let mut cc1 = Daemon::spawn(&dir, "cc1", &cc_args(cc_port, &s, 30.0));
    let fc = Daemon::spawn(&dir, "fc", &fc_args(cc_port, &s, s.rc_loss_at, s.duration));
    fc.wait_for("handover", Duration::from_secs(5), |e| {
        e["event"] == "handover"
    });
    std::thread::sleep(Duration::from_millis(500));
    cc1.kill();
    let cc2_time = 5.5;
    let cc2 = Daemon::spawn(&dir, "cc2", &cc_args(cc_port, &s, cc2_time));
    let fc = fc.finish(Duration::from_secs(20));
    let cc2 = cc2.finish(Duration::from_secs(20));
    let both = format!("{}\n{}", fc.dump(), cc2.dump());
    fc.assert_ran_to_the_end(s.duration);
    cc2.assert_ran_to_the_end(cc2_time);
    assert_eq!(
        fc.events.modes(),
        ["FBWA", "CIRCLE", "FBWAG", "RTL", "FBWA"],
        "{both}"
    );
    let after_rtl = fc
        .events
        .after(|e| e["event"] == "mode" && e["mode"] == "RTL");
    assert_eq!(after_rtl.of("control_applied").count(), 0, "{both}");
    assert_controls_from_companion(&fc, true, &both);
    assert!(cc2.events.control_starts().is_empty(), "{both}");
    assert!(
        cc2.events.summary("handbacks") > 0,
        "the new CC answered nothing\n{both}"
    );
}
