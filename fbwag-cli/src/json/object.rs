//! A line's JSON object: its keys and raw values, and their typed reading.

use super::{unhex_key, Error};
use serde::de::{Deserialize, DeserializeOwned, Deserializer, Error as _, MapAccess, Visitor};
use serde_json::value::RawValue;
use std::collections::HashSet;
use std::fmt;

/// A JSON object as its keys and their raw values, in order; a repeated key
/// is an error (which of the two values was meant is unknowable). Raw values
/// are the text as written, handed on to the generated `Deserialize`.
pub struct Object<'a>(pub Vec<(String, &'a RawValue)>);

impl<'de> Deserialize<'de> for Object<'de> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Entries;
        impl<'de> Visitor<'de> for Entries {
            type Value = Object<'de>;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a JSON object")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Object<'de>, A::Error> {
                let mut seen = HashSet::new();
                let mut entries = Vec::new();
                while let Some((k, v)) = map.next_entry::<String, &'de RawValue>()? {
                    if !seen.insert(k.clone()) {
                        return Err(A::Error::custom(format_args!("duplicate key `{k}`")));
                    }
                    entries.push((k, v));
                }
                Ok(Object(entries))
            }
        }
        d.deserialize_map(Entries)
    }
}

impl<'a> Object<'a> {
    /// The raw value of `key`; `null` counts as absent.
    pub fn get(&self, key: &str) -> Option<&'a RawValue> {
        self.0
            .iter()
            .find(|(k, _)| k == key)
            .map(|&(_, v)| v)
            .filter(|v| v.get() != "null")
    }

    pub fn has(&self, key: &str) -> bool {
        self.get(key).is_some()
    }

    /// Refuses any key not in `allowed`: a misspelt key must not be ignored.
    pub fn only(&self, allowed: &'static [&'static str]) -> Result<(), Error> {
        match self.0.iter().find(|(k, _)| !allowed.contains(&k.as_str())) {
            Some((k, _)) => Err(Error::UnknownKey {
                key: k.clone(),
                expected: allowed,
            }),
            None => Ok(()),
        }
    }

    /// The value of `key` as a `T`, described as `expected` when it is not.
    fn typed<T: DeserializeOwned>(
        &self,
        key: &'static str,
        expected: &'static str,
    ) -> Result<Option<T>, Error> {
        let Some(raw) = self.get(key) else {
            return Ok(None);
        };
        serde_json::from_str(raw.get())
            .map(Some)
            .map_err(|_| Error::Type {
                key,
                expected,
                value: shown(raw),
            })
    }

    pub fn uint(&self, key: &'static str, max: u64) -> Result<Option<u64>, Error> {
        match self.typed::<u64>(key, "an integer") {
            Ok(Some(n)) if n > max => Err(Error::Range {
                key,
                max,
                value: n.to_string(),
            }),
            Err(Error::Type { value, .. }) => Err(Error::Range { key, max, value }),
            other => other,
        }
    }

    pub fn bool(&self, key: &'static str) -> Result<Option<bool>, Error> {
        self.typed(key, "true or false")
    }

    pub fn string(&self, key: &'static str) -> Result<Option<String>, Error> {
        self.typed(key, "a string")
    }

    /// The bytes of the hex string of `key` (none when absent).
    pub fn hex(&self, key: &'static str) -> Result<Vec<u8>, Error> {
        unhex_key(Some(key), &self.string(key)?.unwrap_or_default())
    }
}

/// A raw value for an error message: at most 40 characters of it, so a
/// huge value does not flood the log.
fn shown(raw: &RawValue) -> String {
    let text = raw.get().trim();
    match text.char_indices().nth(40) {
        Some((cut, _)) => format!("{}…", &text[..cut]),
        None => text.to_string(),
    }
}
