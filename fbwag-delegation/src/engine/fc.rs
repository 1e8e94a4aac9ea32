//! The flight controller's engine.

use super::{earliest, next_tick, origin, Verdict};
use crate::control::Control;
use crate::digest::Digest;
use crate::fc::{Authority, FcAction, FcConfig, FcInput, FlightController};
use crate::outbox::Outbox;
use crate::{wire, ConfigError, Moment, Origin, Trust};
use core::hash::Hash;
use fbwag_dialect::{Frame, Message, MessageView};

/// What the FC must do.
// No allocation (no_std): a message to send is carried by value, and
// outputs queue in a fixed buffer of the engine.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum FcOutput {
    /// Send this message with the FC's ids, on every channel.
    Transmit(Message),
    /// Fly in the mode of this authority (see [`crate::wire::custom_mode`]).
    SetMode(Authority),
    /// Apply this control now: it came from the trusted companion, addressed
    /// to this FC, in companion control.
    ApplyControl {
        /// The sender, as received.
        from: Origin,
        /// The control message, whole.
        control: Control,
    },
    /// Companion control has ended: drop every override applied so far,
    /// now (the pilot or the FC's own mode flies).
    ReleaseControl,
}

/// Counters of the engine, for logs and tests. They saturate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct FcEngineStats {
    /// Frames from the trusted companion.
    pub trusted_frames: u64,
    /// Frames from anyone else, or unsigned where signing is required.
    pub untrusted_frames: u64,
    /// FBWAG_NOTICEs among the untrusted frames (spoofed takeovers).
    pub untrusted_notices: u64,
    /// Control messages applied.
    pub controls_applied: u64,
    /// Control messages from an untrusted sender: never applied.
    pub controls_untrusted: u64,
    /// Control messages of the trusted companion addressed to another
    /// system or component.
    pub controls_misaddressed: u64,
    /// Control messages of the trusted companion outside companion control.
    pub controls_outside_companion: u64,
}

impl FcEngineStats {
    /// These counters and `other`'s added up (saturating).
    pub fn plus(&self, other: &FcEngineStats) -> FcEngineStats {
        let add = |a: u64, b: u64| a.saturating_add(b);
        FcEngineStats {
            trusted_frames: add(self.trusted_frames, other.trusted_frames),
            untrusted_frames: add(self.untrusted_frames, other.untrusted_frames),
            untrusted_notices: add(self.untrusted_notices, other.untrusted_notices),
            controls_applied: add(self.controls_applied, other.controls_applied),
            controls_untrusted: add(self.controls_untrusted, other.controls_untrusted),
            controls_misaddressed: add(self.controls_misaddressed, other.controls_misaddressed),
            controls_outside_companion: add(
                self.controls_outside_companion,
                other.controls_outside_companion,
            ),
        }
    }
}

/// The flight controller's side of the protocol on the wire: receiver
/// sampling, the FC state machine, its heartbeats and notices, and the
/// control it applies. See the [module docs](super) for what it decides.
///
/// ```
/// use fbwag_delegation::engine::{FcEngine, FcOutput};
/// use fbwag_delegation::fc::{Authority, FcConfig};
/// use fbwag_delegation::Moment;
///
/// let mut fc = FcEngine::new(FcConfig::default(), Moment::ZERO)?;
/// fc.set_receiver_ok(false); // the pilot's radio link is gone
/// let mut t = Moment::ZERO;
/// let mut modes = Vec::new();
/// while t < Moment::from_millis(500) {
///     fc.handle_timeout(t);
///     while let Some(out) = fc.poll_output() {
///         match out {
///             FcOutput::Transmit(msg) => { /* encode and send `msg` */ }
///             FcOutput::SetMode(a) => modes.push(a),
///             _ => {}
///         }
///     }
///     t = fc.poll_timeout().unwrap();
/// }
/// // Two bad samples at 10 Hz: the FC asks the companion to take over.
/// assert_eq!(modes, [Authority::Handshake]);
/// # Ok::<(), fbwag_delegation::ConfigError>(())
/// ```
#[derive(Debug, Clone)]
pub struct FcEngine {
    machine: FlightController,
    trust: Trust,
    receiver_ok: bool,
    /// Overrides are applied (the machine's `AcceptOverrides`).
    accepting: bool,
    next_sample: Moment,
    next_heartbeat: Moment,
    out: Outbox<FcOutput, 16>,
    stats: FcEngineStats,
}

impl FcEngine {
    /// An engine with the pilot in control and a healthy receiver; its
    /// timers start at `now` (first receiver sample and heartbeat).
    pub fn new(cfg: FcConfig, now: Moment) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(FcEngine {
            machine: FlightController::new(cfg),
            trust: Trust {
                peer: cfg.companion,
                require_signed: cfg.require_signed,
            },
            receiver_ok: true,
            accepting: false,
            next_sample: now,
            next_heartbeat: now,
            out: Outbox::new(),
            stats: FcEngineStats::default(),
        })
    }

    /// The state machine (read only).
    pub fn machine(&self) -> &FlightController {
        &self.machine
    }

    /// Who flies now.
    pub fn authority(&self) -> Authority {
        self.machine.authority()
    }

    /// Counters.
    pub fn stats(&self) -> &FcEngineStats {
        &self.stats
    }

    /// Feeds `d` everything that decides what the engine does next (see
    /// [`crate::digest`]); its counters are left out.
    pub fn digest(&self, d: &mut impl Digest) {
        let FcEngine {
            machine,
            trust,
            receiver_ok,
            accepting,
            next_sample,
            next_heartbeat,
            out,
            stats: _,
        } = self;
        machine.digest(d);
        (trust, receiver_ok, accepting).hash(d);
        d.instant(*next_sample);
        d.instant(*next_heartbeat);
        out.len().hash(d);
    }

    /// The real receiver's state from now on (not RC overrides: those
    /// count as RC in ArduPlane and would end the failsafe). Sampled at
    /// [`FcConfig::rc_sample_period`].
    pub fn set_receiver_ok(&mut self, ok: bool) {
        self.receiver_ok = ok;
    }

    /// The next output, if any.
    #[must_use]
    pub fn poll_output(&mut self) -> Option<FcOutput> {
        self.out.pop()
    }

    /// When [`handle_timeout`](Self::handle_timeout) must next be called.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Moment> {
        earliest([
            Some(self.next_sample),
            Some(self.next_heartbeat),
            self.machine.poll_timeout(),
        ])
    }

    /// Timers due at `now`: receiver sampling, the machine's retries and
    /// time-outs, heartbeats.
    pub fn handle_timeout(&mut self, now: Moment) {
        let cfg = *self.machine.config();
        if now >= self.next_sample {
            self.next_sample = next_tick(self.next_sample, cfg.rc_sample_period, now);
            let receiver_ok = self.receiver_ok;
            self.machine
                .handle_input(now, FcInput::RcSample { receiver_ok });
            self.drain_machine(now);
        }
        if self.machine.poll_timeout().is_some_and(|t| now >= t) {
            self.machine.handle_timeout(now);
            self.drain_machine(now);
        }
        if now >= self.next_heartbeat {
            let authority = self.machine.authority();
            let period = if authority == Authority::Companion {
                cfg.companion_heartbeat_period
            } else {
                cfg.heartbeat_period
            };
            self.next_heartbeat = next_tick(self.next_heartbeat, period, now);
            self.transmit(Message::Heartbeat(wire::fc_heartbeat(authority)));
        }
    }

    /// A frame the parser accepted at `now`, with whether its signature
    /// verified. Only the trusted companion's frames act on the protocol.
    pub fn handle_frame(
        &mut self,
        now: Moment,
        frame: &Frame<&[u8]>,
        authenticated: bool,
    ) -> Verdict {
        let from = origin(frame, authenticated);
        let trusted = self.trust.admits(from);
        let verdict = if trusted {
            bump(&mut self.stats.trusted_frames);
            Verdict::Trusted
        } else {
            bump(&mut self.stats.untrusted_frames);
            Verdict::Untrusted
        };
        let Some(view) = MessageView::new(frame.msg_id(), frame.payload()) else {
            return verdict;
        };
        if let Some(control) = Control::from_view(&view) {
            self.control(now, from, trusted, control);
            return verdict;
        }
        match view {
            MessageView::FbwagNotice(n) if trusted => {
                let input = FcInput::Notice {
                    status: n.failsafe_status(),
                    timestamp: n.timestamp(),
                };
                self.machine.handle_input(now, input);
            }
            MessageView::FbwagNotice(_) => bump(&mut self.stats.untrusted_notices),
            MessageView::Heartbeat(_) if trusted => {
                self.machine.handle_input(now, FcInput::Heartbeat)
            }
            _ => {}
        }
        self.drain_machine(now);
        verdict
    }

    fn control(&mut self, now: Moment, from: Origin, trusted: bool, control: Control) {
        if !trusted {
            bump(&mut self.stats.controls_untrusted);
            return;
        }
        if !control.addresses(self.machine.config().own) {
            bump(&mut self.stats.controls_misaddressed);
            return;
        }
        self.machine.handle_input(now, FcInput::Control);
        self.drain_machine(now);
        if self.accepting {
            bump(&mut self.stats.controls_applied);
            self.out.push(FcOutput::ApplyControl { from, control });
        } else {
            bump(&mut self.stats.controls_outside_companion);
        }
    }

    /// Turns the machine's actions into outputs.
    fn drain_machine(&mut self, now: Moment) {
        let own = self.machine.config().own;
        while let Some(action) = self.machine.poll_action() {
            match action {
                FcAction::SendNotice { status, timestamp } => {
                    self.transmit(Message::FbwagNotice(wire::notice(own, status, timestamp)))
                }
                FcAction::ConfirmTakeover { event } => {
                    let companion = self.machine.config().companion;
                    self.transmit(Message::Statustext(wire::takeover_text(companion, event)))
                }
                FcAction::ConfirmHandBack { event } => self.transmit(Message::Statustext(
                    wire::status_text(crate::TEXT_RC_TOOK_OVER, event),
                )),
                FcAction::SetAuthority(a) => {
                    self.out.push(FcOutput::SetMode(a));
                    // Say the new mode at once: the companion stops or is
                    // confirmed without waiting for the next heartbeat.
                    self.next_heartbeat = self.next_heartbeat.min(now);
                }
                FcAction::AcceptOverrides(on) => {
                    self.accepting = on;
                    if !on {
                        self.out.push(FcOutput::ReleaseControl);
                    }
                }
            }
        }
    }

    fn transmit(&mut self, message: Message) {
        self.out.push(FcOutput::Transmit(message));
    }
}

/// A saturating counter step.
pub(super) fn bump(counter: &mut u64) {
    *counter = counter.saturating_add(1);
}
