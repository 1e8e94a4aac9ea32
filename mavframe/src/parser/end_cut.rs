//! At the end of the stream (a datagram's end, a flush), the start bytes
//! whose frame that end cuts: their bytes will never come, so none of them
//! can be good, and they are rejected by a mask, 64 positions at once.
//!
//! In a datagram of garbage most start bytes claim frames longer than the
//! rest of the datagram (a 0xFE's length byte is 0xFE: a 262-byte frame).
//! Rejected one at a time, each cost the rejection loop a round (about 45
//! instructions in 300-byte datagrams of `found_c`); by mask, the blocks of
//! 64 positions cost about two instructions per position, each computed
//! once per datagram ([`EndCuts`] keeps them: the rejection loop's runs
//! start at their candidates, wherever those are, and would compute each
//! block about four times over).

use super::memo::{zero_padded, BLOCK_WINDOW};
#[cfg(test)]
use crate::frame::{frame_len, FrameError};
use crate::frame::{
    CHECKSUM_LEN, HEADER_LEN_V1, HEADER_LEN_V2, IFLAG_SIGNED, MAX_FRAME_LEN, SIGNATURE_LEN, STX_V1,
};

/// What [`EndCuts::at`] finds of 64 positions (bit `j`: the `j`-th).
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub(super) struct EndCut {
    /// Positions whose frame, were they a start byte, the end cuts (its
    /// header, or the length its header claims), as [`frame_len`] reads
    /// the header: meaningful for start bytes only.
    pub(super) cut: u64,
    /// Positions two bytes before a byte with the signed flag (for a
    /// MAVLink 2 start byte: its flags).
    pub(super) signed: u64,
}

/// Blocks kept: more than the bytes asked about span (the last
/// 64 + [`MAX_FRAME_LEN`] before the end, 344: at most seven blocks).
const SLOTS: usize = 8;

const _: () = assert!(SLOTS * 64 >= 64 + MAX_FRAME_LEN + 2 * 64);

/// The blocks of 64 positions (aligned on stream positions) computed for
/// the bytes that end at stream position `end`.
#[derive(Debug)]
pub(super) struct EndCuts {
    /// Where the bytes of the blocks kept end (`u64::MAX`: none kept).
    end: u64,
    slots: [Slot; SLOTS],
}

/// A block of [`EndCuts`]: its first position, and the first of its
/// positions the bytes held when it was computed (the ones before are
/// never asked about again: the parser's candidate only moves forward).
#[derive(Debug, Clone, Copy)]
struct Slot {
    first: u64,
    from: u64,
    cut: EndCut,
}

const EMPTY: Slot = Slot {
    first: u64::MAX,
    from: u64::MAX,
    cut: EndCut { cut: 0, signed: 0 },
};

impl Default for EndCuts {
    fn default() -> Self {
        Self::new()
    }
}

impl EndCuts {
    pub(super) const fn new() -> Self {
        EndCuts {
            end: u64::MAX,
            slots: [EMPTY; SLOTS],
        }
    }

    /// Forgets every block: the bytes at their positions may not be the
    /// ones seen ([`super::memo::Memo::forget_from`]).
    pub(super) fn forget(&mut self) {
        self.end = u64::MAX;
    }

    /// The [`EndCut`] of the 64 positions from `bytes[base]` (`bytes[0]`
    /// is stream position `at`), the stream ending with `bytes`. Nothing is
    /// cut where every frame starting in the block is whole.
    #[inline]
    pub(super) fn at(&mut self, bytes: &[u8], at: u64, base: usize) -> EndCut {
        if bytes.len().saturating_sub(base) >= 64 + MAX_FRAME_LEN {
            return EndCut::default();
        }
        let end = at + bytes.len() as u64;
        if end != self.end {
            self.slots = [EMPTY; SLOTS];
            self.end = end;
        }
        let p = at + base as u64;
        let (first, shift) = (p & !63, (p & 63) as u32);
        let lo = self.block(bytes, at, first, p);
        if shift == 0 {
            return lo;
        }
        let hi = self.block(bytes, at, first + 64, first + 64);
        EndCut {
            cut: lo.cut >> shift | hi.cut << (64 - shift),
            signed: lo.signed >> shift | hi.signed << (64 - shift),
        }
    }

    /// The block of positions from `first` (a multiple of 64), known or
    /// computed from `bytes` (from stream position `at`; asked about
    /// positions from `p` on, `p` in the block).
    #[inline]
    fn block(&mut self, bytes: &[u8], at: u64, first: u64, p: u64) -> EndCut {
        let slot = &mut self.slots[(first / 64) as usize % SLOTS];
        if slot.first == first && slot.from <= p {
            return slot.cut;
        }
        let cut = compute(bytes, at, first, self.end);
        *slot = Slot {
            first,
            from: first.max(at),
            cut,
        };
        cut
    }
}

/// The [`EndCut`] of the 64 positions from stream position `first`, from
/// `bytes` (stream position `at` on, ending at `end`). Zeros stand for the
/// positions before `at` (never asked about) and after `end`: a header
/// reaching past the end is cut whatever those hold, and is not signed.
#[inline(never)]
fn compute(bytes: &[u8], at: u64, first: u64, end: u64) -> EndCut {
    if first >= end {
        // No start bytes there.
        return EndCut::default();
    }
    let from = first.max(at);
    let (skip, rel) = ((from - first) as usize, (from - at) as usize);
    let window = zero_padded(&bytes[rel.min(bytes.len())..], skip);
    // At most 64 + MAX_FRAME_LEN + 63: an i16.
    let room = (end - first).min(i16::MAX as u64) as usize;
    cut_of_block(&window, room)
}

/// The [`EndCut`] of the 64 positions at the start of `window` (66 bytes:
/// the length and flags of the last two after them), with `room` bytes from
/// the first to the end: position `j` is cut when `j` plus the frame
/// length its header claims is past `room` (the length byte, plus 8 after
/// 0xFE, else plus 12, and 13 more when the flags say signed). 16
/// positions at a time in SSE2 registers (every x86-64 has them), the sums
/// in 16-bit lanes.
#[cfg(all(
    any(target_arch = "x86", target_arch = "x86_64"),
    target_feature = "sse2"
))]
fn cut_of_block(window: &[u8; BLOCK_WINDOW], room: usize) -> EndCut {
    use safe_arch::{
        add_i16_m128i, add_i8_m128i, bitand_m128i, bitandnot_m128i, cmp_eq_mask_i8_m128i,
        cmp_gt_mask_i16_m128i, load_unaligned_m128i, m128i, move_mask_i8_m128i,
        pack_i16_to_i8_m128i, set_splat_i16_m128i, set_splat_i8_m128i, unpack_high_i8_m128i,
        unpack_low_i8_m128i, zeroed_m128i,
    };
    let load = |i: usize| -> m128i {
        let mut b = [0u8; 16];
        b.copy_from_slice(&window[i..i + 16]);
        load_unaligned_m128i(&b)
    };
    let splat = |b: usize| set_splat_i8_m128i(b as i8);
    let zero = zeroed_m128i();
    let room = room.min(i16::MAX as usize) as i16;
    let (mut cut, mut signed_bits) = (0u64, 0u64);
    for k in 0..4 {
        let (stx, len, flags) = (load(16 * k), load(16 * k + 1), load(16 * k + 2));
        let v1 = cmp_eq_mask_i8_m128i(stx, splat(STX_V1.into()));
        let flag = splat(IFLAG_SIGNED.into());
        let signed = cmp_eq_mask_i8_m128i(bitand_m128i(flags, flag), flag);
        // The bytes besides the payload: 8 (MAVLink 1), else 12 (+ 13).
        let v2_more = add_i8_m128i(
            bitand_m128i(signed, splat(SIGNATURE_LEN)),
            splat(HEADER_LEN_V2 - HEADER_LEN_V1),
        );
        let besides = add_i8_m128i(
            bitandnot_m128i(v1, v2_more),
            splat(HEADER_LEN_V1 + CHECKSUM_LEN),
        );
        // The room left at each position: `room - j`.
        let left_lo = add_i16_m128i(
            set_splat_i16_m128i(room - (16 * k) as i16),
            m128i::from([0i16, -1, -2, -3, -4, -5, -6, -7]),
        );
        let left_hi = add_i16_m128i(left_lo, set_splat_i16_m128i(-8));
        let widen = |v: m128i| (unpack_low_i8_m128i(v, zero), unpack_high_i8_m128i(v, zero));
        let ((len_lo, len_hi), (besides_lo, besides_hi)) = (widen(len), widen(besides));
        let over = pack_i16_to_i8_m128i(
            cmp_gt_mask_i16_m128i(add_i16_m128i(len_lo, besides_lo), left_lo),
            cmp_gt_mask_i16_m128i(add_i16_m128i(len_hi, besides_hi), left_hi),
        );
        cut |= u64::from(move_mask_i8_m128i(over) as u16) << (16 * k);
        signed_bits |= u64::from(move_mask_i8_m128i(signed) as u16) << (16 * k);
    }
    EndCut {
        cut,
        signed: signed_bits,
    }
}

/// [`cut_of_block`] a position at a time: where SSE2 is not there, and the
/// reference of the tests.
#[cfg_attr(
    all(
        any(target_arch = "x86", target_arch = "x86_64"),
        target_feature = "sse2"
    ),
    allow(dead_code)
)]
fn cut_by_positions(window: &[u8; BLOCK_WINDOW], room: usize) -> EndCut {
    let byte = |i: usize| window.get(i).copied().unwrap_or(0);
    let (mut cut, mut signed) = (0u64, 0u64);
    for j in 0..64 {
        let is_signed = byte(j + 2) & IFLAG_SIGNED != 0;
        let besides = match byte(j) {
            STX_V1 => HEADER_LEN_V1 + CHECKSUM_LEN,
            _ if is_signed => HEADER_LEN_V2 + CHECKSUM_LEN + SIGNATURE_LEN,
            _ => HEADER_LEN_V2 + CHECKSUM_LEN,
        };
        cut |= u64::from(j + usize::from(byte(j + 1)) + besides > room) << j;
        signed |= u64::from(is_signed) << j;
    }
    EndCut { cut, signed }
}

#[cfg(not(all(
    any(target_arch = "x86", target_arch = "x86_64"),
    target_feature = "sse2"
)))]
fn cut_of_block(window: &[u8; BLOCK_WINDOW], room: usize) -> EndCut {
    cut_by_positions(window, room)
}

/// Whether the frame of the start byte `bytes[rel]` is cut by the end of
/// `bytes`, as `frame_len` reads its header: what each bit of
/// [`EndCut::cut`] says of a start byte.
#[cfg(test)]
fn cut_by_end(bytes: &[u8], rel: usize) -> bool {
    match bytes.get(rel..).map(frame_len) {
        Some(Ok(n)) => bytes.len() - rel < n,
        Some(Err(FrameError::Incomplete { .. })) => true,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{IFLAG_KNOWN, STX_V2};

    const MOST: usize = 64 + MAX_FRAME_LEN + 70;

    /// Garbage: mostly start bytes, short lengths, flags 0/1.
    fn bytes(x: &mut u64) -> [u8; MOST] {
        core::array::from_fn(|_| {
            *x ^= *x << 13;
            *x ^= *x >> 7;
            *x ^= *x << 17;
            match (*x >> 40) % 8 {
                0 | 1 => STX_V1,
                2 | 3 => STX_V2,
                4 => 1,
                5 => (*x >> 48) as u8 % 40,
                _ => (*x >> 48) as u8,
            }
        })
    }

    /// Every start byte's bit is what `frame_len` says of its frame, for
    /// bytes of every length near the longest frame, asked about from
    /// every position (blocks kept or computed, aligned or not), with the
    /// bytes starting anywhere in a block.
    #[test]
    fn each_start_bytes_cut_bit_is_what_frame_len_says() {
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for round in 0..300 {
            let len = 1 + round % MOST;
            let all = &bytes(&mut x)[..len];
            let at = 1000 + round as u64 * 7;
            let mut cuts = EndCuts::default();
            for base in 0..len {
                let got = cuts.at(all, at, base);
                for j in 0..64.min(len - base) {
                    let rel = base + j;
                    let start = matches!(all[rel], STX_V1 | STX_V2);
                    let refused = all[rel] == STX_V2
                        && all.len() >= rel + HEADER_LEN_V2
                        && all[rel + 2] & !IFLAG_KNOWN != 0;
                    if start && !refused {
                        assert_eq!(
                            got.cut >> j & 1 != 0,
                            cut_by_end(all, rel),
                            "len {len} base {base} j {j}"
                        );
                    }
                    let signed = all.get(rel + 2).is_some_and(|f| f & IFLAG_SIGNED != 0);
                    assert_eq!(
                        got.signed >> j & 1 != 0,
                        signed,
                        "len {len} base {base} j {j}"
                    );
                }
            }
        }
    }

    /// The same from bytes that start later, as the parser passes them
    /// once it has dropped a candidate's bytes.
    #[test]
    fn blocks_computed_from_later_bytes_answer_for_those() {
        let mut x = 0x2545_F491_4F6C_DD1Du64;
        for round in 0..200 {
            let len = 64 + round % 300;
            let all = &bytes(&mut x)[..len];
            let mut cuts = EndCuts::default();
            let mut start = 0;
            while start < len {
                let got = cuts.at(&all[start..], 64 * 9 + start as u64, 0);
                let fresh = EndCuts::default().at(&all[start..], 64 * 9 + start as u64, 0);
                assert_eq!(got, fresh, "len {len} start {start}");
                start += 1 + (x as usize % 23);
            }
        }
    }

    #[test]
    fn vectors_equal_positions() {
        let mut x = 0x1234_5678_9ABC_DEF1u64;
        for round in 0..2000 {
            let window: [u8; 66] = bytes(&mut x)[..66].try_into().unwrap();
            let room = round % (64 + MAX_FRAME_LEN + 64);
            assert_eq!(cut_of_block(&window, room), cut_by_positions(&window, room));
        }
    }
}
