//! The `fields` object of a line, through the generated messages' serde
//! impls in their compact form (`is_human_readable() == false`): enums and
//! bitmasks as numbers (as pymavlink prints them), char arrays as bytes,
//! floats and arrays as values. This module is the small serde format that
//! writes and reads those values the way the tool's JSON lines have them:
//!
//! - integers as JSON numbers, range-checked against the field's wire type
//!   when read (an enum's Rust type may be wider than its field);
//! - floats as the shortest numbers that read back exactly, and the strings
//!   of [`mavframe::serde::float`] for NaNs and infinities; read from their
//!   text straight to the field's type (one rounding, no detour through f64);
//! - `char` fields as a string up to the first NUL when that loses nothing,
//!   else as the field's every byte value;
//! - arrays with exactly the declared number of elements;
//! - keys in wire order (pymavlink's `ordered_fieldnames`), fields left out
//!   of a line as zeros (not the message's `Default`, which sets
//!   `mavlink_version`).
//!
//! [`mavframe::serde::float`]: fbwag_dialect::mavframe::serde::float

use super::{shown, value, Object};
use fbwag_dialect::mavframe::serde::float::{self, Float, SpecialError};
use fbwag_dialect::mavframe::{FieldMeta, FieldType, MessageMeta};
use fbwag_dialect::{Message, MESSAGES};
use serde::de::{self, DeserializeSeed, EnumAccess, IntoDeserializer, SeqAccess, VariantAccess};
use serde::ser::{self, Impossible, Serialize, SerializeStruct, SerializeTuple};
use serde_json::value::RawValue;
use serde_json::Value;
use std::cell::RefCell;
use std::fmt::{self, Write as _};

/// What went wrong between a message and its JSON values.
#[derive(Debug)]
pub struct FieldsError(pub String);

impl fmt::Display for FieldsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for FieldsError {}

impl ser::Error for FieldsError {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        FieldsError(msg.to_string())
    }
}

impl de::Error for FieldsError {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        FieldsError(msg.to_string())
    }
}

fn unsupported<T>(what: &str) -> Result<T, FieldsError> {
    Err(FieldsError(format!(
        "a message field cannot be {what} in this format"
    )))
}

/// The `Serializer` methods no message or field value calls.
macro_rules! not_a_message {
    () => {
        fn serialize_bool(self, _: bool) -> Result<(), FieldsError> {
            unsupported("a bool")
        }
        fn serialize_i8(self, _: i8) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_i16(self, _: i16) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_i32(self, _: i32) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_i64(self, _: i64) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_u8(self, _: u8) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_u16(self, _: u16) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_u32(self, _: u32) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_u64(self, _: u64) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_f32(self, _: f32) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_f64(self, _: f64) -> Result<(), FieldsError> {
            unsupported("a bare number")
        }
        fn serialize_char(self, _: char) -> Result<(), FieldsError> {
            unsupported("a char")
        }
        fn serialize_str(self, _: &str) -> Result<(), FieldsError> {
            unsupported("a string")
        }
        fn serialize_bytes(self, _: &[u8]) -> Result<(), FieldsError> {
            unsupported("bytes")
        }
        fn serialize_tuple(self, _: usize) -> Result<Self::SerializeTuple, FieldsError> {
            unsupported("a tuple")
        }
        not_a_value! {}
    };
}

/// The `Serializer` methods no field value calls.
macro_rules! not_a_value {
    () => {
        fn serialize_none(self) -> Result<(), FieldsError> {
            unsupported("an option")
        }
        fn serialize_some<T: ?Sized + Serialize>(self, _: &T) -> Result<(), FieldsError> {
            unsupported("an option")
        }
        fn serialize_unit(self) -> Result<(), FieldsError> {
            unsupported("a unit")
        }
        fn serialize_unit_struct(self, _: &'static str) -> Result<(), FieldsError> {
            unsupported("a unit")
        }
        fn serialize_unit_variant(
            self,
            _: &'static str,
            _: u32,
            _: &'static str,
        ) -> Result<(), FieldsError> {
            unsupported("a unit variant")
        }
        fn serialize_newtype_struct<T: ?Sized + Serialize>(
            self,
            _: &'static str,
            _: &T,
        ) -> Result<(), FieldsError> {
            unsupported("a newtype")
        }
        fn serialize_seq(self, _: Option<usize>) -> Result<Self::SerializeSeq, FieldsError> {
            unsupported("a sequence")
        }
        fn serialize_tuple_struct(
            self,
            _: &'static str,
            _: usize,
        ) -> Result<Self::SerializeTupleStruct, FieldsError> {
            unsupported("a tuple struct")
        }
        fn serialize_tuple_variant(
            self,
            _: &'static str,
            _: u32,
            _: &'static str,
            _: usize,
        ) -> Result<Self::SerializeTupleVariant, FieldsError> {
            unsupported("a tuple variant")
        }
        fn serialize_map(self, _: Option<usize>) -> Result<Self::SerializeMap, FieldsError> {
            unsupported("a map")
        }
        fn serialize_struct_variant(
            self,
            _: &'static str,
            _: u32,
            _: &'static str,
            _: usize,
        ) -> Result<Self::SerializeStructVariant, FieldsError> {
            unsupported("a struct variant")
        }
    };
}

// ---------------------------------------------------------------- writing

/// Appends the `fields` object of `message` (whose table row is `meta`).
pub fn write(out: &mut String, meta: &MessageMeta, message: &Message) -> Result<(), FieldsError> {
    SCRATCH.with(|scratch| match scratch.try_borrow_mut() {
        Ok(mut scratch) => scratch.write(out, meta, message),
        // Not reentrant; were it ever, fresh buffers do the same.
        Err(_) => Scratch::default().write(out, meta, message),
    })
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// Buffers kept from line to line, so a line allocates nothing here.
#[derive(Default)]
struct Scratch {
    /// Every value's JSON text, in the order serde gives them.
    values: String,
    /// Each field's text in `values`, by wire index.
    spans: Vec<(usize, usize)>,
    /// Per message of the dialect (by index in its table): the wire index
    /// of the k-th field serde writes (in declaration, i.e. XML, order),
    /// learnt from the names on the message's first line.
    orders: Vec<Vec<usize>>,
    /// The order of a message the dialect's table does not have (none).
    other: Vec<usize>,
}

impl Scratch {
    fn write(
        &mut self,
        out: &mut String,
        meta: &MessageMeta,
        message: &Message,
    ) -> Result<(), FieldsError> {
        self.values.clear();
        self.spans.clear();
        self.spans.resize(meta.fields.len(), (0, 0));
        let order = match MESSAGES.binary_search_by_key(&meta.id, |m| m.id) {
            Ok(i) => {
                self.orders.resize_with(MESSAGES.len(), Vec::new);
                &mut self.orders[i]
            }
            Err(_) => &mut self.other,
        };
        let mut fields = FieldsWriter {
            meta,
            values: &mut self.values,
            spans: &mut self.spans,
            order,
            next: 0,
        };
        message.serialize(MessageWriter(&mut fields))?;
        out.push('{');
        for (i, (f, &(start, end))) in meta.fields.iter().zip(&self.spans).enumerate() {
            if i > 0 {
                out.push(',');
            }
            out.push('"');
            out.push_str(f.name);
            out.push_str("\":");
            out.push_str(&self.values[start..end]);
        }
        out.push('}');
        Ok(())
    }
}

struct FieldsWriter<'a> {
    meta: &'a MessageMeta,
    values: &'a mut String,
    spans: &'a mut [(usize, usize)],
    order: &'a mut Vec<usize>,
    /// Fields written so far.
    next: usize,
}

impl FieldsWriter<'_> {
    /// The wire index of the next field, named `key`: as last time for
    /// this message, or found by name (and remembered).
    fn index(&mut self, key: &str) -> Option<usize> {
        let k = self.next;
        self.next += 1;
        if let Some(&i) = self.order.get(k) {
            let name = self.meta.fields[i].name;
            // The derive's literal and the table's are usually one.
            if std::ptr::eq(name, key) || name == key {
                return Some(i);
            }
        }
        let i = self.meta.fields.iter().position(|f| f.name == key)?;
        self.order.truncate(k);
        self.order.push(i);
        Some(i)
    }
}

/// Takes the `Message` enum and the message struct inside it.
struct MessageWriter<'a, 'b>(&'a mut FieldsWriter<'b>);

impl ser::Serializer for MessageWriter<'_, '_> {
    type Ok = ();
    type Error = FieldsError;
    type SerializeSeq = Impossible<(), FieldsError>;
    type SerializeTuple = Impossible<(), FieldsError>;
    type SerializeTupleStruct = Impossible<(), FieldsError>;
    type SerializeTupleVariant = Impossible<(), FieldsError>;
    type SerializeMap = Impossible<(), FieldsError>;
    type SerializeStruct = Self;
    type SerializeStructVariant = Impossible<(), FieldsError>;

    fn is_human_readable(&self) -> bool {
        false
    }

    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        message: &T,
    ) -> Result<(), FieldsError> {
        message.serialize(self)
    }

    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Self, FieldsError> {
        Ok(self)
    }

    not_a_message! {}
}

impl SerializeStruct for MessageWriter<'_, '_> {
    type Ok = ();
    type Error = FieldsError;

    fn serialize_field<T: ?Sized + Serialize>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), FieldsError> {
        let w = &mut *self.0;
        let i = w
            .index(key)
            .ok_or_else(|| FieldsError(format!("{} has no field `{key}`", w.meta.name)))?;
        let start = w.values.len();
        value.serialize(ValueWriter {
            out: w.values,
            field: &w.meta.fields[i],
        })?;
        w.spans[i] = (start, w.values.len());
        Ok(())
    }

    fn end(self) -> Result<(), FieldsError> {
        Ok(())
    }
}

/// Writes one field's value (or one array element).
struct ValueWriter<'a> {
    out: &'a mut String,
    field: &'a FieldMeta,
}

impl ValueWriter<'_> {
    fn number(self, v: impl itoa::Integer) -> Result<(), FieldsError> {
        self.out.push_str(itoa::Buffer::new().format(v));
        Ok(())
    }

    fn float<F: Float>(self, v: F) -> Result<(), FieldsError> {
        // Debug is the shortest form that reads back as the same value
        // (signed zero and subnormals included).
        let _ = match float::special(v) {
            Some(text) => write!(self.out, "\"{text}\""),
            None => write!(self.out, "{v:?}"),
        };
        Ok(())
    }

    /// A `char` or `char[N]`: the text up to the first NUL when the rest is
    /// NULs and the text is UTF-8, otherwise every byte as a number.
    fn chars(self, bytes: &[u8]) -> Result<(), FieldsError> {
        let n = (self.field.array_len as usize).max(1);
        let bytes = &bytes[..bytes.len().min(n)];
        let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
        match std::str::from_utf8(&bytes[..end]) {
            Ok(s) if bytes[end..].iter().all(|&b| b == 0) => {
                self.out.push_str(&Value::from(s).to_string())
            }
            _ => {
                self.out.push('[');
                for i in 0..n {
                    if i > 0 {
                        self.out.push(',');
                    }
                    let _ = write!(self.out, "{}", bytes.get(i).copied().unwrap_or(0));
                }
                self.out.push(']');
            }
        }
        Ok(())
    }
}

impl<'a> ser::Serializer for ValueWriter<'a> {
    type Ok = ();
    type Error = FieldsError;
    type SerializeSeq = Impossible<(), FieldsError>;
    type SerializeTuple = TupleWriter<'a>;
    type SerializeTupleStruct = Impossible<(), FieldsError>;
    type SerializeTupleVariant = Impossible<(), FieldsError>;
    type SerializeMap = Impossible<(), FieldsError>;
    type SerializeStruct = Impossible<(), FieldsError>;
    type SerializeStructVariant = Impossible<(), FieldsError>;

    fn is_human_readable(&self) -> bool {
        false
    }

    fn serialize_u8(self, v: u8) -> Result<(), FieldsError> {
        if self.field.ty == FieldType::Char {
            self.chars(&[v])
        } else {
            self.number(v)
        }
    }

    fn serialize_i8(self, v: i8) -> Result<(), FieldsError> {
        self.number(v)
    }

    fn serialize_u16(self, v: u16) -> Result<(), FieldsError> {
        self.number(v)
    }

    fn serialize_i16(self, v: i16) -> Result<(), FieldsError> {
        self.number(v)
    }

    fn serialize_u32(self, v: u32) -> Result<(), FieldsError> {
        self.number(v)
    }

    fn serialize_i32(self, v: i32) -> Result<(), FieldsError> {
        self.number(v)
    }

    fn serialize_u64(self, v: u64) -> Result<(), FieldsError> {
        self.number(v)
    }

    fn serialize_i64(self, v: i64) -> Result<(), FieldsError> {
        self.number(v)
    }

    fn serialize_f32(self, v: f32) -> Result<(), FieldsError> {
        self.float(v)
    }

    fn serialize_f64(self, v: f64) -> Result<(), FieldsError> {
        self.float(v)
    }

    fn serialize_bytes(self, v: &[u8]) -> Result<(), FieldsError> {
        self.chars(v)
    }

    fn serialize_tuple(self, _: usize) -> Result<TupleWriter<'a>, FieldsError> {
        self.out.push('[');
        Ok(TupleWriter {
            out: self.out,
            field: self.field,
            first: true,
        })
    }

    fn serialize_struct(
        self,
        _: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStruct, FieldsError> {
        unsupported("a struct")
    }

    fn serialize_newtype_variant<T: ?Sized + Serialize>(
        self,
        _: &'static str,
        _: u32,
        _: &'static str,
        _: &T,
    ) -> Result<(), FieldsError> {
        unsupported("a newtype variant")
    }

    fn serialize_bool(self, _: bool) -> Result<(), FieldsError> {
        unsupported("a bool")
    }

    fn serialize_char(self, _: char) -> Result<(), FieldsError> {
        unsupported("a char")
    }

    fn serialize_str(self, _: &str) -> Result<(), FieldsError> {
        unsupported("a string")
    }

    not_a_value! {}
}

/// Writes an array field's elements.
struct TupleWriter<'a> {
    out: &'a mut String,
    field: &'a FieldMeta,
    first: bool,
}

impl SerializeTuple for TupleWriter<'_> {
    type Ok = ();
    type Error = FieldsError;

    fn serialize_element<T: ?Sized + Serialize>(&mut self, value: &T) -> Result<(), FieldsError> {
        if !self.first {
            self.out.push(',');
        }
        self.first = false;
        value.serialize(ValueWriter {
            out: &mut *self.out,
            field: self.field,
        })
    }

    fn end(self) -> Result<(), FieldsError> {
        self.out.push(']');
        Ok(())
    }
}

// ---------------------------------------------------------------- reading

/// The message a line's `fields` describe (whose table row is `meta`);
/// a key that is not a field of it is refused.
pub fn read(meta: &'static MessageMeta, fields: &Object<'_>) -> Result<Message, FieldsError> {
    // The line's fields in its order, then the others as zeros.
    let mut given = vec![false; meta.fields.len()];
    let mut values = Vec::with_capacity(meta.fields.len());
    let mut guess = 0;
    for (name, raw) in &fields.0 {
        // Lines usually list the fields in wire order, as decode writes them.
        let i = match meta.fields.get(guess) {
            Some(f) if f.name == name => guess,
            _ => meta
                .fields
                .iter()
                .position(|f| f.name == name)
                .ok_or_else(|| FieldsError(format!("{} has no field `{name}`", meta.name)))?,
        };
        given[i] = true;
        guess = i + 1;
        values.push((&meta.fields[i], Some(*raw)));
    }
    for (f, _) in meta.fields.iter().zip(&given).filter(|(_, &g)| !g) {
        values.push((f, None));
    }
    Message::deserialize(MessageReader { meta, values })
}

use serde::Deserialize as _;

/// Presents the line as `{"NAME": {fields}}`, the `Message` enum's form.
struct MessageReader<'a> {
    meta: &'static MessageMeta,
    values: Vec<(&'static FieldMeta, Option<&'a RawValue>)>,
}

impl<'de, 'a> de::Deserializer<'de> for MessageReader<'a> {
    type Error = FieldsError;

    fn is_human_readable(&self) -> bool {
        false
    }

    fn deserialize_any<V: de::Visitor<'de>>(self, _: V) -> Result<V::Value, FieldsError> {
        unsupported("anything but a message")
    }

    fn deserialize_enum<V: de::Visitor<'de>>(
        self,
        _: &'static str,
        _: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, FieldsError> {
        visitor.visit_enum(self)
    }

    serde::forward_to_deserialize_any! {
        bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string
        bytes byte_buf option unit unit_struct newtype_struct seq tuple
        tuple_struct map struct identifier ignored_any
    }
}

impl<'de, 'a> EnumAccess<'de> for MessageReader<'a> {
    type Error = FieldsError;
    type Variant = Self;

    fn variant_seed<V: DeserializeSeed<'de>>(
        self,
        seed: V,
    ) -> Result<(V::Value, Self), FieldsError> {
        let name: de::value::StrDeserializer<'_, FieldsError> = self.meta.name.into_deserializer();
        Ok((seed.deserialize(name)?, self))
    }
}

impl<'de, 'a> VariantAccess<'de> for MessageReader<'a> {
    type Error = FieldsError;

    fn unit_variant(self) -> Result<(), FieldsError> {
        unsupported("a unit variant")
    }

    fn newtype_variant_seed<T: DeserializeSeed<'de>>(
        self,
        seed: T,
    ) -> Result<T::Value, FieldsError> {
        seed.deserialize(de::value::MapAccessDeserializer::new(FieldsReader {
            values: self.values.into_iter(),
            current: None,
        }))
    }

    fn tuple_variant<V: de::Visitor<'de>>(self, _: usize, _: V) -> Result<V::Value, FieldsError> {
        unsupported("a tuple variant")
    }

    fn struct_variant<V: de::Visitor<'de>>(
        self,
        _: &'static [&'static str],
        _: V,
    ) -> Result<V::Value, FieldsError> {
        unsupported("a struct variant")
    }
}

/// The fields as a map, each value read by a [`ValueReader`].
struct FieldsReader<'a> {
    values: std::vec::IntoIter<(&'static FieldMeta, Option<&'a RawValue>)>,
    current: Option<(&'static FieldMeta, Option<&'a RawValue>)>,
}

impl<'de, 'a> de::MapAccess<'de> for FieldsReader<'a> {
    type Error = FieldsError;

    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, FieldsError> {
        let Some(entry) = self.values.next() else {
            return Ok(None);
        };
        self.current = Some(entry);
        let name: de::value::StrDeserializer<'_, FieldsError> = entry.0.name.into_deserializer();
        seed.deserialize(name).map(Some)
    }

    fn next_value_seed<V: DeserializeSeed<'de>>(
        &mut self,
        seed: V,
    ) -> Result<V::Value, FieldsError> {
        let (field, raw) = self
            .current
            .take()
            .ok_or_else(|| FieldsError("a value without its key".into()))?;
        seed.deserialize(ValueReader { field, raw })
            .map_err(|e| FieldsError(format!("field `{}`: {e}", field.name)))
    }
}

/// Reads one field's value (or one array element): its JSON text, or a
/// zero when the line leaves the field out (`raw` is `None`).
struct ValueReader<'a> {
    field: &'static FieldMeta,
    raw: Option<&'a RawValue>,
}

impl ValueReader<'_> {
    /// The integer, in the range of the field's wire type.
    fn integer(&self) -> Result<i128, FieldsError> {
        let ty = self.field.ty;
        let (lo, hi) = match ty {
            FieldType::Char | FieldType::U8 => (0, i128::from(u8::MAX)),
            FieldType::I8 => (i128::from(i8::MIN), i128::from(i8::MAX)),
            FieldType::U16 => (0, i128::from(u16::MAX)),
            FieldType::I16 => (i128::from(i16::MIN), i128::from(i16::MAX)),
            FieldType::U32 => (0, i128::from(u32::MAX)),
            FieldType::I32 => (i128::from(i32::MIN), i128::from(i32::MAX)),
            FieldType::U64 => (0, i128::from(u64::MAX)),
            FieldType::I64 => (i128::from(i64::MIN), i128::from(i64::MAX)),
            FieldType::F32 | FieldType::F64 => return unsupported("an integer for a float"),
        };
        match self.raw {
            None => Ok(0),
            Some(raw) => integer(raw, lo, hi, ty).map_err(FieldsError),
        }
    }

    fn visit_integer<'de, V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        if self.field.ty == FieldType::Char {
            return visitor.visit_u8(self.chars()?[0]);
        }
        match self.integer()? {
            n if n < 0 => visitor.visit_i64(n as i64),
            // In range of the field's type: at most u64::MAX.
            n => visitor.visit_u64(n as u64),
        }
    }

    fn float<F: Float + std::str::FromStr>(&self) -> Result<F, FieldsError> {
        match self.raw {
            None => Ok(F::from_bits64(0)),
            Some(raw) => float_value::<F>(raw).map_err(FieldsError),
        }
    }

    /// A `char[N]` (or `char`, N = 1): a string of at most N bytes
    /// (NUL-padded), or exactly N byte values (what is written when bytes
    /// follow a NUL).
    fn chars(&self) -> Result<Vec<u8>, FieldsError> {
        let room = (self.field.array_len as usize).max(1);
        let mut out = vec![0u8; room];
        let Some(raw) = self.raw else {
            return Ok(out);
        };
        match value(raw) {
            Value::String(s) if s.len() <= room => out[..s.len()].copy_from_slice(s.as_bytes()),
            Value::String(s) => {
                return Err(FieldsError(format!("{} bytes do not fit char[{room}]", s.len())))
            }
            Value::Array(items) if items.len() == room => {
                for (d, item) in out.iter_mut().zip(&items) {
                    *d = item
                        .as_u64()
                        .and_then(|b| u8::try_from(b).ok())
                        .ok_or_else(|| FieldsError(format!("{item} is not a byte value (0 to 255)")))?;
                }
            }
            _ => {
                return Err(FieldsError(format!(
                    "expected a string of at most {room} bytes or an array of {room} byte values, not {}",
                    shown(raw)
                )))
            }
        }
        Ok(out)
    }
}

impl<'de, 'a> de::Deserializer<'de> for ValueReader<'a> {
    type Error = FieldsError;

    fn is_human_readable(&self) -> bool {
        false
    }

    fn deserialize_any<V: de::Visitor<'de>>(self, _: V) -> Result<V::Value, FieldsError> {
        unsupported("a value of unknown type")
    }

    fn deserialize_u8<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        self.visit_integer(visitor)
    }

    fn deserialize_u16<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        self.visit_integer(visitor)
    }

    fn deserialize_u32<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        self.visit_integer(visitor)
    }

    fn deserialize_u64<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        self.visit_integer(visitor)
    }

    fn deserialize_i8<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        self.visit_integer(visitor)
    }

    fn deserialize_i16<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        self.visit_integer(visitor)
    }

    fn deserialize_i32<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        self.visit_integer(visitor)
    }

    fn deserialize_i64<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        self.visit_integer(visitor)
    }

    fn deserialize_f32<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        match self.field.ty {
            FieldType::F32 => visitor.visit_f32(self.float::<f32>()?),
            _ => unsupported("a float for an integer"),
        }
    }

    fn deserialize_f64<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        match self.field.ty {
            FieldType::F64 => visitor.visit_f64(self.float::<f64>()?),
            _ => unsupported("a double for an integer"),
        }
    }

    fn deserialize_bytes<V: de::Visitor<'de>>(self, visitor: V) -> Result<V::Value, FieldsError> {
        visitor.visit_bytes(&self.chars()?)
    }

    fn deserialize_byte_buf<V: de::Visitor<'de>>(
        self,
        visitor: V,
    ) -> Result<V::Value, FieldsError> {
        self.deserialize_bytes(visitor)
    }

    fn deserialize_tuple<V: de::Visitor<'de>>(
        self,
        _: usize,
        visitor: V,
    ) -> Result<V::Value, FieldsError> {
        let n = self.field.array_len as usize;
        let items: Vec<Option<&RawValue>> = match self.raw {
            None => vec![None; n],
            Some(raw) => {
                let expected = || format!("expected an array of {n} {}", self.field.ty.c_name());
                let items: Vec<&RawValue> =
                    serde_json::from_str(raw.get()).map_err(|_| FieldsError(expected()))?;
                if items.len() != n {
                    return Err(FieldsError(format!(
                        "{}: it has {}",
                        expected(),
                        items.len()
                    )));
                }
                items.into_iter().map(Some).collect()
            }
        };
        visitor.visit_seq(ElementsReader {
            field: self.field,
            items: items.into_iter().enumerate(),
        })
    }

    serde::forward_to_deserialize_any! {
        bool i128 u128 char str string option unit unit_struct newtype_struct
        seq tuple_struct map struct enum identifier ignored_any
    }
}

/// An array field's elements.
struct ElementsReader<'a> {
    field: &'static FieldMeta,
    items: std::iter::Enumerate<std::vec::IntoIter<Option<&'a RawValue>>>,
}

impl<'de, 'a> SeqAccess<'de> for ElementsReader<'a> {
    type Error = FieldsError;

    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, FieldsError> {
        let Some((k, raw)) = self.items.next() else {
            return Ok(None);
        };
        seed.deserialize(ValueReader {
            field: self.field,
            raw,
        })
        .map(Some)
        .map_err(|e| FieldsError(format!("element {k}: {e}")))
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.items.len())
    }
}

/// A JSON integer from `lo` to `hi`.
fn integer(raw: &RawValue, lo: i128, hi: i128, ty: FieldType) -> Result<i128, String> {
    let text = raw.get().trim();
    let range = || {
        format!(
            "{} is out of range for {} ({lo} to {hi})",
            shown(raw),
            ty.c_name()
        )
    };
    let v = value(raw);
    let n = match v
        .as_i64()
        .map(i128::from)
        .or_else(|| v.as_u64().map(i128::from))
    {
        Some(n) => n,
        // Digits only, yet too large for 64 bits.
        None if v.is_number() && text.bytes().all(|b| b.is_ascii_digit() || b == b'-') => {
            return Err(range())
        }
        None => {
            return Err(format!(
                "{} is not an integer ({})",
                shown(raw),
                ty.c_name()
            ))
        }
    };
    if (lo..=hi).contains(&n) {
        Ok(n)
    } else {
        Err(range())
    }
}

/// A float field's value: a JSON number, parsed straight from its text to
/// the field's type (so rounding happens once, to the nearest value), or
/// one of the strings of [`float`]. Finite numbers beyond the type's range
/// are refused rather than turned into infinities.
fn float_value<F: Float + std::str::FromStr>(raw: &RawValue) -> Result<F, String> {
    let text = raw.get().trim();
    match value(raw) {
        Value::Number(_) => match text.parse::<F>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(format!(
                "{} is out of range for {} (use \"inf\" or \"-inf\" for infinities)",
                shown(raw),
                F::C_NAME
            )),
        },
        Value::String(s) => float::parse_special(&s).map_err(|e| match e {
            SpecialError::NotNan => format!("\"{s}\": these bits are not a NaN"),
            _ => format!(
                "\"{s}\" is not a {} (\"NaN\", \"NaN:0x\" and {} hex digits, \"inf\" or \"-inf\")",
                F::C_NAME,
                F::HEX_DIGITS
            ),
        }),
        _ => Err(format!(
            "expected a number, \"NaN\", \"NaN:0x…\", \"inf\" or \"-inf\" for a {}, not {}",
            F::C_NAME,
            shown(raw)
        )),
    }
}
