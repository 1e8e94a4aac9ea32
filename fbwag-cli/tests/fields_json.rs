//! The `fields` object `fbwag decode` writes comes from the generated
//! messages' serde impls; these pin what the other tests leave open: keys
//! in wire order (pymavlink's `ordered_fieldnames`, not the XML order the
//! Rust structs have), enums and bitmasks as numbers, and a line's missing
//! fields encoded as zeros even where the message's `Default` is not zero.

mod common;

/// `common::fbwag` with stdout as text.
fn fbwag(args: &[&str], input: &[u8]) -> (String, String, Option<i32>) {
    let (out, err, code) = common::fbwag(args, input);
    (String::from_utf8(out).unwrap(), err, code)
}

#[test]
fn heartbeat_fields_are_numbers_in_wire_order() {
    let line = r#"{"name":"HEARTBEAT","sysid":1,"compid":1,"fields":{"type":1,"autopilot":3,"base_mode":209,"custom_mode":10,"system_status":4,"mavlink_version":3}}"#;
    let (hex, err, code) = fbwag(&["encode", "--hex"], line.as_bytes());
    assert_eq!(code, Some(0), "{err}");
    let (json, err, code) = fbwag(&["decode", "--hex"], hex.as_bytes());
    assert_eq!(code, Some(0), "{err}");
    assert!(
        json.ends_with(r#""fields":{"custom_mode":10,"type":1,"autopilot":3,"base_mode":209,"system_status":4,"mavlink_version":3}}
"#),
        "{json}"
    );
}

#[test]
fn left_out_fields_are_zeros_not_the_default() {
    // HEARTBEAT's Default sets mavlink_version to 3; a line without it
    // asks for 0, and gets a payload of zeros.
    let (hex, err, code) = fbwag(
        &["encode", "--hex"],
        br#"{"name":"HEARTBEAT","fields":{"type":2}}"#,
    );
    assert_eq!(code, Some(0), "{err}");
    let (json, _, _) = fbwag(&["decode", "--hex"], hex.as_bytes());
    assert!(
        json.contains(
            r#""type":2,"autopilot":0,"base_mode":0,"system_status":0,"mavlink_version":0}"#
        ),
        "{json}"
    );
}

#[test]
fn arrays_chars_and_floats_keep_the_tool_s_forms() {
    let line = r#"{"name":"NAMED_VALUE_FLOAT","fields":{"time_boot_ms":1,"value":"NaN:0xffc00001","name":[65,0,66,0,0,0,0,0,0,0]}}"#;
    let (hex, err, code) = fbwag(&["encode", "--hex"], line.as_bytes());
    assert_eq!(code, Some(0), "{err}");
    let (json, _, _) = fbwag(&["decode", "--hex"], hex.as_bytes());
    assert!(
        json.contains(
            r#""fields":{"time_boot_ms":1,"value":"NaN:0xffc00001","name":[65,0,66,0,0,0,0,0,0,0]}"#
        ),
        "{json}"
    );
}

/// `fbwag encode --hex` of one line, which must encode.
fn encode(line: &str) -> String {
    let (hex, err, code) = fbwag(&["encode", "--hex"], line.as_bytes());
    assert_eq!(code, Some(0), "{line}: {err}");
    hex
}

#[test]
fn encode_also_takes_the_generated_serde_forms() {
    // Entry names and bitmask text for enums; `{"hex": …}` and fewer byte
    // values than the field holds for chars (the rest are NULs).
    let named = r#"{"name":"HEARTBEAT","fields":{"type":"MAV_TYPE_FIXED_WING","base_mode":"MAV_MODE_FLAG_SAFETY_ARMED | 0x1"}}"#;
    let numbers = r#"{"name":"HEARTBEAT","fields":{"type":1,"base_mode":129}}"#;
    assert_eq!(encode(named), encode(numbers));
    let whole = format!(
        r#"{{"name":"STATUSTEXT","fields":{{"text":[65,255{}]}}}}"#,
        ",0".repeat(48)
    );
    for short in [
        r#"{"name":"STATUSTEXT","fields":{"text":{"hex":"41ff"}}}"#,
        r#"{"name":"STATUSTEXT","fields":{"text":[65,255]}}"#,
    ] {
        assert_eq!(encode(short), encode(&whole), "{short}");
    }
    // Decode writes what pymavlink prints: numbers, and every byte of a
    // char array that is not text.
    let (json, _, _) = fbwag(&["decode", "--hex"], encode(named).as_bytes());
    assert!(
        json.contains(r#""type":1,"autopilot":0,"base_mode":129"#),
        "{json}"
    );
}
