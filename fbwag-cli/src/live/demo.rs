//! `fbwag demo`: the companion daemon and the FC simulator over loopback
//! UDP through a relay that drops a share of the datagrams each way.

use super::cc::{run_cc, CcOptions};
use super::net::LinkOptions;
use crate::fc_sim::{run_fc, FcOptions, FcReport};
use fbwag_delegation::control::WingsLevel;
use fbwag_delegation::Peer;
use fbwag_dialect::Endpoint;
use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant as WallInstant};

/// The lossy radio of the demo: which datagrams it drops.
///
/// A datagram's fate depends only on the seed, its direction, its message
/// id and how many datagrams of that id went that way before it, not on
/// when it came: the protocol's frames (the FC's first notice, the
/// companion's first acknowledgement, ...) meet the same fate in every run
/// with the same seed, so the demo's figures repeat, up to scheduling
/// jitter of milliseconds.
#[derive(Debug)]
pub struct Dropper {
    seed: u64,
    loss: f64,
    counts: std::collections::HashMap<(bool, u32), u64>,
}

impl Dropper {
    pub fn new(seed: u64, loss: f64) -> Self {
        Dropper {
            seed,
            loss,
            counts: std::collections::HashMap::new(),
        }
    }

    /// Whether to drop this datagram (`uplink`: companion to FC).
    pub fn drops(&mut self, uplink: bool, datagram: &[u8]) -> bool {
        let id = msg_id(datagram);
        let k = self.counts.entry((uplink, id)).or_insert(0);
        *k += 1;
        let x = splitmix64(self.seed ^ (u64::from(uplink) << 63) ^ (u64::from(id) << 32) ^ *k);
        let uniform = (x >> 11) as f64 / (1u64 << 53) as f64;
        uniform < self.loss
    }
}

/// The message id of the frame a datagram starts with (0 when it starts
/// with none).
fn msg_id(d: &[u8]) -> u32 {
    match d {
        [0xFD, _, _, _, _, _, _, a, b, c, ..] => u32::from_le_bytes([*a, *b, *c, 0]),
        [0xFE, _, _, _, _, id, ..] => u32::from(*id),
        _ => 0,
    }
}

/// SplitMix64's finaliser: a well-mixed 64-bit hash of `x`.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A UDP relay between the FC (whose datagrams arrive at `fc_side`) and
/// the companion at `cc_addr`, dropping datagrams as [`Dropper`] decides;
/// one thread per direction, so neither waits on the other. Runs until
/// `until`; returns (passed, dropped).
pub fn run_relay(
    fc_side: UdpSocket,
    cc_addr: SocketAddr,
    loss: f64,
    until: WallInstant,
    seed: u64,
) -> io::Result<(u64, u64)> {
    let cc_side = UdpSocket::bind("127.0.0.1:0")?;
    for s in [&fc_side, &cc_side] {
        s.set_read_timeout(Some(Duration::from_millis(20)))?;
    }
    let dropper = std::sync::Mutex::new(Dropper::new(seed, loss));
    let fc_addr = std::sync::Mutex::new(None::<SocketAddr>);
    let (fc_side, cc_side) = (&fc_side, &cc_side);
    let relay = |from: &UdpSocket, uplink: bool| {
        let (mut passed, mut dropped) = (0u64, 0u64);
        let mut buf = [0u8; 2048];
        while WallInstant::now() < until {
            let Ok((n, source)) = from.recv_from(&mut buf) else {
                continue;
            };
            let to = if uplink {
                *fc_addr.lock().unwrap_or_else(|e| e.into_inner())
            } else {
                *fc_addr.lock().unwrap_or_else(|e| e.into_inner()) = Some(source);
                Some(cc_addr)
            };
            let lost = dropper
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .drops(uplink, &buf[..n]);
            match to {
                Some(to) if !lost => {
                    passed += 1;
                    // A send that fails (the peer not up yet) is a loss.
                    let out = if uplink { fc_side } else { cc_side };
                    let _ = out.send_to(&buf[..n], to);
                }
                _ => dropped += 1,
            }
        }
        (passed, dropped)
    };
    let ((p1, d1), (p2, d2)) = std::thread::scope(|s| {
        let down = s.spawn(|| relay(fc_side, false));
        let up = relay(cc_side, true);
        (down.join().unwrap_or_default(), up)
    });
    Ok((p1 + p2, d1 + d2))
}

/// Settings of the demo.
pub struct DemoOptions {
    /// Share of datagrams the relay drops each way.
    pub loss: f64,
    /// Receiver failures.
    pub cycles: u32,
    /// Seconds each failure lasts, and the receiver works between them.
    pub lost_for: f64,
    pub back_for: f64,
    /// Seed of the relay's drops.
    pub seed: u64,
}

/// When the demo's first failure comes (s): the daemons have met by then.
const FIRST_FAILURE: f64 = 2.0;

/// A link with neither signing nor a fixed peer; nothing is routed to it
/// (the demo has no other link).
fn plain_link(endpoint: Endpoint) -> LinkOptions {
    LinkOptions {
        endpoint,
        name: None,
        key: None,
        peer: None,
        signing_state: None,
        routed_rate: None,
    }
}

/// The companion of the demo: listening at `addr`, flying wings level.
fn companion(addr: SocketAddr, own: Peer, fc: Peer, duration: f64) -> CcOptions {
    CcOptions {
        outs: Vec::new(),
        filters: Vec::new(),
        dedup: None,
        trusted_outs: Vec::new(),
        trusted_out_remote: false,
        autonomy: None,
        autonomy_peer: None,
        autonomy_fallback: Default::default(),
        link: plain_link(Endpoint::UdpIn(addr.into())),
        own,
        fc,
        rate_hz: 20.0,
        controller: Box::new(WingsLevel { throttle: 1600 }),
        require_signed: false,
        duration: Some(Duration::from_secs_f64(duration)),
        exit_after_handback: false,
        events: None,
        log_level: crate::live::Level::Info,
        report: None,
        tlog: None,
        stop_on_signals: false,
    }
}

/// The FC of the demo, sending to the relay at `relay`.
fn flight_controller(relay: SocketAddr, own: Peer, companion: Peer, o: &DemoOptions) -> FcOptions {
    let period = o.lost_for + o.back_for;
    let outages: Vec<(f64, Option<f64>)> = (0..o.cycles)
        .map(|k| {
            let lost = FIRST_FAILURE + f64::from(k) * period;
            (lost, Some(lost + o.lost_for))
        })
        .collect();
    FcOptions {
        link: plain_link(Endpoint::UdpOut(relay.into())),
        own,
        companion,
        outages,
        duration: demo_duration(o),
        require_signed: false,
        events: None,
        log_level: crate::live::Level::Info,
        report: None,
        stop_on_signals: false,
        home: crate::fc_sim::plane::Home::DEFAULT,
        pilot_mode: crate::fc_sim::PilotMode::Fbwa,
        arm_at: 0.0,
        key_file: None,
    }
}

/// How long the FC runs: every failure and return, and half a second.
fn demo_duration(o: &DemoOptions) -> f64 {
    FIRST_FAILURE + f64::from(o.cycles) * (o.lost_for + o.back_for) + 0.5
}

/// Runs the demo: prints the timeline and a summary of the handovers.
pub fn demo(o: DemoOptions) -> io::Result<FcReport> {
    let duration = demo_duration(&o);
    let (loss, seed) = (o.loss, o.seed);
    // The CC listens; the relay forwards the FC's datagrams to it and the
    // CC's answers back to the FC.
    let cc_port = UdpSocket::bind("127.0.0.1:0")?.local_addr()?.port();
    let relay_socket = UdpSocket::bind("127.0.0.1:0")?;
    let relay_port = relay_socket.local_addr()?.port();
    let until = WallInstant::now() + Duration::from_secs_f64(duration + 0.5);
    let cc_addr = SocketAddr::from(([127, 0, 0, 1], cc_port));
    let relay = std::thread::spawn(move || run_relay(relay_socket, cc_addr, loss, until, seed));
    let (fc_id, cc_id) = (Peer::new(1, 1), Peer::new(1, 191));
    let cc_opts = companion(cc_addr, cc_id, fc_id, duration + 0.3);
    let cc = std::thread::spawn(move || run_cc(cc_opts, Box::new(io::stdout())));
    let relay_addr = SocketAddr::from(([127, 0, 0, 1], relay_port));
    let fc_opts = flight_controller(relay_addr, fc_id, cc_id, &o);
    let report = run_fc(fc_opts, Box::new(io::stdout()))?;
    let joined = |what| io::Error::other(format!("{what} thread panicked"));
    let cc_report = cc.join().map_err(|_| joined("companion"))??;
    let (passed, dropped) = relay.join().map_err(|_| joined("relay"))??;
    println!(
        "\nsummary: relay passed {passed} and dropped {dropped} datagrams ({:.0} % loss asked, seed {seed})",
        loss * 100.0
    );
    println!(
        "companion: {} takeover(s), {} hand-back acknowledgement(s)",
        cc_report.takeovers, cc_report.handbacks
    );
    println!("{}", handover_summary(&report));
    Ok(report)
}

/// "handovers (receiver failure → companion control): 5 of 5 failures;
/// 101, 1106, ... ms; p50 ..., max ..."
fn handover_summary(report: &FcReport) -> String {
    let mut ms: Vec<u64> = report
        .handovers
        .iter()
        .map(|h| (h * 1000.0).round() as u64)
        .collect();
    let list = ms.iter().map(u64::to_string).collect::<Vec<_>>().join(", ");
    ms.sort_unstable();
    let head = format!(
        "handovers (receiver failure → companion control): {} of {} failures",
        ms.len(),
        report.outages
    );
    match (ms.get((ms.len().max(1) - 1) / 2), ms.last()) {
        (Some(p50), Some(max)) => format!("{head}: {list} ms; p50 {p50} ms, max {max} ms"),
        _ => format!("{head} (see the timeline)"),
    }
}
