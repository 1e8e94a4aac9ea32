//! `fbwag demo`: the companion daemon and the FC simulator over loopback
//! UDP through a relay that drops a share of the datagrams each way.

use super::cc::{run_cc, CcOptions};
use super::fc::{run_fc, FcOptions, FcReport};
use super::link::LinkOptions;
use fbwag_delegation::control::WingsLevel;
use fbwag_delegation::Peer;
use fbwag_dialect::Endpoint;
use rand::{Rng, SeedableRng};
use std::io;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant as WallInstant};

/// A UDP relay between two peers that drops a share of datagrams each way
/// (the demo's "lossy radio"). Runs until `until`; returns (passed, dropped).
pub fn run_relay(
    fc_side: UdpSocket,
    cc_addr: SocketAddr,
    loss: f64,
    until: WallInstant,
    seed: u64,
) -> io::Result<(u64, u64)> {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let cc_side = UdpSocket::bind("127.0.0.1:0")?;
    fc_side.set_read_timeout(Some(Duration::from_millis(5)))?;
    cc_side.set_read_timeout(Some(Duration::from_millis(5)))?;
    let mut fc_addr = None;
    let (mut passed, mut dropped) = (0u64, 0u64);
    let mut buf = [0u8; 2048];
    while WallInstant::now() < until {
        if let Ok((n, from)) = fc_side.recv_from(&mut buf) {
            fc_addr = Some(from);
            if rng.gen::<f64>() < loss {
                dropped += 1;
            } else {
                passed += 1;
                // A send that fails (the companion not up yet) is a loss.
                let _ = cc_side.send_to(&buf[..n], cc_addr);
            }
        }
        if let (Ok((n, _)), Some(fc)) = (cc_side.recv_from(&mut buf), fc_addr) {
            if rng.gen::<f64>() < loss {
                dropped += 1;
            } else {
                passed += 1;
                let _ = fc_side.send_to(&buf[..n], fc);
            }
        }
    }
    Ok((passed, dropped))
}

/// Runs the demo: prints the timeline and the handover time.
pub fn demo(
    loss: f64,
    rc_loss_at: f64,
    rc_back_at: f64,
    duration: f64,
    seed: u64,
) -> io::Result<FcReport> {
    // The CC listens; the relay forwards the FC's datagrams to it and the
    // CC's answers back to the FC.
    let cc_port = UdpSocket::bind("127.0.0.1:0")?.local_addr()?.port();
    let relay_socket = UdpSocket::bind("127.0.0.1:0")?;
    let relay_port = relay_socket.local_addr()?.port();
    let until = WallInstant::now() + Duration::from_secs_f64(duration + 0.5);
    let cc_addr = SocketAddr::from(([127, 0, 0, 1], cc_port));
    let relay = std::thread::spawn(move || run_relay(relay_socket, cc_addr, loss, until, seed));
    let (fc_id, cc_id) = (Peer::new(1, 1), Peer::new(1, 191));
    let cc = std::thread::spawn(move || {
        run_cc(
            CcOptions {
                link: LinkOptions {
                    endpoint: Endpoint::UdpIn(cc_addr),
                    key: None,
                    peer: None,
                },
                own: cc_id,
                fc: fc_id,
                rate_hz: 20.0,
                controller: Box::new(WingsLevel { throttle: 1600 }),
                require_signed: false,
                duration: Some(Duration::from_secs_f64(duration + 0.3)),
                exit_after_handback: false,
                events: None,
            },
            Box::new(io::stdout()),
        )
    });
    let report = run_fc(
        FcOptions {
            link: LinkOptions {
                endpoint: Endpoint::UdpOut(SocketAddr::from(([127, 0, 0, 1], relay_port))),
                key: None,
                peer: None,
            },
            own: fc_id,
            companion: cc_id,
            rc_loss_at: Some(rc_loss_at),
            rc_back_at: Some(rc_back_at),
            duration,
            require_signed: false,
            events: None,
            home: super::plane::Home::DEFAULT,
            pilot_mode: super::fc::PilotMode::Fbwa,
        },
        Box::new(io::stdout()),
    )?;
    let joined = |what| io::Error::other(format!("{what} thread panicked"));
    let cc_report = cc.join().map_err(|_| joined("companion"))??;
    let (passed, dropped) = relay.join().map_err(|_| joined("relay"))??;
    println!(
        "\nsummary: relay passed {passed} and dropped {dropped} datagrams ({:.0} % loss asked)",
        loss * 100.0
    );
    println!(
        "companion: {} takeover(s), {} hand-back acknowledgement(s)",
        cc_report.takeovers, cc_report.handbacks
    );
    println!(
        "FC modes: {}",
        report
            .timeline
            .iter()
            .map(|(t, a)| format!("{t:.2} s {a:?}"))
            .collect::<Vec<_>>()
            .join(" → ")
    );
    match report.handover {
        Some(h) => println!(
            "handover time (receiver failure → companion control): {:.0} ms",
            h * 1000.0
        ),
        None => println!("no handover happened (see the timeline)"),
    }
    Ok(report)
}
