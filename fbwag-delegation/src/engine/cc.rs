//! The companion computer's engine.

use super::fc::bump;
use super::{earliest, next_tick, origin, Verdict};
use crate::cc::{CcAction, CcConfig, CcInput, CcState, Companion};
use crate::control::Control;
use crate::digest::Digest;
use crate::outbox::Outbox;
use crate::{mode, wire, ConfigError, Moment, Trust};
use core::hash::Hash;
use fbwag_dialect::{Frame, Message, MessageView};

/// What the companion must do or know.
// No allocation (no_std): a message to send is carried by value, and
// outputs queue in a fixed buffer of the engine.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum CcOutput {
    /// Send this message with the companion's ids to the FC.
    Transmit(Message),
    /// Control is due: a built-in controller submits one control now with
    /// [`CcEngine::submit_control`] (every control period while the
    /// companion controls). An external autonomy keeps its own pace and can
    /// ignore this.
    ControlDue,
    /// The companion took over for this FC event: control from now on is
    /// forwarded.
    ControlStarted {
        /// The FC's event id.
        event: u32,
    },
    /// Control has ended (hand-back, fallback, or the FC went silent):
    /// control is dropped from now on.
    ControlStopped,
    /// The FC was heard (first time, or again after [`CcOutput::FcLost`]).
    FcFound,
    /// The FC has been silent for its timeout.
    ///
    /// ```
    /// use fbwag_delegation::cc::CcConfig;
    /// use fbwag_delegation::engine::{CcEngine, CcOutput};
    /// use fbwag_delegation::{wire, Moment, Peer};
    /// use fbwag_delegation::fc::Authority;
    /// use fbwag_dialect::{encode, Frame, Header, Message, Version};
    ///
    /// let mut cc = CcEngine::new(CcConfig::default(), Moment::ZERO)?;
    /// // One FC heartbeat at 1 s, then silence.
    /// let hb = Message::Heartbeat(wire::fc_heartbeat(Authority::Pilot));
    /// let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    /// let h = Header { seq: 0, sysid: 1, compid: 1 };
    /// let n = encode(Version::V2, h, &hb, None, &mut buf).unwrap();
    /// let frame = Frame::new_checked(&buf[..n]).unwrap();
    /// let authenticated = false; // an unsigned frame (no link key)
    /// let _ = cc.handle_frame(Moment::from_millis(1000), &frame, authenticated);
    /// let mut events = Vec::new();
    /// while let Some(t) = cc.poll_timeout().filter(|t| *t <= Moment::from_millis(5000)) {
    ///     cc.handle_timeout(t);
    ///     while let Some(out) = cc.poll_output() { events.push(out) }
    /// }
    /// while let Some(out) = cc.poll_output() { events.push(out) }
    /// assert!(events.contains(&CcOutput::FcLost), "3 s after its last frame");
    /// # Ok::<(), fbwag_delegation::ConfigError>(())
    /// ```
    FcLost,
    /// The companion declined the takeover of this FC event, or gave it
    /// back, because its control source is silent (see
    /// [`CcEngine::set_control_ready`]): the FC falls back at once.
    Declined {
        /// The FC's event.
        event: u32,
    },
    /// The FC rebooted (its event ids restarted); its old events are
    /// forgotten, and the companion answers the new boot's notices.
    FcRebooted,
    /// The FC confirmed the takeover of this event to another companion:
    /// this one stopped at once ([`CcOutput::ControlStopped`] comes
    /// before).
    Superseded {
        /// The FC's event.
        event: u32,
        /// Whom the FC accepted.
        by: crate::Peer,
    },
}

/// What became of a control message submitted to the engine.
#[must_use]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlVerdict {
    /// Sent to the FC (a [`CcOutput::Transmit`] follows).
    Forwarded,
    /// Dropped: the companion does not hold control.
    NotInControl,
}

/// Counters of the engine, for logs and tests. They saturate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct CcEngineStats {
    /// Frames from the trusted FC.
    pub trusted_frames: u64,
    /// Frames from anyone else, or unsigned where signing is required.
    pub untrusted_frames: u64,
    /// FBWAG_NOTICEs among the untrusted frames (spoofed or replayed).
    pub untrusted_notices: u64,
    /// Control messages forwarded to the FC.
    pub controls_forwarded: u64,
    /// Control messages dropped because the companion did not hold control.
    pub controls_dropped: u64,
}

/// The companion's side of the protocol on the wire: the companion state
/// machine, its heartbeat, FC liveness and reboots, and the gate on control.
/// See the [module docs](super) for what it decides.
///
/// ```
/// use fbwag_delegation::control::{Controller, WingsLevel};
/// use fbwag_delegation::engine::{CcEngine, CcOutput};
/// use fbwag_delegation::cc::CcConfig;
/// use fbwag_delegation::Moment;
///
/// let cfg = CcConfig::default();
/// let mut cc = CcEngine::new(cfg, Moment::ZERO)?;
/// // Outside companion control, control goes nowhere.
/// let now = Moment::from_millis(10);
/// let verdict = cc.submit_control(now, WingsLevel { throttle: 1600 }.control(now, cfg.fc));
/// assert_eq!(verdict, fbwag_delegation::engine::ControlVerdict::NotInControl);
/// // Its timer sends the companion's 1 Hz HEARTBEAT.
/// cc.handle_timeout(Moment::ZERO);
/// assert!(matches!(cc.poll_output(), Some(CcOutput::Transmit(_))));
/// # Ok::<(), fbwag_delegation::ConfigError>(())
/// ```
#[derive(Debug, Clone)]
pub struct CcEngine {
    machine: Companion,
    trust: Trust,
    next_heartbeat: Moment,
    out: Outbox<CcOutput, 16>,
    stats: CcEngineStats,
}

impl CcEngine {
    /// An engine that has not heard the FC yet; its heartbeat timer starts
    /// at `now`.
    pub fn new(cfg: CcConfig, now: Moment) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(CcEngine {
            machine: Companion::new(cfg),
            trust: Trust {
                peer: cfg.fc,
                require_signed: cfg.require_signed,
            },
            next_heartbeat: now,
            out: Outbox::new(),
            stats: CcEngineStats::default(),
        })
    }

    /// The state machine (read only).
    pub fn machine(&self) -> &Companion {
        &self.machine
    }

    /// Where the companion stands.
    pub fn state(&self) -> CcState {
        self.machine.state()
    }

    /// Counters.
    pub fn stats(&self) -> &CcEngineStats {
        &self.stats
    }

    /// Feeds `d` everything that decides what the engine does next (see
    /// [`crate::digest`]); its counters are left out.
    pub fn digest(&self, d: &mut impl Digest) {
        let CcEngine {
            machine,
            trust,
            next_heartbeat,
            out,
            stats: _,
        } = self;
        machine.digest(d);
        trust.hash(d);
        d.instant(*next_heartbeat);
        out.len().hash(d);
    }

    /// The next output, if any.
    #[must_use]
    pub fn poll_output(&mut self) -> Option<CcOutput> {
        self.out.pop()
    }

    /// When [`handle_timeout`](Self::handle_timeout) must next be called.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Moment> {
        earliest([Some(self.next_heartbeat), self.machine.poll_timeout()])
    }

    /// Timers due at `now`: the machine's (control stream, repeated
    /// acknowledgements, time-outs) and the heartbeat.
    pub fn handle_timeout(&mut self, now: Moment) {
        if self.machine.poll_timeout().is_some_and(|t| now >= t) {
            self.with_machine(|m| m.handle_timeout(now));
        }
        if now >= self.next_heartbeat {
            let period = self.machine.config().heartbeat_period;
            self.next_heartbeat = next_tick(self.next_heartbeat, period, now);
            self.out
                .push(CcOutput::Transmit(Message::Heartbeat(wire::cc_heartbeat())));
        }
    }

    /// A frame the parser accepted at `now`, with whether its signature
    /// verified. Only the trusted FC's frames act on the protocol; every
    /// one of them also proves it is alive.
    pub fn handle_frame(
        &mut self,
        now: Moment,
        frame: &Frame<&[u8]>,
        authenticated: bool,
    ) -> Verdict {
        let from = origin(frame, authenticated);
        let view = MessageView::new(frame.msg_id(), frame.payload());
        if !self.trust.admits(from) {
            bump(&mut self.stats.untrusted_frames);
            if matches!(view, Some(MessageView::FbwagNotice(_))) {
                bump(&mut self.stats.untrusted_notices);
            }
            return Verdict::Untrusted;
        }
        bump(&mut self.stats.trusted_frames);
        let input = match view {
            Some(MessageView::Heartbeat(h)) => CcInput::Heartbeat {
                seq: from.seq,
                companion_control: h.custom_mode() == mode::FBWAG,
            },
            Some(MessageView::FbwagNotice(n)) => CcInput::Notice {
                status: n.failsafe_status(),
                timestamp: n.timestamp(),
            },
            Some(MessageView::Statustext(t)) => match wire::takeover_by(t.text().as_bytes()) {
                Some(by) => CcInput::TakeoverConfirmed {
                    seq: from.seq,
                    event: t.id(),
                    by,
                },
                None => CcInput::FcAlive,
            },
            _ => CcInput::FcAlive,
        };
        self.with_machine(|m| m.handle_input(now, input));
        Verdict::Trusted
    }

    /// Whether the control source can fly now: a built-in controller always
    /// can; an external autonomy only while it speaks. While it cannot, the
    /// companion declines takeovers, and gives back an episode it holds
    /// ([`CcOutput::Declined`]), so the FC never sits in companion control
    /// without control.
    pub fn set_control_ready(&mut self, ready: bool) {
        self.with_machine(|m| m.set_control_ready(ready));
    }

    /// Control from the companion's controller or autonomy: forwarded to the
    /// FC (re-addressed to it) only while the companion holds control
    /// (from its acknowledgement until the FC ends the episode); dropped and
    /// counted otherwise. The FC applies it only in companion control.
    pub fn submit_control(&mut self, _now: Moment, control: Control) -> ControlVerdict {
        if self.machine.state() != CcState::Controlling {
            bump(&mut self.stats.controls_dropped);
            return ControlVerdict::NotInControl;
        }
        bump(&mut self.stats.controls_forwarded);
        let message = control.addressed_to(self.machine.config().fc).to_message();
        self.out.push(CcOutput::Transmit(message));
        ControlVerdict::Forwarded
    }

    /// Runs `step` on the machine, then turns its actions and any change of
    /// FC liveness into outputs.
    fn with_machine(&mut self, step: impl FnOnce(&mut Companion)) {
        let before = self.machine.state();
        step(&mut self.machine);
        let after = self.machine.state();
        if before == CcState::Idle && after != CcState::Idle {
            self.out.push(CcOutput::FcFound);
        }
        let fc = self.machine.config().fc;
        while let Some(action) = self.machine.poll_action() {
            let output = match action {
                CcAction::SendNotice { status, timestamp } => {
                    CcOutput::Transmit(Message::FbwagNotice(wire::notice(fc, status, timestamp)))
                }
                CcAction::SendControl => CcOutput::ControlDue,
                CcAction::StartControl => CcOutput::ControlStarted {
                    event: self.machine.event().unwrap_or_default(),
                },
                CcAction::StopControl => CcOutput::ControlStopped,
                CcAction::FcRebooted => CcOutput::FcRebooted,
                CcAction::Declined { event } => CcOutput::Declined { event },
                CcAction::Superseded { event, by } => CcOutput::Superseded { event, by },
            };
            self.out.push(output);
        }
        if before != CcState::Idle && after == CcState::Idle {
            self.out.push(CcOutput::FcLost);
        }
    }
}
