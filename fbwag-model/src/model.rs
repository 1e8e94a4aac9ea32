//! The stateright model: actions, and the transition that drives the real
//! nodes through them.

use crate::props::{self, Invariant};
use crate::setup::{self, Fault, ModelConfig, AUTONOMY, AUTONOMY_ADDR, AUTONOMY_LINK, FC_LINK};
use crate::state::{Ghost, Held, InFlight, Party, Sent, Side, State, Steps};
use crate::wire::{self, Endpoint};
use fbwag_delegation::cc::CcConfig;
use fbwag_delegation::control::Control;
use fbwag_delegation::engine::FcOutput;
use fbwag_delegation::fc::{Authority, FcConfig};
use fbwag_delegation::node::{Arrival, CompanionEvent, CompanionNode, FcNode, Output};
use fbwag_delegation::{wire as pwire, Moment, Status};
use fbwag_dialect::Message;
use stateright::{Model, Property};
use std::sync::atomic::AtomicUsize;
use std::sync::Arc;

/// What a stranger without the key injects (unsigned, delivered at once).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Forgery {
    /// To the FC: a takeover acknowledgement (status 2) of the FC's latest
    /// event, with the companion's ids.
    Takeover,
    /// To the FC: an RC override with the companion's ids.
    Control,
    /// To the companion: an RC-loss notice of a new event, with the FC's ids.
    RcLost,
    /// To the companion: a heartbeat in companion control, with the FC's ids.
    CompanionMode,
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
    /// Frame `index` in flight to `to` is lost.
    Lose(Party, usize),
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
    /// Per property (in [`props::properties`] order), the fewest steps to a
    /// state that broke (or, for the states to reach, showed) it.
    pub shortest: Arc<Vec<AtomicUsize>>,
    /// Bounds of the world and the planted fault, if any.
    pub cfg: ModelConfig,
    /// The FC's settings.
    pub fc: FcConfig,
    /// The companion's settings.
    pub cc: CcConfig,
}

/// Timeline lines of a replayed step (`None` while checking).
pub type Log = Option<Vec<String>>;

fn say(log: &mut Log, now: Moment, who: &str, what: impl FnOnce() -> String) {
    if let Some(lines) = log {
        lines.push(format!("t={:.3} {who}: {}", now.0 as f64 / 1e6, what()));
    }
}

impl DelegationModel {
    /// The model with `cfg`'s bounds and the grid settings (see
    /// [`setup::fc_config`]).
    pub fn new(cfg: ModelConfig) -> Self {
        DelegationModel {
            checked: Arc::new(AtomicUsize::new(0)),
            shortest: Arc::new(
                (0..props::COUNT)
                    .map(|_| AtomicUsize::new(usize::MAX))
                    .collect(),
            ),
            cfg,
            fc: setup::fc_config(),
            cc: setup::cc_config(),
        }
    }

    fn faulty(&self, f: Fault) -> bool {
        self.cfg.fault == Some(f)
    }

    /// The initial world: both nodes just started, the pilot flying.
    pub fn initial(&self) -> State {
        let mut fc = setup::fc_node(self.fc, Moment::ZERO);
        fc.set_receiver_ok(true);
        let mut s = State {
            steps: Steps(0),
            now: Moment::ZERO,
            fc: Side {
                node: Held::new(fc),
                link: Endpoint::starting(self.fc.own, 1, Moment::ZERO),
                boot: Moment::ZERO,
                boots: 0,
            },
            cc: Side {
                node: Held::new(setup::cc_node(self.cc, Moment::ZERO)),
                link: Endpoint::starting(self.cc.own, 2, Moment::ZERO),
                boot: Moment::ZERO,
                boots: 0,
            },
            to_cc: Vec::new(),
            to_fc: Vec::new(),
            rc_ok: true,
            autonomy_speaks: true,
            ghost: Ghost::default(),
        };
        self.autonomy_control(&mut s, &mut None);
        s
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
            Action::Lose(to, i) => {
                let f = queue(&mut s, to).get(i)?.clone();
                queue(&mut s, to).remove(i);
                say(log, s.now, "link", || format!("loses {}", describe(&f)));
            }
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
                s.fc.node.update(|n| n.set_receiver_ok(ok));
                s.ghost.rc_changed = s.now;
                s.ghost.rc_flips += 1;
                say(log, s.now, "pilot", || {
                    if ok { "receiver back" } else { "receiver lost" }.into()
                });
            }
            Action::RebootFc { signing_kept } => self.reboot_fc(&mut s, signing_kept, log),
            Action::RebootCc { signing_kept } => self.reboot_cc(&mut s, signing_kept, log),
            Action::Forge(f) => self.forge(&mut s, f, log),
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
        Some(s)
    }

    /// Moves the clock to `t`; frames still in flight are lost, and a
    /// speaking autonomy's control (a stream far faster than the grid)
    /// reaches the companion first.
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
        let outs = s.cc.node.update(|n| {
            let _ = n.handle_frame(now, arrival);
            cc_outputs(n)
        });
        self.on_cc_outputs(s, outs, log);
    }

    fn tick_fc(&self, s: &mut State, log: &mut Log) {
        let Some(t) = s.fc_deadline() else { return };
        self.advance(s, t, log);
        let now = s.fc_now();
        let before = s.fc.node.get().engine().authority();
        let outs = s.fc.node.update(|n| {
            n.handle_timeout(now);
            fc_outputs(n)
        });
        self.on_fc_outputs(s, before, outs, None, log);
        if self.faulty(Fault::EndlessRetries)
            && s.fc.node.get().engine().authority() == Authority::Handshake
        {
            if let Some(event) = latest_event(&s.ghost, Party::Fc) {
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
        let outs = s.cc.node.update(|n| {
            n.handle_timeout(now);
            cc_outputs(n)
        });
        self.on_cc_outputs(s, outs, log);
    }

    fn deliver(&self, s: &mut State, to: Party, i: usize, log: &mut Log) -> Option<()> {
        let f = queue(s, to).get(i)?.clone();
        queue(s, to).remove(i);
        say(log, s.now, "link", || format!("delivers {}", describe(&f)));
        match to {
            Party::Cc => self.arrive_cc(s, &f.bytes, log),
            _ => {
                let control = wire::message_of(&f.bytes)
                    .as_ref()
                    .and_then(Control::from_message)
                    .is_some();
                let handshake = s.fc.node.get().engine().authority() == Authority::Handshake;
                if self.faulty(Fault::ControlInHandshake) && control && handshake {
                    say(log, s.now, "harness", || {
                        "applies the control in handshake".into()
                    });
                    s.ghost.broken |= Invariant::SingleController.bit();
                }
                self.arrive_fc(s, &f.bytes, &f, log);
            }
        }
        Some(())
    }

    /// `bytes` reach the FC's link; `cause` is what the harness knows of them.
    fn arrive_fc(&self, s: &mut State, bytes: &[u8], cause: &InFlight, log: &mut Log) {
        let Some((frame, authenticated)) = s.fc.link.parse(bytes) else {
            say(log, s.now, "FC", || "link parser refuses the frame".into());
            return;
        };
        let now = s.fc_now();
        let arrival = Arrival {
            link: FC_LINK,
            source: None,
            frame: wire::frame_of(&frame),
            authenticated,
        };
        let before = s.fc.node.get().engine().authority();
        let (fate, outs) = s.fc.node.update(|n| {
            let fate = n.handle_frame(now, arrival);
            (fate, fc_outputs(n))
        });
        if let Some(reason) = fate.dropped {
            say(log, s.now, "FC", || format!("drops it: {}", reason.name()));
        }
        self.on_fc_outputs(s, before, outs, Some(cause), log);
    }

    fn arrive_cc(&self, s: &mut State, bytes: &[u8], log: &mut Log) {
        let Some((frame, authenticated)) = s.cc.link.parse(bytes) else {
            say(log, s.now, "CC", || "link parser refuses the frame".into());
            return;
        };
        let now = s.cc_now();
        let arrival = Arrival {
            link: FC_LINK,
            source: None,
            frame: wire::frame_of(&frame),
            authenticated,
        };
        let (fate, outs) = s.cc.node.update(|n| {
            let fate = n.handle_frame(now, arrival);
            (fate, cc_outputs(n))
        });
        if let Some(reason) = fate.dropped {
            say(log, s.now, "CC", || format!("drops it: {}", reason.name()));
        }
        self.on_cc_outputs(s, outs, log);
    }

    /// The FC node's outputs: frames onto the link, and the checks of
    /// every mode change and every control applied.
    fn on_fc_outputs(
        &self,
        s: &mut State,
        mut authority: Authority,
        outs: Vec<Output<FcOutput>>,
        cause: Option<&InFlight>,
        log: &mut Log,
    ) {
        for out in outs {
            match out {
                Output::Transmit { links, message } if links.contains(FC_LINK) => {
                    self.transmit(s, Party::Fc, &message, log)
                }
                Output::Event(FcOutput::SetMode(a)) => {
                    say(log, s.now, "FC", || format!("mode {a:?}"));
                    self.mode_changed(s, authority, a, cause);
                    authority = a;
                }
                Output::Event(FcOutput::ApplyControl { from, control }) => {
                    say(log, s.now, "FC", || {
                        format!(
                            "applies {} from {}/{}",
                            control.name(),
                            from.peer.sysid,
                            from.peer.compid
                        )
                    });
                    if authority != Authority::Companion {
                        s.ghost.broken |= Invariant::SingleController.bit();
                    }
                    let genuine = cause.is_some_and(|c| c.from == Party::Cc);
                    if from.peer != self.fc.companion || !from.authenticated || !genuine {
                        s.ghost.broken |= Invariant::TrustedControl.bit();
                    }
                }
                Output::Event(FcOutput::ReleaseControl) => {
                    say(log, s.now, "FC", || "releases control".into())
                }
                _ => {}
            }
        }
    }

    /// Records a mode change and checks a takeover's acknowledgement.
    fn mode_changed(
        &self,
        s: &mut State,
        from: Authority,
        to: Authority,
        cause: Option<&InFlight>,
    ) {
        if from == Authority::Companion && to != Authority::Companion {
            s.ghost.left_companion = Some(s.now);
        }
        s.ghost.handshake_since = (to == Authority::Handshake).then_some(s.now);
        if to != Authority::Companion || from == Authority::Companion {
            return;
        }
        // Companion control begins: only on the companion's own
        // acknowledgement of an event this FC boot announced.
        let Some(ack) = cause else {
            s.ghost.broken |= Invariant::SingleController.bit();
            return;
        };
        if ack.from != Party::Cc {
            s.ghost.broken |= Invariant::SingleController.bit();
        }
        let event = match wire::message_of(&ack.bytes) {
            Some(Message::FbwagNotice(n)) => Some(n.timestamp),
            _ => None,
        };
        let announced = event.is_some_and(|e| {
            s.ghost
                .sent
                .iter()
                .any(|n| n.from == Party::Fc && n.status == Status::RC_LOST.0 && n.event == e)
        });
        if ack.fc_boot != s.fc.boots || !announced {
            s.ghost.broken |= Invariant::NoStaleTakeover.bit();
        }
    }

    fn on_cc_outputs(&self, s: &mut State, outs: Vec<Output<CompanionEvent>>, log: &mut Log) {
        for out in outs {
            match out {
                Output::Transmit { links, message } if links.contains(FC_LINK) => {
                    self.transmit(s, Party::Cc, &message, log)
                }
                Output::Event(e) => say(log, s.now, "CC", || format!("{e:?}")),
                _ => {}
            }
        }
    }

    /// Frames `message` as `from` and puts it in flight (lost when the
    /// link already holds its bound).
    fn transmit(&self, s: &mut State, from: Party, message: &Message, log: &mut Log) {
        let now = s.now;
        let bytes = match from {
            Party::Fc => s.fc.link.frame(message, now),
            _ => s.cc.link.frame(message, now),
        };
        let f = InFlight {
            bytes,
            from,
            fc_boot: s.fc.boots,
        };
        if let Message::FbwagNotice(n) = message {
            let limit = 1 + match from {
                Party::Fc => self.fc.max_retries,
                _ => self.cc.max_ack_retries,
            };
            count_notice(&mut s.ghost, from, n.failsafe_status.0, n.timestamp, limit);
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
        if s.fc.node.get().engine().authority() == Authority::Companion {
            s.ghost.left_companion = Some(s.now);
        }
        let mut node = setup::fc_node(self.fc, Moment::ZERO);
        node.set_receiver_ok(s.rc_ok);
        s.fc = Side {
            node: Held::new(node),
            link: s.fc.link.restarted(kept, s.now),
            boot: s.now,
            boots: s.fc.boots + 1,
        };
        s.ghost.handshake_since = None;
        s.ghost.sent.retain(|n| n.from != Party::Fc);
        say(log, s.now, "FC", || {
            format!("reboots (signing state kept: {kept})")
        });
    }

    fn reboot_cc(&self, s: &mut State, kept: bool, log: &mut Log) {
        s.cc = Side {
            node: Held::new(setup::cc_node(self.cc, Moment::ZERO)),
            link: s.cc.link.restarted(kept, s.now),
            boot: s.now,
            boots: s.cc.boots + 1,
        };
        s.ghost.sent.retain(|n| n.from != Party::Cc);
        say(log, s.now, "CC", || {
            format!("reboots (signing state kept: {kept})")
        });
    }

    fn forge(&self, s: &mut State, f: Forgery, log: &mut Log) {
        s.ghost.forgeries += 1;
        let fc_ids = self.fc.own;
        let cc_ids = self.fc.companion;
        let (to, ids, message) = match f {
            Forgery::Takeover => {
                let e = latest_event(&s.ghost, Party::Fc).unwrap_or(0);
                let n = pwire::notice(fc_ids, Status::CC_TAKEOVER_CONFIRMED, e);
                (Party::Fc, cc_ids, Message::FbwagNotice(n))
            }
            Forgery::Control => (
                Party::Fc,
                cc_ids,
                Control::rc(fc_ids, [1900; 8]).to_message(),
            ),
            Forgery::RcLost => {
                let e = s.fc_now().as_millis() as u32 + 1;
                let n = pwire::notice(fc_ids, Status::RC_LOST, e);
                (Party::Cc, fc_ids, Message::FbwagNotice(n))
            }
            Forgery::CompanionMode => {
                let hb = pwire::fc_heartbeat(Authority::Companion);
                (Party::Cc, fc_ids, Message::Heartbeat(hb))
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
            Party::Fc => self.arrive_fc(s, &bytes, &cause, log),
            _ => self.arrive_cc(s, &bytes, log),
        }
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
        self.arrive_fc(s, &bytes, &old, log);
        Some(())
    }
}

/// The frames in flight to `to`.
fn queue(s: &mut State, to: Party) -> &mut Vec<InFlight> {
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

/// Counts a notice of `from`; past `limit` for one status and event, the
/// retry bound is broken.
fn count_notice(g: &mut Ghost, from: Party, status: u8, event: u32, limit: u8) {
    let i = g
        .sent
        .iter()
        .position(|n| n.from == from && n.status == status && n.event == event);
    let count = match i {
        Some(i) => {
            g.sent[i].count = g.sent[i].count.saturating_add(1);
            g.sent[i].count
        }
        None => {
            g.sent.push(Sent {
                from,
                status,
                event,
                count: 1,
            });
            1
        }
    };
    if count > limit {
        g.broken |= Invariant::BoundedNotices.bit();
    }
}

/// The newest RC-loss event `from` announced in its current boot.
fn latest_event(g: &Ghost, from: Party) -> Option<u32> {
    g.sent
        .iter()
        .filter(|n| n.from == from && n.status == Status::RC_LOST.0)
        .map(|n| n.event)
        .max()
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
                actions.push(Action::Lose(to, i));
                if s.ghost.dups < c.dups && q.len() < c.max_in_flight {
                    actions.push(Action::Duplicate(to, i));
                }
            }
        }
        if s.ghost.rc_flips < c.rc_flips {
            actions.push(if s.rc_ok {
                Action::RcLost
            } else {
                Action::RcBack
            });
        }
        if s.fc.boots < c.fc_reboots {
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
        if s.ghost.forgeries < c.forgeries {
            for f in [
                Forgery::Takeover,
                Forgery::Control,
                Forgery::RcLost,
                Forgery::CompanionMode,
            ] {
                actions.push(Action::Forge(f));
            }
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
        self.step(s, action, &mut None)
    }

    fn properties(&self) -> Vec<Property<Self>> {
        props::properties()
    }

    fn within_boundary(&self, s: &State) -> bool {
        s.now <= Moment::ZERO + self.cfg.horizon
    }
}
