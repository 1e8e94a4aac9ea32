//! What a loaded [`Schema`] shows its users: read-only views of messages,
//! fields, enums and entries after includes, enum merging and layout, so
//! tools (CRC_EXTRA tables, documentation, checks) need not generate code.
//! The parsed model behind them stays private and free to change.

use crate::diag::Diagnostic;
use crate::layout::Layout;
use crate::model::{Entry, Field, Message};
use crate::schema::{MergedEnum, Schema};

impl Schema {
    /// Every message of every file (roots and includes), in load order:
    /// the roots first, then includes breadth first, each file's messages
    /// in XML order.
    pub fn messages(&self) -> impl Iterator<Item = MessageDef<'_>> + '_ {
        self.message_refs().map(|r| MessageDef {
            message: self.message(r),
            layout: self.layout(r),
        })
    }

    /// Every enum after merging its declarations across files, by name.
    pub fn enums(&self) -> impl Iterator<Item = EnumDef<'_>> + '_ {
        self.enums.values().map(|merged| EnumDef { merged })
    }

    /// Warnings found while loading (the input is valid nonetheless).
    pub fn warnings(&self) -> &[Diagnostic] {
        &self.warnings
    }
}

/// A message of a [`Schema`], with its wire layout.
#[derive(Debug, Clone, Copy)]
pub struct MessageDef<'a> {
    message: &'a Message,
    layout: &'a Layout,
}

impl<'a> MessageDef<'a> {
    /// The message id (at most 2^24 - 1: a loaded schema is checked).
    pub fn id(&self) -> u32 {
        // Ids above 0xFF_FFFF are rejected by `Schema::load`.
        self.message.id as u32
    }

    /// The XML name, e.g. `HEARTBEAT`.
    pub fn name(&self) -> &'a str {
        &self.message.name
    }

    /// The description text.
    pub fn description(&self) -> &'a str {
        &self.message.description
    }

    /// The CRC_EXTRA byte, as pymavlink computes it.
    pub fn crc_extra(&self) -> u8 {
        self.layout.crc_extra
    }

    /// Payload length without extension fields (the MAVLink 1 length).
    pub fn min_len(&self) -> usize {
        self.layout.min_len
    }

    /// Payload length with every extension field.
    pub fn max_len(&self) -> usize {
        self.layout.max_len
    }

    /// The fields in XML order (not wire order: see [`FieldDef::offset`]).
    pub fn fields(&self) -> impl Iterator<Item = FieldDef<'a>> + 'a {
        let layout = self.layout;
        self.message
            .fields
            .iter()
            .zip(&layout.offsets)
            .map(|(field, &offset)| FieldDef { field, offset })
    }
}

/// A field of a [`MessageDef`].
#[derive(Debug, Clone, Copy)]
pub struct FieldDef<'a> {
    field: &'a Field,
    offset: usize,
}

impl<'a> FieldDef<'a> {
    /// The XML name.
    pub fn name(&self) -> &'a str {
        &self.field.name
    }

    /// The element type's C name, e.g. `uint16_t`, `char`, `float`.
    pub fn c_type(&self) -> &'static str {
        self.field.primitive.c_name()
    }

    /// `Some(n)` for an array `type[n]`.
    pub fn array_len(&self) -> Option<usize> {
        self.field.array_len
    }

    /// Byte offset in the payload.
    pub fn offset(&self) -> usize {
        self.offset
    }

    /// Bytes on the wire.
    pub fn wire_len(&self) -> usize {
        self.field.wire_len()
    }

    /// Declared after `<extensions/>` (absent from MAVLink 1 frames).
    pub fn is_extension(&self) -> bool {
        self.field.extension
    }

    /// The `enum` attribute: the enum the value belongs to.
    pub fn enum_name(&self) -> Option<&'a str> {
        self.field.enum_name.as_deref()
    }

    /// The `units` attribute.
    pub fn units(&self) -> Option<&'a str> {
        self.field.units.as_deref()
    }

    /// The description text.
    pub fn description(&self) -> &'a str {
        &self.field.description
    }
}

/// An enum of a [`Schema`], merged across the files declaring it.
#[derive(Debug, Clone, Copy)]
pub struct EnumDef<'a> {
    merged: &'a MergedEnum,
}

impl<'a> EnumDef<'a> {
    /// The XML name, e.g. `MAV_TYPE`.
    pub fn name(&self) -> &'a str {
        &self.merged.def.name
    }

    /// The description text (the first non-empty one of the declarations).
    pub fn description(&self) -> &'a str {
        &self.merged.def.description
    }

    /// `bitmask="true"` in any declaration.
    pub fn is_bitmask(&self) -> bool {
        self.merged.def.bitmask
    }

    /// The entries, sorted by value as pymavlink sorts them; values are
    /// those pymavlink assigns (auto-numbered entries included).
    pub fn entries(&self) -> impl Iterator<Item = EntryDef<'a>> + 'a {
        self.merged
            .def
            .entries
            .iter()
            .map(|entry| EntryDef { entry })
    }
}

/// An entry of an [`EnumDef`].
#[derive(Debug, Clone, Copy)]
pub struct EntryDef<'a> {
    entry: &'a Entry,
}

impl<'a> EntryDef<'a> {
    /// The XML name, e.g. `MAV_TYPE_FIXED_WING`.
    pub fn name(&self) -> &'a str {
        &self.entry.name
    }

    /// The value.
    pub fn value(&self) -> u64 {
        self.entry.value
    }

    /// The description text.
    pub fn description(&self) -> &'a str {
        &self.entry.description
    }
}
