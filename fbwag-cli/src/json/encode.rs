//! A JSON line to the frame it describes (see [`json_to_frame`]).

use super::object::Object;
use super::{fields, Error};
use fbwag_dialect::mavframe::frame::{
    truncated_len, Frame, FrameError, Header, Version, IFLAG_SIGNED, MAX_FRAME_LEN,
};
use fbwag_dialect::mavframe::{MessageMeta, MessageSet as _, Signer};
use fbwag_dialect::Dialect;

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
