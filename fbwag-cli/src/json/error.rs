//! Why a line cannot be encoded, or hex text read.

use fbwag_dialect::mavframe::frame::FrameError;
use std::fmt;

/// Why a line cannot be encoded, or hex text read.
#[derive(Debug)]
pub enum Error {
    /// Hex text with an odd number of digits; the key it is the value of.
    OddHex(Option<&'static str>, usize),
    /// Hex text with a character that is not a hex digit, at this digit.
    NotHex(Option<&'static str>, usize),
    /// The line is not JSON, or not an object of distinct keys.
    Json(serde_json::Error),
    /// A key the line format does not have.
    UnknownKey {
        key: String,
        expected: &'static [&'static str],
    },
    /// A key's value of the wrong JSON type (`value` as shown, shortened).
    Type {
        key: &'static str,
        expected: &'static str,
        value: String,
    },
    /// An integer key's value beyond its range.
    Range {
        key: &'static str,
        max: u64,
        value: String,
    },
    /// The line breaks a rule of the format; the text says which.
    Refused(&'static str),
    /// `raw` is not a frame.
    RawFrame(FrameError),
    /// `raw` has bytes after its frame.
    RawTrailing(usize),
    /// A key disagrees with the `raw` frame's bytes.
    RawDisagrees {
        key: &'static str,
        said: u64,
        actual: u64,
    },
    /// A message id the dialect does not have.
    UnknownId(u64),
    /// A message name the dialect does not have.
    UnknownName(String),
    /// `msgid` and `name` name different messages.
    IdMismatch {
        id: u64,
        name: &'static str,
        expected: u32,
    },
    /// `fields` is not an object of distinct keys.
    Fields(serde_json::Error),
    /// A key of `fields` that is not a field of the message.
    UnknownField {
        message: &'static str,
        field: String,
    },
    /// A field value the message's type refuses (`field` when known).
    Field {
        message: &'static str,
        field: Option<&'static str>,
        source: serde_json::Error,
    },
    /// `version` other than 1 or 2.
    Version(u64),
    /// A `signature` of other than 6 bytes.
    SignatureLen(usize),
    /// `extra` bytes beyond a 255-byte payload.
    ExtraTooLong {
        message: &'static str,
        max: usize,
        extra: usize,
    },
    /// `payload_len` above the message's fields without `extra` filling it.
    ExtraMissing {
        message: &'static str,
        max: usize,
        len: usize,
        extra: usize,
    },
    /// `extra` with a `payload_len` that does not end with it.
    ExtraLen { full: usize, len: usize },
    /// `payload_len` would cut off non-zero bytes of `field`.
    CutOff {
        len: usize,
        field: &'static str,
        used: usize,
    },
    /// A message whose id does not fit MAVLink 1.
    NotV1 { message: &'static str, id: u32 },
    /// A frame that cannot be built (not for a message of the table).
    Frame(FrameError),
}

/// serde_json's text of `e` without its position, which counts in a text
/// other than the line.
fn bare(e: &serde_json::Error) -> String {
    let text = e.to_string();
    let at = format!(" at line {} column {}", e.line(), e.column());
    text.strip_suffix(&at).map_or(text.clone(), str::to_string)
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let key_of = |key: &Option<&str>| key.map(|k| format!("`{k}`: ")).unwrap_or_default();
        match self {
            Error::OddHex(key, n) => write!(f, "{}odd number of hex digits ({n})", key_of(key)),
            Error::NotHex(key, at) => write!(f, "{}not a hex digit at digit {at}", key_of(key)),
            Error::Json(e) if e.classify() == serde_json::error::Category::Data => {
                f.write_str(&bare(e))
            }
            Error::Json(e) => write!(f, "not JSON: {e}"),
            Error::UnknownKey { key, expected } => {
                write!(f, "unknown key `{key}` (expected: {})", expected.join(", "))
            }
            Error::Type { key, expected, value } => {
                write!(f, "`{key}` must be {expected}, not {value}")
            }
            Error::Range { key, max, value } => {
                write!(f, "`{key}` must be an integer from 0 to {max}, not {value}")
            }
            Error::Refused(rule) => f.write_str(rule),
            Error::RawFrame(e) => write!(f, "`raw` is not a frame: {e}"),
            Error::RawTrailing(n) => write!(f, "`raw` holds {n} bytes after its frame"),
            Error::RawDisagrees { key, said, actual } => {
                write!(f, "`{key}` is {said}, but the `raw` frame's is {actual}")
            }
            Error::UnknownId(id) => write!(f, "unknown message id {id}"),
            Error::UnknownName(name) => write!(f, "unknown message name `{name}`"),
            Error::IdMismatch { id, name, expected } => {
                write!(f, "`msgid` {id} does not match `name` {name} (id {expected})")
            }
            Error::Fields(e) => write!(f, "`fields`: {}", bare(e)),
            Error::UnknownField { message, field } => write!(f, "{message} has no field `{field}`"),
            Error::Field { message, field: Some(field), source } => {
                write!(f, "{message}.{field}: {}", bare(source))
            }
            Error::Field { message, field: None, source } => write!(f, "{message}: {}", bare(source)),
            Error::Version(v) => write!(f, "`version` must be 1 or 2, not {v}"),
            Error::SignatureLen(n) => write!(f, "`signature` must be 6 bytes, not {n}"),
            Error::ExtraTooLong { message, max, extra } => write!(
                f,
                "`extra`: {extra} bytes after {message}'s {max} exceed a 255-byte payload"
            ),
            Error::ExtraMissing { message, max, len, extra } => write!(
                f,
                "payload_len {len} is above {message}'s {max} bytes: `extra` must hold the {} bytes beyond them (it holds {extra})",
                len.saturating_sub(*max)
            ),
            Error::ExtraLen { full, len } => write!(f, "`extra` needs payload_len {full}, not {len}"),
            Error::CutOff { len, field, used } => {
                write!(f, "payload_len {len} would cut off {field}, whose bytes end at {used}")
            }
            Error::NotV1 { message, id } => {
                write!(f, "{message} (id {id}) cannot be sent as MAVLink 1")
            }
            Error::Frame(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Json(e) | Error::Fields(e) | Error::Field { source: e, .. } => Some(e),
            Error::RawFrame(e) | Error::Frame(e) => Some(e),
            _ => None,
        }
    }
}
