//! Value enums (generated `struct MavType(pub u8)` newtypes): the entry's
//! XML name in human-readable formats (`"MAV_TYPE_FIXED_WING"`), the number
//! for a value the XML does not list (so it is kept, as on the wire), the
//! number in compact formats. Reading takes a name or a number.
//!
//! Generated code calls [`serialize`] and [`deserialize`] with the entry
//! table; nothing here needs to be called by hand.

use super::Repr;
use core::fmt;
use serde::de::{self, Deserializer, Unexpected, Visitor};
use serde::Serializer;

/// Serializes a value enum: `name` (the entry's XML name, if it has one)
/// or the number.
pub fn serialize<R: Repr, S: Serializer>(
    serializer: S,
    value: R,
    name: Option<&'static str>,
) -> Result<S::Ok, S::Error> {
    match name {
        Some(name) if serializer.is_human_readable() => serializer.serialize_str(name),
        _ => value.serialize(serializer),
    }
}

/// Deserializes a value enum of XML name `enum_name` whose entries are
/// `entries` (XML name, value): a name of the table, or any number the
/// representation holds.
pub fn deserialize<'de, R: Repr, D: Deserializer<'de>>(
    deserializer: D,
    enum_name: &'static str,
    entries: &'static [(&'static str, R)],
) -> Result<R, D::Error> {
    if deserializer.is_human_readable() {
        deserializer.deserialize_any(EnumVisitor { enum_name, entries })
    } else {
        R::deserialize(deserializer)
    }
}

struct EnumVisitor<R: 'static> {
    enum_name: &'static str,
    entries: &'static [(&'static str, R)],
}

impl<R: Repr> Visitor<'_> for EnumVisitor<R> {
    type Value = R;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "a {} entry name or a value from 0 to {}",
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
        self.entries
            .iter()
            .find(|(name, _)| *name == v)
            .map(|&(_, value)| value)
            .ok_or_else(|| E::invalid_value(Unexpected::Str(v), &self))
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use serde::{Deserialize, Serialize};
    use std::string::{String, ToString};

    #[derive(Debug, PartialEq, Clone, Copy)]
    struct Kind(u16);

    const ENTRIES: &[(&str, u16)] = &[("KIND_A", 0), ("KIND_B", 300)];

    impl Serialize for Kind {
        fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
            let name = ENTRIES.iter().find(|e| e.1 == self.0).map(|e| e.0);
            serialize(s, self.0, name)
        }
    }

    impl<'de> Deserialize<'de> for Kind {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
            deserialize(d, "KIND", ENTRIES).map(Kind)
        }
    }

    fn back(text: &str) -> Result<Kind, String> {
        serde_json::from_str(text).map_err(|e| e.to_string())
    }

    #[test]
    fn names_for_entries_numbers_for_the_rest() {
        assert_eq!(serde_json::to_string(&Kind(300)).unwrap(), r#""KIND_B""#);
        assert_eq!(serde_json::to_string(&Kind(7)).unwrap(), "7");
        assert_eq!(back(r#""KIND_B""#), Ok(Kind(300)));
        assert_eq!(back("300"), Ok(Kind(300)));
        assert_eq!(back("65535"), Ok(Kind(65535)));
    }

    #[test]
    fn unknown_names_and_values_beyond_the_type_are_refused() {
        let e = back(r#""KIND_C""#).unwrap_err();
        assert!(e.contains("KIND entry name"), "{e}");
        assert!(back("65536").is_err());
        assert!(back("-1").is_err());
        assert!(back("1.0").is_err());
        assert!(back(r#""300""#).is_err());
    }
}
