//! A companion computer in one file: mavframe's `Router` carries the links
//! and signs and verifies on them, fbwag-delegation's `CompanionNode`
//! decides what each frame is and what to send. When the FC loses its RC
//! receiver, the companion takes over and flies wings level.
//!
//! ```sh
//! KEY=$(openssl rand -hex 32)
//! fbwag fc-sim --link udpin:127.0.0.1:14550 --sign-key "$KEY" --require-signed --rc-loss-at 5 &
//! cargo run -p fbwag-delegation --example companion -- udpout:127.0.0.1:14550 "$KEY" 15
//! ```
//!
//! Arguments: the FC's link, its key (64 hex digits), seconds to run.
//! `cargo test` runs the example against an in-process FC (below).

use fbwag_delegation::cc::CcConfig;
use fbwag_delegation::control::{Controller, WingsLevel};
use fbwag_delegation::engine::CcOutput;
use fbwag_delegation::node::{Answers, Arrival, CompanionEvent, CompanionNode, ControlSource};
use fbwag_delegation::node::{LinkSpec, Output, Role};
use fbwag_delegation::Moment;
use fbwag_dialect::mavframe::conn::Endpoint;
use fbwag_dialect::mavframe::route::Links;
use fbwag_dialect::mavframe::router::{LinkConfig, Router, RouterEvent};
use fbwag_dialect::{Dialect, Unsigned};
use std::error::Error;
use std::time::{Duration, Instant};

/// What the companion did: takeovers, RC overrides sent, frames refused.
#[derive(Debug, Default)]
pub struct Report {
    pub takeovers: u32,
    pub controls: u64,
    pub dropped: u64,
}

/// Runs a companion on the FC link `fc`, signed with `key`, until
/// `deadline`.
pub async fn companion(
    fc: Endpoint,
    key: [u8; 32],
    deadline: Instant,
) -> Result<Report, Box<dyn Error>> {
    let started = Instant::now();
    let now = || Moment(started.elapsed().as_micros() as u64);
    // The link signs what it sends and verifies what it receives; unsigned
    // frames reach the node, which refuses them (and counts them).
    let mut router = Router::<Dialect>::new();
    let mut link = LinkConfig::new(fc);
    link.key = Some(key);
    link.unsigned = Unsigned::Accept;
    let fc_link = router.add(link).await?;
    let cfg = CcConfig {
        require_signed: true,
        ..CcConfig::default()
    };
    let mut node = CompanionNode::new(cfg, ControlSource::Builtin, now())?;
    node.add_link(fc_link, LinkSpec::new(Role::Peer, Answers::Target))?;
    let (mut pilot, mut report) = (WingsLevel { throttle: 1500 }, Report::default());

    while Instant::now() < deadline {
        if node.poll_timeout().is_some_and(|t| t <= now()) {
            node.handle_timeout(now());
        }
        // What the node asks for: frames to send, peers to answer, events.
        while let Some(out) = node.poll_output() {
            let (sys, comp) = (cfg.own.sysid, cfg.own.compid);
            match out {
                Output::Transmit { links, message } => {
                    router.send_message(links, sys, comp, &message);
                }
                Output::TransmitTo { link, to, message } => {
                    router.send_message_to(Links::only(link), Some(to), sys, comp, &message);
                }
                Output::Peers { link, peers } => {
                    router.set_peers(link, &peers.iter().collect::<Vec<_>>());
                }
                Output::Event(CompanionEvent::Engine(CcOutput::ControlDue)) => {
                    report.controls += 1;
                    let _ = node.submit_control(now(), pilot.control(now(), cfg.fc));
                }
                Output::Event(CompanionEvent::Engine(CcOutput::ControlStarted { event })) => {
                    report.takeovers += 1;
                    println!("FC event {event}: the companion flies");
                }
                Output::Event(event) => println!("{event:?}"),
                _ => {}
            }
        }
        // Sleep until the node's next deadline, a frame, or the end.
        let wake = node
            .poll_timeout()
            .map_or(deadline, |t| started + Duration::from_micros(t.0));
        let wait = wake.min(deadline).saturating_duration_since(Instant::now());
        let Some(RouterEvent::Frame(inbound)) = tokio::select!(
            event = router.recv() => event,
            _ = tokio::time::sleep(wait) => continue,
        ) else {
            continue; // a link down or up again: the router reopens it
        };
        let fate = node.handle_frame(
            now(),
            Arrival {
                link: inbound.link,
                source: inbound.source,
                frame: inbound.frame.frame(),
                authenticated: inbound.frame.is_authenticated(),
            },
        );
        // Where the frame goes: nowhere, byte for byte, or signed again.
        if fate.dropped.is_some() {
            report.dropped += 1;
        } else if fate.sign {
            router.route_signed(&inbound, fate.route);
        } else if !fate.route.is_empty() {
            router.route(&inbound, fate.route);
        }
    }
    router.shutdown(Duration::from_secs(1)).await;
    Ok(report)
}

fn main() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [fc, key, seconds] = &args[..] else {
        return Err("usage: companion FC_LINK KEY_HEX64 SECONDS".into());
    };
    let key = parse_key(key).ok_or("the key is 64 hex digits")?;
    let deadline = Instant::now() + Duration::from_secs(seconds.parse()?);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let report = runtime.block_on(companion(fc.parse()?, key, deadline))?;
    println!("{report:?}");
    Ok(())
}

fn parse_key(hex: &str) -> Option<[u8; 32]> {
    let mut key = [0u8; 32];
    for (i, b) in key.iter_mut().enumerate() {
        *b = u8::from_str_radix(hex.get(2 * i..2 * i + 2)?, 16).ok()?;
    }
    (hex.len() == 64).then_some(key)
}

#[cfg(test)]
mod tests {
    use super::*;
    use fbwag_delegation::engine::FcOutput;
    use fbwag_delegation::fc::FcConfig;
    use fbwag_delegation::node::FcNode;

    /// An FC on `link`, signed with `key`, whose receiver fails at `loss`:
    /// the RC overrides it applied from the companion, authenticated.
    async fn fc(link: Endpoint, key: [u8; 32], loss: Instant, deadline: Instant) -> u64 {
        let started = Instant::now();
        let now = || Moment(started.elapsed().as_micros() as u64);
        let mut router = Router::<Dialect>::new();
        let mut config = LinkConfig::new(link);
        config.key = Some(key);
        let cc_link = router.add(config).await.expect("the FC's link opens");
        let cfg = FcConfig {
            require_signed: true,
            ..FcConfig::default()
        };
        let mut node = FcNode::new(cfg, now()).expect("a valid configuration");
        let spec = LinkSpec::new(Role::Peer, Answers::Chosen);
        node.add_link(cc_link, spec).expect("one link");
        let mut applied = 0;
        while Instant::now() < deadline {
            node.set_receiver_ok(Instant::now() < loss);
            if node.poll_timeout().is_some_and(|t| t <= now()) {
                node.handle_timeout(now());
            }
            while let Some(out) = node.poll_output() {
                let own = cfg.own;
                match out {
                    Output::Transmit { links, message } => {
                        router.send_message(links, own.sysid, own.compid, &message);
                    }
                    Output::Peers { link, peers } => {
                        router.set_peers(link, &peers.iter().collect::<Vec<_>>());
                    }
                    Output::Event(FcOutput::ApplyControl { from, .. }) if from.authenticated => {
                        applied += 1;
                    }
                    _ => {}
                }
            }
            let wait = Duration::from_millis(10);
            if let Ok(Some(RouterEvent::Frame(inbound))) =
                tokio::time::timeout(wait, router.recv()).await
            {
                let arrival = Arrival {
                    link: inbound.link,
                    source: inbound.source,
                    frame: inbound.frame.frame(),
                    authenticated: inbound.frame.is_authenticated(),
                };
                // One link: nothing to route on.
                let _ = node.handle_frame(now(), arrival);
            }
        }
        router.shutdown(Duration::from_secs(1)).await;
        applied
    }

    #[test]
    fn the_companion_takes_over_when_the_fc_loses_its_receiver() {
        let port = std::net::UdpSocket::bind("127.0.0.1:0")
            .and_then(|s| s.local_addr())
            .expect("a free port")
            .port();
        let key = parse_key(&"5a".repeat(32)).expect("a key");
        let start = Instant::now();
        let (loss, deadline) = (
            start + Duration::from_millis(1500),
            start + Duration::from_secs(4),
        );
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .expect("a runtime");
        let fc_link = format!("udpin:127.0.0.1:{port}")
            .parse()
            .expect("an endpoint");
        let cc_link = format!("udpout:127.0.0.1:{port}")
            .parse()
            .expect("an endpoint");
        let (applied, report) = runtime.block_on(async {
            tokio::join!(
                fc(fc_link, key, loss, deadline),
                companion(cc_link, key, deadline)
            )
        });
        let report = report.expect("the companion runs");
        assert_eq!(report.takeovers, 1, "{report:?}");
        assert!(
            report.controls > 0 && applied > 0,
            "{report:?}, {applied} applied"
        );
        assert_eq!(report.dropped, 0, "{report:?}");
    }
}
