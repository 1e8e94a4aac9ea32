//! The companion computer's side: answer the FC's notices, stream control
//! while delegated, stop on hand-back. See `docs/delegation.md`.
//!
//! The companion *controls* (streams overrides) from its acknowledgement
//! until the FC ends the episode, but it *believes it is in control* only
//! while the FC confirms it: the takeover confirmation, then HEARTBEATs in
//! companion control, each valid for a lease of one retry period. So the
//! belief never outlives the FC's decision by more than that, whatever the
//! link loses; the FC, for its part, ignores overrides outside companion
//! control.
//!
//! The machine's inputs are protocol events from the configured FC, already
//! judged trustworthy: [`crate::engine::CcEngine`] decides that (ids and
//! signature) and turns frames into inputs and actions into frames.

use crate::digest::{self, Digest};
use crate::outbox::Outbox;
use crate::{ConfigError, Moment, Peer, Status};
use core::hash::Hash;
use core::time::Duration;

/// Settings; [`CcConfig::default`] holds the paper's values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CcConfig {
    /// This companion's ids.
    pub own: Peer,
    /// The flight controller it serves.
    pub fc: Peer,
    /// Accept the FC's messages only when their signature verified.
    pub require_signed: bool,
    /// Time between repeated acknowledgements while the FC's confirmation
    /// is missing.
    pub ack_retry_interval: Duration,
    /// Acknowledgements repeated after the first, per event.
    pub max_ack_retries: u8,
    /// How long one confirmation (takeover text, FBWAG heartbeat) keeps the
    /// belief of being in control. With the link's delay it must stay within
    /// one retry period, so the belief never outlives the FC's decision by
    /// more than that; the FC confirms every 200 ms in companion control.
    pub control_lease: Duration,
    /// Stop controlling when the takeover is not confirmed within this time
    /// (the FC has fallen back by then).
    pub confirm_timeout: Duration,
    /// Period of the control stream (RC_CHANNELS_OVERRIDE), well below
    /// ArduPlane's RC_OVERRIDE_TIME.
    pub control_period: Duration,
    /// Standing by, forget the FC when it has not been heard for this long.
    pub fc_timeout: Duration,
    /// Controlling, stop only when the FC has not been heard for this long:
    /// the FC decides and gates overrides, so a downlink outage must not end
    /// companion control (the uplink may still carry the control stream).
    pub control_fc_timeout: Duration,
    /// The longest an FC event can stay live: the FC repeats a notice for
    /// at most its handshake timeout, plus the link's delay. A notice older
    /// than this by the FC's own clock, as far as the companion can tell,
    /// comes from a new boot of the FC (its event ids restarted), not from
    /// the current one. See [`CcAction::FcRebooted`].
    pub fc_event_lifetime: Duration,
    /// HEARTBEAT period of the companion (MAVLink's 1 Hz).
    pub heartbeat_period: Duration,
}

impl CcConfig {
    /// Checks the settings: every period and timeout positive, the lease
    /// and the control stream consistent.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let positive = [
            ("ack_retry_interval", self.ack_retry_interval),
            ("control_lease", self.control_lease),
            ("confirm_timeout", self.confirm_timeout),
            ("control_period", self.control_period),
            ("fc_timeout", self.fc_timeout),
            ("control_fc_timeout", self.control_fc_timeout),
            ("fc_event_lifetime", self.fc_event_lifetime),
            ("heartbeat_period", self.heartbeat_period),
        ];
        for (name, d) in positive {
            if d.is_zero() {
                return Err(ConfigError::Zero(name));
            }
        }
        if self.control_period >= self.control_lease {
            return Err(ConfigError::Order("control_period", "control_lease"));
        }
        // The belief of being in control must end within one retry period
        // of the FC's decision (found by the model check: a 3 s lease let
        // the companion believe it controlled a restarted FC for 3 s).
        if self.control_lease >= self.ack_retry_interval {
            return Err(ConfigError::Order("control_lease", "ack_retry_interval"));
        }
        Ok(())
    }
}

impl Default for CcConfig {
    fn default() -> Self {
        CcConfig {
            own: Peer::new(1, 191),
            fc: Peer::new(1, 1),
            require_signed: false,
            ack_retry_interval: Duration::from_secs(1),
            max_ack_retries: 3,
            control_lease: Duration::from_millis(750),
            confirm_timeout: Duration::from_secs(5),
            control_period: Duration::from_millis(50),
            fc_timeout: Duration::from_secs(3),
            control_fc_timeout: Duration::from_secs(10),
            fc_event_lifetime: Duration::from_secs(6),
            heartbeat_period: Duration::from_secs(1),
        }
    }
}

/// What the companion is told. Everything but `Reboot` comes from the
/// configured FC (the engine has checked the sender).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CcInput {
    /// The FC's HEARTBEAT.
    Heartbeat {
        /// The frame's sequence number: a late frame says nothing new.
        seq: u8,
        /// Its flight mode is companion control (FBWAG).
        companion_control: bool,
    },
    /// The FC's FBWAG_NOTICE.
    Notice {
        /// `failsafe_status`.
        status: Status,
        /// `timestamp`: the event.
        timestamp: u32,
    },
    /// The FC confirmed the takeover of an event (the paper's STATUSTEXT
    /// "FBWAG-ACK: CC has taken over!", whose `id` carries the event's low
    /// 16 bits, followed by the ids of the companion it accepted).
    TakeoverConfirmed {
        /// The frame's sequence number.
        seq: u8,
        /// The event's low 16 bits.
        event: u16,
        /// Whom the FC accepted, when it says (the paper's text alone does
        /// not: then it is taken to be this companion).
        by: Option<Peer>,
    },
    /// Any other frame of the FC: it is alive.
    FcAlive,
    /// The companion restarted: everything is forgotten.
    Reboot,
}

/// What the companion must do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CcAction {
    /// Send FBWAG_NOTICE to the FC.
    SendNotice {
        /// `failsafe_status`.
        status: Status,
        /// `timestamp`: the FC's event being answered.
        timestamp: u32,
    },
    /// Send one control message now (RC_CHANNELS_OVERRIDE from the
    /// controller); emitted every `control_period` while controlling.
    SendControl,
    /// Control starts (log it; prepare the controller).
    StartControl,
    /// Control ends: stop overriding.
    StopControl,
    /// The companion declined the takeover of this event, or gave up
    /// control of it, because its control source (the autonomy) is silent:
    /// it answered the notice with status 0, which sends the FC to its
    /// failsafe at once rather than into companion control without control.
    Declined {
        /// The FC's event.
        event: u32,
    },
    /// The FC confirmed the takeover of the event this companion controls
    /// to another companion (a second companion with the FC's trust, or
    /// one the FC was configured for on the ground): control stopped at
    /// once ([`CcAction::StopControl`] before this), rather than a belief
    /// of flying renewed by the FC's heartbeats in companion control.
    Superseded {
        /// The FC's event.
        event: u32,
        /// Whom the FC accepted.
        by: Peer,
    },
    /// The FC has rebooted: a notice came whose event id is older than any
    /// live event of the boot the companion knew, or an RC-loss notice of
    /// an event older than the newest came again a retry later (the FC
    /// repeats only its current event). Its events are forgotten and the
    /// notice is handled as new.
    FcRebooted,
}

/// The companion's view of the link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CcState {
    /// No FC heard yet (or no longer).
    Idle,
    /// The FC is there; the pilot flies.
    Standby,
    /// Delegated: acknowledging, streaming control.
    Controlling,
}

/// Counters for logs and tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct CcStats {
    /// Takeover requests answered (events).
    pub takeovers: u32,
    /// Takeovers declined or given up for a silent control source (events).
    pub declines: u32,
    /// Acknowledgements sent, all statuses.
    pub acks_sent: u32,
    /// Control messages sent.
    pub controls_sent: u32,
    /// FC reboots recognised.
    pub fc_reboots: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum State {
    Idle,
    Standby,
    Controlling {
        event: u32,
        since: Moment,
        /// Acknowledgements sent for the event: wider than
        /// `max_ack_retries`, so a limit of 255 cannot overflow it.
        acks: u16,
        next_ack: Moment,
        /// When the last acknowledgement went out.
        last_ack: Moment,
        /// When the FC last confirmed companion control, and the sequence
        /// number of the frame that did.
        confirmed: Option<(Moment, u8)>,
        next_control: Moment,
    },
}

/// The companion computer's state machine.
///
/// Inputs are typed protocol events (the engine, [`crate::engine::CcEngine`],
/// makes them from the trusted FC's frames).
///
/// ```
/// use fbwag_delegation::cc::{CcAction, CcConfig, CcInput, CcState, Companion};
/// use fbwag_delegation::{Moment, Status};
///
/// let mut cc = Companion::new(CcConfig::default());
/// let lost = CcInput::Notice { status: Status::RC_LOST, timestamp: 1100 };
/// cc.handle_input(Moment::from_millis(1105), lost);
/// let actions: Vec<_> = std::iter::from_fn(|| cc.poll_action()).collect();
/// // It acknowledges the event, starts controlling, and its first control
/// // message is due at once.
/// assert_eq!(actions[0], CcAction::SendNotice {
///     status: Status::CC_TAKEOVER_CONFIRMED,
///     timestamp: 1100,
/// });
/// assert!(actions.contains(&CcAction::SendControl));
/// assert_eq!(cc.state(), CcState::Controlling);
/// // It believes it is in control only once the FC confirms.
/// assert!(!cc.believes_in_control(Moment::from_millis(1105)));
/// let confirmed = CcInput::TakeoverConfirmed { seq: 7, event: 1100, by: Some(cc.config().own) };
/// cc.handle_input(Moment::from_millis(1110), confirmed);
/// assert!(cc.believes_in_control(Moment::from_millis(1110)));
/// ```
#[derive(Debug, Clone)]
pub struct Companion {
    cfg: CcConfig,
    state: State,
    last_fc: Option<Moment>,
    /// The last hand-back event acknowledged, and how often.
    normal_acks: (u32, u16),
    /// The newest FC event seen and when it arrived: a late or duplicated
    /// notice of it (or of an older one) must not start control again,
    /// unless it is too old to be live (the FC rebooted).
    newest_event: Option<(u32, Moment)>,
    /// An RC-loss notice of an event older than the newest, and when it
    /// first came: see [`Companion::repeats_an_older_event`].
    older_notice: Option<(u32, Moment)>,
    /// Whether the control source can fly now (see
    /// [`Companion::set_control_ready`]).
    control_ready: bool,
    /// The last event declined, and how often the decline was sent.
    declined: (u32, u16),
    stats: CcStats,
    out: Outbox<CcAction, 8>,
}

impl Companion {
    /// A companion that has not heard the FC yet.
    pub fn new(cfg: CcConfig) -> Self {
        Companion {
            cfg,
            state: State::Idle,
            last_fc: None,
            normal_acks: (0, 0),
            newest_event: None,
            older_notice: None,
            control_ready: true,
            declined: (0, 0),
            stats: CcStats::default(),
            out: Outbox::new(),
        }
    }

    /// The settings.
    pub fn config(&self) -> &CcConfig {
        &self.cfg
    }

    /// Where the companion stands.
    pub fn state(&self) -> CcState {
        match self.state {
            State::Idle => CcState::Idle,
            State::Standby => CcState::Standby,
            State::Controlling { .. } => CcState::Controlling,
        }
    }

    /// The FC event the companion controls for, while it does.
    pub fn event(&self) -> Option<u32> {
        match self.state {
            State::Controlling { event, .. } => Some(event),
            _ => None,
        }
    }

    /// True while the FC's confirmation of companion control is fresh.
    pub fn believes_in_control(&self, now: Moment) -> bool {
        matches!(self.state, State::Controlling { confirmed: Some((at, _)), .. } if now.since(at) <= self.cfg.control_lease)
    }

    /// Counters.
    pub fn stats(&self) -> &CcStats {
        &self.stats
    }

    /// Whether the control source (a built-in controller always; an
    /// external autonomy while it speaks) can fly the aircraft. While it
    /// cannot, a takeover is declined; when it stops during control, the
    /// companion gives the event back (status 0 for it), so the FC never
    /// sits in companion control without control.
    pub fn set_control_ready(&mut self, ready: bool) {
        self.control_ready = ready;
        if let (false, State::Controlling { event, .. }) = (ready, self.state) {
            self.stop(State::Standby);
            self.decline(event);
        }
    }

    /// Feeds `d` everything that decides what the companion does next (see
    /// [`crate::digest`]); its counters are left out.
    pub fn digest(&self, d: &mut impl Digest) {
        let Companion {
            cfg,
            state,
            last_fc,
            normal_acks,
            newest_event,
            older_notice,
            control_ready,
            declined,
            stats: _,
            out,
        } = self;
        cfg.hash(d);
        match *state {
            State::Idle => d.write_u8(0),
            State::Standby => d.write_u8(1),
            State::Controlling {
                event,
                since,
                acks,
                next_ack,
                last_ack,
                confirmed,
                next_control,
            } => {
                d.write_u8(2);
                d.event(event);
                acks.hash(d);
                // Unconfirmed, the companion repeats its acknowledgement
                // and gives up after confirm_timeout; confirmed, neither.
                if confirmed.is_none() {
                    d.instant_within(since, cfg.confirm_timeout);
                    if acks <= u16::from(cfg.max_ack_retries) {
                        d.instant(next_ack);
                    }
                }
                d.instant_within(last_ack, cfg.ack_retry_interval / 2);
                digest::option(d, confirmed, |d, (at, seq)| {
                    d.instant_within(at, cfg.control_lease);
                    d.sequence(seq);
                });
                d.instant(next_control);
            }
        }
        digest::option(d, *last_fc, |d, t| d.instant_within(t, self.fc_timeout()));
        // A count of 0 holds no event (both start as (0, 0)).
        for (event, count) in [*normal_acks, *declined] {
            digest::option(d, (count > 0).then_some((event, count)), |d, (e, n)| {
                d.event(e);
                n.hash(d);
            });
        }
        let lapses = [
            (newest_event, cfg.fc_event_lifetime),
            (older_notice, cfg.ack_retry_interval / 2),
        ];
        for (heard, lapse) in lapses {
            digest::option(d, *heard, |d, (event, at)| {
                d.event(event);
                d.instant_within(at, lapse);
            });
        }
        control_ready.hash(d);
        out.len().hash(d);
    }

    /// The next action to carry out, if any.
    #[must_use]
    pub fn poll_action(&mut self) -> Option<CcAction> {
        self.out.pop()
    }

    /// When [`handle_timeout`](Self::handle_timeout) must next be called.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Moment> {
        let fc_gone = self.last_fc.map(|t| t + self.fc_timeout());
        match self.state {
            State::Idle => None,
            State::Standby => fc_gone,
            State::Controlling {
                since,
                acks,
                next_ack,
                confirmed,
                next_control,
                ..
            } => {
                let mut t = next_control;
                if confirmed.is_none() {
                    t = t.min(since + self.cfg.confirm_timeout);
                    if acks <= u16::from(self.cfg.max_ack_retries) {
                        t = t.min(next_ack);
                    }
                }
                Some(fc_gone.map_or(t, |g| t.min(g)))
            }
        }
    }

    /// Timers: the control stream, repeated acknowledgements, time-outs.
    pub fn handle_timeout(&mut self, now: Moment) {
        if self.last_fc.is_some_and(|t| now >= t + self.fc_timeout()) && self.state != State::Idle {
            self.stop(State::Idle);
            self.last_fc = None;
            return;
        }
        let State::Controlling {
            event,
            since,
            confirmed,
            ..
        } = self.state
        else {
            return;
        };
        if confirmed.is_none() && now >= since + self.cfg.confirm_timeout {
            self.stop(State::Standby);
            return;
        }
        // Decide and advance the timers in place, then emit.
        let (mut ack_due, mut control_due) = (false, false);
        if let State::Controlling {
            acks,
            next_ack,
            last_ack,
            next_control,
            ..
        } = &mut self.state
        {
            if confirmed.is_none()
                && now >= *next_ack
                && *acks <= u16::from(self.cfg.max_ack_retries)
            {
                *acks = acks.saturating_add(1);
                *next_ack = *next_ack + self.cfg.ack_retry_interval;
                *last_ack = now;
                ack_due = true;
            }
            if now >= *next_control {
                // Keep the cadence; after a long stall, restart it from now.
                *next_control = (*next_control + self.cfg.control_period).max(now);
                control_due = true;
            }
        }
        if ack_due {
            self.ack(Status::CC_TAKEOVER_CONFIRMED, event);
        }
        if control_due {
            self.control_due();
        }
    }

    fn control_due(&mut self) {
        self.stats.controls_sent = self.stats.controls_sent.saturating_add(1);
        self.out.push(CcAction::SendControl);
    }

    /// An input at time `now`. Drain [`poll_action`](Self::poll_action)
    /// after every call.
    pub fn handle_input(&mut self, now: Moment, input: CcInput) {
        if input == CcInput::Reboot {
            // A restart forgets everything.
            *self = Companion::new(self.cfg);
            return;
        }
        self.last_fc = Some(now);
        if self.state == State::Idle {
            self.state = State::Standby;
        }
        match input {
            CcInput::Heartbeat {
                seq,
                companion_control,
            } => self.heartbeat(now, companion_control, seq),
            CcInput::TakeoverConfirmed { seq, event: id, by } => {
                // Bound to the event, so a late confirmation of an earlier
                // episode confirms nothing.
                let State::Controlling { event, .. } = self.state else {
                    return;
                };
                match by {
                    _ if event as u16 != id => {}
                    Some(other) if other != self.cfg.own => {
                        self.stop(State::Standby);
                        self.out.push(CcAction::Superseded { event, by: other });
                    }
                    _ => self.confirm(now, seq),
                }
            }
            CcInput::Notice { status, timestamp } => self.notice(now, status, timestamp),
            CcInput::FcAlive | CcInput::Reboot => {}
        }
    }

    fn heartbeat(&mut self, now: Moment, companion_control: bool, seq: u8) {
        let State::Controlling { confirmed, .. } = self.state else {
            return;
        };
        // Only a frame sent after the last confirmation says anything new:
        // the link may deliver an older heartbeat late. But not a lease
        // late: by then an FC that restarted numbers its frames from 0
        // again, and its other mode is news whatever the number.
        let newer = confirmed.is_none_or(|(_, s)| crate::seq_after(seq, s));
        let lapsed = confirmed.is_some_and(|(at, _)| now.since(at) > self.cfg.control_lease);
        if companion_control && newer {
            self.confirm(now, seq);
        } else if !companion_control && confirmed.is_some() && (newer || lapsed) {
            // The FC has left companion control (RTL, the pilot, a
            // restart): stop.
            self.stop(State::Standby);
        }
    }

    fn confirm(&mut self, now: Moment, seq: u8) {
        if let State::Controlling { confirmed, .. } = &mut self.state {
            if confirmed.is_none_or(|(_, s)| crate::seq_after(seq, s)) {
                *confirmed = Some((now, seq));
            }
        }
    }

    fn notice(&mut self, now: Moment, status: Status, timestamp: u32) {
        let repeated = status == Status::RC_LOST && self.repeats_an_older_event(now, timestamp);
        if repeated || self.is_of_a_new_boot(now, timestamp) {
            // The episode of the old boot is over, whatever it was.
            self.stop(State::Standby);
            self.stats.fc_reboots = self.stats.fc_reboots.saturating_add(1);
            self.out.push(CcAction::FcRebooted);
            (self.newest_event, self.older_notice) = (None, None);
            self.normal_acks = (0, 0);
        }
        match status {
            Status::RC_LOST => match self.state {
                State::Controlling {
                    event,
                    acks,
                    last_ack,
                    ..
                } if event == timestamp => {
                    // The FC did not get our acknowledgement: repeat it,
                    // within the per-event bound, and restart our own
                    // retry timer. The FC's repeated notice and our timer
                    // come about together (both every retry interval): one
                    // answer serves both, or they would spend the bound
                    // twice as fast and leave the FC's last notice
                    // unanswered.
                    let interval = self.cfg.ack_retry_interval;
                    let just_answered = now.since(last_ack) < interval / 2;
                    if !just_answered && acks <= u16::from(self.cfg.max_ack_retries) {
                        self.ack(Status::CC_TAKEOVER_CONFIRMED, timestamp);
                        if let State::Controlling {
                            acks,
                            next_ack,
                            last_ack,
                            ..
                        } = &mut self.state
                        {
                            *acks = acks.saturating_add(1);
                            *next_ack = now + interval;
                            *last_ack = now;
                        }
                    }
                }
                // A decline the FC may not have heard: say it again.
                _ if self.declined.0 == timestamp && self.declined.1 > 0 => {
                    if self.declined.1 <= u16::from(self.cfg.max_ack_retries) {
                        self.decline(timestamp);
                    }
                }
                // An event already handled, or older: late or duplicated.
                _ if self
                    .newest_event
                    .is_some_and(|(n, _)| !event_after(timestamp, n)) => {}
                _ if !self.control_ready => {
                    self.newest_event = Some((timestamp, now));
                    self.decline(timestamp);
                }
                _ => {
                    self.newest_event = Some((timestamp, now));
                    self.stats.takeovers = self.stats.takeovers.saturating_add(1);
                    // The first control message goes out with the
                    // acknowledgement; the stream follows every period.
                    self.state = State::Controlling {
                        event: timestamp,
                        since: now,
                        acks: 1,
                        next_ack: now + self.cfg.ack_retry_interval,
                        last_ack: now,
                        confirmed: None,
                        next_control: now + self.cfg.control_period,
                    };
                    self.ack(Status::CC_TAKEOVER_CONFIRMED, timestamp);
                    self.out.push(CcAction::StartControl);
                    self.control_due();
                }
            },
            Status::NORMAL => {
                self.saw_event(now, timestamp);
                // The FC no longer delegates: stop, and acknowledge every
                // time asked (the FC retries until it hears us).
                if matches!(self.state, State::Controlling { .. }) {
                    self.stop(State::Standby);
                }
                let count = if self.normal_acks.0 == timestamp {
                    self.normal_acks.1
                } else {
                    0
                };
                if count <= u16::from(self.cfg.max_ack_retries) {
                    self.normal_acks = (timestamp, count.saturating_add(1));
                    self.ack(Status::NORMAL, timestamp);
                }
            }
            _ => {}
        }
    }

    /// Hand-back events count too: a status 1 older than a hand-back is stale.
    fn saw_event(&mut self, now: Moment, timestamp: u32) {
        if self
            .newest_event
            .is_none_or(|(n, _)| event_after(timestamp, n))
        {
            self.newest_event = Some((timestamp, now));
        }
    }

    /// True when event `timestamp` cannot belong to the FC boot that sent
    /// the newest event. Event ids are the FC's milliseconds since boot: at
    /// `now` that boot's clock reads at least `newest + (now − arrival)`,
    /// and its live events are at most `fc_event_lifetime` older than its
    /// clock. An id further behind restarted counting: the FC rebooted. (A
    /// replay of an old frame also looks like this; with signing the
    /// verifier has refused it already, and without signing anyone can
    /// forge a notice anyway.)
    fn is_of_a_new_boot(&self, now: Moment, timestamp: u32) -> bool {
        let Some((newest, arrived)) = self.newest_event else {
            return false;
        };
        if event_after(timestamp, newest) {
            return false;
        }
        let behind = u64::from(newest.wrapping_sub(timestamp));
        let since = now.since(arrived).as_millis() as u64;
        behind + since > self.cfg.fc_event_lifetime.as_millis() as u64
    }

    /// True when RC-loss event `timestamp`, older than the newest event,
    /// was notified before, at least half an `ack_retry_interval` ago. The
    /// FC repeats the notice of its current event every retry interval (the
    /// companion's matches it), and only of its current event: one whose id
    /// went back comes from a new boot whose clock restarted, though fewer
    /// than `fc_event_lifetime` ago (a quick reboot, or one early in the
    /// old boot). A late or duplicated frame of the old boot comes once, or
    /// twice close together. The first such notice is remembered here.
    fn repeats_an_older_event(&mut self, now: Moment, timestamp: u32) -> bool {
        let Some((newest, _)) = self.newest_event else {
            return false;
        };
        if timestamp == newest || event_after(timestamp, newest) {
            return false;
        }
        match self.older_notice {
            Some((event, first)) if event == timestamp => {
                now.since(first) >= self.cfg.ack_retry_interval / 2
            }
            _ => {
                self.older_notice = Some((timestamp, now));
                false
            }
        }
    }

    fn fc_timeout(&self) -> Duration {
        match self.state {
            State::Controlling { .. } => self.cfg.control_fc_timeout,
            _ => self.cfg.fc_timeout,
        }
    }

    fn stop(&mut self, next: State) {
        if matches!(self.state, State::Controlling { .. }) {
            self.out.push(CcAction::StopControl);
        }
        self.state = next;
    }

    /// Answers RC-loss event `event` with status 0: not taken (or no
    /// longer held), within the per-event bound of acknowledgements.
    fn decline(&mut self, event: u32) {
        let count = if self.declined.0 == event {
            self.declined.1
        } else {
            self.stats.declines = self.stats.declines.saturating_add(1);
            self.out.push(CcAction::Declined { event });
            0
        };
        self.declined = (event, count.saturating_add(1));
        self.ack(Status::NORMAL, event);
    }

    fn ack(&mut self, status: Status, timestamp: u32) {
        self.stats.acks_sent = self.stats.acks_sent.saturating_add(1);
        self.out.push(CcAction::SendNotice { status, timestamp });
    }
}

/// True when FC event `a` is newer than `b`: events are milliseconds since
/// the FC booted (wrapping after 49 days).
fn event_after(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}
