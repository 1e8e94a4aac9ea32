//! Array fields (`[T; N]` of numbers, any `N`): a sequence of exactly `N`
//! elements, floats among them written as [`float`](super::float) fields.
//!
//! serde's own array impls stop at 32 elements and would write a NaN as
//! JSON `null`; this module has neither limit.
//!
//! ```
//! # use mavframe::serde as serde;
//! #[derive(serde::Serialize, serde::Deserialize)]
//! #[serde(crate = "mavframe::serde")]
//! struct Covariance {
//!     #[serde(with = "mavframe::serde::array")]
//!     values: [f32; 45],
//! }
//! let mut c = Covariance { values: [0.0; 45] };
//! c.values[0] = f32::NAN;
//! let text = serde_json::to_string(&c).unwrap();
//! assert!(text.starts_with(r#"{"values":["NaN",0.0,"#));
//! let back: Covariance = serde_json::from_str(&text).unwrap();
//! assert!(back.values[0].is_nan());
//! ```

use core::fmt;
use core::marker::PhantomData;
use serde::de::{self, DeserializeSeed, Deserializer, IgnoredAny, SeqAccess, Visitor};
use serde::ser::SerializeTuple;
use serde::{Deserialize, Serialize, Serializer};

mod sealed {
    pub trait Sealed {}
}

/// The element types of MAVLink arrays: the integers, `f32` and `f64`.
pub trait Element: Copy + Default + sealed::Sealed + 'static {
    /// Serializes one element.
    fn serialize_element<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error>;
    /// Deserializes one element.
    fn deserialize_element<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error>;
}

macro_rules! plain {
    ($($t:ty),*) => {$(
        impl sealed::Sealed for $t {}
        impl Element for $t {
            fn serialize_element<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                self.serialize(serializer)
            }
            fn deserialize_element<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                <$t>::deserialize(deserializer)
            }
        }
    )*};
}

plain!(u8, i8, u16, i16, u32, i32, u64, i64);

macro_rules! float {
    ($($t:ty),*) => {$(
        impl sealed::Sealed for $t {}
        impl Element for $t {
            fn serialize_element<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                super::float::serialize(self, serializer)
            }
            fn deserialize_element<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                super::float::deserialize(deserializer)
            }
        }
    )*};
}

float!(f32, f64);

/// One element, for `serialize_element`.
struct Item<'a, T>(&'a T);

impl<T: Element> Serialize for Item<'_, T> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        self.0.serialize_element(serializer)
    }
}

/// Serializes an array field (`#[serde(with = "mavframe::serde::array")]`).
pub fn serialize<T: Element, S: Serializer, const N: usize>(
    value: &[T; N],
    serializer: S,
) -> Result<S::Ok, S::Error> {
    let mut tuple = serializer.serialize_tuple(N)?;
    for v in value {
        tuple.serialize_element(&Item(v))?;
    }
    tuple.end()
}

/// Deserializes an array field: exactly `N` elements.
pub fn deserialize<'de, T: Element, D: Deserializer<'de>, const N: usize>(
    deserializer: D,
) -> Result<[T; N], D::Error> {
    deserializer.deserialize_tuple(N, ArrayVisitor::<T, N>(PhantomData))
}

struct ArrayVisitor<T, const N: usize>(PhantomData<T>);

impl<'de, T: Element, const N: usize> Visitor<'de> for ArrayVisitor<T, N> {
    type Value = [T; N];

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "an array of {N} elements")
    }

    fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<[T; N], A::Error> {
        let mut out = [T::default(); N];
        for (i, slot) in out.iter_mut().enumerate() {
            *slot = seq
                .next_element_seed(ElementSeed(PhantomData))?
                .ok_or_else(|| de::Error::invalid_length(i, &self))?;
        }
        // Longer arrays are refused, not cut.
        if seq.next_element::<IgnoredAny>()?.is_some() {
            return Err(de::Error::invalid_length(N + 1, &self));
        }
        Ok(out)
    }
}

struct ElementSeed<T>(PhantomData<T>);

impl<'de, T: Element> DeserializeSeed<'de> for ElementSeed<T> {
    type Value = T;

    fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<T, D::Error> {
        T::deserialize_element(deserializer)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::{String, ToString};

    #[derive(Serialize, Deserialize, Debug, PartialEq)]
    #[serde(crate = "::serde")]
    struct Big {
        #[serde(with = "super")]
        ints: [i16; 40],
        #[serde(with = "super")]
        floats: [f64; 3],
    }

    fn back(text: &str) -> Result<Big, String> {
        serde_json::from_str(text).map_err(|e| e.to_string())
    }

    #[test]
    fn long_arrays_and_float_arrays_round_trip() {
        let mut big = Big {
            ints: [0; 40],
            floats: [f64::NAN, -0.0, f64::INFINITY],
        };
        big.ints[39] = -7;
        let text = serde_json::to_string(&big).unwrap();
        assert!(
            text.ends_with(r#"-7],"floats":["NaN",-0.0,"inf"]}"#),
            "{text}"
        );
        let again = back(&text).unwrap();
        assert_eq!(again.ints, big.ints);
        let bits = |a: &[f64; 3]| a.map(f64::to_bits);
        assert_eq!(bits(&again.floats), bits(&big.floats));
    }

    #[test]
    fn wrong_lengths_and_values_are_refused() {
        let zeros = |n: usize| std::format!("[{}]", std::vec!["0"; n].join(","));
        let line =
            |ints: &str, floats: &str| std::format!(r#"{{"ints":{ints},"floats":{floats}}}"#);
        assert!(back(&line(&zeros(40), &zeros(3))).is_ok());
        assert!(back(&line(&zeros(39), &zeros(3))).is_err());
        assert!(back(&line(&zeros(41), &zeros(3))).is_err());
        assert!(back(&line(&zeros(40), "[0,0,\"nan\"]")).is_err());
        assert!(back(&line(&zeros(40).replace("[0", "[40000"), &zeros(3))).is_err());
    }
}
