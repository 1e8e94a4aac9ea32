//! The invariants judged at a transition (a frame's fate, an output, a
//! frame sent), and the facts recorded for the invariants judged in every
//! state ([`crate::props`]).

use crate::model::{node_digest, DelegationModel, Log};
use crate::props::{autonomy_silent, Invariant, Reach};
use crate::setup::{AUTONOMY_ADDR, AUTONOMY_LINK, CC_ADDR, FC_ADDR, FC_LINK};
use crate::state::{Ghost, InFlight, Party, Sent, State};
use crate::wire;
use core::net::SocketAddr;
use fbwag_delegation::control::Control;
use fbwag_delegation::engine::{CcOutput, FcOutput};
use fbwag_delegation::fc::Authority;
use fbwag_delegation::node::{CompanionEvent, Fate, Output, Peers};
use fbwag_delegation::{mode, Moment, Status, TEXT_CC_TOOK_OVER};
use fbwag_dialect::Message;

/// A frame a node handled, as the checks see it.
pub(crate) struct Inputs<'a> {
    /// The frame the link's parser accepted.
    pub frame: &'a [u8],
    /// Its signature verified.
    pub authenticated: bool,
    /// Where it came from.
    pub cause: &'a InFlight,
    /// What the node made of it.
    pub fate: &'a Fate,
    /// The node's digest before it, if it was unsigned.
    pub digest_before: Option<u64>,
    /// The node's timers due had run before it (else the frame's call may
    /// also do what they would, as a daemon's does).
    pub up_to_date: bool,
}

/// A frame reached the FC's node.
pub(crate) fn on_fc_arrival(
    m: &DelegationModel,
    s: &mut State,
    a: &Inputs,
    before: Authority,
    outs: &[Output<FcOutput>],
    log: &mut Log,
) {
    let from = wire::sender(a.frame);
    let genuine = a.authenticated && from == Some(m.fc.companion);
    if genuine {
        s.ghost.fc_heard_cc = Some(s.now);
    }
    if a.fate.serve && !a.authenticated && m.fc.require_signed {
        m.break_now(
            s,
            Invariant::NodePolicy,
            log,
            "the FC serves an unsigned request",
        );
    }
    if a.up_to_date
        && a.digest_before
            .is_some_and(|d| d != node_digest(s, Party::Fc, &m.relevance()))
    {
        m.break_now(
            s,
            Invariant::UnsignedChangesNothing,
            log,
            "an unsigned frame changed the FC",
        );
    }
    let Some(Message::FbwagNotice(n)) = wire::message_of(a.frame).filter(|_| genuine) else {
        return;
    };
    let after = s.fc.node.engine().authority();
    let newest = s.ghost.fc_newest;
    if Some(n.timestamp) != newest.map(|(_, e)| e) {
        let sends = outs.iter().any(|o| matches!(o, Output::Transmit { .. }));
        if after != before || sends {
            m.break_now(
                s,
                Invariant::StaleAckIgnored,
                log,
                "a stale notice acted on",
            );
        }
        return;
    }
    let current = newest == Some((Status::RC_LOST.0, n.timestamp));
    let delegated = matches!(before, Authority::Handshake | Authority::Companion);
    if n.failsafe_status == Status::NORMAL && current && delegated {
        if after != Authority::Rtl {
            m.break_now(
                s,
                Invariant::DeclineFallsBack,
                log,
                "a decline left the FC flying on",
            );
        }
        let reach = match before {
            Authority::Handshake => Reach::Declined,
            _ => Reach::GivenBack,
        };
        m.reach(reach, s.steps.0);
    }
}

/// A frame reached the companion's FC link.
pub(crate) fn on_cc_arrival(m: &DelegationModel, s: &mut State, a: &Inputs, log: &mut Log) {
    let from = wire::sender(a.frame);
    let of_fc = from == Some(m.cc.fc);
    let message = wire::message_of(a.frame);
    if a.fate.input && of_fc {
        s.ghost.cc_heard_fc = Some(s.now);
        if !matches!(message, Some(Message::Heartbeat(_))) {
            s.ghost.cc_heard_fc_news = Some(s.now);
        }
    }
    let confirmation = match message {
        Some(Message::Heartbeat(h)) => h.custom_mode == mode::FBWAG,
        Some(Message::Statustext(t)) => t.text.starts_with(TEXT_CC_TOOK_OVER.as_bytes()),
        _ => false,
    };
    if a.authenticated && of_fc && confirmation {
        s.ghost.confirmation = Some(s.now);
    }
    if !a.authenticated && m.cc.require_signed {
        let route = a.fate.route;
        if route.contains(AUTONOMY_LINK) || route.contains(FC_LINK) || (of_fc && !route.is_empty())
        {
            m.break_now(
                s,
                Invariant::NodePolicy,
                log,
                "an unauthenticated frame routed",
            );
        }
    }
    if of_fc
        && a.up_to_date
        && a.digest_before
            .is_some_and(|d| d != node_digest(s, Party::Cc, &m.relevance()))
    {
        m.break_now(
            s,
            Invariant::UnsignedChangesNothing,
            log,
            "an unsigned frame changed the companion",
        );
    }
    let _ = a.cause;
}

/// Every address in `peers` is `only`.
fn answers_only(peers: &Peers, only: SocketAddr) -> bool {
    peers.iter().all(|p| p == only)
}

/// The FC node's outputs of one call, in order: mode changes, control
/// applied, whom its link answers.
pub(crate) fn on_fc_outputs(
    m: &DelegationModel,
    s: &mut State,
    mut authority: Authority,
    outs: &[Output<FcOutput>],
    cause: Option<&InFlight>,
    log: &mut Log,
) {
    let announces_normal = outs.iter().any(|o| {
        matches!(o, Output::Transmit { message: Message::FbwagNotice(n), .. }
            if n.failsafe_status == Status::NORMAL)
    });
    for out in outs {
        match out {
            Output::Peers { peers, .. } if !answers_only(peers, CC_ADDR) => {
                m.break_now(
                    s,
                    Invariant::PeerBySignature,
                    log,
                    "the FC answers a stranger",
                );
            }
            Output::Event(FcOutput::SetMode(a)) => {
                let left = matches!(authority, Authority::Handshake | Authority::Companion)
                    && matches!(a, Authority::Pilot | Authority::Rtl);
                if left && !announces_normal {
                    m.break_now(s, Invariant::LeavesWithNotice, log, "left without notice 0");
                }
                mode_changed(m, s, authority, *a, cause, log);
                authority = *a;
            }
            Output::Event(FcOutput::ApplyControl { from, .. }) => {
                if authority != Authority::Companion {
                    m.break_now(
                        s,
                        Invariant::SingleController,
                        log,
                        "control outside companion control",
                    );
                }
                let genuine = cause.is_some_and(|c| c.from == Party::Cc);
                if from.peer != m.fc.companion || !from.authenticated || !genuine {
                    m.break_now(
                        s,
                        Invariant::TrustedControl,
                        log,
                        "control not the companion's",
                    );
                }
                s.ghost.controlled = Some(s.now);
            }
            _ => {}
        }
    }
}

/// Records a mode change and checks a takeover's acknowledgement.
fn mode_changed(
    m: &DelegationModel,
    s: &mut State,
    from: Authority,
    to: Authority,
    cause: Option<&InFlight>,
    log: &mut Log,
) {
    let g = &mut s.ghost;
    // Control still came within the override time-out: the FC's other
    // timer (the companion's silence) is the one that ran out.
    let controlled = g
        .controlled
        .is_some_and(|t| s.now.since(t) < m.fc.override_timeout);
    if from == Authority::Companion && to != Authority::Companion {
        g.left_companion = Some(s.now);
        g.controlled = None;
    }
    g.handshake_since = (to == Authority::Handshake).then_some(s.now);
    let timer = cause.is_none();
    match (from, to) {
        (Authority::Handshake, Authority::Rtl) if timer => {
            m.reach(Reach::HandshakeTimeout, s.steps.0);
            let full = 1 + m.fc.max_retries;
            let boot = s.fc.boots;
            let cycles = g
                .sent
                .iter()
                .filter(|n| (n.from, n.boot, n.status) == (Party::Fc, boot, Status::RC_LOST.0))
                .filter(|n| n.count == full)
                .count();
            if cycles >= 2 {
                m.reach(Reach::TwoHandshakeTimeouts, s.steps.0);
            }
        }
        (Authority::Companion, Authority::Rtl) if timer => {
            let why = if controlled {
                Reach::CompanionSilence
            } else {
                Reach::OverrideTimeout
            };
            m.reach(why, s.steps.0)
        }
        (Authority::Handshake | Authority::Companion, Authority::Pilot) => {
            m.reach(Reach::PilotBack, s.steps.0)
        }
        _ => {}
    }
    if to != Authority::Companion || from == Authority::Companion {
        return;
    }
    m.reach(Reach::CompanionControl, s.steps.0);
    g.controlled = Some(s.now);
    // Companion control begins: only on the companion's own
    // acknowledgement of the newest event this FC boot announced.
    let Some(ack) = cause else {
        m.break_now(
            s,
            Invariant::SingleController,
            log,
            "companion control on a timer",
        );
        return;
    };
    if ack.from != Party::Cc {
        m.break_now(
            s,
            Invariant::SingleController,
            log,
            "companion control on a stranger's frame",
        );
    }
    let event = match wire::message_of(&ack.bytes) {
        Some(Message::FbwagNotice(n)) => Some(n.timestamp),
        _ => None,
    };
    let newest = s
        .ghost
        .fc_newest
        .filter(|(status, _)| *status == Status::RC_LOST.0);
    if ack.fc_boot != s.fc.boots || event.is_none() || event != newest.map(|(_, e)| e) {
        m.break_now(
            s,
            Invariant::NoStaleTakeover,
            log,
            "companion control on a stale event",
        );
    }
}

/// The companion node's outputs of one call.
pub(crate) fn on_cc_outputs(
    m: &DelegationModel,
    s: &mut State,
    outs: &[Output<CompanionEvent>],
    log: &mut Log,
) {
    let event = |e: CcOutput| outs.contains(&Output::Event(CompanionEvent::Engine(e)));
    for out in outs {
        match out {
            Output::Peers { link, peers } => {
                let only = if *link == AUTONOMY_LINK {
                    AUTONOMY_ADDR
                } else {
                    FC_ADDR
                };
                if !answers_only(peers, only) {
                    m.break_now(
                        s,
                        Invariant::PeerBySignature,
                        log,
                        "the companion answers a stranger",
                    );
                }
            }
            Output::Transmit { links, message } => {
                let control = Control::from_message(message).is_some();
                if control && links.without(FC_LINK) != Default::default() {
                    m.break_now(s, Invariant::NodePolicy, log, "control sent past the FC");
                }
            }
            Output::Event(CompanionEvent::Engine(CcOutput::ControlStarted { .. })) => {
                s.ghost.cc_started = Some(s.now)
            }
            _ => {}
        }
    }
    if event(CcOutput::FcRebooted) {
        m.reach(Reach::FcRebootRecognised, s.steps.0);
    }
    if event(CcOutput::FcLost) {
        let controlling = event(CcOutput::ControlStopped);
        let what = if controlling {
            Reach::FcSilentWhileControlling
        } else {
            Reach::FcSilent
        };
        m.reach(what, s.steps.0);
    }
}

/// The companion stopped controlling at its timers, neither for the FC's
/// silence nor for its autonomy's: never confirmed.
pub(crate) fn on_cc_timers(m: &DelegationModel, s: &State, outs: &[Output<CompanionEvent>]) {
    let had = |e: &dyn Fn(&CcOutput) -> bool| {
        outs.iter()
            .any(|o| matches!(o, Output::Event(CompanionEvent::Engine(x)) if e(x)))
    };
    let stopped = had(&|e| *e == CcOutput::ControlStopped);
    let other = had(&|e| matches!(e, CcOutput::FcLost | CcOutput::Declined { .. }));
    if stopped && !other {
        m.reach(Reach::ConfirmTimeout, s.steps.0);
    }
}

/// A frame `from` signed and put on the link.
pub(crate) fn on_transmit(
    m: &DelegationModel,
    s: &mut State,
    from: Party,
    message: &Message,
    bytes: &[u8],
    log: &mut Log,
) {
    let side = (from == Party::Cc) as usize;
    if let Some(sig) = wire::frame_of(bytes).signature() {
        let ts = sig.timestamp();
        if s.ghost.signed[side].is_some_and(|last| ts <= last) {
            m.break_now(s, Invariant::SignerForward, log, "a signing time went back");
        }
        s.ghost.signed[side] = Some(ts);
    }
    let Message::FbwagNotice(n) = message else {
        return;
    };
    let (status, event) = (n.failsafe_status, n.timestamp);
    if from == Party::Fc {
        let previous = s.ghost.fc_newest;
        let new = previous.is_none_or(|(_, e)| e != event);
        if new && previous.is_some_and(|(st, _)| st == status.0) {
            m.break_now(
                s,
                Invariant::NoticesAreEvents,
                log,
                "a status announced twice",
            );
        }
        if new {
            s.ghost.fc_newest = Some((status.0, event));
        }
    }
    if from == Party::Cc && status == Status::CC_TAKEOVER_CONFIRMED && autonomy_silent(s) {
        m.break_now(
            s,
            Invariant::NoAckWhileSilent,
            log,
            "a takeover acknowledged while silent",
        );
    }
    let limit = 1 + match from {
        Party::Fc => m.fc.max_retries,
        _ => m.cc.max_ack_retries,
    };
    // The FC's own boot; for the companion, the latest FC boot that
    // announced the event (or the current one).
    let boot = match from {
        Party::Fc => s.fc.boots,
        _ => s
            .ghost
            .sent
            .iter()
            .filter(|n| n.from == Party::Fc && n.event == event)
            .map(|n| n.boot)
            .max()
            .unwrap_or(s.fc.boots),
    };
    let (count, first) = count_notice(&mut s.ghost, (from, boot), status.0, event, s.now);
    if count > limit {
        m.break_now(
            s,
            Invariant::BoundedNotices,
            log,
            "a notice past its retries",
        );
    }
    if s.now.since(first) > m.notices_end() {
        m.break_now(
            s,
            Invariant::NoticesEnd,
            log,
            "a notice after its retries ended",
        );
    }
    match (from, status) {
        (Party::Fc, Status::RC_LOST) if count > 1 => m.reach(Reach::Retry, s.steps.0),
        (Party::Cc, Status::CC_TAKEOVER_CONFIRMED) if count > 1 => {
            m.reach(Reach::AckRetry, s.steps.0)
        }
        _ => {}
    }
}

/// Counts a notice of `from`: how many of this status and event so far,
/// and when the first went out.
fn count_notice(
    g: &mut Ghost,
    (from, boot): (Party, u8),
    status: u8,
    event: u32,
    now: Moment,
) -> (u8, Moment) {
    let i = g
        .sent
        .iter()
        .position(|n| (n.from, n.boot, n.status, n.event) == (from, boot, status, event));
    match i {
        Some(i) => {
            let n = &mut g.sent[i];
            n.count = n.count.saturating_add(1);
            (n.count, n.first)
        }
        None => {
            g.sent.push(Sent {
                from,
                boot,
                status,
                event,
                count: 1,
                first: now,
            });
            (1, now)
        }
    }
}

/// Facts of the state a transition reached.
pub(crate) fn after_step(m: &DelegationModel, s: &State) {
    let cc = s.cc.node.engine();
    let believes = cc.machine().believes_in_control(s.cc_now());
    if believes {
        m.reach(Reach::CompanionBelieves, s.steps.0);
    }
    let confirmed_since_start = s
        .ghost
        .confirmation
        .zip(s.ghost.cc_started)
        .is_some_and(|(c, start)| c >= start);
    let controlling = cc.state() == fbwag_delegation::cc::CcState::Controlling;
    if controlling && confirmed_since_start && !believes {
        m.reach(Reach::LeaseLapsed, s.steps.0);
    }
}
