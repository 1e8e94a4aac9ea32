//! `float` and `double` fields: every bit pattern survives, in any format.
//!
//! Compact formats get the native value (their encodings keep all bits).
//! Human-readable ones get a number for finite values and a string
//! otherwise, because JSON has no NaN or infinity: `"inf"`, `"-inf"`,
//! `"NaN"` for the canonical quiet NaN (`0x7fc00000`, `0x7ff8000000000000`)
//! and `"NaN:0x…"` with the bit pattern (8 or 16 hex digits) for every
//! other NaN, so sign and payload bits survive. These are the strings of
//! `fbwag decode`.
//!
//! Reading a `float` from text: formats hand over decimal numbers as `f64`;
//! the nearest `f64` then rounds to the nearest `f32`. That second rounding
//! can only go wrong when the `f64` lies exactly halfway between two `f32`
//! values; then the value whose shortest decimal form (what serializers
//! write, e.g. `7.038531e-26`) gives that `f64` wins, so every `f32` this
//! module wrote reads back exactly. (serde_json needs its `float_roundtrip`
//! feature for `f64` numbers to be parsed exactly in the first place.)
//!
//! ```
//! # use mavframe::serde as serde;
//! #[derive(serde::Serialize, serde::Deserialize)]
//! #[serde(crate = "mavframe::serde")]
//! struct Sample {
//!     #[serde(with = "mavframe::serde::float")]
//!     roll: f32,
//! }
//! let text = serde_json::to_string(&Sample { roll: f32::NAN }).unwrap();
//! assert_eq!(text, r#"{"roll":"NaN"}"#);
//! let back: Sample = serde_json::from_str(r#"{"roll":"NaN:0xffc00001"}"#).unwrap();
//! assert_eq!(back.roll.to_bits(), 0xffc0_0001);
//! ```

use core::fmt::{self, Write as _};
use core::marker::PhantomData;
use serde::de::{self, Deserializer, Unexpected, Visitor};
use serde::{Deserialize, Serialize, Serializer};

mod sealed {
    pub trait Sealed {}
    impl Sealed for f32 {}
    impl Sealed for f64 {}
}

/// `f32` and `f64`, the float types of MAVLink fields.
pub trait Float:
    Copy + PartialEq + fmt::Debug + Serialize + for<'de> Deserialize<'de> + sealed::Sealed + 'static
{
    /// Bits of the NaN written as plain `"NaN"`.
    const CANONICAL_NAN: u64;
    /// Hex digits of a bit pattern.
    const HEX_DIGITS: usize;
    /// The C type name (`float`, `double`).
    const C_NAME: &'static str;
    /// The bit pattern, widened to 64 bits.
    fn to_bits64(self) -> u64;
    /// The value of a bit pattern (only the low `HEX_DIGITS * 4` bits count).
    fn from_bits64(bits: u64) -> Self;
    /// Infinity of the given sign.
    fn infinity(negative: bool) -> Self;
    /// Whether the value is a NaN.
    fn is_nan(self) -> bool;
    /// Whether the value is neither NaN nor infinite.
    fn is_finite(self) -> bool;
    /// A value read as `f64` from text, rounded to this type; `None` when a
    /// finite value is beyond the type's range.
    fn from_f64(v: f64) -> Option<Self>;
    /// An integer read from text, rounded to this type.
    fn from_i128(v: i128) -> Self;
}

impl Float for f32 {
    const CANONICAL_NAN: u64 = 0x7fc0_0000;
    const HEX_DIGITS: usize = 8;
    const C_NAME: &'static str = "float";

    fn to_bits64(self) -> u64 {
        u64::from(self.to_bits())
    }

    fn from_bits64(bits: u64) -> Self {
        // Only the low 32 bits hold an f32 pattern.
        f32::from_bits(bits as u32)
    }

    fn infinity(negative: bool) -> Self {
        if negative {
            f32::NEG_INFINITY
        } else {
            f32::INFINITY
        }
    }

    fn is_nan(self) -> bool {
        f32::is_nan(self)
    }

    fn is_finite(self) -> bool {
        f32::is_finite(self)
    }

    fn from_f64(v: f64) -> Option<Self> {
        narrow(v)
    }

    fn from_i128(v: i128) -> Self {
        v as f32
    }
}

impl Float for f64 {
    const CANONICAL_NAN: u64 = 0x7ff8_0000_0000_0000;
    const HEX_DIGITS: usize = 16;
    const C_NAME: &'static str = "double";

    fn to_bits64(self) -> u64 {
        self.to_bits()
    }

    fn from_bits64(bits: u64) -> Self {
        f64::from_bits(bits)
    }

    fn infinity(negative: bool) -> Self {
        if negative {
            f64::NEG_INFINITY
        } else {
            f64::INFINITY
        }
    }

    fn is_nan(self) -> bool {
        f64::is_nan(self)
    }

    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }

    fn from_f64(v: f64) -> Option<Self> {
        Some(v)
    }

    fn from_i128(v: i128) -> Self {
        v as f64
    }
}

/// `v` rounded to `f32` (see the module docs for the halfway case);
/// `None` for a finite `v` beyond `f32`'s range.
fn narrow(v: f64) -> Option<f32> {
    let x = v as f32;
    if x.is_infinite() && v.is_finite() {
        return None;
    }
    if !x.is_finite() || f64::from(x) == v {
        return Some(x);
    }
    // The f32 on the other side of `v`; `v` is halfway when it is the mean
    // of the two (exact in f64: adjacent f32 values differ in 24 bits).
    let toward_v = if f64::from(x) < v { 1i64 } else { -1 };
    let step = if x.is_sign_negative() {
        -toward_v
    } else {
        toward_v
    };
    let other = f32::from_bits((i64::from(x.to_bits()) + step) as u32);
    if !other.is_finite() || (f64::from(x) + f64::from(other)) / 2.0 != v {
        return Some(x);
    }
    // Halfway: `as` rounded to even. The text was one of the two values'
    // shortest forms; keep the one whose form reads as `v`.
    if reads_as(x, v) || !reads_as(other, v) {
        Some(x)
    } else {
        Some(other)
    }
}

/// Whether `x`'s shortest decimal form parses to the `f64` `v`.
fn reads_as(x: f32, v: f64) -> bool {
    let mut text = StackText::<48>::new();
    // `Debug` is the shortest form that reads back as `x`.
    if write!(text, "{x:?}").is_err() {
        return false;
    }
    text.as_str().parse::<f64>() == Ok(v)
}

/// A small text buffer on the stack (no allocation in `no_std`).
pub(crate) struct StackText<const N: usize> {
    buf: [u8; N],
    len: usize,
}

impl<const N: usize> StackText<N> {
    pub(crate) fn new() -> Self {
        StackText {
            buf: [0; N],
            len: 0,
        }
    }

    pub(crate) fn as_str(&self) -> &str {
        // Only whole `&str`s are ever appended.
        core::str::from_utf8(&self.buf[..self.len]).unwrap_or("")
    }
}

impl<const N: usize> fmt::Write for StackText<N> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        let end = self.len + s.len();
        let dst = self.buf.get_mut(self.len..end).ok_or(fmt::Error)?;
        dst.copy_from_slice(s.as_bytes());
        self.len = end;
        Ok(())
    }
}

/// The string a value that is not a finite number is written as (see the
/// module docs); its `Display` is the text, without quotes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Special {
    kind: SpecialKind,
    bits: u64,
    digits: usize,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum SpecialKind {
    Nan,
    NanBits,
    Inf,
    NegInf,
}

impl fmt::Display for Special {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.kind {
            SpecialKind::Nan => f.write_str("NaN"),
            SpecialKind::NanBits => write!(f, "NaN:0x{:0w$x}", self.bits, w = self.digits),
            SpecialKind::Inf => f.write_str("inf"),
            SpecialKind::NegInf => f.write_str("-inf"),
        }
    }
}

/// The string for `v`, or `None` when `v` is finite (and written as a number).
pub fn special<F: Float>(v: F) -> Option<Special> {
    let bits = v.to_bits64();
    let kind = if v.is_finite() {
        return None;
    } else if !v.is_nan() {
        if v == F::infinity(true) {
            SpecialKind::NegInf
        } else {
            SpecialKind::Inf
        }
    } else if bits == F::CANONICAL_NAN {
        SpecialKind::Nan
    } else {
        SpecialKind::NanBits
    };
    Some(Special {
        kind,
        bits,
        digits: F::HEX_DIGITS,
    })
}

/// Why a string is not one of the float strings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SpecialError {
    /// Not `"NaN"`, `"inf"`, `"-inf"` or `"NaN:0x"` with the type's number
    /// of hex digits.
    Unknown,
    /// `"NaN:0x…"` with bits that are not a NaN (an infinity or a number).
    NotNan,
}

impl fmt::Display for SpecialError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SpecialError::Unknown => {
                "expected \"NaN\", \"NaN:0x\" and the bits in hex, \"inf\" or \"-inf\""
            }
            SpecialError::NotNan => "these bits are not a NaN",
        })
    }
}

impl core::error::Error for SpecialError {}

/// The value of one of the float strings (see the module docs).
pub fn parse_special<F: Float>(s: &str) -> Result<F, SpecialError> {
    match s {
        "NaN" => return Ok(F::from_bits64(F::CANONICAL_NAN)),
        "inf" => return Ok(F::infinity(false)),
        "-inf" => return Ok(F::infinity(true)),
        _ => {}
    }
    let v = s
        .strip_prefix("NaN:0x")
        .filter(|h| h.len() == F::HEX_DIGITS && h.bytes().all(|b| b.is_ascii_hexdigit()))
        .and_then(|h| u64::from_str_radix(h, 16).ok())
        .map(F::from_bits64)
        .ok_or(SpecialError::Unknown)?;
    if v.is_nan() {
        Ok(v)
    } else {
        Err(SpecialError::NotNan)
    }
}

/// Serializes a float field (`#[serde(with = "mavframe::serde::float")]`).
pub fn serialize<F: Float, S: Serializer>(v: &F, serializer: S) -> Result<S::Ok, S::Error> {
    match special(*v) {
        Some(text) if serializer.is_human_readable() => serializer.collect_str(&text),
        _ => v.serialize(serializer),
    }
}

/// Deserializes a float field: any number, or one of the strings.
pub fn deserialize<'de, F: Float, D: Deserializer<'de>>(deserializer: D) -> Result<F, D::Error> {
    if deserializer.is_human_readable() {
        deserializer.deserialize_any(FloatVisitor(PhantomData))
    } else {
        F::deserialize(deserializer)
    }
}

struct FloatVisitor<F>(PhantomData<F>);

impl<F: Float> Visitor<'_> for FloatVisitor<F> {
    type Value = F;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "a {} (a number, \"NaN\", \"NaN:0x…\", \"inf\" or \"-inf\")",
            F::C_NAME
        )
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<F, E> {
        F::from_f64(v).ok_or_else(|| E::invalid_value(Unexpected::Float(v), &self))
    }

    fn visit_f32<E: de::Error>(self, v: f32) -> Result<F, E> {
        // Widening is exact, and narrowing an f32 gives it back.
        self.visit_f64(f64::from(v))
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<F, E> {
        Ok(F::from_i128(i128::from(v)))
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<F, E> {
        Ok(F::from_i128(i128::from(v)))
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<F, E> {
        parse_special(v).map_err(|_| E::invalid_value(Unexpected::Str(v), &self))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::format;
    use std::string::{String, ToString};

    #[derive(Serialize, Deserialize, Debug, PartialEq)]
    #[serde(crate = "::serde")]
    struct Both {
        #[serde(with = "super")]
        f: f32,
        #[serde(with = "super")]
        d: f64,
    }

    fn json(f: f32, d: f64) -> String {
        serde_json::to_string(&Both { f, d }).unwrap()
    }

    fn back(text: &str) -> Result<(u32, u64), String> {
        serde_json::from_str::<Both>(text)
            .map(|b| (b.f.to_bits(), b.d.to_bits()))
            .map_err(|e| e.to_string())
    }

    #[test]
    fn specials_are_strings_and_numbers_stay_numbers() {
        assert_eq!(json(1.5, -0.0), r#"{"f":1.5,"d":-0.0}"#);
        assert_eq!(json(f32::NAN, f64::NAN), r#"{"f":"NaN","d":"NaN"}"#);
        assert_eq!(
            json(f32::INFINITY, f64::NEG_INFINITY),
            r#"{"f":"inf","d":"-inf"}"#
        );
        assert_eq!(
            json(
                f32::from_bits(0xffc0_0001),
                f64::from_bits(0x7ff0_0000_0000_0001)
            ),
            r#"{"f":"NaN:0xffc00001","d":"NaN:0x7ff0000000000001"}"#
        );
    }

    #[test]
    fn every_form_reads_back_bit_for_bit() {
        for (f, d) in [
            (0x7fc0_0000u32, 0x7ff8_0000_0000_0000u64),
            (0xffc0_0001, 0xfff0_0000_0000_0001),
            (0x7f80_0000, 0xfff0_0000_0000_0000),
            (0x8000_0000, 0x8000_0000_0000_0000),
            (1, 1),
            (0x7f7f_ffff, 0x7fef_ffff_ffff_ffff),
        ] {
            let text = json(f32::from_bits(f), f64::from_bits(d));
            assert_eq!(back(&text), Ok((f, d)), "{text}");
        }
    }

    /// Random bit patterns through serde_json (whose shortest forms are
    /// what `narrow` must undo). Every finite f32 was checked once this
    /// way, outside the test suite (2^32 patterns, serde_json 1.0.154):
    /// 0x15ae43fd was the only one `as` alone got wrong.
    #[test]
    fn random_bit_patterns_round_trip_through_json() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for _ in 0..100_000 {
            // xorshift64*: deterministic, no dependency.
            state ^= state >> 12;
            state ^= state << 25;
            state ^= state >> 27;
            let r = state.wrapping_mul(0x2545_f491_4f6c_dd1d);
            let (f, d) = (r as u32, r.rotate_left(17));
            let text = json(f32::from_bits(f), f64::from_bits(d));
            assert_eq!(back(&text), Ok((f, d)), "{text}");
        }
    }

    #[test]
    fn out_of_range_and_unknown_strings_are_refused() {
        assert!(back(r#"{"f":1e39,"d":0}"#).unwrap_err().contains("float"));
        assert!(back(r#"{"f":"nan","d":0}"#).is_err());
        assert!(back(r#"{"f":"NaN:0x7f800000","d":0}"#).is_err());
        assert!(back(r#"{"f":"NaN:0x7fc0000","d":0}"#).is_err());
        assert!(back(r#"{"f":true,"d":0}"#).is_err());
        // The largest finite values and integers are fine.
        assert_eq!(
            back(r#"{"f":3.4028235e38,"d":2}"#),
            Ok((f32::MAX.to_bits(), 2f64.to_bits()))
        );
        assert_eq!(
            parse_special::<f32>("NaN:0x7f800000"),
            Err(SpecialError::NotNan)
        );
        assert_eq!(
            parse_special::<f64>("NaN:0x7fc00001"),
            Err(SpecialError::Unknown)
        );
    }

    /// 7.038531e-26 is the shortest form of the f32 0x15ae43fd; its nearest
    /// f64 lies exactly halfway between that f32 and the next, where `as`
    /// rounds to the even one (0x15ae43fe).
    #[test]
    fn halfway_doubles_read_as_the_float_that_was_written() {
        let x = f32::from_bits(0x15ae_43fd);
        assert_eq!(format!("{x:?}"), "7.038531e-26");
        let v: f64 = "7.038531e-26".parse().unwrap();
        assert_eq!((v as f32).to_bits(), 0x15ae_43fe, "the trap is real");
        assert_eq!(narrow(v).map(f32::to_bits), Some(0x15ae_43fd));
        assert_eq!(narrow(-v).map(f32::to_bits), Some(0x95ae_43fd));
        // The even neighbour's own form still reads as itself.
        let y = f32::from_bits(0x15ae_43fe);
        let w: f64 = format!("{y:?}").parse().unwrap();
        assert_eq!(narrow(w).map(f32::to_bits), Some(0x15ae_43fe));
    }
}
