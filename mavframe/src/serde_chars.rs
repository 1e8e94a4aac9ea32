//! `char[N]` fields (`[u8; N]`): text that keeps every byte.
//!
//! Trailing NULs are padding and are dropped; everything before the last
//! non-NUL byte is kept, interior NULs and the bytes after them included.
//! Human-readable formats get that text as a string when it is UTF-8, and
//! as `{"hex": "…"}` (two lower-case digits per byte) when it is not, so a
//! string always means exactly its UTF-8 bytes. Compact formats get the
//! bytes. Reading accepts a string, `{"hex": …}`, bytes or a sequence of
//! byte values, each of at most `N` bytes (zero-padded to `N`).
//!
//! ```
//! # use mavframe::serde as serde;
//! #[derive(serde::Serialize, serde::Deserialize, PartialEq, Debug)]
//! #[serde(crate = "mavframe::serde")]
//! struct Text {
//!     #[serde(with = "mavframe::serde::chars")]
//!     text: [u8; 8],
//! }
//! let hello = Text { text: *b"hi\0there" };
//! assert_eq!(serde_json::to_string(&hello).unwrap(), r#"{"text":"hi\u0000there"}"#);
//! let latin1 = Text { text: *b"caf\xe9\0\0\0\0" };
//! assert_eq!(serde_json::to_string(&latin1).unwrap(), r#"{"text":{"hex":"636166e9"}}"#);
//! let back: Text = serde_json::from_str(r#"{"text":{"hex":"636166e9"}}"#).unwrap();
//! assert_eq!(back, latin1);
//! ```

use core::fmt;
use serde::de::{self, Deserializer, MapAccess, SeqAccess, Unexpected, Visitor};
use serde::ser::SerializeMap;
use serde::Serializer;

/// The bytes before the trailing NULs.
pub fn trimmed(bytes: &[u8]) -> &[u8] {
    let end = bytes.iter().rposition(|&b| b != 0).map_or(0, |i| i + 1);
    &bytes[..end]
}

/// Lower-case hex of some bytes, as `Display`.
pub struct Hex<'a>(pub &'a [u8]);

impl fmt::Display for Hex<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.iter().try_for_each(|b| write!(f, "{b:02x}"))
    }
}

impl serde::Serialize for Hex<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

/// Serializes a char array (`#[serde(with = "mavframe::serde::chars")]`).
pub fn serialize<S: Serializer, const N: usize>(
    value: &[u8; N],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    let bytes = trimmed(value);
    if !serializer.is_human_readable() {
        return serializer.serialize_bytes(bytes);
    }
    match core::str::from_utf8(bytes) {
        Ok(text) => serializer.serialize_str(text),
        Err(_) => {
            let mut map = serializer.serialize_map(Some(1))?;
            map.serialize_entry("hex", &Hex(bytes))?;
            map.end()
        }
    }
}

/// Deserializes a char array from any of the forms of the module docs.
pub fn deserialize<'de, D: Deserializer<'de>, const N: usize>(
    deserializer: D,
) -> Result<[u8; N], D::Error> {
    if deserializer.is_human_readable() {
        deserializer.deserialize_any(CharsVisitor::<N>)
    } else {
        deserializer.deserialize_bytes(CharsVisitor::<N>)
    }
}

struct CharsVisitor<const N: usize>;

impl<const N: usize> CharsVisitor<N> {
    fn fill<E: de::Error>(&self, bytes: &[u8]) -> Result<[u8; N], E> {
        let mut out = [0u8; N];
        out.get_mut(..bytes.len())
            .ok_or_else(|| E::invalid_length(bytes.len(), self))?
            .copy_from_slice(bytes);
        Ok(out)
    }
}

impl<'de, const N: usize> Visitor<'de> for CharsVisitor<N> {
    type Value = [u8; N];

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "text of at most {N} bytes (a string, {{\"hex\": …}} or byte values)"
        )
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<[u8; N], E> {
        self.fill(v.as_bytes())
    }

    fn visit_bytes<E: de::Error>(self, v: &[u8]) -> Result<[u8; N], E> {
        self.fill(v)
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[u8; N], A::Error> {
        let mut out = [0u8; N];
        let mut len = 0;
        while let Some(b) = seq.next_element::<u8>()? {
            *out.get_mut(len)
                .ok_or_else(|| de::Error::invalid_length(len + 1, &self))? = b;
            len += 1;
        }
        Ok(out)
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<[u8; N], A::Error> {
        let mut out = None;
        while map.next_key::<HexKey>()?.is_some() {
            if out.is_some() {
                return Err(de::Error::duplicate_field("hex"));
            }
            out = Some(map.next_value_seed(HexText::<N>)?);
        }
        out.ok_or_else(|| de::Error::missing_field("hex"))
    }
}

/// The one key of `{"hex": …}`.
struct HexKey;

impl<'de> de::Deserialize<'de> for HexKey {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_identifier(HexKey)
    }
}

impl Visitor<'_> for HexKey {
    type Value = HexKey;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("the key `hex`")
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<HexKey, E> {
        match v {
            "hex" => Ok(HexKey),
            _ => Err(E::unknown_field(v, &["hex"])),
        }
    }
}

/// The value of `{"hex": …}`: at most `N` bytes as hex digits.
struct HexText<const N: usize>;

impl<'de, const N: usize> de::DeserializeSeed<'de> for HexText<N> {
    type Value = [u8; N];

    fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<[u8; N], D::Error> {
        deserializer.deserialize_str(self)
    }
}

impl<const N: usize> Visitor<'_> for HexText<N> {
    type Value = [u8; N];

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "an even number of hex digits, at most {}", 2 * N)
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<[u8; N], E> {
        let digits = v.as_bytes();
        if digits.len() % 2 != 0 || digits.len() > 2 * N {
            return Err(E::invalid_length(digits.len(), &self));
        }
        let mut out = [0u8; N];
        // Digits only: `from_str_radix` alone would take a leading `+`.
        if !digits.iter().all(u8::is_ascii_hexdigit) {
            return Err(E::invalid_value(Unexpected::Str(v), &self));
        }
        for (slot, pair) in out.iter_mut().zip(digits.chunks(2)) {
            let high = (pair[0] as char).to_digit(16).unwrap_or(0);
            let low = (pair[1] as char).to_digit(16).unwrap_or(0);
            *slot = (high * 16 + low) as u8;
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use serde::{Deserialize, Serialize};
    use std::string::{String, ToString};

    #[derive(Serialize, Deserialize, Debug, PartialEq)]
    #[serde(crate = "::serde")]
    struct T {
        #[serde(with = "super")]
        t: [u8; 4],
    }

    fn json(t: [u8; 4]) -> String {
        serde_json::to_string(&T { t }).unwrap()
    }

    fn back(text: &str) -> Result<[u8; 4], String> {
        serde_json::from_str::<T>(text)
            .map(|v| v.t)
            .map_err(|e| e.to_string())
    }

    #[test]
    fn text_drops_only_trailing_nuls() {
        assert_eq!(json(*b"ab\0\0"), r#"{"t":"ab"}"#);
        assert_eq!(json(*b"\0\0\0\0"), r#"{"t":""}"#);
        assert_eq!(json(*b"a\0b\0"), r#"{"t":"a\u0000b"}"#);
        assert_eq!(json(*b"abcd"), r#"{"t":"abcd"}"#);
        assert_eq!(json(*b"\xff\0\x01\0"), r#"{"t":{"hex":"ff0001"}}"#);
    }

    #[test]
    fn every_byte_pattern_round_trips() {
        // All 4-byte arrays over a set of bytes covering NUL, ASCII, quote,
        // backslash, UTF-8 lead and continuation bytes and invalid bytes.
        let alphabet = [0u8, b'a', b'"', b'\\', 0x7f, 0x80, 0xc3, 0xa9, 0xff];
        for i in 0..alphabet.len().pow(4) {
            let mut t = [0u8; 4];
            let mut k = i;
            for b in &mut t {
                *b = alphabet[k % alphabet.len()];
                k /= alphabet.len();
            }
            assert_eq!(back(&json(t)), Ok(t), "{t:?}");
        }
    }

    #[test]
    fn every_input_form_is_read_and_overlong_ones_refused() {
        assert_eq!(back(r#"{"t":"ab"}"#), Ok(*b"ab\0\0"));
        assert_eq!(back(r#"{"t":[97,0,98]}"#), Ok(*b"a\0b\0"));
        assert_eq!(back(r#"{"t":{"hex":"61FF"}}"#), Ok(*b"a\xff\0\0"));
        assert!(back(r#"{"t":"abcde"}"#).is_err());
        assert!(back(r#"{"t":[1,2,3,4,5]}"#).is_err());
        assert!(back(r#"{"t":[256]}"#).is_err());
        assert!(back(r#"{"t":{"hex":"6162636465"}}"#).is_err());
        assert!(back(r#"{"t":{"hex":"616"}}"#).is_err());
        assert!(back(r#"{"t":{"hex":"+1"}}"#).is_err());
        assert!(back(r#"{"t":{"hex":"zz"}}"#).is_err());
        assert!(back(r#"{"t":{"hex":"61","hex":"62"}}"#).is_err());
        assert!(back(r#"{"t":{"text":"61"}}"#).is_err());
        assert!(back(r#"{"t":{}}"#).is_err());
        assert!(back(r#"{"t":5}"#).is_err());
    }
}
