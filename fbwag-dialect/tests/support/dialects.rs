//! Made-up dialects for the parser tests: every id known (every candidate
//! costs a checksum); a few ids known, made of start bytes and small
//! numbers (most candidates are raw); the same without id 0.
#![allow(dead_code)]

use fbwag_dialect::mavframe::{MessageMeta, MessageSet};

pub fn row(id: u32, crc_extra: u8) -> MessageMeta {
    MessageMeta::new(id, "X", crc_extra, 1, 255, &[])
}

/// Every id known (CRC_EXTRA from the id's low byte): every candidate costs
/// a checksum.
pub struct AllKnown;
pub static ALL_ROWS: [MessageMeta; 256] = {
    let mut t = [MessageMeta::new(0, "X", 0, 1, 255, &[]); 256];
    let mut i = 0;
    while i < 256 {
        t[i].id = i as u32;
        t[i].crc_extra = (i as u8) ^ 0x5A;
        i += 1;
    }
    t
};
impl MessageSet for AllKnown {
    type Message = ();
    type View<'a> = ();
    const MESSAGES: &'static [MessageMeta] = &[];
    const MAX_ID: u32 = u32::MAX;
    fn meta(id: u32) -> Option<&'static MessageMeta> {
        Some(&ALL_ROWS[(id & 0xFF) as usize])
    }
    fn parse(_: u32, _: &[u8]) -> Option<()> {
        None
    }
    fn view(_: u32, _: &[u8]) -> Option<()> {
        None
    }
}

/// A few ids known, made of start bytes and small numbers: most candidates
/// are raw.
pub struct Few;
pub static FEW_IDS: [u32; 7] = [0, 1, 2, 0xFD, 0xFE, 0xFD_FD, 0x01_FE_FD];
pub static FEW_ROWS: [MessageMeta; 7] = {
    let mut t = [MessageMeta::new(0, "X", 0, 1, 255, &[]); 7];
    let mut i = 0;
    while i < 7 {
        t[i].id = FEW_IDS[i];
        t[i].crc_extra = 7 * i as u8 + 1;
        i += 1;
    }
    t
};
impl MessageSet for Few {
    type Message = ();
    type View<'a> = ();
    const MESSAGES: &'static [MessageMeta] = &FEW_ROWS;
    fn parse(_: u32, _: &[u8]) -> Option<()> {
        None
    }
    fn view(_: u32, _: &[u8]) -> Option<()> {
        None
    }
}

/// [`Few`] without id 0 (every real dialect has HEARTBEAT = 0).
pub struct NoZero;
impl MessageSet for NoZero {
    type Message = ();
    type View<'a> = ();
    const MESSAGES: &'static [MessageMeta] = &FEW_ROWS;
    fn meta(id: u32) -> Option<&'static MessageMeta> {
        FEW_ROWS[1..].iter().find(|m| m.id == id)
    }
    fn parse(_: u32, _: &[u8]) -> Option<()> {
        None
    }
    fn view(_: u32, _: &[u8]) -> Option<()> {
        None
    }
}
