//! The stateright model: actions, and the transition that drives the real
//! nodes through them.

use crate::check::{self as checks, Inputs};
use crate::props::{self, Invariant, Reach};
use crate::setup::{
    self, Fault, ModelConfig, AUTONOMY, AUTONOMY_ADDR, AUTONOMY_LINK, FC_LINK, GROUND_LINK,
};
use crate::state::{Ghost, InFlight, Party, Recording, Relevance, Side, State, Steps};
use crate::wire::{self, Endpoint};
use core::net::SocketAddr;
use core::time::Duration;
use fbwag_delegation::cc::CcConfig;
use fbwag_delegation::control::Control;
use fbwag_delegation::engine::FcOutput;
use fbwag_delegation::fc::{Authority, FcConfig};
use fbwag_delegation::node::{Arrival, CompanionEvent, CompanionNode, Fate, FcNode, Output};
use fbwag_delegation::{wire as pwire, Moment, Status};
use fbwag_dialect::dialects::common::{CommandLong, MavCmd, ParamSet, SetupSigning};
use fbwag_dialect::Message;
use stateright::{Model, Property};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;

/// What a stranger without the key injects (unsigned, delivered at once,
/// from the address it names).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Forgery {
    /// To the FC, from the companion's address: a takeover acknowledgement
    /// (status 2) of the FC's current handshake, with the companion's ids.
    Takeover,
    /// To the FC, from the stranger's own address: an RC override with the
    /// companion's ids.
    Control,
    /// To the FC, from the companion's address: a ground station's
    /// command (as the companion routes them).
    GroundRequest,
    /// To the companion, from the FC's address: an RC-loss notice of a new
    /// event, with the FC's ids.
    RcLost,
    /// To the companion, from the stranger's own address: a heartbeat in
    /// companion control, with the FC's ids.
    CompanionMode,
    /// To the companion, from the FC's address: a broadcast heartbeat of
    /// another sender (system 0: nobody's route is learned from it).
    Broadcast,
    /// Into the companion's trusted ground link, as a local process that
    /// bound its port first: `PARAM_SET FBWAG_CC_COMPID = 77` to the FC
    /// (who flies: the FC would then take another companion's control).
    WhoFlies,
    /// Into the trusted ground link: SETUP_SIGNING to the FC (a key of
    /// the process's own).
    NewKey,
    /// Into the trusted ground link: `PARAM_SET AIRSPEED_CRUISE`, which a
    /// ground tool may change: the link signs it on.
    GroundParameter,
}

impl Forgery {
    /// Every forgery.
    pub const ALL: [Forgery; 9] = [
        Forgery::Takeover,
        Forgery::Control,
        Forgery::GroundRequest,
        Forgery::RcLost,
        Forgery::CompanionMode,
        Forgery::Broadcast,
        Forgery::WhoFlies,
        Forgery::NewKey,
        Forgery::GroundParameter,
    ];
}

/// One step of the world.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Action {
    /// The FC's timers at its deadline (the clock jumps there; frames
    /// still in flight when the clock moves are lost).
    TickFc,
    /// The companion's timers at its deadline; a speaking autonomy's
    /// control frame arrives first.
    TickCc,
    /// Frame `index` in flight to `to` arrives (any of them: reordering).
    Deliver(Party, usize),
    /// Frame `index` in flight to `to` is duplicated.
    Duplicate(Party, usize),
    /// The pilot's receiver fails.
    RcLost,
    /// The pilot's receiver works again.
    RcBack,
    /// The FC restarts, keeping its signing state or not.
    RebootFc {
        /// A signing state file survives the restart.
        signing_kept: bool,
    },
    /// The companion restarts, keeping its signing state or not.
    RebootCc {
        /// A signing state file survives the restart.
        signing_kept: bool,
    },
    /// A stranger injects a forged frame.
    Forge(Forgery),
    /// The stranger replays capture `index` of this instant.
    Replay(usize),
    /// The autonomy falls silent.
    AutonomySilent,
    /// The autonomy speaks again.
    AutonomySpeaks,
    /// Planted fault (c): the harness replays the companion's
    /// acknowledgement of an earlier FC boot, signed afresh.
    ReplayStaleAck,
}

/// The model: the settings of both nodes and of the world around them.
#[derive(Debug, Clone)]
pub struct DelegationModel {
    /// States whose invariants were evaluated (shared by the checker's
    /// threads): the states explored.
    pub checked: Arc<AtomicUsize>,
    /// The latest virtual time of a state explored (µs).
    pub latest: Arc<AtomicU64>,
    /// Per property (in [`props::properties`] order), the fewest steps to a
    /// state that broke it.
    pub shortest: Arc<Vec<AtomicUsize>>,
    /// Per [`Reach`], the fewest steps to a transition that showed it.
    pub reached: Arc<Vec<AtomicUsize>>,
    /// A state past [`ModelConfig::horizon`] was left out: what was
    /// explored is not the world's fixpoint.
    pub cut: Arc<AtomicBool>,
    /// Bounds of the world and the planted fault, if any.
    pub cfg: ModelConfig,
    /// The FC's settings.
    pub fc: FcConfig,
    /// The companion's settings.
    pub cc: CcConfig,
}

/// Timeline lines of a replayed step (`None` while checking).
pub type Log = Option<Vec<String>>;

pub(crate) fn say(log: &mut Log, now: Moment, who: &str, what: impl FnOnce() -> String) {
    if let Some(lines) = log {
        lines.push(format!("t={:.3} {who}: {}", now.0 as f64 / 1e6, what()));
    }
}

fn counters(n: usize) -> Arc<Vec<AtomicUsize>> {
    Arc::new((0..n).map(|_| AtomicUsize::new(usize::MAX)).collect())
}

impl DelegationModel {
    /// The model with `cfg`'s bounds and the grid settings (see
    /// [`setup::fc_config`]).
    pub fn new(cfg: ModelConfig) -> Self {
        DelegationModel {
            checked: Arc::new(AtomicUsize::new(0)),
            latest: Arc::new(AtomicU64::new(0)),
            shortest: counters(props::COUNT),
            reached: counters(Reach::ALL.len()),
            cut: Arc::new(AtomicBool::new(false)),
            cfg,
            fc: setup::fc_config(),
            cc: setup::cc_config(),
        }
    }

    pub(crate) fn faulty(&self, f: Fault) -> bool {
        self.cfg.fault == Some(f)
    }

    /// How far back a time can matter (see [`setup::memory`]).
    pub fn memory(&self) -> Duration {
        setup::memory(&self.fc, &self.cc)
    }

    /// The initial world: both nodes just started, the pilot flying.
    pub fn initial(&self) -> State {
        let mut fc = setup::fc_node(self.fc, Moment::ZERO);
        fc.set_receiver_ok(true);
        let mut cc = setup::cc_node(self.cc, Moment::ZERO);
        let outs = cc_outputs(&mut cc);
        let mut s = State {
            steps: Steps(0),
            now: Moment::ZERO,
            fc: Side {
                node: Arc::new(fc),
                link: Endpoint::starting(self.fc.own, 1, Moment::ZERO),
                boot: Moment::ZERO,
                boots: 0,
            },
            cc: Side {
                node: Arc::new(cc),
                link: Endpoint::starting(self.cc.own, 2, Moment::ZERO),
                boot: Moment::ZERO,
                boots: 0,
            },
            to_cc: Vec::new(),
            to_fc: Vec::new(),
            rc_ok: true,
            autonomy_speaks: true,
            ghost: Ghost::default(),
            digest: 0,
        };
        self.on_cc_outputs(&mut s, outs, &mut None);
        self.autonomy_control(&mut s, &mut None);
        self.seal(&mut s);
        s
    }

    /// Whether the FC may still restart in `s`.
    pub fn fc_may_restart(&self, s: &State) -> bool {
        s.fc.boots < self.cfg.fc_reboots && s.fc_now() <= Moment::ZERO + self.cfg.fc_reboot_window
    }

    /// How long each fact of the ghost can matter (see [`Relevance`]).
    pub fn relevance(&self) -> Relevance {
        let (fc, cc) = (&self.fc, &self.cc);
        let grid = setup::GRID;
        let samples = fc.rc_loss_samples.max(fc.rc_regain_samples);
        Relevance {
            memory: self.memory(),
            events: self.notices_end() * 2 + grid,
            rc: fc.rc_sample_period * u32::from(samples) + grid,
            silence: setup::SILENCE + grid,
            handshake: fc.handshake_timeout + grid,
            override_: fc.override_timeout + grid,
            heartbeat: fc.heartbeat_timeout + grid,
            fc_timeout: cc.fc_timeout + grid,
            stop: cc.control_fc_timeout + grid,
            lease: cc.control_lease + grid,
            belief: fc.retry_interval + grid,
            notices: self.notices_end() + grid,
        }
    }

    /// How long after its first notice of an event a side may still send
    /// one: its retries.
    pub fn notices_end(&self) -> Duration {
        let fc = self.fc.retry_interval * u32::from(self.fc.max_retries);
        let cc = self.cc.ack_retry_interval * u32::from(self.cc.max_ack_retries);
        fc.max(cc)
    }

    /// Sets `s`'s identity (see [`crate::state`]).
    fn seal(&self, s: &mut State) {
        s.digest = s.compute_digest(&self.relevance(), self.fc_may_restart(s));
    }

    /// Records that `what` happened on a path of `steps` steps.
    pub(crate) fn reach(&self, what: Reach, steps: usize) {
        self.reached[what as usize].fetch_min(steps, Ordering::Relaxed);
    }

    /// Applies `action` to `s`, writing the timeline into `log`. `None`
    /// when the action does not apply.
    pub fn step(&self, s: &State, action: Action, log: &mut Log) -> Option<State> {
        let mut s = s.clone();
        s.steps.0 += 1;
        match action {
            Action::TickFc => self.tick_fc(&mut s, log),
            Action::TickCc => self.tick_cc(&mut s, log),
            Action::Deliver(to, i) => self.deliver(&mut s, to, i, log)?,
            Action::Duplicate(to, i) => {
                let f = queue(&mut s, to).get(i)?.clone();
                say(log, s.now, "link", || {
                    format!("duplicates {}", describe(&f))
                });
                queue(&mut s, to).push(f);
                s.ghost.dups += 1;
            }
            Action::RcLost | Action::RcBack => {
                s.rc_ok = action == Action::RcBack;
                let ok = s.rc_ok;
                s.fc.update(|n| n.set_receiver_ok(ok));
                s.ghost.rc_changed = s.now;
                s.ghost.rc_flips += 1;
                say(log, s.now, "pilot", || {
                    format!("receiver {}", if ok { "back" } else { "lost" })
                });
            }
            Action::RebootFc { signing_kept } => self.reboot_fc(&mut s, signing_kept, log),
            Action::RebootCc { signing_kept } => self.reboot_cc(&mut s, signing_kept, log),
            Action::Forge(f) => self.forge(&mut s, f, log),
            Action::Replay(i) => self.replay(&mut s, i, log)?,
            Action::AutonomySilent | Action::AutonomySpeaks => {
                s.autonomy_speaks = action == Action::AutonomySpeaks;
                s.ghost.autonomy_flips += 1;
                let speaks = s.autonomy_speaks;
                say(log, s.now, "autonomy", || {
                    if speaks { "speaks" } else { "falls silent" }.into()
                });
                if speaks {
                    self.autonomy_control(&mut s, log);
                }
            }
            Action::ReplayStaleAck => self.replay_stale_ack(&mut s, log)?,
        }
        checks::after_step(self, &s);
        self.seal(&mut s);
        Some(s)
    }

    /// Moves the clock to `t`; frames still in flight are lost, the
    /// stranger's captures of the instant are gone, and a speaking
    /// autonomy's control (a stream far faster than the grid) reaches the
    /// companion first.
    fn advance(&self, s: &mut State, t: Moment, log: &mut Log) {
        if t <= s.now {
            return;
        }
        let lost = s.to_cc.len() + s.to_fc.len();
        if lost > 0 {
            say(log, s.now, "link", || {
                format!("{lost} frame(s) never arrive")
            });
        }
        s.to_cc.clear();
        s.to_fc.clear();
        s.ghost.recordings.clear();
        s.now = t;
        if s.autonomy_speaks {
            self.autonomy_control(s, log);
        }
    }

    /// One control frame of the autonomy on the companion's autonomy link.
    fn autonomy_control(&self, s: &mut State, log: &mut Log) {
        let now = s.cc_now();
        let control = Control::rc(self.cc.fc, [1500; 8]).to_message();
        let bytes = wire::forged(AUTONOMY, 0, &control);
        let arrival = Arrival {
            link: AUTONOMY_LINK,
            source: Some(AUTONOMY_ADDR),
            frame: wire::frame_of(&bytes),
            authenticated: false,
        };
        s.ghost.autonomy_heard = Some(s.now);
        let (fate, outs) = s.cc.update(|n| {
            let fate = n.handle_frame(now, arrival);
            (fate, cc_outputs(n))
        });
        if fate.route.contains(FC_LINK) {
            // Control reaches the FC through the gate only (its own frame).
            self.break_now(s, Invariant::NodePolicy, log, "routes the autonomy's frame");
        }
        self.on_cc_outputs(s, outs, log);
    }

    pub(crate) fn break_now(&self, s: &mut State, i: Invariant, log: &mut Log, why: &str) {
        s.ghost.broken |= i.bit();
        say(log, s.now, "CHECK", || {
            format!("{} broken: {why}", i.name())
        });
    }

    fn tick_fc(&self, s: &mut State, log: &mut Log) {
        let Some(t) = s.fc_deadline() else { return };
        self.advance(s, t, log);
        let now = s.fc_now();
        let before = s.fc.node.engine().authority();
        let outs = s.fc.update(|n| {
            n.handle_timeout(now);
            fc_outputs(n)
        });
        self.on_fc_outputs(s, before, outs, None, log);
        if self.faulty(Fault::EndlessRetries)
            && s.fc.node.engine().authority() == Authority::Handshake
        {
            if let Some((_, event)) = s.ghost.fc_newest {
                let m = Message::FbwagNotice(pwire::notice(self.fc.own, Status::RC_LOST, event));
                say(log, s.now, "harness", || "re-sends the FC's notice".into());
                self.transmit(s, Party::Fc, &m, log);
            }
        }
    }

    fn tick_cc(&self, s: &mut State, log: &mut Log) {
        let Some(t) = s.cc_deadline() else { return };
        self.advance(s, t, log);
        let now = s.cc_now();
        let outs = s.cc.update(|n| {
            n.handle_timeout(now);
            cc_outputs(n)
        });
        checks::on_cc_timers(self, s, &outs);
        self.on_cc_outputs(s, outs, log);
    }

    fn deliver(&self, s: &mut State, to: Party, i: usize, log: &mut Log) -> Option<()> {
        let f = queue(s, to).get(i)?.clone();
        queue(s, to).remove(i);
        say(log, s.now, "link", || format!("delivers {}", describe(&f)));
        match to {
            Party::Cc => self.arrive_cc(s, &f.bytes, setup::FC_ADDR, &f, log),
            _ => {
                let control = wire::message_of(&f.bytes)
                    .as_ref()
                    .and_then(Control::from_message)
                    .is_some();
                let handshake = s.fc.node.engine().authority() == Authority::Handshake;
                if self.faulty(Fault::ControlInHandshake) && control && handshake {
                    say(log, s.now, "harness", || {
                        "applies the control in handshake".into()
                    });
                    s.ghost.broken |= Invariant::SingleController.bit();
                }
                self.arrive_fc(s, &f.bytes, setup::CC_ADDR, &f, log);
            }
        }
        Some(())
    }

    /// `bytes` reach the FC's link from `source`; `cause` is what the
    /// harness knows of them.
    pub(crate) fn arrive_fc(
        &self,
        s: &mut State,
        bytes: &[u8],
        source: SocketAddr,
        cause: &InFlight,
        log: &mut Log,
    ) {
        let Some((frame, authenticated)) = s.fc.link.parse(bytes) else {
            say(log, s.now, "FC", || "link parser refuses the frame".into());
            return;
        };
        let now = s.fc_now();
        let arrival = Arrival {
            link: FC_LINK,
            source: Some(source),
            frame: wire::frame_of(&frame),
            authenticated,
        };
        let before = s.fc.node.engine().authority();
        let unsigned = !wire::frame_of(&frame).is_signed();
        let digest_before = unsigned.then(|| node_digest(s, Party::Fc, &self.relevance()));
        let up_to_date = s.fc_deadline().is_none_or(|t| t > s.now);
        let (fate, outs) = s.fc.update(|n| {
            let fate = n.handle_frame(now, arrival);
            (fate, fc_outputs(n))
        });
        say_fate(log, s.now, "FC", &fate);
        let inputs = Inputs {
            frame: &frame,
            authenticated,
            cause,
            fate: &fate,
            digest_before,
            up_to_date,
        };
        checks::on_fc_arrival(self, s, &inputs, before, &outs, log);
        if authenticated {
            self.authenticated(s, Party::Fc, &frame, cause, log);
        }
        self.on_fc_outputs(s, before, outs, Some(cause), log);
    }

    pub(crate) fn arrive_cc(
        &self,
        s: &mut State,
        bytes: &[u8],
        source: SocketAddr,
        cause: &InFlight,
        log: &mut Log,
    ) {
        let Some((frame, authenticated)) = s.cc.link.parse(bytes) else {
            say(log, s.now, "CC", || "link parser refuses the frame".into());
            return;
        };
        let now = s.cc_now();
        let arrival = Arrival {
            link: FC_LINK,
            source: Some(source),
            frame: wire::frame_of(&frame),
            authenticated,
        };
        let unsigned = !wire::frame_of(&frame).is_signed();
        let digest_before = unsigned.then(|| node_digest(s, Party::Cc, &self.relevance()));
        let up_to_date = s.cc_deadline().is_none_or(|t| t > s.now);
        let (fate, outs) = s.cc.update(|n| {
            let fate = n.handle_frame(now, arrival);
            (fate, cc_outputs(n))
        });
        say_fate(log, s.now, "CC", &fate);
        let inputs = Inputs {
            frame: &frame,
            authenticated,
            cause,
            fate: &fate,
            digest_before,
            up_to_date,
        };
        checks::on_cc_arrival(self, s, &inputs, log);
        if authenticated {
            self.authenticated(s, Party::Cc, &frame, cause, log);
        }
        self.on_cc_outputs(s, outs, log);
    }

    /// A frame `to` authenticated: replay protection's own record, the
    /// stranger's capture, and the documented gap.
    fn authenticated(
        &self,
        s: &mut State,
        to: Party,
        frame: &[u8],
        cause: &InFlight,
        log: &mut Log,
    ) {
        let side = (to == Party::Cc) as usize;
        let ts = wire::frame_of(frame).signature().map(|sig| sig.timestamp());
        let Some(ts) = ts else { return };
        let newest = &mut s.ghost.authenticated[side];
        if newest.is_some_and(|n| ts <= n) {
            self.break_now(s, Invariant::NoReplay, log, "a replay authenticated");
            return;
        }
        *newest = Some(ts);
        if cause.from == Party::Stranger {
            // A capture authenticated again, by a side whose signing state
            // began after it was captured: the documented gap.
            say(log, s.now, "CHECK", || {
                "the documented gap: a replay into a restart without its signing state".into()
            });
            s.ghost.gap = true;
            self.reach(Reach::ReplayGap, s.steps.0);
        } else if !s.ghost.recordings.iter().any(|r| r.to == to) {
            s.ghost.recordings.push(Recording {
                to,
                bytes: frame.to_vec(),
            });
        }
    }

    /// The FC node's outputs: frames onto the link, and the checks of
    /// every mode change and every control applied.
    fn on_fc_outputs(
        &self,
        s: &mut State,
        before: Authority,
        outs: Vec<Output<FcOutput>>,
        cause: Option<&InFlight>,
        log: &mut Log,
    ) {
        checks::on_fc_outputs(self, s, before, &outs, cause, log);
        for out in outs {
            match out {
                Output::Transmit { links, message } if links.contains(FC_LINK) => {
                    self.transmit(s, Party::Fc, &message, log)
                }
                Output::TransmitTo { message, .. } => {
                    say(log, s.now, "FC", || {
                        format!("answers the stranger with {}", summary(&message))
                    });
                    let _ = s.fc.link.frame(&message, s.now);
                }
                Output::Event(FcOutput::SetMode(a)) => {
                    say(log, s.now, "FC", || format!("mode {a:?}"))
                }
                Output::Event(FcOutput::ApplyControl { control, .. }) => {
                    say(log, s.now, "FC", || format!("applies {}", control.name()))
                }
                Output::Event(FcOutput::ReleaseControl) => {
                    say(log, s.now, "FC", || "releases control".into())
                }
                _ => {}
            }
        }
    }

    fn on_cc_outputs(&self, s: &mut State, outs: Vec<Output<CompanionEvent>>, log: &mut Log) {
        checks::on_cc_outputs(self, s, &outs, log);
        for out in outs {
            match out {
                Output::Transmit { links, message } if links.contains(FC_LINK) => {
                    self.transmit(s, Party::Cc, &message, log)
                }
                Output::TransmitTo { message, .. } => {
                    let _ = s.cc.link.frame(&message, s.now);
                }
                Output::Event(e) => say(log, s.now, "CC", || format!("{e:?}")),
                _ => {}
            }
        }
    }

    /// Frames `message` as `from` and puts it in flight (lost when the
    /// link already holds its bound).
    pub(crate) fn transmit(&self, s: &mut State, from: Party, message: &Message, log: &mut Log) {
        let now = s.now;
        let bytes = match from {
            Party::Fc => s.fc.link.frame(message, now),
            _ => s.cc.link.frame(message, now),
        };
        checks::on_transmit(self, s, from, message, &bytes, log);
        let f = InFlight {
            bytes,
            from,
            fc_boot: s.fc.boots,
        };
        if let Message::FbwagNotice(n) = message {
            let ack = from == Party::Cc && n.failsafe_status == Status::CC_TAKEOVER_CONFIRMED;
            if ack && self.faulty(Fault::StaleAckAfterReboot) {
                s.ghost.recorded_ack = Some(f.clone());
            }
        }
        let to = if from == Party::Fc {
            Party::Cc
        } else {
            Party::Fc
        };
        let full = queue(s, to).len() >= self.cfg.max_in_flight;
        say(log, now, party_name(from), || {
            format!(
                "sends {}{}",
                summary(message),
                if full { " (link full: lost)" } else { "" }
            )
        });
        if !full {
            queue(s, to).push(f);
        }
    }

    fn reboot_fc(&self, s: &mut State, kept: bool, log: &mut Log) {
        if s.fc.node.engine().authority() == Authority::Companion {
            s.ghost.left_companion = Some(s.now);
        }
        let mut node = setup::fc_node(self.fc, Moment::ZERO);
        node.set_receiver_ok(s.rc_ok);
        s.fc = Side {
            node: Arc::new(node),
            link: s.fc.link.restarted(kept, s.now),
            boot: s.now,
            boots: s.fc.boots + 1,
        };
        let g = &mut s.ghost;
        (g.handshake_since, g.controlled, g.fc_heard_cc) = (None, None, None);
        g.fc_newest = None;
        if !kept {
            (g.authenticated[0], g.signed[0]) = (None, None);
        }
        say(log, s.now, "FC", || {
            format!("reboots (signing state kept: {kept})")
        });
    }

    fn reboot_cc(&self, s: &mut State, kept: bool, log: &mut Log) {
        let mut node = setup::cc_node(self.cc, Moment::ZERO);
        let outs = cc_outputs(&mut node);
        s.cc = Side {
            node: Arc::new(node),
            link: s.cc.link.restarted(kept, s.now),
            boot: s.now,
            boots: s.cc.boots + 1,
        };
        let g = &mut s.ghost;
        g.sent.retain(|n| n.from != Party::Cc);
        (
            g.cc_started,
            g.cc_heard_fc,
            g.confirmation,
            g.autonomy_heard,
        ) = (None, None, None, None);
        g.cc_heard_fc_news = None;
        if !kept {
            (g.authenticated[1], g.signed[1]) = (None, None);
        }
        say(log, s.now, "CC", || {
            format!("reboots (signing state kept: {kept})")
        });
        self.on_cc_outputs(s, outs, log);
    }

    fn forge(&self, s: &mut State, f: Forgery, log: &mut Log) {
        let fc_ids = self.fc.own;
        let cc_ids = self.fc.companion;
        let command = |target: fbwag_delegation::Peer| {
            Message::CommandLong(CommandLong {
                target_system: target.sysid,
                target_component: target.compid,
                command: MavCmd::COMPONENT_ARM_DISARM,
                param1: 1.0,
                ..CommandLong::default()
            })
        };
        let (to, ids, source, message) = match f {
            Forgery::Takeover => {
                let handshake = s.fc.node.engine().authority() == Authority::Handshake;
                let Some((_, e)) = s.ghost.fc_newest.filter(|_| handshake) else {
                    return;
                };
                let n = pwire::notice(fc_ids, Status::CC_TAKEOVER_CONFIRMED, e);
                (Party::Fc, cc_ids, setup::CC_ADDR, Message::FbwagNotice(n))
            }
            Forgery::Control => (
                Party::Fc,
                cc_ids,
                setup::STRANGER_ADDR,
                Control::rc(fc_ids, [1900; 8]).to_message(),
            ),
            Forgery::GroundRequest => (Party::Fc, setup::STATION, setup::CC_ADDR, command(fc_ids)),
            Forgery::RcLost => {
                let e = s.fc_now().as_millis() as u32 + 1;
                let n = pwire::notice(fc_ids, Status::RC_LOST, e);
                (Party::Cc, fc_ids, setup::FC_ADDR, Message::FbwagNotice(n))
            }
            Forgery::CompanionMode => {
                let hb = pwire::fc_heartbeat(Authority::Companion);
                (
                    Party::Cc,
                    fc_ids,
                    setup::STRANGER_ADDR,
                    Message::Heartbeat(hb),
                )
            }
            Forgery::Broadcast => {
                let hb = Message::Heartbeat(Default::default());
                let nobody = fbwag_delegation::Peer::new(0, setup::STATION.compid);
                (Party::Cc, nobody, setup::FC_ADDR, hb)
            }
            Forgery::WhoFlies | Forgery::NewKey | Forgery::GroundParameter => {
                return self.send_into_trusted_link(s, f, log);
            }
        };
        let bytes = wire::forged(ids, 0, &message);
        say(log, s.now, "stranger", || {
            format!("injects {} (unsigned)", summary(&message))
        });
        let cause = InFlight {
            bytes: bytes.clone(),
            from: Party::Stranger,
            fc_boot: s.fc.boots,
        };
        match to {
            Party::Fc => self.arrive_fc(s, &bytes, source, &cause, log),
            _ => self.arrive_cc(s, &bytes, source, &cause, log),
        }
    }

    /// A frame into the companion's trusted ground link: whatever the
    /// node would sign on to the FC is judged at its fate (the FC's
    /// parameters and key live in the program, not in its node).
    fn send_into_trusted_link(&self, s: &mut State, f: Forgery, log: &mut Log) {
        let fc = self.fc.own;
        let param = |name: &str, value: f32| {
            let mut param_id = [0u8; 16];
            param_id[..name.len()].copy_from_slice(name.as_bytes());
            Message::ParamSet(ParamSet {
                target_system: fc.sysid,
                target_component: fc.compid,
                param_id,
                param_value: value,
                ..ParamSet::default()
            })
        };
        let message = match f {
            Forgery::WhoFlies => param("FBWAG_CC_COMPID", 77.0),
            Forgery::NewKey => Message::SetupSigning(SetupSigning {
                target_system: fc.sysid,
                target_component: fc.compid,
                secret_key: [7; 32],
                ..SetupSigning::default()
            }),
            _ => param("AIRSPEED_CRUISE", 22.0),
        };
        let bytes = wire::forged(setup::STATION, 0, &message);
        say(log, s.now, "stranger", || {
            format!("sends {} into the trusted link", summary(&message))
        });
        let arrival = Arrival {
            link: GROUND_LINK,
            source: None,
            frame: wire::frame_of(&bytes),
            authenticated: false,
        };
        let now = s.cc_now();
        let (fate, outs) = s.cc.update(|n| {
            let fate = n.handle_frame(now, arrival);
            (fate, cc_outputs(n))
        });
        say_fate(log, s.now, "CC", &fate);
        if fate.route.contains(FC_LINK) {
            if f == Forgery::GroundParameter {
                self.reach(Reach::TrustedSignedOn, s.steps.0);
            } else {
                let why = "signs on what decides who flies";
                self.break_now(s, Invariant::WhoFliesOnTheGround, log, why);
            }
        }
        self.on_cc_outputs(s, outs, log);
    }

    fn replay(&self, s: &mut State, i: usize, log: &mut Log) -> Option<()> {
        let r = s.ghost.recordings.get(i)?.clone();
        say(log, s.now, "stranger", || {
            let what = wire::message_of(&r.bytes).map_or("a frame".into(), |m| summary(&m));
            format!("replays {what} it captured")
        });
        let cause = InFlight {
            bytes: r.bytes.clone(),
            from: Party::Stranger,
            fc_boot: s.fc.boots,
        };
        match r.to {
            Party::Fc => self.arrive_fc(s, &r.bytes, setup::CC_ADDR, &cause, log),
            _ => self.arrive_cc(s, &r.bytes, setup::FC_ADDR, &cause, log),
        }
        Some(())
    }

    fn replay_stale_ack(&self, s: &mut State, log: &mut Log) -> Option<()> {
        let old = s.ghost.recorded_ack.take()?;
        let message = wire::message_of(&old.bytes)?;
        let bytes = s.cc.link.frame(&message, s.now);
        say(log, s.now, "harness", || {
            format!(
                "replays {} of an earlier FC boot, signed afresh",
                summary(&message)
            )
        });
        self.arrive_fc(s, &bytes, setup::CC_ADDR, &old, log);
        Some(())
    }
}

/// The digest of one side's node alone, at its clock's now.
pub(crate) fn node_digest(s: &State, side: Party, r: &Relevance) -> u64 {
    let fc_now = s.fc_now();
    let mut d = crate::state::Clock::new(s.now, fc_now.as_millis() as u32, s.fc.link.seq, r);
    match side {
        Party::Fc => s.fc.node.digest(d.at(fc_now)),
        _ => s.cc.node.digest(d.at(s.cc_now())),
    }
    core::hash::Hasher::finish(&d)
}

fn say_fate(log: &mut Log, now: Moment, who: &str, fate: &Fate) {
    if let Some(reason) = fate.dropped {
        say(log, now, who, || format!("drops it: {}", reason.name()));
    }
}

/// The frames in flight to `to`.
pub(crate) fn queue(s: &mut State, to: Party) -> &mut Vec<InFlight> {
    match to {
        Party::Cc => &mut s.to_cc,
        _ => &mut s.to_fc,
    }
}

fn fc_outputs(n: &mut FcNode) -> Vec<Output<FcOutput>> {
    core::iter::from_fn(|| n.poll_output()).collect()
}

fn cc_outputs(n: &mut CompanionNode) -> Vec<Output<CompanionEvent>> {
    core::iter::from_fn(|| n.poll_output()).collect()
}

fn party_name(p: Party) -> &'static str {
    match p {
        Party::Fc => "FC",
        Party::Cc => "CC",
        Party::Stranger => "stranger",
    }
}

/// A message in a few words, for the timeline.
pub fn summary(m: &Message) -> String {
    match m {
        Message::FbwagNotice(n) => format!(
            "FBWAG_NOTICE status {} event {}",
            n.failsafe_status.0, n.timestamp
        ),
        Message::Heartbeat(h) => format!("HEARTBEAT mode {}", h.custom_mode),
        Message::Statustext(t) => format!("STATUSTEXT id {}", t.id),
        Message::ParamSet(p) => {
            let name = p.param_id.split(|&b| b == 0).next().unwrap_or_default();
            format!(
                "PARAM_SET {} = {}",
                String::from_utf8_lossy(name),
                p.param_value
            )
        }
        other => other.meta().name.to_string(),
    }
}

fn describe(f: &InFlight) -> String {
    let what = wire::message_of(&f.bytes).map_or("a frame".into(), |m| summary(&m));
    let arrow = match f.from {
        Party::Fc => "FC → CC",
        _ => "CC → FC",
    };
    format!("{what} ({arrow})")
}

impl Model for DelegationModel {
    type State = State;
    type Action = Action;

    fn init_states(&self) -> Vec<State> {
        vec![self.initial()]
    }

    fn actions(&self, s: &State, actions: &mut Vec<Action>) {
        if s.ghost.gap {
            return;
        }
        let earliest = s.earliest();
        if earliest.is_some() && s.fc_deadline() == earliest {
            actions.push(Action::TickFc);
        }
        if earliest.is_some() && s.cc_deadline() == earliest {
            actions.push(Action::TickCc);
        }
        let c = &self.cfg;
        for (to, q) in [(Party::Cc, &s.to_cc), (Party::Fc, &s.to_fc)] {
            for i in 0..q.len() {
                actions.push(Action::Deliver(to, i));
                if s.ghost.dups < c.dups && q.len() < c.max_in_flight {
                    actions.push(Action::Duplicate(to, i));
                }
            }
        }
        let rtl = s.fc.node.engine().authority() == Authority::Rtl;
        if s.ghost.rc_flips < c.rc_flips && (s.rc_ok || rtl || !c.rc_back_in_rtl) {
            actions.push(if s.rc_ok {
                Action::RcLost
            } else {
                Action::RcBack
            });
        }
        if self.fc_may_restart(s) {
            actions.push(Action::RebootFc { signing_kept: true });
            actions.push(Action::RebootFc {
                signing_kept: false,
            });
        }
        if s.cc.boots < c.cc_reboots {
            actions.push(Action::RebootCc { signing_kept: true });
            actions.push(Action::RebootCc {
                signing_kept: false,
            });
        }
        if c.stranger {
            actions.extend(Forgery::ALL.map(Action::Forge));
            actions.extend((0..s.ghost.recordings.len()).map(Action::Replay));
        }
        if s.ghost.autonomy_flips < c.autonomy_flips {
            actions.push(if s.autonomy_speaks {
                Action::AutonomySilent
            } else {
                Action::AutonomySpeaks
            });
        }
        let stale = s
            .ghost
            .recorded_ack
            .as_ref()
            .is_some_and(|r| r.fc_boot < s.fc.boots);
        if self.faulty(Fault::StaleAckAfterReboot) && stale {
            actions.push(Action::ReplayStaleAck);
        }
    }

    fn next_state(&self, s: &State, action: Action) -> Option<State> {
        let next = self.step(s, action, &mut None)?;
        // A forgery or replay that changed nothing leads back here.
        (next.digest != s.digest).then_some(next)
    }

    fn properties(&self) -> Vec<Property<Self>> {
        props::properties()
    }

    fn within_boundary(&self, s: &State) -> bool {
        let within = self.cfg.horizon.is_none_or(|h| s.now <= Moment::ZERO + h);
        if !within {
            self.cut.store(true, Ordering::Relaxed);
        }
        within
    }
}
