//! The parsed form of MAVLink XML: files, messages, fields, enums.
//!
//! Values are kept as the XML states them; the schema resolves
//! includes, merges enums and computes wire layouts on top of this.

use crate::diag::Loc;
use std::path::PathBuf;

/// A scalar wire type.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Primitive {
    /// `char`: one byte, a string element in arrays.
    Char,
    /// `uint8_t`
    U8,
    /// `int8_t`
    I8,
    /// `uint16_t`
    U16,
    /// `int16_t`
    I16,
    /// `uint32_t`
    U32,
    /// `int32_t`
    I32,
    /// `uint64_t`
    U64,
    /// `int64_t`
    I64,
    /// `float`
    F32,
    /// `double`
    F64,
}

impl Primitive {
    /// Parses the XML spelling (`uint8_t`, or `uint8` as pymavlink accepts).
    pub fn from_xml(name: &str) -> Option<Primitive> {
        let base = name.strip_suffix("_t").unwrap_or(name);
        Some(match base {
            "char" => Primitive::Char,
            "uint8" => Primitive::U8,
            "int8" => Primitive::I8,
            "uint16" => Primitive::U16,
            "int16" => Primitive::I16,
            "uint32" => Primitive::U32,
            "int32" => Primitive::I32,
            "uint64" => Primitive::U64,
            "int64" => Primitive::I64,
            "float" if name == "float" => Primitive::F32,
            "double" if name == "double" => Primitive::F64,
            _ => return None,
        })
    }

    /// The C name, as hashed into CRC_EXTRA.
    pub fn c_name(self) -> &'static str {
        match self {
            Primitive::Char => "char",
            Primitive::U8 => "uint8_t",
            Primitive::I8 => "int8_t",
            Primitive::U16 => "uint16_t",
            Primitive::I16 => "int16_t",
            Primitive::U32 => "uint32_t",
            Primitive::I32 => "int32_t",
            Primitive::U64 => "uint64_t",
            Primitive::I64 => "int64_t",
            Primitive::F32 => "float",
            Primitive::F64 => "double",
        }
    }

    /// Size in bytes on the wire.
    pub fn size(self) -> usize {
        match self {
            Primitive::Char | Primitive::U8 | Primitive::I8 => 1,
            Primitive::U16 | Primitive::I16 => 2,
            Primitive::U32 | Primitive::I32 | Primitive::F32 => 4,
            Primitive::U64 | Primitive::I64 | Primitive::F64 => 8,
        }
    }

    /// The variant name of `mavframe::FieldType`.
    pub fn field_type(self) -> &'static str {
        match self {
            Primitive::Char => "Char",
            Primitive::U8 => "U8",
            Primitive::I8 => "I8",
            Primitive::U16 => "U16",
            Primitive::I16 => "I16",
            Primitive::U32 => "U32",
            Primitive::I32 => "I32",
            Primitive::U64 => "U64",
            Primitive::I64 => "I64",
            Primitive::F32 => "F32",
            Primitive::F64 => "F64",
        }
    }

    /// The Rust type (`char` is a byte).
    pub fn rust_name(self) -> &'static str {
        match self {
            Primitive::Char | Primitive::U8 => "u8",
            Primitive::I8 => "i8",
            Primitive::U16 => "u16",
            Primitive::I16 => "i16",
            Primitive::U32 => "u32",
            Primitive::I32 => "i32",
            Primitive::U64 => "u64",
            Primitive::I64 => "i64",
            Primitive::F32 => "f32",
            Primitive::F64 => "f64",
        }
    }

    /// True for the unsigned integers an enum can be carried in.
    pub fn is_unsigned_int(self) -> bool {
        matches!(
            self,
            Primitive::U8 | Primitive::U16 | Primitive::U32 | Primitive::U64
        )
    }
}

/// A `<deprecated>` marker.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Deprecated {
    /// `since` attribute (a date).
    pub since: String,
    /// `replaced_by` attribute.
    pub replaced_by: String,
    /// Explanation text.
    pub text: String,
}

/// One `<field>` of a message.
#[derive(Debug, Clone)]
pub struct Field {
    /// Name as in the XML (hashed into CRC_EXTRA).
    pub name: String,
    /// Element type.
    pub primitive: Primitive,
    /// `Some(n)` for `type[n]`.
    pub array_len: Option<usize>,
    /// `uint8_t_mavlink_version`: filled with the dialect version on send.
    pub mavlink_version: bool,
    /// `enum` attribute.
    pub enum_name: Option<String>,
    /// `display` attribute (`bitmask`).
    pub display: Option<String>,
    /// `units` attribute.
    pub units: Option<String>,
    /// `multiplier` attribute.
    pub multiplier: Option<String>,
    /// `instance` attribute.
    pub instance: bool,
    /// `invalid` attribute: the value that means "not known".
    pub invalid: Option<String>,
    /// `default` attribute.
    pub default: Option<String>,
    /// Description text.
    pub description: String,
    /// Declared after `<extensions/>`.
    pub extension: bool,
    /// Where the field is declared.
    pub loc: Loc,
    /// Where its `enum` attribute is.
    pub enum_loc: Loc,
}

impl Field {
    /// Bytes on the wire.
    pub fn wire_len(&self) -> usize {
        self.primitive.size() * self.array_len.unwrap_or(1)
    }
}

/// One `<message>`.
#[derive(Debug, Clone)]
pub struct Message {
    /// Message id.
    pub id: u64,
    /// Name, e.g. `HEARTBEAT`.
    pub name: String,
    /// Description text.
    pub description: String,
    /// `<deprecated>` marker.
    pub deprecated: Option<Deprecated>,
    /// `<wip/>` marker.
    pub wip: bool,
    /// Fields in XML order.
    pub fields: Vec<Field>,
    /// Where the message is declared.
    pub loc: Loc,
    /// Where its `id` attribute is.
    pub id_loc: Loc,
}

/// A `<param>` of a command enum entry.
#[derive(Debug, Clone, Default)]
pub struct Param {
    /// `index` attribute (1–7).
    pub index: String,
    /// `label` attribute.
    pub label: Option<String>,
    /// `units` attribute.
    pub units: Option<String>,
    /// Description text.
    pub description: String,
}

/// One `<entry>` of an enum.
#[derive(Debug, Clone)]
pub struct Entry {
    /// Name, e.g. `MAV_TYPE_FIXED_WING`.
    pub name: String,
    /// Value (given, or assigned as pymavlink assigns it).
    pub value: u64,
    /// True when the XML gave no value.
    pub autovalue: bool,
    /// Description text.
    pub description: String,
    /// `<deprecated>` marker.
    pub deprecated: Option<Deprecated>,
    /// `<wip/>` marker.
    pub wip: bool,
    /// Command parameters.
    pub params: Vec<Param>,
    /// Where the entry is declared.
    pub loc: Loc,
}

/// One `<enum>` as one file declares it (before merging across includes).
#[derive(Debug, Clone)]
pub struct Enum {
    /// Name, e.g. `MAV_TYPE`.
    pub name: String,
    /// Description text.
    pub description: String,
    /// `bitmask="true"`.
    pub bitmask: bool,
    /// `<deprecated>` marker.
    pub deprecated: Option<Deprecated>,
    /// Entries in XML order.
    pub entries: Vec<Entry>,
    /// Lowest entry value (pymavlink's `start_value`), for merging.
    pub start_value: Option<u64>,
    /// Highest entry value (pymavlink's `highest_value`, starting at 0).
    pub highest_value: u64,
    /// Where the enum is declared.
    pub loc: Loc,
}

/// One `<include>`.
#[derive(Debug, Clone)]
pub struct Include {
    /// The path as written, relative to the including file.
    pub name: String,
    /// Where the include is.
    pub loc: Loc,
}

/// One XML file.
#[derive(Debug, Clone)]
pub struct XmlFile {
    /// Path on disk (canonical).
    pub path: PathBuf,
    /// `<version>`, 2 when absent (as pymavlink).
    pub version: u8,
    /// `<dialect>`.
    pub dialect: Option<u32>,
    /// Includes in order.
    pub includes: Vec<Include>,
    /// Enums in order.
    pub enums: Vec<Enum>,
    /// Messages in order.
    pub messages: Vec<Message>,
}
