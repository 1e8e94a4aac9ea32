//! The named invariants, each checked in every state the checker reaches.

use crate::model::DelegationModel;
use crate::state::State;
use core::time::Duration;
use fbwag_delegation::cc::CcState;
use fbwag_delegation::fc::Authority;
use fbwag_delegation::Moment;
use stateright::Property;
use std::sync::atomic::Ordering;

/// An invariant of the protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Invariant {
    /// Never two controllers.
    SingleController,
    /// Control only from the trusted companion.
    TrustedControl,
    /// An RC loss is answered in time.
    RcLossAnswered,
    /// The pilot gets control back in time.
    PilotBack,
    /// No FC state waits forever.
    NoWaitForever,
    /// The companion's belief of control is bounded.
    BeliefBounded,
    /// Retries end.
    BoundedNotices,
    /// No takeover for a stale event after a reboot.
    NoStaleTakeover,
}

/// Every invariant, in bit order.
pub const INVARIANTS: [Invariant; 8] = [
    Invariant::SingleController,
    Invariant::TrustedControl,
    Invariant::RcLossAnswered,
    Invariant::PilotBack,
    Invariant::NoWaitForever,
    Invariant::BeliefBounded,
    Invariant::BoundedNotices,
    Invariant::NoStaleTakeover,
];

impl Invariant {
    /// Its bit in [`crate::state::Ghost::broken`].
    pub fn bit(self) -> u16 {
        1 << INVARIANTS.iter().position(|i| *i == self).unwrap_or(0)
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Invariant::SingleController => "single-controller",
            Invariant::TrustedControl => "trusted-control-only",
            Invariant::RcLossAnswered => "rc-loss-answered-in-time",
            Invariant::PilotBack => "pilot-back-in-time",
            Invariant::NoWaitForever => "no-wait-forever",
            Invariant::BeliefBounded => "belief-bounded",
            Invariant::BoundedNotices => "bounded-notices",
            Invariant::NoStaleTakeover => "no-stale-takeover",
        }
    }

    /// The exact statement (docs/delegation.md, "Model-checked").
    pub fn statement(self) -> &'static str {
        match self {
            Invariant::SingleController => {
                "the FC enters companion control only on the delivery of the companion's own \
                 acknowledgement (status 2) of its event, and applies control only while in \
                 companion control"
            }
            Invariant::TrustedControl => {
                "every control the FC applies came from a frame the companion's node sent, \
                 with the companion's ids and a verified signature"
            }
            Invariant::RcLossAnswered => {
                "while the receiver is lost, the FC leaves pilot control within \
                 rc_loss_samples receiver samples of the loss (or of its boot), and no \
                 handshake lasts longer than handshake_timeout"
            }
            Invariant::PilotBack => {
                "while the receiver works, the FC is back in pilot control within \
                 rc_regain_samples receiver samples of its return"
            }
            Invariant::NoWaitForever => {
                "in handshake or companion control the FC machine has a deadline; \
                 controlling, so has the companion's"
            }
            Invariant::BeliefBounded => {
                "the companion believes it controls while the FC is not in companion \
                 control for at most retry_interval after the FC left it"
            }
            Invariant::BoundedNotices => {
                "each FBWAG_NOTICE status and event is sent at most 1 + max_retries \
                 times by the FC, and 1 + max_ack_retries times by the companion, per boot"
            }
            Invariant::NoStaleTakeover => {
                "companion control begins only on an acknowledgement sent to the FC's \
                 current boot, of an event that boot announced"
            }
        }
    }

    /// Whether `s` satisfies it.
    pub fn holds(self, m: &DelegationModel, s: &State) -> bool {
        if self == INVARIANTS[0] {
            // Every state the search evaluates passes here once.
            m.checked.fetch_add(1, Ordering::Relaxed);
        }
        if s.ghost.broken & self.bit() != 0 {
            return false;
        }
        match self {
            Invariant::RcLossAnswered => rc_loss_answered(m, s),
            Invariant::PilotBack => pilot_back(m, s),
            Invariant::NoWaitForever => no_wait_forever(s),
            Invariant::BeliefBounded => belief_bounded(m, s),
            _ => true,
        }
    }
}

fn since(s: &State, t: Moment) -> Duration {
    s.now.since(t)
}

fn rc_loss_answered(m: &DelegationModel, s: &State) -> bool {
    let authority = s.fc.node.get().engine().authority();
    if let (Authority::Handshake, Some(start)) = (authority, s.ghost.handshake_since) {
        if since(s, start) > m.fc.handshake_timeout {
            return false;
        }
    }
    if s.rc_ok || authority != Authority::Pilot {
        return true;
    }
    let lost = s.ghost.rc_changed.max(s.fc.boot);
    since(s, lost) <= m.fc.rc_sample_period * u32::from(m.fc.rc_loss_samples)
}

fn pilot_back(m: &DelegationModel, s: &State) -> bool {
    let authority = s.fc.node.get().engine().authority();
    !s.rc_ok
        || authority == Authority::Pilot
        || since(s, s.ghost.rc_changed) <= m.fc.rc_sample_period * u32::from(m.fc.rc_regain_samples)
}

fn no_wait_forever(s: &State) -> bool {
    let fc = s.fc.node.get().engine();
    let fc_ok = match fc.authority() {
        Authority::Handshake | Authority::Companion => fc.machine().poll_timeout().is_some(),
        Authority::Pilot | Authority::Rtl => true,
    };
    let cc = s.cc.node.get().engine();
    let cc_ok = cc.state() != CcState::Controlling || cc.machine().poll_timeout().is_some();
    fc_ok && cc_ok
}

fn belief_bounded(m: &DelegationModel, s: &State) -> bool {
    let believes =
        s.cc.node
            .get()
            .engine()
            .machine()
            .believes_in_control(s.cc_now());
    let fc_companion = s.fc.node.get().engine().authority() == Authority::Companion;
    if !believes || fc_companion {
        return true;
    }
    s.ghost
        .left_companion
        .is_some_and(|t| since(s, t) <= m.fc.retry_interval)
}

/// Properties: the invariants, then the states to reach.
pub const COUNT: usize = INVARIANTS.len() + REACHES.len();

/// What stateright is told of property `index` in `s`, where `found`
/// says whether `s` breaks the invariant (or shows the state to reach).
/// stateright keeps the *last* state it was told of, so only a state on a
/// path no longer than the shortest seen so far is reported: the search
/// is breadth first, and the counterexample kept is a shortest one.
fn report(m: &DelegationModel, s: &State, index: usize, found: bool) -> bool {
    if !found {
        return false;
    }
    let before = m.shortest[index].fetch_min(s.steps.0, Ordering::Relaxed);
    s.steps.0 <= before
}

/// The stateright properties: one `always` per invariant, one `sometimes`
/// per state to reach.
pub fn properties() -> Vec<Property<DelegationModel>> {
    // `Property::always` takes a plain function: one per invariant.
    macro_rules! always {
        ($($i:literal: $inv:ident),*) => {
            vec![$(Property::always(Invariant::$inv.name(), |m: &DelegationModel, s: &State| {
                !report(m, s, $i, !Invariant::$inv.holds(m, s))
            })),*]
        };
    }
    let mut all = always!(
        0: SingleController,
        1: TrustedControl,
        2: RcLossAnswered,
        3: PilotBack,
        4: NoWaitForever,
        5: BeliefBounded,
        6: BoundedNotices,
        7: NoStaleTakeover
    );
    // Examples the search must reach, so the invariants are not vacuous.
    all.push(Property::sometimes(REACHES[0], |m, s: &State| {
        let found = s.fc.node.get().engine().authority() == Authority::Companion;
        report(m, s, 8, found)
    }));
    all.push(Property::sometimes(REACHES[1], |m, s: &State| {
        let found =
            s.cc.node
                .get()
                .engine()
                .machine()
                .believes_in_control(s.cc_now());
        report(m, s, 9, found)
    }));
    all.push(Property::sometimes(REACHES[2], |m, s: &State| {
        let found = s.fc.node.get().engine().authority() == Authority::Rtl;
        report(m, s, 10, found)
    }));
    all
}

/// States the search must reach (stateright `sometimes`): companion
/// control, the companion's confirmed belief, the RTL fallback.
pub const REACHES: [&str; 3] = ["companion-control", "companion-believes", "rtl-fallback"];
