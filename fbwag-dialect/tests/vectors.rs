//! The reference frames pymavlink 2.4.50 and the C library agree on, encoded
//! and decoded by the runtime.
// Uses messages outside the companion-computer subset.

use fbwag_dialect::dialects::minimal::{Heartbeat, MavAutopilot, MavModeFlag, MavState, MavType};
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::mavframe::frame::{encode, Frame, Header, Version};
use fbwag_dialect::mavframe::{MessageSet as _, Signer, Verifier};
use fbwag_dialect::{Dialect, FbwagFailsafeStatus, FbwagNotice};

fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

const H: Header = Header {
    seq: 0,
    sysid: 1,
    compid: 1,
};
const KEY: [u8; 32] = {
    let mut k = [0u8; 32];
    let mut i = 0;
    while i < 32 {
        k[i] = i as u8;
        i += 1;
    }
    k
};

fn notice(system_id: u8, component_id: u8, status: u8, text: &str, timestamp: u32) -> FbwagNotice {
    FbwagNotice {
        system_id,
        component_id,
        failsafe_status: FbwagFailsafeStatus(status),
        text: chars(text),
        timestamp,
    }
}

fn heartbeat() -> Heartbeat {
    Heartbeat {
        r#type: MavType::GCS,
        autopilot: MavAutopilot::INVALID,
        base_mode: MavModeFlag::empty(),
        custom_mode: 0,
        system_status: MavState::UNINIT,
        mavlink_version: 3,
    }
}

fn encoded<M: fbwag_dialect::mavframe::MessageData>(
    v: Version,
    m: &M,
    signer: Option<&mut Signer>,
) -> Vec<u8> {
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    let n = encode(v, H, m, signer, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn decode(bytes: &[u8]) -> (Frame<&[u8]>, fbwag_dialect::Message) {
    let frame = Frame::new_checked(bytes).unwrap();
    assert_eq!(frame.as_bytes().len(), bytes.len());
    let meta = Dialect::meta(frame.msg_id()).unwrap();
    assert!(frame.check_crc(meta.crc_extra), "CRC");
    let msg = Dialect::parse(frame.msg_id(), frame.payload()).unwrap();
    (frame, msg)
}

#[test]
fn fbwag_notice_unsigned() {
    let bytes = hex("fd0c0000000101993a0040e201000101014642574147d933");
    let m = notice(1, 1, 1, "FBWAG", 123_456);
    assert_eq!(encoded(Version::V2, &m, None), bytes);
    let (frame, msg) = decode(&bytes);
    assert_eq!(
        (frame.msg_id(), frame.header(), frame.is_signed()),
        (15001, H, false)
    );
    assert_eq!(msg, m.into());
}

#[test]
fn fbwag_notice_signed() {
    let bytes = hex("fd0c0100000101993a0040e201000101014642574147b50400e803000000002e8ccc077218");
    let m = notice(1, 1, 1, "FBWAG", 123_456);
    let mut signer = Signer::new(KEY, 0, 1000);
    assert_eq!(encoded(Version::V2, &m, Some(&mut signer)), bytes);
    assert_eq!(
        signer.timestamp(),
        1001,
        "each signed frame advances the timestamp"
    );
    let (frame, msg) = decode(&bytes);
    let sig = frame.signature().unwrap();
    assert_eq!((sig.link_id(), sig.timestamp()), (0, 1000));
    assert_eq!(msg, m.into());
    let mut v: Verifier = Verifier::new(KEY);
    assert_eq!(v.verify(&frame), Ok(()));
    assert_eq!(
        v.verify(&frame),
        Err(fbwag_dialect::mavframe::signing::SignatureError::Replay)
    );
    let mut wrong: Verifier = Verifier::new([7; 32]);
    assert_eq!(
        wrong.verify(&frame),
        Err(fbwag_dialect::mavframe::signing::SignatureError::Mismatch)
    );
}

#[test]
fn fbwag_notice_truncated_to_last_nonzero_byte() {
    let bytes = hex("fd050000000101993a0000000000015ff8");
    let m = notice(1, 0, 0, "", 0);
    assert_eq!(encoded(Version::V2, &m, None), bytes);
    let (frame, msg) = decode(&bytes);
    assert_eq!(frame.payload_len(), 5);
    assert_eq!(msg, m.into());
}

#[test]
fn all_zero_payload_keeps_one_byte() {
    let out = encoded(Version::V2, &notice(0, 0, 0, "", 0), None);
    assert_eq!(out[1], 1, "payload length");
    assert_eq!(decode(&out).1, notice(0, 0, 0, "", 0).into());
}

#[test]
fn heartbeat_v2_and_v1() {
    let v2 = hex("fd0900000001010000000000000006080000036be3");
    let v1 = hex("fe0900010100000000000608000003f120");
    assert_eq!(encoded(Version::V2, &heartbeat(), None), v2);
    assert_eq!(encoded(Version::V1, &heartbeat(), None), v1);
    assert_eq!(decode(&v2).1, heartbeat().into());
    let (frame, msg) = decode(&v1);
    assert_eq!((frame.version(), frame.header()), (Version::V1, H));
    assert_eq!(msg, heartbeat().into());
}

#[test]
fn v1_rejects_large_ids_and_drops_extensions() {
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    let err = encode(Version::V1, H, &notice(1, 1, 1, "FBWAG", 1), None, &mut buf);
    assert_eq!(
        err,
        Err(fbwag_dialect::mavframe::FrameError::IdTooLargeForV1(15001))
    );
    // RC_CHANNELS_OVERRIDE has extensions (chan9..18): MAVLink 1 sends 18 bytes.
    let m = fbwag_dialect::dialects::common::RcChannelsOverride {
        chan1_raw: 1500,
        chan18_raw: 2000,
        ..Default::default()
    };
    let n = encode(Version::V1, H, &m, None, &mut buf).unwrap();
    assert_eq!((n, buf[1]), (6 + 18 + 2, 18));
    let (_, decoded) = decode(&buf[..n]);
    let fbwag_dialect::Message::RcChannelsOverride(d) = decoded else {
        panic!()
    };
    assert_eq!((d.chan1_raw, d.chan18_raw), (1500, 0));
}

#[test]
fn small_output_buffers_are_errors_not_panics() {
    for len in 0..40 {
        let mut buf = vec![0u8; len];
        let r = encode(
            Version::V2,
            H,
            &notice(1, 1, 1, "FBWAG", 123_456),
            None,
            &mut buf,
        );
        assert_eq!(r.is_ok(), len >= 24, "buffer of {len}");
    }
}
