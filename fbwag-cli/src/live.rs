//! The delegation protocol on real links: the companion daemon (`fbwag
//! cc`), a flight-controller simulator speaking like ArduPlane (`fbwag
//! fc-sim`), and both over a lossy loopback relay (`fbwag demo`).
//!
//! The state machines are the simulator's; here a wall clock drives them and
//! frames come from `mavframe::conn` transports.

use fbwag_delegation::cc::{CcAction, CcConfig, CcInput, Companion};
use fbwag_delegation::fc::{Authority, FcAction, FcConfig, FcInput, FlightController};
use fbwag_delegation::{wire, Origin, Peer, Status};
use fbwag_dialect::dialects::common::{Attitude, RcChannels, RcChannelsOverride, SysStatus};
use fbwag_dialect::dialects::minimal::{Heartbeat, MavAutopilot, MavModeFlag, MavState, MavType};
use fbwag_dialect::mavframe::conn::Endpoint;
use fbwag_dialect::{Connection, Message, ReceivedFrame, Signer, Verifier};
use std::io::Write;
use std::time::{Duration, Instant as WallInstant};

/// The machines' time from a wall clock.
#[derive(Clone, Copy)]
pub struct Clock(WallInstant);

impl Clock {
    pub fn start() -> Self {
        Clock(WallInstant::now())
    }

    pub fn now(&self) -> fbwag_delegation::Instant {
        fbwag_delegation::Instant(self.0.elapsed().as_micros() as u64)
    }

    pub fn secs(&self) -> f64 {
        self.0.elapsed().as_secs_f64()
    }

    /// Wall time until machine time `t` (zero if past).
    pub fn until(&self, t: fbwag_delegation::Instant) -> Duration {
        Duration::from_micros(t.0.saturating_sub(self.now().0))
    }
}

/// A log line with the time since start: every transition is logged.
pub fn log(out: &mut dyn Write, clock: &Clock, who: &str, what: &str) {
    let _ = writeln!(out, "[{:>8.3} s] {who}: {what}", clock.secs());
    let _ = out.flush();
}

fn origin(r: &ReceivedFrame<fbwag_dialect::Dialect>) -> Origin {
    let h = r.header();
    Origin {
        peer: Peer::new(h.sysid, h.compid),
        authenticated: r.is_authenticated(),
        seq: h.seq,
    }
}

/// Opens `endpoint`; with a key, signs what is sent and verifies what
/// comes (unsigned frames still arrive, marked unauthenticated: whether they
/// count is the state machine's policy).
fn open_link(endpoint: &Endpoint, key: Option<[u8; 32]>) -> std::io::Result<Connection> {
    let Some(k) = key else {
        return Connection::open(endpoint);
    };
    let transport = fbwag_dialect::mavframe::conn::open(endpoint)?;
    let mut link = Connection::with_parser(
        transport,
        fbwag_dialect::Parser::with_signing(Verifier::new(k), true),
    );
    link.set_signer(Some(Signer::new(
        k,
        0,
        fbwag_dialect::mavframe::signing::timestamp_now(),
    )));
    Ok(link)
}

/// Channel values a controller outputs (PWM µs, 0 = release the channel).
pub trait Controller {
    /// The override channels 1–8 for now.
    fn channels(&mut self, t: f64) -> [u16; 8];
    /// Name for the log.
    fn name(&self) -> &'static str;
}

/// The default: wings level, cruise throttle, rudder centred.
pub struct WingsLevel {
    pub throttle: u16,
}

impl Controller for WingsLevel {
    fn channels(&mut self, _t: f64) -> [u16; 8] {
        [1500, 1500, self.throttle, 1500, 0, 0, 0, 0]
    }
    fn name(&self) -> &'static str {
        "wings-level"
    }
}

/// A gentle constant-bank circle (for ground tests of the override path).
pub struct Circle {
    pub throttle: u16,
}

impl Controller for Circle {
    fn channels(&mut self, _t: f64) -> [u16; 8] {
        [1650, 1500, self.throttle, 1500, 0, 0, 0, 0]
    }
    fn name(&self) -> &'static str {
        "circle"
    }
}

/// Settings of the companion daemon.
pub struct CcOptions {
    pub link: Endpoint,
    pub sysid: u8,
    pub compid: u8,
    pub fc_sysid: u8,
    pub fc_compid: u8,
    pub rate_hz: f64,
    pub controller: Box<dyn Controller + Send>,
    pub sign_key: Option<[u8; 32]>,
    pub require_signed: bool,
    pub duration: Option<Duration>,
    pub exit_after_handback: bool,
}

/// The companion daemon. Returns (takeovers, hand-backs) when it ends.
pub fn run_cc(mut o: CcOptions, out: &mut dyn Write) -> std::io::Result<(u32, u32)> {
    let clock = Clock::start();
    let mut link = open_link(&o.link, o.sign_key)?;
    let cfg = CcConfig {
        own: Peer::new(o.sysid, o.compid),
        fc: Peer::new(o.fc_sysid, o.fc_compid),
        require_signed: o.require_signed,
        control_period: Duration::from_secs_f64(1.0 / o.rate_hz.clamp(1.0, 100.0)),
        ..CcConfig::default()
    };
    let mut cc = Companion::new(cfg);
    log(
        out,
        &clock,
        "cc",
        &format!(
            "listening on {} as {}/{}, serving FC {}/{}, controller {}",
            o.link,
            o.sysid,
            o.compid,
            o.fc_sysid,
            o.fc_compid,
            o.controller.name()
        ),
    );
    let mut next_heartbeat = clock.now();
    let (mut takeovers, mut handbacks) = (0u32, 0u32);
    let mut last_state = cc.state();
    loop {
        if o.duration.is_some_and(|d| clock.secs() >= d.as_secs_f64()) {
            break;
        }
        let now = clock.now();
        if now >= next_heartbeat {
            let hb = Heartbeat {
                r#type: MavType::ONBOARD_CONTROLLER,
                autopilot: MavAutopilot::INVALID,
                system_status: MavState::ACTIVE,
                ..Heartbeat::default()
            };
            link.send_auto(o.sysid, o.compid, &hb)?;
            next_heartbeat = now + Duration::from_secs(1);
        }
        let deadline = cc
            .poll_timeout()
            .map_or(next_heartbeat, |t| t.min(next_heartbeat));
        let wait = clock.until(deadline).min(Duration::from_millis(100));
        if let Some(r) = link.recv(Some(wait))? {
            let from = origin(&r);
            let now = clock.now();
            match r.message() {
                Some(Message::Heartbeat(h)) => cc.handle_input(
                    now,
                    CcInput::Heartbeat {
                        from,
                        custom_mode: h.custom_mode,
                    },
                ),
                Some(Message::FbwagNotice(n)) => {
                    log(
                        out,
                        &clock,
                        "cc",
                        &format!(
                            "<- FBWAG_NOTICE status {} event {}",
                            n.failsafe_status.0, n.timestamp
                        ),
                    );
                    cc.handle_input(
                        now,
                        CcInput::Notice {
                            from,
                            status: n.failsafe_status,
                            timestamp: n.timestamp,
                        },
                    );
                }
                Some(Message::Statustext(t)) => {
                    let end = t.text.iter().position(|&b| b == 0).unwrap_or(t.text.len());
                    let text = String::from_utf8_lossy(&t.text[..end]).into_owned();
                    log(out, &clock, "cc", &format!("<- STATUSTEXT {text:?}"));
                    cc.handle_input(
                        now,
                        CcInput::StatusText {
                            from,
                            text: &text,
                            id: t.id,
                        },
                    );
                }
                _ => {}
            }
        }
        let now = clock.now();
        if cc.poll_timeout().is_some_and(|t| t <= now) {
            cc.handle_timeout(now);
        }
        while let Some(a) = cc.poll_action() {
            match a {
                CcAction::SendNotice { status, timestamp } => {
                    let n = wire::notice(Peer::new(o.fc_sysid, o.fc_compid), status, timestamp);
                    link.send_auto(o.sysid, o.compid, &n)?;
                    log(
                        out,
                        &clock,
                        "cc",
                        &format!("-> FBWAG_NOTICE status {} event {timestamp}", status.0),
                    );
                    if status == Status::NORMAL {
                        handbacks += 1;
                    }
                }
                CcAction::SendControl => {
                    let c = o.controller.channels(clock.secs());
                    let m = RcChannelsOverride {
                        target_system: o.fc_sysid,
                        target_component: o.fc_compid,
                        chan1_raw: c[0],
                        chan2_raw: c[1],
                        chan3_raw: c[2],
                        chan4_raw: c[3],
                        chan5_raw: c[4],
                        chan6_raw: c[5],
                        chan7_raw: c[6],
                        chan8_raw: c[7],
                        ..Default::default()
                    };
                    link.send_auto(o.sysid, o.compid, &m)?;
                }
                CcAction::StartControl => {
                    takeovers += 1;
                    log(
                        out,
                        &clock,
                        "cc",
                        "takeover: streaming RC_CHANNELS_OVERRIDE",
                    );
                }
                CcAction::StopControl => log(out, &clock, "cc", "control ends: overrides stopped"),
            }
        }
        if cc.state() != last_state {
            log(
                out,
                &clock,
                "cc",
                &format!("state {:?} -> {:?}", last_state, cc.state()),
            );
            last_state = cc.state();
        }
        if o.exit_after_handback
            && handbacks > 0
            && cc.state() != fbwag_delegation::cc::CcState::Controlling
        {
            break;
        }
    }
    Ok((takeovers, handbacks))
}

/// Settings of the flight-controller simulator.
pub struct FcOptions {
    pub link: Endpoint,
    pub sysid: u8,
    pub compid: u8,
    pub cc_sysid: u8,
    pub cc_compid: u8,
    pub rc_loss_at: Option<f64>,
    pub rc_back_at: Option<f64>,
    pub duration: f64,
    pub sign_key: Option<[u8; 32]>,
    pub require_signed: bool,
}

/// What the FC simulator saw, for the demo and tests.
#[derive(Debug, Default, Clone)]
pub struct FcReport {
    /// (seconds, authority) at every change.
    pub timeline: Vec<(f64, Authority)>,
    /// Seconds from RC loss (receiver) to companion control.
    pub handover: Option<f64>,
    /// Seconds at which the receiver was lost.
    pub rc_lost_at: Option<f64>,
}

/// The flight-controller simulator: ArduPlane-like telemetry, a receiver
/// that fails and returns on schedule, and the FC state machine.
pub fn run_fc(o: FcOptions, out: &mut dyn Write) -> std::io::Result<FcReport> {
    let clock = Clock::start();
    let mut link = open_link(&o.link, o.sign_key)?;
    let cfg = FcConfig {
        own: Peer::new(o.sysid, o.compid),
        companion: Peer::new(o.cc_sysid, o.cc_compid),
        require_signed: o.require_signed,
        ..FcConfig::default()
    };
    let mut fc = FlightController::new(cfg);
    let mut report = FcReport::default();
    log(
        out,
        &clock,
        "fc",
        &format!(
            "ArduPlane simulator on {} as {}/{}; companion {}/{}",
            o.link, o.sysid, o.compid, o.cc_sysid, o.cc_compid
        ),
    );
    let (mut next_sample, mut next_hb, mut next_att, mut next_slow) =
        (clock.now(), clock.now(), clock.now(), clock.now());
    let mut accept_overrides = false;
    let mut override_ch = [0u16; 8];
    let mut roll = 0.0f32;
    let mut reported_loss = false;
    while clock.secs() < o.duration {
        let now = clock.now();
        let t = clock.secs();
        let receiver_ok =
            !(o.rc_loss_at.is_some_and(|l| t >= l) && o.rc_back_at.is_none_or(|b| t < b));
        if !receiver_ok && !reported_loss {
            reported_loss = true;
            report.rc_lost_at = Some(t);
            log(out, &clock, "fc", "receiver: signal lost (failsafe)");
        }
        if receiver_ok && reported_loss {
            reported_loss = false;
            log(out, &clock, "fc", "receiver: signal back");
        }
        if now >= next_sample {
            fc.handle_input(now, FcInput::RcSample { receiver_ok });
            next_sample = next_sample + Duration::from_millis(100);
        }
        if now >= next_hb {
            let a = fc.authority();
            let hb = Heartbeat {
                r#type: MavType::FIXED_WING,
                autopilot: MavAutopilot::ARDUPILOTMEGA,
                base_mode: MavModeFlag::CUSTOM_MODE_ENABLED
                    | MavModeFlag::STABILIZE_ENABLED
                    | MavModeFlag::SAFETY_ARMED,
                custom_mode: wire::custom_mode(a),
                system_status: MavState::ACTIVE,
                mavlink_version: 3,
            };
            link.send_auto(o.sysid, o.compid, &hb)?;
            // In companion control the heartbeat is the confirmation stream.
            next_hb = now
                + if a == Authority::Companion {
                    Duration::from_millis(200)
                } else {
                    Duration::from_secs(1)
                };
        }
        if now >= next_att {
            // Roll follows the aileron channel in companion control.
            let target = if accept_overrides && override_ch[0] != 0 {
                (override_ch[0] as f32 - 1500.0) / 500.0 * 0.78
            } else {
                0.0
            };
            roll += (target - roll) * 0.2;
            let att = Attitude {
                time_boot_ms: (t * 1000.0) as u32,
                roll,
                pitch: 0.02,
                yaw: (t as f32 * 0.05) % std::f32::consts::TAU,
                ..Default::default()
            };
            link.send_auto(o.sysid, o.compid, &att)?;
            next_att = now + Duration::from_millis(100);
        }
        if now >= next_slow {
            let rc = RcChannels {
                time_boot_ms: (t * 1000.0) as u32,
                chancount: 8,
                chan1_raw: if accept_overrides && override_ch[0] != 0 {
                    override_ch[0]
                } else {
                    1500
                },
                chan3_raw: if accept_overrides && override_ch[2] != 0 {
                    override_ch[2]
                } else {
                    1400
                },
                rssi: if receiver_ok { 200 } else { 0 },
                ..Default::default()
            };
            link.send_auto(o.sysid, o.compid, &rc)?;
            let sys = SysStatus {
                voltage_battery: 12_400,
                battery_remaining: 80,
                ..Default::default()
            };
            link.send_auto(o.sysid, o.compid, &sys)?;
            next_slow = now + Duration::from_millis(500);
        }
        let deadline = [
            Some(next_sample),
            Some(next_hb),
            Some(next_att),
            fc.poll_timeout(),
        ]
        .into_iter()
        .flatten()
        .min()
        .unwrap_or(now);
        let wait = clock.until(deadline).min(Duration::from_millis(50));
        if let Some(r) = link.recv(Some(wait))? {
            let from = origin(&r);
            let now = clock.now();
            match r.message() {
                Some(Message::FbwagNotice(n)) => {
                    log(
                        out,
                        &clock,
                        "fc",
                        &format!(
                            "<- FBWAG_NOTICE status {} event {} from {}/{}",
                            n.failsafe_status.0, n.timestamp, from.peer.sysid, from.peer.compid
                        ),
                    );
                    fc.handle_input(
                        now,
                        FcInput::Notice {
                            from,
                            status: n.failsafe_status,
                            timestamp: n.timestamp,
                        },
                    );
                }
                Some(Message::RcChannelsOverride(ov)) => {
                    if accept_overrides && from.peer == fc.config().companion {
                        override_ch = [
                            ov.chan1_raw,
                            ov.chan2_raw,
                            ov.chan3_raw,
                            ov.chan4_raw,
                            ov.chan5_raw,
                            ov.chan6_raw,
                            ov.chan7_raw,
                            ov.chan8_raw,
                        ];
                    }
                    fc.handle_input(now, FcInput::Control { from });
                }
                Some(Message::SetAttitudeTarget(_)) => {
                    fc.handle_input(now, FcInput::Control { from })
                }
                Some(Message::Heartbeat(_)) => fc.handle_input(now, FcInput::Heartbeat { from }),
                _ => {}
            }
        }
        let now = clock.now();
        if fc.poll_timeout().is_some_and(|t| t <= now) {
            fc.handle_timeout(now);
        }
        while let Some(a) = fc.poll_action() {
            match a {
                FcAction::SendNotice { status, timestamp } => {
                    let n = wire::notice(Peer::new(o.sysid, o.compid), status, timestamp);
                    link.send_auto(o.sysid, o.compid, &n)?;
                    log(
                        out,
                        &clock,
                        "fc",
                        &format!("-> FBWAG_NOTICE status {} event {timestamp}", status.0),
                    );
                }
                FcAction::SendStatusText { text, event } => {
                    let s = wire::status_text(text, event);
                    link.send_auto(o.sysid, o.compid, &s)?;
                    log(out, &clock, "fc", &format!("-> STATUSTEXT {text:?}"));
                }
                FcAction::SetAuthority(a) => {
                    let t = clock.secs();
                    report.timeline.push((t, a));
                    let name = match a {
                        Authority::Pilot => "FBWA (pilot in control)",
                        Authority::Handshake => "CIRCLE (asking the companion to take over)",
                        Authority::Companion => "FBWAG (companion control)",
                        Authority::Rtl => "RTL (fallback)",
                    };
                    log(out, &clock, "fc", &format!("MODE CHANGE -> {name}"));
                    if a == Authority::Companion && report.handover.is_none() {
                        report.handover = report.rc_lost_at.map(|l| t - l);
                        if let Some(h) = report.handover {
                            log(
                                out,
                                &clock,
                                "fc",
                                &format!("handover {:.0} ms after the receiver failed", h * 1000.0),
                            );
                        }
                    }
                }
                FcAction::AcceptOverrides(on) => {
                    accept_overrides = on;
                    if !on {
                        override_ch = [0; 8];
                    }
                }
            }
        }
    }
    Ok(report)
}

/// A UDP relay between two peers that drops a share of datagrams each way
/// (the demo's "lossy radio"). Runs until `until`.
pub fn run_relay(
    fc_side: std::net::UdpSocket,
    cc_addr: std::net::SocketAddr,
    loss: f64,
    until: WallInstant,
    seed: u64,
) -> std::io::Result<(u64, u64)> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let cc_side = std::net::UdpSocket::bind("127.0.0.1:0")?;
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
                cc_side.send_to(&buf[..n], cc_addr)?;
            }
        }
        if let (Ok((n, _)), Some(fc)) = (cc_side.recv_from(&mut buf), fc_addr) {
            if rng.gen::<f64>() < loss {
                dropped += 1;
            } else {
                passed += 1;
                fc_side.send_to(&buf[..n], fc)?;
            }
        }
    }
    Ok((passed, dropped))
}

/// `fbwag demo`: the companion daemon and the FC simulator over loopback
/// UDP through a lossy relay; prints the timeline and the handover time.
pub fn demo(
    loss: f64,
    rc_loss_at: f64,
    rc_back_at: f64,
    duration: f64,
    seed: u64,
) -> Result<FcReport, String> {
    let io = |e: std::io::Error| format!("demo: {e}");
    // The CC listens; the relay forwards the FC's datagrams to it and the
    // CC's answers back to the FC.
    let cc_socket = std::net::UdpSocket::bind("127.0.0.1:0").map_err(io)?;
    let cc_port = cc_socket.local_addr().map_err(io)?.port();
    drop(cc_socket);
    let relay_socket = std::net::UdpSocket::bind("127.0.0.1:0").map_err(io)?;
    let relay_port = relay_socket.local_addr().map_err(io)?.port();
    let until = WallInstant::now() + Duration::from_secs_f64(duration + 0.5);
    let relay = std::thread::spawn(move || {
        run_relay(
            relay_socket,
            format!("127.0.0.1:{cc_port}").parse().expect("address"),
            loss,
            until,
            seed,
        )
    });
    let cc_link: Endpoint = format!("udpin:127.0.0.1:{cc_port}")
        .parse()
        .map_err(|e| format!("{e}"))?;
    let cc = std::thread::spawn(move || {
        let mut out = std::io::stdout();
        run_cc(
            CcOptions {
                link: cc_link,
                sysid: 1,
                compid: 191,
                fc_sysid: 1,
                fc_compid: 1,
                rate_hz: 20.0,
                controller: Box::new(WingsLevel { throttle: 1600 }),
                sign_key: None,
                require_signed: false,
                duration: Some(Duration::from_secs_f64(duration + 0.3)),
                exit_after_handback: false,
            },
            &mut out,
        )
    });
    let fc_link: Endpoint = format!("udpout:127.0.0.1:{relay_port}")
        .parse()
        .map_err(|e| format!("{e}"))?;
    let mut out = std::io::stdout();
    let report = run_fc(
        FcOptions {
            link: fc_link,
            sysid: 1,
            compid: 1,
            cc_sysid: 1,
            cc_compid: 191,
            rc_loss_at: Some(rc_loss_at),
            rc_back_at: Some(rc_back_at),
            duration,
            sign_key: None,
            require_signed: false,
        },
        &mut out,
    )
    .map_err(io)?;
    let (takeovers, handbacks) = cc
        .join()
        .map_err(|_| "companion thread panicked".to_string())?
        .map_err(io)?;
    let (passed, dropped) = relay
        .join()
        .map_err(|_| "relay thread panicked".to_string())?
        .map_err(io)?;
    println!(
        "\nsummary: relay passed {passed} and dropped {dropped} datagrams ({:.0} % loss asked)",
        loss * 100.0
    );
    println!("companion: {takeovers} takeover(s), {handbacks} hand-back acknowledgement(s)");
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
