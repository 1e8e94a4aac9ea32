//! A deterministic simulator: the two protocol engines of
//! [`crate::engine`] (the very code `fbwag fc-sim` and `fbwag cc` run), and
//! modelled links carrying real MAVLink frames (encoded, signed, parsed by
//! the runtime), on a virtual clock. The simulator only moves bytes and
//! time: which frames count, who is trusted and which control is applied
//! is decided by the engines. A trial is identified by its scenario, link
//! and seed.
//!
//! Invariants are checked on every event of every trial (see
//! [`Violation`]); [`report`] aggregates trials into Table I and sweeps.

pub mod link;
pub mod report;

use crate::cc::CcConfig;
use crate::control::{Control, Controller, WingsLevel};
use crate::engine::{CcEngine, CcOutput, FcEngine, FcOutput};
use crate::fc::{Authority, FcConfig};
use crate::{Instant, Peer, Status};
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Header, Message, Parser, Signer, Unsigned, Verifier, Version};
use link::{GilbertElliott, Link, LinkModel};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::time::Duration;

/// The scenarios: the paper's four tests, then the ones beyond it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Scenario {
    /// Test 1: the pilot flies; RC is never lost. Success: nothing happens.
    NormalRc,
    /// Test 2: RC lost once; the companion takes over. Success: companion
    /// control within 5 s.
    RcLoss,
    /// Test 3: as RC loss, on a link losing frames (50 % in Table I).
    /// Success: companion control within 5 s (else RTL).
    MessageLoss,
    /// Test 4: the companion is off. Success: RTL, never a takeover.
    CcFailure,
    /// RC lost and regained four times. Success: every loss delegated, the
    /// pilot back in control at the end, the companion standing by.
    RcFlapping,
    /// RC returns while the handshake runs. Success: the pilot in control,
    /// the companion not controlling.
    RcReturnMidHandshake,
    /// The companion reboots during companion control. Success: RTL.
    CcReboot,
    /// The companion is off and an attacker acknowledges the notices, as
    /// another system and as the companion itself (unsigned; the FC
    /// requires signatures). Success: RTL, never a takeover.
    SpoofedTakeover,
    /// Signed link, but the companion has the wrong key. Success: RTL, never a
    /// takeover.
    WrongKey,
    /// Signed link; the companion takes over, and an attacker streams
    /// unsigned control (RC overrides, attitude targets, manual control) as
    /// the companion and as a ground station at 50 Hz throughout. Success:
    /// the companion controls, and not one of the attacker's messages is
    /// applied.
    SpoofedControl,
}

impl Scenario {
    /// Every scenario.
    pub const ALL: [Scenario; 10] = [
        Scenario::NormalRc,
        Scenario::RcLoss,
        Scenario::MessageLoss,
        Scenario::CcFailure,
        Scenario::RcFlapping,
        Scenario::RcReturnMidHandshake,
        Scenario::CcReboot,
        Scenario::SpoofedTakeover,
        Scenario::WrongKey,
        Scenario::SpoofedControl,
    ];

    /// Its command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Scenario::NormalRc => "normal-rc",
            Scenario::RcLoss => "rc-loss",
            Scenario::MessageLoss => "message-loss",
            Scenario::CcFailure => "cc-failure",
            Scenario::RcFlapping => "rc-flapping",
            Scenario::RcReturnMidHandshake => "rc-return-mid-handshake",
            Scenario::CcReboot => "cc-reboot",
            Scenario::SpoofedTakeover => "spoofed-takeover",
            Scenario::WrongKey => "wrong-key",
            Scenario::SpoofedControl => "spoofed-control",
        }
    }

    /// The scenario with this name.
    pub fn from_name(name: &str) -> Option<Scenario> {
        Scenario::ALL.into_iter().find(|s| s.name() == name)
    }

    /// What the companion is expected to end up doing.
    fn expects_takeover(self) -> bool {
        matches!(
            self,
            Scenario::RcLoss
                | Scenario::MessageLoss
                | Scenario::RcFlapping
                | Scenario::CcReboot
                | Scenario::SpoofedControl
        )
    }
}

/// One trial's settings.
#[derive(Debug, Clone, Copy)]
pub struct Trial {
    /// What happens.
    pub scenario: Scenario,
    /// FC → companion link.
    pub downlink: LinkModel,
    /// Companion → FC link.
    pub uplink: LinkModel,
    /// The seed of every random choice in the trial.
    pub seed: u64,
    /// Drop exactly the frames whose bit is set among the first 16 frames
    /// sent after the RC loss (both directions, in sending order).
    pub drop_pattern: Option<u16>,
    /// FC settings.
    pub fc: FcConfig,
    /// Companion settings.
    pub cc: CcConfig,
    /// Record a timeline of protocol events in [`Outcome::trace`].
    pub trace: bool,
}

impl Trial {
    /// A trial of `scenario` over the serial link losing `loss` of the
    /// frames in each direction.
    pub fn new(scenario: Scenario, loss: f64, seed: u64) -> Self {
        Trial {
            scenario,
            downlink: LinkModel::lossy(loss),
            uplink: LinkModel::lossy(loss),
            seed,
            drop_pattern: None,
            fc: FcConfig::default(),
            cc: CcConfig::default(),
            trace: false,
        }
    }

    /// Bursty loss (Gilbert–Elliott) with mean `loss` and bursts of
    /// `burst` frames, instead of independent loss.
    pub fn bursty(mut self, loss: f64, burst: f64) -> Self {
        for l in [&mut self.downlink, &mut self.uplink] {
            l.loss = 0.0;
            l.burst = Some(GilbertElliott::with_mean(loss, burst));
        }
        self
    }
}

/// A broken invariant, with when it broke.
#[derive(Debug, Clone, PartialEq)]
pub struct Violation {
    /// Virtual time.
    pub at: Instant,
    /// What broke.
    pub what: String,
}

/// What a trial produced.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The scenario's success criterion held.
    pub success: bool,
    /// From RC loss to companion control (takeover scenarios), or to RTL
    /// (fallback scenarios).
    pub response: Option<Duration>,
    /// The FC fell back to RTL at least once.
    pub fallback: bool,
    /// Companion control began where it must not (normal RC, companion
    /// off, spoofed, wrong key).
    pub false_takeover: bool,
    /// Broken invariants (must be empty).
    pub violations: Vec<Violation>,
    /// Who flies at the end.
    pub final_authority: Authority,
    /// Frames sent, both directions.
    pub frames: u64,
    /// Control messages the FC applied (from whomever: see `violations`).
    pub controls_applied: u64,
    /// The timeline, when [`Trial::trace`] is set.
    pub trace: Vec<String>,
}

const FC: Peer = Peer::new(1, 1);
const CC: Peer = Peer::new(1, 191);
const KEY: [u8; 32] = [0x42; 32];
const WRONG_KEY: [u8; 32] = [0x24; 32];
/// FC and companion heartbeat periods: the engines start at a random
/// phase within them.
const FC_HEARTBEAT: Duration = Duration::from_secs(1);
const CC_HEARTBEAT: Duration = Duration::from_secs(1);
/// The attacker's control stream in `SpoofedControl`.
const SPOOF_CONTROL: Duration = Duration::from_millis(20);
/// How often invariants are checked between other events.
const PROBE: Duration = Duration::from_millis(50);

#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Node {
    Fc,
    Cc,
}

#[derive(Debug)]
enum Event {
    Deliver(Node, Vec<u8>),
    Rc(bool),
    FcTimer,
    CcTimer,
    CcPower(bool),
    Spoof,
    SpoofControl,
    Probe,
}

/// One side's MAVLink endpoint: sequence numbers, optional signing, parser.
struct Endpoint {
    id: Peer,
    seq: u8,
    signer: Option<Signer>,
    parser: Parser,
}

impl Endpoint {
    fn new(id: Peer, sign_key: Option<[u8; 32]>, verify_key: Option<[u8; 32]>) -> Self {
        Endpoint {
            id,
            seq: 0,
            signer: sign_key.map(|k| Signer::new(k, 0, 1)),
            parser: match verify_key {
                // Unsigned frames reach the machine, marked unauthenticated:
                // whether they count is the machine's policy.
                Some(k) => Parser::with_signing(Verifier::new(k), Unsigned::Accept),
                None => Parser::new(),
            },
        }
    }

    fn frame<M: Encode + ?Sized>(&mut self, msg: &M) -> Vec<u8> {
        let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
        let h = Header {
            seq: self.seq,
            sysid: self.id.sysid,
            compid: self.id.compid,
        };
        self.seq = self.seq.wrapping_add(1);
        let n = encode(Version::V2, h, msg, self.signer.as_mut(), &mut buf)
            .expect("280 bytes fit any frame");
        buf[..n].to_vec()
    }
}

struct World {
    trial: Trial,
    rng: Pcg64,
    now: Instant,
    queue: BinaryHeap<Reverse<(Instant, u64, usize)>>,
    events: HashMap<usize, Event>,
    next_id: usize,
    fc: FcEngine,
    cc: CcEngine,
    cc_cfg: CcConfig,
    controller: WingsLevel,
    fc_end: Endpoint,
    cc_end: Endpoint,
    spoof_end: [Endpoint; 2],
    down: Link,
    up: Link,
    receiver_ok: bool,
    cc_powered: bool,
    fc_timer: Option<Instant>,
    cc_timer: Option<Instant>,
    /// Frames sent since the RC loss, for drop patterns.
    after_loss: u32,
    rc_lost_at: Option<Instant>,
    last_event: Option<u32>,
    // Observations.
    authority_since: Instant,
    left_companion_at: Option<Instant>,
    first_companion: Option<Instant>,
    first_rtl: Option<Instant>,
    fallback: bool,
    takeovers: u32,
    controls_applied: u64,
    notices: HashMap<(u8, u32), u8>,
    acks: HashMap<(u8, u32), u8>,
    violations: Vec<Violation>,
    frames: u64,
    trace: Vec<String>,
}

impl World {
    fn new(trial: Trial) -> Self {
        let (fc_key, cc_sign, cc_verify, fc_cfg, cc_cfg) = match trial.scenario {
            Scenario::SpoofedTakeover => (
                Some(KEY),
                Some(KEY),
                Some(KEY),
                FcConfig {
                    require_signed: true,
                    ..trial.fc
                },
                trial.cc,
            ),
            Scenario::WrongKey => (
                Some(KEY),
                Some(WRONG_KEY),
                Some(WRONG_KEY),
                FcConfig {
                    require_signed: true,
                    ..trial.fc
                },
                CcConfig {
                    require_signed: true,
                    ..trial.cc
                },
            ),
            Scenario::SpoofedControl => (
                Some(KEY),
                Some(KEY),
                Some(KEY),
                FcConfig {
                    require_signed: true,
                    ..trial.fc
                },
                CcConfig {
                    require_signed: true,
                    ..trial.cc
                },
            ),
            _ => (None, None, None, trial.fc, trial.cc),
        };
        let mut rng = Pcg64::seed_from_u64(trial.seed);
        // The engines' timers (receiver sampling, heartbeats) start at a
        // random phase.
        let fc_start = Instant::ZERO + random_below(&mut rng, FC_HEARTBEAT);
        let cc_start = Instant::ZERO + random_below(&mut rng, CC_HEARTBEAT);
        World {
            trial,
            rng,
            now: Instant::ZERO,
            queue: BinaryHeap::new(),
            events: HashMap::new(),
            next_id: 0,
            fc: FcEngine::new(fc_cfg, fc_start).expect("the trial's FC settings are valid"),
            cc: CcEngine::new(cc_cfg, cc_start).expect("the trial's companion settings are valid"),
            cc_cfg,
            controller: WingsLevel { throttle: 1600 },
            fc_end: Endpoint::new(FC, fc_key, fc_key),
            cc_end: Endpoint::new(CC, cc_sign, cc_verify),
            spoof_end: [
                Endpoint::new(CC, None, None),
                Endpoint::new(Peer::new(255, 190), None, None),
            ],
            down: Link::new(trial.downlink),
            up: Link::new(trial.uplink),
            receiver_ok: true,
            cc_powered: true,
            fc_timer: None,
            cc_timer: None,
            after_loss: 0,
            rc_lost_at: None,
            last_event: None,
            authority_since: Instant::ZERO,
            left_companion_at: None,
            first_companion: None,
            first_rtl: None,
            fallback: false,
            takeovers: 0,
            controls_applied: 0,
            notices: HashMap::new(),
            acks: HashMap::new(),
            violations: Vec::new(),
            frames: 0,
            trace: Vec::new(),
        }
    }

    fn log(&mut self, what: impl FnOnce() -> String) {
        if self.trial.trace {
            let line = format!("{:>9.3} s  {}", self.now.0 as f64 / 1e6, what());
            self.trace.push(line);
        }
    }

    fn at(&mut self, t: Instant, e: Event) {
        let id = self.next_id;
        self.next_id += 1;
        self.events.insert(id, e);
        self.queue.push(Reverse((t, id as u64, id)));
    }

    fn violation(&mut self, what: String) {
        if self.violations.len() < 16 {
            self.violations.push(Violation { at: self.now, what });
        }
    }

    /// Sends `bytes` from `from` across its link.
    fn send(&mut self, from: Node, bytes: Vec<u8>) {
        self.frames += 1;
        let drop = match (self.trial.drop_pattern, self.rc_lost_at) {
            (Some(mask), Some(_)) => {
                let k = self.after_loss;
                self.after_loss += 1;
                k < 16 && mask & (1 << k) != 0
            }
            _ => false,
        };
        let arrivals = match from {
            Node::Fc => self.down.transmit(self.now, &mut self.rng),
            Node::Cc => self.up.transmit(self.now, &mut self.rng),
        };
        if drop {
            return;
        }
        let to = if from == Node::Fc { Node::Cc } else { Node::Fc };
        for at in arrivals {
            self.at(at, Event::Deliver(to, bytes.clone()));
        }
    }

    fn run(mut self, end: Instant) -> Outcome {
        self.schedule_scenario();
        while let Some(Reverse((t, _, id))) = self.queue.pop() {
            if t > end {
                break;
            }
            self.now = t;
            let event = self.events.remove(&id).expect("queued event");
            self.handle(event);
            self.pump();
            self.check();
        }
        self.now = end;
        self.finish()
    }

    fn schedule_scenario(&mut self) {
        let r = random_below;
        self.at(Instant::ZERO + PROBE, Event::Probe);
        self.pump();
        let loss = Instant::from_millis(5000) + r(&mut self.rng, Duration::from_secs(1));
        let s = self.trial.scenario;
        if matches!(s, Scenario::CcFailure | Scenario::SpoofedTakeover) {
            self.cc_powered = false;
        }
        match s {
            Scenario::NormalRc => {}
            Scenario::RcFlapping => {
                // Lost 3 s, back 2 s, four times.
                let mut t = loss;
                for _ in 0..4 {
                    self.at(t, Event::Rc(false));
                    t = t + Duration::from_secs(3);
                    self.at(t, Event::Rc(true));
                    t = t + Duration::from_secs(2);
                }
            }
            Scenario::RcReturnMidHandshake => {
                self.at(loss, Event::Rc(false));
                // Back after detection (two samples), while the
                // acknowledgement is still on its way or just arrived.
                let back =
                    Duration::from_millis(200) + r(&mut self.rng, Duration::from_millis(150));
                self.at(loss + back, Event::Rc(true));
            }
            Scenario::CcReboot => {
                self.at(loss, Event::Rc(false));
                let down = loss + Duration::from_secs(3);
                self.at(down, Event::CcPower(false));
                self.at(down + Duration::from_secs(2), Event::CcPower(true));
            }
            Scenario::SpoofedTakeover => {
                self.at(loss, Event::Rc(false));
                self.at(loss + Duration::from_millis(400), Event::Spoof);
            }
            Scenario::SpoofedControl => {
                self.at(loss, Event::Rc(false));
                self.at(Instant::from_millis(1000), Event::SpoofControl);
            }
            _ => self.at(loss, Event::Rc(false)),
        }
    }

    fn handle(&mut self, event: Event) {
        match event {
            Event::Rc(ok) => {
                self.log(|| format!("receiver {}", if ok { "back" } else { "lost" }));
                self.receiver_ok = ok;
                self.fc.set_receiver_ok(ok);
                if !ok && self.rc_lost_at.is_none() {
                    self.rc_lost_at = Some(self.now);
                }
            }
            Event::FcTimer => {
                if self.fc_timer.is_some_and(|t| t <= self.now) {
                    self.fc_timer = None;
                    self.fc.handle_timeout(self.now);
                }
            }
            Event::CcTimer => {
                if self.cc_timer.is_some_and(|t| t <= self.now) {
                    self.cc_timer = None;
                    if self.cc_powered {
                        self.cc.handle_timeout(self.now);
                    }
                }
            }
            Event::CcPower(on) => {
                self.log(|| {
                    format!(
                        "companion powered {}",
                        if on { "on (reboot)" } else { "off" }
                    )
                });
                self.cc_powered = on;
                if on {
                    // A restart forgets everything.
                    self.cc = CcEngine::new(self.cc_cfg, self.now)
                        .expect("the trial's companion settings are valid");
                    self.cc_timer = None;
                }
            }
            Event::Spoof => {
                // Acknowledge the FC's current event, as the companion and
                // as a ground station, unsigned.
                if let Some(event) = self.last_event {
                    for k in 0..2 {
                        let forged = crate::wire::notice(FC, Status::CC_TAKEOVER_CONFIRMED, event);
                        let bytes = self.spoof_end[k].frame(&forged);
                        self.send(Node::Cc, bytes);
                    }
                }
                self.at(self.now + Duration::from_millis(250), Event::Spoof);
            }
            Event::SpoofControl => {
                // Hard over and full throttle, in every control message, as
                // the companion and as a ground station, unsigned.
                let k = (self.now.0 / 1000) as usize;
                let forged = match k % 3 {
                    0 => Control::rc(FC, [1000, 2000, 2000, 1000, 0, 0, 0, 0]),
                    1 => Control::Attitude(Default::default()).addressed_to(FC),
                    _ => Control::Manual(Default::default()).addressed_to(FC),
                };
                let bytes = self.spoof_end[k % 2].frame(&forged.to_message());
                self.send(Node::Cc, bytes);
                self.at(self.now + SPOOF_CONTROL, Event::SpoofControl);
            }
            Event::Probe => self.at(self.now + PROBE, Event::Probe),
            Event::Deliver(Node::Fc, bytes) => self.deliver_fc(&bytes),
            Event::Deliver(Node::Cc, bytes) => {
                if self.cc_powered {
                    self.deliver_cc(&bytes);
                }
            }
        }
    }

    // A delivery is one packet, as on UDP or a packetising radio: nothing
    // after it completes a frame started in it, so the parser is told the
    // packet ended (`flush`). Otherwise a false start byte (say, in the
    // signature block of a frame refused as a replay) would hold the next
    // packet's frames until enough bytes arrived to refute it: seconds, at
    // the protocol's rates.
    fn deliver_fc(&mut self, bytes: &[u8]) {
        let mut input = bytes;
        while let Some(r) = self.fc_end.parser.next(&mut input) {
            let _ = self.fc.handle_frame(self.now, &r.frame, r.authenticated);
        }
        while let Some(r) = self.fc_end.parser.flush() {
            let _ = self.fc.handle_frame(self.now, &r.frame, r.authenticated);
        }
    }

    fn deliver_cc(&mut self, bytes: &[u8]) {
        let mut input = bytes;
        while let Some(r) = self.cc_end.parser.next(&mut input) {
            let _ = self.cc.handle_frame(self.now, &r.frame, r.authenticated);
        }
        while let Some(r) = self.cc_end.parser.flush() {
            let _ = self.cc.handle_frame(self.now, &r.frame, r.authenticated);
        }
    }

    /// Carries out the engines' outputs and re-arms their timers.
    fn pump(&mut self) {
        while let Some(out) = self.fc.poll_output() {
            match out {
                FcOutput::Transmit(msg) => self.fc_transmit(msg),
                FcOutput::SetMode(a) => self.authority_changed(a),
                FcOutput::ApplyControl { from, control } => {
                    self.controls_applied += 1;
                    let trusted = from.peer == CC
                        && (from.authenticated || !self.fc.machine().config().require_signed);
                    if !trusted || self.fc.authority() != Authority::Companion {
                        self.violation(format!(
                            "FC applied {} from {}/{} (authenticated {}) in {:?}",
                            control.name(),
                            from.peer.sysid,
                            from.peer.compid,
                            from.authenticated,
                            self.fc.authority()
                        ));
                    }
                }
                FcOutput::ReleaseControl => {}
            }
        }
        while self.cc_powered {
            let Some(out) = self.cc.poll_output() else {
                break;
            };
            match out {
                CcOutput::Transmit(msg) => self.cc_transmit(msg),
                CcOutput::ControlDue => {
                    let control = self.controller.control(self.now, FC);
                    let _ = self.cc.submit_control(self.now, control);
                }
                CcOutput::ControlStarted { event } => {
                    self.log(|| format!("CC starts controlling (event {event})"))
                }
                CcOutput::ControlStopped => self.log(|| "CC stops controlling".into()),
                CcOutput::FcFound => self.log(|| "CC hears the FC".into()),
                CcOutput::FcLost => self.log(|| "CC lost the FC".into()),
                CcOutput::FcRebooted => self.log(|| "CC: the FC rebooted".into()),
            }
        }
        if let Some(t) = self.fc.poll_timeout() {
            if self.fc_timer.is_none_or(|old| t < old) {
                self.fc_timer = Some(t);
                self.at(t.max(self.now), Event::FcTimer);
            }
        }
        // A companion that is off runs no timers (it reboots into Idle).
        if let Some(t) = self.cc.poll_timeout().filter(|_| self.cc_powered) {
            if self.cc_timer.is_none_or(|old| t < old) {
                self.cc_timer = Some(t);
                self.at(t.max(self.now), Event::CcTimer);
            }
        }
    }

    fn fc_transmit(&mut self, msg: Message) {
        match &msg {
            Message::FbwagNotice(n) => {
                let (status, timestamp) = (n.failsafe_status, n.timestamp);
                self.log(|| format!("FC -> notice status {} event {timestamp}", status.0));
                let count = self.notices.entry((status.0, timestamp)).or_insert(0);
                *count += 1;
                if *count > 1 + self.fc.machine().config().max_retries {
                    let c = *count;
                    self.violation(format!(
                        "FC sent notice status {} event {timestamp} {c} times",
                        status.0
                    ));
                }
                if status == Status::RC_LOST {
                    self.last_event = Some(timestamp);
                }
            }
            Message::Statustext(t) => {
                let (text, id) = (t.text, t.id);
                self.log(|| {
                    let end = text.iter().position(|&b| b == 0).unwrap_or(text.len());
                    format!(
                        "FC -> STATUSTEXT {:?} (event {id})",
                        String::from_utf8_lossy(&text[..end])
                    )
                });
            }
            _ => {}
        }
        let bytes = self.fc_end.frame(&msg);
        self.send(Node::Fc, bytes);
    }

    fn cc_transmit(&mut self, msg: Message) {
        if let Message::FbwagNotice(n) = &msg {
            let (status, timestamp) = (n.failsafe_status, n.timestamp);
            self.log(|| format!("CC -> notice status {} event {timestamp}", status.0));
            let count = self.acks.entry((status.0, timestamp)).or_insert(0);
            *count += 1;
            if *count > 1 + self.cc.machine().config().max_ack_retries {
                let c = *count;
                self.violation(format!(
                    "companion acknowledged status {} event {timestamp} {c} times",
                    status.0
                ));
            }
        }
        let bytes = self.cc_end.frame(&msg);
        self.send(Node::Cc, bytes);
    }

    fn authority_changed(&mut self, a: Authority) {
        self.log(|| format!("FC authority -> {a:?}"));
        match a {
            Authority::Companion => {
                self.takeovers += 1;
                self.left_companion_at = None;
                self.first_companion.get_or_insert(self.now);
            }
            Authority::Rtl => {
                self.fallback = true;
                self.first_rtl.get_or_insert(self.now);
            }
            _ => {}
        }
        if a != Authority::Companion && self.left_companion_at.is_none() && self.takeovers > 0 {
            self.left_companion_at = Some(self.now);
        }
        self.authority_since = self.now;
    }

    /// Invariants that must hold at every event.
    fn check(&mut self) {
        if self.cc_powered
            && self.cc.machine().believes_in_control(self.now)
            && self.fc.authority() != Authority::Companion
        {
            let retry = self.fc.machine().config().retry_interval;
            match self.left_companion_at {
                Some(left) if self.now.since(left) <= retry => {}
                Some(left) => {
                    let late = self.now.since(left);
                    self.violation(format!("companion believes it is in control {late:?} after the FC gave control elsewhere"));
                }
                None => self.violation(
                    "companion believes it is in control, but the FC never gave it control".into(),
                ),
            }
        }
    }

    fn finish(mut self) -> Outcome {
        let auth = self.fc.authority();
        if auth == Authority::Handshake {
            self.violation("the handshake never ended".into());
        }
        let s = self.trial.scenario;
        let loss = self.rc_lost_at;
        let within = |t: Option<Instant>, limit: Duration| match (t, loss) {
            (Some(t), Some(l)) => t.since(l) <= limit,
            _ => false,
        };
        let handshake = self.trial.fc.handshake_timeout;
        let false_takeover =
            !s.expects_takeover() && s != Scenario::RcReturnMidHandshake && self.takeovers > 0;
        let (success, response) = match s {
            Scenario::NormalRc => (self.notices.is_empty() && auth == Authority::Pilot, None),
            Scenario::RcLoss | Scenario::MessageLoss => (
                within(self.first_companion, handshake),
                self.first_companion.zip(loss).map(|(t, l)| t.since(l)),
            ),
            Scenario::CcFailure | Scenario::SpoofedTakeover | Scenario::WrongKey => (
                self.takeovers == 0 && auth == Authority::Rtl,
                self.first_rtl.zip(loss).map(|(t, l)| t.since(l)),
            ),
            Scenario::RcFlapping => (
                self.takeovers == 4
                    && auth == Authority::Pilot
                    && self.cc.state() != crate::cc::CcState::Controlling,
                self.first_companion.zip(loss).map(|(t, l)| t.since(l)),
            ),
            Scenario::RcReturnMidHandshake => (
                auth == Authority::Pilot && self.cc.state() != crate::cc::CcState::Controlling,
                None,
            ),
            Scenario::CcReboot => (
                self.takeovers == 1 && auth == Authority::Rtl,
                self.first_rtl.zip(loss).map(|(t, l)| t.since(l)),
            ),
            Scenario::SpoofedControl => (
                within(self.first_companion, handshake) && auth == Authority::Companion,
                self.first_companion.zip(loss).map(|(t, l)| t.since(l)),
            ),
        };
        Outcome {
            success: success && self.violations.is_empty(),
            response,
            fallback: self.fallback,
            false_takeover,
            violations: self.violations,
            final_authority: auth,
            frames: self.frames,
            controls_applied: self.controls_applied,
            trace: self.trace,
        }
    }
}

/// Runs one trial.
///
/// ```
/// use fbwag_delegation::fc::Authority;
/// use fbwag_delegation::sim::{run, Scenario, Trial};
///
/// // The paper's Test 2 over a link losing 10 % of the frames each way.
/// let outcome = run(&Trial::new(Scenario::RcLoss, 0.1, 42));
/// assert!(outcome.violations.is_empty());
/// assert!(!outcome.false_takeover);
/// if outcome.success {
///     assert_eq!(outcome.final_authority, Authority::Companion);
///     println!("handover in {:?}", outcome.response.unwrap());
/// }
/// ```
pub fn run(trial: &Trial) -> Outcome {
    let end = match trial.scenario {
        Scenario::NormalRc => Instant::from_millis(30_000),
        Scenario::RcFlapping => Instant::from_millis(30_000),
        _ => Instant::from_millis(20_000),
    };
    World::new(*trial).run(end)
}

/// A uniformly random duration below `max`.
fn random_below(rng: &mut Pcg64, max: Duration) -> Duration {
    Duration::from_micros(rng.gen_range(0..max.as_micros() as u64))
}
