//! The rules of `docs/delegation.md` a trial checks on every event, beside
//! those [`super::World`] checks itself (who applies control, where frames
//! are routed, whom the ports answer, the belief's bound): the same
//! invariants as `fbwag-model`'s, judged on each simulated trial. Each
//! broken rule is a [`super::Violation`] of the trial.

use super::Side;
use crate::cc::{CcConfig, CcState};
use crate::digest::Digest;
use crate::engine::{CcOutput, FcOutput};
use crate::fc::{Authority, FcConfig};
use crate::node::{CompanionEvent, CompanionNode, FcNode, Output};
use crate::{mode, Moment, Status, TEXT_CC_TOOK_OVER};
use core::hash::Hasher;
use core::time::Duration;
use fbwag_dialect::{Frame, Message};
use std::collections::hash_map::DefaultHasher;
use std::collections::HashMap;

/// A notice of one side: how many of its status and event, and when the
/// first went out.
type Sent = HashMap<(Side, u8, u32), (u8, Moment)>;

/// What the rules remember of a trial.
pub(super) struct Rules {
    fc: FcConfig,
    cc: CcConfig,
    /// The autonomy's silence, when a silent autonomy declines.
    declines: Option<Duration>,
    /// The downlink's longest delay: the companion answers the FC's
    /// notices as they arrive.
    delay: Duration,
    rc_changed: Moment,
    handshake_since: Option<Moment>,
    /// In companion control: its start or the last control applied.
    controlled: Option<Moment>,
    fc_heard_cc: Option<Moment>,
    left_companion: Option<Moment>,
    cc_started: Option<Moment>,
    cc_heard_fc: Option<Moment>,
    /// The last frame of the FC the companion took that was no heartbeat.
    cc_heard_fc_news: Option<Moment>,
    confirmation: Option<Moment>,
    autonomy_heard: Option<Moment>,
    /// The newest event the FC announced, with its status.
    fc_newest: Option<(u8, u32)>,
    sent: Sent,
    /// The newest signing time each side authenticated, per stream.
    authenticated: HashMap<(Side, u8, u8, u8), u64>,
    /// The last signing time each side signed.
    signed: HashMap<Side, u64>,
    /// Rules broken since the last [`Rules::take`].
    broken: Vec<String>,
}

/// What the FC's node was handed: a frame of the companion, if genuine
/// (from the companion's own datagram, its ids, authenticated), as
/// `(status, event)` when a notice.
pub(super) struct FcInput {
    pub(super) genuine_notice: Option<(Status, u32)>,
}

impl Rules {
    pub(super) fn new(
        fc: FcConfig,
        cc: CcConfig,
        declines: Option<Duration>,
        delay: Duration,
    ) -> Self {
        Rules {
            fc,
            cc,
            declines,
            delay,
            rc_changed: Moment::ZERO,
            handshake_since: None,
            controlled: None,
            fc_heard_cc: None,
            left_companion: None,
            cc_started: None,
            cc_heard_fc: None,
            cc_heard_fc_news: None,
            confirmation: None,
            autonomy_heard: None,
            fc_newest: None,
            sent: HashMap::new(),
            authenticated: HashMap::new(),
            signed: HashMap::new(),
            broken: Vec::new(),
        }
    }

    /// The rules broken since the last call.
    pub(super) fn take(&mut self) -> Vec<String> {
        core::mem::take(&mut self.broken)
    }

    fn broke(&mut self, rule: &str, what: String) {
        self.broken.push(format!("{rule}: {what}"));
    }

    /// The pilot's receiver changed.
    pub(super) fn rc(&mut self, now: Moment) {
        self.rc_changed = now;
    }

    /// The autonomy's frame reached the companion.
    pub(super) fn autonomy_frame(&mut self, now: Moment) {
        self.autonomy_heard = Some(now);
    }

    /// The companion restarted: it knows nothing, nor its autonomy.
    pub(super) fn cc_restarted(&mut self) {
        (self.cc_started, self.cc_heard_fc, self.cc_heard_fc_news) = (None, None, None);
        (self.confirmation, self.autonomy_heard) = (None, None);
        self.sent.retain(|(side, _, _), _| *side != Side::Cc);
    }

    fn autonomy_silent(&self, now: Moment) -> bool {
        self.autonomy_heard
            .is_none_or(|t| self.declines.is_some_and(|s| now >= t + s))
    }

    /// `side` authenticated `frame`: never a frame of a stream as old as
    /// one it authenticated before.
    pub(super) fn authenticated(&mut self, now: Moment, side: Side, frame: &Frame<&[u8]>) {
        let Some(sig) = frame.signature() else { return };
        let h = frame.header();
        let key = (side, sig.link_id(), h.sysid, h.compid);
        let ts = sig.timestamp();
        if let Some(newest) = self.authenticated.insert(key, ts) {
            if ts <= newest {
                self.broke(
                    "no-replay",
                    format!("{side:?} authenticated signing time {ts} after {newest} at {now:?}"),
                );
            }
        }
    }

    /// `side` signed and sent `bytes`, `message`: its signing time goes
    /// forward; its notices are events, bounded in number and in time; a
    /// silent autonomy's companion acknowledges no takeover.
    pub(super) fn sent(&mut self, now: Moment, side: Side, message: &Message, bytes: &[u8]) {
        if let Some(sig) = Frame::new_checked(bytes).ok().and_then(|f| f.signature()) {
            let ts = sig.timestamp();
            if let Some(last) = self.signed.insert(side, ts) {
                if ts <= last {
                    self.broke(
                        "signer-never-goes-back",
                        format!("{side:?} signed {ts} after {last}"),
                    );
                }
            }
        }
        let Message::FbwagNotice(n) = message else {
            return;
        };
        let (status, event) = (n.failsafe_status, n.timestamp);
        if side == Side::Fc {
            let new = self.fc_newest.is_none_or(|(_, e)| e != event);
            if new && self.fc_newest.is_some_and(|(s, _)| s == status.0) {
                self.broke(
                    "notices-are-events",
                    format!("status {} announced twice", status.0),
                );
            }
            if new {
                self.fc_newest = Some((status.0, event));
            }
        }
        let declining = self.declines.is_some() && self.autonomy_silent(now);
        if side == Side::Cc && status == Status::CC_TAKEOVER_CONFIRMED && declining {
            self.broke(
                "no-takeover-while-silent",
                format!("event {event} acknowledged"),
            );
        }
        self.count(now, side, status, event);
    }

    fn count(&mut self, now: Moment, side: Side, status: Status, event: u32) {
        let (limit, span) = match side {
            Side::Fc => (
                self.fc.max_retries,
                self.fc.retry_interval * u32::from(self.fc.max_retries),
            ),
            Side::Cc => (
                self.cc.max_ack_retries,
                self.cc.ack_retry_interval * u32::from(self.cc.max_ack_retries) + self.delay,
            ),
        };
        let entry = self.sent.entry((side, status.0, event)).or_insert((0, now));
        entry.0 = entry.0.saturating_add(1);
        let (count, first) = *entry;
        if count > 1 + limit {
            self.broke(
                "bounded-notices",
                format!(
                    "{side:?} sent status {} event {event} {count} times",
                    status.0
                ),
            );
        }
        if now.since(first) > span {
            self.broke(
                "notices-end",
                format!(
                    "{side:?} sent status {} event {event} after its retries",
                    status.0
                ),
            );
        }
    }

    /// What the FC's node did with one call (`input`: a frame it was
    /// handed, if any): modes, control, notices.
    pub(super) fn fc_outputs(
        &mut self,
        now: Moment,
        mut authority: Authority,
        outs: &[Output<FcOutput>],
        input: Option<&FcInput>,
    ) {
        let before = authority;
        let normal = outs.iter().any(|o| {
            matches!(o, Output::Transmit { message: Message::FbwagNotice(n), .. }
                if n.failsafe_status == Status::NORMAL)
        });
        for out in outs {
            match out {
                Output::Event(FcOutput::SetMode(a)) => {
                    self.mode(now, authority, *a, input, normal);
                    authority = *a;
                }
                Output::Event(FcOutput::ApplyControl { .. }) => self.controlled = Some(now),
                _ => {}
            }
        }
        let Some((status, event)) = input.and_then(|i| i.genuine_notice) else {
            return;
        };
        let sends = outs.iter().any(|o| matches!(o, Output::Transmit { .. }));
        if Some(event) != self.fc_newest.map(|(_, e)| e) {
            if authority != before || sends {
                self.broke(
                    "stale-ack-changes-nothing",
                    format!("event {event} acted on"),
                );
            }
            return;
        }
        let current = self.fc_newest == Some((Status::RC_LOST.0, event));
        let delegated = matches!(before, Authority::Handshake | Authority::Companion);
        if status == Status::NORMAL && current && delegated && authority != Authority::Rtl {
            self.broke(
                "decline-falls-back",
                format!("event {event}: {authority:?}"),
            );
        }
    }

    fn mode(
        &mut self,
        now: Moment,
        from: Authority,
        to: Authority,
        input: Option<&FcInput>,
        announced: bool,
    ) {
        let delegated = matches!(from, Authority::Handshake | Authority::Companion);
        if delegated && matches!(to, Authority::Pilot | Authority::Rtl) && !announced {
            self.broke(
                "leaves-with-notice",
                format!("{from:?} to {to:?} without notice 0"),
            );
        }
        if from == Authority::Companion && to != Authority::Companion {
            self.left_companion = Some(now);
            self.controlled = None;
        }
        self.handshake_since = (to == Authority::Handshake).then_some(now);
        if to == Authority::Companion && from != Authority::Companion {
            self.controlled = Some(now);
            let ack = input.and_then(|i| i.genuine_notice);
            let newest = self.fc_newest.filter(|(s, _)| *s == Status::RC_LOST.0);
            let genuine = ack.is_some_and(|(s, e)| {
                s == Status::CC_TAKEOVER_CONFIRMED && newest.is_some_and(|(_, n)| n == e)
            });
            if !genuine {
                self.broke(
                    "no-stale-takeover",
                    "companion control without the companion's acknowledgement of the newest \
                     event"
                        .into(),
                );
            }
        }
    }

    /// A frame the FC's node took from the companion, authenticated.
    pub(super) fn fc_heard(&mut self, now: Moment) {
        self.fc_heard_cc = Some(now);
    }

    /// A frame the companion's node took from the FC as input.
    pub(super) fn cc_heard(&mut self, now: Moment, message: Option<&Message>, authenticated: bool) {
        self.cc_heard_fc = Some(now);
        if !matches!(message, Some(Message::Heartbeat(_))) {
            self.cc_heard_fc_news = Some(now);
        }
        let confirms = match message {
            Some(Message::Heartbeat(h)) => h.custom_mode == mode::FBWAG,
            Some(Message::Statustext(t)) => t.text.starts_with(TEXT_CC_TOOK_OVER.as_bytes()),
            _ => false,
        };
        if confirms && (authenticated || !self.cc.require_signed) {
            self.confirmation = Some(now);
        }
    }

    /// The companion's node's events.
    pub(super) fn cc_event(&mut self, now: Moment, event: &CompanionEvent) {
        if let CompanionEvent::Engine(CcOutput::ControlStarted { .. }) = event {
            self.cc_started = Some(now);
        }
    }

    /// The rules judged in every state, once each node's timers due now
    /// have run (`cc`: the companion, when it is on).
    pub(super) fn check(&mut self, now: Moment, fc: &FcNode, cc: Option<&CompanionNode>) {
        let within = |t: Option<Moment>, d: Duration| t.is_some_and(|t| now.since(t) <= d);
        if fc.poll_timeout().is_some_and(|t| t > now) {
            self.check_fc(now, fc, within);
        }
        let Some(cc) = cc.filter(|cc| cc.poll_timeout().is_none_or(|t| t > now)) else {
            return;
        };
        let controlling = cc.engine().state() == CcState::Controlling;
        let believes = cc.engine().machine().believes_in_control(now);
        let companion = fc.engine().authority() == Authority::Companion;
        if believes && !within(self.confirmation, self.cc.control_lease) {
            self.broke("belief-from-confirmation", format!("belief at {now:?}"));
        }
        let from = self
            .cc_started
            .max(self.left_companion)
            .max(self.cc_heard_fc_news);
        if controlling && !companion && !within(from, self.cc.control_fc_timeout) {
            self.broke("companion-stops", format!("still controlling at {now:?}"));
        }
        let heard = match cc.engine().state() {
            CcState::Idle => true,
            CcState::Standby => within(self.cc_heard_fc, self.cc.fc_timeout),
            CcState::Controlling => within(self.cc_heard_fc, self.cc.control_fc_timeout),
        };
        if !heard {
            self.broke("companion-hears-fc", format!("at {now:?}"));
        }
        if controlling && self.declines.is_some() && self.autonomy_silent(now) {
            self.broke("silent-autonomy-holds-nothing", format!("at {now:?}"));
        }
        if controlling && cc.engine().machine().poll_timeout().is_none() {
            self.broke(
                "no-wait-forever",
                "the companion controls without a deadline".into(),
            );
        }
    }

    fn check_fc(
        &mut self,
        now: Moment,
        fc: &FcNode,
        within: impl Fn(Option<Moment>, Duration) -> bool,
    ) {
        let cfg = self.fc;
        let authority = fc.engine().authority();
        if authority == Authority::Handshake && !within(self.handshake_since, cfg.handshake_timeout)
        {
            self.broke(
                "rc-loss-answered-in-time",
                "a handshake past its time-out".into(),
            );
        }
        if authority == Authority::Companion {
            if !within(self.controlled, cfg.override_timeout) {
                self.broke(
                    "never-without-control",
                    format!("no control applied at {now:?}"),
                );
            }
            if !within(self.fc_heard_cc, cfg.heartbeat_timeout) {
                self.broke("companion-heard", format!("companion silent at {now:?}"));
            }
        }
        let delegated = matches!(authority, Authority::Handshake | Authority::Companion);
        if delegated && fc.engine().machine().poll_timeout().is_none() {
            self.broke(
                "no-wait-forever",
                format!("{authority:?} without a deadline"),
            );
        }
    }

    /// Judges the receiver: `rc_ok` now, with the rule's bounds.
    pub(super) fn check_receiver(&mut self, now: Moment, rc_ok: bool, fc: &FcNode) {
        if fc.poll_timeout().is_some_and(|t| t <= now) {
            return;
        }
        let cfg = self.fc;
        let authority = fc.engine().authority();
        let since = now.since(self.rc_changed);
        // The n-th sample after the change comes within n periods of it.
        let bound = |n: u8| cfg.rc_sample_period * u32::from(n);
        if !rc_ok && authority == Authority::Pilot && since > bound(cfg.rc_loss_samples) {
            self.broke(
                "rc-loss-answered-in-time",
                format!("still the pilot's at {now:?}"),
            );
        }
        if rc_ok && authority != Authority::Pilot && since > bound(cfg.rc_regain_samples) {
            self.broke(
                "pilot-back-in-time",
                format!("still {authority:?} at {now:?}"),
            );
        }
    }
}

/// A node's digest for "an unsigned frame changes nothing": every value
/// as it is (before and after one frame, at one instant).
pub(super) struct Exact(DefaultHasher);

impl Exact {
    pub(super) fn of(feed: impl FnOnce(&mut Exact)) -> u64 {
        let mut d = Exact(DefaultHasher::new());
        feed(&mut d);
        d.0.finish()
    }
}

impl Hasher for Exact {
    fn finish(&self) -> u64 {
        self.0.finish()
    }

    fn write(&mut self, bytes: &[u8]) {
        self.0.write(bytes);
    }
}

impl Digest for Exact {
    fn instant(&mut self, t: Moment) {
        self.0.write_u64(t.0);
    }

    fn event(&mut self, event: u32) {
        self.0.write_u32(event);
    }

    fn sequence(&mut self, seq: u8) {
        self.0.write_u8(seq);
    }
}
