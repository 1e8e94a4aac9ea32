//! Frames ↔ JSON lines. The envelope comes from the frame and the dialect's
//! table; the `fields` object from the generated messages' serde impls, in
//! their compact form (enums as numbers, as pymavlink prints them), written
//! and read by the small serde format of [`fields`], keys in wire order.
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
//! line describes must land in the frame (see [`json_to_frame`]).

mod fields;

use fbwag_dialect::mavframe::frame::{
    truncated_len, Frame, Header, Version, IFLAG_SIGNED, MAX_FRAME_LEN,
};
use fbwag_dialect::mavframe::{Dialect as _, MessageMeta, Signer};
use fbwag_dialect::Dialect;
use serde::de::{Deserialize, Deserializer, Error as _, MapAccess, Visitor};
use serde_json::value::RawValue;
use serde_json::Value;
use std::collections::HashSet;
use std::fmt::{self, Write as _};

/// Lower-case hex of `bytes`.
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
}

/// Bytes of hex text, whitespace ignored.
pub fn unhex(text: &str) -> Result<Vec<u8>, String> {
    let digits: Vec<u8> = text.bytes().filter(|b| !b.is_ascii_whitespace()).collect();
    if digits.len() % 2 != 0 {
        return Err(format!("odd number of hex digits ({})", digits.len()));
    }
    digits
        .chunks(2)
        .enumerate()
        .map(|(i, pair)| {
            let s = std::str::from_utf8(pair)
                .map_err(|_| format!("non-ASCII byte in hex at digit {}", 2 * i))?;
            u8::from_str_radix(s, 16).map_err(|_| format!("`{s}` is not hex (digit {})", 2 * i))
        })
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
    let mut fields = String::with_capacity(256);
    if let Err(e) = fields::write(&mut fields, meta, &message) {
        // Cannot happen for generated messages; the raw frame loses nothing.
        debug_assert!(false, "{}: {e}", meta.name);
        return raw_json(out, frame);
    }
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

/// Options of [`json_to_frame`].
pub struct EncodeOptions<'a> {
    /// Force MAVLink 1 (`--v1`): base fields only.
    pub force_v1: bool,
    /// Sign every frame with this signer (`--sign-key`).
    pub signer: Option<&'a mut Signer>,
}

/// What one line encoded to.
pub struct Encoded {
    /// Frame length in the output buffer.
    pub len: usize,
    /// The line's `tlog_us`, if it has one.
    pub tlog_us: Option<u64>,
}

/// A JSON object as its keys and their raw values, in order; a repeated key
/// is an error (which of the two values was meant is unknowable). Raw values
/// keep numbers as written, so floats are parsed exactly for their type.
struct Object<'a>(Vec<(String, &'a RawValue)>);

impl<'de> Deserialize<'de> for Object<'de> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Entries;
        impl<'de> Visitor<'de> for Entries {
            type Value = Object<'de>;
            fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str("a JSON object")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Object<'de>, A::Error> {
                // A line's few keys are compared directly; a set takes over
                // for long objects, so a flood of keys stays linear.
                const DIRECT: usize = 32;
                let mut seen = HashSet::new();
                let mut entries: Vec<(String, &'de RawValue)> = Vec::new();
                while let Some((k, v)) = map.next_entry::<String, &'de RawValue>()? {
                    let repeated = if entries.len() < DIRECT {
                        entries.iter().any(|(e, _)| *e == k)
                    } else {
                        if seen.is_empty() {
                            seen.extend(entries.iter().map(|(e, _)| e.clone()));
                        }
                        !seen.insert(k.clone())
                    };
                    if repeated {
                        return Err(A::Error::custom(format!("duplicate key `{k}`")));
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
    fn parse(text: &'a str) -> Result<Self, String> {
        serde_json::from_str(text).map_err(|e| match e.classify() {
            serde_json::error::Category::Data => e.to_string(),
            _ => format!("not JSON: {e}"),
        })
    }

    /// The raw value of `key`; `null` counts as absent.
    fn get(&self, key: &str) -> Option<&'a RawValue> {
        self.0
            .iter()
            .find(|(k, _)| k == key)
            .map(|&(_, v)| v)
            .filter(|v| v.get() != "null")
    }

    fn has(&self, key: &str) -> bool {
        self.get(key).is_some()
    }

    /// Refuses any key not in `allowed`: a misspelt key must not be ignored.
    fn only(&self, allowed: &[&str]) -> Result<(), String> {
        match self.0.iter().find(|(k, _)| !allowed.contains(&k.as_str())) {
            Some((k, _)) => Err(format!(
                "unknown key `{k}` (expected: {})",
                allowed.join(", ")
            )),
            None => Ok(()),
        }
    }

    fn uint(&self, key: &str, max: u64) -> Result<Option<u64>, String> {
        let Some(raw) = self.get(key) else {
            return Ok(None);
        };
        match value(raw).as_u64() {
            Some(n) if n <= max => Ok(Some(n)),
            _ => Err(format!(
                "`{key}` must be an integer from 0 to {max}, not {}",
                shown(raw)
            )),
        }
    }

    fn bool(&self, key: &str) -> Result<Option<bool>, String> {
        let Some(raw) = self.get(key) else {
            return Ok(None);
        };
        match value(raw) {
            Value::Bool(b) => Ok(Some(b)),
            _ => Err(format!("`{key}` must be true or false, not {}", shown(raw))),
        }
    }

    fn string(&self, key: &str) -> Result<Option<String>, String> {
        let Some(raw) = self.get(key) else {
            return Ok(None);
        };
        match value(raw) {
            Value::String(s) => Ok(Some(s)),
            _ => Err(format!("`{key}` must be a string, not {}", shown(raw))),
        }
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

/// A raw value as a [`Value`]. Raw values come from a parsed document, so
/// they are valid JSON; `Null` is only a fallback that every caller refuses.
fn value(raw: &RawValue) -> Value {
    serde_json::from_str(raw.get()).unwrap_or(Value::Null)
}

/// Keys of a known message's line.
const MESSAGE_KEYS: &[&str] = &[
    "tlog_us",
    "version",
    "seq",
    "sysid",
    "compid",
    "msgid",
    "name",
    "signed",
    "link_id",
    "sign_timestamp",
    "signature",
    "compat_flags",
    "payload_len",
    "extra",
    "fields",
];

/// Keys of a raw frame's line.
const RAW_KEYS: &[&str] = &[
    "tlog_us", "version", "seq", "sysid", "compid", "msgid", "name", "signed", "raw",
];

/// Encodes one JSON line into `out`.
///
/// Refused (the error says why): anything not a JSON object of the keys
/// above (unknown or repeated keys included); a known message without
/// `fields` (`"fields":{}` asks for all zeros; fields left out are zero);
/// unknown field names; values of the wrong JSON type, out of their
/// field's range, or strings and arrays longer than the field (arrays must
/// have exactly the declared length); `payload_len` that would cut off
/// non-zero field bytes, or exceed the message without `extra` holding the
/// bytes beyond it; `"signed": true` without a `signature` to copy or a
/// signer; signing a MAVLink 1 frame or an unsigned raw frame.
pub fn json_to_frame(
    line: &str,
    opts: &mut EncodeOptions<'_>,
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<Encoded, String> {
    let obj = Object::parse(line)?;
    let tlog_us = obj.uint("tlog_us", u64::MAX)?;
    let len = if obj.has("raw") {
        raw_frame(&obj, opts, out)?
    } else {
        message_frame(&obj, opts, out)?
    };
    Ok(Encoded { len, tlog_us })
}

/// A frame of an unknown message, copied from `raw`; the other keys describe
/// it and must agree with its bytes.
fn raw_frame(
    obj: &Object<'_>,
    opts: &mut EncodeOptions<'_>,
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<usize, String> {
    obj.only(RAW_KEYS)?;
    let bytes = unhex(&obj.string("raw")?.unwrap_or_default())?;
    let frame = Frame::new_checked(&bytes).map_err(|e| format!("`raw` is not a frame: {e}"))?;
    let n = frame.as_bytes().len();
    if n != bytes.len() {
        return Err(format!(
            "`raw` holds {} bytes after its frame",
            bytes.len() - n
        ));
    }
    if obj.has("name") {
        return Err("`name` must be null for a `raw` frame".into());
    }
    let h = frame.header();
    let v2 = frame.version() == Version::V2;
    for (key, actual) in [
        ("version", if v2 { 2 } else { 1 }),
        ("seq", u64::from(h.seq)),
        ("sysid", u64::from(h.sysid)),
        ("compid", u64::from(h.compid)),
        ("msgid", u64::from(frame.msg_id())),
    ] {
        if let Some(said) = obj.uint(key, u64::MAX)? {
            if said != actual {
                return Err(format!(
                    "`{key}` is {said}, but the `raw` frame's is {actual}"
                ));
            }
        }
    }
    if obj.bool("signed")?.is_some_and(|s| s != frame.is_signed()) {
        return Err("`signed` disagrees with the `raw` frame".into());
    }
    if v2 && opts.force_v1 {
        return Err("--v1: a raw MAVLink 2 frame of an unknown message cannot be converted".into());
    }
    out[..n].copy_from_slice(&bytes);
    match opts.signer.as_deref_mut() {
        None => {}
        // Re-signing keeps the checksum; adding a signature would change the
        // flags it covers, and an unknown message's checksum cannot be redone.
        Some(signer) if frame.is_signed() => sign(signer, &mut out[..n])?,
        Some(_) if v2 => return Err("--sign-key: this unsigned frame of an unknown message cannot be signed (its checksum cannot be recomputed)".into()),
        Some(_) => return Err("--sign-key: this MAVLink 1 frame cannot be signed".into()),
    }
    Ok(n)
}

/// Signs a whole MAVLink 2 frame (its last 13 bytes are the block).
fn sign(signer: &mut Signer, frame: &mut [u8]) -> Result<(), String> {
    if signer.timestamp() > crate::args::MAX_SIGN_TIMESTAMP {
        return Err("the signing timestamp passed 2^48 - 1 (48 bits)".into());
    }
    signer.sign_frame(frame);
    Ok(())
}

/// The frame of a known message.
fn message_frame(
    obj: &Object<'_>,
    opts: &mut EncodeOptions<'_>,
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<usize, String> {
    obj.only(MESSAGE_KEYS)?;
    let meta = message_meta(obj)?;
    let fields = obj.get("fields").ok_or(
        "no `fields`: a message line lists its field values (`\"fields\":{}` for all zeros)",
    )?;
    // A fresh buffer per line: nothing of an earlier line can leak in.
    let mut payload = [0u8; 255];
    fill_fields(meta, fields, &mut payload)?;
    let header = Header {
        seq: obj.uint("seq", 255)?.unwrap_or(0) as u8,
        sysid: obj.uint("sysid", 255)?.unwrap_or(0) as u8,
        compid: obj.uint("compid", 255)?.unwrap_or(0) as u8,
    };
    if opts.force_v1 {
        return v1_frame(meta, header, &payload[..meta.min_len as usize], out);
    }
    match obj.uint("version", 255)? {
        Some(1) => v1_line(obj, meta, header, &mut payload, opts, out),
        None | Some(2) => v2_line(obj, meta, header, &mut payload, opts, out),
        Some(v) => Err(format!("`version` must be 1 or 2, not {v}")),
    }
}

/// The message a line names by `name`, `msgid` or both (which must agree).
fn message_meta(obj: &Object<'_>) -> Result<&'static MessageMeta, String> {
    let id = obj.uint("msgid", 0xFF_FFFF)?;
    let Some(name) = obj.string("name")? else {
        let id = id.ok_or("needs `name` or `msgid`")?;
        return Dialect::meta(id as u32).ok_or_else(|| format!("unknown message id {id}"));
    };
    let m = Dialect::MESSAGES
        .iter()
        .find(|m| m.name == name)
        .ok_or_else(|| format!("unknown message name `{name}`"))?;
    match id {
        Some(id) if id != u64::from(m.id) => Err(format!(
            "`msgid` {id} does not match `name` {name} (id {})",
            m.id
        )),
        _ => Ok(m),
    }
}

/// Fills `payload` with the message of `fields` (fields left out are zero).
fn fill_fields(
    meta: &'static MessageMeta,
    fields: &RawValue,
    payload: &mut [u8],
) -> Result<(), String> {
    let fields = Object::parse(fields.get()).map_err(|e| format!("`fields`: {e}"))?;
    let message = fields::read(meta, &fields).map_err(|e| e.to_string())?;
    message
        .emit(payload)
        .map(|_| ())
        .map_err(|e| format!("{}: {e}", meta.name))
}

/// A MAVLink 2 frame as the line says: its length, flags and signature.
fn v2_line(
    obj: &Object<'_>,
    meta: &MessageMeta,
    header: Header,
    payload: &mut [u8; 255],
    opts: &mut EncodeOptions<'_>,
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<usize, String> {
    let canonical = truncated_len(&payload[..meta.max_len as usize]);
    let len = payload_length(obj, meta, payload, canonical)?;
    let compat = obj.uint("compat_flags", 255)?;
    let block = if opts.signer.is_some() {
        None
    } else {
        signature_block(obj)?
    };
    let signed = block.is_some() || opts.signer.is_some();
    let flags = if signed { IFLAG_SIGNED } else { 0 };
    let mut frame = Frame::new_v2(&mut out[..], len as u8, flags, compat.unwrap_or(0) as u8)
        .map_err(|e| e.to_string())?;
    frame.set_header(header);
    frame.set_msg_id(meta.id).map_err(|e| e.to_string())?;
    frame.payload_mut().copy_from_slice(&payload[..len]);
    frame.fill_checksum(meta.crc_extra);
    match (opts.signer.as_deref_mut(), block) {
        (Some(signer), _) => sign(signer, frame.as_bytes_mut())?,
        (None, Some((link_id, timestamp, signature))) => frame
            .set_signature(link_id, timestamp, signature)
            .map_err(|e| e.to_string())?,
        (None, None) => {}
    }
    Ok(frame.frame_len())
}

/// A signature block's link id, timestamp and signature.
type SignatureFields = (u8, u64, [u8; 6]);

/// The signature block a line carries, checked against its `signed`.
fn signature_block(obj: &Object<'_>) -> Result<Option<SignatureFields>, String> {
    let keys = ["signature", "link_id", "sign_timestamp"];
    let given = keys.iter().filter(|k| obj.has(k)).count();
    match (obj.bool("signed")?, given) {
        (Some(false) | None, 0) => return Ok(None),
        (Some(false), _) => {
            return Err("`signed` is false, but the line has a signature".into());
        }
        (Some(true), 0) => {
            return Err(
                "`signed` is true, but there is no `signature` to copy and no --sign-key to sign with"
                    .into(),
            );
        }
        (_, n) if n < keys.len() => {
            return Err(
                "a signature needs all of `signature`, `link_id` and `sign_timestamp`".into(),
            );
        }
        _ => {}
    }
    let sig = unhex(&obj.string("signature")?.unwrap_or_default())?;
    let sig: [u8; 6] = sig
        .try_into()
        .map_err(|s: Vec<u8>| format!("`signature` must be 6 bytes, not {}", s.len()))?;
    let link_id = obj.uint("link_id", 255)?.unwrap_or(0) as u8;
    let ts = obj
        .uint("sign_timestamp", crate::args::MAX_SIGN_TIMESTAMP)?
        .unwrap_or(0);
    Ok(Some((link_id, ts, sig)))
}

/// The payload length a line asks for (`default` when it does not say):
/// `extra` bytes are placed after the fields, and no non-zero byte may fall
/// outside the length.
fn payload_length(
    obj: &Object<'_>,
    meta: &MessageMeta,
    payload: &mut [u8; 255],
    default: usize,
) -> Result<usize, String> {
    let max = meta.max_len as usize;
    let extra = match obj.string("extra")? {
        Some(h) => unhex(&h).map_err(|e| format!("`extra`: {e}"))?,
        None => Vec::new(),
    };
    let full = max + extra.len();
    let slot = payload.get_mut(max..full).ok_or_else(|| {
        format!(
            "`extra`: {} bytes after {}'s {max} exceed a 255-byte payload",
            extra.len(),
            meta.name
        )
    })?;
    slot.copy_from_slice(&extra);
    let len = match obj.uint("payload_len", 255)? {
        Some(n) => n as usize,
        None if !extra.is_empty() => full,
        None => default,
    };
    if len > max && len != full {
        return Err(format!(
            "payload_len {len} is above {}'s {max} bytes: `extra` must hold the {} bytes beyond them (it holds {})",
            meta.name,
            len - max,
            extra.len()
        ));
    }
    if !extra.is_empty() && len != full {
        return Err(format!("`extra` needs payload_len {full}, not {len}"));
    }
    let used = payload[..full]
        .iter()
        .rposition(|&b| b != 0)
        .map_or(0, |i| i + 1);
    if len < used {
        let field = meta
            .fields
            .iter()
            .find(|f| (f.offset as usize..f.offset as usize + f.wire_len()).contains(&(used - 1)))
            .map_or("`extra`", |f| f.name);
        return Err(format!(
            "payload_len {len} would cut off {field}, whose bytes end at {used}"
        ));
    }
    Ok(len)
}

/// A MAVLink 1 frame as the line says (`"version": 1`).
fn v1_line(
    obj: &Object<'_>,
    meta: &MessageMeta,
    header: Header,
    payload: &mut [u8; 255],
    opts: &EncodeOptions<'_>,
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<usize, String> {
    let sig_keys = ["signature", "link_id", "sign_timestamp"];
    if obj.bool("signed")? == Some(true) || sig_keys.iter().any(|k| obj.has(k)) {
        return Err("a MAVLink 1 frame cannot be signed".into());
    }
    if opts.signer.is_some() {
        return Err("--sign-key: this MAVLink 1 frame cannot be signed".into());
    }
    if obj.uint("compat_flags", 255)?.is_some_and(|c| c != 0) {
        return Err("a MAVLink 1 frame has no compat_flags".into());
    }
    let len = payload_length(obj, meta, payload, meta.min_len as usize)?;
    v1_frame(meta, header, &payload[..len], out)
}

fn v1_frame(
    meta: &MessageMeta,
    header: Header,
    payload: &[u8],
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<usize, String> {
    let id = u8::try_from(meta.id)
        .map_err(|_| format!("{} (id {}) cannot be sent as MAVLink 1", meta.name, meta.id))?;
    let mut frame = Frame::new_v1(&mut out[..], payload.len() as u8).map_err(|e| e.to_string())?;
    frame.set_header(header);
    frame.set_msg_id(u32::from(id)).map_err(|e| e.to_string())?;
    frame.payload_mut().copy_from_slice(payload);
    frame.fill_checksum(meta.crc_extra);
    Ok(frame.frame_len())
}
