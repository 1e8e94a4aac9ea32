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
use fbwag_dialect::mavframe::router::{Inbound, LinkConfig, Out, Policy, Router};
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

/// The node as the router's policy: each frame a link receives is judged
/// by the node in the link's task, and sent on (or not) there; what the
/// node asks for goes out through the same [`Out`].
struct Companion {
    node: CompanionNode,
    cfg: CcConfig,
    pilot: WingsLevel,
    report: Report,
    started: Instant,
}

impl Companion {
    fn now(&self) -> Moment {
        Moment(self.started.elapsed().as_micros() as u64)
    }

    /// What the node asks for: frames to send, peers to answer, events.
    fn drain(&mut self, out: &mut Out<'_>) {
        let (sys, comp) = (self.cfg.own.sysid, self.cfg.own.compid);
        while let Some(output) = self.node.poll_output() {
            match output {
                Output::Transmit { links, message } => {
                    out.send_message(links, sys, comp, &message);
                }
                Output::TransmitTo { link, to, message } => {
                    out.send_message_to(Links::only(link), Some(to), sys, comp, &message);
                }
                Output::Peers { link, peers } => {
                    out.set_peers(link, &peers.iter().collect::<Vec<_>>());
                }
                Output::Event(CompanionEvent::Engine(CcOutput::ControlDue)) => {
                    self.report.controls += 1;
                    let now = self.now();
                    let control = self.pilot.control(now, self.cfg.fc);
                    let _ = self.node.submit_control(now, control);
                }
                Output::Event(CompanionEvent::Engine(CcOutput::ControlStarted { event })) => {
                    self.report.takeovers += 1;
                    println!("FC event {event}: the companion flies");
                }
                Output::Event(event) => println!("{event:?}"),
                _ => {}
            }
        }
    }

    /// The node's timers, when due: how long until the next.
    fn timers(&mut self, out: &mut Out<'_>) -> Option<Duration> {
        let now = self.now();
        if self.node.poll_timeout().is_some_and(|t| t <= now) {
            self.node.handle_timeout(now);
        }
        self.drain(out);
        let next = self.node.poll_timeout()?;
        Some(Duration::from_micros(next.0.saturating_sub(self.now().0)))
    }
}

impl Policy<Dialect> for Companion {
    fn frame(&mut self, inbound: &Inbound<'_, Dialect>, out: &mut Out<'_>) {
        let arrival = Arrival {
            link: inbound.link,
            source: inbound.source,
            frame: inbound.frame.frame(),
            authenticated: inbound.frame.is_authenticated(),
        };
        let fate = self.node.handle_frame(self.now(), arrival);
        // Where the frame goes: nowhere, byte for byte, or signed again.
        if fate.dropped.is_some() {
            self.report.dropped += 1;
        } else if fate.sign {
            out.route_signed(inbound, fate.route);
        } else if !fate.route.is_empty() {
            out.route(inbound, fate.route);
        }
        self.drain(out);
    }
}

/// Runs a companion on the FC link `fc`, signed with `key`, until
/// `deadline`.
pub async fn companion(
    fc: Endpoint,
    key: [u8; 32],
    deadline: Instant,
) -> Result<Report, Box<dyn Error>> {
    let started = Instant::now();
    let cfg = CcConfig {
        require_signed: true,
        ..CcConfig::default()
    };
    let now = Moment(0);
    let mut node = CompanionNode::new(cfg, ControlSource::Builtin, now)?;
    // The FC's link is the router's first: link 0.
    node.add_link(0, LinkSpec::new(Role::Peer, Answers::Target))?;
    let companion = Companion {
        node,
        cfg,
        pilot: WingsLevel { throttle: 1500 },
        report: Report::default(),
        started,
    };
    // The link signs what it sends and verifies what it receives; unsigned
    // frames reach the node, which refuses them (and counts them).
    let mut router = Router::<Dialect, _>::new(companion);
    let mut link = LinkConfig::new(fc);
    link.key = Some(key);
    link.unsigned = Unsigned::Accept;
    router.add(link).await?;
    // The frames are the links'; this loop runs the node's timers.
    while Instant::now() < deadline {
        let wait = router
            .with(|c, out| c.timers(out))
            .unwrap_or(deadline - Instant::now());
        let wait = wait.min(deadline.saturating_duration_since(Instant::now()));
        tokio::time::sleep(wait).await;
    }
    let companion = router.shutdown(Duration::from_secs(1)).await;
    Ok(companion.ok_or("a link task outlived the router")?.report)
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

    /// The FC's node, as its router's policy: the RC overrides it applied
    /// from the companion, authenticated.
    struct Fc {
        node: FcNode,
        cfg: FcConfig,
        started: Instant,
        loss: Instant,
        applied: u64,
    }

    impl Fc {
        fn now(&self) -> Moment {
            Moment(self.started.elapsed().as_micros() as u64)
        }

        fn drain(&mut self, out: &mut Out<'_>) {
            let own = self.cfg.own;
            while let Some(output) = self.node.poll_output() {
                match output {
                    Output::Transmit { links, message } => {
                        out.send_message(links, own.sysid, own.compid, &message);
                    }
                    Output::Peers { link, peers } => {
                        out.set_peers(link, &peers.iter().collect::<Vec<_>>());
                    }
                    Output::Event(FcOutput::ApplyControl { from, .. }) if from.authenticated => {
                        self.applied += 1;
                    }
                    _ => {}
                }
            }
        }
    }

    impl Policy<Dialect> for Fc {
        fn frame(&mut self, inbound: &Inbound<'_, Dialect>, out: &mut Out<'_>) {
            let arrival = Arrival {
                link: inbound.link,
                source: inbound.source,
                frame: inbound.frame.frame(),
                authenticated: inbound.frame.is_authenticated(),
            };
            // One link: nothing to route on.
            let _ = self.node.handle_frame(self.now(), arrival);
            self.drain(out);
        }
    }

    /// An FC on `link`, signed with `key`, whose receiver fails at `loss`:
    /// the RC overrides it applied from the companion, authenticated.
    async fn fc(link: Endpoint, key: [u8; 32], loss: Instant, deadline: Instant) -> u64 {
        let cfg = FcConfig {
            require_signed: true,
            ..FcConfig::default()
        };
        let mut node = FcNode::new(cfg, Moment(0)).expect("a valid configuration");
        let spec = LinkSpec::new(Role::Peer, Answers::Chosen);
        node.add_link(0, spec).expect("one link");
        let fc = Fc {
            node,
            cfg,
            started: Instant::now(),
            loss,
            applied: 0,
        };
        let mut router = Router::<Dialect, _>::new(fc);
        let mut config = LinkConfig::new(link);
        config.key = Some(key);
        router.add(config).await.expect("the FC's link opens");
        while Instant::now() < deadline {
            router.with(|fc, out| {
                fc.node.set_receiver_ok(Instant::now() < fc.loss);
                let now = fc.now();
                if fc.node.poll_timeout().is_some_and(|t| t <= now) {
                    fc.node.handle_timeout(now);
                }
                fc.drain(out);
            });
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
        let fc = router.shutdown(Duration::from_secs(1)).await;
        fc.expect("the FC's policy back").applied
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
