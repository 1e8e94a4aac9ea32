//! A deterministic simulator: the two protocol nodes of [`crate::node`]
//! ([`FcNode`] and [`CompanionNode`]: the engines with the policy of their
//! links, the very code `fbwag fc-sim` and `fbwag cc` run), and modelled
//! links carrying real MAVLink frames (encoded, signed, parsed by the
//! runtime), on a virtual clock. The simulator only moves bytes and time:
//! which frames count, where they are routed, who is trusted and which
//! control is applied is decided by the nodes. A trial is identified by its
//! scenario, link and seed.
//!
//! The FC node has one link, 0: the modelled radio or serial line to the
//! companion. The companion node has link 0 (that line), link 1 (a
//! ground-station port) and, where an autonomy flies, link 2 (the
//! autonomy's port). What the companion sends or routes to link 0 crosses
//! the uplink model, byte for byte; what it puts on links 1 and 2 is
//! checked and counted.
//!
//! Invariants are checked on every event of every trial (see
//! [`Violation`]); [`report`] aggregates trials into Table I and sweeps.

pub mod link;
pub mod report;
mod rules;

use crate::cc::CcConfig;
use crate::control::{Control, Controller, WingsLevel};
use crate::engine::{CcOutput, FcOutput};
use crate::fc::{Authority, FcConfig};
use crate::node::{
    Answers, Arrival, AutonomyFallback, CompanionEvent, CompanionNode, ControlSource, Drops, Fate,
    FcNode, LinkId, LinkSpec, Output, Peers, Role, AUTONOMY_SILENCE,
};
use crate::{Moment, Origin, Peer, Status};
use core::net::{Ipv4Addr, SocketAddr, SocketAddrV4};
use fbwag_dialect::dialects::common::{CommandLong, ManualControl, MavCmd};
use fbwag_dialect::dialects::minimal::{Heartbeat, MavAutopilot, MavType};
use fbwag_dialect::dialects::standard::GlobalPositionInt;
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Frame, Header, Message, Parser, Signer, Unsigned, Verifier, Version};
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
    /// Signed links; the companion's control comes from an autonomy (link
    /// 2) streaming RC overrides (channel 1 = 1234) at 20 Hz from 100 ms on.
    /// Strangers throughout: unsigned frames with the FC's ids on the FC
    /// line and on the ground port, a bystander's unsigned frames on the FC
    /// line, a second autonomy at another address streaming overrides
    /// (channel 1 = 1999), a hijacker on the ground port speaking from
    /// hundreds of addresses, and one signed ground station speaking from
    /// the start. Success: companion control within the handshake timeout,
    /// the autonomy's control applied, the FC's frames reaching the
    /// autonomy, and the station answered.
    Strangers,
    /// The companion's control comes from an autonomy that never speaks:
    /// it declines the takeover. Success: never a takeover, and the FC in
    /// RTL one round trip (plus 5 ms) after its first RC-loss notice.
    SilentAutonomy,
    /// As [`Scenario::SilentAutonomy`], but the companion flies wings level
    /// while its autonomy is silent. Success: companion control within the
    /// handshake timeout, and the wings-level control (throttle 1500)
    /// applied.
    SilentAutonomyFallback,
}

impl Scenario {
    /// Every scenario.
    pub const ALL: [Scenario; 13] = [
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
        Scenario::Strangers,
        Scenario::SilentAutonomy,
        Scenario::SilentAutonomyFallback,
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
            Scenario::Strangers => "strangers",
            Scenario::SilentAutonomy => "silent-autonomy",
            Scenario::SilentAutonomyFallback => "silent-autonomy-fallback",
        }
    }

    /// The scenario with this name.
    pub fn from_name(name: &str) -> Option<Scenario> {
        Scenario::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Whether its success criterion follows from the rules alone,
    /// whatever the link loses: nothing happens without an RC loss; the
    /// FC falls back to RTL without a companion's signed acknowledgement.
    fn guaranteed(self) -> bool {
        matches!(
            self,
            Scenario::NormalRc
                | Scenario::CcFailure
                | Scenario::SpoofedTakeover
                | Scenario::WrongKey
        )
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
                | Scenario::Strangers
                | Scenario::SilentAutonomyFallback
        )
    }

    /// Where the companion's control comes from.
    fn source(self) -> ControlSource {
        let autonomy = |fallback| ControlSource::Autonomy {
            link: AUTONOMY_LINK,
            fallback,
            silence: AUTONOMY_SILENCE,
        };
        match self {
            Scenario::Strangers | Scenario::SilentAutonomy => autonomy(AutonomyFallback::Decline),
            Scenario::SilentAutonomyFallback => autonomy(AutonomyFallback::WingsLevel),
            _ => ControlSource::Builtin,
        }
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
    pub at: Moment,
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
    /// off, spoofed, wrong key, silent autonomy).
    pub false_takeover: bool,
    /// Broken invariants (must be empty).
    pub violations: Vec<Violation>,
    /// Who flies at the end.
    pub final_authority: Authority,
    /// Frames sent across the modelled link, both directions.
    pub frames: u64,
    /// Control messages the FC applied (from whomever: see `violations`).
    pub controls_applied: u64,
    /// Frames the FC's node dropped, by reason.
    pub fc_drops: Drops,
    /// Frames the companion's node dropped, by reason (its last boot).
    pub cc_drops: Drops,
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

/// The companion's links; the FC's only link is 0 as well.
const FC_LINK: LinkId = 0;
const GROUND_LINK: LinkId = 1;
const AUTONOMY_LINK: LinkId = 2;

/// The autonomy's ids (the companion re-addresses its control to the FC).
const AUTONOMY: Peer = Peer::new(1, 192);
/// A ground station's ids.
const STATION: Peer = Peer::new(255, 190);
/// A device on the FC line that is neither the FC nor the companion.
const BYSTANDER: Peer = Peer::new(42, 1);
/// Channel 1 of the autonomy's control, and of every stranger's.
const AUTONOMY_CH1: u16 = 1234;
const STRANGER_CH1: u16 = 1999;
/// Throttle (channel 3) of the companion's wings-level fallback.
const FALLBACK_THROTTLE: u16 = 1500;
/// The autonomy speaks from then on, at 20 Hz.
const AUTONOMY_START: Duration = Duration::from_millis(100);
const AUTONOMY_PERIOD: Duration = Duration::from_millis(50);
/// The forger's round of frames with the FC's ids, and the hijacker's pace.
const FORGER_PERIOD: Duration = Duration::from_millis(100);
const HIJACKER_PERIOD: Duration = Duration::from_millis(20);
/// The ground station's heartbeat.
const STATION_PERIOD: Duration = Duration::from_secs(1);

/// Where the programs around the companion speak from.
const fn addr(ip: [u8; 4], port: u16) -> SocketAddr {
    let [a, b, c, d] = ip;
    SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::new(a, b, c, d), port))
}
const AUTONOMY_ADDR: SocketAddr = addr([127, 0, 0, 1], 14600);
const IMPOSTOR_ADDR: SocketAddr = addr([127, 0, 0, 1], 14601);
const STATION_ADDR: SocketAddr = addr([192, 0, 2, 10], 14550);
const FORGER_ADDR: SocketAddr = addr([198, 51, 100, 7], 14550);

/// The two ends of the modelled link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Side {
    Fc,
    Cc,
}

/// Who put a datagram on the modelled link.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sender {
    /// The node at that end, its own frames.
    Own,
    /// The companion, routing another link's frame byte for byte.
    Routed,
    /// Someone else on the line.
    Stranger,
}

/// The programs of [`Scenario::Strangers`], each a periodic event.
#[derive(Debug, Clone, Copy)]
enum Stranger {
    Autonomy,
    Impostor,
    Forger,
    Hijacker,
    Station,
}

#[derive(Debug)]
enum Event {
    Deliver(Side, Sender, Vec<u8>),
    Rc(bool),
    FcTimer,
    CcTimer,
    CcPower(bool),
    Spoof,
    SpoofControl,
    Stranger(Stranger),
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
            parser: parser(verify_key),
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

    /// The same frame as `id` would send it.
    fn frame_as<M: Encode + ?Sized>(&mut self, id: Peer, msg: &M) -> Vec<u8> {
        self.id = id;
        self.frame(msg)
    }
}

/// A link's parser: with a key, unsigned frames reach the node marked
/// unauthenticated (whether they count is the node's policy).
fn parser(verify_key: Option<[u8; 32]>) -> Parser {
    match verify_key {
        Some(k) => Parser::with_signing(Verifier::new(k), Unsigned::Accept),
        None => Parser::new(),
    }
}

/// The frames of one datagram, copied out of the parser, each with whether
/// its signature verified. A delivery is one packet, as on UDP or a
/// packetising radio: nothing after it completes a frame started in it, so
/// the parser is told the packet ended (`flush`). Otherwise a false start
/// byte (say, in the signature block of a frame refused as a replay) would
/// hold the next packet's frames until enough bytes arrived to refute it:
/// seconds, at the protocol's rates.
fn parse(parser: &mut Parser, bytes: &[u8]) -> Vec<(Vec<u8>, bool)> {
    let mut frames = Vec::new();
    let mut input = bytes;
    while let Some(r) = parser.next(&mut input) {
        frames.push((r.frame().as_bytes().to_vec(), r.is_authenticated()));
    }
    while let Some(r) = parser.flush() {
        frames.push((r.frame().as_bytes().to_vec(), r.is_authenticated()));
    }
    frames
}

/// The message a frame carries, if the dialect knows it.
fn message(frame: &Frame<&[u8]>) -> Option<Message> {
    <fbwag_dialect::Dialect as fbwag_dialect::mavframe::MessageSet>::parse(
        frame.msg_id(),
        frame.payload(),
    )
}

/// The sender's ids of a frame.
fn ids(frame: &Frame<&[u8]>) -> Peer {
    let h = frame.header();
    Peer::new(h.sysid, h.compid)
}

/// Each side's settings and keys for a trial.
struct Setup {
    fc: FcConfig,
    cc: CcConfig,
    fc_key: Option<[u8; 32]>,
    cc_sign: Option<[u8; 32]>,
    cc_verify: Option<[u8; 32]>,
}

impl Setup {
    fn of(trial: &Trial) -> Setup {
        let signed_fc = FcConfig {
            require_signed: true,
            ..trial.fc
        };
        let signed_cc = CcConfig {
            require_signed: true,
            ..trial.cc
        };
        let (key, cc_key, fc, cc) = match trial.scenario {
            Scenario::SpoofedTakeover => (KEY, KEY, signed_fc, trial.cc),
            Scenario::WrongKey => (KEY, WRONG_KEY, signed_fc, signed_cc),
            Scenario::SpoofedControl | Scenario::Strangers => (KEY, KEY, signed_fc, signed_cc),
            _ => {
                return Setup {
                    fc: trial.fc,
                    cc: trial.cc,
                    fc_key: None,
                    cc_sign: None,
                    cc_verify: None,
                }
            }
        };
        Setup {
            fc,
            cc,
            fc_key: Some(key),
            cc_sign: Some(cc_key),
            cc_verify: Some(cc_key),
        }
    }
}

/// The companion's node as the daemon sets it up: the FC line, a ground
/// port and, with an autonomy, the autonomy's port.
fn companion(cfg: CcConfig, source: ControlSource, now: Moment) -> CompanionNode {
    let mut node =
        CompanionNode::new(cfg, source, now).expect("the trial's companion settings are valid");
    let mut links = vec![
        (FC_LINK, Role::Peer, Answers::Target),
        (GROUND_LINK, Role::Ground, Answers::Chosen),
    ];
    if matches!(source, ControlSource::Autonomy { .. }) {
        links.push((AUTONOMY_LINK, Role::Autonomy, Answers::Chosen));
    }
    for (link, role, answers) in links {
        node.add_link(link, LinkSpec::new(role, answers))
            .expect("distinct links");
    }
    node
}

/// The FC's node: its one link, the line to the companion.
fn flight_controller(cfg: FcConfig, now: Moment) -> FcNode {
    let mut node = FcNode::new(cfg, now).expect("the trial's FC settings are valid");
    let spec = LinkSpec::new(Role::Peer, Answers::Target);
    node.add_link(FC_LINK, spec).expect("one link");
    node
}

/// The programs around the companion: the autonomy and the strangers of
/// [`Scenario::Strangers`].
struct Around {
    autonomy: Endpoint,
    impostor: Endpoint,
    /// Unsigned frames with the FC's ids, and a bystander's.
    forger: Endpoint,
    /// Unsigned frames from ever new addresses, with many ids.
    hijacker: Endpoint,
    hijacks: u32,
    /// A ground station that signs.
    station: Endpoint,
    /// The ground port answers it: from then on it must keep answering it.
    station_answered: bool,
    /// The companion's parsers of its ground and autonomy ports.
    ground_parser: Parser,
    autonomy_parser: Parser,
}

impl Around {
    fn new(key: Option<[u8; 32]>) -> Self {
        let station_key = key.map(|k| Signer::new(k, 1, 1));
        Around {
            autonomy: Endpoint::new(AUTONOMY, None, None),
            impostor: Endpoint::new(AUTONOMY, None, None),
            forger: Endpoint::new(FC, None, None),
            hijacker: Endpoint::new(STATION, None, None),
            hijacks: 0,
            station: Endpoint {
                signer: station_key,
                ..Endpoint::new(STATION, None, None)
            },
            station_answered: false,
            // Ground ports verify with the FC line's key, as in the daemon.
            ground_parser: parser(key),
            autonomy_parser: parser(None),
        }
    }
}

struct World {
    trial: Trial,
    rng: Pcg64,
    now: Moment,
    queue: BinaryHeap<Reverse<(Moment, u64, usize)>>,
    events: HashMap<usize, Event>,
    next_id: usize,
    fc: FcNode,
    cc: CompanionNode,
    cc_cfg: CcConfig,
    source: ControlSource,
    controller: WingsLevel,
    fc_end: Endpoint,
    cc_end: Endpoint,
    spoof_end: [Endpoint; 2],
    around: Around,
    down: Link,
    up: Link,
    receiver_ok: bool,
    cc_powered: bool,
    fc_timer: Option<Moment>,
    cc_timer: Option<Moment>,
    /// Frames sent since the RC loss, for drop patterns.
    after_loss: u32,
    rc_lost_at: Option<Moment>,
    last_event: Option<u32>,
    // Observations.
    left_companion_at: Option<Moment>,
    first_companion: Option<Moment>,
    first_rtl: Option<Moment>,
    first_notice: Option<Moment>,
    fallback: bool,
    takeovers: u32,
    controls_applied: u64,
    /// Controls applied carrying the autonomy's mark, and the wings-level
    /// fallback's.
    autonomy_applied: u64,
    fallback_applied: u64,
    /// The FC's frames the companion routed to the autonomy.
    fc_to_autonomy: u64,
    notices: HashMap<(u8, u32), u8>,
    /// The rules judged on every event (`rules.rs`).
    rules: rules::Rules,
    /// Who flies, as the FC's outputs said so far.
    fc_authority: Authority,
    violations: Vec<Violation>,
    frames: u64,
    trace: Vec<String>,
}

impl World {
    fn new(trial: Trial) -> Self {
        let setup = Setup::of(&trial);
        let source = trial.scenario.source();
        let mut rng = Pcg64::seed_from_u64(trial.seed);
        // The engines' timers (receiver sampling, heartbeats) start at a
        // random phase.
        let fc_start = Moment::ZERO + random_below(&mut rng, FC_HEARTBEAT);
        let cc_start = Moment::ZERO + random_below(&mut rng, CC_HEARTBEAT);
        World {
            trial,
            rng,
            now: Moment::ZERO,
            queue: BinaryHeap::new(),
            events: HashMap::new(),
            next_id: 0,
            fc: flight_controller(setup.fc, fc_start),
            cc: companion(setup.cc, source, cc_start),
            cc_cfg: setup.cc,
            source,
            controller: WingsLevel { throttle: 1600 },
            fc_end: Endpoint::new(FC, setup.fc_key, setup.fc_key),
            cc_end: Endpoint::new(CC, setup.cc_sign, setup.cc_verify),
            spoof_end: [
                Endpoint::new(CC, None, None),
                Endpoint::new(STATION, None, None),
            ],
            around: Around::new(setup.cc_verify),
            down: Link::new(trial.downlink),
            up: Link::new(trial.uplink),
            receiver_ok: true,
            cc_powered: true,
            fc_timer: None,
            cc_timer: None,
            after_loss: 0,
            rc_lost_at: None,
            last_event: None,
            left_companion_at: None,
            first_companion: None,
            first_rtl: None,
            first_notice: None,
            fallback: false,
            takeovers: 0,
            controls_applied: 0,
            autonomy_applied: 0,
            fallback_applied: 0,
            fc_to_autonomy: 0,
            notices: HashMap::new(),
            rules: rules::Rules::new(
                setup.fc,
                setup.cc,
                declines(source),
                trial.downlink.longest_delay(),
            ),
            fc_authority: Authority::Pilot,
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

    fn at(&mut self, t: Moment, e: Event) {
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

    /// Sends `bytes` from side `from` across the modelled link.
    fn send(&mut self, from: Side, sender: Sender, bytes: Vec<u8>) {
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
            Side::Fc => self.down.transmit(self.now, &mut self.rng),
            Side::Cc => self.up.transmit(self.now, &mut self.rng),
        };
        if drop {
            return;
        }
        let to = if from == Side::Fc { Side::Cc } else { Side::Fc };
        for at in arrivals {
            self.at(at, Event::Deliver(to, sender, bytes.clone()));
        }
    }

    fn run(mut self, end: Moment) -> Outcome {
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
        self.at(Moment::ZERO + PROBE, Event::Probe);
        self.pump();
        let loss = Moment::from_millis(5000) + r(&mut self.rng, Duration::from_secs(1));
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
                self.at(Moment::from_millis(1000), Event::SpoofControl);
            }
            Scenario::Strangers => {
                self.at(loss, Event::Rc(false));
                self.schedule_strangers();
            }
            _ => self.at(loss, Event::Rc(false)),
        }
    }

    /// The autonomy from 100 ms on; the strangers at random phases, the
    /// second autonomy once the first has spoken (the autonomy's port
    /// answers the first program it hears while that one speaks).
    fn schedule_strangers(&mut self) {
        let r = random_below;
        let start = Moment::ZERO + AUTONOMY_START;
        self.at(start, Event::Stranger(Stranger::Autonomy));
        let impostor = start + Duration::from_millis(1) + r(&mut self.rng, AUTONOMY_PERIOD);
        self.at(impostor, Event::Stranger(Stranger::Impostor));
        let forger = Moment::ZERO + r(&mut self.rng, FORGER_PERIOD);
        self.at(forger, Event::Stranger(Stranger::Forger));
        let hijacker = Moment::ZERO + r(&mut self.rng, HIJACKER_PERIOD);
        self.at(hijacker, Event::Stranger(Stranger::Hijacker));
        // The station speaks before the hijacker has taken every slot of
        // the ground port (8 frames, 160 ms): a station that keeps
        // speaking keeps its slot, but one that comes after a stranger
        // has filled the port waits for a slot silent 3 s.
        let station = Moment::ZERO + r(&mut self.rng, Duration::from_millis(100));
        self.at(station, Event::Stranger(Stranger::Station));
    }

    fn handle(&mut self, event: Event) {
        match event {
            Event::Rc(ok) => {
                self.log(|| format!("receiver {}", if ok { "back" } else { "lost" }));
                self.rules.rc(self.now);
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
            Event::CcPower(on) => self.power(on),
            Event::Spoof => {
                // Acknowledge the FC's current event, as the companion and
                // as a ground station, unsigned.
                if let Some(event) = self.last_event {
                    for k in 0..2 {
                        let forged = crate::wire::notice(FC, Status::CC_TAKEOVER_CONFIRMED, event);
                        let bytes = self.spoof_end[k].frame(&forged);
                        self.send(Side::Cc, Sender::Stranger, bytes);
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
                self.send(Side::Cc, Sender::Stranger, bytes);
                self.at(self.now + SPOOF_CONTROL, Event::SpoofControl);
            }
            Event::Stranger(who) => self.stranger(who),
            Event::Probe => self.at(self.now + PROBE, Event::Probe),
            Event::Deliver(Side::Fc, sender, bytes) => self.deliver_fc(sender, &bytes),
            Event::Deliver(Side::Cc, _, bytes) => self.deliver_cc(FC_LINK, None, &bytes),
        }
    }

    fn power(&mut self, on: bool) {
        self.log(|| {
            format!(
                "companion powered {}",
                if on { "on (reboot)" } else { "off" }
            )
        });
        self.cc_powered = on;
        if on {
            // A restart forgets everything.
            self.cc = companion(self.cc_cfg, self.source, self.now);
            self.cc_timer = None;
            self.rules.cc_restarted();
        }
    }

    /// One turn of a program around the companion: what it sends now, and
    /// when it speaks next.
    fn stranger(&mut self, who: Stranger) {
        let next = match who {
            Stranger::Autonomy => {
                let control = Control::rc(AUTONOMY, [AUTONOMY_CH1, 1500, 1550, 1500, 0, 0, 0, 0]);
                let bytes = self.around.autonomy.frame(&control.to_message());
                if self.cc_powered {
                    self.rules.autonomy_frame(self.now);
                }
                self.deliver_cc(AUTONOMY_LINK, Some(AUTONOMY_ADDR), &bytes);
                // Its own heartbeat once a second: for the ground stations.
                if self.now.as_millis() % 1000 < AUTONOMY_PERIOD.as_millis() as u64 {
                    let hb = Message::Heartbeat(Heartbeat {
                        r#type: MavType::ONBOARD_CONTROLLER,
                        autopilot: MavAutopilot::INVALID,
                        ..Heartbeat::default()
                    });
                    let bytes = self.around.autonomy.frame(&hb);
                    self.deliver_cc(AUTONOMY_LINK, Some(AUTONOMY_ADDR), &bytes);
                }
                AUTONOMY_PERIOD
            }
            Stranger::Impostor => {
                let control = Control::rc(AUTONOMY, [STRANGER_CH1, 2000, 2000, 1000, 0, 0, 0, 0]);
                let bytes = self.around.impostor.frame(&control.to_message());
                self.deliver_cc(AUTONOMY_LINK, Some(IMPOSTOR_ADDR), &bytes);
                AUTONOMY_PERIOD
            }
            Stranger::Forger => {
                self.forge();
                FORGER_PERIOD
            }
            Stranger::Hijacker => {
                self.hijack();
                HIJACKER_PERIOD
            }
            Stranger::Station => {
                let hb = Message::Heartbeat(Heartbeat {
                    r#type: MavType::GCS,
                    autopilot: MavAutopilot::INVALID,
                    ..Heartbeat::default()
                });
                let bytes = self.around.station.frame(&hb);
                self.deliver_cc(GROUND_LINK, Some(STATION_ADDR), &bytes);
                STATION_PERIOD
            }
        };
        self.at(self.now + next, Event::Stranger(who));
    }

    /// Unsigned frames with the FC's ids on the FC line (as if on the same
    /// serial line) and on the ground port: a heartbeat claiming companion
    /// control and a position; and a bystander's position on the FC line.
    fn forge(&mut self) {
        let hb = Message::Heartbeat(crate::wire::fc_heartbeat(Authority::Companion));
        let position = Message::GlobalPositionInt(GlobalPositionInt {
            time_boot_ms: self.now.as_millis() as u32,
            lat: 474_000_000,
            lon: 85_000_000,
            alt: 500_000,
            relative_alt: 100_000,
            ..GlobalPositionInt::default()
        });
        for msg in [hb, position] {
            let bytes = self.around.forger.frame_as(FC, &msg);
            self.deliver_cc(FC_LINK, None, &bytes);
            let bytes = self.around.forger.frame_as(FC, &msg);
            self.deliver_cc(GROUND_LINK, Some(FORGER_ADDR), &bytes);
        }
        let bytes = self.around.forger.frame_as(BYSTANDER, &position);
        self.deliver_cc(FC_LINK, None, &bytes);
    }

    /// One frame from a new address on the ground port, unsigned: control
    /// and commands for the FC and the autonomy, the companion's own
    /// acknowledgement, heartbeats; as the ground station, the companion
    /// and systems of its own.
    fn hijack(&mut self) {
        let k = self.around.hijacks;
        self.around.hijacks += 1;
        let source = addr(
            [203, 0, 113, (1 + k % 250) as u8],
            20_000 + (k % 997) as u16,
        );
        let other = Peer::new(100 + (k % 100) as u8, 1);
        let command = |target: Peer| {
            Message::CommandLong(CommandLong {
                target_system: target.sysid,
                target_component: target.compid,
                command: MavCmd::COMPONENT_ARM_DISARM,
                param1: 0.0,
                param2: 21196.0,
                ..CommandLong::default()
            })
        };
        let (id, msg) = match k % 7 {
            0 => (
                STATION,
                Control::rc(FC, [STRANGER_CH1, 2000, 2000, 1000, 0, 0, 0, 0]).to_message(),
            ),
            1 => (other, command(FC)),
            2 => (other, command(AUTONOMY)),
            3 => {
                let event = self.last_event.unwrap_or_default();
                let ack = crate::wire::notice(FC, Status::CC_TAKEOVER_CONFIRMED, event);
                (CC, Message::FbwagNotice(ack))
            }
            4 => (
                other,
                Control::Attitude(Default::default())
                    .addressed_to(FC)
                    .to_message(),
            ),
            5 => (
                other,
                Control::Manual(ManualControl {
                    x: 1000,
                    z: 1000,
                    ..ManualControl::default()
                })
                .addressed_to(FC)
                .to_message(),
            ),
            _ => (
                other,
                Message::Heartbeat(Heartbeat {
                    r#type: MavType::GCS,
                    ..Heartbeat::default()
                }),
            ),
        };
        let bytes = self.around.hijacker.frame_as(id, &msg);
        self.deliver_cc(GROUND_LINK, Some(source), &bytes);
    }

    /// A datagram at the FC: each frame's fate is the FC node's; its
    /// outputs are carried out at once, so applied control is traced to the
    /// datagram's sender.
    fn deliver_fc(&mut self, sender: Sender, bytes: &[u8]) {
        for (frame, authenticated) in parse(&mut self.fc_end.parser, bytes) {
            let view = Frame::new_unchecked(&frame[..]);
            let arrival = Arrival {
                link: FC_LINK,
                source: None,
                frame: view,
                authenticated,
            };
            let trusted = ids(&view) == CC && (authenticated || !self.fc.config().require_signed);
            let genuine_notice = match message(&view) {
                Some(Message::FbwagNotice(n)) if trusted && sender == Sender::Own => {
                    Some((n.failsafe_status, n.timestamp))
                }
                _ => None,
            };
            let signing = self.fc.config().require_signed;
            let unsigned = signing && !view.is_signed() && ids(&view) == CC && self.fc_up_to_date();
            let before = unsigned.then(|| rules::Exact::of(|d| self.fc.digest(d)));
            let fate: Fate = self.fc.handle_frame(self.now, arrival);
            if before.is_some_and(|b| b != rules::Exact::of(|d| self.fc.digest(d))) {
                self.violation("unsigned-changes-nothing: an unsigned frame changed the FC".into());
            }
            if fate.serve && !authenticated && self.fc.config().require_signed {
                self.violation(
                    "unauthenticated-stays-out: the FC serves an unsigned request".into(),
                );
            }
            if authenticated {
                self.rules.authenticated(self.now, Side::Fc, &view);
            }
            if trusted {
                self.rules.fc_heard(self.now);
            }
            self.pump_fc(Some(sender), Some(&rules::FcInput { genuine_notice }));
        }
    }

    /// The FC's timers due now have run.
    fn fc_up_to_date(&self) -> bool {
        self.fc.poll_timeout().is_none_or(|t| t > self.now)
    }

    /// A datagram at the companion's link `link`: each frame's fate is the
    /// companion node's. Its own outputs go first, then the frame where
    /// the node routes it: byte for byte over the uplink for link 0,
    /// checked and counted for the others.
    fn deliver_cc(&mut self, link: LinkId, source: Option<SocketAddr>, bytes: &[u8]) {
        if !self.cc_powered {
            return;
        }
        let parser = match link {
            FC_LINK => &mut self.cc_end.parser,
            GROUND_LINK => &mut self.around.ground_parser,
            _ => &mut self.around.autonomy_parser,
        };
        for (frame, authenticated) in parse(parser, bytes) {
            let view = Frame::new_unchecked(&frame[..]);
            let arrival = Arrival {
                link,
                source,
                frame: view,
                authenticated,
            };
            let of_fc = ids(&view) == FC && link == FC_LINK;
            let up_to_date = self.cc.poll_timeout().is_none_or(|t| t > self.now);
            let unsigned = self.cc_cfg.require_signed && !view.is_signed() && of_fc && up_to_date;
            let before = unsigned.then(|| rules::Exact::of(|d| self.cc.digest(d)));
            let fate = self.cc.handle_frame(self.now, arrival);
            if before.is_some_and(|b| b != rules::Exact::of(|d| self.cc.digest(d))) {
                let what = "an unsigned frame with the FC's ids changed the companion";
                self.violation(format!("unsigned-changes-nothing: {what}"));
            }
            if authenticated && link == FC_LINK {
                self.rules.authenticated(self.now, Side::Cc, &view);
            }
            if fate.input && of_fc {
                let message = message(&view);
                self.rules
                    .cc_heard(self.now, message.as_ref(), authenticated);
            }
            self.pump_cc();
            self.routed(&arrival, &fate);
        }
    }

    /// Carries out both nodes' outputs and re-arms their timers.
    fn pump(&mut self) {
        self.pump_fc(None, None);
        self.pump_cc();
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

    /// The FC node's outputs; `sender`: who sent the datagram being
    /// handled, and what the rules need of it.
    fn pump_fc(&mut self, sender: Option<Sender>, input: Option<&rules::FcInput>) {
        let outs: Vec<_> = std::iter::from_fn(|| self.fc.poll_output()).collect();
        let before = core::mem::replace(&mut self.fc_authority, self.fc.engine().authority());
        self.rules.fc_outputs(self.now, before, &outs, input);
        for out in outs {
            match out {
                Output::Transmit { links, message } => {
                    if links.contains(FC_LINK) {
                        self.fc_transmit(message);
                    }
                }
                Output::Event(FcOutput::SetMode(a)) => self.authority_changed(a),
                Output::Event(FcOutput::ApplyControl { from, control }) => {
                    self.applied(from, control, sender)
                }
                Output::TransmitTo { .. } => {}
                Output::Event(FcOutput::ReleaseControl | FcOutput::Transmit(_)) => {}
                Output::Peers { .. } => {}
            }
        }
    }

    /// Control the FC applied: only the trusted companion's, in companion
    /// control, from a datagram the companion itself sent, and never a
    /// stranger's.
    fn applied(&mut self, from: Origin, control: Control, sender: Option<Sender>) {
        self.controls_applied += 1;
        let authority = self.fc.engine().authority();
        let trusted = from.peer == CC && (from.authenticated || !self.fc.config().require_signed);
        if !trusted || authority != Authority::Companion {
            self.violation(format!(
                "FC applied {} from {}/{} (authenticated {}) in {authority:?}",
                control.name(),
                from.peer.sysid,
                from.peer.compid,
                from.authenticated,
            ));
        }
        if sender != Some(Sender::Own) {
            self.violation(format!(
                "FC applied {} that the companion did not send ({sender:?})",
                control.name()
            ));
        }
        let channels = control.rc_channels().unwrap_or_default();
        match channels {
            [STRANGER_CH1, ..] => self.violation(format!(
                "FC applied a stranger's {} (channel 1 = {STRANGER_CH1})",
                control.name()
            )),
            [AUTONOMY_CH1, ..] => self.autonomy_applied += 1,
            [1500, 1500, FALLBACK_THROTTLE, 1500, ..] => self.fallback_applied += 1,
            _ => {}
        }
    }

    /// The companion node's outputs (none while it is off).
    fn pump_cc(&mut self) {
        while self.cc_powered {
            let Some(out) = self.cc.poll_output() else {
                break;
            };
            match out {
                Output::Transmit { links, message } => {
                    if links.contains(FC_LINK) {
                        self.cc_transmit(message);
                    }
                    self.sent_around(links.without(FC_LINK), &message);
                }
                Output::Peers { link, peers } => self.peers_changed(link, peers),
                // The simulated links carry no signing time to catch up.
                Output::TransmitTo { .. } => {}
                Output::Event(CompanionEvent::Engine(e)) => {
                    self.rules.cc_event(self.now, &CompanionEvent::Engine(e));
                    self.cc_event(e)
                }
                Output::Event(CompanionEvent::AutonomySilent(silent)) => self
                    .log(|| format!("CC: autonomy {}", if silent { "silent" } else { "speaks" })),
            }
        }
    }

    fn cc_event(&mut self, event: CcOutput) {
        match event {
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
            CcOutput::Declined { event } => self.log(|| format!("CC declines event {event}")),
            CcOutput::Superseded { event, by } => self.log(|| {
                format!(
                    "CC: the FC accepted {}/{} for event {event}",
                    by.sysid, by.compid
                )
            }),
            CcOutput::Transmit(_) => {}
        }
    }

    /// The companion's own messages on its ground and autonomy ports:
    /// control is for the FC only. (Its notices, which name no target,
    /// go to every link, so ground stations see the handshake.)
    fn sent_around(&mut self, links: crate::node::Links, message: &Message) {
        if Control::from_message(message).is_some() && !links.is_empty() {
            self.violation(format!(
                "the companion sent {} to links {:?}",
                message.meta().name,
                links.iter().collect::<Vec<_>>()
            ));
        }
    }

    /// Where the companion routes a frame: byte for byte over the uplink
    /// for link 0, checked on every link. With signing required, nothing
    /// unauthenticated reaches the FC or the autonomy, nothing with the
    /// FC's ids goes anywhere unauthenticated; the autonomy reaches the FC
    /// only through the companion's gate.
    fn routed(&mut self, a: &Arrival, fate: &Fate) {
        let route = fate.route;
        if route.is_empty() {
            return;
        }
        let from = ids(&a.frame);
        let what = || {
            format!(
                "{} from {}/{} on link {}",
                <fbwag_dialect::Dialect as fbwag_dialect::mavframe::MessageSet>::meta(
                    a.frame.msg_id()
                )
                .map_or("an unknown message", |m| m.name),
                from.sysid,
                from.compid,
                a.link
            )
        };
        let to = route.iter().collect::<Vec<_>>();
        if self.cc_cfg.require_signed && !a.authenticated {
            if from == FC {
                self.violation(format!("unauthenticated {} routed to links {to:?}", what()));
            }
            if a.link == FC_LINK && route.contains(AUTONOMY_LINK) {
                self.violation(format!("unauthenticated {} routed to the autonomy", what()));
            }
            if route.contains(FC_LINK) {
                self.violation(format!("unauthenticated {} routed to the FC", what()));
            }
        }
        if a.link == AUTONOMY_LINK && route.contains(FC_LINK) {
            self.violation(format!("{} routed to the FC past the gate", what()));
        }
        if from == FC && a.link == FC_LINK && route.contains(AUTONOMY_LINK) {
            self.fc_to_autonomy += 1;
        }
        if route.contains(FC_LINK) {
            self.send(Side::Cc, Sender::Routed, a.frame.as_bytes().to_vec());
        }
    }

    /// Whom a companion port answers: the ground station keeps its place
    /// against any number of strangers; the autonomy's port answers the
    /// autonomy only.
    fn peers_changed(&mut self, link: LinkId, peers: Peers) {
        let station = STATION_ADDR;
        if link == GROUND_LINK {
            match (self.around.station_answered, peers.contains(station)) {
                (true, false) => self.violation(format!(
                    "the ground port no longer answers the station {station}"
                )),
                (false, true) => self.around.station_answered = true,
                _ => {}
            }
        }
        if link == AUTONOMY_LINK && peers.iter().any(|p| p != AUTONOMY_ADDR) {
            self.violation(format!(
                "the autonomy's port answers {:?}",
                peers.iter().collect::<Vec<_>>()
            ));
        }
    }

    fn fc_transmit(&mut self, msg: Message) {
        match &msg {
            Message::FbwagNotice(n) => {
                let (status, timestamp) = (n.failsafe_status, n.timestamp);
                self.log(|| format!("FC -> notice status {} event {timestamp}", status.0));
                *self.notices.entry((status.0, timestamp)).or_insert(0) += 1;
                if status == Status::RC_LOST {
                    self.last_event = Some(timestamp);
                    self.first_notice.get_or_insert(self.now);
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
        self.rules.sent(self.now, Side::Fc, &msg, &bytes);
        self.send(Side::Fc, Sender::Own, bytes);
    }

    fn cc_transmit(&mut self, msg: Message) {
        if let Message::FbwagNotice(n) = &msg {
            let (status, timestamp) = (n.failsafe_status, n.timestamp);
            self.log(|| format!("CC -> notice status {} event {timestamp}", status.0));
        }
        let bytes = self.cc_end.frame(&msg);
        self.rules.sent(self.now, Side::Cc, &msg, &bytes);
        self.send(Side::Cc, Sender::Own, bytes);
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
    }

    /// Invariants that must hold at every event.
    fn check(&mut self) {
        let cc = self.cc_powered.then_some(&self.cc);
        self.rules.check(self.now, &self.fc, cc);
        self.rules
            .check_receiver(self.now, self.receiver_ok, &self.fc);
        for broken in self.rules.take() {
            self.violation(broken);
        }
        if self.cc_powered
            && self.cc.engine().machine().believes_in_control(self.now)
            && self.fc.engine().authority() != Authority::Companion
        {
            let retry = self.fc.config().retry_interval;
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

    /// The scenario's success criterion, and the response time it reports.
    fn verdict(&self) -> (bool, Option<Duration>) {
        let auth = self.fc.engine().authority();
        let cc_state = self.cc.engine().state();
        let loss = self.rc_lost_at;
        let since_loss = |t: Option<Moment>| t.zip(loss).map(|(t, l)| t.since(l));
        let handshake = self.trial.fc.handshake_timeout;
        let within = |t: Option<Moment>| since_loss(t).is_some_and(|d| d <= handshake);
        let to_companion = since_loss(self.first_companion);
        let to_rtl = since_loss(self.first_rtl);
        match self.trial.scenario {
            Scenario::NormalRc => (self.notices.is_empty() && auth == Authority::Pilot, None),
            Scenario::RcLoss | Scenario::MessageLoss => {
                (within(self.first_companion), to_companion)
            }
            Scenario::CcFailure | Scenario::SpoofedTakeover | Scenario::WrongKey => {
                (self.takeovers == 0 && auth == Authority::Rtl, to_rtl)
            }
            Scenario::RcFlapping => (
                self.takeovers == 4
                    && auth == Authority::Pilot
                    && cc_state != crate::cc::CcState::Controlling,
                to_companion,
            ),
            Scenario::RcReturnMidHandshake => (
                auth == Authority::Pilot && cc_state != crate::cc::CcState::Controlling,
                None,
            ),
            Scenario::CcReboot => (self.takeovers == 1 && auth == Authority::Rtl, to_rtl),
            Scenario::SpoofedControl => (
                within(self.first_companion) && auth == Authority::Companion,
                to_companion,
            ),
            Scenario::Strangers => (
                within(self.first_companion)
                    && auth == Authority::Companion
                    && self.autonomy_applied > 0
                    && self.fc_to_autonomy > 0
                    && self.around.station_answered,
                to_companion,
            ),
            Scenario::SilentAutonomy => {
                // The decline's round trip: both directions' worst delay.
                let (d, u) = (self.trial.downlink, self.trial.uplink);
                let round_trip = d.latency + d.jitter + u.latency + u.jitter;
                let prompt = self
                    .first_rtl
                    .zip(self.first_notice)
                    .is_some_and(|(rtl, notice)| {
                        rtl.since(notice) <= round_trip + Duration::from_millis(5)
                    });
                (
                    self.takeovers == 0 && auth == Authority::Rtl && prompt,
                    to_rtl,
                )
            }
            Scenario::SilentAutonomyFallback => (
                within(self.first_companion)
                    && auth == Authority::Companion
                    && self.fallback_applied > 0,
                to_companion,
            ),
        }
    }

    fn finish(mut self) -> Outcome {
        let auth = self.fc.engine().authority();
        if auth == Authority::Handshake {
            self.violation("the handshake never ended".into());
        }
        let s = self.trial.scenario;
        let false_takeover =
            !s.expects_takeover() && s != Scenario::RcReturnMidHandshake && self.takeovers > 0;
        let (success, response) = self.verdict();
        // The rules themselves decide these, whatever the link loses.
        if false_takeover {
            self.violation(format!(
                "a takeover in {}, where no rule allows one",
                s.name()
            ));
        }
        if !success && s.guaranteed() {
            self.violation(format!(
                "{}: its outcome is the rules', yet it failed",
                s.name()
            ));
        }
        Outcome {
            success: success && self.violations.is_empty(),
            response,
            fallback: self.fallback,
            false_takeover,
            violations: self.violations,
            final_authority: auth,
            frames: self.frames,
            controls_applied: self.controls_applied,
            fc_drops: *self.fc.drops(),
            cc_drops: *self.cc.drops(),
            trace: self.trace,
        }
    }
}

/// How long a silent autonomy must be silent for its companion to
/// decline, if it declines.
fn declines(source: ControlSource) -> Option<Duration> {
    match source {
        ControlSource::Autonomy {
            fallback: AutonomyFallback::Decline,
            silence,
            ..
        } => Some(silence),
        _ => None,
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
        Scenario::NormalRc => Moment::from_millis(30_000),
        Scenario::RcFlapping => Moment::from_millis(30_000),
        _ => Moment::from_millis(20_000),
    };
    World::new(*trial).run(end)
}

/// A uniformly random duration below `max`.
fn random_below(rng: &mut Pcg64, max: Duration) -> Duration {
    Duration::from_micros(rng.gen_range(0..max.as_micros() as u64))
}
