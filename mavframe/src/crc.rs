//! CRC-16/MCRF4XX, the MAVLink frame checksum ("X.25" in MAVLink sources).
//!
//! Reflected polynomial 0x8408, initial value 0xFFFF, no final xor. The
//! MAVLink specification updates it a byte at a time with four shifts and
//! xors: a chain of about ten dependent operations per byte, which was most
//! of the time of stream decoding. This module computes the same function
//! "slice-by-16": sixteen tables of 256 entries (8 KiB, built at compile
//! time), so sixteen bytes cost one xor of the register into the first two,
//! sixteen independent table loads and their xors; only the first two loads
//! wait for the previous block. Tails of 8, 4, 2 and 1 bytes use the first
//! tables; [`frame_crc`] folds a frame's tail and its CRC_EXTRA byte in one
//! block of their exact length. Over the frames of a telemetry capture (36 bytes on average) it
//! is about eight times faster than the byte loop or crc-any's byte table;
//! against plain slice-by-8, slice-by-16 with the interleaved sums of
//! `block` makes stream decoding 15 % and encoding 37 % faster
//! (BENCHMARKS.md).
//!
//! The specification's byte update is kept as the reference
//! ([`update_bytewise`]); crc-any's CRC-16/MCRF4XX is the test oracle of both.

/// Reflected CRC-16/MCRF4XX polynomial (0x1021 bit-reversed).
const POLY: u16 = 0x8408;

/// Number of tables: bytes folded per step of the main loop.
const SLICES: usize = 16;

/// `TABLES[0][b]`: the CRC register after shifting byte `b` through a zero
/// register; `TABLES[k][b]`: the same followed by `k` zero bytes. A byte `k`
/// positions before the end of a block is looked up in `TABLES[k]`.
static TABLES: [[u16; 256]; SLICES] = tables();

const fn tables() -> [[u16; 256]; SLICES] {
    let mut t = [[0u16; 256]; SLICES];
    let mut b = 0;
    while b < 256 {
        let mut crc = b as u16;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ POLY
            } else {
                crc >> 1
            };
            bit += 1;
        }
        t[0][b] = crc;
        b += 1;
    }
    let mut k = 1;
    while k < SLICES {
        let mut b = 0;
        while b < 256 {
            let prev = t[k - 1][b];
            t[k][b] = (prev >> 8) ^ t[0][(prev & 0xFF) as usize];
            b += 1;
        }
        k += 1;
    }
    t
}

/// Folds an `N`-byte block (2 ≤ `N` ≤ `SLICES`) into `crc`. The register
/// is xored into the block's first two bytes; every other byte is looked up
/// independently of it. Those lookups are summed first, in four interleaved
/// sums (a shorter chain than one running xor), so that the chain from one
/// block's register to the next is only: xor, two loads, two xors.
#[inline(always)]
fn block<const N: usize>(crc: u16, bytes: &[u8; N]) -> u16 {
    let mut rest = [0u16; 4];
    let mut i = 2;
    while i < N {
        rest[i % 4] ^= TABLES[N - 1 - i][usize::from(bytes[i])];
        i += 1;
    }
    let first = crc ^ u16::from_le_bytes([bytes[0], bytes[1]]);
    (rest[0] ^ rest[1])
        ^ (rest[2] ^ rest[3])
        ^ TABLES[N - 1][usize::from(first as u8)]
        ^ TABLES[N - 2][usize::from(first >> 8)]
}

/// Folds one byte into `crc`.
#[inline(always)]
fn byte(crc: u16, b: u8) -> u16 {
    (crc >> 8) ^ TABLES[0][usize::from(crc as u8 ^ b)]
}

/// The specification's byte-at-a-time update (MAVLink `crc_accumulate`):
/// the reference the table-driven [`Crc::update`] equals.
pub fn update_bytewise(mut crc: u16, bytes: &[u8]) -> u16 {
    for &b in bytes {
        let tmp = b ^ (crc as u8);
        let tmp = tmp ^ (tmp << 4);
        crc = (crc >> 8) ^ ((tmp as u16) << 8) ^ ((tmp as u16) << 3) ^ ((tmp as u16) >> 4);
    }
    crc
}

/// A running MAVLink checksum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Crc(u16);

impl Crc {
    /// A checksum with MAVLink's initial value.
    #[inline]
    pub const fn new() -> Self {
        Crc(0xFFFF)
    }

    /// Adds bytes.
    #[inline]
    pub fn update(&mut self, bytes: &[u8]) {
        let mut crc = self.0;
        let mut blocks = bytes.chunks_exact(SLICES);
        for b in &mut blocks {
            // `chunks_exact` yields SLICES bytes: the conversion cannot fail
            // and compiles to nothing.
            if let Ok(b) = b.try_into() {
                crc = block::<SLICES>(crc, b);
            }
        }
        let mut rest = blocks.remainder();
        if let Some((b, tail)) = rest.split_first_chunk::<8>() {
            crc = block(crc, b);
            rest = tail;
        }
        if let Some((b, tail)) = rest.split_first_chunk::<4>() {
            crc = block(crc, b);
            rest = tail;
        }
        if let Some((b, tail)) = rest.split_first_chunk::<2>() {
            crc = block(crc, b);
            rest = tail;
        }
        if let Some(&b) = rest.first() {
            crc = byte(crc, b);
        }
        self.0 = crc;
    }

    /// Adds one byte.
    #[inline]
    pub fn update_byte(&mut self, b: u8) {
        self.0 = byte(self.0, b);
    }

    /// The checksum so far.
    #[inline]
    pub const fn get(&self) -> u16 {
        self.0
    }
}

impl Default for Crc {
    fn default() -> Self {
        Self::new()
    }
}

/// Folds `bytes` (`M` of them) followed by `extra` as one `N`-byte block
/// (`N = M + 1`, 2 ≤ `N` ≤ `SLICES`): [`block`] with its last byte given
/// apart, so a frame's tail and its CRC_EXTRA byte take one step.
#[inline(always)]
fn block_extra<const N: usize, const M: usize>(crc: u16, bytes: &[u8; M], extra: u8) -> u16 {
    let at = |i: usize| if i < M { bytes[i] } else { extra };
    let mut rest = [0u16; 4];
    let mut i = 2;
    while i < N {
        rest[i % 4] ^= TABLES[N - 1 - i][usize::from(at(i))];
        i += 1;
    }
    let first = crc ^ u16::from_le_bytes([at(0), at(1)]);
    (rest[0] ^ rest[1])
        ^ (rest[2] ^ rest[3])
        ^ TABLES[N - 1][usize::from(first as u8)]
        ^ TABLES[N - 2][usize::from(first >> 8)]
}

/// The checksum of a frame: `bytes` from after the start byte to the end of
/// the payload, then the message's CRC_EXTRA seed.
///
/// The whole 16-byte blocks go through [`Crc::update`]; the rest (0–15
/// bytes) and CRC_EXTRA are folded in one block of their exact length,
/// instead of up to five dependent steps (8, 4, 2, 1 bytes, then the seed):
/// for the short frames of telemetry that chain was most of the checksum's
/// time.
#[inline]
pub fn frame_crc(bytes: &[u8], crc_extra: u8) -> u16 {
    let whole = bytes.len() - bytes.len() % SLICES;
    let (blocks, tail) = bytes.split_at(whole);
    let mut crc = Crc::new();
    crc.update(blocks);
    let crc = crc.get();
    // One arm per tail length (LLVM makes the chain a jump table).
    macro_rules! tail {
        ($($m:literal => $n:literal),*) => {
            $(if let Ok(t) = <&[u8; $m]>::try_from(tail) {
                return block_extra::<$n, $m>(crc, t, crc_extra);
            })*
        };
    }
    tail!(1 => 2, 2 => 3, 3 => 4, 4 => 5, 5 => 6, 6 => 7, 7 => 8, 8 => 9,
          9 => 10, 10 => 11, 11 => 12, 12 => 13, 13 => 14, 14 => 15, 15 => 16);
    byte(crc, crc_extra)
}

/// Most bytes a frame checksum covers: a MAVLink 2 header after its start
/// byte (9 bytes) and a 255-byte payload. CRC_EXTRA is folded separately.
pub(crate) const MAX_COVERED: usize = 9 + 255;

/// `ADVANCE[k]`: the register after `k` zero bytes (`k` ≤
/// [`MAX_COVERED`] + 1, the extra byte's step included).
///
/// The register update is linear over GF(2) in (register, byte), so `k`
/// zero bytes are a linear map of the register: four table loads by nibble
/// for any `k` up to a frame's, independent of each other, from 33 KiB of
/// tables built at compile time (only the parser's recovery path reads
/// them). Two levels of byte tables (`k = 16 a + b`: the map of `16 a`
/// after the map of `b`) take as much room and make the second two loads
/// wait for the first two: the parser's worst case (garbage dense in start
/// bytes, each a checksum) ran about 6 % slower with them (`parser_worst`
/// example); one level of byte tables would take 256 KiB. [`between_extra`]
/// builds on it.
static ADVANCE: [NibbleMap; MAX_COVERED + 2] = nibble_maps();

/// A linear map of the 16-bit register, as four tables of 16 entries, one
/// per nibble of its argument.
type NibbleMap = [[u16; 16]; 4];

/// `maps[k]`: the register after `k` zero bytes, by nibbles; each map one
/// zero byte after the one before it.
const fn nibble_maps<const N: usize>() -> [NibbleMap; N] {
    let mut maps = [[[0u16; 16]; 4]; N];
    let mut nibble = 0;
    while nibble < 4 {
        let mut v = 0;
        while v < 16 {
            let mut r = (v << (4 * nibble)) as u16;
            let mut k = 0;
            while k < N {
                maps[k][nibble][v] = r;
                r = (r >> 8) ^ TABLES[0][(r & 0xFF) as usize];
                k += 1;
            }
            v += 1;
        }
        nibble += 1;
    }
    maps
}

/// `map · x`.
#[inline(always)]
fn apply_nibbles(map: &NibbleMap, x: u16) -> u16 {
    let x = usize::from(x);
    map[0][x & 15] ^ map[1][x >> 4 & 15] ^ map[2][x >> 8 & 15] ^ map[3][x >> 12]
}

/// Folds one byte into a register: the step [`between`]'s prefix states are
/// made of.
#[inline(always)]
pub(crate) fn step(crc: u16, b: u8) -> u16 {
    byte(crc, b)
}

/// The checksum, from MAVLink's initial value, of the `k` bytes between two
/// prefix states (`k` ≤ [`MAX_COVERED`]): `before` is a register after some
/// bytes, `after` the same register after `k` more, both from any common
/// start. Linearity makes it `A^k · (0xFFFF ⊕ before) ⊕ after`, where `A^k`
/// is `k` zero bytes: the checksum of any stretch of a window costs four
/// table loads once the window's prefix states are known, however many
/// candidate frames overlap in it. `None` when `k` is out of range.
#[cfg(test)]
fn between(before: u16, after: u16, k: usize) -> Option<u16> {
    advance(0xFFFF ^ before, k).map(|r| r ^ after)
}

/// [`between`] with CRC_EXTRA folded in: a frame's checksum from the
/// prefix states around the bytes it covers. The extra byte's step is
/// affine (`step(x, e) = A·x ⊕ step(0, e)`), so it is taken apart: `A^(k+1)`
/// of the start, and `A` of the end state, are independent loads, not a
/// last dependent look-up after the rest (this is the cost of each start
/// byte in garbage dense in them).
#[inline]
pub(crate) fn between_extra(before: u16, after: u16, k: usize, crc_extra: u8) -> Option<u16> {
    let end = step(after, 0) ^ TABLES[0][usize::from(crc_extra)];
    advance(0xFFFF ^ before, k + 1).map(|r| r ^ end)
}

/// `A^k · r`: the register `r` after `k` zero bytes (`k` ≤
/// [`MAX_COVERED`] + 1), `None` beyond.
#[inline(always)]
fn advance(r: u16, k: usize) -> Option<u16> {
    Some(apply_nibbles(ADVANCE.get(k)?, r))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn oracle(bytes: &[u8]) -> u16 {
        let mut c = crc_any::CRCu16::crc16mcrf4cc();
        c.digest(bytes);
        c.get_crc()
    }

    fn pseudo_random(data: &mut [u8]) {
        let mut x: u32 = 0x1234_5678;
        for b in data.iter_mut() {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *b = x as u8;
        }
    }

    #[test]
    fn check_value_of_crc16_mcrf4xx() {
        // The catalogue check value for CRC-16/MCRF4XX over "123456789".
        let mut c = Crc::new();
        c.update(b"123456789");
        assert_eq!(c.get(), 0x6F91);
        assert_eq!(update_bytewise(0xFFFF, b"123456789"), 0x6F91);
    }

    #[test]
    fn equals_crc_any_on_every_length_and_pattern() {
        let mut data = [0u8; 300];
        pseudo_random(&mut data);
        for pattern in [&data[..], &[0u8; 300][..], &[0xFFu8; 300][..]] {
            for len in 0..pattern.len() {
                let mut c = Crc::new();
                c.update(&pattern[..len]);
                assert_eq!(c.get(), oracle(&pattern[..len]), "length {len}");
                assert_eq!(
                    update_bytewise(0xFFFF, &pattern[..len]),
                    oracle(&pattern[..len]),
                    "bytewise, length {len}"
                );
            }
        }
    }

    #[test]
    fn one_byte_step_equals_the_byte_loop_exhaustively() {
        for crc in 0..=u16::MAX {
            for b in 0..=u8::MAX {
                assert_eq!(byte(crc, b), update_bytewise(crc, &[b]));
            }
        }
    }

    #[test]
    fn frame_crc_equals_crc_any_for_every_length_and_seed() {
        // Every tail length (0–15 after the whole blocks) meets the one-step
        // tail-and-seed path, for frames up to the longest.
        let mut data = [0u8; 300];
        pseudo_random(&mut data);
        for len in 0..=data.len() {
            for seed in [0x00, 0x32, 0xff] {
                let mut c = crc_any::CRCu16::crc16mcrf4cc();
                c.digest(&data[..len]);
                c.digest(&[seed]);
                assert_eq!(frame_crc(&data[..len], seed), c.get_crc(), "length {len}");
            }
        }
    }

    #[test]
    fn split_updates_equal_one_update() {
        // Any split of the input (block boundaries anywhere) gives the same
        // checksum, including the one-byte CRC_EXTRA step of frame_crc.
        let mut data = [0u8; 64];
        pseudo_random(&mut data);
        for len in 0..data.len() {
            for cut in 0..=len {
                let mut c = Crc::new();
                c.update(&data[..cut]);
                c.update(&data[cut..len]);
                assert_eq!(c.get(), oracle(&data[..len]), "length {len}, cut {cut}");
            }
            let mut extra = crc_any::CRCu16::crc16mcrf4cc();
            extra.digest(&data[..len]);
            extra.digest(&[0x32]);
            assert_eq!(frame_crc(&data[..len], 0x32), extra.get_crc());
        }
    }

    #[test]
    fn between_two_prefix_states_is_the_checksum_of_the_bytes_between() {
        // Prefix states from an arbitrary start (0 and 0x1234: the start
        // cancels out), every window of every length up to the longest.
        let mut data = [0u8; 600];
        pseudo_random(&mut data);
        data[100..140].fill(0xFD);
        for start in [0u16, 0x1234] {
            let mut prefix = [0u16; 601];
            prefix[0] = start;
            for (i, &b) in data.iter().enumerate() {
                prefix[i + 1] = step(prefix[i], b);
            }
            for s in (0..300).step_by(7) {
                for k in 0..=MAX_COVERED {
                    assert_eq!(
                        between(prefix[s], prefix[s + k], k),
                        Some(oracle(&data[s..s + k])),
                        "start {start:#x} at {s} length {k}"
                    );
                    for extra in [0u8, 0x32, 0xFF] {
                        let mut c = crc_any::CRCu16::crc16mcrf4cc();
                        c.digest(&data[s..s + k]);
                        c.digest(&[extra]);
                        assert_eq!(
                            between_extra(prefix[s], prefix[s + k], k, extra),
                            Some(c.get_crc()),
                            "with extra {extra:#x}, start {start:#x} at {s} length {k}"
                        );
                    }
                }
            }
        }
        assert_eq!(between(0, 0, 16 * (MAX_COVERED / 16 + 2)), None);
        assert_eq!(between_extra(0, 0, 16 * (MAX_COVERED / 16 + 2), 0), None);
    }
}
