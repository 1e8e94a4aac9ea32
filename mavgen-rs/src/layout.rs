//! Wire layout and CRC_EXTRA of a message, by pymavlink's rules.
//!
//! Base fields are sorted by element size, largest first (a stable sort, so
//! equal sizes keep XML order); extension fields follow in XML order. The
//! CRC_EXTRA seed hashes the name and the base fields in wire order, so it
//! changes whenever a peer would decode the payload differently.

use crate::model::Message;
use crc_any::CRCu16;
use std::cmp::Reverse;

/// Where each field of a message sits in the payload.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Layout {
    /// Field indices (XML order) in wire order.
    pub order: Vec<usize>,
    /// Payload offset of each field, indexed by XML order.
    pub offsets: Vec<usize>,
    /// Length of the base fields (no extensions): the MAVLink 1 length.
    pub min_len: usize,
    /// Length with every extension field.
    pub max_len: usize,
    /// The CRC_EXTRA seed.
    pub crc_extra: u8,
    /// Offset of `target_system` (or MANUAL_CONTROL's `target`), for routing.
    pub target_system: Option<usize>,
    /// Offset of `target_component`, for routing.
    pub target_component: Option<usize>,
}

impl Layout {
    /// Computes the layout of `msg`.
    pub fn of(msg: &Message) -> Layout {
        let base: Vec<usize> = (0..msg.fields.len())
            .filter(|&i| !msg.fields[i].extension)
            .collect();
        let mut order = base.clone();
        order.sort_by_key(|&i| Reverse(msg.fields[i].primitive.size()));
        order.extend((0..msg.fields.len()).filter(|&i| msg.fields[i].extension));

        let mut offsets = vec![0; msg.fields.len()];
        let mut at = 0;
        let (mut target_system, mut target_component) = (None, None);
        for &i in &order {
            let f = &msg.fields[i];
            offsets[i] = at;
            if f.name == "target_system" || (msg.name == "MANUAL_CONTROL" && f.name == "target") {
                target_system = Some(at);
            } else if f.name == "target_component" {
                target_component = Some(at);
            }
            at += f.wire_len();
        }
        let min_len = base.iter().map(|&i| msg.fields[i].wire_len()).sum();

        let mut crc = CRCu16::crc16mcrf4cc();
        crc.digest(msg.name.as_bytes());
        crc.digest(b" ");
        for &i in &order[..base.len()] {
            let f = &msg.fields[i];
            crc.digest(f.primitive.c_name().as_bytes());
            crc.digest(b" ");
            crc.digest(f.name.as_bytes());
            crc.digest(b" ");
            if let Some(n) = f.array_len {
                // The length is hashed as one byte (arrays are at most 255).
                crc.digest(&[n as u8]);
            }
        }
        let crc = crc.get_crc();
        Layout {
            order,
            offsets,
            min_len,
            max_len: at,
            crc_extra: (crc & 0xff) as u8 ^ (crc >> 8) as u8,
            target_system,
            target_component,
        }
    }
}
