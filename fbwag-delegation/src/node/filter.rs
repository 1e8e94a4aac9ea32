//! What a link lets through: per-link, per-direction filters of routed
//! frames ([`Filter`], built from [`FilterRules`]) and the
//! de-duplication of frames that arrive twice ([`Dedup`]).
//!
//! A filter decides on three things of a frame's header: its message id,
//! its source system and its source component. For each, an allow list,
//! when given, admits only what it lists, and a block list removes what it
//! lists (a block outranks an allow: `allow-sys=1-10` with `block-sys=3`
//! admits 1, 2 and 4 to 10). A frame passes when all three admit it.
//! The rules are folded once, when the filter is built, into one set per
//! kind, so judging a frame is two bit tests and a binary search over at
//! most [`MAX_MSG_IDS`] ids, without allocation.

use crate::Moment;
use core::fmt;
use core::time::Duration;
use fbwag_dialect::mavframe::MessageSet;
use fbwag_dialect::{Dialect, Frame};

/// Which way a frame crosses a link.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Direction {
    /// Frames the link delivers: a frame the in-filter refuses is dropped
    /// before routing ([`DropReason::Filtered`](super::DropReason)).
    In,
    /// Frames routed to the link: the out-filter removes the link from the
    /// route of a frame it refuses.
    Out,
}

/// A set of 8-bit ids (systems or components): a bit each; empty by
/// default.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct IdSet([u64; 4]);

impl IdSet {
    /// No id.
    pub const NONE: IdSet = IdSet([0; 4]);
    /// Every id.
    pub const ALL: IdSet = IdSet([u64::MAX; 4]);

    /// Whether `id` is in the set.
    pub const fn contains(&self, id: u8) -> bool {
        (self.0[(id >> 6) as usize] >> (id & 63)) & 1 == 1
    }

    /// Adds `id`.
    pub fn insert(&mut self, id: u8) {
        self.0[usize::from(id >> 6)] |= 1 << (id & 63);
    }

    /// The ids of `self` not in `other`.
    pub const fn difference(self, other: IdSet) -> IdSet {
        let (a, b) = (self.0, other.0);
        IdSet([a[0] & !b[0], a[1] & !b[1], a[2] & !b[2], a[3] & !b[3]])
    }

    /// Whether the set holds no id.
    pub const fn is_empty(&self) -> bool {
        self.0[0] | self.0[1] | self.0[2] | self.0[3] == 0
    }

    /// The ids, in order.
    pub fn iter(self) -> impl Iterator<Item = u8> {
        (0..=u8::MAX).filter(move |id| self.contains(*id))
    }
}

impl fmt::Debug for IdSet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if *self == IdSet::ALL {
            return f.write_str("all");
        }
        f.debug_list().entries(self.iter()).finish()
    }
}

/// Message ids a filter lists at most, per direction: each list of
/// [`FilterRules`], and what is left once they are folded.
pub const MAX_MSG_IDS: usize = 16;

/// The largest MAVLink 2 message id (24 bits).
const MAX_MSG_ID: u32 = 0xFF_FFFF;
/// The highest system or component id.
const SYS_COMP_MAX: u32 = u8::MAX as u32;

/// A sorted list of at most [`MAX_MSG_IDS`] message ids.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
struct MsgIds {
    ids: [u32; MAX_MSG_IDS],
    len: u8,
}

impl MsgIds {
    fn as_slice(&self) -> &[u32] {
        self.ids.get(..usize::from(self.len)).unwrap_or(&[])
    }

    fn contains(&self, id: u32) -> bool {
        self.as_slice().binary_search(&id).is_ok()
    }

    fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Adds `id` in its place (a second time is a no-op).
    fn insert(&mut self, id: u32) -> Result<(), FilterError> {
        let Err(at) = self.as_slice().binary_search(&id) else {
            return Ok(());
        };
        let len = usize::from(self.len);
        if len == MAX_MSG_IDS {
            return Err(FilterError::TooManyMsgIds);
        }
        self.ids.copy_within(at..len, at + 1);
        self.ids[at] = id;
        self.len += 1;
        Ok(())
    }

    /// The ids of `self` not in `other`.
    fn difference(&self, other: &MsgIds) -> MsgIds {
        let mut out = MsgIds::default();
        for id in self.as_slice().iter().filter(|id| !other.contains(**id)) {
            out.ids[usize::from(out.len)] = *id;
            out.len += 1;
        }
        out
    }
}

impl fmt::Debug for MsgIds {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.as_slice()).finish()
    }
}

/// Which frames one direction of a link lets through: every allow list
/// given admits only what it lists, every block list removes what it
/// lists (outranking an allow list), and a frame passes when its message
/// id, source system and source component all pass. Small (136 bytes),
/// `Copy`, and [`Filter::ALL`] by default.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct Filter {
    systems: IdSet,
    components: IdSet,
    msgs: MsgIds,
    /// `msgs` are the only ids admitted (an allow list); else they are
    /// the ids refused.
    msgs_only: bool,
}

impl Filter {
    /// Lets every frame through.
    pub const ALL: Filter = Filter {
        systems: IdSet::ALL,
        components: IdSet::ALL,
        msgs: MsgIds {
            ids: [0; MAX_MSG_IDS],
            len: 0,
        },
        msgs_only: false,
    };

    /// Whether a frame of message `msg_id` from `sysid`/`compid` passes.
    pub fn admits(&self, msg_id: u32, sysid: u8, compid: u8) -> bool {
        self.systems.contains(sysid)
            && self.components.contains(compid)
            && self.msgs.contains(msg_id) == self.msgs_only
    }

    /// Whether `frame` passes.
    pub fn admits_frame(&self, frame: &Frame<&[u8]>) -> bool {
        let h = frame.header();
        self.admits(frame.msg_id(), h.sysid, h.compid)
    }

    /// Whether it lets every frame through.
    pub fn is_all(&self) -> bool {
        *self == Filter::ALL
    }
}

impl Default for Filter {
    fn default() -> Self {
        Filter::ALL
    }
}

impl fmt::Debug for Filter {
    // Short for the filter every link has unless told otherwise: nodes'
    // Debug text is what the model checker tells states apart by.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_all() {
            return f.write_str("Filter::ALL");
        }
        f.debug_struct("Filter")
            .field("systems", &self.systems)
            .field("components", &self.components)
            .field(
                if self.msgs_only {
                    "msgs_only"
                } else {
                    "msgs_not"
                },
                &self.msgs,
            )
            .finish()
    }
}

/// One kind of rule.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Rule {
    /// Only these message ids (`allow-msg`).
    AllowMsg,
    /// Not these message ids (`block-msg`).
    BlockMsg,
    /// Only these source systems (`allow-sys`).
    AllowSys,
    /// Not these source systems (`block-sys`).
    BlockSys,
    /// Only these source components (`allow-comp`).
    AllowComp,
    /// Not these source components (`block-comp`).
    BlockComp,
}

impl Rule {
    /// Every kind.
    pub const ALL: [Rule; 6] = [
        Rule::AllowMsg,
        Rule::BlockMsg,
        Rule::AllowSys,
        Rule::BlockSys,
        Rule::AllowComp,
        Rule::BlockComp,
    ];

    /// Its name in rule text.
    pub const fn name(self) -> &'static str {
        match self {
            Rule::AllowMsg => "allow-msg",
            Rule::BlockMsg => "block-msg",
            Rule::AllowSys => "allow-sys",
            Rule::BlockSys => "block-sys",
            Rule::AllowComp => "allow-comp",
            Rule::BlockComp => "block-comp",
        }
    }

    fn is_msg(self) -> bool {
        matches!(self, Rule::AllowMsg | Rule::BlockMsg)
    }
}

/// Why rule text or an id was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FilterError {
    /// Text before `=` that is not a rule's name.
    UnknownRule,
    /// No `=`, or no id after it.
    NoIds,
    /// A message id that is neither a number nor a message of the dialect.
    UnknownMessage,
    /// A system or component id that is not a number or a range `A-B`
    /// (`A` ≤ `B`).
    BadId,
    /// A number past the rule's range.
    OutOfRange {
        /// The highest id the rule takes: 255 for systems and components,
        /// 2²⁴−1 for messages.
        max: u32,
    },
    /// More than [`MAX_MSG_IDS`] message ids in one list.
    TooManyMsgIds,
}

impl fmt::Display for FilterError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FilterError::UnknownRule => f.write_str(
                "a rule is allow-msg, block-msg, allow-sys, block-sys, allow-comp or block-comp",
            ),
            FilterError::NoIds => f.write_str("a rule is NAME=ID[,ID...]"),
            FilterError::UnknownMessage => {
                f.write_str("a message is a number or a message name of the dialect")
            }
            FilterError::BadId => {
                f.write_str("a system or component is a number or a range A-B (0-255)")
            }
            FilterError::OutOfRange { max } => write!(f, "an id is at most {max}"),
            FilterError::TooManyMsgIds => write!(f, "more than {MAX_MSG_IDS} message ids"),
        }
    }
}

impl core::error::Error for FilterError {}

/// The rules of one direction of a link, as given; [`FilterRules::filter`]
/// folds them into a [`Filter`]. An empty allow list is no allow list.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FilterRules {
    allow_msgs: MsgIds,
    block_msgs: MsgIds,
    allow_sys: Option<IdSet>,
    block_sys: IdSet,
    allow_comp: Option<IdSet>,
    block_comp: IdSet,
}

impl FilterRules {
    /// No rule: every frame passes.
    pub fn new() -> Self {
        FilterRules::default()
    }

    /// Adds `id` to the list of `rule`.
    pub fn add(&mut self, rule: Rule, id: u32) -> Result<(), FilterError> {
        if rule.is_msg() {
            if id > MAX_MSG_ID {
                return Err(FilterError::OutOfRange { max: MAX_MSG_ID });
            }
            let list = match rule {
                Rule::AllowMsg => &mut self.allow_msgs,
                _ => &mut self.block_msgs,
            };
            return list.insert(id);
        }
        let id = u8::try_from(id).map_err(|_| FilterError::OutOfRange { max: SYS_COMP_MAX })?;
        match rule {
            Rule::AllowSys => self.allow_sys.get_or_insert(IdSet::NONE).insert(id),
            Rule::BlockSys => self.block_sys.insert(id),
            Rule::AllowComp => self.allow_comp.get_or_insert(IdSet::NONE).insert(id),
            _ => self.block_comp.insert(id),
        }
        Ok(())
    }

    /// Adds a rule given as text, `NAME=ID[,ID...]`: `allow-msg=0,ATTITUDE`,
    /// `block-sys=200-210`. Messages are numbers or names of the dialect
    /// (any case); systems and components are numbers or ranges `A-B`.
    pub fn parse(&mut self, text: &str) -> Result<(), FilterError> {
        let (name, ids) = text.split_once('=').ok_or(FilterError::NoIds)?;
        let rule = Rule::ALL
            .into_iter()
            .find(|r| r.name().eq_ignore_ascii_case(name.trim()))
            .ok_or(FilterError::UnknownRule)?;
        let mut any = false;
        for item in ids.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            any = true;
            if rule.is_msg() {
                self.add(rule, msg_id(item)?)?;
            } else {
                let (from, to) = id_range(item)?;
                for id in from..=to {
                    self.add(rule, id)?;
                }
            }
        }
        if any {
            Ok(())
        } else {
            Err(FilterError::NoIds)
        }
    }

    /// Whether a `block-msg` rule names message `id`.
    pub fn blocks_msg(&self, id: u32) -> bool {
        self.block_msgs.contains(id)
    }

    /// The filter these rules make.
    pub fn filter(&self) -> Filter {
        let (msgs, msgs_only) = if self.allow_msgs.is_empty() {
            (self.block_msgs, false)
        } else {
            (self.allow_msgs.difference(&self.block_msgs), true)
        };
        Filter {
            systems: self
                .allow_sys
                .unwrap_or(IdSet::ALL)
                .difference(self.block_sys),
            components: self
                .allow_comp
                .unwrap_or(IdSet::ALL)
                .difference(self.block_comp),
            msgs,
            msgs_only,
        }
    }
}

/// A message id: a number, or a name the dialect knows.
fn msg_id(item: &str) -> Result<u32, FilterError> {
    if item.bytes().all(|b| b.is_ascii_digit()) {
        return item
            .parse()
            .map_err(|_| FilterError::OutOfRange { max: MAX_MSG_ID });
    }
    <Dialect as MessageSet>::MESSAGES
        .iter()
        .find(|m| m.name.eq_ignore_ascii_case(item))
        .map(|m| m.id)
        .ok_or(FilterError::UnknownMessage)
}

/// A system or component id, or a range `A-B`, as numbers (checked
/// against 255 when added).
fn id_range(item: &str) -> Result<(u32, u32), FilterError> {
    let number = |s: &str| {
        let s = s.trim();
        if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
            return Err(FilterError::BadId);
        }
        s.parse::<u32>()
            .map_err(|_| FilterError::OutOfRange { max: SYS_COMP_MAX })
    };
    let (from, to) = match item.split_once('-') {
        Some((a, b)) => (number(a)?, number(b)?),
        None => (number(item)?, number(item)?),
    };
    if from > to {
        return Err(FilterError::BadId);
    }
    // Checked here so that a huge range is refused before it is walked.
    if to > SYS_COMP_MAX {
        return Err(FilterError::OutOfRange { max: SYS_COMP_MAX });
    }
    Ok((from, to))
}

/// Frames remembered for de-duplication: at most this many frames within
/// one window are recognised when they come again.
pub const DEDUP_SLOTS: usize = 128;

/// Frames seen lately, to drop a second copy of one (identical bytes)
/// that arrives within the window, as redundant links deliver: a ring of
/// [`DEDUP_SLOTS`] 64-bit hashes with the time each was first seen
/// (2 KiB, whatever the traffic). The window counts from the copy that
/// went on: a copy seen after it passes again, and starts a new window.
///
/// The hash (FNV-1a over the whole frame) is not secret: a frame made to
/// collide with one a sender will send could suppress it, but making it
/// means predicting those bytes (sequence number, payload, signature),
/// and whoever can do that can send the frame itself first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Dedup {
    window: Duration,
    seen: [(u64, Moment); DEDUP_SLOTS],
    /// Slots filled (they fill in order, then the ring wraps).
    len: usize,
    /// The slot the next frame takes.
    next: usize,
}

impl Dedup {
    /// Remembers frames for `window`.
    pub fn new(window: Duration) -> Self {
        Dedup {
            window,
            seen: [(0, Moment::ZERO); DEDUP_SLOTS],
            len: 0,
            next: 0,
        }
    }

    /// The window.
    pub fn window(&self) -> Duration {
        self.window
    }

    /// Feeds `d` the frames remembered and when (see [`crate::digest`]).
    pub(super) fn digest(&self, d: &mut impl crate::digest::Digest) {
        use core::hash::Hash;
        let Dedup {
            window,
            seen,
            len,
            next,
        } = self;
        (window, len, next).hash(d);
        for (hash, at) in seen.get(..*len).unwrap_or(&[]) {
            hash.hash(d);
            d.instant_within(*at, *window);
        }
    }

    /// Whether `bytes` were seen less than the window before `now`; if
    /// not, they are remembered from `now`.
    pub fn is_duplicate(&mut self, bytes: &[u8], now: Moment) -> bool {
        let hash = fnv1a(bytes);
        let window = self.window;
        let seen = self.seen.get(..self.len).unwrap_or(&[]);
        if seen
            .iter()
            .any(|(h, at)| *h == hash && now.since(*at) < window)
        {
            return true;
        }
        // A frame seen before the window is remembered afresh where it
        // was, so it takes one slot however often it comes.
        let slot = seen
            .iter()
            .position(|(h, _)| *h == hash)
            .unwrap_or_else(|| {
                let slot = self.next;
                self.next = (self.next + 1) % DEDUP_SLOTS;
                self.len = (self.len + 1).min(DEDUP_SLOTS);
                slot
            });
        if let Some(entry) = self.seen.get_mut(slot) {
            *entry = (hash, now);
        }
        false
    }
}

/// FNV-1a, 64 bits.
fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ u64::from(*b)).wrapping_mul(0x0100_0000_01b3)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rules(texts: &[&str]) -> Filter {
        let mut r = FilterRules::new();
        for t in texts {
            r.parse(t).unwrap();
        }
        r.filter()
    }

    #[test]
    fn no_rule_admits_everything() {
        let f = FilterRules::new().filter();
        assert!(f.is_all());
        assert!(f.admits(0, 0, 0) && f.admits(MAX_MSG_ID, 255, 255));
    }

    #[test]
    fn an_allow_list_admits_only_what_it_lists() {
        let f = rules(&["allow-msg=0,ATTITUDE", "allow-sys=1,255"]);
        assert!(f.admits(0, 1, 1));
        assert!(f.admits(30, 255, 190));
        assert!(!f.admits(33, 1, 1), "GLOBAL_POSITION_INT is not listed");
        assert!(!f.admits(0, 2, 1), "system 2 is not listed");
    }

    #[test]
    fn a_block_list_removes_what_it_lists_and_outranks_an_allow_list() {
        let f = rules(&["block-sys=3", "allow-sys=1-10"]);
        let admitted: Vec<u8> = (0..=255).filter(|s| f.admits(0, *s, 1)).collect();
        assert_eq!(admitted, [1, 2, 4, 5, 6, 7, 8, 9, 10]);
        let f = rules(&["allow-msg=0,30", "block-msg=heartbeat"]);
        assert!(f.admits(30, 1, 1) && !f.admits(0, 1, 1) && !f.admits(33, 1, 1));
        // Everything allowed is blocked: nothing passes.
        let f = rules(&["allow-comp=1", "block-comp=1"]);
        assert!((0..=255).all(|c| !f.admits(0, 1, c)));
        let f = rules(&["allow-msg=0", "block-msg=0"]);
        assert!(!f.admits(0, 1, 1) && !f.admits(1, 1, 1));
    }

    #[test]
    fn the_three_kinds_must_all_admit() {
        let f = rules(&["block-msg=33", "allow-comp=1", "block-sys=9"]);
        assert!(f.admits(0, 1, 1));
        assert!(!f.admits(33, 1, 1));
        assert!(!f.admits(0, 1, 2));
        assert!(!f.admits(0, 9, 1));
    }

    #[test]
    fn bad_rule_text_is_refused_with_its_reason() {
        let mut r = FilterRules::new();
        for (text, error) in [
            ("allow-msg", FilterError::NoIds),
            ("allow-msg=", FilterError::NoIds),
            ("allow-msg= , ", FilterError::NoIds),
            ("permit-msg=1", FilterError::UnknownRule),
            ("allow-msg=NO_SUCH_MESSAGE", FilterError::UnknownMessage),
            (
                "allow-msg=16777216",
                FilterError::OutOfRange { max: 16_777_215 },
            ),
            (
                "allow-msg=99999999999",
                FilterError::OutOfRange { max: 16_777_215 },
            ),
            ("block-sys=256", FilterError::OutOfRange { max: 255 }),
            (
                "block-sys=0-4000000000",
                FilterError::OutOfRange { max: 255 },
            ),
            (
                "block-comp=1-99999999999",
                FilterError::OutOfRange { max: 255 },
            ),
            ("block-sys=9-3", FilterError::BadId),
            ("block-comp=x", FilterError::BadId),
            ("block-comp=-", FilterError::BadId),
        ] {
            assert_eq!(r.parse(text), Err(error), "{text}");
        }
        let many: Vec<String> = (0..=MAX_MSG_IDS).map(|i| i.to_string()).collect();
        let text = format!("block-msg={}", many.join(","));
        assert_eq!(r.parse(&text), Err(FilterError::TooManyMsgIds));
        // An id given twice takes one place.
        let mut r = FilterRules::new();
        let same = vec!["7"; MAX_MSG_IDS + 4].join(",");
        r.parse(&format!("allow-msg={same}")).unwrap();
        assert!(r.filter().admits(7, 1, 1) && !r.filter().admits(8, 1, 1));
    }

    #[test]
    fn a_filter_is_small_and_its_debug_text_short_when_it_admits_all() {
        assert!(core::mem::size_of::<Filter>() <= 136);
        assert_eq!(format!("{:?}", Filter::ALL), "Filter::ALL");
        let f = rules(&["allow-sys=1,2", "block-msg=0"]);
        assert_eq!(
            format!("{f:?}"),
            "Filter { systems: [1, 2], components: all, msgs_not: [0] }"
        );
    }

    const MS: u64 = 1000;

    #[test]
    fn a_copy_within_the_window_is_a_duplicate_and_after_it_is_not() {
        let mut d = Dedup::new(Duration::from_millis(100));
        let (a, b) = ([0xfd, 1, 2, 3], [0xfd, 1, 2, 4]);
        assert!(!d.is_duplicate(&a, Moment(0)));
        assert!(d.is_duplicate(&a, Moment(99 * MS)));
        assert!(!d.is_duplicate(&b, Moment(99 * MS)), "other bytes");
        // The window counts from the copy that went on.
        assert!(!d.is_duplicate(&a, Moment(100 * MS)));
        assert!(d.is_duplicate(&a, Moment(150 * MS)));
        assert!(!d.is_duplicate(&a, Moment(200 * MS)));
        // One slot for a frame however often it comes.
        assert_eq!(d.len, 2);
    }

    #[test]
    fn memory_stays_bounded_and_the_oldest_frame_is_forgotten_first() {
        let mut d = Dedup::new(Duration::from_secs(60));
        let frame = |i: usize| (i as u32).to_le_bytes();
        for i in 0..DEDUP_SLOTS * 3 {
            assert!(!d.is_duplicate(&frame(i), Moment(i as u64)));
        }
        assert_eq!(d.len, DEDUP_SLOTS);
        let now = Moment(1_000_000);
        // The last DEDUP_SLOTS frames are remembered, the ones before not.
        let last = DEDUP_SLOTS * 3 - 1;
        assert!(d.is_duplicate(&frame(last), now));
        assert!(d.is_duplicate(&frame(last + 1 - DEDUP_SLOTS), now));
        assert!(!d.is_duplicate(&frame(last - DEDUP_SLOTS), now));
        assert!(core::mem::size_of::<Dedup>() <= DEDUP_SLOTS * 16 + 64);
    }
}
