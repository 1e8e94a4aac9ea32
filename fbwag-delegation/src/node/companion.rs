//! The companion computer's node: the FC link, ground-station links and
//! the autonomy's link around the companion engine.

use super::{
    sender, Arrival, Core, Direction, DropReason, Fate, Filter, LinkId, LinkSpec, NodeError,
    Output, Role,
};
use crate::cc::{CcConfig, CcState};
use crate::control::{Control, Controller, WingsLevel};
use crate::digest::{self, Digest};
use crate::engine::{CcEngine, CcOutput, ControlVerdict, Verdict};
use crate::outbox::Outbox;
use crate::{wire, Moment, Peer};
use core::hash::Hash;
use core::time::Duration;
use fbwag_dialect::{Message, MessageView};

/// What the companion does when its autonomy is silent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum AutonomyFallback {
    /// Decline a takeover, and give back an episode held (the FC's failsafe
    /// runs at once).
    #[default]
    Decline,
    /// Take over and fly wings level until the autonomy speaks.
    WingsLevel,
}

/// Where the companion's control comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ControlSource {
    /// A built-in controller: the program answers each
    /// [`CcOutput::ControlDue`] with [`CompanionNode::submit_control`].
    Builtin,
    /// The user's autonomy program, on this link.
    Autonomy {
        /// Its link (added with [`Role::Autonomy`]).
        link: LinkId,
        /// What to do while it is silent.
        fallback: AutonomyFallback,
        /// How long without a frame from it makes it silent.
        silence: Duration,
    },
}

/// Whether the autonomy's `view` asks the FC for telemetry (a rate, a
/// message once): REQUEST_DATA_STREAM, MAV_CMD_SET_MESSAGE_INTERVAL,
/// MAV_CMD_REQUEST_MESSAGE. The only messages of the autonomy but its
/// control that reach the FC.
fn asks_for_telemetry(view: &MessageView<'_>) -> bool {
    use fbwag_dialect::dialects::common::MavCmd;
    let telemetry = |c: MavCmd| matches!(c, MavCmd::SET_MESSAGE_INTERVAL | MavCmd::REQUEST_MESSAGE);
    match view {
        MessageView::RequestDataStream(_) => true,
        MessageView::CommandLong(c) => telemetry(c.command()),
        MessageView::CommandInt(c) => telemetry(c.command()),
        _ => false,
    }
}

/// The default silence of an autonomy: it streams its control (gated
/// until the companion holds it) at 20 Hz or so, so half a second without
/// a frame means it is not flying.
pub const AUTONOMY_SILENCE: Duration = Duration::from_millis(500);

/// Throttle of the wings-level fallback (µs).
const FALLBACK_THROTTLE: u16 = 1500;

/// The companion's node: the [`CcEngine`] and the policy of its links
/// (see the [module docs](super)).
///
/// ```
/// use fbwag_delegation::cc::CcConfig;
/// use fbwag_delegation::node::{Answers, Arrival, CompanionNode, ControlSource, DropReason};
/// use fbwag_delegation::node::{LinkSpec, Role};
/// use fbwag_delegation::Moment;
/// use fbwag_dialect::dialects::minimal::Heartbeat;
/// use fbwag_dialect::mavframe::frame::MAX_FRAME_LEN;
/// use fbwag_dialect::{encode, Frame, Header, Version};
///
/// let cfg = CcConfig::default(); // the FC is 1/1, the companion 1/191
/// let mut node = CompanionNode::new(cfg, ControlSource::Builtin, Moment::ZERO)?;
/// let (fc_link, ground_link) = (0, 1);
/// node.add_link(fc_link, LinkSpec::new(Role::Peer, Answers::Target))?;
/// node.add_link(ground_link, LinkSpec::new(Role::Ground, Answers::Chosen))?;
///
/// // The FC's HEARTBEAT, as its link's parser hands it over.
/// let mut buf = [0u8; MAX_FRAME_LEN];
/// let header = Header { seq: 0, sysid: 1, compid: 1 };
/// let len = encode(Version::V2, header, &Heartbeat::default(), None, &mut buf)?;
/// let frame = Frame::new_checked(&buf[..len])?;
///
/// // On the FC link: protocol input, and routed on to the ground station.
/// let fate = node.handle_frame(
///     Moment::ZERO,
///     Arrival { link: fc_link, source: None, frame, authenticated: false },
/// );
/// while let Some(_output) = node.poll_output() { /* send, answer, log */ }
/// assert!(fate.input && fate.route.contains(ground_link));
///
/// // The same ids from a ground link: someone posing as the FC.
/// let source = Some("192.168.1.20:14550".parse()?);
/// let fate = node.handle_frame(
///     Moment::ZERO,
///     Arrival { link: ground_link, source, frame, authenticated: false },
/// );
/// while let Some(_output) = node.poll_output() {}
/// assert_eq!(fate.dropped, Some(DropReason::Impersonation));
/// assert_eq!(node.drops().get(DropReason::Impersonation), 1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone)]
pub struct CompanionNode {
    engine: CcEngine,
    core: Core,
    cfg: CcConfig,
    source: ControlSource,
    /// When the autonomy last spoke.
    autonomy_heard: Option<Moment>,
    /// The autonomy is silent (or was never heard).
    silent: bool,
    out: Outbox<Output<CompanionEvent>, 24>,
}

/// What the companion's node reports besides transmissions and peers.
// Carried by value (no_std, no allocation), as the engine's outputs.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum CompanionEvent {
    /// The engine's event ([`CcOutput::Transmit`] never comes here).
    Engine(CcOutput),
    /// The autonomy fell silent (`true`: takeovers are declined, or the
    /// wings-level fallback flies) or speaks again.
    AutonomySilent(bool),
}

impl CompanionNode {
    /// A node whose engine starts at `now`, with no links yet.
    pub fn new(cfg: CcConfig, source: ControlSource, now: Moment) -> Result<Self, NodeError> {
        Ok(CompanionNode {
            engine: CcEngine::new(cfg, now)?,
            core: Core::new(cfg.require_signed),
            cfg,
            source,
            autonomy_heard: None,
            silent: false,
            out: Outbox::new(),
        }
        .with_readiness(now))
    }

    /// Starts with the autonomy silent: it has not spoken yet.
    fn with_readiness(mut self, now: Moment) -> Self {
        self.update_readiness(now);
        self
    }

    /// Adds link `link`.
    pub fn add_link(&mut self, link: LinkId, spec: LinkSpec) -> Result<(), NodeError> {
        self.core.add(link, spec)
    }

    /// Sets the filter of link `link` in `direction` (every link starts
    /// with [`Filter::ALL`] both ways). Filters narrow routing only: the
    /// engine takes its inputs from the FC link, and control from the
    /// autonomy, before any filter is asked, and the node's own messages
    /// (the protocol's, control to the FC) are never filtered.
    pub fn set_filter(
        &mut self,
        link: LinkId,
        direction: Direction,
        filter: Filter,
    ) -> Result<(), NodeError> {
        self.core.set_filter(link, direction, filter)
    }

    /// Drops a copy of a routed frame that went on less than `window`
    /// before, from any link (`None` or zero: off, the default); the
    /// engine still sees every frame of the FC link.
    pub fn set_dedup(&mut self, window: Option<Duration>) {
        self.core.set_dedup(window);
    }

    /// The engine (read only).
    pub fn engine(&self) -> &CcEngine {
        &self.engine
    }

    /// Frames dropped, by reason.
    pub fn drops(&self) -> &super::Drops {
        &self.core.drops
    }

    /// Feeds `d` everything that decides what the node does next: the
    /// engine's, the links', the autonomy's (see [`crate::digest`]);
    /// counters are left out.
    pub fn digest(&self, d: &mut impl Digest) {
        let CompanionNode {
            engine,
            core,
            cfg,
            source,
            autonomy_heard,
            silent,
            out,
        } = self;
        engine.digest(d);
        core.digest(d);
        (cfg, source, silent).hash(d);
        let silence = match source {
            ControlSource::Autonomy { silence, .. } => *silence,
            ControlSource::Builtin => Duration::ZERO,
        };
        digest::option(d, *autonomy_heard, |d, t| d.instant_within(t, silence));
        out.len().hash(d);
    }

    /// A link was opened again: whom it answered is forgotten.
    pub fn link_reopened(&mut self, link: LinkId) {
        self.core.reopened(link);
    }

    /// When [`handle_timeout`](Self::handle_timeout) must next run.
    pub fn poll_timeout(&self) -> Option<Moment> {
        [self.engine.poll_timeout(), self.silence_deadline()]
            .into_iter()
            .flatten()
            .min()
    }

    /// Timers due at `now`.
    pub fn handle_timeout(&mut self, now: Moment) {
        self.update_readiness(now);
        self.engine.handle_timeout(now);
        self.drain_engine(now);
    }

    /// Control from a built-in controller ([`ControlSource::Builtin`]).
    pub fn submit_control(&mut self, now: Moment, control: Control) -> ControlVerdict {
        let verdict = self.engine.submit_control(now, control);
        self.drain_engine(now);
        verdict
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<Output<CompanionEvent>> {
        self.out.pop()
    }

    /// Link `link`'s parser refused a frame of `sender` from `source` for
    /// its signature: on the listening FC link, while it answers no FC,
    /// a source claiming the FC's ids gets the companion's signed
    /// heartbeat, once a second at most, so that an FC with another key
    /// sees the mismatch too.
    pub fn handle_bad_signature(
        &mut self,
        now: Moment,
        link: LinkId,
        source: core::net::SocketAddr,
        sender: Peer,
    ) {
        if sender == self.cfg.fc && self.core.signature_beacon(link, source, now) {
            let message = Message::Heartbeat(wire::cc_heartbeat());
            self.out.push(Output::TransmitTo {
                link,
                to: source,
                message,
            });
        }
    }

    /// A frame link `a.link` delivered at `now`: its fate.
    pub fn handle_frame(&mut self, now: Moment, a: Arrival) -> Fate {
        let Some(spec) = self.core.spec(a.link) else {
            return Fate::default();
        };
        // A silence that began before this frame counts for it, timer run
        // or not: a notice then is declined, not taken over.
        self.update_readiness(now);
        let fate = if sender(&a.frame) == self.cfg.own {
            self.core.drop(DropReason::OwnIds)
        } else {
            match spec.role {
                Role::Peer => self.on_fc_link(now, &a),
                Role::Ground => self.on_ground_link(now, &a, spec),
                Role::Autonomy => self.on_autonomy_link(now, &a),
            }
        };
        self.update_readiness(now);
        self.drain_engine(now);
        fate
    }

    /// A frame of the FC link. The engine sees every frame from the
    /// link's peer (it counts what it does not trust); only the FC's
    /// trusted frames act, and may make their source the peer.
    fn on_fc_link(&mut self, now: Moment, a: &Arrival) -> Fate {
        let from = sender(&a.frame);
        let heartbeat = || Message::Heartbeat(wire::cc_heartbeat());
        if let Err(dropped) = self
            .core
            .peer_source(a, now, self.cfg.fc, &mut self.out, heartbeat)
        {
            return dropped;
        }
        let verdict = self.engine.handle_frame(now, &a.frame, a.authenticated);
        if from == self.cfg.fc && verdict == Verdict::Untrusted {
            return self.core.drop(DropReason::Unauthenticated);
        }
        let input = verdict == Verdict::Trusted;
        // Filters and duplicates decide only whether the frame also goes
        // on: an input the engine took is no drop.
        if let Some(reason) = self.core.screen(a, now) {
            return if input {
                Fate {
                    input,
                    ..Fate::default()
                }
            } else {
                self.core.drop(reason)
            };
        }
        let mut fate = self.routed(a, a.authenticated);
        fate.input = input;
        fate
    }

    /// A frame of a ground-station link. A trusted link's frames count as
    /// verified (those of ids the dialect knows: the others cannot be
    /// signed on the way).
    fn on_ground_link(&mut self, now: Moment, a: &Arrival, spec: LinkSpec) -> Fate {
        let from = sender(&a.frame);
        if from == self.cfg.fc {
            return self.core.drop(DropReason::Impersonation);
        }
        let sign = spec.trusted && !a.authenticated && super::known(&a.frame);
        let verified = a.authenticated || sign;
        let out = &mut self.out;
        let known = self
            .core
            .admits_source(a, now, true, verified, &mut |link, peers| {
                out.push(Output::Peers { link, peers })
            });
        if !known && matches!(spec.answers, super::Answers::Fixed(_)) {
            return self.core.drop(DropReason::NotPeer);
        }
        // Who flies is decided on the ground: the key is lent to the
        // trusted link's tool for everything else.
        if sign
            && MessageView::new(a.frame.msg_id(), a.frame.payload())
                .is_some_and(|view| crate::protected::protected(&view).is_some())
        {
            return self.core.drop(DropReason::Protected);
        }
        if let Some(reason) = self.core.screen(a, now) {
            return self.core.drop(reason);
        }
        let mut fate = self.routed(a, verified);
        fate.sign = sign && !fate.route.is_empty();
        fate
    }

    /// A frame of the autonomy's link.
    fn on_autonomy_link(&mut self, now: Moment, a: &Arrival) -> Fate {
        let out = &mut self.out;
        let admitted = self
            .core
            .admits_source(a, now, true, false, &mut |link, peers| {
                out.push(Output::Peers { link, peers })
            });
        if !admitted {
            return self.core.drop(DropReason::NotPeer);
        }
        let from = sender(&a.frame);
        if from == self.cfg.fc {
            return self.core.drop(DropReason::Impersonation);
        }
        self.autonomy_heard = Some(now);
        let view = MessageView::new(a.frame.msg_id(), a.frame.payload());
        let Some(control) = view.as_ref().and_then(Control::from_view) else {
            if let Some(reason) = self.core.screen(a, now) {
                return self.core.drop(reason);
            }
            // Telemetry rates for the FC, signed on; the rest stays on the
            // ground side.
            if view.as_ref().is_some_and(asks_for_telemetry) {
                let to = self.core.route(a, true, self.core.of(Role::Peer));
                return Fate {
                    sign: !to.is_empty(),
                    ..Fate::routed(to)
                };
            }
            let to = self.core.route(a, true, self.core.of(Role::Ground));
            return Fate::routed(to);
        };
        match self.engine.submit_control(now, control) {
            ControlVerdict::Forwarded => Fate {
                input: true,
                ..Fate::default()
            },
            ControlVerdict::NotInControl => self.core.drop(DropReason::Gated),
        }
    }

    /// Routes a frame of the FC link or a ground link (`verified`: its
    /// signature, or its link's trust): unverified, where signing is
    /// required, only to ground links. Routes learned from the FC link or
    /// from verified frames outrank strangers'.
    fn routed(&mut self, a: &Arrival, verified: bool) -> Fate {
        let fc_link = self.core.spec(a.link).is_some_and(|s| s.role == Role::Peer);
        let full = self.core.route(a, verified || fc_link, self.core.all());
        if verified || !self.cfg.require_signed {
            return Fate::routed(full);
        }
        let to = full.intersection(self.core.of(Role::Ground));
        if to.is_empty() && !full.is_empty() {
            return self.core.drop(DropReason::Unauthenticated);
        }
        Fate::routed(to)
    }

    /// When the autonomy falls silent, while it speaks.
    fn silence_deadline(&self) -> Option<Moment> {
        match self.source {
            ControlSource::Autonomy { silence, .. } if !self.silent => {
                self.autonomy_heard.map(|t| t + silence)
            }
            _ => None,
        }
    }

    /// Follows the autonomy's silence at `now`: declining takeovers while
    /// it is silent, or flying the fallback then.
    fn update_readiness(&mut self, now: Moment) {
        let ControlSource::Autonomy {
            fallback, silence, ..
        } = self.source
        else {
            return;
        };
        let silent = self.autonomy_heard.is_none_or(|t| now >= t + silence);
        if silent == self.silent {
            return;
        }
        self.silent = silent;
        if fallback == AutonomyFallback::Decline {
            self.engine.set_control_ready(!silent);
        }
        self.out
            .push(Output::Event(CompanionEvent::AutonomySilent(silent)));
    }

    /// Carries the engine's outputs out: its messages on their links
    /// (addressed ones to the FC, broadcasts everywhere), control due to the
    /// fallback or the program, events to the program. Until the FC is
    /// heard, broadcasts (the heartbeat) go to the FC link only: a ground
    /// tool that takes the first component it hears for the vehicle
    /// (mavsdk_server 3.x waits for ever once it heard a companion first)
    /// hears the FC's heartbeat, routed, before the companion's.
    fn drain_engine(&mut self, now: Moment) {
        while let Some(output) = self.engine.poll_output() {
            match output {
                CcOutput::Transmit(message) => {
                    let targeted = message.meta().target_system_offset.is_some();
                    let fc_heard = self.engine.state() != CcState::Idle;
                    let links = if targeted || !fc_heard {
                        self.core.of(Role::Peer)
                    } else {
                        self.core.all()
                    };
                    self.out.push(Output::Transmit { links, message });
                }
                CcOutput::ControlDue => self.control_due(now),
                event => self.out.push(Output::Event(CompanionEvent::Engine(event))),
            }
        }
    }

    fn control_due(&mut self, now: Moment) {
        match self.source {
            ControlSource::Builtin => self
                .out
                .push(Output::Event(CompanionEvent::Engine(CcOutput::ControlDue))),
            ControlSource::Autonomy {
                fallback: AutonomyFallback::WingsLevel,
                ..
            } if self.silent => {
                let control = WingsLevel {
                    throttle: FALLBACK_THROTTLE,
                }
                .control(now, self.cfg.fc);
                let _ = self.engine.submit_control(now, control);
            }
            // The autonomy keeps its own pace.
            ControlSource::Autonomy { .. } => {}
        }
    }
}
