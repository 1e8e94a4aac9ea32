//! Bitmask enums (generated flag sets): in human-readable formats the text
//! format of the bitflags crate with the flags' XML names,
//! `"MAV_MODE_FLAG_SAFETY_ARMED | MAV_MODE_FLAG_GUIDED_ENABLED | 0x40"`:
//! the named flags set, in table order, then the bits no flag names, in
//! hex; `""` for no bit. Compact formats get the number. Reading takes that
//! text (names and hex numbers joined by `|`, in any order) or a number;
//! every bit survives.
//!
//! Generated code calls [`serialize`] and [`deserialize`] with the flag
//! table; nothing here needs to be called by hand.

use super::Repr;
use core::fmt;
use serde::de::{self, Deserializer, Unexpected, Visitor};
use serde::Serializer;

/// The text of `bits` (see the module docs), as `Display`.
pub struct Text<R: 'static> {
    bits: R,
    flags: &'static [(&'static str, R)],
}

impl<R: Repr> Text<R> {
    /// The text of `bits` with the names of `flags` (XML name, value).
    pub fn new(bits: R, flags: &'static [(&'static str, R)]) -> Self {
        Text { bits, flags }
    }
}

impl<R: Repr> fmt::Display for Text<R> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let bits: u64 = self.bits.into();
        let mut rest = bits;
        let mut first = true;
        for &(name, value) in self.flags {
            let value: u64 = value.into();
            // As bitflags: a flag is named when all its bits are set and
            // some are not named yet (multi-bit flags overlap others).
            if value != 0 && bits & value == value && rest & value != 0 {
                if !first {
                    f.write_str(" | ")?;
                }
                f.write_str(name)?;
                rest &= !value;
                first = false;
            }
        }
        if rest != 0 {
            if !first {
                f.write_str(" | ")?;
            }
            write!(f, "{rest:#x}")?;
        }
        Ok(())
    }
}

/// Serializes a flag set: the text, or the number in compact formats.
pub fn serialize<R: Repr, S: Serializer>(
    serializer: S,
    bits: R,
    flags: &'static [(&'static str, R)],
) -> Result<S::Ok, S::Error> {
    if serializer.is_human_readable() {
        serializer.collect_str(&Text::new(bits, flags))
    } else {
        bits.serialize(serializer)
    }
}

/// Deserializes a flag set of XML name `enum_name` whose flags are `flags`.
pub fn deserialize<'de, R: Repr, D: Deserializer<'de>>(
    deserializer: D,
    enum_name: &'static str,
    flags: &'static [(&'static str, R)],
) -> Result<R, D::Error> {
    if deserializer.is_human_readable() {
        deserializer.deserialize_any(FlagsVisitor { enum_name, flags })
    } else {
        R::deserialize(deserializer)
    }
}

/// The bits of a text (see the module docs).
pub fn parse<R: Repr>(text: &str, flags: &[(&str, R)]) -> Option<R> {
    if text.trim().is_empty() {
        return R::try_from(0).ok();
    }
    let mut bits = 0u64;
    for token in text.split('|').map(str::trim) {
        let value = match token
            .strip_prefix("0x")
            .or_else(|| token.strip_prefix("0X"))
        {
            Some(hex) if !hex.is_empty() && hex.bytes().all(|b| b.is_ascii_hexdigit()) => {
                u64::from_str_radix(hex, 16).ok()?
            }
            Some(_) => return None,
            None => flags.iter().find(|(name, _)| *name == token)?.1.into(),
        };
        bits |= value;
    }
    R::try_from(bits).ok()
}

struct FlagsVisitor<R: 'static> {
    enum_name: &'static str,
    flags: &'static [(&'static str, R)],
}

impl<R: Repr> Visitor<'_> for FlagsVisitor<R> {
    type Value = R;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} flag names and hex numbers joined by `|`, or a value from 0 to {}",
            self.enum_name,
            R::MAX
        )
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<R, E> {
        R::try_from(v).map_err(|_| E::invalid_value(Unexpected::Unsigned(v), &self))
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<R, E> {
        u64::try_from(v)
            .ok()
            .and_then(|v| R::try_from(v).ok())
            .ok_or_else(|| E::invalid_value(Unexpected::Signed(v), &self))
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<R, E> {
        parse(v, self.flags).ok_or_else(|| E::invalid_value(Unexpected::Str(v), &self))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use serde::{Deserialize, Serialize};
    use std::string::{String, ToString};

    #[derive(Debug, PartialEq, Clone, Copy)]
    struct Modes(u8);

    /// Two single-bit flags, a two-bit flag over them, and a zero flag.
    const FLAGS: &[(&str, u8)] = &[
        ("MODE_NONE", 0),
        ("MODE_A", 1),
        ("MODE_B", 2),
        ("MODE_AB", 3),
        ("MODE_HIGH", 0x80),
    ];

    impl Serialize for Modes {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            serialize(s, self.0, FLAGS)
        }
    }

    impl<'de> Deserialize<'de> for Modes {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            deserialize(d, "MODES", FLAGS).map(Modes)
        }
    }

    fn json(bits: u8) -> String {
        serde_json::to_string(&Modes(bits)).unwrap()
    }

    fn back(text: &str) -> Result<u8, String> {
        serde_json::from_str::<Modes>(text)
            .map(|m| m.0)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn text_names_flags_then_unnamed_bits() {
        assert_eq!(json(0), r#""""#);
        assert_eq!(json(1), r#""MODE_A""#);
        assert_eq!(json(3), r#""MODE_A | MODE_B""#);
        assert_eq!(json(0x91), r#""MODE_A | MODE_HIGH | 0x10""#);
        assert_eq!(json(0x40), r#""0x40""#);
    }

    #[test]
    fn every_value_round_trips() {
        for bits in 0..=255u8 {
            assert_eq!(back(&json(bits)), Ok(bits));
        }
    }

    #[test]
    fn names_hex_and_numbers_are_read_and_the_rest_refused() {
        assert_eq!(back(r#""MODE_AB""#), Ok(3));
        assert_eq!(back(r#"" 0x10 |MODE_HIGH ""#), Ok(0x90));
        assert_eq!(back(r#""MODE_NONE""#), Ok(0));
        assert_eq!(back("145"), Ok(145));
        let e = back(r#""MODE_C""#).unwrap_err();
        assert!(e.contains("MODES flag names"), "{e}");
        assert!(back(r#""0x100""#).is_err());
        assert!(back(r#""MODE_A |""#).is_err());
        assert!(back(r#""0x""#).is_err());
        assert!(back(r#""0x+1""#).is_err());
        assert!(back("256").is_err());
        assert!(back("-1").is_err());
    }
}
