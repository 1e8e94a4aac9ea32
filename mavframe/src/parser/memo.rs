//! What the parser remembers about the bytes after its current candidate
//! frame, so that each input byte costs a bounded amount of work, whatever
//! the input.
//!
//! The parser decides about one candidate (a start byte) at a time and,
//! when it rejects one, resumes at the next start byte. Two of its
//! decisions read far past the candidate, and on input dense in start bytes
//! every candidate would read the same bytes again:
//!
//! - the checksum of a candidate of a known message covers up to 264 bytes;
//! - a candidate of an unknown id is taken only if no good frame of a known
//!   id starts inside it: up to 279 positions, each a checksum.
//!
//! [`Memo`] answers both in amortised constant time per byte:
//!
//! - **Checksums.** The first checksum over fresh bytes is computed directly
//!   (the fast slice-by-16 path, as before: a good frame costs what it did).
//!   A checksum over bytes an earlier one already covered (a candidate
//!   inside a rejected one) comes from *prefix states* instead: the CRC
//!   register after every position of the window, each computed once, one
//!   byte step per position. The CRC is affine over GF(2), so the checksum
//!   of any stretch is a 16-column product of its two end states
//!   ([`crc::between_extra`]). Direct checksums never overlap (each starts at or
//!   after the end of the previous one) and prefix states are computed once
//!   per position, so checksumming costs at most two byte steps per byte.
//! - **Good known frames inside a candidate.** Whether a good frame of a
//!   known id starts at a position depends on the bytes only, so each
//!   position is classified when the scan first reaches it (a *frontier*
//!   that only moves forward), and the answer is kept in a bit ring: good,
//!   or *undecided* (its frame is not whole yet). A position that can still
//!   change waits in a list keyed by the stream position at which it can
//!   (its header's or its frame's end), and is classified again when the
//!   bytes reach it: at most three times in all. "Is there a good frame in
//!   (candidate, end)" and "the first undecided one" are then searches of
//!   at most five words of the rings.
//!
//! Stream positions are absolute (`u64`, bytes pushed before them); the
//! rings index them modulo their size, which exceeds the span of positions
//! alive at once (see the constants).

use super::end_cut::EndCuts;
use super::{msg_id, BYTES_PER_RAW_SIGNATURE_BYTE, RAW_SIGNATURE_BURST};
use crate::crc;
use crate::frame::{
    frame_len, Frame, FrameError, Version, CHECKSUM_LEN, HEADER_LEN_V1, HEADER_LEN_V2, IFLAG_KNOWN,
    IFLAG_SIGNED, MAX_FRAME_LEN, SIGNATURE_LEN, STX_V1, STX_V2,
};
use crate::message::MessageSet;

/// Prefix states kept. A checksum asked for while the candidate is at `c`
/// starts after a position inside the candidate (before `c + MAX_FRAME_LEN`) and
/// covers at most 264 bytes: live states span less than 545 positions.
const PREFIX_RING: usize = 1024;
const PREFIX_MASK: u64 = PREFIX_RING as u64 - 1;
/// Prefix states are computed this far past what a checksum needs...
const PREFIX_AHEAD: u64 = 64;
/// ...but never further than this past the candidate, so that the live
/// states fit the ring (and at least as far as the checksum of a position
/// the scan classifies ahead reaches).
const PREFIX_REACH: u64 = {
    let ahead = 2 * MAX_FRAME_LEN as u64 + PREFIX_AHEAD;
    let scanned = (MAX_FRAME_LEN + SCAN_AHEAD + crc::MAX_COVERED + 1) as u64;
    if ahead > scanned {
        ahead
    } else {
        scanned
    }
};

/// Positions of the inside scan (inside the candidate: fewer than
/// [`MAX_FRAME_LEN`]) and their wake-up positions (at most a frame after
/// the bytes available, which are after those positions).
const SCAN_RING: usize = 512;
const SCAN_MASK: u64 = SCAN_RING as u64 - 1;
const SCAN_WORDS: usize = SCAN_RING / 64;

/// Positions of the MAVLink 1 verdicts: the scan's reach and a block more,
/// so that they are checked by whole blocks from their frontier.
const V1_RING: usize = 1024;
const V1_WORDS: usize = V1_RING / 64;

/// Bytes from a block's first position that hold every MAVLink 1 frame
/// starting in the block (64 positions, then at most 6 + 255 + 2 bytes).
const V1_WINDOW: usize = 64 + HEADER_LEN_V1 + 255 + CHECKSUM_LEN;

/// Positions classified past the end of the candidate asked about, as long
/// as every frame starting there is whole in the bytes at hand (one whose
/// end is not there would wait, to be classified again, and would likely
/// never be asked about). Where frames are cut, only the positions asked
/// about. Keeping a minimum of 32 more there (each scan has a fixed cost,
/// and candidates whose frames end a few bytes apart pay a scan each) costs
/// more: the MAVLink 1 verdicts and the masks are computed by whole blocks
/// for the scan too, so no minimum is cheaper in 300- and 64-byte reads on
/// every input but `many_senders` (+2 %; `found_j` −27 % in 64-byte reads)
/// and the same in 64 KiB reads.
const SCAN_AHEAD: usize = 192;

/// Where the scan for a candidate needing positions before `end` stops, in
/// `len` bytes: see [`SCAN_AHEAD`].
fn scan_end(end: usize, len: usize) -> usize {
    let whole = len.saturating_sub(MAX_FRAME_LEN);
    end.max(whole.min(end + SCAN_AHEAD)).min(len)
}

/// The most the budget for checking unknown ids' signatures holds, in its
/// units (see [`Memo::sig_credit_at`]).
const CREDIT_CAP: u64 = RAW_SIGNATURE_BURST * BYTES_PER_RAW_SIGNATURE_BYTE;

/// Ids above 255 whose CRC_EXTRA [`Memo`] keeps at once.
const V2_EXTRA_SLOTS: usize = 32;

const _: () = assert!(
    PREFIX_RING as u64 > PREFIX_REACH
        && SCAN_RING > MAX_FRAME_LEN + SCAN_AHEAD + 10
        // A checksum of a position scanned ahead ends within reach.
        && PREFIX_REACH >= (MAX_FRAME_LEN + SCAN_AHEAD + crc::MAX_COVERED + 1) as u64
);

/// Whether a good frame of a known id starts inside a candidate (after its
/// first byte, before the end asked about).
#[derive(Debug, PartialEq, Eq)]
pub(super) enum Inside {
    Yes,
    No,
    /// A position inside may still start one: the first such needs this
    /// many bytes (counted from the candidate's start byte) to decide.
    Undecided(usize),
}

/// What [`Memo::classify_start`] found at a start byte.
enum Start {
    /// A whole frame of a known id with a good checksum.
    Good,
    /// A whole frame of a known id with a bad checksum.
    BadCrc,
    /// A whole frame of an unknown id.
    Raw,
    /// Anything else: classified and recorded.
    Other,
}

/// What the bytes available say about one position.
enum Class {
    /// No good frame of a known id starts here, whatever follows.
    NotGood,
    /// A whole frame of a known id with a good checksum starts here.
    Good,
    /// A whole frame of a known id with a bad checksum starts here.
    BadCrc,
    /// Not decided yet; `undecided` when it counts as such for the parser's
    /// rules (see [`Memo::classify`]); decided again once the stream
    /// reaches `wake`.
    Pending { undecided: bool, wake: u64 },
}

/// What [`Memo::v1_checks`] finds of MAVLink 1 start bytes, a bit per
/// position of a block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct V1 {
    /// The frame is whole and of a known id...
    pub(super) whole: u64,
    /// ...and its checksum is good.
    pub(super) good: u64,
    /// The frame is whole and of an unknown id.
    pub(super) raw: u64,
}

impl V1 {
    const NONE: V1 = V1 {
        whole: 0,
        good: 0,
        raw: 0,
    };

    fn masked(self, mask: u64) -> V1 {
        V1 {
            whole: self.whole & mask,
            good: self.good & mask,
            raw: self.raw & mask,
        }
    }
}

/// See the module documentation. About 6 KiB.
pub(super) struct Memo {
    /// `prefix[x % PREFIX_RING]`: the CRC register after the bytes from the
    /// start of the current run of prefix states up to stream position `x`
    /// (exclusive), for `x` up to `prefix_end`.
    prefix: [u16; PREFIX_RING],
    /// End of the prefix states; the run is dead when it is not after the
    /// current candidate.
    prefix_end: u64,
    /// End of the last checksum computed directly: the next direct one
    /// starts at or after it.
    direct_end: u64,
    /// Positions before it (and after the candidate) are classified.
    frontier: u64,
    /// Positions from it to the frontier are classified (the scan jumps
    /// when the candidate passes the frontier).
    scanned_from: u64,
    /// A good known frame starts at the position (bit ring).
    good: [u64; SCAN_WORDS],
    /// A whole frame of a known id with a bad checksum starts at the
    /// position (bit ring): with `good`, the verdict on the checksum when
    /// the position becomes the candidate.
    bad: [u64; SCAN_WORDS],
    /// The position is undecided (bit ring).
    undecided: [u64; SCAN_WORDS],
    /// A whole frame of an unknown id starts at the position (bit ring):
    /// the fast rejection loop's candidates that only the signing policy
    /// or the byte after them can refuse, looked up by the scan first.
    raw: [u64; SCAN_WORDS],
    /// No bit of `good` is set at this position or after it...
    good_before: u64,
    /// ...nor of `undecided`.
    undecided_before: u64,
    /// Lists of pending positions by wake-up position: `wake_head[w % ring]`
    /// is the first one's ring slot + 1 (0: none) in its low 16 bits, the
    /// epoch it was written in above them; `wake_next[slot]` the next
    /// one's. A head of another epoch is an empty list.
    wake_head: [u32; SCAN_RING],
    wake_next: [u16; SCAN_RING],
    /// Bumped by [`Memo::forget_from`]: every list becomes empty at once.
    epoch: u32,
    /// Wake-up positions up to this one have been handled.
    woken: u64,
    /// The largest wake-up position listed.
    last_wake: u64,
    /// Position + 1 of the last whole known frame found good by
    /// [`Memo::candidate_crc_ok`]: asked again when the fast rejection loop
    /// hands the candidate over.
    good_candidate: u64,
    /// Candidate position + 1 of the last unknown-id frame whose signature
    /// failed: the verifier has not changed since (a change needs an
    /// accepted frame, which moves the candidate), so it would fail again.
    raw_signature_failed: u64,
    /// Candidate position + 1 of the last unknown-id frame whose check the
    /// budget paid for: a candidate waiting for bytes is checked again, and
    /// paid for once. (Not forgotten with the bytes: the budget is spent.)
    raw_check_paid: u64,
    /// What the budget for checking unknown ids' signatures holds (see the
    /// parser's module docs and [`Memo::sig_credit_at`]), as of stream
    /// position `sig_credit_at`.
    sig_credit: u64,
    sig_credit_at: u64,
    /// CRC_EXTRA of MAVLink 1 ids (0–255) as the dialect says, looked up
    /// once each: `fold << 16 | 0x200 | 0x100 (known) | crc_extra`, where
    /// `fold` is its [`crc::extra_fold`]; 0 before the first look-up. A
    /// table load instead of the dialect's jump table, whose indirect
    /// branch garbage's random ids keep mispredicting.
    v1_extra: [u32; 256],
    /// `v1_extra` holds every id.
    v1_filled: bool,
    /// The same for some ids above 255 (id, value): see
    /// [`Memo::v2_crc_extra`].
    v2_extra: [(u32, u16); V2_EXTRA_SLOTS],
    /// MAVLink 1 start bytes whose frame was whole and of a known id (bit
    /// ring), and of those the ones with a good checksum, at the positions
    /// from `v1_from` to `v1_frontier` ([`Memo::v1_verdicts`]): the scan and
    /// the fast rejection loop ask about the same positions.
    v1_whole: [u64; V1_WORDS],
    v1_good: [u64; V1_WORDS],
    /// The MAVLink 1 start bytes whose frame was whole and of an unknown
    /// id, at the same positions.
    v1_raw: [u64; V1_WORDS],
    v1_from: u64,
    v1_frontier: u64,
    /// Start bytes by kind, and MAVLink 2 flags other than known, of the
    /// positions from `masks_from` to `masks_frontier` (bit rings): the
    /// scan and every run of the fast rejection loop look at the same
    /// positions again ([`Memo::starts`]).
    mask_v1: [u64; SCAN_WORDS],
    mask_v2: [u64; SCAN_WORDS],
    mask_flags: [u64; SCAN_WORDS],
    masks_from: u64,
    masks_frontier: u64,
    /// The fast rejection loop's last run found start bytes dense (fewer
    /// than its `DENSE` bytes apart): the next one goes by masks at once.
    pub(super) dense_starts: bool,
    /// No state about positions from here on (the frontier, the prefix
    /// states and the last direct checksum all end before): a candidate
    /// there is checked exactly as without a memo.
    busy_until: u64,
    /// At the end of the stream, the start bytes whose frame it cuts.
    pub(super) end_cuts: EndCuts,
    /// Elementary steps taken: see [`super::Work::steps`].
    pub(super) steps: u64,
    /// Signatures checked (SHA-256): see [`super::Work::signatures`].
    pub(super) signatures: u64,
}

/// What the checksum check needs of a whole frame, read from its header
/// once.
#[derive(Debug, Clone, Copy)]
pub(super) struct Whole {
    /// Message id.
    pub(super) id: u32,
    /// Bytes the checksum covers (after the start byte, up to the checksum).
    pub(super) covered: usize,
}

impl Whole {
    /// The frame at the start of `bytes` when its header is whole, its
    /// incompatibility flags known and all its bytes there: what `frame_len`
    /// and `Frame` would say, read once.
    #[inline(always)]
    pub(super) fn at(bytes: &[u8]) -> Option<Whole> {
        let (covered, len, id) = match *bytes.first()? {
            STX_V2 => {
                let h = bytes.get(..HEADER_LEN_V2)?;
                if h[2] & !IFLAG_KNOWN != 0 {
                    return None;
                }
                let sig = if h[2] & IFLAG_SIGNED != 0 {
                    SIGNATURE_LEN
                } else {
                    0
                };
                let covered = HEADER_LEN_V2 - 1 + usize::from(h[1]);
                let id = u32::from_le_bytes([h[7], h[8], h[9], 0]);
                (covered, covered + 1 + CHECKSUM_LEN + sig, id)
            }
            STX_V1 => {
                let covered = HEADER_LEN_V1 - 1 + usize::from(*bytes.get(1)?);
                // A whole MAVLink 1 frame (8 bytes at least) has its id byte.
                (
                    covered,
                    covered + 1 + CHECKSUM_LEN,
                    u32::from(*bytes.get(5)?),
                )
            }
            _ => return None,
        };
        if bytes.len() < len {
            return None;
        }
        Some(Whole { id, covered })
    }

    /// The checksum the frame carries, in its bytes `frame` (from its start
    /// byte): read when a checksum is compared with it, not for every
    /// frame of an unknown id.
    #[inline(always)]
    fn carried(&self, frame: &[u8]) -> Option<u16> {
        let c = frame.get(self.covered + 1..self.covered + 3)?;
        Some(u16::from_le_bytes([c[0], c[1]]))
    }

    /// The same, for a frame already delimited.
    #[inline(always)]
    pub(super) fn of(frame: &Frame<&[u8]>) -> Whole {
        let header = match frame.version() {
            Version::V2 => HEADER_LEN_V2,
            Version::V1 => HEADER_LEN_V1,
        };
        Whole {
            id: frame.msg_id(),
            covered: header - 1 + frame.payload_len(),
        }
    }
}

impl Memo {
    pub(super) const fn new() -> Self {
        Memo {
            prefix: [0; PREFIX_RING],
            prefix_end: 0,
            direct_end: 0,
            frontier: 0,
            scanned_from: 0,
            good: [0; SCAN_WORDS],
            bad: [0; SCAN_WORDS],
            undecided: [0; SCAN_WORDS],
            raw: [0; SCAN_WORDS],
            good_before: 0,
            undecided_before: 0,
            wake_head: [0; SCAN_RING],
            wake_next: [0; SCAN_RING],
            epoch: 1,
            woken: 0,
            last_wake: 0,
            good_candidate: 0,
            raw_signature_failed: 0,
            raw_check_paid: 0,
            sig_credit: CREDIT_CAP,
            sig_credit_at: 0,
            v1_extra: [0; 256],
            v2_extra: [(0, 0); V2_EXTRA_SLOTS],
            v1_filled: false,
            v1_whole: [0; V1_WORDS],
            v1_good: [0; V1_WORDS],
            v1_raw: [0; V1_WORDS],
            v1_from: 0,
            v1_frontier: 0,
            busy_until: 0,
            dense_starts: false,
            mask_v1: [0; SCAN_WORDS],
            mask_v2: [0; SCAN_WORDS],
            mask_flags: [0; SCAN_WORDS],
            masks_from: 0,
            masks_frontier: 0,
            end_cuts: EndCuts::new(),
            steps: 0,
            signatures: 0,
        }
    }

    /// Whether the whole frame `w`, at `bytes[rel..]` where `bytes[0]` is
    /// stream position `at` (the current candidate), carries the checksum of
    /// its message (`crc_extra`). The first checksum over fresh bytes is
    /// computed directly; one over bytes an earlier one covered, from
    /// prefix states.
    #[inline(always)]
    fn crc_matches(&mut self, bytes: &[u8], at: u64, rel: usize, w: &Whole, crc_extra: u8) -> bool {
        let start = at + rel as u64 + 1;
        let end = start + w.covered as u64;
        if (self.prefix_end > at && start <= self.prefix_end) || start < self.direct_end {
            if self.prefix_end <= at || end > self.prefix_end {
                self.extend_prefix(bytes, at, end);
            }
            let before = self.prefix[slot_of(start, PREFIX_MASK)];
            let after = self.prefix[slot_of(end, PREFIX_MASK)];
            let carried = bytes.get(rel..).and_then(|f| w.carried(f));
            return carried.is_some()
                && crc::between_extra(before, after, w.covered, crc_extra) == carried;
        }
        self.direct_end = end;
        self.busy_until = self.busy_until.max(end);
        self.steps += w.covered as u64;
        match bytes.get(rel + 1..rel + 1 + w.covered) {
            Some(covered) => Some(crc::frame_crc(covered, crc_extra)) == w.carried(&bytes[rel..]),
            None => false,
        }
    }

    /// Whether something is known about position `at` or after it.
    #[inline(always)]
    pub(super) fn busy_at(&self, at: u64) -> bool {
        at < self.busy_until
    }

    /// Whether `frame`, the candidate at `at`, carries its checksum: when
    /// nothing is known about it or after it, exactly the check without a
    /// memo (the hot path: a good frame whole in the input), else
    /// [`candidate_crc_ok`](Self::candidate_crc_ok).
    #[inline(always)]
    pub(super) fn frame_crc_ok(
        &mut self,
        bytes: &[u8],
        at: u64,
        frame: &Frame<&[u8]>,
        crc_extra: u8,
    ) -> bool {
        if at < self.busy_until {
            return self.candidate_crc_ok(bytes, at, &Whole::of(frame), crc_extra);
        }
        // (Counted by `Parser::work`: these bytes are consumed now, as a
        // frame or a rejected candidate.)
        let ok = frame.check_crc(crc_extra);
        if !ok {
            self.steps += frame.as_bytes().len() as u64;
            // Candidates inside it come next: their checksums over these
            // bytes from prefix states, not directly again.
            self.direct_end = at + 1 + Whole::of(frame).covered as u64;
            self.busy_until = self.direct_end;
        }
        ok
    }

    /// [`crc_matches`](Self::crc_matches) for the candidate itself
    /// (`bytes[0]`), from the scan's verdict when an earlier candidate's
    /// scan classified it. A frame is taken only on its own bytes' checksum.
    #[inline(always)]
    pub(super) fn candidate_crc_ok(
        &mut self,
        bytes: &[u8],
        at: u64,
        w: &Whole,
        crc_extra: u8,
    ) -> bool {
        if self.good_candidate == at + 1 {
            return true;
        }
        let remembered = at >= self.scanned_from && at < self.frontier;
        if remembered && test_bit(&self.bad, at) {
            return false;
        }
        let direct_end = self.direct_end;
        let ok = (remembered && test_bit(&self.good, at))
            || self.crc_matches(bytes, at, 0, w, crc_extra);
        // What is remembered (verdicts, prefix states) was computed from
        // bytes a caller may not have passed again (one that drops the rest
        // of its input after a frame): confirmed on the frame's own bytes,
        // unless `crc_matches` has just done exactly that.
        let end = at + 1 + w.covered as u64;
        let ok = ok
            && ((self.direct_end == end && direct_end != end)
                || bytes
                    .get(1..1 + w.covered)
                    .is_some_and(|c| Some(crc::frame_crc(c, crc_extra)) == w.carried(bytes)));
        if ok {
            self.good_candidate = at + 1;
        }
        ok
    }

    /// Extends the prefix states to `end` at least (restarting them just
    /// after the candidate when they are all behind it), and ahead of it by
    /// a batch the next checksums will likely need: one tight loop, not a
    /// byte per candidate through memory.
    #[inline(never)]
    fn extend_prefix(&mut self, bytes: &[u8], at: u64, end: u64) {
        if self.prefix_end <= at {
            // No checksum asked from now on starts before the candidate.
            self.prefix_end = at + 1;
            self.prefix[slot_of(at + 1, PREFIX_MASK)] = 0;
        }
        let avail = at + bytes.len() as u64;
        let upto = avail
            .min((end + PREFIX_AHEAD).max(self.prefix_end + PREFIX_AHEAD))
            .min(at + PREFIX_REACH)
            .max(end);
        let (Ok(from), Ok(to)) = (
            usize::try_from(self.prefix_end - at),
            usize::try_from(upto - at),
        ) else {
            return;
        };
        let Some(new) = bytes.get(from..to) else {
            return;
        };
        let mut r = self.prefix[slot_of(self.prefix_end, PREFIX_MASK)];
        // The states after each new byte, in at most two runs of the ring
        // (it wraps once at most): no index masked per state.
        let mut slot = slot_of(self.prefix_end + 1, PREFIX_MASK);
        let mut new = new;
        while !new.is_empty() {
            let n = new.len().min(PREFIX_RING - slot);
            let (bytes, rest) = new.split_at(n);
            r = prefix_states(r, bytes, &mut self.prefix[slot..slot + n]);
            (new, slot) = (rest, 0);
        }
        self.steps += upto - self.prefix_end;
        self.prefix_end = upto;
        self.busy_until = self.busy_until.max(upto);
    }

    /// Whether a good frame of a known id starts at a position after
    /// `bytes[0]` (stream position `at`, the candidate) and before
    /// `bytes[len]`, as far as `bytes` tells. `at_eof`: `bytes` end the
    /// stream (a flush, or the end of a datagram), so a position whose
    /// frame they cut is never good, and none waits.
    #[inline(always)]
    pub(super) fn inside<D: MessageSet>(
        &mut self,
        bytes: &[u8],
        at: u64,
        len: usize,
        at_eof: bool,
    ) -> Inside {
        let end = len.min(bytes.len());
        let avail = at + bytes.len() as u64;
        if avail < self.woken || self.woken < avail.min(self.last_wake) {
            self.wake::<D>(bytes, at);
        } else {
            // Nothing waits for these bytes.
            self.woken = avail;
        }
        if at + end as u64 > self.frontier {
            // Ahead of what is asked, so that the next candidates (in
            // garbage, a byte or two later) find their positions decided.
            let to = if at_eof {
                // Nothing waits at the end of the stream: as far as the
                // bytes go.
                end.max(bytes.len().min(end + SCAN_AHEAD))
            } else {
                scan_end(end, bytes.len())
            };
            self.scan::<D>(bytes, at, to, at_eof);
        }
        let (from, to) = (at + 1, at + end as u64);
        self.steps += 1;
        // In garbage neither ring has a bit set after the candidate: the
        // bounds say so without a search.
        if self.good_before > from && first_set(&self.good, from, to).is_some() {
            return Inside::Yes;
        }
        match first_set(&self.undecided, from, to.min(self.undecided_before)) {
            Some(q) => Inside::Undecided(needed_at(bytes, (q - at) as usize)),
            None => Inside::No,
        }
    }

    /// Classifies again the pending positions whose wake-up position the
    /// bytes have reached, each as of its wake-up position (so that what it
    /// waits for next is at most a frame ahead of the positions handled).
    #[inline(never)]
    fn wake<D: MessageSet>(&mut self, bytes: &[u8], at: u64) {
        let avail = at + bytes.len() as u64;
        if avail < self.woken {
            self.forget_from(at);
        }
        let upto = avail.min(self.last_wake).min(at + PREFIX_REACH);
        if upto > self.prefix_end || self.prefix_end <= at {
            // The checksums of the positions woken, from prefix states
            // extended once (in small reads, a few bytes per position).
            self.extend_prefix(bytes, at, upto);
        }
        while self.woken < avail.min(self.last_wake) {
            self.woken += 1;
            let w = self.woken;
            self.steps += 1;
            let head = core::mem::take(&mut self.wake_head[slot_of(w, SCAN_MASK)]);
            let mut link = if head >> 16 == self.epoch {
                head as u16
            } else {
                0
            };
            while link != 0 {
                let slot = u64::from(link - 1);
                link = self.wake_next[slot_of(slot, SCAN_MASK)];
                // The position waiting: the one of this slot less than a
                // ring before its wake-up position.
                let q = w - (w.wrapping_sub(slot) & SCAN_MASK);
                clear_bit(&mut self.undecided, q);
                self.steps += 1;
                // Positions before the candidate are of no more use.
                if q > at {
                    let upto = &bytes[..bytes.len().min((w - at) as usize)];
                    let class = self.classify::<D>(upto, at, (q - at) as usize);
                    self.record(q, class);
                }
            }
        }
        self.woken = self.woken.max(avail);
    }

    /// Classifies the positions from the frontier (or just after the
    /// candidate) to `bytes[end]`, exclusive (`at_eof`: as [`inside`](Self::inside)).
    #[inline(never)]
    fn scan<D: MessageSet>(&mut self, bytes: &[u8], at: u64, end: usize, at_eof: bool) {
        let to = at + end as u64;
        if self.frontier <= at {
            self.frontier = at + 1;
            self.scanned_from = at + 1;
        }
        let from = self.frontier;
        if from >= to {
            return;
        }
        clear_range(&mut self.good, from, to);
        clear_range(&mut self.bad, from, to);
        clear_range(&mut self.undecided, from, to);
        // The MAVLink 1 verdicts by whole blocks from their frontier: the
        // scan's blocks start wherever it stopped last.
        self.v1_reach(from);
        self.v1_blocks_ahead::<D>(bytes, at, to, at_eof);
        let lo = (from - at) as usize;
        // By kind, so that no branch per position asks which kind it is
        // (in garbage, unpredictable): each position is decided alone, and
        // the verdicts of a block are stored at once (a store per position
        // would make each wait for the previous one's).
        for base in (0..end - lo).step_by(64) {
            let n = end - lo - base;
            self.masks_ahead(bytes, at, at + (lo + base + n.min(64)) as u64);
            let Starts { kinds, .. } = self.starts_seen(bytes, at, lo + base, n.min(64));
            let v1 = self.v1_verdicts::<D>(bytes, at, lo + base, (kinds[0], n));
            let (mut good, mut bad, mut raw) = (v1.good, v1.whole & !v1.good, v1.raw);
            // At the end, the frames it cuts are never good: their bytes
            // will not come.
            let cut = match at_eof {
                true => self.end_cuts.at(bytes, at, lo + base).cut & (kinds[0] | kinds[1]),
                false => 0,
            };
            self.steps += u64::from((v1.whole | v1.raw | cut).count_ones());
            // (A whole frame of an unknown id is that and nothing else:
            // what `classify_start` would say.)
            for mut starts in [kinds[0] & !v1.whole & !v1.raw & !cut, kinds[1] & !cut] {
                while starts != 0 {
                    let j = starts.trailing_zeros();
                    starts &= starts - 1;
                    self.steps += 1;
                    let rel = lo + base + j as usize;
                    match self.classify_start::<D>(bytes, at, rel) {
                        Start::Good => good |= 1 << j,
                        Start::BadCrc => bad |= 1 << j,
                        Start::Raw => raw |= 1 << j,
                        Start::Other => {}
                    }
                }
            }
            let first = at + (lo + base) as u64;
            // (Written whole, block by block: no clearing first.)
            merge_bits(&mut self.raw, first, raw, u64::MAX >> (64 - n.min(64)));
            or_bits(&mut self.good, first, good);
            if good != 0 {
                self.good_before = self
                    .good_before
                    .max(first + 64 - u64::from(good.leading_zeros()));
            }
            or_bits(&mut self.bad, first, bad);
        }
        self.steps += to - from;
        self.frontier = to;
        self.busy_until = self.busy_until.max(to);
    }

    /// Classifies the start byte at `bytes[rel]`: for a whole frame of a
    /// known id, whether its checksum is good; the rest by
    /// [`classify`](Self::classify), recorded here.
    #[inline(always)]
    fn classify_start<D: MessageSet>(&mut self, bytes: &[u8], at: u64, rel: usize) -> Start {
        match Whole::at(&bytes[rel..]) {
            Some(w) => match self.crc_extra::<D>(w.id) {
                Some(extra) if self.crc_matches(bytes, at, rel, &w, extra) => Start::Good,
                Some(_) => Start::BadCrc,
                None => Start::Raw,
            },
            None => {
                let class = self.classify::<D>(bytes, at, rel);
                self.record(at + rel as u64, class);
                Start::Other
            }
        }
    }

    /// Of the 64 positions from stream position `first`, those the scan
    /// found to start a whole frame of an unknown id (0 where it has not
    /// looked).
    #[inline(always)]
    pub(super) fn raw_starts(&self, first: u64) -> u64 {
        let (lo, hi) = (self.scanned_from.max(first), self.frontier.min(first + 64));
        if lo >= hi {
            return 0;
        }
        bits_from(&self.raw, first) & span_mask(lo - first, hi - first)
    }

    /// What `bytes` (from the candidate at `at`) say about position
    /// `at + rel`, a start byte: the rules of the parser's "known good frame
    /// inside" check. Undecided are the positions whose header is not whole
    /// (for MAVLink 1: up to its id byte), and those of a known id whose
    /// frame is not whole. (Before, a MAVLink 1 header cut before its id
    /// byte was read as id 0: with a dialect without id 0 the answer then
    /// depended on where a chunk ended.)
    fn classify<D: MessageSet>(&mut self, bytes: &[u8], at: u64, rel: usize) -> Class {
        let Some(inner) = bytes.get(rel..) else {
            return Class::NotGood;
        };
        let q = at + rel as u64;
        let v1 = inner.first() == Some(&STX_V1);
        self.steps += 1;
        match frame_len(inner) {
            Ok(n) if inner.len() >= n => {
                let w = Whole::of(&Frame::new_unchecked(&inner[..n]));
                match self.crc_extra::<D>(w.id) {
                    Some(extra) if self.crc_matches(bytes, at, rel, &w, extra) => Class::Good,
                    Some(_) => Class::BadCrc,
                    None => Class::NotGood,
                }
            }
            Ok(_) if v1 && inner.len() < HEADER_LEN_V1 => Class::Pending {
                // The id byte is not there yet: any id, known maybe.
                undecided: true,
                wake: q + HEADER_LEN_V1 as u64,
            },
            Ok(n) => {
                if self.crc_extra::<D>(msg_id(inner)).is_some() {
                    Class::Pending {
                        undecided: true,
                        wake: q + n as u64,
                    }
                } else {
                    Class::NotGood
                }
            }
            Err(FrameError::Incomplete { .. }) => Class::Pending {
                undecided: true,
                // The length byte of MAVLink 1, the whole header of 2.
                wake: q + if v1 { 2 } else { HEADER_LEN_V2 as u64 },
            },
            Err(_) => Class::NotGood,
        }
    }

    fn record(&mut self, q: u64, class: Class) {
        match class {
            Class::NotGood => {}
            Class::Good => {
                set_bit(&mut self.good, q);
                self.good_before = self.good_before.max(q + 1);
            }
            Class::BadCrc => set_bit(&mut self.bad, q),
            Class::Pending { undecided, wake } => {
                if undecided {
                    set_bit(&mut self.undecided, q);
                    self.undecided_before = self.undecided_before.max(q + 1);
                }
                let slot = slot_of(q, SCAN_MASK);
                let head = &mut self.wake_head[slot_of(wake, SCAN_MASK)];
                self.wake_next[slot] = if *head >> 16 == self.epoch {
                    *head as u16
                } else {
                    0
                };
                // slot < SCAN_RING ≤ u16::MAX.
                *head = self.epoch << 16 | (slot as u32 + 1);
                self.last_wake = self.last_wake.max(wake);
            }
        }
    }

    /// Forgets that the candidate's checksum was found good, the one fact
    /// a frame is taken on without reading its bytes again.
    pub(super) fn forget_good_candidate(&mut self) {
        self.good_candidate = 0;
    }

    /// Forgets what is known about stream positions from `pos` on, and
    /// what was computed from bytes there (in constant time): called when
    /// the bytes from `pos` on may not be those seen. At the end of a
    /// stream what follows is another; fewer bytes at hand than before means
    /// a caller dropped input the parser had looked at (it must pass the
    /// rest of its input again after a frame) and passed other bytes.
    pub(super) fn forget_from(&mut self, pos: u64) {
        self.epoch += 1;
        if self.epoch > u32::from(u16::MAX) {
            // Heads of an epoch this old may still sit in the ring.
            self.wake_head = [0; SCAN_RING];
            self.steps += SCAN_RING as u64;
            self.epoch = 1;
        }
        (self.woken, self.last_wake) = (pos, pos);
        (self.frontier, self.scanned_from) = (pos, pos);
        self.v1_frontier = self.v1_frontier.min(pos);
        self.masks_frontier = self.masks_frontier.min(pos);
        (self.prefix_end, self.direct_end) = (0, self.direct_end.max(pos));
        (self.good_candidate, self.raw_signature_failed) = (0, 0);
        self.busy_until = self.direct_end;
        self.end_cuts.forget();
    }

    /// Of the MAVLink 1 start bytes `mask` among the 64 positions from
    /// `bytes[block]` (`bytes[0]` is stream position `at`, no later than
    /// the current candidate): those whose frame is whole, of a known id or
    /// not, and of the known ones, those whose checksum is good. One
    /// tight loop over prefix states extended once: in garbage dense in
    /// 0xFE this is the cost of every byte.
    pub(super) fn v1_checks<D: MessageSet>(
        &mut self,
        bytes: &[u8],
        at: u64,
        block: usize,
        mask: u64,
    ) -> V1 {
        if mask == 0 {
            return V1::NONE;
        }
        self.fill_v1_extra::<D>();
        // Every frame of the block whole in `bytes`: no bound to check.
        let window = bytes
            .get(block..block + V1_WINDOW)
            .and_then(|w| <&[u8; V1_WINDOW]>::try_from(w).ok());
        // Only known ids have a checksum to check: without one in the
        // block (a stream of frames of unknown ids), no prefix state.
        let (mask, raw) = match window {
            Some(window) => {
                let known = v1_known(&self.v1_extra, window, mask);
                (known, mask & !known)
            }
            None => (mask, 0),
        };
        if mask == 0 {
            return V1 { raw, ..V1::NONE };
        }
        // The farthest a checksum of a frame starting in the block reaches.
        let far = at + (block + 64 + HEADER_LEN_V1 + 255).min(bytes.len()) as u64;
        if self.prefix_end <= at || far > self.prefix_end {
            self.extend_prefix(bytes, at, far);
        }
        if let Some(window) = window {
            let good = v1_good_whole(
                &self.prefix,
                &self.v1_extra,
                window,
                at + block as u64,
                mask,
            );
            return V1 {
                whole: mask,
                good,
                raw,
            };
        }
        let (mut whole, mut good, mut raw) = (0u64, 0u64, 0u64);
        let mut m = mask;
        while m != 0 {
            let j = m.trailing_zeros() as usize;
            m &= m - 1;
            let rel = block + j;
            let (Some(&len), Some(&id)) = (bytes.get(rel + 1), bytes.get(rel + 5)) else {
                continue;
            };
            let covered = HEADER_LEN_V1 - 1 + usize::from(len);
            let extra = self.v1_extra[usize::from(id)];
            let Some(carried) = bytes.get(rel + 1 + covered..rel + 3 + covered) else {
                continue;
            };
            if extra & 0x100 == 0 {
                raw |= 1 << j;
                continue;
            }
            let start = at + (rel + 1) as u64;
            let before = self.prefix[slot_of(start, PREFIX_MASK)];
            let after = self.prefix[slot_of(start + covered as u64, PREFIX_MASK)];
            let ok = crc::between_extra(before, after, covered, extra as u8)
                == Some(u16::from_le_bytes([carried[0], carried[1]]));
            whole |= 1 << j;
            good |= u64::from(ok) << j;
        }
        V1 { whole, good, raw }
    }

    /// [`v1_checks`](Self::v1_checks), each position checked once: the
    /// verdicts are remembered in bit rings up to a frontier (the scan and
    /// the fast rejection loop pass over the same positions, the loop again
    /// each time a candidate it cannot reject alone interrupts it). A
    /// position whose frame was not whole when checked stays "not whole":
    /// callers check those on their own. `mask` holds every start byte of
    /// the first `n` positions of the block (`n` ≤ 64).
    #[inline(always)]
    pub(super) fn v1_verdicts<D: MessageSet>(
        &mut self,
        bytes: &[u8],
        at: u64,
        block: usize,
        (mask, n): (u64, usize),
    ) -> V1 {
        let first = at + block as u64;
        let end = first + n.min(64) as u64;
        if first >= self.v1_from && end <= self.v1_frontier {
            // All checked already (the scan runs ahead of the fast
            // rejection loop): most calls from the loop.
            return self.remembered_v1(first).masked(mask);
        }
        self.v1_verdicts_fresh::<D>(bytes, at, block, mask, end)
    }

    /// [`v1_verdicts`](Self::v1_verdicts) of a block (positions from
    /// `bytes[block]` to stream position `end`) not all checked yet (out of
    /// line: the check of a block all checked stays small).
    #[inline(never)]
    fn v1_verdicts_fresh<D: MessageSet>(
        &mut self,
        bytes: &[u8],
        at: u64,
        block: usize,
        mask: u64,
        end: u64,
    ) -> V1 {
        let first = at + block as u64;
        // The positions of the block already checked.
        let (lo, hi) = (self.v1_from.max(first), self.v1_frontier.min(end));
        let known = if lo < hi {
            span_mask(lo - first, hi - first)
        } else {
            0
        };
        let fresh = mask & !known;
        let checked = self.v1_checks::<D>(bytes, at, block, fresh);
        self.steps += u64::from(fresh.count_ones());
        self.v1_reach(first);
        if first >= self.v1_from && first <= self.v1_frontier && end > self.v1_frontier {
            let from = self.v1_frontier;
            let new = span_mask(from - first, end - first);
            self.remember_v1(first, checked, new);
            self.steps += end - from;
            self.v1_frontier = end;
            self.v1_from = self.v1_from.max(end.saturating_sub(V1_RING as u64));
        }
        let before = self.remembered_v1(first).masked(known);
        V1 {
            whole: checked.whole | before.whole,
            good: checked.good | before.good,
            raw: checked.raw | before.raw,
        }
        .masked(mask)
    }

    /// Starts the MAVLink 1 verdicts again at stream position `first` when
    /// nothing remembered reaches it (their frontier moves on from there).
    #[inline(always)]
    fn v1_reach(&mut self, first: u64) {
        if self.v1_frontier < first || self.v1_from > self.v1_frontier {
            (self.v1_from, self.v1_frontier) = (first, first);
        }
    }

    /// The verdicts remembered of the 64 positions from `first`.
    #[inline(always)]
    fn remembered_v1(&self, first: u64) -> V1 {
        V1 {
            whole: bits_from(&self.v1_whole, first),
            good: bits_from(&self.v1_good, first),
            raw: bits_from(&self.v1_raw, first),
        }
    }

    /// Remembers the verdicts `v1` of the positions `which` of the 64 from
    /// `first`.
    #[inline(always)]
    fn remember_v1(&mut self, first: u64, v1: V1, which: u64) {
        merge_bits(&mut self.v1_whole, first, v1.whole, which);
        merge_bits(&mut self.v1_good, first, v1.good, which);
        merge_bits(&mut self.v1_raw, first, v1.raw, which);
    }

    /// Moves the frontier of [`v1_verdicts`](Self::v1_verdicts) past `end`
    /// by whole blocks of 64 positions from it, when `bytes` (from stream
    /// position `at`) hold every frame starting in them and the ring of
    /// verdicts keeps them: the blocks of the fast rejection loop and of
    /// the scan start at their candidate or where they stopped, wherever
    /// that is, and would check the few positions past the frontier each
    /// time (a call per block, not about two: `found_i` and `found_j` with
    /// a key 1-2 instructions per byte less).
    /// At the end of the stream (`at_eof`), a block whose frames the end
    /// cuts is checked all the same, its positions in `bytes`: those frames
    /// never will be whole (in datagrams, the blocks would otherwise never
    /// be whole, and every run paid for the positions past the frontier).
    #[inline(never)]
    fn v1_blocks_ahead<D: MessageSet>(&mut self, bytes: &[u8], at: u64, end: u64, at_eof: bool) {
        while self.v1_frontier < end {
            let x = self.v1_frontier;
            let rel = (x - at) as usize;
            let held = rel + if at_eof { 64 } else { V1_WINDOW };
            if x + 64 > at + (V1_RING - MAX_FRAME_LEN) as u64 || bytes.len() < held {
                return;
            }
            let masks = self
                .remembered_masks(x, 64)
                .unwrap_or_else(|| raw_masks(bytes, rel, 64));
            let checked = self.v1_checks::<D>(bytes, at, rel, masks.0);
            self.remember_v1(x, checked, !0);
            self.steps += 64 + u64::from(masks.0.count_ones());
            self.v1_frontier = x + 64;
            self.v1_from = self
                .v1_from
                .max(self.v1_frontier.saturating_sub(V1_RING as u64));
        }
    }

    /// Of the MAVLink 1 start bytes `mask` among the 64 positions from
    /// `bytes[0]` (stream position `at`, no later than the current
    /// candidate; all of them when `bytes` is shorter; `at_eof`: they end
    /// the stream): those whose frame is whole, of a known id, with a bad
    /// checksum.
    #[inline(always)]
    pub(super) fn v1_bad_crc<D: MessageSet>(
        &mut self,
        bytes: &[u8],
        at: u64,
        mask: u64,
        at_eof: bool,
    ) -> u64 {
        let end = at + bytes.len().min(64) as u64;
        if end > self.v1_frontier && at >= self.v1_from && at <= self.v1_frontier {
            self.v1_blocks_ahead::<D>(bytes, at, end, at_eof);
        }
        let v1 = self.v1_verdicts::<D>(bytes, at, 0, (mask, bytes.len()));
        v1.whole & !v1.good
    }

    /// Whether [`v1_verdicts`](Self::v1_verdicts) found the MAVLink 1
    /// candidate at `at` whole, of a known id, with a bad checksum (false
    /// also when it has not looked there): the fast rejection loop's
    /// candidates before it goes by masks were often checked already.
    #[inline(always)]
    pub(super) fn v1_known_bad(&self, at: u64) -> bool {
        at >= self.v1_from
            && at < self.v1_frontier
            && test_bit(&self.v1_whole, at)
            && !test_bit(&self.v1_good, at)
    }

    /// Looks up the CRC_EXTRA of every MAVLink 1 id, once.
    fn fill_v1_extra<D: MessageSet>(&mut self) {
        if !self.v1_filled {
            for id in 0..256 {
                self.crc_extra::<D>(id);
            }
            self.v1_filled = true;
        }
    }

    /// The CRC_EXTRA of message `id`, `None` when the dialect does not know
    /// it.
    #[inline(always)]
    pub(super) fn crc_extra<D: MessageSet>(&mut self, id: u32) -> Option<u8> {
        let Some(cached) = self.v1_extra.get_mut(id as usize) else {
            return self.v2_crc_extra::<D>(id);
        };
        if *cached == 0 {
            *cached = 0x200
                | D::meta(id).map_or(0, |m| {
                    u32::from(crc::extra_fold(m.crc_extra)) << 16 | 0x100 | u32::from(m.crc_extra)
                });
        }
        (*cached & 0x100 != 0).then_some(*cached as u8)
    }

    /// [`crc_extra`](Self::crc_extra) of an id above 255, through a small
    /// cache: the scan and the fast rejection loop ask about the same
    /// candidates, and garbage repeats its ids (the dialect's look-up is a
    /// search among its ids).
    #[inline(always)]
    fn v2_crc_extra<D: MessageSet>(&mut self, id: u32) -> Option<u8> {
        // Above the dialect's largest id (most ids of garbage, three bytes
        // at random), unknown without the cache: ids chosen to share its
        // slots made every look-up a search (`found_n`).
        if id > D::MAX_ID {
            return None;
        }
        let slot = &mut self.v2_extra[(id ^ id >> 7 ^ id >> 14) as usize % V2_EXTRA_SLOTS];
        if slot.0 != id || slot.1 == 0 {
            *slot = (
                id,
                0x200 | D::meta(id).map_or(0, |m| 0x100 | u16::from(m.crc_extra)),
            );
        }
        (slot.1 & 0x100 != 0).then_some(slot.1 as u8)
    }

    /// Whether the candidate at `at`, an unknown id whose signature was
    /// checked, failed that check.
    #[inline(always)]
    pub(super) fn raw_signature_failed(&self, at: u64) -> bool {
        self.raw_signature_failed == at + 1
    }

    #[inline(always)]
    pub(super) fn set_raw_signature_failed(&mut self, at: u64) {
        self.raw_signature_failed = at + 1;
    }

    /// The budget for checking unknown ids' signatures, in hashed bytes times
    /// [`BYTES_PER_RAW_SIGNATURE_BYTE`] (each byte consumed earns one: no
    /// remainder to keep), with what the bytes up to stream position `at`
    /// earned. (Computed, not stored, when a candidate asks: most ask and
    /// are refused.)
    #[inline(always)]
    fn sig_credit_at(&self, at: u64) -> u64 {
        let earned = at.saturating_sub(self.sig_credit_at);
        self.sig_credit.saturating_add(earned).min(CREDIT_CAP)
    }

    /// Pays for the check of the candidate at stream position `at`, `cost`
    /// hashed bytes, once however often it is checked: false when the
    /// budget cannot (the candidate is refused unchecked).
    #[inline(always)]
    pub(super) fn pay_for_raw_check(&mut self, at: u64, cost: u64) -> bool {
        if self.raw_check_paid == at + 1 {
            return true;
        }
        let (held, cost) = (self.sig_credit_at(at), cost * BYTES_PER_RAW_SIGNATURE_BYTE);
        if held < cost {
            return false;
        }
        self.sig_credit = held - cost;
        self.sig_credit_at = self.sig_credit_at.max(at);
        self.raw_check_paid = at + 1;
        true
    }

    /// Whether the budget cannot pay for the check of any signed frame
    /// at stream position `at` (of the shortest, the cheapest to check),
    /// the candidate not paid for already: refused unchecked whatever its
    /// length, as [`pay_for_raw_check`](Self::pay_for_raw_check) would.
    #[inline(always)]
    pub(super) fn cannot_pay_any(&self, at: u64) -> bool {
        const SHORTEST: usize = HEADER_LEN_V2 + CHECKSUM_LEN + SIGNATURE_LEN;
        self.raw_check_paid != at + 1
            && self.sig_credit_at(at)
                < super::raw_signature_cost(SHORTEST) * BYTES_PER_RAW_SIGNATURE_BYTE
    }

    /// Gives back what the check of the candidate at `at` took: its
    /// signature is good.
    #[inline(always)]
    pub(super) fn refund_raw_signature(&mut self, at: u64, cost: u64) {
        self.sig_credit = self
            .sig_credit_at(at)
            .saturating_add(cost * BYTES_PER_RAW_SIGNATURE_BYTE)
            .min(CREDIT_CAP);
        self.sig_credit_at = self.sig_credit_at.max(at);
    }
}

impl Memo {
    /// The start bytes of the 64 positions from `bytes[base]` (stream
    /// position `at + base`) among the first `count` of `bytes`, by kind:
    /// see [`Starts`]. Compares the compiler vectorises, then set bits: no
    /// branch per byte; and remembered, two blocks ahead, so that the next
    /// runs over these positions read them.
    #[inline]
    pub(super) fn starts(&mut self, bytes: &[u8], at: u64, base: usize, count: usize) -> Starts {
        let n = (count - base).min(64);
        let first = at + base as u64;
        let end = first + n as u64;
        if first < self.masks_from || end > self.masks_frontier {
            self.remember_masks(bytes, at, first);
        }
        // Else the last positions of the bytes.
        let masks = self
            .remembered_masks(first, n)
            .unwrap_or_else(|| raw_masks(bytes, base, n));
        starts_of(bytes, base, masks)
    }

    /// What the rings know of the 64 positions from stream position
    /// `first` (`bytes[0]`), when the MAVLink 1 verdicts cover them all
    /// (`None` otherwise; their masks are computed here if the ring does
    /// not hold them): the start bytes by kind, and of those the ones
    /// rejected whatever follows. `bytes` holds every header starting there
    /// (a MAVLink 2 start byte's flags are refused only where its header is
    /// whole).
    #[inline(always)]
    pub(super) fn block(&mut self, bytes: &[u8], first: u64) -> Option<Block> {
        if first < self.v1_from || first + 64 > self.v1_frontier {
            return None;
        }
        if first < self.masks_from || first + 64 > self.masks_frontier {
            self.remember_masks(bytes, first, first);
        }
        let (v1, v2, flags) = self.remembered_masks(first, 64)?;
        let whole = bits_from(&self.v1_whole, first);
        let good = bits_from(&self.v1_good, first);
        Some(Block {
            starts: v1 | v2,
            bad_v1: v1 & whole & !good,
            refused: v2 & flags,
        })
    }

    /// The masks of the `n` positions from `first` (`n` ≤ 64), when the
    /// ring holds them all.
    #[inline(always)]
    fn remembered_masks(&self, first: u64, n: usize) -> Option<(u64, u64, u64)> {
        if first < self.masks_from || first + n as u64 > self.masks_frontier {
            return None;
        }
        let first_n = u64::MAX >> (64 - n);
        Some((
            bits_from(&self.mask_v1, first) & first_n,
            bits_from(&self.mask_v2, first) & first_n,
            bits_from(&self.mask_flags, first) & first_n,
        ))
    }

    /// [`starts`](Self::starts) for the scan: read from the ring of masks
    /// when it holds them, else computed and not remembered (the scan
    /// moves the ring only where [`masks_ahead`](Self::masks_ahead) lets
    /// it, so that it never loses the positions the rejection loop passes
    /// over again and again: in small reads, masks were once computed five
    /// times over).
    #[inline]
    fn starts_seen(&self, bytes: &[u8], at: u64, base: usize, n: usize) -> Starts {
        let masks = self
            .remembered_masks(at + base as u64, n)
            .unwrap_or_else(|| raw_masks(bytes, base, n));
        starts_of(bytes, base, masks)
    }

    /// Moves the frontier of the ring of masks on to `end`, when the ring
    /// reaches `at` and keeps every position from it: the scan's blocks are
    /// then read again by the fast rejection loop and by
    /// [`v1_blocks_ahead`](Self::v1_blocks_ahead), not computed three times.
    #[inline]
    fn masks_ahead(&mut self, bytes: &[u8], at: u64, end: u64) {
        if self.masks_from > at || self.masks_frontier < at || self.masks_frontier >= end {
            return;
        }
        // Blocks are added while the frontier is at most `last` (so it
        // stays within SCAN_RING - 64 positions of `at`).
        let last = at + (SCAN_RING - 128) as u64;
        self.extend_masks(bytes, at, end.min(last + 1));
    }

    /// Computes the masks of the positions from the frontier (or from
    /// `first` when the frontier is behind it) to two blocks after `first`.
    #[inline(never)]
    fn remember_masks(&mut self, bytes: &[u8], at: u64, first: u64) {
        if self.masks_frontier < first || self.masks_from > first {
            (self.masks_from, self.masks_frontier) = (first, first);
        }
        self.extend_masks(bytes, at, first + 128);
    }

    /// Moves the frontier of the ring of masks by whole blocks of 64
    /// positions until it reaches `upto`, as far as `bytes` (from stream
    /// position `at`) hold them, and forgets what the ring no longer keeps.
    fn extend_masks(&mut self, bytes: &[u8], at: u64, upto: u64) {
        while self.masks_frontier < upto {
            let x = self.masks_frontier;
            let Some(window) = usize::try_from(x - at)
                .ok()
                .and_then(|rel| bytes.get(rel..rel + BLOCK_WINDOW))
            else {
                break;
            };
            let (v1, v2, flags) = masks_of_block(window);
            merge_bits(&mut self.mask_v1, x, v1, !0);
            merge_bits(&mut self.mask_v2, x, v2, !0);
            merge_bits(&mut self.mask_flags, x, flags, !0);
            self.masks_frontier = x + 64;
        }
        self.masks_from = self
            .masks_from
            .max(self.masks_frontier.saturating_sub(SCAN_RING as u64));
    }
}

/// Writes to `states` the CRC register after each of `bytes` folded into
/// `r` in turn (as many states as bytes), and returns the last.
#[inline(always)]
fn prefix_states(mut r: u16, bytes: &[u8], states: &mut [u16]) -> u16 {
    let mut fours = bytes.chunks_exact(4);
    let mut outs = states.chunks_exact_mut(4);
    for (b, out) in (&mut fours).zip(&mut outs) {
        let four = crc::step4(r, [b[0], b[1], b[2], b[3]]);
        out.copy_from_slice(&four);
        r = four[3];
    }
    for (&b, out) in fours.remainder().iter().zip(outs.into_remainder()) {
        r = crc::step(r, b);
        *out = r;
    }
    r
}

/// Of the MAVLink 1 start bytes `mask` of a block whose every frame is
/// whole in `window`, those of a known id. One load per start byte, no
/// branch on the id: in garbage, known and unknown ids alternate at random.
fn v1_known(v1_extra: &[u32; 256], window: &[u8; V1_WINDOW], mask: u64) -> u64 {
    let mut known = 0u64;
    let mut m = mask;
    while m != 0 {
        let j = (m.trailing_zeros() & 63) as usize;
        m &= m - 1;
        known |= u64::from(v1_extra[usize::from(window[j + 5])] >> 8 & 1) << j;
    }
    known
}

/// Of the MAVLink 1 start bytes `known` (whole, of known ids) of a block
/// whose every frame is whole in `window` (stream position `first` on),
/// those whose checksum is good, from the prefix states and the table of
/// CRC_EXTRA. Not generic, and apart from the memo's other fields: the loop
/// keeps its tables and bases in registers.
#[inline(never)]
fn v1_good_whole(
    prefix: &[u16; PREFIX_RING],
    v1_extra: &[u32; 256],
    window: &[u8; V1_WINDOW],
    first: u64,
    known: u64,
) -> u64 {
    // Ring slot of the first covered byte of the block's first position
    // (a slot, not the position: no overflow on 32-bit targets).
    let base = slot_of(first + 1, PREFIX_MASK);
    let mut good = 0u64;
    let mut m = known;
    while m != 0 {
        let j = (m.trailing_zeros() & 63) as usize;
        m &= m - 1;
        let len = window[j + 1];
        let fold = (v1_extra[usize::from(window[j + 5])] >> 16) as u16;
        let end = j + 6 + usize::from(len);
        let carried = u16::from_le_bytes([window[end], window[end + 1]]);
        let before = prefix[(base + j) % PREFIX_RING];
        let after = prefix[(base + j + 5 + usize::from(len)) % PREFIX_RING];
        good |= u64::from(crc::between_v1(before, after, len, fold) == carried) << j;
    }
    good
}

/// (0xFE, 0xFD, flags other than known) of the `n` positions from
/// `bytes[base]`.
fn raw_masks(bytes: &[u8], base: usize, n: usize) -> (u64, u64, u64) {
    match bytes.get(base..base + BLOCK_WINDOW) {
        Some(window) => {
            // (A short block, the last of a scan, where bytes follow.)
            let first_n = u64::MAX >> (64 - n);
            let (v1, v2, bad_flags) = masks_of_block(window);
            (v1 & first_n, v2 & first_n, bad_flags & first_n)
        }
        None => {
            // The last block of the bytes: in a buffer of zeros, which
            // start nothing and have known flags (in a datagram every run
            // over its tail passes here: a byte at a time cost about 13
            // instructions per byte of `found_c` in 300-byte datagrams).
            let window = zero_padded(bytes.get(base..).unwrap_or(&[]), 0);
            let first_n = u64::MAX >> (64 - n);
            let (v1, v2, bad_flags) = masks_of_block(&window);
            (v1 & first_n, v2 & first_n, bad_flags & first_n)
        }
    }
}

/// The bytes a block's masks read: its 64 positions and two more (the
/// flags of the last two).
pub(super) const BLOCK_WINDOW: usize = 64 + 2;

/// A block's window of zeros with `bytes` from its position `skip` on (as
/// many as fit): for blocks the bytes do not fill.
#[inline]
pub(super) fn zero_padded(bytes: &[u8], skip: usize) -> [u8; BLOCK_WINDOW] {
    let mut window = [0u8; BLOCK_WINDOW];
    let n = bytes.len().min(BLOCK_WINDOW.saturating_sub(skip));
    window[skip..skip + n].copy_from_slice(&bytes[..n]);
    window
}

/// The [`Starts`] of the block at `bytes[base]` from its masks.
#[inline(always)]
fn starts_of(bytes: &[u8], base: usize, (v1, v2, bad_flags): (u64, u64, u64)) -> Starts {
    // Positions whose header is whole: base + j + 10 <= len.
    let whole = bytes.len().saturating_sub(base + HEADER_LEN_V2 - 1);
    let whole = if whole >= 64 { !0 } else { (1u64 << whole) - 1 };
    let refused = v2 & bad_flags & whole;
    Starts {
        kinds: [v1, v2 & !refused],
        refused,
    }
}

/// The start bytes among the first `count` of `bytes`, 64 positions at a
/// time, as [`Memo::starts`] finds them without remembering (the
/// reference its tests compare with).
#[cfg(test)]
fn start_masks(bytes: &[u8], count: usize) -> impl Iterator<Item = Starts> + '_ {
    (0..count).step_by(64).map(move |base| {
        let n = (count - base).min(64);
        starts_of(bytes, base, raw_masks(bytes, base, n))
    })
}

/// [`Memo::starts`]' (0xFE, 0xFD, flags other than known) of the 64
/// positions at the start of `window` (66 bytes: the flags of the last two
/// are after them), 16 bytes at a time in SSE2 registers (every x86-64 has
/// them): in garbage dense in start bytes every block passes here once, and
/// the eight-byte words of [`masks_by_words`] cost about 4 instructions per
/// byte more (`found_i`).
#[cfg(all(
    any(target_arch = "x86", target_arch = "x86_64"),
    target_feature = "sse2"
))]
fn masks_of_block(window: &[u8]) -> (u64, u64, u64) {
    use safe_arch::{
        bitand_m128i, cmp_eq_mask_i8_m128i, load_unaligned_m128i, m128i, move_mask_i8_m128i,
        set_splat_i8_m128i, zeroed_m128i,
    };
    let load = |i: usize| -> m128i {
        let mut b = [0u8; 16];
        b.copy_from_slice(&window[i..i + 16]);
        load_unaligned_m128i(&b)
    };
    // The masks of 16 positions: bit `j` of each `u16` is byte `j`'s.
    let mask = |v: m128i| move_mask_i8_m128i(v) as u16;
    let (fe, fd) = (
        set_splat_i8_m128i(STX_V1 as i8),
        set_splat_i8_m128i(STX_V2 as i8),
    );
    let unknown = set_splat_i8_m128i(!IFLAG_KNOWN as i8);
    let (mut v1, mut v2, mut bad_flags) = (0u64, 0u64, 0u64);
    for k in 0..4 {
        let (bytes, flags) = (load(16 * k), load(16 * k + 2));
        let known = cmp_eq_mask_i8_m128i(bitand_m128i(flags, unknown), zeroed_m128i());
        v1 |= u64::from(mask(cmp_eq_mask_i8_m128i(bytes, fe))) << (16 * k);
        v2 |= u64::from(mask(cmp_eq_mask_i8_m128i(bytes, fd))) << (16 * k);
        bad_flags |= u64::from(!mask(known)) << (16 * k);
    }
    (v1, v2, bad_flags)
}

/// [`masks_of_block`] where SSE2 is not there.
#[cfg(not(all(
    any(target_arch = "x86", target_arch = "x86_64"),
    target_feature = "sse2"
)))]
fn masks_of_block(window: &[u8]) -> (u64, u64, u64) {
    masks_by_words(window)
}

/// [`masks_of_block`] eight bytes at a time in a `u64` (no branch, no
/// vector unit needed: the same on every target).
#[cfg_attr(
    all(
        any(target_arch = "x86", target_arch = "x86_64"),
        target_feature = "sse2"
    ),
    allow(dead_code)
)]
fn masks_by_words(window: &[u8]) -> (u64, u64, u64) {
    let word = |i: usize| {
        let mut w = [0u8; 8];
        w.copy_from_slice(&window[i..i + 8]);
        u64::from_le_bytes(w)
    };
    let (mut v1, mut v2, mut bad_flags) = (0u64, 0u64, 0u64);
    for k in 0..8 {
        let (w, f) = (word(8 * k), word(8 * k + 2));
        v1 |= u64::from(zero_bytes(w ^ (EACH_BYTE * u64::from(STX_V1)))) << (8 * k);
        v2 |= u64::from(zero_bytes(w ^ (EACH_BYTE * u64::from(STX_V2)))) << (8 * k);
        let unknown = f & (EACH_BYTE * u64::from(!IFLAG_KNOWN));
        bad_flags |= u64::from(!zero_bytes(unknown)) << (8 * k);
    }
    (v1, v2, bad_flags)
}

/// The same, a byte at a time: the reference of the tests.
#[cfg(test)]
fn masks_by_bytes(bytes: &[u8], base: usize, n: usize) -> (u64, u64, u64) {
    let (mut v1, mut v2, mut bad_flags) = (0u64, 0u64, 0u64);
    for (j, &b) in bytes[base..base + n].iter().enumerate() {
        v1 |= u64::from(b == STX_V1) << j;
        v2 |= u64::from(b == STX_V2) << j;
    }
    let flags = bytes.get(base + 2..).unwrap_or(&[]);
    for (j, &f) in flags[..flags.len().min(n)].iter().enumerate() {
        bad_flags |= u64::from(f & !IFLAG_KNOWN != 0) << j;
    }
    (v1, v2, bad_flags)
}

const EACH_BYTE: u64 = 0x0101_0101_0101_0101;
const HIGH_BITS: u64 = 0x8080_8080_8080_8080;

/// Bit `i`: byte `i` of `w` is zero. Exact (no carry crosses bytes: each
/// byte's low seven bits are added to 0x7F alone), then the eight high bits
/// gathered by one multiplication (each lands on its own bit of the top
/// byte, no two products overlap).
#[inline(always)]
fn zero_bytes(w: u64) -> u8 {
    let nonzero = ((w & !HIGH_BITS) + !HIGH_BITS) | w;
    let zero = !nonzero & HIGH_BITS;
    ((zero >> 7).wrapping_mul(0x0102_0408_1020_4080) >> 56) as u8
}

/// The start bytes of 64 positions from `bytes[base]` (bit `j`: position
/// `base + j`).
pub(super) struct Starts {
    /// 0xFE, and 0xFD less `refused`.
    pub(super) kinds: [u64; 2],
    /// The 0xFD whose whole header has unknown incompatibility flags: no
    /// frame there, as `frame_len` says (most of garbage's 0xFD).
    pub(super) refused: u64,
}

/// The 64 positions from one, as [`Memo::block`] finds them
/// (bit `j`: the position `j` after the first).
#[derive(Debug, Clone, Copy)]
pub(super) struct Block {
    /// The start bytes, of either kind.
    pub(super) starts: u64,
    /// The MAVLink 1 ones whose frame is whole, of a known id, with a bad
    /// checksum...
    pub(super) bad_v1: u64,
    /// ...and the MAVLink 2 ones with unknown incompatibility flags.
    pub(super) refused: u64,
}

/// Bytes needed (from `bytes[0]`) to decide about the undecided position
/// `bytes[rel]`: its frame's length, or its header's while that is cut.
fn needed_at(bytes: &[u8], rel: usize) -> usize {
    match bytes.get(rel..).map(frame_len) {
        Some(Ok(n)) | Some(Err(FrameError::Incomplete { needed: n })) => rel + n,
        // Not undecided: cannot happen. More than is held keeps it waiting.
        _ => bytes.len() + 1,
    }
}

#[inline(always)]
fn slot_of(x: u64, mask: u64) -> usize {
    (x & mask) as usize
}

/// The mask of a ring of `W` words' positions.
#[inline(always)]
const fn ring_mask<const W: usize>() -> u64 {
    (W * 64) as u64 - 1
}

fn set_bit<const W: usize>(bits: &mut [u64; W], x: u64) {
    let s = slot_of(x, ring_mask::<W>());
    bits[s / 64] |= 1 << (s % 64);
}

/// Sets the bits of positions `from + j` for the bits `j` of `mask`.
fn or_bits<const W: usize>(bits: &mut [u64; W], from: u64, mask: u64) {
    let s = slot_of(from, ring_mask::<W>());
    let (word, bit) = (s / 64, s % 64);
    bits[word] |= mask << bit;
    if bit != 0 {
        bits[(word + 1) % W] |= mask >> (64 - bit);
    }
}

/// Sets the bits of positions `from + j` to `value`'s for the bits `j` of
/// `which`; the others stay.
#[inline(always)]
fn merge_bits<const W: usize>(bits: &mut [u64; W], from: u64, value: u64, which: u64) {
    let s = slot_of(from, ring_mask::<W>());
    let (word, bit) = (s / 64, s % 64);
    let value = value & which;
    bits[word] = bits[word] & !(which << bit) | value << bit;
    if bit != 0 {
        let next = (word + 1) % W;
        bits[next] = bits[next] & !(which >> (64 - bit)) | value >> (64 - bit);
    }
}

/// The bits of positions `from..from + 64` (bit `j`: position `from + j`).
fn bits_from<const W: usize>(bits: &[u64; W], from: u64) -> u64 {
    let s = slot_of(from, ring_mask::<W>());
    let (word, bit) = (s / 64, s % 64);
    if bit == 0 {
        return bits[word];
    }
    bits[word] >> bit | bits[(word + 1) % W] << (64 - bit)
}

fn clear_bit<const W: usize>(bits: &mut [u64; W], x: u64) {
    let s = slot_of(x, ring_mask::<W>());
    bits[s / 64] &= !(1 << (s % 64));
}

/// The first position in `from..to` (fewer than a ring) whose bit is set.
#[inline]
fn first_set<const W: usize>(bits: &[u64; W], from: u64, to: u64) -> Option<u64> {
    let mut x = from;
    while x < to {
        let s = slot_of(x, ring_mask::<W>());
        // The bits of positions x.. to the end of their word.
        let rest = bits[s / 64] >> (s % 64);
        if rest != 0 {
            let q = x + u64::from(rest.trailing_zeros());
            return (q < to).then_some(q);
        }
        x += 64 - (s % 64) as u64;
    }
    None
}

/// The bits `from..to` of a `u64` (`from <= to <= 64`).
#[inline(always)]
pub(super) fn span_mask(from: u64, to: u64) -> u64 {
    let ones = if to - from >= 64 {
        !0
    } else {
        (1u64 << (to - from)) - 1
    };
    ones.checked_shl(from as u32).unwrap_or(0)
}

/// Clears the bits of positions `from..to` (fewer than a ring).
fn clear_range<const W: usize>(bits: &mut [u64; W], from: u64, to: u64) {
    let mut x = from;
    while x < to {
        let s = slot_of(x, ring_mask::<W>());
        let bit = (s % 64) as u64;
        let span = (64 - bit).min(to - x);
        let mask = if span == 64 { !0 } else { (1u64 << span) - 1 } << bit;
        bits[s / 64] &= !mask;
        x += span;
    }
}

fn test_bit<const W: usize>(bits: &[u64; W], x: u64) -> bool {
    let s = slot_of(x, ring_mask::<W>());
    bits[s / 64] & (1 << (s % 64)) != 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cannot_pay_any_is_what_paying_for_the_shortest_signed_frame_says() {
        // A signed frame's header with an empty payload.
        let header = [STX_V2, 0, IFLAG_SIGNED, 0, 0, 0, 0, 0, 0, 0];
        let shortest = frame_len(&header).unwrap();
        let cost = super::super::raw_signature_cost(shortest);
        // Every credit around the cost of the shortest frame's check.
        for credit in 0..3 * cost * BYTES_PER_RAW_SIGNATURE_BYTE {
            let mut memo = Memo::new();
            (memo.sig_credit, memo.sig_credit_at) = (credit, 1000);
            let at = 1000 + credit % 7;
            let refused = memo.cannot_pay_any(at);
            assert_eq!(
                refused,
                !memo.pay_for_raw_check(at, cost),
                "credit {credit}"
            );
            // Paid for once: the candidate is not refused when asked again.
            assert!(refused || !memo.cannot_pay_any(at));
        }
    }

    #[test]
    fn masks_by_words_and_by_vectors_equal_masks_by_bytes() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for round in 0..2000 {
            let window: [u8; 66] = core::array::from_fn(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                // Mostly start bytes and flags 0/1, some anything.
                match (x >> 40) % 6 {
                    0 => STX_V1,
                    1 => STX_V2,
                    2 => 0,
                    3 => 1,
                    _ => (x >> 48) as u8 ^ round as u8,
                }
            });
            let by_bytes = masks_by_bytes(&window, 0, 64);
            assert_eq!(masks_by_words(&window), by_bytes);
            assert_eq!(masks_of_block(&window), by_bytes);
            // The last, shorter block of the bytes (padded with zeros).
            let cut = round % 66;
            let n = cut.min(64);
            if n > 0 {
                let tail = &window[..cut];
                assert_eq!(raw_masks(tail, 0, n), masks_by_bytes(tail, 0, n), "{cut}");
            }
        }
        for b in 0..=255u8 {
            assert_eq!(
                zero_bytes(u64::from(b) << 24),
                if b == 0 { 0xFF } else { !(1 << 3) }
            );
        }
    }

    /// A dialect knowing three MAVLink 1 ids (one of them 0xFE, the id of
    /// garbage dense in 0xFE).
    struct Three;
    const fn meta(id: u32, crc_extra: u8) -> crate::message::MessageMeta {
        crate::message::MessageMeta {
            id,
            name: "",
            crc_extra,
            min_len: 0,
            max_len: 255,
            target_system_offset: None,
            target_component_offset: None,
            fields: &[],
        }
    }
    impl MessageSet for Three {
        type Message = ();
        type View<'a> = ();
        const MESSAGES: &'static [crate::message::MessageMeta] =
            &[meta(0, 50), meta(3, 7), meta(0xFE, 46)];
        fn parse(_: u32, _: &[u8]) -> Option<()> {
            None
        }
        fn view(_: u32, _: &[u8]) -> Option<()> {
            None
        }
    }

    /// The MAVLink 1 verdicts a memo remembers agree with those computed
    /// afresh from the rest of the stream, however the runs over it overlap:
    /// exactly when every run sees the rest of the stream; when runs see
    /// less, a position checked with its frame cut stays "not whole", but
    /// what is called whole, good or bad is still true.
    #[test]
    fn remembered_v1_verdicts_equal_fresh_ones() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        // Garbage dense in 0xFE, with good frames of the three ids in it.
        let mut stream = [0u8; 30_000];
        let mut i = 0;
        while i < stream.len() {
            if next() % 40 == 0 && i + 8 + 40 < stream.len() {
                let (id, extra) = [(0u8, 50u8), (3, 7), (0xFE, 46)][next() as usize % 3];
                let len = next() as usize % 40;
                stream[i] = STX_V1;
                stream[i + 1] = len as u8;
                stream[i + 5] = id;
                let c = crc::frame_crc(&stream[i + 1..i + 6 + len], extra);
                stream[i + 6 + len..i + 8 + len].copy_from_slice(&c.to_le_bytes());
                i += 8 + len;
            } else {
                stream[i] = match next() % 4 {
                    0 | 1 => STX_V1,
                    2 => next() as u8 % 8,
                    _ => next() as u8,
                };
                i += 1;
            }
        }
        let (mut good_seen, mut raw_seen) = (0, 0);
        for whole_rest in [true, false] {
            let mut memo = Memo::new();
            let mut at = 0usize;
            while at < stream.len() - 1 {
                let left = stream.len() - at;
                let avail = if whole_rest {
                    left
                } else {
                    (1 + next() as usize % 700).min(left)
                };
                let bytes = &stream[at..at + avail];
                let count = avail.min(1 + next() as usize % 300);
                for (k, starts) in start_masks(bytes, count).enumerate() {
                    let (base, mask) = (64 * k, starts.kinds[0]);
                    let n = count - base;
                    let got = memo.v1_verdicts::<Three>(bytes, at as u64, base, (mask, n));
                    // The truth: the same block with the rest of the stream.
                    let rest = &stream[at..];
                    let want = Memo::new().v1_checks::<Three>(rest, at as u64, base, mask);
                    if whole_rest {
                        assert_eq!(got, want, "at {at}, block {base}");
                    } else {
                        assert_eq!(got.whole & !want.whole, 0, "whole: at {at}, block {base}");
                        assert_eq!(
                            got.good,
                            want.good & got.whole,
                            "good: at {at}, block {base}"
                        );
                        assert_eq!(got.raw & !want.raw, 0, "raw: at {at}, block {base}");
                    }
                    good_seen += got.good.count_ones();
                    raw_seen += got.raw.count_ones();
                }
                at += 1 + next() as usize % if next() % 8 == 0 { 600 } else { 20 };
            }
        }
        assert!(
            good_seen > 100 && raw_seen > 100,
            "{good_seen} good frames, {raw_seen} of unknown ids: the test must see some"
        );
    }

    /// The masks a memo remembers are those computed afresh, however the
    /// runs over a stream overlap, start and end (a candidate moving on,
    /// slices of every length, positions far apart).
    #[test]
    fn remembered_masks_equal_fresh_ones() {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        let mut stream = [0u8; 40_000];
        for b in &mut stream {
            *b = match next() % 5 {
                0 => STX_V1,
                1 => STX_V2,
                2 => 0,
                3 => 1,
                _ => next() as u8,
            };
        }
        let mut memo = Memo::new();
        let mut at = 0usize;
        while at < stream.len() - 1 {
            let avail = (1 + next() as usize % 700).min(stream.len() - at);
            let bytes = &stream[at..at + avail];
            let count = 1 + next() as usize % avail;
            for (k, want) in start_masks(bytes, count).enumerate() {
                let got = memo.starts(bytes, at as u64, 64 * k, count);
                assert_eq!(
                    (got.kinds, got.refused),
                    (want.kinds, want.refused),
                    "at {at}, {avail} bytes, count {count}"
                );
            }
            at += 1 + next() as usize % if next() % 8 == 0 { 600 } else { 20 };
        }
    }
}
