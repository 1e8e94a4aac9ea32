//! The `fields` object of a line, through the generated messages' serde
//! impls (forms: [`mavframe::serde`]).
//!
//! Written in their compact form (`is_human_readable() == false`): enums and
//! bitmasks as numbers, as pymavlink prints them; floats as the shortest
//! numbers that read back exactly, NaNs and infinities as the strings of
//! [`float`]; a `char[N]` as a string when its bytes are UTF-8 text padded
//! with NULs, else as its N byte values.
//!
//! Read through the human-readable `Deserialize` with serde_json, which
//! takes every form written here and also entry names for enums, bitmask
//! text, `{"hex": …}` and shorter byte arrays for `char[N]`.
//!
//! [`FieldMeta`] adds what the serde impls do not know: keys in wire order
//! (pymavlink's `ordered_fieldnames`), a `char[N]`'s `N`, fields left out of
//! a line as zeros (not the message's `Default`, which sets
//! `mavlink_version`), and the field a refused value belongs to.
//!
//! [`mavframe::serde`]: fbwag_dialect::mavframe::serde
//! [`float`]: fbwag_dialect::mavframe::serde::float

use super::object::Object;
use super::Error;
use fbwag_dialect::mavframe::serde::float::{self, Float};
use fbwag_dialect::mavframe::{FieldMeta, FieldType, MessageMeta};
use fbwag_dialect::Message;
use serde::ser::{self, Impossible, Serialize, SerializeStruct, SerializeTuple};
use std::fmt::{self, Write as _};

/// The `fields` object of `message`, whose table row is `meta`.
pub fn write(meta: &MessageMeta, message: &Message) -> Result<String, serde_json::Error> {
    let mut w = Writer {
        meta,
        field: None,
        values: String::with_capacity(16 * meta.fields.len()),
        spans: vec![(0, 0); meta.fields.len()],
    };
    message.serialize(&mut w)?;
    let mut out = String::with_capacity(w.values.len() + 16 * meta.fields.len());
    for (f, &(start, end)) in meta.fields.iter().zip(&w.spans) {
        let text = &w.values[start..end];
        if text.is_empty() {
            return Err(ser::Error::custom(format_args!(
                "no value for `{}`",
                f.name
            )));
        }
        out.push(if out.is_empty() { '{' } else { ',' });
        let _ = write!(out, "\"{}\":{text}", f.name);
    }
    out.push('}');
    Ok(out)
}

/// A serde serializer taking one message in compact form: the JSON text of
/// its field values, one after the other.
struct Writer<'m> {
    meta: &'m MessageMeta,
    /// Wire index of the field being written.
    field: Option<usize>,
    values: String,
    /// Each field's text in `values`, by wire index.
    spans: Vec<(usize, usize)>,
}

type WriteResult<T = ()> = Result<T, serde_json::Error>;

impl Writer<'_> {
    fn text(&mut self) -> WriteResult<&mut String> {
        match self.field {
            Some(_) => Ok(&mut self.values),
            None => Err(ser::Error::custom("a value outside a message field")),
        }
    }

    fn push(&mut self, value: impl fmt::Display) -> WriteResult {
        let _ = write!(self.text()?, "{value}");
        Ok(())
    }

    fn float<F: Float>(&mut self, v: F) -> WriteResult {
        // Debug is the shortest form that reads back as the same value
        // (signed zero and subnormals included).
        match float::special(v) {
            Some(text) => self.push(format_args!("\"{text}\"")),
            None => self.push(format_args!("{v:?}")),
        }
    }

    /// A `char[N]` (compact form: its bytes without the trailing NULs).
    fn chars(&mut self, bytes: &[u8]) -> WriteResult {
        let n = self
            .field
            .map_or(0, |i| self.meta.fields[i].array_len as usize);
        match std::str::from_utf8(bytes) {
            Ok(text) if !bytes.contains(&0) => {
                let quoted = serde_json::to_string(text)?;
                self.push(quoted)
            }
            _ => {
                let out = self.text()?;
                for k in 0..n.max(bytes.len()) {
                    out.push(if k == 0 { '[' } else { ',' });
                    let _ = write!(out, "{}", bytes.get(k).copied().unwrap_or(0));
                }
                out.push(']');
                Ok(())
            }
        }
    }
}

/// Serializer methods that write a number as it is.
macro_rules! numbers {
    ($($method:ident: $ty:ty),*) => {$(
        fn $method(self, v: $ty) -> WriteResult {
            self.push(v)
        }
    )*};
}

/// Serializer methods no message in compact form calls.
macro_rules! refused {
    ($($method:ident($($arg:ty),*) -> $ok:ty;)*) => {$(
        fn $method(self, $(_: $arg),*) -> WriteResult<$ok> {
            Err(ser::Error::custom(concat!("not a message value: ", stringify!($method))))
        }
    )*};
}

impl ser::Serializer for &mut Writer<'_> {
    type Ok = ();
    type Error = serde_json::Error;
    type SerializeSeq = Impossible<(), serde_json::Error>;
    type SerializeTuple = Self;
    type SerializeTupleStruct = Impossible<(), serde_json::Error>;
    type SerializeTupleVariant = Impossible<(), serde_json::Error>;
    type SerializeMap = Impossible<(), serde_json::Error>;
    type SerializeStruct = Self;
    type SerializeStructVariant = Impossible<(), serde_json::Error>;

    fn is_human_readable(&self) -> bool {
        false
    }

    numbers!(serialize_u8: u8, serialize_u16: u16, serialize_u32: u32, serialize_u64: u64,
        serialize_i8: i8, serialize_i16: i16, serialize_i32: i32, serialize_i64: i64);

    fn serialize_f32(self, v: f32) -> WriteResult {
        self.float(v)
    }

    fn serialize_f64(self, v: f64) -> WriteResult {
        self.float(v)
    }

    fn serialize_bytes(self, v: &[u8]) -> WriteResult {
        self.chars(v)
    }

    fn serialize_tuple(self, _: usize) -> WriteResult<Self> {
        self.text()?.push('[');
        Ok(self)
    }

    fn serialize_struct(self, _: &'static str, _: usize) -> WriteResult<Self> {
        Ok(self)
    }

    /// The dialect's `Message` enum: the message inside it.
    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        value: &T,
    ) -> WriteResult {
        value.serialize(self)
    }

    fn serialize_newtype_struct<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        value: &T,
    ) -> WriteResult {
        value.serialize(self)
    }

    fn serialize_some<T: ?Sized + Serialize>(self, value: &T) -> WriteResult {
        value.serialize(self)
    }

    refused! {
        serialize_bool(bool) -> ();
        serialize_char(char) -> ();
        serialize_str(&str) -> ();
        serialize_none() -> ();
        serialize_unit() -> ();
        serialize_unit_struct(&'static str) -> ();
        serialize_unit_variant(&'static str, u32, &'static str) -> ();
        serialize_seq(Option<usize>) -> Self::SerializeSeq;
        serialize_tuple_struct(&'static str, usize) -> Self::SerializeTupleStruct;
        serialize_tuple_variant(&'static str, u32, &'static str, usize) -> Self::SerializeTupleVariant;
        serialize_map(Option<usize>) -> Self::SerializeMap;
        serialize_struct_variant(&'static str, u32, &'static str, usize) -> Self::SerializeStructVariant;
    }
}

impl SerializeStruct for &mut Writer<'_> {
    type Ok = ();
    type Error = serde_json::Error;

    fn serialize_field<T: ?Sized + Serialize>(&mut self, key: &'static str, v: &T) -> WriteResult {
        let i = self.meta.fields.iter().position(|f| f.name == key);
        let i = i.ok_or_else(|| ser::Error::custom(format_args!("no field `{key}`")))?;
        self.field = Some(i);
        let start = self.values.len();
        v.serialize(&mut **self)?;
        self.spans[i] = (start, self.values.len());
        Ok(())
    }

    fn end(self) -> WriteResult {
        Ok(())
    }
}

impl SerializeTuple for &mut Writer<'_> {
    type Ok = ();
    type Error = serde_json::Error;

    fn serialize_element<T: ?Sized + Serialize>(&mut self, v: &T) -> WriteResult {
        let text = self.text()?;
        if !text.ends_with('[') {
            text.push(',');
        }
        v.serialize(&mut **self)
    }

    fn end(self) -> WriteResult {
        self.text()?.push(']');
        Ok(())
    }
}

/// The message of `meta` that the line's `fields` describe: the line's
/// values as written, the fields it leaves out as zeros.
pub fn read(meta: &'static MessageMeta, fields: &Object<'_>) -> Result<Message, Error> {
    // The `Message` enum's form, `{"NAME":{…}}`, and where each key starts
    // in it, to name the field of an error by its position.
    let mut text = format!("{{\"{}\":{{", meta.name);
    let mut starts: Vec<(usize, &'static str)> = Vec::with_capacity(meta.fields.len());
    let mut add = |f: &'static FieldMeta, value: &str| {
        if !starts.is_empty() {
            text.push(',');
        }
        starts.push((text.len(), f.name));
        let _ = write!(text, "\"{}\":{value}", f.name);
    };
    let mut given = vec![false; meta.fields.len()];
    for (key, raw) in &fields.0 {
        let i = meta.fields.iter().position(|f| f.name == key);
        let i = i.ok_or_else(|| Error::UnknownField {
            message: meta.name,
            field: key.clone(),
        })?;
        given[i] = true;
        add(&meta.fields[i], raw.get());
    }
    for (f, _) in meta.fields.iter().zip(given).filter(|(_, g)| !g) {
        add(f, &zero(f));
    }
    text.push_str("}}");
    serde_json::from_str(&text).map_err(|source| {
        // Columns count bytes from 1; the text is one line.
        let at = source.column().saturating_sub(1);
        let field = starts.iter().rev().find(|(s, _)| *s < at).map(|&(_, f)| f);
        Error::Field {
            message: meta.name,
            field,
            source,
        }
    })
}

/// The JSON of a field's zero value.
fn zero(f: &FieldMeta) -> String {
    match (f.ty, f.array_len as usize) {
        (_, 0) => "0".into(),
        (FieldType::Char, _) => "\"\"".into(),
        (_, n) => format!("[0{}]", ",0".repeat(n - 1)),
    }
}
