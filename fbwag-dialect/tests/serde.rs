//! serde on the generated dialect (feature `serde`): EVERY message of
//! fbwag.xml, with random values (all float bit patterns that matter, char
//! arrays with bytes after a NUL and text that is not UTF-8, enum values the
//! XML does not list), survives JSON (human-readable forms) and postcard
//! (compact forms) byte for byte; and the forms themselves, one test each.
//! Set `FBWAG_SERDE_SEED` to try other values (the seed is printed).
#![cfg(feature = "serde")]

use fbwag_dialect::dialects::common::{
    GimbalDeviceCapFlags, GimbalDeviceInformation, GimbalManagerInformation, LogData,
};
use fbwag_dialect::dialects::minimal::{Heartbeat, MavAutopilot, MavModeFlag, MavState, MavType};
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::mavframe::{FieldType, MessageMeta};
use fbwag_dialect::{FbwagFailsafeStatus, FbwagNotice, Message, MESSAGES};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde_json::{json, Value};

/// Random payloads per message.
const PER_MESSAGE: usize = 40;

fn seed() -> u64 {
    let seed = std::env::var("FBWAG_SERDE_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(20_251_123);
    println!("FBWAG_SERDE_SEED={seed}");
    seed
}

/// A float bit pattern: mostly the hard cases (NaNs with payloads and
/// either sign, infinities, signed zeros, subnormals, extremes), sometimes
/// anything.
fn float_bits(rng: &mut Pcg64, exp_bits: u32, mantissa_bits: u32) -> u64 {
    let width = 1 + exp_bits + mantissa_bits;
    let sign = if rng.gen() { 1u64 << (width - 1) } else { 0 };
    let exp_all = ((1u64 << exp_bits) - 1) << mantissa_bits;
    let quiet = 1u64 << (mantissa_bits - 1);
    let mantissa = rng.gen::<u64>() & ((1u64 << mantissa_bits) - 1);
    let max_finite = exp_all - 1;
    sign | match rng.gen_range(0..9) {
        0 => exp_all | quiet,
        1 => exp_all | mantissa.max(1),
        2 => exp_all | quiet | mantissa,
        3 => 0,
        4 => exp_all,
        5 => mantissa.max(1),
        6 => [1, quiet * 2 - 1, quiet * 2, max_finite][rng.gen_range(0..4)],
        _ => rng.gen::<u64>() & ((1u64 << (width - 1)) - 1),
    }
}

/// A char array: text then NULs, bytes after a NUL, no NUL, not UTF-8
/// (a lone byte ≥ 0x80, or a cut multi-byte sequence), or random bytes.
fn char_bytes(rng: &mut Pcg64, dst: &mut [u8]) {
    let n = dst.len();
    let text = rng.gen_range(0..=n);
    dst.fill(0);
    for b in &mut dst[..text] {
        *b = rng.gen_range(0x20..0x7f);
    }
    match rng.gen_range(0..6) {
        0 => {}
        1 if text + 1 < n => dst[rng.gen_range(text + 1..n)] = rng.gen_range(1..=255),
        2 if text > 0 => dst[rng.gen_range(0..text)] = rng.gen_range(0x80..=0xff),
        3 if text > 0 => dst[text - 1] = 0xc3, // a cut "é"
        4 if text > 1 => dst[..2].copy_from_slice("é".as_bytes()),
        _ => rng.fill(dst),
    }
}

/// A full payload of random field values (integers: any bit pattern, so
/// enum fields carry values the XML does not list too).
fn payload(rng: &mut Pcg64, meta: &MessageMeta) -> Vec<u8> {
    let mut p = vec![0u8; meta.max_len as usize];
    rng.fill(&mut p[..]);
    for f in meta.fields {
        let at = f.offset as usize;
        let n = (f.array_len as usize).max(1);
        match f.ty {
            FieldType::Char => char_bytes(rng, &mut p[at..at + n]),
            FieldType::F32 => {
                for k in 0..n {
                    let bits = float_bits(rng, 8, 23) as u32;
                    p[at + 4 * k..at + 4 * k + 4].copy_from_slice(&bits.to_le_bytes());
                }
            }
            FieldType::F64 => {
                for k in 0..n {
                    let bits = float_bits(rng, 11, 52);
                    p[at + 8 * k..at + 8 * k + 8].copy_from_slice(&bits.to_le_bytes());
                }
            }
            _ => {}
        }
        if rng.gen_range(0..5) == 0 {
            p[at..at + f.wire_len()].fill(0);
        }
    }
    p
}

/// The payload bytes of a message.
fn bytes(m: &Message) -> Vec<u8> {
    let mut out = [0u8; 255];
    let n = m.emit(&mut out).unwrap();
    out[..n].to_vec()
}

/// Every message of the dialect with random values, with its bytes.
fn every_message(seed: u64) -> Vec<(Message, Vec<u8>)> {
    let mut rng = Pcg64::seed_from_u64(seed);
    let mut all = Vec::new();
    for meta in MESSAGES {
        for _ in 0..PER_MESSAGE {
            let m = Message::parse(meta.id, &payload(&mut rng, meta)).unwrap();
            let b = bytes(&m);
            all.push((m, b));
        }
    }
    all
}

#[test]
fn every_message_round_trips_through_json_byte_for_byte() {
    let seed = seed();
    for (m, expected) in every_message(seed) {
        let text = serde_json::to_string(&m).unwrap();
        let back: Message = serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("seed {seed}: {}: {e}\n{text}", m.name()));
        assert!(
            bytes(&back) == expected,
            "seed {seed}: {} changed through JSON:\n{text}",
            m.name()
        );
        // Keyed by the XML message name, fields by their XML names.
        let value: Value = serde_json::from_str(&text).unwrap();
        let fields = value[m.name()].as_object().expect("{\"NAME\": {…}}");
        let mut keys: Vec<&str> = fields.keys().map(String::as_str).collect();
        let mut xml: Vec<&str> = m.meta().fields.iter().map(|f| f.name).collect();
        keys.sort_unstable();
        xml.sort_unstable();
        assert_eq!(keys, xml, "{}", m.name());
    }
}

#[test]
fn every_message_round_trips_through_postcard_byte_for_byte() {
    let seed = seed();
    let mut buf = [0u8; 2048];
    for (m, expected) in every_message(seed) {
        let used = postcard::to_slice(&m, &mut buf).unwrap();
        let back: Message =
            postcard::from_bytes(used).unwrap_or_else(|e| panic!("seed {seed}: {}: {e}", m.name()));
        assert!(bytes(&back) == expected, "seed {seed}: {}", m.name());
    }
}

fn heartbeat() -> Heartbeat {
    Heartbeat {
        r#type: MavType::FIXED_WING,
        autopilot: MavAutopilot::ARDUPILOTMEGA,
        base_mode: MavModeFlag::SAFETY_ARMED | MavModeFlag::CUSTOM_MODE_ENABLED,
        custom_mode: 5,
        system_status: MavState::ACTIVE,
        mavlink_version: 3,
    }
}

#[test]
fn messages_are_keyed_by_xml_name_with_xml_field_names() {
    let text = serde_json::to_string(&Message::from(heartbeat())).unwrap();
    assert_eq!(
        text,
        r#"{"HEARTBEAT":{"type":"MAV_TYPE_FIXED_WING","autopilot":"MAV_AUTOPILOT_ARDUPILOTMEGA","base_mode":"MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | MAV_MODE_FLAG_SAFETY_ARMED","custom_mode":5,"system_status":"MAV_STATE_ACTIVE","mavlink_version":3}}"#
    );
    // A single message serializes as its struct.
    let notice = FbwagNotice {
        timestamp: 123_456,
        system_id: 1,
        component_id: 1,
        failsafe_status: FbwagFailsafeStatus::RC_LOST,
        text: chars("FBWAG"),
    };
    assert_eq!(
        serde_json::to_value(notice).unwrap(),
        json!({"timestamp": 123456, "system_id": 1, "component_id": 1,
               "failsafe_status": "FBWAG_FAILSAFE_STATUS_RC_LOST", "text": "FBWAG"})
    );
}

#[test]
fn value_enums_are_names_unknown_values_numbers_and_both_are_read() {
    let mut hb = heartbeat();
    hb.r#type = MavType(200);
    let value = serde_json::to_value(hb).unwrap();
    assert_eq!(value["type"], json!(200));
    assert_eq!(value["system_status"], json!("MAV_STATE_ACTIVE"));
    let by_number: Heartbeat = serde_json::from_value(json!({"type": 1})).unwrap();
    let by_name: Heartbeat =
        serde_json::from_value(json!({"type": "MAV_TYPE_FIXED_WING"})).unwrap();
    assert_eq!(by_number.r#type, MavType::FIXED_WING);
    assert_eq!(by_name.r#type, MavType::FIXED_WING);
    for bad in [
        json!("FIXED_WING"),
        json!("1"),
        json!(256),
        json!(-1),
        json!(1.0),
    ] {
        let e = serde_json::from_value::<Heartbeat>(json!({ "type": bad })).unwrap_err();
        assert!(e.to_string().contains("MAV_TYPE"), "{bad}: {e}");
    }
}

#[test]
fn bitmasks_are_readable_text_and_keep_every_bit() {
    // Named flags in table order, then the bits no flag names.
    let info = GimbalDeviceInformation {
        cap_flags2: GimbalDeviceCapFlags::from_bits_retain(0x8000_4001 | 0x1_0000),
        ..GimbalDeviceInformation::default()
    };
    assert_eq!(
        serde_json::to_value(info).unwrap()["cap_flags2"],
        json!("GIMBAL_DEVICE_CAP_FLAGS_HAS_RETRACT | GIMBAL_DEVICE_CAP_FLAGS_CAN_POINT_LOCATION_LOCAL | 0x80004000")
    );
    let mut hb = heartbeat();
    for bits in 0..=255u8 {
        hb.base_mode = MavModeFlag::from_bits_retain(bits);
        let text = serde_json::to_string(&hb).unwrap();
        let back: Heartbeat = serde_json::from_str(&text).unwrap();
        assert_eq!(back.base_mode.bits(), bits, "{text}");
    }
    let read = |v: Value| serde_json::from_value::<Heartbeat>(json!({ "base_mode": v }));
    assert_eq!(read(json!("")).unwrap().base_mode, MavModeFlag::empty());
    assert_eq!(read(json!(129)).unwrap().base_mode.bits(), 129);
    assert_eq!(
        read(json!("0x1|MAV_MODE_FLAG_SAFETY_ARMED"))
            .unwrap()
            .base_mode
            .bits(),
        129
    );
    assert!(read(json!("SAFETY_ARMED")).is_err());
    assert!(read(json!("0x100")).is_err());
}

#[test]
fn char_arrays_are_strings_that_keep_every_byte() {
    let mut notice = FbwagNotice::default();
    let text = |n: &FbwagNotice| serde_json::to_value(n).unwrap()["text"].clone();
    notice.text = *b"F\0AG\0";
    assert_eq!(text(&notice), json!("F\u{0}AG"));
    notice.text[0] = 0xff;
    assert_eq!(text(&notice), json!({"hex": "ff004147"}));
    let back: FbwagNotice = serde_json::from_value(serde_json::to_value(notice).unwrap()).unwrap();
    assert_eq!(back.text, notice.text);
    let too_long = "x".repeat(notice.text.len() + 1);
    assert!(serde_json::from_value::<FbwagNotice>(json!({ "text": too_long })).is_err());
}

#[test]
fn arrays_longer_than_32_and_float_specials_round_trip() {
    let mut log = LogData {
        ofs: 7,
        ..LogData::default()
    };
    assert_eq!(log.data.len(), 90);
    log.data[89] = 0xab;
    let value = serde_json::to_value(log).unwrap();
    assert_eq!(value["data"].as_array().unwrap().len(), 90);
    assert_eq!(serde_json::from_value::<LogData>(value).unwrap(), log);

    let info = GimbalManagerInformation {
        roll_min: f32::NAN,
        roll_max: f32::NEG_INFINITY,
        pitch_min: f32::from_bits(0xffc0_0001),
        ..GimbalManagerInformation::default()
    };
    let value = serde_json::to_value(info).unwrap();
    assert_eq!(value["roll_min"], json!("NaN"));
    assert_eq!(value["roll_max"], json!("-inf"));
    assert_eq!(value["pitch_min"], json!("NaN:0xffc00001"));
    let back: GimbalManagerInformation = serde_json::from_value(value).unwrap();
    assert_eq!(back.pitch_min.to_bits(), 0xffc0_0001);
}

#[test]
fn left_out_fields_default_and_unknown_ones_are_refused() {
    let hb: Heartbeat = serde_json::from_str("{}").unwrap();
    assert_eq!(hb, Heartbeat::default());
    assert_eq!(hb.mavlink_version, 3, "the Default, not zero");
    let e = serde_json::from_str::<Heartbeat>(r#"{"tipe":1}"#).unwrap_err();
    assert!(e.to_string().contains("unknown field `tipe`"), "{e}");
    let e = serde_json::from_str::<Message>(r#"{"NOT_A_MESSAGE":{}}"#).unwrap_err();
    assert!(e.to_string().contains("NOT_A_MESSAGE"), "{e}");
}

/// GIMBAL_DEVICE_CAP_FLAGS is carried in 16 bits (`cap_flags`) and in 32
/// bits (`cap_flags2`), so its type is u32: a value beyond 16 bits is
/// refused for the 16-bit field rather than cut on the wire.
#[test]
fn enum_values_wider_than_their_field_are_refused() {
    let read = |v: Value| serde_json::from_value::<GimbalDeviceInformation>(v);
    let wide = GimbalDeviceCapFlags::from_bits_retain(0x1_0000);
    assert_eq!(
        read(json!({"cap_flags2": 0x1_0000})).unwrap().cap_flags2,
        wide
    );
    assert_eq!(
        read(json!({"cap_flags": 0xffff})).unwrap().cap_flags.bits(),
        0xffff
    );
    for bad in [json!(0x1_0000), json!("0x10000")] {
        let e = read(json!({ "cap_flags": bad })).unwrap_err().to_string();
        assert!(e.contains("0 to 65535"), "{e}");
    }
    // postcard too: the check is the field's, not the format's.
    let mut info = GimbalDeviceInformation {
        cap_flags2: wide,
        ..GimbalDeviceInformation::default()
    };
    let mut buf = [0u8; 512];
    let used = postcard::to_slice(&info, &mut buf).unwrap().to_vec();
    info.cap_flags = wide;
    let bad = postcard::to_slice(&info, &mut buf).unwrap();
    assert!(postcard::from_bytes::<GimbalDeviceInformation>(&used).is_ok());
    assert!(postcard::from_bytes::<GimbalDeviceInformation>(bad).is_err());
}
