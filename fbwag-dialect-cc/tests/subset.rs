//! The companion-computer subset: only its messages are generated, and
//! frames of the others are still parsed, as raw frames.

use fbwag_dialect_cc::mavframe::frame::{encode, Header, Version};
use fbwag_dialect_cc::mavframe::parser::Parser;
use fbwag_dialect_cc::{Dialect, FbwagFailsafeStatus, FbwagNotice, MESSAGES};

#[test]
fn only_the_cc_messages_are_generated() {
    let names: Vec<&str> = MESSAGES.iter().map(|m| m.name).collect();
    let listed = include_str!("../messages.txt")
        .lines()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .filter(|l| !l.is_empty())
        .count();
    assert_eq!(names.len(), listed, "{names:?}");
    for n in [
        "HEARTBEAT",
        "FBWAG_NOTICE",
        "RC_CHANNELS_OVERRIDE",
        "SET_ATTITUDE_TARGET",
        "MANUAL_CONTROL",
        "STATUSTEXT",
    ] {
        assert!(names.contains(&n), "{n} missing");
    }
    assert!(!names.contains(&"SCALED_IMU"));
}

#[test]
fn other_messages_still_parse_as_raw_frames() {
    let notice = FbwagNotice {
        failsafe_status: FbwagFailsafeStatus::RC_LOST,
        ..Default::default()
    };
    let mut a = [0u8; fbwag_dialect_cc::mavframe::frame::MAX_FRAME_LEN];
    let n = encode(Version::V2, Header::default(), &notice, None, &mut a).unwrap();
    // SCALED_PRESSURE (id 29), not in the subset: 14 payload bytes, any CRC.
    let mut raw = vec![0xFD, 14, 0, 0, 0, 1, 1, 29, 0, 0];
    raw.extend_from_slice(&[7u8; 14]);
    raw.extend_from_slice(&[0x12, 0x34]);
    let stream = [&raw[..], &a[..n], &raw[..]].concat();
    let mut p = Parser::<Dialect>::new();
    let mut input: &[u8] = &stream;
    let mut names = Vec::new();
    while let Some(r) = p.next(&mut input) {
        names.push(r.meta().map(|m| m.name));
    }
    while let Some(r) = p.flush() {
        names.push(r.meta().map(|m| m.name));
    }
    assert_eq!(names, vec![None, Some("FBWAG_NOTICE"), None]);
}
