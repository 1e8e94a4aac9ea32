//! What every generated message and dialect provides.

use core::fmt;

/// The payload buffer handed to an `emit` was shorter than the message's
/// wire length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BufferTooSmall {
    /// Bytes the message needs.
    pub needed: usize,
    /// Bytes the buffer had.
    pub got: usize,
}

impl fmt::Display for BufferTooSmall {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "payload buffer of {} bytes is too small: the message needs {}",
            self.got, self.needed
        )
    }
}

impl core::error::Error for BufferTooSmall {}

/// The wire type of a field.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FieldType {
    /// `char`: one byte; `char[N]` is a NUL-padded string.
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

impl FieldType {
    /// Bytes of one element on the wire.
    pub const fn size(self) -> usize {
        match self {
            FieldType::Char | FieldType::U8 | FieldType::I8 => 1,
            FieldType::U16 | FieldType::I16 => 2,
            FieldType::U32 | FieldType::I32 | FieldType::F32 => 4,
            FieldType::U64 | FieldType::I64 | FieldType::F64 => 8,
        }
    }

    /// The C name used in MAVLink XML (`uint16_t`, `float`, …).
    pub const fn c_name(self) -> &'static str {
        match self {
            FieldType::Char => "char",
            FieldType::U8 => "uint8_t",
            FieldType::I8 => "int8_t",
            FieldType::U16 => "uint16_t",
            FieldType::I16 => "int16_t",
            FieldType::U32 => "uint32_t",
            FieldType::I32 => "int32_t",
            FieldType::U64 => "uint64_t",
            FieldType::I64 => "int64_t",
            FieldType::F32 => "float",
            FieldType::F64 => "double",
        }
    }
}

/// Where one field sits in a payload: enough to read or write any message
/// generically (JSON tools, routers, fuzzers) without per-message code.
/// Built with [`FieldMeta::new`]: fields may be added.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub struct FieldMeta {
    /// Name as in the XML.
    pub name: &'static str,
    /// Element type.
    pub ty: FieldType,
    /// Elements: 0 for a scalar, `N` for `type[N]`.
    pub array_len: u8,
    /// Payload offset of the first element.
    pub offset: u8,
    /// Declared after `<extensions/>` (not sent in MAVLink 1).
    pub extension: bool,
}

impl FieldMeta {
    /// A field `name` of `array_len` elements (0 for a scalar) of type `ty`
    /// at payload `offset`, declared after `<extensions/>` or not.
    pub const fn new(
        name: &'static str,
        ty: FieldType,
        array_len: u8,
        offset: u8,
        extension: bool,
    ) -> Self {
        FieldMeta {
            name,
            ty,
            array_len,
            offset,
            extension,
        }
    }

    /// Bytes on the wire.
    pub const fn wire_len(&self) -> usize {
        self.ty.size()
            * if self.array_len == 0 {
                1
            } else {
                self.array_len as usize
            }
    }
}

/// Wire facts of one message: one row of a dialect's table (the C library's
/// `mavlink_msg_entry_t`). Built with [`MessageMeta::new`]: fields may be
/// added.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub struct MessageMeta {
    /// Message id (24 bits in MAVLink 2, 8 bits in MAVLink 1).
    pub id: u32,
    /// Name as in the XML, e.g. `"HEARTBEAT"`.
    pub name: &'static str,
    /// Seed mixed into the frame CRC: a hash of the message's name and base
    /// fields, so peers with different definitions reject each other.
    pub crc_extra: u8,
    /// Payload length without extension fields (the MAVLink 1 length).
    pub min_len: u8,
    /// Payload length with all extension fields.
    pub max_len: u8,
    /// Offset of the `target_system` field in the payload, for routing.
    pub target_system_offset: Option<u8>,
    /// Offset of the `target_component` field in the payload, for routing.
    pub target_component_offset: Option<u8>,
    /// The fields in wire order.
    pub fields: &'static [FieldMeta],
}

impl MessageMeta {
    /// The row of message `id` named `name`, with its CRC_EXTRA seed, its
    /// payload lengths without and with extension fields, and its `fields`
    /// in wire order; no target fields (see
    /// [`with_target_offsets`](Self::with_target_offsets)).
    ///
    /// ```
    /// use mavframe::{FieldMeta, FieldType, MessageMeta};
    ///
    /// const PING: MessageMeta = MessageMeta::new(4, "PING", 237, 1, 1, &[
    ///     FieldMeta::new("value", FieldType::U8, 0, 0, false),
    /// ]);
    /// assert_eq!((PING.fields[0].wire_len(), PING.target_system_offset), (1, None));
    /// ```
    pub const fn new(
        id: u32,
        name: &'static str,
        crc_extra: u8,
        min_len: u8,
        max_len: u8,
        fields: &'static [FieldMeta],
    ) -> Self {
        MessageMeta {
            id,
            name,
            crc_extra,
            min_len,
            max_len,
            target_system_offset: None,
            target_component_offset: None,
            fields,
        }
    }

    /// The same row with the payload offsets of its `target_system` and
    /// `target_component` fields.
    pub const fn with_target_offsets(self, system: Option<u8>, component: Option<u8>) -> Self {
        MessageMeta {
            target_system_offset: system,
            target_component_offset: component,
            ..self
        }
    }
}

/// An owned message of a generated dialect.
pub trait MessageData: Sized + Clone + fmt::Debug + PartialEq + Default {
    /// This message's table row.
    const META: MessageMeta;
    /// The zero-copy view over this message's payload bytes.
    type View<'a>: Copy;

    /// Reads a message from a payload of any length: missing bytes of a
    /// truncated payload read as zero, bytes past the wire length are ignored.
    fn parse(payload: &[u8]) -> Self;

    /// Writes all `max_len` payload bytes (extensions included, no
    /// truncation) at the start of `payload`; returns `max_len`.
    fn emit(&self, payload: &mut [u8]) -> Result<usize, BufferTooSmall>;

    /// A view over `payload` (any length).
    fn view(payload: &[u8]) -> Self::View<'_>;
}

/// Anything that can be framed: every generated message, and each dialect's
/// `Message` enum (whose table row is known only at run time), so a message
/// received as the enum can be sent again through the same
/// [`encode`](crate::frame::encode) and `Connection::send` as a single type.
///
/// ```
/// # use mavframe::{Encode, MessageData, MessageMeta, BufferTooSmall};
/// fn describe<M: Encode + ?Sized>(m: &M) -> (&'static str, u8) {
///     (m.meta().name, m.meta().max_len)
/// }
/// # #[derive(Clone, Debug, PartialEq, Default)] struct Ping;
/// # impl MessageData for Ping {
/// #   const META: MessageMeta = MessageMeta::new(4, "PING", 237, 0, 0, &[]);
/// #   type View<'a> = ();
/// #   fn parse(_: &[u8]) -> Self { Ping }
/// #   fn emit(&self, _: &mut [u8]) -> Result<usize, BufferTooSmall> { Ok(0) }
/// #   fn view(_: &[u8]) {}
/// # }
/// assert_eq!(describe(&Ping), ("PING", 0));
/// ```
pub trait Encode {
    /// The message's table row.
    fn meta(&self) -> &'static MessageMeta;

    /// Writes all `max_len` payload bytes (extensions included, no
    /// truncation) at the start of `payload`; returns `max_len`.
    fn emit_payload(&self, payload: &mut [u8]) -> Result<usize, BufferTooSmall>;
}

impl<M: MessageData> Encode for M {
    #[inline]
    fn meta(&self) -> &'static MessageMeta {
        const { &M::META }
    }

    #[inline]
    fn emit_payload(&self, payload: &mut [u8]) -> Result<usize, BufferTooSmall> {
        self.emit(payload)
    }
}

/// A generated dialect: the set of messages a link understands.
pub trait MessageSet {
    /// The owned message enum.
    type Message: Clone + fmt::Debug + PartialEq;
    /// The borrowed view enum.
    type View<'a>: Copy;

    /// Every message of the dialect, sorted by id.
    const MESSAGES: &'static [MessageMeta];

    /// The largest id [`meta`](Self::meta) knows: an id above it is
    /// unknown without a look-up (the parser rejects most ids of garbage,
    /// three bytes at random, so). By default the last of
    /// [`MESSAGES`](Self::MESSAGES); a dialect whose `meta` knows ids
    /// beyond those sets it.
    const MAX_ID: u32 = match Self::MESSAGES.last() {
        Some(m) => m.id,
        None => 0,
    };

    /// Table row for `id`, if the dialect knows it.
    fn meta(id: u32) -> Option<&'static MessageMeta> {
        Self::MESSAGES
            .binary_search_by_key(&id, |m| m.id)
            .ok()
            .map(|i| &Self::MESSAGES[i])
    }

    /// Parses a payload into an owned message; `None` for an unknown id.
    fn parse(id: u32, payload: &[u8]) -> Option<Self::Message>;

    /// A view over a payload; `None` for an unknown id.
    fn view(id: u32, payload: &[u8]) -> Option<Self::View<'_>>;
}
