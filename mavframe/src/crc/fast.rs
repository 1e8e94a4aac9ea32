//! Slice-by-16 (feature `fast`): the specification's update takes a
//! chain of about ten dependent operations per byte, which was most of the
//! time of stream decoding. Here sixteen bytes cost one xor of the register
//! into the first two, sixteen independent table loads and their xors;
//! only the first two loads wait for the previous block. Tails of 8, 4, 2
//! and 1 bytes use the first tables; [`frame_crc`] folds a frame's tail and
//! its CRC_EXTRA byte in one block of their exact length. Against plain
//! slice-by-8, slice-by-16 with the interleaved sums of `block` makes
//! stream decoding 15 % and encoding 37 % faster (BENCHMARKS.md).

use super::{MAX_COVERED, POLY};

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
pub(super) fn byte(crc: u16, b: u8) -> u16 {
    (crc >> 8) ^ TABLES[0][usize::from(crc as u8 ^ b)]
}

/// Folds `bytes` into `crc`.
#[inline]
pub(super) fn update(mut crc: u16, bytes: &[u8]) -> u16 {
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
    crc
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

/// See [`super::frame_crc`]. The whole 16-byte blocks go through
/// [`update`]; the rest (0–15 bytes) and CRC_EXTRA are folded in one block
/// of their exact length, instead of up to five dependent steps (8, 4, 2,
/// 1 bytes, then the seed): for the short frames of telemetry that chain
/// was most of the checksum's time.
#[inline]
pub(super) fn frame_crc(bytes: &[u8], crc_extra: u8) -> u16 {
    let whole = bytes.len() - bytes.len() % SLICES;
    let (blocks, tail) = bytes.split_at(whole);
    let crc = update(0xFFFF, blocks);
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

/// `ADVANCE[k]`: the register after `k` zero bytes (`k` ≤
/// [`MAX_COVERED`] + 1, the extra byte's step included).
///
/// `k` zero bytes are a linear map of the register: four table loads by
/// nibble for any `k` up to a frame's, independent of each other, from 33
/// KiB of tables built at compile time (only the parser's recovery path
/// reads them). Two levels of byte tables (`k = 16 a + b`: the map of
/// `16 a` after the map of `b`) take as much room and make the second two
/// loads wait for the first two: the parser's worst case (garbage dense in
/// start bytes, each a checksum) ran about 6 % slower with them
/// (`parser_worst` example); one level of byte tables would take 256 KiB.
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

/// `A^k · r`: the register `r` after `k` zero bytes (`k` ≤
/// [`MAX_COVERED`] + 1), `None` beyond.
#[inline(always)]
pub(super) fn advance(r: u16, k: usize) -> Option<u16> {
    let map = ADVANCE.get(k)?;
    let x = usize::from(r);
    Some(map[0][x & 15] ^ map[1][x >> 4 & 15] ^ map[2][x >> 8 & 15] ^ map[3][x >> 12])
}
