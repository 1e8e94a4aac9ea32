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
//! line describes must land in the frame (see [`json_to_frame`]).

mod error;
mod fields;

pub use error::Error;

use fbwag_dialect::mavframe::frame::{
    truncated_len, Frame, FrameError, Header, Version, IFLAG_SIGNED, MAX_FRAME_LEN,
};
use fbwag_dialect::mavframe::{Dialect as _, MessageMeta, Signer};
use fbwag_dialect::Dialect;
use serde::de::{Deserialize, DeserializeOwned, Deserializer, Error as _, MapAccess, Visitor};
use serde_json::value::RawValue;
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
/// are the text as written, handed on to the generated `Deserialize`.
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
    fn only(&self, allowed: &'static [&'static str]) -> Result<(), Error> {
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

    fn uint(&self, key: &'static str, max: u64) -> Result<Option<u64>, Error> {
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

    fn bool(&self, key: &'static str) -> Result<Option<bool>, Error> {
        self.typed(key, "true or false")
    }

    fn string(&self, key: &'static str) -> Result<Option<String>, Error> {
        self.typed(key, "a string")
    }

    /// The bytes of the hex string of `key` (none when absent).
    fn hex(&self, key: &'static str) -> Result<Vec<u8>, Error> {
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

/// Keys of a signature block.
const SIGNATURE_KEYS: [&str; 3] = ["signature", "link_id", "sign_timestamp"];

/// Encodes one JSON line into `out`.
///
/// Refused (the error says why): anything not a JSON object of the keys
/// above (unknown or repeated keys included); a known message without
/// `fields` (`"fields":{}` asks for all zeros; fields left out are zero);
/// unknown field names; values the field's type does not hold exactly
/// (wrong JSON type, out of range, strings and byte arrays longer than a
/// `char[N]`, arrays not of the declared length); `payload_len` that would
/// cut off non-zero field bytes, or exceed the message without `extra`
/// holding the bytes beyond it; `"signed": true` without a `signature` to
/// copy or a signer; signing a MAVLink 1 frame or an unsigned raw frame.
pub fn json_to_frame(
    line: &str,
    opts: &mut EncodeOptions<'_>,
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<Encoded, Error> {
    let obj: Object<'_> = serde_json::from_str(line).map_err(Error::Json)?;
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
) -> Result<usize, Error> {
    obj.only(RAW_KEYS)?;
    let bytes = obj.hex("raw")?;
    let frame = Frame::new_checked(&bytes).map_err(Error::RawFrame)?;
    let n = frame.as_bytes().len();
    if n != bytes.len() {
        return Err(Error::RawTrailing(bytes.len() - n));
    }
    if obj.has("name") {
        return Err(Error::Refused("`name` must be null for a `raw` frame"));
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
        match obj.uint(key, u64::MAX)? {
            Some(said) if said != actual => return Err(Error::RawDisagrees { key, said, actual }),
            _ => {}
        }
    }
    if obj.bool("signed")?.is_some_and(|s| s != frame.is_signed()) {
        return Err(Error::Refused("`signed` disagrees with the `raw` frame"));
    }
    if v2 && opts.force_v1 {
        return Err(Error::Refused(
            "--v1: a raw MAVLink 2 frame of an unknown message cannot be converted",
        ));
    }
    out[..n].copy_from_slice(&bytes);
    match opts.signer.as_deref_mut() {
        None => {}
        // Re-signing keeps the checksum; adding a signature would change the
        // flags it covers, and an unknown message's checksum cannot be redone.
        Some(signer) if frame.is_signed() => sign(signer, &mut out[..n])?,
        Some(_) if v2 => return Err(Error::Refused("--sign-key: this unsigned frame of an unknown message cannot be signed (its checksum cannot be recomputed)")),
        Some(_) => return Err(Error::Refused(V1_SIGN_KEY)),
    }
    Ok(n)
}

const V1_SIGN_KEY: &str = "--sign-key: this MAVLink 1 frame cannot be signed";

/// Signs a whole MAVLink 2 frame (its last 13 bytes are the block).
fn sign(signer: &mut Signer, frame: &mut [u8]) -> Result<(), Error> {
    if signer.timestamp() > crate::args::MAX_SIGN_TIMESTAMP {
        return Err(Error::Refused(
            "the signing timestamp passed 2^48 - 1 (48 bits)",
        ));
    }
    signer.sign_frame(frame);
    Ok(())
}

/// The frame of a known message.
fn message_frame(
    obj: &Object<'_>,
    opts: &mut EncodeOptions<'_>,
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<usize, Error> {
    obj.only(MESSAGE_KEYS)?;
    let meta = message_meta(obj)?;
    let fields = obj.get("fields").ok_or(Error::Refused(
        "no `fields`: a message line lists its field values (`\"fields\":{}` for all zeros)",
    ))?;
    let fields: Object<'_> = serde_json::from_str(fields.get()).map_err(Error::Fields)?;
    let message = fields::read(meta, &fields)?;
    // A fresh buffer per line: nothing of an earlier line can leak in.
    let mut payload = [0u8; 255];
    message
        .emit(&mut payload)
        .map_err(|e| Error::Frame(FrameError::BufferTooSmall { needed: e.needed }))?;
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
        Some(v) => Err(Error::Version(v)),
    }
}

/// The message a line names by `name`, `msgid` or both (which must agree).
fn message_meta(obj: &Object<'_>) -> Result<&'static MessageMeta, Error> {
    let id = obj.uint("msgid", 0xFF_FFFF)?;
    let Some(name) = obj.string("name")? else {
        let id = id.ok_or(Error::Refused("needs `name` or `msgid`"))?;
        return Dialect::meta(id as u32).ok_or(Error::UnknownId(id));
    };
    let m = Dialect::MESSAGES
        .iter()
        .find(|m| m.name == name)
        .ok_or(Error::UnknownName(name))?;
    match id {
        Some(id) if id != u64::from(m.id) => Err(Error::IdMismatch {
            id,
            name: m.name,
            expected: m.id,
        }),
        _ => Ok(m),
    }
}

/// A MAVLink 2 frame as the line says: its length, flags and signature.
fn v2_line(
    obj: &Object<'_>,
    meta: &MessageMeta,
    header: Header,
    payload: &mut [u8; 255],
    opts: &mut EncodeOptions<'_>,
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<usize, Error> {
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
        .map_err(Error::Frame)?;
    frame.set_header(header);
    frame.set_msg_id(meta.id).map_err(Error::Frame)?;
    frame.payload_mut().copy_from_slice(&payload[..len]);
    frame.fill_checksum(meta.crc_extra);
    match (opts.signer.as_deref_mut(), block) {
        (Some(signer), _) => sign(signer, frame.as_bytes_mut())?,
        (None, Some((link_id, timestamp, signature))) => frame
            .set_signature(link_id, timestamp, signature)
            .map_err(Error::Frame)?,
        (None, None) => {}
    }
    Ok(frame.frame_len())
}

/// A signature block's link id, timestamp and signature.
type SignatureFields = (u8, u64, [u8; 6]);

/// The signature block a line carries, checked against its `signed`.
fn signature_block(obj: &Object<'_>) -> Result<Option<SignatureFields>, Error> {
    let given = SIGNATURE_KEYS.iter().filter(|k| obj.has(k)).count();
    match (obj.bool("signed")?, given) {
        (Some(false) | None, 0) => return Ok(None),
        (Some(false), _) => {
            return Err(Error::Refused(
                "`signed` is false, but the line has a signature",
            ))
        }
        (Some(true), 0) => return Err(Error::Refused(
            "`signed` is true, but there is no `signature` to copy and no --sign-key to sign with",
        )),
        (_, n) if n < SIGNATURE_KEYS.len() => {
            return Err(Error::Refused(
                "a signature needs all of `signature`, `link_id` and `sign_timestamp`",
            ))
        }
        _ => {}
    }
    let sig: [u8; 6] = obj
        .hex("signature")?
        .try_into()
        .map_err(|s: Vec<u8>| Error::SignatureLen(s.len()))?;
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
) -> Result<usize, Error> {
    let (message, max) = (meta.name, meta.max_len as usize);
    let extra = obj.hex("extra")?;
    let full = max + extra.len();
    payload
        .get_mut(max..full)
        .ok_or(Error::ExtraTooLong {
            message,
            max,
            extra: extra.len(),
        })?
        .copy_from_slice(&extra);
    let len = match obj.uint("payload_len", 255)? {
        Some(n) => n as usize,
        None if !extra.is_empty() => full,
        None => default,
    };
    if len > max && len != full {
        let extra = extra.len();
        return Err(Error::ExtraMissing {
            message,
            max,
            len,
            extra,
        });
    }
    if !extra.is_empty() && len != full {
        return Err(Error::ExtraLen { full, len });
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
        return Err(Error::CutOff { len, field, used });
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
) -> Result<usize, Error> {
    if obj.bool("signed")? == Some(true) || SIGNATURE_KEYS.iter().any(|k| obj.has(k)) {
        return Err(Error::Refused("a MAVLink 1 frame cannot be signed"));
    }
    if opts.signer.is_some() {
        return Err(Error::Refused(V1_SIGN_KEY));
    }
    if obj.uint("compat_flags", 255)?.is_some_and(|c| c != 0) {
        return Err(Error::Refused("a MAVLink 1 frame has no compat_flags"));
    }
    let len = payload_length(obj, meta, payload, meta.min_len as usize)?;
    v1_frame(meta, header, &payload[..len], out)
}

fn v1_frame(
    meta: &MessageMeta,
    header: Header,
    payload: &[u8],
    out: &mut [u8; MAX_FRAME_LEN],
) -> Result<usize, Error> {
    let id = u8::try_from(meta.id).map_err(|_| Error::NotV1 {
        message: meta.name,
        id: meta.id,
    })?;
    let mut frame = Frame::new_v1(&mut out[..], payload.len() as u8).map_err(Error::Frame)?;
    frame.set_header(header);
    frame.set_msg_id(u32::from(id)).map_err(Error::Frame)?;
    frame.payload_mut().copy_from_slice(payload);
    frame.fill_checksum(meta.crc_extra);
    Ok(frame.frame_len())
}
