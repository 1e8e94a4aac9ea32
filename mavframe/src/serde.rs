//! Serde for generated messages and enums (feature `serde`).
//!
//! This module is the [serde](https://serde.rs) crate itself, re-exported
//! (`mavframe::serde::Serialize`, `mavframe::serde::de`, the derives…), so
//! crates that include generated bindings need no serde dependency of their
//! own: generated code derives with `#[serde(crate = "::mavframe::serde")]`.
//! serde is built without `std` or `alloc`, like the rest of the crate.
//!
//! Its own submodules are the forms of MAVLink values, one per kind of
//! field. Which form a format gets follows
//! [`Serializer::is_human_readable`]: JSON, YAML and TOML are
//! human-readable, postcard and bincode are compact.
//!
//! | values | human-readable | compact |
//! |---|---|---|
//! | [value enums](value_enum) | `"MAV_TYPE_FIXED_WING"`; a number for values the XML does not list | the number |
//! | [bitmasks](flags) | `"MAV_MODE_FLAG_SAFETY_ARMED \| 0x40"` (bitflags' text, XML names) | the number |
//! | [`char[N]`](chars) | a string without trailing NULs, `{"hex": "…"}` when not UTF-8 | the bytes without trailing NULs |
//! | [`float`, `double`](float) | a number; `"NaN"`, `"NaN:0x…"`, `"inf"`, `"-inf"` | the value |
//! | [arrays](mod@array) (any length) | a sequence of exactly `N` | a tuple of `N` |
//! | integers | the number | the number |
//!
//! Every form reads back bit for bit. Generated messages are structs with
//! their XML field names (`"type"`, not `"r#type"`); fields left out read as
//! the message's `Default` (zero, and the dialect's version for
//! `mavlink_version`), and unknown fields are refused, so that a misspelt
//! key cannot silently become a zero on the wire. A dialect's `Message`
//! enum is externally tagged by XML message name:
//! `{"HEARTBEAT": {"type": "MAV_TYPE_FIXED_WING", …}}`.
//!
//! Generated code has these impls under `#[cfg(feature = "serde")]`: a
//! crate that includes bindings declares a `serde` feature enabling
//! `mavframe/serde` (`serde = ["mavframe/serde"]`).

pub use ::serde::*;

#[path = "serde_array.rs"]
pub mod array;
#[path = "serde_chars.rs"]
pub mod chars;
#[path = "serde_flags.rs"]
pub mod flags;
#[path = "serde_float.rs"]
pub mod float;
#[path = "serde_value_enum.rs"]
pub mod value_enum;

use ::serde::de::{Error as _, Unexpected};
use core::fmt;

mod sealed {
    pub trait Sealed {}
    impl Sealed for u8 {}
    impl Sealed for u16 {}
    impl Sealed for u32 {}
    impl Sealed for u64 {}
}

/// The unsigned types enums and flag sets are represented by.
pub trait Repr:
    Copy
    + Eq
    + Into<u64>
    + TryFrom<u64>
    + fmt::LowerHex
    + fmt::Display
    + ::serde::Serialize
    + for<'de> Deserialize<'de>
    + sealed::Sealed
    + 'static
{
    /// The largest value.
    const MAX: Self;
}

impl Repr for u8 {
    const MAX: Self = u8::MAX;
}

impl Repr for u16 {
    const MAX: Self = u16::MAX;
}

impl Repr for u32 {
    const MAX: Self = u32::MAX;
}

impl Repr for u64 {
    const MAX: Self = u64::MAX;
}

/// Deserializes an enum or flag set `T` (represented by `R`) for a field of
/// the narrower wire type `W`, refusing values `W` cannot hold: the enum's
/// type is as wide as its widest field, and writing the value into this
/// field would otherwise drop its high bits. Generated code uses it as
/// `#[serde(deserialize_with = "mavframe::serde::narrow::<_, _, u32, u16>")]`.
pub fn narrow<'de, D, T, R, W>(deserializer: D) -> Result<T, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de> + Copy + Into<R>,
    R: Repr,
    W: Repr,
{
    let value = T::deserialize(deserializer)?;
    let raw: u64 = value.into().into();
    if W::try_from(raw).is_ok() {
        Ok(value)
    } else {
        Err(D::Error::invalid_value(
            Unexpected::Unsigned(raw),
            &Fits(W::MAX.into()),
        ))
    }
}

/// What [`narrow`] expects.
struct Fits(u64);

impl ::serde::de::Expected for Fits {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "a value the field holds (0 to {})", self.0)
    }
}
