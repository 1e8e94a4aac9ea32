//! The named invariants, each the rule of `docs/delegation.md` it guards,
//! checked in every state the checker reaches; and the situations the
//! search must reach, so that none of them holds vacuously.

use crate::model::DelegationModel;
use crate::state::State;
use core::time::Duration;
use fbwag_delegation::cc::CcState;
use fbwag_delegation::fc::Authority;
use fbwag_delegation::Moment;
use stateright::Property;
use std::sync::atomic::Ordering;

macro_rules! invariants {
    ($($(#[doc = $doc:literal])* $v:ident = $name:literal: $statement:literal,)*) => {
        /// An invariant of the protocol.
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum Invariant {
            $($(#[doc = $doc])* $v,)*
        }

        /// Every invariant, in bit order.
        pub const INVARIANTS: &[Invariant] = &[$(Invariant::$v,)*];

        impl Invariant {
            /// Its name.
            pub fn name(self) -> &'static str {
                match self { $(Invariant::$v => $name,)* }
            }

            /// The exact statement (docs/delegation.md, "Model-checked").
            pub fn statement(self) -> &'static str {
                match self { $(Invariant::$v => $statement,)* }
            }
        }
    };
}

invariants! {
    /// Never two controllers.
    SingleController = "single-controller":
        "the FC enters companion control only on the delivery of the companion's own \
         acknowledgement (status 2) of its event, and applies control only in companion control",
    /// Control only from the trusted companion.
    TrustedControl = "trusted-control-only":
        "every control the FC applies came from a frame the companion's node sent, with the \
         companion's ids and a verified signature",
    /// No takeover for a stale event.
    NoStaleTakeover = "no-stale-takeover":
        "companion control begins only on an acknowledgement sent to the FC's current boot, of \
         the newest event that boot announced",
    /// Stale acknowledgements change nothing.
    StaleAckIgnored = "stale-ack-changes-nothing":
        "a companion's notice of an event other than the newest the FC announced changes neither \
         who flies nor what the FC sends",
    /// A decline sends the FC home at once.
    DeclineFallsBack = "decline-falls-back":
        "the companion's status 0 for the FC's current RC-loss event puts the FC in RTL at once",
    /// Every exit from delegation is announced.
    LeavesWithNotice = "leaves-with-notice":
        "the FC leaves handshake or companion control (but by restarting) only with a status-0 \
         notice",
    /// Notices are events, never a stream.
    NoticesAreEvents = "notices-are-events":
        "each new event the FC announces has another status than the one before it in its boot",
    /// Retries end.
    BoundedNotices = "bounded-notices":
        "each FBWAG_NOTICE status and event is sent at most 1 + max_retries times by the FC, and \
         1 + max_ack_retries times by the companion, per boot",
    /// Retries end in time.
    NoticesEnd = "notices-end":
        "each side sends the notices of one status and event within max_retries retry \
         intervals of its first (3 s), never later",
    /// A silent autonomy takes nothing over.
    NoAckWhileSilent = "no-takeover-while-silent":
        "the companion never acknowledges a takeover (status 2) while its autonomy is silent \
         (no frame for its silence period)",
    /// A silent autonomy holds nothing.
    SilentHoldsNothing = "silent-autonomy-holds-nothing":
        "once its timers due have run, the companion does not control while its autonomy is \
         silent: it gives the event back",
    /// Unsigned frames act on nothing.
    UnsignedChangesNothing = "unsigned-changes-nothing":
        "an unsigned frame changes nothing in the FC's node, nor, with the FC's ids, in the \
         companion's, once their timers due have run (counters aside)",
    /// The node policy of signing.
    NodePolicy = "unauthenticated-stays-out":
        "with signing required the FC serves no unauthenticated request; the companion routes \
         nothing unauthenticated to the FC or the autonomy, nothing unauthenticated with the FC's \
         ids anywhere, nothing of the autonomy to the FC but through its gate, and its control to \
         the FC only",
    /// Whom a listening link answers.
    PeerBySignature = "peer-only-by-signature":
        "the peer link answers only the peer whose signature verified, the autonomy link only \
         the autonomy",
    /// Replay protection.
    NoReplay = "no-replay":
        "no side authenticates a frame older than or as old as one it authenticated before, \
         since its signing state began",
    /// Signing time never goes back.
    SignerForward = "signer-never-goes-back":
        "each side signs every frame later than the one before, since its signing state began",
    /// RC loss is answered.
    RcLossAnswered = "rc-loss-answered-in-time":
        "while the receiver is lost, the FC leaves pilot control within rc_loss_samples \
         receiver samples of the loss (or of its boot), and no handshake lasts longer than \
         handshake_timeout",
    /// The pilot gets control back in time.
    PilotBack = "pilot-back-in-time":
        "while the receiver works, the FC is back in pilot control within rc_regain_samples \
         receiver samples of its return",
    /// No state waits forever.
    NoWaitForever = "no-wait-forever":
        "in handshake or companion control the FC machine has a deadline; controlling, so has \
         the companion's",
    /// Never in companion control without control.
    NeverWithoutControl = "never-without-control":
        "the FC is in companion control without applying control for at most override_timeout",
    /// Never in companion control with a silent companion.
    CompanionHeard = "companion-heard":
        "in companion control, the FC authenticated a frame of the companion within \
         heartbeat_timeout",
    /// The companion's belief is bounded.
    BeliefBounded = "belief-bounded":
        "the companion believes it controls while the FC is not in companion control for at \
         most retry_interval after the FC left it",
    /// Belief only from a fresh confirmation.
    BeliefConfirmed = "belief-from-confirmation":
        "the companion believes it controls only within control_lease of a confirmation (an \
         FBWAG heartbeat or the takeover text) of the FC",
    /// The companion stops.
    CompanionStops = "companion-stops":
        "the companion controls while the FC is not in companion control for at most \
         control_fc_timeout after the latest of its takeover, the FC leaving companion control \
         and the last frame of the FC other than a heartbeat it took (a heartbeat shows the FC's \
         mode: it may end control, never prolong it)",
    /// The companion follows the FC's silence.
    CompanionHearsFc = "companion-hears-fc":
        "the companion stands by only within fc_timeout, and controls only within \
         control_fc_timeout, of a frame of the FC",
    /// Who flies is decided on the ground.
    WhoFliesOnTheGround = "who-flies-decided-on-the-ground":
        "the companion signs on from its trusted ground link no frame that changes who flies or \
         when the failsafe starts (PARAM_SET of the delegation's parameters, SETUP_SIGNING): \
         those go nowhere",
}

impl Invariant {
    /// Its bit in [`crate::state::Ghost::broken`].
    pub fn bit(self) -> u32 {
        1 << INVARIANTS.iter().position(|i| *i == self).unwrap_or(0)
    }

    /// Whether `s` satisfies it.
    pub fn holds(self, m: &DelegationModel, s: &State) -> bool {
        if self == INVARIANTS[0] {
            // Every state the search evaluates passes here once.
            m.checked.fetch_add(1, Ordering::Relaxed);
            m.latest.fetch_max(s.now.0, Ordering::Relaxed);
        }
        if s.ghost.gap {
            // Past the documented gap nothing is claimed.
            return true;
        }
        if s.ghost.broken & self.bit() != 0 {
            return false;
        }
        match self {
            Invariant::RcLossAnswered => rc_loss_answered(m, s),
            Invariant::PilotBack => pilot_back(m, s),
            Invariant::NoWaitForever => no_wait_forever(s),
            Invariant::NeverWithoutControl => never_without_control(m, s),
            Invariant::CompanionHeard => companion_heard(m, s),
            Invariant::BeliefBounded => belief_bounded(m, s),
            Invariant::BeliefConfirmed => belief_confirmed(m, s),
            Invariant::CompanionStops => companion_stops(m, s),
            Invariant::CompanionHearsFc => companion_hears_fc(m, s),
            Invariant::SilentHoldsNothing => silent_holds_nothing(s),
            _ => true,
        }
    }
}

fn since(s: &State, t: Moment) -> Duration {
    s.now.since(t)
}

/// `t` is at most `d` before now.
fn within(s: &State, t: Option<Moment>, d: Duration) -> bool {
    t.is_some_and(|t| since(s, t) <= d)
}

fn authority(s: &State) -> Authority {
    s.fc.node.engine().authority()
}

fn rc_loss_answered(m: &DelegationModel, s: &State) -> bool {
    if let (Authority::Handshake, Some(start)) = (authority(s), s.ghost.handshake_since) {
        if since(s, start) > m.fc.handshake_timeout {
            return false;
        }
    }
    if s.rc_ok || authority(s) != Authority::Pilot {
        return true;
    }
    let lost = s.ghost.rc_changed.max(s.fc.boot);
    since(s, lost) <= m.fc.rc_sample_period * u32::from(m.fc.rc_loss_samples)
}

fn pilot_back(m: &DelegationModel, s: &State) -> bool {
    !s.rc_ok
        || authority(s) == Authority::Pilot
        || since(s, s.ghost.rc_changed) <= m.fc.rc_sample_period * u32::from(m.fc.rc_regain_samples)
}

fn no_wait_forever(s: &State) -> bool {
    let fc = s.fc.node.engine();
    let fc_ok = match fc.authority() {
        Authority::Handshake | Authority::Companion => fc.machine().poll_timeout().is_some(),
        Authority::Pilot | Authority::Rtl => true,
    };
    let cc = s.cc.node.engine();
    let cc_ok = cc.state() != CcState::Controlling || cc.machine().poll_timeout().is_some();
    fc_ok && cc_ok
}

fn never_without_control(m: &DelegationModel, s: &State) -> bool {
    if authority(s) != Authority::Companion || !fc_up_to_date(s) {
        return true;
    }
    within(s, s.ghost.controlled, m.fc.override_timeout)
}

fn companion_heard(m: &DelegationModel, s: &State) -> bool {
    authority(s) != Authority::Companion
        || !fc_up_to_date(s)
        || within(s, s.ghost.fc_heard_cc, m.fc.heartbeat_timeout)
}

fn believes(s: &State) -> bool {
    s.cc.node.engine().machine().believes_in_control(s.cc_now())
}

fn belief_bounded(m: &DelegationModel, s: &State) -> bool {
    !believes(s)
        || authority(s) == Authority::Companion
        || within(s, s.ghost.left_companion, m.fc.retry_interval)
}

fn belief_confirmed(m: &DelegationModel, s: &State) -> bool {
    !believes(s) || within(s, s.ghost.confirmation, m.cc.control_lease)
}

fn controlling(s: &State) -> bool {
    s.cc.node.engine().state() == CcState::Controlling
}

fn companion_stops(m: &DelegationModel, s: &State) -> bool {
    if !controlling(s) || authority(s) == Authority::Companion || !cc_up_to_date(s) {
        return true;
    }
    let g = &s.ghost;
    let from = g.cc_started.max(g.left_companion).max(g.cc_heard_fc_news);
    within(s, from, m.cc.control_fc_timeout)
}

/// The FC's timers due now have run.
fn fc_up_to_date(s: &State) -> bool {
    s.fc_deadline().is_none_or(|t| t > s.now)
}

/// The companion's timers due now have run.
fn cc_up_to_date(s: &State) -> bool {
    s.cc_deadline().is_none_or(|t| t > s.now)
}

fn companion_hears_fc(m: &DelegationModel, s: &State) -> bool {
    if !cc_up_to_date(s) {
        return true;
    }
    let heard = s.ghost.cc_heard_fc;
    match s.cc.node.engine().state() {
        CcState::Idle => true,
        CcState::Standby => within(s, heard, m.cc.fc_timeout),
        CcState::Controlling => within(s, heard, m.cc.control_fc_timeout),
    }
}

/// The autonomy has been silent for its silence period (by the harness's
/// own record of its frames).
pub(crate) fn autonomy_silent(s: &State) -> bool {
    s.ghost
        .autonomy_heard
        .is_none_or(|t| s.now >= t + crate::setup::SILENCE)
}

fn silent_holds_nothing(s: &State) -> bool {
    !(cc_up_to_date(s) && autonomy_silent(s) && controlling(s))
}

/// Properties: the invariants.
pub const COUNT: usize = INVARIANTS.len();

/// What stateright is told of invariant `index` in `s`, where `broken`
/// says whether `s` breaks it. stateright keeps the *last* state it was
/// told of, so only a state on a path no longer than the shortest seen so
/// far is reported: the search is breadth first, and the counterexample
/// kept is a shortest one.
fn report(m: &DelegationModel, s: &State, index: usize, broken: bool) -> bool {
    if !broken {
        return false;
    }
    let before = m.shortest[index].fetch_min(s.steps.0, Ordering::Relaxed);
    s.steps.0 <= before
}

/// The stateright properties: one `always` per invariant.
pub fn properties() -> Vec<Property<DelegationModel>> {
    // `Property::always` takes a plain function: one per invariant.
    macro_rules! always {
        ($($i:literal),*) => {
            vec![$(Property::always(INVARIANTS[$i].name(), |m: &DelegationModel, s: &State| {
                !report(m, s, $i, !INVARIANTS[$i].holds(m, s))
            })),*]
        };
    }
    let all = always!(
        0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24,
        25
    );
    debug_assert_eq!(all.len(), INVARIANTS.len());
    all
}

/// Situations the search must reach, so that the invariants and every
/// timer of both nodes are exercised: each recorded, with the fewest steps
/// to it, when a transition shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Reach {
    /// The FC enters companion control.
    CompanionControl,
    /// The companion believes it controls (a confirmation arrived).
    CompanionBelieves,
    /// The FC repeats its notice (the retry timer).
    Retry,
    /// The FC falls back to RTL after its last retry (the handshake timeout).
    HandshakeTimeout,
    /// Twice in one boot: two whole RC-loss cycles, each to the RTL after
    /// its last retry.
    TwoHandshakeTimeouts,
    /// The FC falls back from companion control on its own timers, for
    /// want of control (the override timeout).
    OverrideTimeout,
    /// The FC falls back from companion control on its own timers while
    /// control still came: the companion-silence timeout.
    CompanionSilence,
    /// The FC falls back on the companion's decline (a silent autonomy).
    Declined,
    /// The companion gives an event back when its autonomy falls silent.
    GivenBack,
    /// The pilot's receiver returns and the FC hands back.
    PilotBack,
    /// The companion repeats its acknowledgement (its retry timer).
    AckRetry,
    /// The companion stops controlling, never confirmed (confirm timeout).
    ConfirmTimeout,
    /// The companion gives up on an FC silent for control_fc_timeout.
    FcSilentWhileControlling,
    /// The companion forgets an FC silent for fc_timeout.
    FcSilent,
    /// The companion recognises an FC restart.
    FcRebootRecognised,
    /// The companion's belief lapses (its lease runs out).
    LeaseLapsed,
    /// A replay reached the documented gap (a restart without signing state).
    ReplayGap,
    /// The trusted ground link signs a parameter a ground tool may set on
    /// to the FC.
    TrustedSignedOn,
}

impl Reach {
    /// Every situation.
    pub const ALL: [Reach; 18] = [
        Reach::CompanionControl,
        Reach::CompanionBelieves,
        Reach::Retry,
        Reach::HandshakeTimeout,
        Reach::TwoHandshakeTimeouts,
        Reach::OverrideTimeout,
        Reach::CompanionSilence,
        Reach::Declined,
        Reach::GivenBack,
        Reach::PilotBack,
        Reach::AckRetry,
        Reach::ConfirmTimeout,
        Reach::FcSilentWhileControlling,
        Reach::FcSilent,
        Reach::FcRebootRecognised,
        Reach::LeaseLapsed,
        Reach::ReplayGap,
        Reach::TrustedSignedOn,
    ];

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Reach::CompanionControl => "companion-control",
            Reach::CompanionBelieves => "companion-believes",
            Reach::Retry => "retry",
            Reach::HandshakeTimeout => "handshake-timeout",
            Reach::TwoHandshakeTimeouts => "two-handshake-timeouts",
            Reach::OverrideTimeout => "override-timeout",
            Reach::CompanionSilence => "companion-silence",
            Reach::Declined => "declined",
            Reach::GivenBack => "given-back",
            Reach::PilotBack => "pilot-back",
            Reach::AckRetry => "ack-retry",
            Reach::ConfirmTimeout => "confirm-timeout",
            Reach::FcSilentWhileControlling => "fc-silent-while-controlling",
            Reach::FcSilent => "fc-silent",
            Reach::FcRebootRecognised => "fc-reboot-recognised",
            Reach::LeaseLapsed => "lease-lapsed",
            Reach::ReplayGap => "replay-gap",
            Reach::TrustedSignedOn => "trusted-signed-on",
        }
    }
}
