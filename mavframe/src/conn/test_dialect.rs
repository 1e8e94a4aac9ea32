//! A two-message dialect written by hand, for tests that cannot use a
//! generated one (mavframe sits below the generator's output).

use crate::field::Scalar;
use crate::message::{BufferTooSmall, FieldMeta, FieldType, MessageData, MessageMeta, MessageSet};

/// Id 1, one `uint32_t`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Ping {
    pub value: u32,
}

/// Id 300 (too large for MAVLink 1), one `uint8_t`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Big {
    pub value: u8,
}

const PING_FIELDS: &[FieldMeta] = &[FieldMeta::new("value", FieldType::U32, 0, 0, false)];

const BIG_FIELDS: &[FieldMeta] = &[FieldMeta::new("value", FieldType::U8, 0, 0, false)];

impl MessageData for Ping {
    const META: MessageMeta = MessageMeta::new(1, "PING_TEST", 42, 4, 4, PING_FIELDS);
    type View<'a> = &'a [u8];

    fn parse(payload: &[u8]) -> Self {
        Ping {
            value: u32::read(payload, 0),
        }
    }

    fn emit(&self, payload: &mut [u8]) -> Result<usize, BufferTooSmall> {
        let got = payload.len();
        let out = payload
            .get_mut(..4)
            .ok_or(BufferTooSmall { needed: 4, got })?;
        out.copy_from_slice(&self.value.to_le_bytes());
        Ok(4)
    }

    fn view(payload: &[u8]) -> &[u8] {
        payload
    }
}

impl MessageData for Big {
    const META: MessageMeta = MessageMeta::new(300, "BIG_TEST", 7, 1, 1, BIG_FIELDS);
    type View<'a> = &'a [u8];

    fn parse(payload: &[u8]) -> Self {
        Big {
            value: payload.first().copied().unwrap_or(0),
        }
    }

    fn emit(&self, payload: &mut [u8]) -> Result<usize, BufferTooSmall> {
        let got = payload.len();
        *payload
            .first_mut()
            .ok_or(BufferTooSmall { needed: 1, got })? = self.value;
        Ok(1)
    }

    fn view(payload: &[u8]) -> &[u8] {
        payload
    }
}

/// The dialect of [`Ping`] and [`Big`].
pub struct TestDialect;

impl MessageSet for TestDialect {
    type Message = Ping;
    type View<'a> = &'a [u8];
    const MESSAGES: &'static [MessageMeta] = &[Ping::META, Big::META];

    fn parse(id: u32, payload: &[u8]) -> Option<Ping> {
        (id == 1).then(|| Ping::parse(payload))
    }

    fn view(id: u32, payload: &[u8]) -> Option<&[u8]> {
        matches!(id, 1 | 300).then_some(payload)
    }
}
