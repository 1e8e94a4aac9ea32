//! What the parser remembers about the positions after its candidate, so
//! that each position is decided once: whether a good frame of a known id
//! starts there (a bit), and the CRC register after it (a prefix state).
//!
//! Positions are classified in stream order, behind a frontier that only
//! moves forward. A position whose frame is not whole yet is *pending*: it
//! waits in a list keyed by the stream position at which its header, then
//! its frame, will be whole, and is classified again when the bytes reach
//! it (at most three classifications in all). A checksum over fresh bytes
//! is computed directly; one over bytes an earlier checksum covered comes
//! from two prefix states ([`crc::between_extra`]: the CRC is affine), each
//! state computed once. Rings of [`RING`] slots hold it all: the positions
//! alive at once (a candidate, the frames starting inside it, and their
//! ends) span less.

use crate::crc;
use crate::frame::{frame_len, HEADER_LEN_V1, HEADER_LEN_V2, MAX_FRAME_LEN, STX_V1, STX_V2};
use crate::message::MessageSet;

/// Slots of each ring: a frame's length. The positions alive are the
/// candidate and those inside it; the wake-up positions are less than a
/// frame after the bytes at hand; a checksum spans less than a frame.
pub(super) const RING: usize = MAX_FRAME_LEN;
const WORDS: usize = RING.div_ceil(64);

/// Whether a good frame of a known id starts inside a candidate.
#[derive(Debug, PartialEq, Eq)]
pub(super) enum Inside {
    Yes,
    No,
    /// A position inside may still start one: the first such is decided
    /// once this many bytes (from the candidate's start byte) are there.
    Undecided(usize),
}

/// What the bytes at a position say.
enum Class {
    /// No good frame of a known id starts here, whatever follows.
    NotGood,
    /// Not decided until this many bytes from here are there.
    Wait(usize),
    /// A whole frame of a known id: its checksum covers `covered` bytes.
    Whole { covered: usize, crc_extra: u8 },
}

fn class<D: MessageSet>(b: &[u8]) -> Class {
    let header = match b.first() {
        Some(&STX_V2) => HEADER_LEN_V2,
        Some(&STX_V1) => HEADER_LEN_V1,
        _ => return Class::NotGood,
    };
    if b.len() < header {
        return Class::Wait(header);
    }
    // Unknown incompatibility flags, or an unknown id: never good.
    let (Ok(len), Some(meta)) = (frame_len(b), D::meta(super::msg_id(b))) else {
        return Class::NotGood;
    };
    if b.len() < len {
        return Class::Wait(len);
    }
    Class::Whole {
        covered: header - 1 + usize::from(b[1]),
        crc_extra: meta.crc_extra,
    }
}

/// The checksum a whole frame of `covered` covered bytes carries.
fn carried(b: &[u8], covered: usize) -> u16 {
    u16::from_le_bytes([b[covered + 1], b[covered + 2]])
}

/// Whether the whole frame at the start of `b` carries the checksum of its
/// `covered` bytes, computed directly: one bounds check for the covered
/// bytes and the checksum after them (every frame of a valid stream comes
/// here).
// Inlined where size does not count (`fast`): every frame comes here.
#[cfg_attr(feature = "fast", inline(always))]
#[cfg_attr(not(feature = "fast"), inline(never))]
fn direct_good(b: &[u8], covered: usize, crc_extra: u8) -> bool {
    let Some(body) = b.get(1..covered + 3) else {
        return false;
    };
    let (data, sum) = body.split_at(covered);
    crc::frame_crc(data, crc_extra) == u16::from_le_bytes([sum[0], sum[1]])
}

// Out of line in small builds (about fifteen callers).
#[cfg_attr(not(feature = "fast"), inline(never))]
#[cfg(target_pointer_width = "64")]
fn slot(x: u64) -> usize {
    (x % RING as u64) as usize
}

// The same in 32-bit steps: a 32-bit board has no 64-bit division, and
// the library's for it costs a microcontroller ~900 bytes of code and a
// call per byte parsed.
#[cfg_attr(not(feature = "fast"), inline(never))]
#[cfg(not(target_pointer_width = "64"))]
fn slot(x: u64) -> usize {
    slot_in_32_bits(x)
}

/// `x mod RING` from `x = hi·2³² + lo`, with `2³² mod RING` as `HIGH`.
#[cfg(any(test, not(target_pointer_width = "64")))]
fn slot_in_32_bits(x: u64) -> usize {
    const RING32: u32 = RING as u32;
    const HIGH: u32 = ((1u64 << 32) % RING as u64) as u32;
    let (hi, lo) = ((x >> 32) as u32, x as u32);
    // Below RING·HIGH + RING: no overflow.
    ((hi % RING32 * HIGH + lo % RING32) % RING32) as usize
}

/// The words holding the bits of positions `lo..hi` (fewer than
/// [`RING`]), in order: (word, shift of the first position's bit, a mask of
/// as many bits as positions in the word, the first position).
fn spans(lo: u64, hi: u64) -> impl Iterator<Item = (usize, usize, u64, u64)> {
    let (mut x, mut s) = (lo, slot(lo));
    core::iter::from_fn(move || {
        if x >= hi {
            return None;
        }
        let n = (64 - s % 64).min(RING - s).min((hi - x) as usize);
        let span = (s / 64, s % 64, mask(n), x);
        x += n as u64;
        s = if s + n == RING { 0 } else { s + n };
        Some(span)
    })
}

fn mask(n: usize) -> u64 {
    if n >= 64 {
        !0
    } else {
        (1 << n) - 1
    }
}

/// Sets (`on`) or clears the bit of position `x`.
fn set_bit(bits: &mut [u64; WORDS], x: u64, on: bool) {
    let s = slot(x);
    let m = 1 << (s % 64);
    if on {
        bits[s / 64] |= m;
    } else {
        bits[s / 64] &= !m;
    }
}

fn bit(bits: &[u64; WORDS], x: u64) -> bool {
    let s = slot(x);
    bits[s / 64] >> (s % 64) & 1 != 0
}

/// The verdict on a candidate's checksum.
#[derive(Debug, PartialEq, Eq)]
pub(super) enum Crc {
    Good,
    Bad,
}

/// See the module documentation.
// In this order (`repr(C)`): the scalars within a byte's displacement of
// the memo's address (shorter instructions), the rings after them.
#[repr(C)]
pub(super) struct Memo {
    prefix_start: u64,
    prefix_end: u64,
    /// End of the last checksum computed directly.
    direct_end: u64,
    /// Positions before it (from the candidate on) are classified.
    frontier: u64,
    /// No good or pending bit is set from here on (in garbage most
    /// searches inside a candidate end here at once).
    marked_end: u64,
    /// Nothing is known about positions from here on (the frontier, the
    /// prefix states and the last direct checksum end before).
    busy: u64,
    /// Wake-up positions up to this one are handled...
    woken: u64,
    /// ...and none is listed after this one.
    last_wake: u64,
    /// Elementary steps: see [`super::Work::steps`].
    pub(super) steps: u64,
    /// A good frame of a known id starts at the position, or one may once
    /// more bytes are there (neither: a whole frame of a known id starting
    /// there has a bad checksum).
    good: [u64; WORDS],
    pending: [u64; WORDS],
    /// `prefix[slot(x)]`: the CRC register after the bytes from
    /// `prefix_start` to `x` (exclusive), for `x` up to `prefix_end`.
    prefix: [u16; RING],
    /// Pending positions by wake-up position: `head[slot(w)]` is the slot
    /// + 1 of the first (0: none), `next[slot]` of the one after it.
    head: [u16; RING],
    next: [u16; RING],
}

impl Memo {
    pub(super) const fn new() -> Self {
        Memo {
            prefix: [0; RING],
            prefix_start: 0,
            prefix_end: 0,
            direct_end: 0,
            frontier: 0,
            good: [0; WORDS],
            pending: [0; WORDS],
            head: [0; RING],
            next: [0; RING],
            marked_end: 0,
            busy: 0,
            woken: 0,
            last_wake: 0,
            steps: 0,
        }
    }

    /// The checksum verdict on the whole frame of a known id at the start
    /// of `bytes` (stream position `at`). A frame is taken only on its own
    /// bytes' checksum: a good verdict remembered (from bytes a caller may
    /// not have passed again) is confirmed directly; the cost is the
    /// frame's, which is then consumed.
    #[cfg_attr(feature = "fast", inline)]
    #[cfg_attr(not(feature = "fast"), inline(never))]
    pub(super) fn candidate<D: MessageSet>(
        &mut self,
        bytes: &[u8],
        at: u64,
        covered: usize,
        crc_extra: u8,
    ) -> Crc {
        if at < self.busy {
            return self.remembered::<D>(bytes, at, covered, crc_extra);
        }
        // Nothing known here or after: the check without a memo. A good
        // frame is consumed (the next candidate starts after its checksum);
        // a bad one's checksum is remembered as direct, so that the
        // candidates inside it use prefix states.
        if direct_good(bytes, covered, crc_extra) {
            return Crc::Good;
        }
        self.direct(at, covered);
        Crc::Bad
    }

    /// [`Memo::candidate`] where something is known: the verdict of an
    /// earlier candidate's scan, or the checksum from prefix states. A good
    /// one is confirmed on the frame's own bytes.
    #[inline(never)]
    fn remembered<D: MessageSet>(
        &mut self,
        bytes: &[u8],
        at: u64,
        covered: usize,
        crc_extra: u8,
    ) -> Crc {
        let maybe_good = if at < self.frontier {
            self.wake::<D>(bytes, at);
            bit(&self.good, at) || bit(&self.pending, at)
        } else {
            self.frontier = at + 1;
            self.crc_at(bytes, at, at, covered, crc_extra) == Some(carried(bytes, covered))
        };
        if !maybe_good {
            return Crc::Bad;
        }
        self.direct(at, covered);
        if direct_good(bytes, covered, crc_extra) {
            Crc::Good
        } else {
            Crc::Bad
        }
    }

    /// A checksum of the frame at `at` computed directly.
    #[cfg_attr(not(feature = "fast"), inline(never))]
    fn direct(&mut self, at: u64, covered: usize) {
        self.frontier = self.frontier.max(at + 1);
        self.direct_end = self.direct_end.max(at + 1 + covered as u64);
        self.busy = self.busy.max(self.direct_end);
        self.steps += covered as u64;
    }

    /// Whether a good frame of a known id starts after the candidate at
    /// `bytes[0]` (stream position `at`) and before its `upto`th byte, as
    /// far as the bytes at hand tell.
    pub(super) fn inside<D: MessageSet>(&mut self, bytes: &[u8], at: u64, upto: usize) -> Inside {
        let hi = at + upto.min(bytes.len()) as u64;
        loop {
            self.classify_to::<D>(bytes, at, hi);
            self.steps += 1;
            let mut pending = None;
            for (w, shift, m, x) in spans(at + 1, hi.min(self.marked_end)) {
                if (self.good[w] >> shift) & m != 0 {
                    return Inside::Yes;
                }
                let p = (self.pending[w] >> shift) & m;
                if pending.is_none() && p != 0 {
                    pending = Some(x + u64::from(p.trailing_zeros()));
                }
            }
            let Some(q) = pending else {
                return Inside::No;
            };
            if let Class::Wait(n) = class::<D>(&bytes[(q - at) as usize..]) {
                return Inside::Undecided((q - at) as usize + n);
            }
            // Wake-ups are handled: only bytes other than those the
            // position was classified from get here. Decided from these
            // bytes, then the search again.
            set_bit(&mut self.pending, q, false);
            self.classify::<D>(bytes, at, q);
        }
    }

    /// Classifies the positions before `hi` not classified yet, after the
    /// pending ones whose bytes have come.
    fn classify_to<D: MessageSet>(&mut self, bytes: &[u8], at: u64, hi: u64) {
        self.wake::<D>(bytes, at);
        let lo = self.frontier.max(at);
        if lo >= hi {
            return;
        }
        for (w, shift, m, _) in spans(lo, hi) {
            self.good[w] &= !(m << shift);
            self.pending[w] &= !(m << shift);
        }
        let mut o = (lo - at) as usize;
        let end = (hi - at) as usize;
        self.steps += (end - o) as u64;
        while let Some(i) = bytes[o..end]
            .iter()
            .position(|&b| b == STX_V2 || b == STX_V1)
        {
            self.classify::<D>(bytes, at, at + (o + i) as u64);
            o += i + 1;
        }
        self.frontier = hi;
        self.busy = self.busy.max(hi);
    }

    /// Classifies position `q` (its bits clear): good, pending (listed
    /// for its wake-up), or nothing.
    fn classify<D: MessageSet>(&mut self, bytes: &[u8], at: u64, q: u64) {
        let b = &bytes[(q - at) as usize..];
        self.steps += 1;
        match class::<D>(b) {
            Class::NotGood => {}
            Class::Wait(n) => {
                let w = q + n as u64;
                set_bit(&mut self.pending, q, true);
                self.marked_end = self.marked_end.max(q + 1);
                let s = slot(q);
                self.next[s] = self.head[slot(w)];
                self.head[slot(w)] = s as u16 + 1;
                self.last_wake = self.last_wake.max(w);
                // (Only a caller that passed other bytes than before can
                // make a wake-up position one already handled.)
                self.woken = self.woken.min(w - 1);
            }
            Class::Whole { covered, crc_extra } => {
                if self.crc_at(bytes, at, q, covered, crc_extra) == Some(carried(b, covered)) {
                    set_bit(&mut self.good, q, true);
                    self.marked_end = self.marked_end.max(q + 1);
                }
            }
        }
    }

    /// Handles the wake-up positions up to the end of `bytes` (stream
    /// position `at`): their pending positions are classified again.
    fn wake<D: MessageSet>(&mut self, bytes: &[u8], at: u64) {
        let avail = at + bytes.len() as u64;
        let (mut w, base) = (slot(self.woken), slot(at));
        while self.woken < avail.min(self.last_wake) {
            self.woken += 1;
            w = if w + 1 == RING { 0 } else { w + 1 };
            let mut s = core::mem::take(&mut self.head[w]);
            self.steps += 1;
            while s != 0 {
                let sl = usize::from(s - 1);
                s = self.next[sl];
                // The position of that slot among those alive (a position
                // whose candidate has passed maps to one not classified).
                let ahead = sl + RING - base;
                let q = at + (if ahead >= RING { ahead - RING } else { ahead }) as u64;
                if q < self.frontier && bit(&self.pending, q) {
                    set_bit(&mut self.pending, q, false);
                    self.classify::<D>(bytes, at, q);
                }
            }
        }
        self.woken = self.woken.max(avail);
    }

    /// The checksum of the whole frame at position `q` (`covered` bytes
    /// after its start byte, CRC_EXTRA folded in): directly over fresh
    /// bytes, else from prefix states.
    fn crc_at(&mut self, bytes: &[u8], at: u64, q: u64, covered: usize, extra: u8) -> Option<u16> {
        let o = (q - at) as usize;
        let (s, e) = (q + 1, q + 1 + covered as u64);
        self.busy = self.busy.max(e);
        if s >= self.prefix_end.max(self.direct_end) {
            self.direct_end = e;
            self.steps += covered as u64;
            return Some(crc::frame_crc(&bytes[o + 1..o + 1 + covered], extra));
        }
        if s > self.prefix_end || s < self.prefix_start || self.prefix_end - s >= RING as u64 {
            (self.prefix_start, self.prefix_end) = (s, s);
            self.prefix[slot(s)] = 0xFFFF;
        }
        if self.prefix_end < e {
            let (mut i, from) = (slot(self.prefix_end), (self.prefix_end - at) as usize);
            let mut state = self.prefix[i];
            for &b in &bytes[from..from + (e - self.prefix_end) as usize] {
                state = crc::step(state, b);
                i = if i + 1 == RING { 0 } else { i + 1 };
                self.prefix[i] = state;
            }
            self.steps += e - self.prefix_end;
            self.prefix_end = e;
        }
        let (before, after) = (self.prefix[slot(s)], self.prefix[slot(e)]);
        crc::between_extra(before, after, covered, extra)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_32_bit_slot_is_the_remainder() {
        let edges = [
            0,
            1,
            279,
            280,
            281,
            u32::MAX as u64,
            1 << 32,
            (1 << 32) + 279,
        ];
        let far = [
            u64::MAX,
            u64::MAX - 1,
            u64::MAX / 280 * 280,
            0xdead_beef_cafe_f00d,
        ];
        for x in edges.into_iter().chain(far) {
            assert_eq!(slot_in_32_bits(x), (x % RING as u64) as usize, "{x}");
        }
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..10_000 {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            assert_eq!(slot_in_32_bits(x), (x % RING as u64) as usize, "{x}");
        }
    }
}
