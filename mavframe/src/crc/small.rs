//! The default implementation, for small boards: the specification's byte
//! update (no table), and the register advanced over `k` zero bytes by one
//! multiplication by x^(8k) mod P, from 66 bytes of powers of x.

use super::{bytewise, MAX_COVERED, POLY};

/// Folds one byte into `crc`.
#[inline(never)]
pub(super) fn byte(crc: u16, b: u8) -> u16 {
    bytewise(crc, b)
}

/// Folds `bytes` into `crc`.
#[inline(never)]
pub(super) fn update(mut crc: u16, bytes: &[u8]) -> u16 {
    for &b in bytes {
        crc = byte(crc, b);
    }
    crc
}

/// See [`super::frame_crc`].
#[inline]
pub(super) fn frame_crc(bytes: &[u8], crc_extra: u8) -> u16 {
    byte(update(0xFFFF, bytes), crc_extra)
}

/// The register is a polynomial over GF(2) of degree below 16, reflected:
/// bit 15 is the coefficient of x^0, bit 0 that of x^15. One zero byte
/// through the register multiplies it by x^8 modulo the CRC's polynomial
/// P; `k` of them by x^(8k) mod P.
///
/// `a · x mod P`: one bit through the register.
const fn times_x(a: u16) -> u16 {
    if a & 1 != 0 {
        (a >> 1) ^ POLY
    } else {
        a >> 1
    }
}

/// `a · b mod P`: sixteen steps, whatever the operands.
#[inline(never)]
fn multiply(a: u16, mut b: u16) -> u16 {
    let mut product = 0;
    for bit in (0..16).rev() {
        // The coefficient of x^(15 - bit) of `a`, times `b · x^(15 - bit)`.
        product ^= b & 0u16.wrapping_sub(a >> bit & 1);
        b = times_x(b);
    }
    product
}

/// x^(8k) mod P for `k` = 16 `a` + `b`: `HIGH[a]` · `LOW[b]`, from two
/// tables of 17 and 16 powers (66 bytes).
static LOW: [u16; 16] = powers(1);
static HIGH: [u16; (MAX_COVERED + 1) / 16 + 1] = powers(16);

/// `t[i]`: x^(8 · step · i) mod P.
const fn powers<const N: usize>(step: usize) -> [u16; N] {
    let mut t = [0u16; N];
    // x^0.
    let mut p = 0x8000;
    let mut i = 0;
    while i < N {
        t[i] = p;
        let mut bit = 0;
        while bit < 8 * step {
            p = times_x(p);
            bit += 1;
        }
        i += 1;
    }
    t
}

/// `A^k · r`: the register `r` after `k` zero bytes (`k` ≤
/// [`MAX_COVERED`] + 1), `None` beyond.
#[inline]
pub(super) fn advance(r: u16, k: usize) -> Option<u16> {
    if k > MAX_COVERED + 1 {
        return None;
    }
    Some(multiply(multiply(HIGH[k / 16], LOW[k % 16]), r))
}
