//! The model's state: both real nodes, the frames in flight, the pilot's
//! receiver, the virtual clock, and the facts the invariants need (which
//! the nodes keep private, so the harness records them from the nodes'
//! outputs as they happen).
//!
//! # State identity
//!
//! A state is identified by a 64-bit digest ([`State::digest`]) of
//! everything that decides what can happen next, with every time counted
//! from now: the nodes feed their own state through
//! [`fbwag_delegation::digest::Digest`] (times, FC event ids and the FC's
//! sequence numbers apart from other values, counters left out), the
//! signing state and the frames in flight are fed the same way. So the
//! same situation at another time is the same state, and the search
//! closes: a pilot flying for an hour is one state.
//!
//! Two abstractions make that sound, each argued from the product's rules:
//!
//! - **Times far back.** No rule of either node compares a time with one
//!   more than [`memory`](crate::setup::memory) (11.5 s with the model's
//!   settings: the companion's 10 s FC silence, an event's 6 s lifetime
//!   plus the 5 s handshake) before it or before now; each node says which
//!   of its times matter for less (a lease, a time-out:
//!   [`Digest::instant_within`]). Every frame that reaches a node was
//!   signed at its instant (frames in flight and the stranger's
//!   recordings never outlive it), and carries an event at most both
//!   sides' retries old ([`Relevance::events`]). So any time, event id or
//!   signing time further back digests as "long ago".
//! - **Sequence numbers and the FC's uptime.** Event ids are the FC's
//!   milliseconds since boot and its sequence numbers count its frames:
//!   after an FC restart, both start again and the companion compares the
//!   new ones with the old boot's. Until the FC can no longer restart
//!   ([`ModelConfig::fc_reboot_window`](crate::ModelConfig)), its uptime
//!   and sequence number are fed as they are, so states at other uptimes
//!   stay apart; afterwards only their differences are. The companion's
//!   sequence numbers are never compared by the FC, so they are not fed.
//!
//! Frames in flight are fed as a sorted list, so their order (which
//! [`Action::Deliver`](crate::Action) picks from anyway) does not split a
//! state: symmetric states are one.

use crate::wire::Endpoint;
use core::hash::{Hash, Hasher};
use core::time::Duration;
use fbwag_delegation::cc::CcState;
use fbwag_delegation::digest::Digest;
use fbwag_delegation::fc::Authority;
use fbwag_delegation::node::{CompanionNode, FcNode};
use fbwag_delegation::Moment;
use std::sync::Arc;

/// Who put a frame on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Party {
    /// The flight controller's node.
    Fc,
    /// The companion's node.
    Cc,
    /// Someone without the key.
    Stranger,
}

/// A frame in flight, with what the harness knows of its origin.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct InFlight {
    /// The frame's bytes, as encoded (and signed) by the sender.
    pub bytes: Vec<u8>,
    /// The sender.
    pub from: Party,
    /// How many times the FC had booted when it was sent: an
    /// acknowledgement sent to an earlier boot is stale.
    pub fc_boot: u8,
}

/// A digest with every time counted from a now: [`Digest`] for the nodes,
/// the signing state, the frames and the ghost.
pub struct Clock {
    h: ahash::AHasher,
    now: Moment,
    event_now: u32,
    seq_now: u8,
    memory: u64,
    events: u64,
}

/// A hasher seeded alike in every run.
fn hasher() -> ahash::AHasher {
    use core::hash::BuildHasher;
    ahash::RandomState::with_seeds(0x5eed, 0xfb7a, 0x6d0d, 0xe1).build_hasher()
}

/// What "long ago" digests as: no difference is this far back.
const LONG_AGO: i64 = i64::MIN;

impl Clock {
    /// A digest counting times from `now` (microseconds), FC events from
    /// `event_now` (milliseconds) and FC sequence numbers from `seq_now`;
    /// a time more than `r.memory` back is long ago, so is an event more
    /// than `r.events` old.
    pub fn new(now: Moment, event_now: u32, seq_now: u8, r: &Relevance) -> Self {
        Clock {
            h: hasher(),
            now,
            event_now,
            seq_now,
            memory: r.memory.as_micros() as u64,
            events: r.events.as_micros() as u64,
        }
    }

    /// The same counts, another clock's now (each node's clock starts at
    /// its boot).
    pub fn at(&mut self, now: Moment) -> &mut Self {
        self.now = now;
        self
    }

    /// The FC event id of now.
    pub fn event_now(&self) -> u32 {
        self.event_now
    }

    /// A signing time (of a frame, a signer, a verifier), counted from
    /// now's: every frame a node can still receive was signed at this
    /// instant or later (frames in flight and the stranger's captures
    /// never outlive their instant), so any earlier time compares with
    /// all of them alike and digests as long ago.
    pub fn signing(&mut self, ts: u64) {
        let now = crate::wire::signing_time(self.now);
        self.h.write_i64(if ts < now {
            LONG_AGO
        } else {
            (ts - now) as i64
        });
    }

    /// A time a check compares with now against `matters` at most: past
    /// it, long ago (as is none).
    pub fn age(&mut self, t: Option<Moment>, matters: Duration) {
        let since = t.map(|t| self.now.0 as i64 - t.0 as i64);
        let old = since.is_none_or(|s| s > matters.as_micros() as i64);
        self.h
            .write_i64(if old { LONG_AGO } else { since.unwrap_or(0) });
    }

    /// A fresh digest with the same counts, for a part hashed apart.
    pub fn part(&self) -> Clock {
        Clock {
            h: hasher(),
            ..*self
        }
    }
}

impl Hasher for Clock {
    fn finish(&self) -> u64 {
        self.h.finish()
    }

    fn write(&mut self, bytes: &[u8]) {
        self.h.write(bytes);
    }
}

impl Digest for Clock {
    fn instant(&mut self, t: Moment) {
        let since = self.now.0 as i64 - t.0 as i64;
        let past = since > self.memory as i64;
        self.h.write_i64(if past { LONG_AGO } else { since });
    }

    fn event(&mut self, event: u32) {
        let since_ms = i64::from(self.event_now.wrapping_sub(event) as i32);
        let past = since_ms * 1000 > self.events as i64;
        self.h.write_i64(if past { LONG_AGO } else { since_ms });
    }

    fn instant_within(&mut self, t: Moment, lapse: Duration) {
        let since = self.now.0 as i64 - t.0 as i64;
        let past = since > (lapse.as_micros() as i64).min(self.memory as i64);
        self.h.write_i64(if past { LONG_AGO } else { since });
    }

    fn sequence(&mut self, seq: u8) {
        self.h.write_u8(self.seq_now.wrapping_sub(seq));
    }
}

/// One side: its node, its MAVLink endpoint, and its boot.
#[derive(Clone, Debug)]
pub struct Side<N> {
    /// The node (shared by the states it did not change in).
    pub node: Arc<N>,
    /// Framing and signing.
    pub link: Endpoint,
    /// When it last booted (its own clock reads `now - boot`).
    pub boot: Moment,
    /// Boots so far (0: the first run).
    pub boots: u8,
}

impl<N: Clone> Side<N> {
    /// Runs `f` on a copy of the node and keeps the result.
    pub fn update<R>(&mut self, f: impl FnOnce(&mut N) -> R) -> R {
        f(Arc::make_mut(&mut self.node))
    }
}

/// Notices sent, per sender, FC boot, status and event (for the retry
/// bound).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Sent {
    /// The sender.
    pub from: Party,
    /// The FC boot whose event it is: an FC restarted counts its event
    /// ids from 0 again, so one id may name an event of each boot. The
    /// companion's notice of an event is of the latest boot that
    /// announced it.
    pub boot: u8,
    /// `failsafe_status`.
    pub status: u8,
    /// `timestamp`: the event.
    pub event: u32,
    /// How many.
    pub count: u8,
    /// When the first went out.
    pub first: Moment,
}

/// A frame a node authenticated at this instant, which the stranger
/// captured and may replay (from the sender's address) until the clock
/// moves on.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Recording {
    /// The side that authenticated it.
    pub to: Party,
    /// Its bytes.
    pub bytes: Vec<u8>,
}

/// What the invariants read besides the nodes, recorded by the harness.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash)]
pub struct Ghost {
    /// Invariants broken at a transition (bit = index in
    /// [`crate::props::INVARIANTS`]).
    pub broken: u32,
    /// The product's documented gap was reached: a replay authenticated by
    /// a side restarted without its signing state. Nothing is claimed past
    /// it (see the threat model), so the search stops there.
    pub gap: bool,
    /// When the pilot's receiver last changed (lost or back).
    pub rc_changed: Moment,
    /// When the FC entered its current handshake.
    pub handshake_since: Option<Moment>,
    /// In companion control, when the FC entered it or last applied
    /// control, whichever is later.
    pub controlled: Option<Moment>,
    /// When the FC last left companion control (mode change or reboot).
    pub left_companion: Option<Moment>,
    /// When the FC last authenticated a frame of the companion.
    pub fc_heard_cc: Option<Moment>,
    /// When the companion started controlling (its current boot).
    pub cc_started: Option<Moment>,
    /// When the companion last took a frame of the FC as input.
    pub cc_heard_fc: Option<Moment>,
    /// When the companion last took a frame of the FC other than a
    /// heartbeat as input (a heartbeat shows the FC's mode: it may end
    /// control, never prolong it).
    pub cc_heard_fc_news: Option<Moment>,
    /// When a confirmation of companion control (an FBWAG heartbeat, a
    /// takeover text) of the FC last reached the companion.
    pub confirmation: Option<Moment>,
    /// When the autonomy's last control frame reached the companion's
    /// current boot (none: not yet).
    pub autonomy_heard: Option<Moment>,
    /// The newest event the FC announced in its current boot, with its
    /// status.
    pub fc_newest: Option<(u8, u32)>,
    /// Notices sent in the current boot of each sender.
    pub sent: Vec<Sent>,
    /// The newest signing time each side (FC, companion) authenticated in
    /// its current signing state: replay protection's own record.
    pub authenticated: [Option<u64>; 2],
    /// The last signing time each side signed in its signing state.
    pub signed: [Option<u64>; 2],
    /// What the stranger captured at this instant.
    pub recordings: Vec<Recording>,
    /// Receiver flips so far.
    pub rc_flips: u8,
    /// Duplicates so far.
    pub dups: u8,
    /// Autonomy silences and returns so far.
    pub autonomy_flips: u8,
    /// Planted fault (c): the last acknowledgement of the companion, kept
    /// for a replay after the FC reboots.
    pub recorded_ack: Option<InFlight>,
}

/// Steps from the initial state on the path that first reached a state:
/// not part of the state (equal states reached by longer paths are the
/// same state), so it neither hashes nor compares.
#[derive(Clone, Copy, Debug, Default)]
pub struct Steps(pub usize);

/// The whole model state.
#[derive(Clone, Debug)]
pub struct State {
    /// Steps from the start (see [`Steps`]).
    pub steps: Steps,
    /// Virtual time.
    pub now: Moment,
    /// The flight controller.
    pub fc: Side<FcNode>,
    /// The companion.
    pub cc: Side<CompanionNode>,
    /// Frames on their way to the companion.
    pub to_cc: Vec<InFlight>,
    /// Frames on their way to the FC.
    pub to_fc: Vec<InFlight>,
    /// The pilot's receiver works.
    pub rc_ok: bool,
    /// The autonomy streams its control.
    pub autonomy_speaks: bool,
    /// Facts for the invariants.
    pub ghost: Ghost,
    /// The state's identity (see the module docs), set by
    /// [`crate::DelegationModel::step`].
    pub digest: u64,
}

impl Hash for State {
    fn hash<H: Hasher>(&self, h: &mut H) {
        self.digest.hash(h);
    }
}

impl PartialEq for State {
    fn eq(&self, other: &Self) -> bool {
        self.digest == other.digest
    }
}

impl Eq for State {}

impl State {
    /// The FC's own clock.
    pub fn fc_now(&self) -> Moment {
        Moment(self.now.0 - self.fc.boot.0)
    }

    /// The companion's own clock.
    pub fn cc_now(&self) -> Moment {
        Moment(self.now.0 - self.cc.boot.0)
    }

    /// The FC's next deadline, in model time.
    pub fn fc_deadline(&self) -> Option<Moment> {
        let t = self.fc.node.poll_timeout()?;
        Some(Moment(self.fc.boot.0 + t.0))
    }

    /// The companion's next deadline, in model time.
    pub fn cc_deadline(&self) -> Option<Moment> {
        let t = self.cc.node.poll_timeout()?;
        Some(Moment(self.cc.boot.0 + t.0))
    }

    /// The earliest deadline of either node.
    pub fn earliest(&self) -> Option<Moment> {
        [self.fc_deadline(), self.cc_deadline()]
            .into_iter()
            .flatten()
            .min()
    }

    /// The digest of the whole state (see the module docs); `anchored`:
    /// the FC may still restart, so its uptime and sequence number count
    /// as they are.
    pub fn compute_digest(&self, r: &Relevance, anchored: bool) -> u64 {
        let fc_now = self.fc_now();
        let event_now = fc_now.as_millis() as u32;
        let mut d = Clock::new(self.now, event_now, self.fc.link.seq, r);
        self.fc.node.digest(d.at(fc_now));
        self.cc.node.digest(d.at(self.cc_now()));
        d.at(self.now);
        for side in [&self.fc.link, &self.cc.link] {
            side.digest(&mut d);
        }
        (self.fc.boots, self.cc.boots, anchored).hash(&mut d);
        if anchored {
            (fc_now, self.fc.link.seq).hash(&mut d);
        }
        d.age(Some(self.fc.boot), r.rc);
        for queue in [&self.to_cc, &self.to_fc] {
            let mut frames: Vec<u64> = queue.iter().map(|f| self.frame_digest(f, &d)).collect();
            frames.sort_unstable();
            frames.hash(&mut d);
        }
        (self.rc_ok, self.autonomy_speaks).hash(&mut d);
        self.ghost_digest(r, &mut d);
        d.finish()
    }

    fn frame_digest(&self, f: &InFlight, d: &Clock) -> u64 {
        let mut part = d.part();
        (f.from, self.fc.boots.wrapping_sub(f.fc_boot)).hash(&mut part);
        crate::wire::digest_frame(&f.bytes, f.from == Party::Fc, &mut part);
        part.finish()
    }

    /// The ghost's facts, each as far as an invariant can still read it.
    fn ghost_digest(&self, r: &Relevance, d: &mut Clock) {
        let g = &self.ghost;
        (g.broken, g.gap, g.rc_flips, g.dups, g.autonomy_flips).hash(d);
        d.age(Some(g.rc_changed), r.rc);
        d.age(g.autonomy_heard, r.silence);
        let fc = self.fc.node.engine().authority();
        let cc = self.cc.node.engine();
        match fc {
            Authority::Handshake => d.age(g.handshake_since, r.handshake),
            Authority::Companion => {
                d.age(g.controlled, r.override_);
                d.age(g.fc_heard_cc, r.heartbeat);
            }
            Authority::Pilot | Authority::Rtl => {}
        }
        match cc.state() {
            CcState::Idle => {}
            CcState::Standby => d.age(g.cc_heard_fc, r.fc_timeout),
            CcState::Controlling => {
                d.age(g.cc_heard_fc, r.stop);
                d.age(g.confirmation, r.lease);
                if fc != Authority::Companion {
                    let from = g.cc_started.max(g.left_companion).max(g.cc_heard_fc_news);
                    d.age(from, r.stop);
                    d.age(g.left_companion, r.belief);
                }
            }
        }
        g.fc_newest.is_some().hash(d);
        if let Some((status, event)) = g.fc_newest {
            status.hash(d);
            d.event(event);
        }
        let mut sent: Vec<u64> = g
            .sent
            .iter()
            .map(|n| {
                let mut part = d.part();
                (n.from, self.fc.boots.wrapping_sub(n.boot), n.status).hash(&mut part);
                part.event(n.event);
                // Past its retries, a notice's count no longer matters:
                // one more would break notices-end.
                if self.now.since(n.first) <= r.notices {
                    n.count.hash(&mut part);
                    part.age(Some(n.first), r.notices);
                }
                part.finish()
            })
            .collect();
        sent.sort_unstable();
        sent.hash(d);
        for ts in g.authenticated.iter().chain(&g.signed) {
            ts.is_some().hash(d);
            if let Some(ts) = ts {
                d.signing(*ts);
            }
        }
        let mut recordings: Vec<u64> = g
            .recordings
            .iter()
            .map(|rec| {
                let mut part = d.part();
                rec.to.hash(&mut part);
                crate::wire::digest_frame(&rec.bytes, rec.to == Party::Cc, &mut part);
                part.finish()
            })
            .collect();
        recordings.sort_unstable();
        recordings.hash(d);
        g.recorded_ack.is_some().hash(d);
        if let Some(f) = &g.recorded_ack {
            let mut part = d.part();
            crate::wire::digest_frame(&f.bytes, false, &mut part);
            part.finish().hash(d);
        }
    }
}

/// How long each fact of the ghost can matter to an invariant (each
/// bound, plus a step of the grid): past it, a fact digests as long ago.
#[derive(Debug, Clone, Copy)]
pub struct Relevance {
    /// Anything (see [`crate::setup::memory`]).
    pub memory: Duration,
    /// An event id: a notice reaching the FC is of an event at most both
    /// sides' retries old (the companion answers up to 3 s after the FC's
    /// last notice of it, itself up to 3 s after the first), one reaching
    /// the companion at most the FC's; older events compare with them
    /// alike. (That no notice comes later is `notices-end`.)
    pub events: Duration,
    /// A receiver change, a boot: the receiver samples to react.
    pub rc: Duration,
    /// The autonomy's last frame: its silence.
    pub silence: Duration,
    /// A handshake's start.
    pub handshake: Duration,
    /// Companion control without control: the override timeout.
    pub override_: Duration,
    /// The FC hearing the companion: the companion-silence timeout.
    pub heartbeat: Duration,
    /// The companion hearing the FC, standing by.
    pub fc_timeout: Duration,
    /// The companion controlling: how long it may.
    pub stop: Duration,
    /// A confirmation: the lease.
    pub lease: Duration,
    /// The FC leaving companion control: the companion's belief.
    pub belief: Duration,
    /// A notice's retries.
    pub notices: Duration,
}
