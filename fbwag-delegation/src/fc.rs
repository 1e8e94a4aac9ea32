//! The flight controller's side: detect RC loss, delegate to the companion
//! with an acknowledged, bounded handshake, fall back to RTL, hand back to
//! the pilot. See `docs/delegation.md` for the specification.
//!
//! The FC tracks the real receiver (fed as [`FcInput::RcSample`]), never RC
//! overrides: in ArduPlane an override counts as valid RC and would end the
//! failsafe. Overrides are accepted only in companion control
//! ([`FcAction::AcceptOverrides`]), so a companion that still believes it
//! controls the aircraft cannot move a surface once the FC has given control
//! elsewhere.
//!
//! The machine's inputs are protocol events from the configured companion,
//! already judged trustworthy: [`crate::engine::FcEngine`] decides that (ids
//! and signature), turns frames into inputs and actions into frames. Embed
//! the engine, not the bare machine, unless you apply the same trust rules.

use crate::digest::{self, Digest};
use crate::outbox::Outbox;
use crate::{ConfigError, Moment, Peer, Status};
use core::hash::Hash;
use core::time::Duration;

/// Who flies the aircraft, as the FC decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Authority {
    /// The pilot, through the RC receiver.
    Pilot,
    /// The FC itself, flying its short failsafe (CIRCLE) while it asks the
    /// companion to take over.
    Handshake,
    /// The companion computer, through RC overrides (mode FBWAG).
    Companion,
    /// Return to launch: the fallback.
    Rtl,
}

/// Settings; [`FcConfig::default`] holds the paper's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FcConfig {
    /// This FC's ids (the notices' `system_id`/`component_id`).
    pub own: Peer,
    /// The companion allowed to take over.
    pub companion: Peer,
    /// Accept the companion's messages only when their signature verified.
    pub require_signed: bool,
    /// Consecutive bad receiver samples that make an RC loss (the paper: 2).
    pub rc_loss_samples: u8,
    /// Consecutive good receiver samples that make RC return.
    pub rc_regain_samples: u8,
    /// Time between notices of one event (the paper: about 1 s).
    pub retry_interval: Duration,
    /// Notices repeated after the first (the paper: 3).
    pub max_retries: u8,
    /// From the first notice to RTL without an acknowledgement (about 5 s).
    pub handshake_timeout: Duration,
    /// Companion control ends (RTL) when no RC override has come for this
    /// long; below ArduPlane's RC_OVERRIDE_TIME (3 s), after which
    /// overrides expire anyway.
    pub override_timeout: Duration,
    /// Companion control ends (RTL) when the companion has been silent (no
    /// HEARTBEAT, override or notice) for this long.
    pub heartbeat_timeout: Duration,
    /// How often the real receiver is sampled (ArduPlane's RC check: 10 Hz).
    pub rc_sample_period: Duration,
    /// HEARTBEAT period outside companion control.
    pub heartbeat_period: Duration,
    /// HEARTBEAT period in companion control: the confirmation stream that
    /// renews the companion's lease ([`crate::cc::CcConfig::control_lease`]).
    pub companion_heartbeat_period: Duration,
}

impl FcConfig {
    /// Checks the settings: every period and timeout positive, sample
    /// counts at least 1, the confirmation stream faster than the retry
    /// period (so the companion's belief can follow the FC's decision).
    pub fn validate(&self) -> Result<(), ConfigError> {
        let positive = [
            ("retry_interval", self.retry_interval),
            ("handshake_timeout", self.handshake_timeout),
            ("override_timeout", self.override_timeout),
            ("heartbeat_timeout", self.heartbeat_timeout),
            ("rc_sample_period", self.rc_sample_period),
            ("heartbeat_period", self.heartbeat_period),
            (
                "companion_heartbeat_period",
                self.companion_heartbeat_period,
            ),
        ];
        for (name, d) in positive {
            if d.is_zero() {
                return Err(ConfigError::Zero(name));
            }
        }
        if self.rc_loss_samples == 0 {
            return Err(ConfigError::Zero("rc_loss_samples"));
        }
        if self.rc_regain_samples == 0 {
            return Err(ConfigError::Zero("rc_regain_samples"));
        }
        if self.companion_heartbeat_period > self.retry_interval {
            return Err(ConfigError::Order(
                "companion_heartbeat_period",
                "retry_interval",
            ));
        }
        Ok(())
    }
}

impl Default for FcConfig {
    fn default() -> Self {
        FcConfig {
            own: Peer::new(1, 1),
            companion: Peer::new(1, 191),
            require_signed: false,
            rc_loss_samples: 2,
            rc_regain_samples: 2,
            retry_interval: Duration::from_secs(1),
            max_retries: 3,
            handshake_timeout: Duration::from_secs(5),
            override_timeout: Duration::from_secs(1),
            heartbeat_timeout: Duration::from_secs(3),
            rc_sample_period: Duration::from_millis(100),
            heartbeat_period: Duration::from_secs(1),
            companion_heartbeat_period: Duration::from_millis(200),
        }
    }
}

/// What the FC is told. Everything but the receiver sample comes from the
/// configured companion (the engine has checked the sender).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FcInput {
    /// One sample of the real receiver (not of overrides), at the RC check
    /// rate (10 Hz on ArduPlane).
    RcSample {
        /// The receiver delivers valid frames (no failsafe flag, not stale).
        receiver_ok: bool,
    },
    /// The companion's FBWAG_NOTICE.
    Notice {
        /// `failsafe_status`.
        status: Status,
        /// `timestamp`: the event it answers.
        timestamp: u32,
    },
    /// A control message of the companion (RC_CHANNELS_OVERRIDE,
    /// SET_ATTITUDE_TARGET or MANUAL_CONTROL addressed to this FC).
    Control,
    /// The companion's HEARTBEAT.
    Heartbeat,
}

/// What the FC must do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FcAction {
    /// Send FBWAG_NOTICE on every active channel (an event, never a stream).
    SendNotice {
        /// `failsafe_status`.
        status: Status,
        /// `timestamp`: the event id.
        timestamp: u32,
    },
    /// Tell the companion that it has control for `event` (on the wire: the
    /// paper's STATUSTEXT "FBWAG-ACK: CC has taken over!", its `id` the
    /// event's low 16 bits).
    ConfirmTakeover {
        /// The event confirmed.
        event: u32,
    },
    /// Tell the companion that its acknowledgement of the hand-back `event`
    /// arrived (STATUSTEXT "FBWAG-ACK: RC has taken over!").
    ConfirmHandBack {
        /// The event confirmed.
        event: u32,
    },
    /// Switch who flies (map to a flight mode: see [`crate::mode`]).
    SetAuthority(Authority),
    /// Apply (true) or discard and ignore (false) RC overrides.
    AcceptOverrides(bool),
}

/// Counters for logs and tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct FcStats {
    /// RC losses detected (events started).
    pub rc_losses: u32,
    /// Notices sent, all statuses.
    pub notices_sent: u32,
    /// Takeovers confirmed.
    pub takeovers: u32,
    /// RTL fallbacks.
    pub fallbacks: u32,
    /// Events the companion declined or gave back (status 0 for the
    /// current RC-loss event): each a fallback at once.
    pub declined: u32,
    /// Acknowledgements of another (older) event: ignored.
    pub stale_acks: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Pilot,
    Handshake {
        event: u32,
        started: Moment,
        /// Notices sent for the event: wider than `max_retries` so a limit
        /// of 255 cannot overflow it.
        sent: u16,
        next: Moment,
    },
    Companion {
        event: u32,
        last_control: Moment,
        last_heartbeat: Moment,
    },
    Rtl,
}

/// An announcement of status 0 awaiting the companion's acknowledgement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct HandBack {
    event: u32,
    sent: u16,
    next: Moment,
}

/// The flight controller's state machine.
///
/// Inputs are typed protocol events (the engine, [`crate::engine::FcEngine`],
/// makes them from trusted frames); actions say what to send and who flies.
///
/// ```
/// use fbwag_delegation::fc::{Authority, FcAction, FcConfig, FcInput, FlightController};
/// use fbwag_delegation::{Moment, Status};
///
/// let mut fc = FlightController::new(FcConfig::default());
/// // Two bad receiver samples at 10 Hz: RC is lost; the FC asks the
/// // companion, stamping the event with its milliseconds since boot.
/// fc.handle_input(Moment::from_millis(1000), FcInput::RcSample { receiver_ok: false });
/// fc.handle_input(Moment::from_millis(1100), FcInput::RcSample { receiver_ok: false });
/// let actions: Vec<_> = std::iter::from_fn(|| fc.poll_action()).collect();
/// assert_eq!(actions[1], FcAction::SendNotice { status: Status::RC_LOST, timestamp: 1100 });
/// // The companion acknowledges event 1100: companion control.
/// let ack = FcInput::Notice { status: Status::CC_TAKEOVER_CONFIRMED, timestamp: 1100 };
/// fc.handle_input(Moment::from_millis(1150), ack);
/// assert_eq!(fc.authority(), Authority::Companion);
/// ```
#[derive(Debug, Clone)]
pub struct FlightController {
    cfg: FcConfig,
    state: State,
    /// Debounced receiver state and the run of samples disagreeing with it.
    receiver_ok: bool,
    run: u8,
    /// The status last announced, to send none twice (the paper's no-flooding rule).
    announced: Status,
    handback: Option<HandBack>,
    last_event: Option<u32>,
    stats: FcStats,
    out: Outbox<FcAction, 8>,
}

impl FlightController {
    /// An FC with the pilot in control and a healthy receiver.
    pub fn new(cfg: FcConfig) -> Self {
        FlightController {
            cfg,
            state: State::Pilot,
            receiver_ok: true,
            run: 0,
            announced: Status::NORMAL,
            handback: None,
            last_event: None,
            stats: FcStats::default(),
            out: Outbox::new(),
        }
    }

    /// The settings.
    pub fn config(&self) -> &FcConfig {
        &self.cfg
    }

    /// Who flies now.
    pub fn authority(&self) -> Authority {
        match self.state {
            State::Pilot => Authority::Pilot,
            State::Handshake { .. } => Authority::Handshake,
            State::Companion { .. } => Authority::Companion,
            State::Rtl => Authority::Rtl,
        }
    }

    /// The debounced receiver state.
    pub fn receiver_ok(&self) -> bool {
        self.receiver_ok
    }

    /// Counters.
    pub fn stats(&self) -> &FcStats {
        &self.stats
    }

    /// Feeds `d` everything that decides what the machine does next (see
    /// [`crate::digest`]); its counters are left out.
    pub fn digest(&self, d: &mut impl Digest) {
        let FlightController {
            cfg,
            state,
            receiver_ok,
            run,
            announced,
            handback,
            last_event,
            stats: _,
            out,
        } = self;
        cfg.hash(d);
        match *state {
            State::Pilot => d.write_u8(0),
            State::Handshake {
                event,
                started,
                sent,
                next,
            } => {
                d.write_u8(1);
                d.event(event);
                d.instant_within(started, cfg.handshake_timeout);
                sent.hash(d);
                if sent <= u16::from(cfg.max_retries) {
                    d.instant(next);
                }
            }
            State::Companion {
                event,
                last_control,
                last_heartbeat,
            } => {
                d.write_u8(2);
                d.event(event);
                d.instant_within(last_control, cfg.override_timeout);
                d.instant_within(last_heartbeat, cfg.heartbeat_timeout);
            }
            State::Rtl => d.write_u8(3),
        }
        (receiver_ok, run, announced).hash(d);
        digest::option(d, *handback, |d, h| {
            d.event(h.event);
            h.sent.hash(d);
            if h.sent <= u16::from(cfg.max_retries) {
                d.instant(h.next);
            }
        });
        digest::option(d, *last_event, |d, e| d.event(e));
        out.len().hash(d);
    }

    /// The next action to carry out, if any.
    #[must_use]
    pub fn poll_action(&mut self) -> Option<FcAction> {
        self.out.pop()
    }

    /// When [`handle_timeout`](Self::handle_timeout) must next be called.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Moment> {
        let state = match self.state {
            State::Handshake {
                started,
                sent,
                next,
                ..
            } => {
                let deadline = started + self.cfg.handshake_timeout;
                Some(if sent <= u16::from(self.cfg.max_retries) {
                    next.min(deadline)
                } else {
                    deadline
                })
            }
            State::Companion {
                last_control,
                last_heartbeat,
                ..
            } => Some(
                (last_control + self.cfg.override_timeout)
                    .min(last_heartbeat + self.cfg.heartbeat_timeout),
            ),
            State::Pilot | State::Rtl => None,
        };
        let handback = self
            .handback
            .filter(|h| h.sent <= u16::from(self.cfg.max_retries))
            .map(|h| h.next);
        match (state, handback) {
            (Some(a), Some(b)) => Some(a.min(b)),
            (a, b) => a.or(b),
        }
    }

    /// Timers: retries, the handshake deadline, companion silence.
    pub fn handle_timeout(&mut self, now: Moment) {
        match self.state {
            State::Handshake {
                event,
                started,
                sent,
                next,
            } => {
                if now >= started + self.cfg.handshake_timeout {
                    self.fall_back(now);
                } else if now >= next && sent <= u16::from(self.cfg.max_retries) {
                    self.send_notice(Status::RC_LOST, event);
                    self.state = State::Handshake {
                        event,
                        started,
                        sent: sent.saturating_add(1),
                        next: next + self.cfg.retry_interval,
                    };
                }
            }
            State::Companion {
                last_control,
                last_heartbeat,
                ..
            } => {
                if now >= last_control + self.cfg.override_timeout
                    || now >= last_heartbeat + self.cfg.heartbeat_timeout
                {
                    self.fall_back(now);
                }
            }
            State::Pilot | State::Rtl => {}
        }
        if let Some(h) = self.handback {
            if now >= h.next && h.sent <= u16::from(self.cfg.max_retries) {
                self.send_notice(Status::NORMAL, h.event);
                self.handback = Some(HandBack {
                    event: h.event,
                    sent: h.sent.saturating_add(1),
                    next: h.next + self.cfg.retry_interval,
                });
            }
        }
    }

    /// An input at time `now`. Drain [`poll_action`](Self::poll_action)
    /// after every call.
    pub fn handle_input(&mut self, now: Moment, input: FcInput) {
        match input {
            FcInput::RcSample { receiver_ok } => self.rc_sample(now, receiver_ok),
            FcInput::Notice { status, timestamp } => {
                if let State::Companion { last_heartbeat, .. } = &mut self.state {
                    *last_heartbeat = now;
                }
                self.notice(now, status, timestamp);
            }
            FcInput::Control => {
                // The control stream is also proof of life.
                if let State::Companion {
                    last_control,
                    last_heartbeat,
                    ..
                } = &mut self.state
                {
                    *last_control = now;
                    *last_heartbeat = now;
                }
            }
            FcInput::Heartbeat => {
                if let State::Companion { last_heartbeat, .. } = &mut self.state {
                    *last_heartbeat = now;
                }
            }
        }
    }

    fn rc_sample(&mut self, now: Moment, ok: bool) {
        if ok == self.receiver_ok {
            self.run = 0;
            return;
        }
        self.run = self.run.saturating_add(1);
        let needed = if ok {
            self.cfg.rc_regain_samples
        } else {
            self.cfg.rc_loss_samples
        };
        if self.run < needed.max(1) {
            return;
        }
        self.run = 0;
        self.receiver_ok = ok;
        if ok {
            self.rc_regained(now);
        } else {
            self.rc_lost(now);
        }
    }

    fn rc_lost(&mut self, now: Moment) {
        if self.state != State::Pilot {
            return;
        }
        self.stats.rc_losses = self.stats.rc_losses.saturating_add(1);
        let event = self.new_event(now);
        // A hand-back still being announced is superseded by this event.
        self.handback = None;
        self.state = State::Handshake {
            event,
            started: now,
            sent: 1,
            next: now + self.cfg.retry_interval,
        };
        self.out.push(FcAction::SetAuthority(Authority::Handshake));
        self.send_notice(Status::RC_LOST, event);
    }

    fn rc_regained(&mut self, now: Moment) {
        if self.state == State::Pilot {
            return;
        }
        // The pilot has authority over everything else, at once.
        self.state = State::Pilot;
        self.out.push(FcAction::AcceptOverrides(false));
        self.out.push(FcAction::SetAuthority(Authority::Pilot));
        self.announce_normal(now);
    }

    /// RTL, and tell the companion it no longer controls anything.
    fn fall_back(&mut self, now: Moment) {
        self.stats.fallbacks = self.stats.fallbacks.saturating_add(1);
        self.state = State::Rtl;
        self.out.push(FcAction::AcceptOverrides(false));
        self.out.push(FcAction::SetAuthority(Authority::Rtl));
        self.announce_normal(now);
    }

    /// Announces status 0 (retried until acknowledged), unless it is already
    /// the status announced.
    fn announce_normal(&mut self, now: Moment) {
        if self.announced == Status::NORMAL {
            return;
        }
        let event = self.new_event(now);
        self.handback = Some(HandBack {
            event,
            sent: 1,
            next: now + self.cfg.retry_interval,
        });
        self.send_notice(Status::NORMAL, event);
    }

    fn notice(&mut self, now: Moment, status: Status, timestamp: u32) {
        match (status, self.state) {
            (Status::CC_TAKEOVER_CONFIRMED, State::Handshake { event, .. })
                if event == timestamp =>
            {
                self.stats.takeovers = self.stats.takeovers.saturating_add(1);
                self.announced = Status::CC_TAKEOVER_CONFIRMED;
                self.state = State::Companion {
                    event,
                    last_control: now,
                    last_heartbeat: now,
                };
                self.out.push(FcAction::SetAuthority(Authority::Companion));
                self.out.push(FcAction::AcceptOverrides(true));
                self.out.push(FcAction::ConfirmTakeover { event });
            }
            (Status::CC_TAKEOVER_CONFIRMED, State::Companion { event, .. })
                if event == timestamp =>
            {
                // A repeated acknowledgement: the companion missed the
                // confirmation; repeat it (bounded by the companion's
                // per-event acknowledgement limit).
                self.out.push(FcAction::ConfirmTakeover { event });
            }
            // The companion declines the event (its control source is
            // silent) or gives it back: the failsafe runs now, not after
            // the retries or the override timeout.
            (Status::NORMAL, State::Handshake { event, .. } | State::Companion { event, .. })
                if event == timestamp =>
            {
                self.stats.declined = self.stats.declined.saturating_add(1);
                self.fall_back(now);
            }
            (Status::NORMAL, _) if self.handback.is_some_and(|h| h.event == timestamp) => {
                self.handback = None;
                self.out
                    .push(FcAction::ConfirmHandBack { event: timestamp });
            }
            (Status::CC_TAKEOVER_CONFIRMED | Status::NORMAL, _) => {
                self.stats.stale_acks = self.stats.stale_acks.saturating_add(1)
            }
            _ => {}
        }
    }

    fn send_notice(&mut self, status: Status, event: u32) {
        self.stats.notices_sent = self.stats.notices_sent.saturating_add(1);
        if status != Status::CC_TAKEOVER_CONFIRMED {
            self.announced = status;
        }
        self.out.push(FcAction::SendNotice {
            status,
            timestamp: event,
        });
    }

    /// The event id: milliseconds since boot, as the paper sends
    /// `AP_HAL::millis()`, made unique if two events share a millisecond.
    fn new_event(&mut self, now: Moment) -> u32 {
        let mut id = now.as_millis() as u32;
        if let Some(last) = self.last_event {
            if id <= last && last.wrapping_sub(id) < u32::MAX / 2 {
                id = last.wrapping_add(1);
            }
        }
        self.last_event = Some(id);
        id
    }
}
