//! Frames ↔ JSON lines, driven by the dialect's field tables: every message
//! is read from and written to its payload bytes generically, in wire order.
//!
//! One object per frame:
//! `{"version":2,"seq":0,"sysid":1,"compid":1,"msgid":15001,"name":"FBWAG_NOTICE","signed":false,"fields":{…}}`.
//! Keys added only when needed to reproduce the bytes exactly: `"link_id"`,
//! `"sign_timestamp"`, `"signature"` for signed frames; `"compat_flags"` when
//! not zero; `"payload_len"` when a MAVLink 2 sender did not drop trailing
//! zeros canonically; `"tlog_us"` for tlog records. Frames of unknown ids are
//! `"name":null` with the whole frame as `"raw"` hex.

use fbwag_dialect::mavframe::crc::frame_crc;
use fbwag_dialect::mavframe::field::{read, Scalar};
use fbwag_dialect::mavframe::frame::{
    self, truncated_len, Frame, Header, Version, HEADER_LEN_V1, HEADER_LEN_V2, IFLAG_SIGNED,
};
use fbwag_dialect::mavframe::{Dialect as _, FieldMeta, FieldType, MessageMeta, Signer};
use fbwag_dialect::Dialect;
use serde_json::{Map, Value};
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

/// A float as JSON: shortest round-trip form, non-finite values as strings.
fn float(out: &mut String, v: f64, shortest: &dyn Fn(&mut String)) {
    if v.is_nan() {
        out.push_str("\"NaN\"");
    } else if v.is_infinite() {
        out.push_str(if v > 0.0 { "\"inf\"" } else { "\"-inf\"" });
    } else {
        shortest(out);
    }
}

fn scalar(out: &mut String, payload: &[u8], ty: FieldType, at: usize) {
    let _ = match ty {
        FieldType::Char | FieldType::U8 => write!(out, "{}", read::<u8>(payload, at)),
        FieldType::I8 => write!(out, "{}", read::<i8>(payload, at)),
        FieldType::U16 => write!(out, "{}", read::<u16>(payload, at)),
        FieldType::I16 => write!(out, "{}", read::<i16>(payload, at)),
        FieldType::U32 => write!(out, "{}", read::<u32>(payload, at)),
        FieldType::I32 => write!(out, "{}", read::<i32>(payload, at)),
        FieldType::U64 => write!(out, "{}", read::<u64>(payload, at)),
        FieldType::I64 => write!(out, "{}", read::<i64>(payload, at)),
        FieldType::F32 => {
            let v = read::<f32>(payload, at);
            // Debug is the shortest form that reads back as the same f32.
            float(out, v as f64, &|o: &mut String| {
                let _ = write!(o, "{v:?}");
            });
            Ok(())
        }
        FieldType::F64 => {
            let v = read::<f64>(payload, at);
            float(out, v, &|o: &mut String| {
                let _ = write!(o, "{v:?}");
            });
            Ok(())
        }
    };
}

/// A `char[N]` (or `char`) value: a string up to the first NUL when that
/// loses nothing, otherwise the bytes as numbers (so encoding restores them).
fn chars(out: &mut String, payload: &[u8], f: &FieldMeta) {
    let n = (f.array_len as usize).max(1);
    let bytes: Vec<u8> = (0..n)
        .map(|i| read::<u8>(payload, f.offset as usize + i))
        .collect();
    let end = bytes.iter().position(|&b| b == 0).unwrap_or(n);
    match std::str::from_utf8(&bytes[..end]) {
        Ok(s) if bytes[end..].iter().all(|&b| b == 0) => out.push_str(&Value::from(s).to_string()),
        _ => {
            out.push('[');
            for (i, b) in bytes.iter().enumerate() {
                if i > 0 {
                    out.push(',');
                }
                let _ = write!(out, "{b}");
            }
            out.push(']');
        }
    }
}

/// The JSON line for a frame; `meta` is `None` for an unknown id.
pub fn frame_to_json(
    frame: &Frame<'_>,
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
    match meta {
        Some(m) => {
            let _ = write!(
                out,
                "\"name\":\"{}\",\"signed\":{}",
                m.name,
                frame.is_signed()
            );
        }
        None => {
            let _ = write!(
                out,
                "\"name\":null,\"signed\":{},\"raw\":\"{}\"}}",
                frame.is_signed(),
                hex(frame.as_bytes())
            );
            return out;
        }
    }
    let meta = meta.expect("handled above");
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
    if frame.version() == Version::V2 {
        // What an encoder produces from these values; otherwise say the length.
        let canonical = truncated_len(&payload[..payload.len().min(meta.max_len as usize)]);
        if payload.len() != canonical {
            let _ = write!(out, ",\"payload_len\":{}", payload.len());
        }
    } else if payload.len() != meta.min_len as usize {
        let _ = write!(out, ",\"payload_len\":{}", payload.len());
    }
    out.push_str(",\"fields\":{");
    for (i, f) in meta.fields.iter().enumerate() {
        if i > 0 {
            out.push(',');
        }
        let _ = write!(out, "\"{}\":", f.name);
        if f.ty == FieldType::Char {
            chars(&mut out, payload, f);
        } else if f.array_len == 0 {
            scalar(&mut out, payload, f.ty, f.offset as usize);
        } else {
            out.push('[');
            for k in 0..f.array_len as usize {
                if k > 0 {
                    out.push(',');
                }
                scalar(&mut out, payload, f.ty, f.offset as usize + k * f.ty.size());
            }
            out.push(']');
        }
    }
    out.push_str("}}");
    out
}

/// Signing for [`json_to_frame`]: sign with a key, or not.
pub struct EncodeOptions<'a> {
    /// Force MAVLink 1 (`--v1`).
    pub force_v1: bool,
    /// Sign every MAVLink 2 frame with this signer (`--sign-key`).
    pub signer: Option<&'a mut Signer>,
}

fn get_u64(obj: &Map<String, Value>, key: &str, max: u64) -> Result<Option<u64>, String> {
    match obj.get(key) {
        None | Some(Value::Null) => Ok(None),
        Some(v) => match v.as_u64() {
            Some(n) if n <= max => Ok(Some(n)),
            _ => Err(format!(
                "`{key}` must be an integer from 0 to {max}, not {v}"
            )),
        },
    }
}

fn write_scalar(
    payload: &mut [u8],
    ty: FieldType,
    at: usize,
    v: &Value,
    name: &str,
) -> Result<(), String> {
    let bad = || format!("field `{name}`: {v} is not a valid {}", ty.c_name());
    fn int<T: TryFrom<i128> + Scalar>(v: &Value) -> Option<T> {
        let n: i128 = v
            .as_i64()
            .map(i128::from)
            .or_else(|| v.as_u64().map(i128::from))?;
        T::try_from(n).ok()
    }
    let float = |v: &Value| -> Option<f64> {
        match v {
            Value::Number(n) => n.as_f64(),
            Value::String(s) if s == "NaN" => Some(f64::NAN),
            Value::String(s) if s == "inf" => Some(f64::INFINITY),
            Value::String(s) if s == "-inf" => Some(f64::NEG_INFINITY),
            _ => None,
        }
    };
    match ty {
        FieldType::Char | FieldType::U8 => int::<u8>(v).ok_or_else(bad)?.write(payload, at),
        FieldType::I8 => int::<i8>(v).ok_or_else(bad)?.write(payload, at),
        FieldType::U16 => int::<u16>(v).ok_or_else(bad)?.write(payload, at),
        FieldType::I16 => int::<i16>(v).ok_or_else(bad)?.write(payload, at),
        FieldType::U32 => int::<u32>(v).ok_or_else(bad)?.write(payload, at),
        FieldType::I32 => int::<i32>(v).ok_or_else(bad)?.write(payload, at),
        FieldType::U64 => int::<u64>(v).ok_or_else(bad)?.write(payload, at),
        FieldType::I64 => int::<i64>(v).ok_or_else(bad)?.write(payload, at),
        FieldType::F32 => (float(v).ok_or_else(bad)? as f32).write(payload, at),
        FieldType::F64 => float(v).ok_or_else(bad)?.write(payload, at),
    }
    Ok(())
}

fn write_field(payload: &mut [u8], f: &FieldMeta, v: &Value) -> Result<(), String> {
    let n = f.array_len as usize;
    let at = f.offset as usize;
    match (f.ty, v) {
        (FieldType::Char, Value::String(s)) => {
            let room = n.max(1);
            if s.len() > room {
                return Err(format!(
                    "field `{}`: {} bytes do not fit char[{room}]",
                    f.name,
                    s.len()
                ));
            }
            payload[at..at + s.len()].copy_from_slice(s.as_bytes());
            Ok(())
        }
        (_, Value::Array(items)) if n > 0 || f.ty == FieldType::Char => {
            if items.len() > n.max(1) {
                return Err(format!(
                    "field `{}`: {} elements, at most {} allowed",
                    f.name,
                    items.len(),
                    n.max(1)
                ));
            }
            for (k, item) in items.iter().enumerate() {
                write_scalar(payload, f.ty, at + k * f.ty.size(), item, f.name)?;
            }
            Ok(())
        }
        (_, _) if n > 0 => Err(format!("field `{}`: expected an array of {n}", f.name)),
        _ => write_scalar(payload, f.ty, at, v, f.name),
    }
}

/// Encodes one JSON line into `out`; returns the frame length.
pub fn json_to_frame(
    line: &str,
    opts: &mut EncodeOptions<'_>,
    out: &mut [u8],
) -> Result<usize, String> {
    let value: Value = serde_json::from_str(line).map_err(|e| format!("not JSON: {e}"))?;
    let obj = value.as_object().ok_or("expected a JSON object")?;
    if let Some(raw) = obj.get("raw") {
        let bytes = unhex(raw.as_str().ok_or("`raw` must be a hex string")?)?;
        let n = bytes.len();
        out.get_mut(..n)
            .ok_or("raw frame too long")?
            .copy_from_slice(&bytes);
        return Ok(n);
    }
    let meta = match (
        obj.get("name").and_then(Value::as_str),
        get_u64(obj, "msgid", 0xFF_FFFF)?,
    ) {
        (Some(name), id) => {
            let m = Dialect::MESSAGES
                .iter()
                .find(|m| m.name == name)
                .ok_or_else(|| format!("unknown message name `{name}`"))?;
            if id.is_some_and(|id| id != m.id as u64) {
                return Err(format!(
                    "`msgid` {} does not match `name` {name} (id {})",
                    id.unwrap_or(0),
                    m.id
                ));
            }
            m
        }
        (None, Some(id)) => {
            Dialect::meta(id as u32).ok_or_else(|| format!("unknown message id {id}"))?
        }
        (None, None) => return Err("needs `name` or `msgid`".into()),
    };
    let version = match (opts.force_v1, get_u64(obj, "version", 2)?) {
        (true, _) | (false, Some(1)) => Version::V1,
        (false, None | Some(2)) => Version::V2,
        (false, Some(v)) => return Err(format!("`version` must be 1 or 2, not {v}")),
    };
    let header = Header {
        seq: get_u64(obj, "seq", 255)?.unwrap_or(0) as u8,
        sysid: get_u64(obj, "sysid", 255)?.unwrap_or(0) as u8,
        compid: get_u64(obj, "compid", 255)?.unwrap_or(0) as u8,
    };
    let start = if version == Version::V2 {
        HEADER_LEN_V2
    } else {
        HEADER_LEN_V1
    };
    let max = meta.max_len as usize;
    let payload = out
        .get_mut(start..start + max)
        .ok_or("output buffer too small")?;
    payload.fill(0);
    let empty = Map::new();
    let fields = match obj.get("fields") {
        None => &empty,
        Some(Value::Object(f)) => f,
        Some(_) => return Err("`fields` must be an object".into()),
    };
    for name in fields.keys() {
        if !meta.fields.iter().any(|f| f.name == name) {
            return Err(format!("{} has no field `{name}`", meta.name));
        }
    }
    for f in meta.fields {
        if let Some(v) = fields.get(f.name) {
            write_field(payload, f, v)?;
        }
    }
    let payload_len = get_u64(obj, "payload_len", 255)?.map(|n| n as usize);
    let compat = get_u64(obj, "compat_flags", 255)?.unwrap_or(0) as u8;
    let verbatim_sig = match (obj.get("signature"), &opts.signer) {
        (Some(sig), None) => {
            let sig = unhex(sig.as_str().ok_or("`signature` must be hex")?)?;
            if sig.len() != 6 {
                return Err("`signature` must be 6 bytes".into());
            }
            let mut block = [0u8; 13];
            block[0] = get_u64(obj, "link_id", 255)?.unwrap_or(0) as u8;
            let ts = get_u64(obj, "sign_timestamp", (1 << 48) - 1)?.unwrap_or(0);
            block[1..7].copy_from_slice(&ts.to_le_bytes()[..6]);
            block[7..].copy_from_slice(&sig);
            Some(block)
        }
        _ => None,
    };
    let canonical = payload_len.is_none() && compat == 0 && verbatim_sig.is_none();
    if version == Version::V1 {
        if meta.id > 255 {
            return Err(format!(
                "{} (id {}) cannot be sent as MAVLink 1",
                meta.name, meta.id
            ));
        }
        // pymavlink's MAVLink 1 frames carry extension fields (C's do not):
        // `payload_len` says how many bytes this one had.
        let len = payload_len.unwrap_or(meta.min_len as usize);
        if len > max {
            return Err(format!(
                "payload_len {len} exceeds {}'s {max} bytes",
                meta.name
            ));
        }
        let total = HEADER_LEN_V1 + len + 2;
        out[..HEADER_LEN_V1].copy_from_slice(&[
            0xFE,
            len as u8,
            header.seq,
            header.sysid,
            header.compid,
            meta.id as u8,
        ]);
        let crc = frame_crc(&out[1..HEADER_LEN_V1 + len], meta.crc_extra);
        out[HEADER_LEN_V1 + len..total].copy_from_slice(&crc.to_le_bytes());
        return Ok(total);
    }
    if canonical {
        return frame::finish(version, header, meta, max, opts.signer.as_deref_mut(), out)
            .map_err(|e| e.to_string());
    }
    // Reproduce exactly what the JSON says: length, flags, signature block.
    let len = payload_len.unwrap_or_else(|| truncated_len(&out[start..start + max]));
    let signed = verbatim_sig.is_some() || opts.signer.is_some();
    let total = HEADER_LEN_V2 + len + 2 + if signed { 13 } else { 0 };
    if len > 255 || out.len() < total {
        return Err(format!("payload_len {len} does not fit"));
    }
    let id = meta.id.to_le_bytes();
    let flags = if signed { IFLAG_SIGNED } else { 0 };
    out[..HEADER_LEN_V2].copy_from_slice(&[
        0xFD,
        len as u8,
        flags,
        compat,
        header.seq,
        header.sysid,
        header.compid,
        id[0],
        id[1],
        id[2],
    ]);
    let crc = frame_crc(&out[1..HEADER_LEN_V2 + len], meta.crc_extra);
    out[HEADER_LEN_V2 + len..HEADER_LEN_V2 + len + 2].copy_from_slice(&crc.to_le_bytes());
    match (verbatim_sig, opts.signer.as_deref_mut()) {
        (_, Some(signer)) => signer.sign_frame(&mut out[..total]),
        (Some(block), None) => out[total - 13..total].copy_from_slice(&block),
        (None, None) => {}
    }
    Ok(total)
}
