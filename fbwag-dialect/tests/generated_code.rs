//! Behaviour of the code mavgen-rs generates, on the real FBWAG dialect.
// Uses messages outside the companion-computer subset.

use fbwag_dialect::dialects::{common, minimal};
use fbwag_dialect::mavframe::{field::chars, MessageSet as _};
use fbwag_dialect::{
    Dialect, FbwagFailsafeStatus, FbwagNotice, FbwagNoticeMut, FbwagNoticeView, Message,
    MessageView, MESSAGES,
};

/// Payload of the reference frame
/// `fd0c0000000101993a0040e201000101014642574147d933` (pymavlink 2.4.50).
const NOTICE_PAYLOAD: [u8; 12] = [
    0x40, 0xe2, 0x01, 0x00, 0x01, 0x01, 0x01, 0x46, 0x42, 0x57, 0x41, 0x47,
];

fn notice() -> FbwagNotice {
    FbwagNotice {
        system_id: 1,
        component_id: 1,
        failsafe_status: FbwagFailsafeStatus::RC_LOST,
        text: chars("FBWAG"),
        timestamp: 123_456,
    }
}

#[test]
fn fbwag_notice_constants_match_pymavlink() {
    assert_eq!((FbwagNotice::ID, FbwagNotice::CRC_EXTRA), (15001, 30));
    assert_eq!((FbwagNotice::MIN_LEN, FbwagNotice::MAX_LEN), (12, 12));
    assert_eq!(FbwagNotice::NAME, "FBWAG_NOTICE");
    let hb = minimal::Heartbeat::META;
    assert_eq!((hb.id, hb.crc_extra, hb.min_len, hb.max_len), (0, 50, 9, 9));
}

#[test]
fn fbwag_notice_emits_the_reference_payload() {
    let mut buf = [0xaa; 20];
    assert_eq!(notice().emit(&mut buf), Ok(12));
    assert_eq!(buf[..12], NOTICE_PAYLOAD);
    assert_eq!(buf[12], 0xaa, "emit writes exactly MAX_LEN bytes");
    let mut short = [0u8; 11];
    assert!(notice().emit(&mut short).is_err());
}

#[test]
fn view_reads_fields_in_place_and_parse_round_trips() {
    let v = FbwagNoticeView::new(&NOTICE_PAYLOAD);
    assert_eq!(v.timestamp(), 123_456);
    assert_eq!(v.failsafe_status(), FbwagFailsafeStatus::RC_LOST);
    assert_eq!(v.text().as_bytes(), b"FBWAG");
    assert!(
        core::ptr::eq(v.text().as_bytes().as_ptr(), &NOTICE_PAYLOAD[7]),
        "char array is borrowed from the payload"
    );
    assert_eq!(FbwagNotice::parse(&NOTICE_PAYLOAD), notice());
    assert_eq!(v.to_message(), notice());
}

#[test]
fn truncated_payloads_read_as_zero_filled() {
    // MAVLink 2 drops trailing zeros: (1, 0, 0, "", 0) travels as 5 bytes.
    let sent = FbwagNotice {
        system_id: 1,
        ..FbwagNotice::default()
    };
    let mut full = [0u8; 12];
    sent.emit(&mut full).unwrap();
    assert_eq!(full, [0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0]);
    assert_eq!(FbwagNotice::parse(&full[..5]), sent);
    // Every prefix parses without panicking and agrees with the zero-filled full payload.
    for n in 0..=12 {
        let mut padded = [0u8; 12];
        padded[..n].copy_from_slice(&NOTICE_PAYLOAD[..n]);
        assert_eq!(
            FbwagNotice::parse(&NOTICE_PAYLOAD[..n]),
            FbwagNotice::parse(&padded)
        );
    }
}

#[test]
fn unknown_enum_values_and_flag_bits_are_kept() {
    let mut p = NOTICE_PAYLOAD;
    p[6] = 7;
    let n = FbwagNotice::parse(&p);
    assert_eq!(n.failsafe_status, FbwagFailsafeStatus(7));
    let mut out = [0u8; 12];
    n.emit(&mut out).unwrap();
    assert_eq!(out, p, "an unlisted value survives a round trip");

    // HEARTBEAT.base_mode is a MAV_MODE_FLAG bitmask; bit values the XML
    // does not define must survive too.
    let hb = minimal::Heartbeat {
        base_mode: minimal::MavModeFlag::from_bits_retain(0xff),
        ..Default::default()
    };
    let mut buf = [0u8; 9];
    hb.emit(&mut buf).unwrap();
    assert_eq!(minimal::Heartbeat::parse(&buf).base_mode.bits(), 0xff);
    assert!(minimal::Heartbeat::parse(&buf)
        .base_mode
        .contains(minimal::MavModeFlag::SAFETY_ARMED));
}

#[test]
fn mavlink_version_defaults_to_the_dialect_version() {
    // minimal.xml declares <version>3</version>; pymavlink fills it in.
    assert_eq!(minimal::Heartbeat::default().mavlink_version, 3);
}

#[test]
fn writer_sets_fields_in_place() {
    let mut buf = [0u8; 12];
    let mut w = FbwagNoticeMut::new(&mut buf).unwrap();
    w.set_timestamp(123_456);
    w.set_system_id(1);
    w.set_component_id(1);
    w.set_failsafe_status(FbwagFailsafeStatus::RC_LOST);
    w.set_text(&chars("FBWAG"));
    assert_eq!(w.view().timestamp(), 123_456);
    assert_eq!(buf, NOTICE_PAYLOAD);
    assert!(FbwagNoticeMut::new(&mut [0u8; 4]).is_err());
}

#[test]
fn dialect_table_is_sorted_complete_and_looked_up_by_id() {
    assert_eq!(
        MESSAGES.len(),
        302,
        "ardupilotmega (301, pymavlink 2.4.50) + FBWAG_NOTICE"
    );
    assert!(MESSAGES.windows(2).all(|w| w[0].id < w[1].id));
    assert_eq!(Dialect::meta(15001).map(|m| m.crc_extra), Some(30));
    assert_eq!(Dialect::meta(0).map(|m| m.name), Some("HEARTBEAT"));
    assert!(Dialect::meta(14999).is_none());
    let cmd = Dialect::meta(common::CommandLong::ID).unwrap();
    assert_eq!(
        (cmd.target_system_offset, cmd.target_component_offset),
        (Some(30), Some(31))
    );
}

#[test]
fn message_enum_parses_views_and_emits_by_id() {
    let m = Message::parse(15001, &NOTICE_PAYLOAD).unwrap();
    assert_eq!(m, Message::from(notice()));
    assert_eq!((m.id(), m.name()), (15001, "FBWAG_NOTICE"));
    let mut buf = [0u8; 255];
    assert_eq!(m.emit(&mut buf), Ok(12));
    assert_eq!(buf[..12], NOTICE_PAYLOAD);
    assert!(
        Message::parse(14999, &NOTICE_PAYLOAD).is_none(),
        "unknown ids are not errors, just unknown"
    );
    match MessageView::new(15001, &NOTICE_PAYLOAD) {
        Some(MessageView::FbwagNotice(v)) => assert_eq!(v.timestamp(), 123_456),
        other => panic!("wrong view: {other:?}"),
    }
    assert_eq!(Dialect::parse(15001, &NOTICE_PAYLOAD), Some(m));
}

#[test]
fn merged_enums_hold_entries_of_every_file() {
    // MAV_CMD lives in common's module but carries ardupilotmega's entries
    // merged into it (42428 = MAV_CMD_DO_SEND_BANNER in ardupilotmega.xml).
    assert_eq!(
        common::MavCmd::from_raw(42428).name(),
        Some("MAV_CMD_DO_SEND_BANNER")
    );
    assert_eq!(common::MavCmd::from_raw(16), common::MavCmd::NAV_WAYPOINT);
    assert_eq!(common::MavCmd::from_raw(65000), common::MavCmd(65000));
}

#[test]
fn arrays_are_views_with_zero_fill() {
    // RC_CHANNELS_OVERRIDE is what the companion computer streams.
    let m = common::RcChannelsOverride {
        target_system: 1,
        target_component: 1,
        chan1_raw: 1500,
        chan18_raw: 7,
        ..Default::default()
    };
    let mut buf = [0u8; 38];
    assert_eq!(m.emit(&mut buf), Ok(38));
    assert_eq!(common::RcChannelsOverride::parse(&buf), m);
    // Extension fields (chan9..chan18) read as 0 from a MAVLink 1 length payload.
    let v1 = common::RcChannelsOverride::parse(&buf[..18]);
    assert_eq!((v1.chan1_raw, v1.chan18_raw), (1500, 0));

    let t = common::Tunnel::parse(&[1, 0, 2, 0, 3, 9, 8]);
    let view = common::TunnelView::new(&[1, 0, 2, 0, 3, 9, 8]);
    assert_eq!(view.payload().get(1), Some(8));
    assert_eq!(view.payload().get(2), Some(0));
    assert_eq!(t.payload[..3], [9, 8, 0]);
}

/// The dialect's `Message` enum frames through the same `encode` as the
/// single type it holds, byte for byte (a received message can be re-sent).
#[test]
fn message_enum_encodes_like_the_message_it_holds() {
    use fbwag_dialect::mavframe::Encode;
    use fbwag_dialect::{encode, FbwagFailsafeStatus, FbwagNotice, Header, Message, Version};
    let notice = FbwagNotice {
        system_id: 1,
        component_id: 1,
        failsafe_status: FbwagFailsafeStatus::RC_LOST,
        text: fbwag_dialect::mavframe::field::chars("FBWAG"),
        timestamp: 4242,
    };
    let as_enum = Message::from(notice);
    assert_eq!(Encode::meta(&as_enum).name, "FBWAG_NOTICE");
    let h = Header {
        seq: 7,
        sysid: 1,
        compid: 191,
    };
    let (mut a, mut b) = (
        [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN],
        [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN],
    );
    let na = encode(Version::V2, h, &notice, None, &mut a).unwrap();
    let nb = encode(Version::V2, h, &as_enum, None, &mut b).unwrap();
    assert_eq!(a[..na], b[..nb]);
    // As a trait object too: a router holds messages of any type.
    let dynamic: &dyn Encode = &as_enum;
    let nc = encode(Version::V1, h, dynamic, None, &mut b);
    assert!(nc.is_err(), "id 15001 does not fit MAVLink 1");
}
