//! Frames ↔ JSON lines. The envelope comes from the frame and the dialect's
//! table; the `fields` object from the generated messages' serde impls
//! (see [`fields`]), keys in wire order.
//!
//! One object per frame:
//! `{"version":2,"seq":0,"sysid":1,"compid":1,"msgid":15001,"name":"FBWAG_NOTICE","signed":false,"fields":{…}}`.
//! Keys added only when needed to reproduce the bytes exactly: `"link_id"`,
//! `"sign_timestamp"`, `"signature"` for signed frames; `"compat_flags"` when
//! not zero; `"payload_len"` when a MAVLink 2 sender did not drop trailing
//! zeros canonically (or a MAVLink 1 frame is not the base length);
//! `"extra"` (hex) for payload bytes beyond the message's fields (a sender
//! with a newer definition); `"tlog_us"` for tlog records. Frames of unknown
//! ids are `"name":null` with the whole frame as `"raw"` hex.
//!
//! Floats: finite values are JSON numbers in shortest round-trip form;
//! `"inf"`, `"-inf"`; `"NaN"` for the canonical quiet NaN (`0x7fc00000`,
//! `0x7ff8000000000000`) and `"NaN:0x…"` with the bit pattern (8 or 16 hex
//! digits) for every other NaN, so sign and payload bits survive.
//!
//! Encoding is exact or refused: every value must fit its field without
//! rounding beyond the nearest representable float, and every byte the
//! line describes must land in the frame (see [`json_to_frame`]). Field
//! values may also be in the generated impls' other forms: enum entry
//! names, bitmask text, `{"hex": …}` for chars.

mod encode;
mod error;
mod fields;
mod object;

pub use encode::{json_to_frame, EncodeOptions};
pub use error::Error;

use fbwag_dialect::mavframe::frame::{truncated_len, Frame, Version};
use fbwag_dialect::mavframe::{MessageMeta, MessageSet as _};
use fbwag_dialect::Dialect;
use std::fmt::Write as _;

/// Lower-case hex of `bytes`.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
}

/// Bytes of hex text, whitespace ignored.
pub fn unhex(text: &str) -> Result<Vec<u8>, Error> {
    unhex_key(None, text)
}

/// Bytes of hex text, the value of `key` if it is one.
fn unhex_key(key: Option<&'static str>, text: &str) -> Result<Vec<u8>, Error> {
    let digits: Vec<u8> = text.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
    if digits.len() % 2 != 0 {
        return Err(Error::OddHex(key, digits.len()));
    }
    let nibble = |i: usize| match (digits[i] as char).to_digit(16) {
        Some(d) => Ok(d as u8),
        None => Err(Error::NotHex(key, i)),
    };
    (0..digits.len() / 2)
        .map(|i| Ok((nibble(2 * i)? << 4) | nibble(2 * i + 1)?))
        .collect()
}

/// The JSON line for a frame; `meta` is `None` for an unknown id.
pub fn frame_to_json(
    frame: &Frame<&[u8]>,
    meta: Option<&MessageMeta>,
    tlog_us: Option<u64>,
) -> String {
    let h = frame.header();
    let mut out = String::with_capacity(256);
    let version = if frame.version() == Version::V2 { 2 } else { 1 };
    out.push('{');
    if let Some(t) = tlog_us {
        let _ = write!(out, "\"tlog_us\":{t},");
    }
    let _ = write!(
        out,
        "\"version\":{version},\"seq\":{},\"sysid\":{},\"compid\":{},\"msgid\":{},",
        h.seq,
        h.sysid,
        h.compid,
        frame.msg_id()
    );
    let Some(meta) = meta else {
        return raw_json(out, frame);
    };
    let Some(message) = Dialect::parse(frame.msg_id(), frame.payload()) else {
        return raw_json(out, frame);
    };
    let fields = match fields::write(meta, &message) {
        Ok(fields) => fields,
        Err(e) => {
            // Cannot happen for generated messages; the raw frame loses nothing.
            debug_assert!(false, "{}: {e}", meta.name);
            return raw_json(out, frame);
        }
    };
    let _ = write!(
        out,
        "\"name\":\"{}\",\"signed\":{}",
        meta.name,
        frame.is_signed()
    );
    envelope_extras(&mut out, frame, meta);
    out.push_str(",\"fields\":");
    out.push_str(&fields);
    out.push('}');
    out
}

/// Ends the line of a frame as `"name":null` with the whole frame in hex.
fn raw_json(mut out: String, frame: &Frame<&[u8]>) -> String {
    let _ = write!(
        out,
        "\"name\":null,\"signed\":{},\"raw\":\"{}\"}}",
        frame.is_signed(),
        hex(frame.as_bytes())
    );
    out
}

/// The keys a known message's line carries only when the frame needs them:
/// signature, compat flags, a non-canonical length, bytes beyond the fields.
fn envelope_extras(out: &mut String, frame: &Frame<&[u8]>, meta: &MessageMeta) {
    if let Some(sig) = frame.signature() {
        let _ = write!(
            out,
            ",\"link_id\":{},\"sign_timestamp\":{},\"signature\":\"{}\"",
            sig.link_id(),
            sig.timestamp(),
            hex(sig.signature())
        );
    }
    if frame.compat_flags() != 0 {
        let _ = write!(out, ",\"compat_flags\":{}", frame.compat_flags());
    }
    let payload = frame.payload();
    let max = meta.max_len as usize;
    let expected = if frame.version() == Version::V2 {
        // What an encoder produces from these values.
        truncated_len(&payload[..payload.len().min(max)])
    } else {
        meta.min_len as usize
    };
    if payload.len() != expected {
        let _ = write!(out, ",\"payload_len\":{}", payload.len());
    }
    if payload.len() > max {
        let _ = write!(out, ",\"extra\":\"{}\"", hex(&payload[max..]));
    }
}
