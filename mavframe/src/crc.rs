//! CRC-16/MCRF4XX, the MAVLink frame checksum ("X.25" in MAVLink sources).
//!
//! Reflected polynomial 0x8408, initial value 0xFFFF, no final xor. Two
//! implementations compute the same function:
//!
//! - by default, the specification's byte update (four shifts and xors, no
//!   table) and, for the parser's recovery path, a register advanced over
//!   `k` zero bytes by a multiplication by x^(8k) mod P, from 66 bytes of
//!   tables: what a small board flashes;
//! - with the `fast` feature (which `std` turns on), "slice-by-16":
//!   sixteen tables of 256 entries (8 KiB, built at compile time), so
//!   sixteen bytes cost one xor of the register into the first two,
//!   sixteen independent table loads and their xors, and the advance by
//!   four loads from 33 KiB of tables. Over the frames of a telemetry
//!   capture (36 bytes on average) it is about eight times faster than the
//!   byte loop (BENCHMARKS.md).
//!
//! The specification's byte update is also kept as the reference
//! ([`update_bytewise`]); crc-any's CRC-16/MCRF4XX is the test oracle of
//! all of them.

#[cfg(feature = "fast")]
mod fast;
// The small implementation is the reference of the fast one's tests, so
// it is compiled for them too.
#[cfg(any(test, not(feature = "fast")))]
mod small;

#[cfg(feature = "fast")]
use fast as imp;
#[cfg(not(feature = "fast"))]
use small as imp;

/// Reflected CRC-16/MCRF4XX polynomial (0x1021 bit-reversed).
const POLY: u16 = 0x8408;

/// The specification's byte-at-a-time update (MAVLink `crc_accumulate`):
/// the reference the table-driven [`Crc::update`] equals.
pub fn update_bytewise(mut crc: u16, bytes: &[u8]) -> u16 {
    for &b in bytes {
        crc = bytewise(crc, b);
    }
    crc
}

/// One byte of [`update_bytewise`].
#[inline(always)]
const fn bytewise(crc: u16, b: u8) -> u16 {
    let tmp = b ^ (crc as u8);
    let tmp = tmp ^ (tmp << 4);
    (crc >> 8) ^ ((tmp as u16) << 8) ^ ((tmp as u16) << 3) ^ ((tmp as u16) >> 4)
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
        self.0 = imp::update(self.0, bytes);
    }

    /// Adds one byte.
    #[inline]
    pub fn update_byte(&mut self, b: u8) {
        self.0 = imp::byte(self.0, b);
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

/// The checksum of a frame: `bytes` from after the start byte to the end of
/// the payload, then the message's CRC_EXTRA seed.
#[inline]
pub fn frame_crc(bytes: &[u8], crc_extra: u8) -> u16 {
    imp::frame_crc(bytes, crc_extra)
}

/// Most bytes a frame checksum covers: a MAVLink 2 header after its start
/// byte (9 bytes) and a 255-byte payload. CRC_EXTRA is folded separately.
pub(crate) const MAX_COVERED: usize = 9 + 255;

/// Folds one byte into a register: the step [`between`]'s prefix states are
/// made of.
#[inline(always)]
pub(crate) fn step(crc: u16, b: u8) -> u16 {
    imp::byte(crc, b)
}

/// The checksum, from MAVLink's initial value, of the `k` bytes between two
/// prefix states (`k` ≤ [`MAX_COVERED`]): `before` is a register after some
/// bytes, `after` the same register after `k` more, both from any common
/// start. The register update is linear over GF(2) in (register, byte), so
/// it is `A^k · (0xFFFF ⊕ before) ⊕ after`, where `A^k` is `k` zero bytes:
/// the checksum of any stretch of a window costs one advance once the
/// window's prefix states are known, however many candidate frames overlap
/// in it. `None` when `k` is out of range.
#[cfg(test)]
fn between(before: u16, after: u16, k: usize) -> Option<u16> {
    imp::advance(0xFFFF ^ before, k).map(|r| r ^ after)
}

/// [`between`] with CRC_EXTRA folded in: a frame's checksum from the
/// prefix states around the bytes it covers. The extra byte's step is
/// affine (`step(x, e) = A·x ⊕ step(0, e)`), so it is taken apart: `A^(k+1)`
/// of the start, and `A` of the end state, are independent of each other,
/// not a last dependent step after the rest (this is the cost of each start
/// byte in garbage dense in them).
#[inline]
pub(crate) fn between_extra(before: u16, after: u16, k: usize, crc_extra: u8) -> Option<u16> {
    let end = step(after, 0) ^ step(0, crc_extra);
    imp::advance(0xFFFF ^ before, k + 1).map(|r| r ^ end)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An implementation's functions, so that each test checks every one
    /// compiled: the small one always, the fast one with its feature.
    struct Imp {
        name: &'static str,
        byte: fn(u16, u8) -> u16,
        update: fn(u16, &[u8]) -> u16,
        frame_crc: fn(&[u8], u8) -> u16,
        advance: fn(u16, usize) -> Option<u16>,
    }

    const IMPS: &[Imp] = &[
        Imp {
            name: "small",
            byte: small::byte,
            update: small::update,
            frame_crc: small::frame_crc,
            advance: small::advance,
        },
        #[cfg(feature = "fast")]
        Imp {
            name: "fast",
            byte: fast::byte,
            update: fast::update,
            frame_crc: fast::frame_crc,
            advance: fast::advance,
        },
    ];

    fn oracle(bytes: &[u8]) -> u16 {
        let mut c = crc_any::CRCu16::crc16mcrf4cc();
        c.digest(bytes);
        c.get_crc()
    }

    fn oracle_extra(bytes: &[u8], extra: u8) -> u16 {
        let mut c = crc_any::CRCu16::crc16mcrf4cc();
        c.digest(bytes);
        c.digest(&[extra]);
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
        for imp in IMPS {
            assert_eq!((imp.update)(0xFFFF, b"123456789"), 0x6F91, "{}", imp.name);
        }
    }

    #[test]
    fn equals_crc_any_on_every_length_and_pattern() {
        let mut data = [0u8; 300];
        pseudo_random(&mut data);
        for pattern in [&data[..], &[0u8; 300][..], &[0xFFu8; 300][..]] {
            for len in 0..pattern.len() {
                let want = oracle(&pattern[..len]);
                let mut c = Crc::new();
                c.update(&pattern[..len]);
                assert_eq!(c.get(), want, "length {len}");
                assert_eq!(update_bytewise(0xFFFF, &pattern[..len]), want, "bytewise");
                for imp in IMPS {
                    let got = (imp.update)(0xFFFF, &pattern[..len]);
                    assert_eq!(got, want, "{}, length {len}", imp.name);
                }
            }
        }
    }

    #[test]
    fn one_byte_step_equals_the_byte_loop_exhaustively() {
        for crc in 0..=u16::MAX {
            for b in 0..=u8::MAX {
                let want = update_bytewise(crc, &[b]);
                for imp in IMPS {
                    assert_eq!((imp.byte)(crc, b), want, "{}", imp.name);
                }
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
                let want = oracle_extra(&data[..len], seed);
                assert_eq!(frame_crc(&data[..len], seed), want, "length {len}");
                for imp in IMPS {
                    let got = (imp.frame_crc)(&data[..len], seed);
                    assert_eq!(got, want, "{}, length {len}", imp.name);
                }
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
                c.update_byte(0x32);
                assert_eq!(c.get(), oracle_extra(&data[..len], 0x32));
            }
            assert_eq!(
                frame_crc(&data[..len], 0x32),
                oracle_extra(&data[..len], 0x32)
            );
        }
    }

    #[test]
    fn advancing_over_zero_bytes_is_the_byte_loop_over_zero_bytes() {
        // Every register bit, and mixed registers, over every k in range.
        let registers = (0..16)
            .map(|b| 1u16 << b)
            .chain([0, 0xFFFF, 0x1234, 0xBEEF]);
        for r in registers {
            let mut want = r;
            for k in 0..=MAX_COVERED + 1 {
                for imp in IMPS {
                    assert_eq!(
                        (imp.advance)(r, k),
                        Some(want),
                        "{}, {r:#x} k {k}",
                        imp.name
                    );
                }
                want = update_bytewise(want, &[0]);
            }
            for imp in IMPS {
                assert_eq!((imp.advance)(r, MAX_COVERED + 2), None, "{}", imp.name);
            }
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
                        assert_eq!(
                            between_extra(prefix[s], prefix[s + k], k, extra),
                            Some(oracle_extra(&data[s..s + k], extra)),
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
