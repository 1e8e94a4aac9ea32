//! `fbwag encode` writes exactly what a line says or refuses the line: the
//! refusal names the line, no frame is written for it, the next lines are
//! still encoded, and the exit status is 1. Tested through the binary only.

mod common;
use common::fbwag;

/// Hex frames of `lines`, which must all encode (exit 0).
fn frames(args: &[&str], lines: &[&str]) -> Vec<String> {
    let input = lines.join("\n") + "\n";
    let (out, err, code) = fbwag(&[&["encode", "--hex"], args].concat(), input.as_bytes());
    assert_eq!(code, Some(0), "{err}");
    String::from_utf8(out)
        .unwrap()
        .lines()
        .map(String::from)
        .collect()
}

/// A good line before and after each bad one, so a bad line can neither
/// leak into nor stop its neighbours.
const GOOD: &str = r#"{"name":"HEARTBEAT","sysid":1,"compid":1,"fields":{"type":1,"autopilot":3,"base_mode":81,"custom_mode":5,"system_status":4,"mavlink_version":3}}"#;
/// Fills 50 bytes of the encoder's frame buffer with `A`s, which a later
/// line must never see.
const LONG: &str = r#"{"name":"STATUSTEXT","fields":{"severity":6,"text":"AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA"}}"#;

/// Asserts that each of `bad` is refused with its line number (and the
/// needle, if given, in the message), while the good lines around it are
/// encoded exactly as on their own.
#[track_caller]
fn assert_refused(args: &[&str], bad: &[(&[u8], &str)]) {
    let good = frames(args, &[LONG, GOOD]);
    for (line, needle) in bad {
        let mut input = format!("{LONG}\n").into_bytes();
        input.extend_from_slice(line);
        input.extend_from_slice(format!("\n{GOOD}\n").as_bytes());
        let (out, err, code) = fbwag(&[&["encode", "--hex"], args].concat(), &input);
        let shown = String::from_utf8_lossy(line);
        assert_eq!(code, Some(1), "{shown}: exit status\n{err}");
        assert!(err.contains("line 2: "), "{shown}: no `line 2:` in\n{err}");
        assert!(err.contains(needle), "{shown}: no {needle:?} in\n{err}");
        let out: Vec<String> = String::from_utf8(out)
            .unwrap()
            .lines()
            .map(String::from)
            .collect();
        assert_eq!(out, good, "{shown}: the other lines changed");
    }
}

#[test]
fn payload_len_beyond_the_message_is_refused_not_filled_from_the_last_line() {
    // HEARTBEAT has 9 bytes; the encoder used to send 200, 41 of them the
    // STATUSTEXT's before.
    assert_refused(
        &[],
        &[
            (
                br#"{"name":"HEARTBEAT","fields":{},"payload_len":200}"#,
                "payload_len",
            ),
            (
                br#"{"name":"HEARTBEAT","fields":{},"payload_len":10}"#,
                "payload_len",
            ),
            // Shorter than the non-zero field bytes: custom_mode would be cut.
            (
                br#"{"name":"HEARTBEAT","fields":{"custom_mode":65536},"payload_len":2}"#,
                "custom_mode",
            ),
            (
                br#"{"name":"HEARTBEAT","version":1,"fields":{},"payload_len":12}"#,
                "payload_len",
            ),
        ],
    );
}

#[test]
fn floats_beyond_their_type_are_refused_not_made_infinite() {
    assert_refused(
        &[],
        &[
            (br#"{"name":"ATTITUDE","fields":{"roll":1e39}}"#, "roll"),
            (br#"{"name":"ATTITUDE","fields":{"pitch":-3.5e38}}"#, "pitch"),
            (br#"{"name":"WHEEL_DISTANCE","fields":{"distance":[1e309,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0]}}"#, "distance"),
            (br#"{"name":"ATTITUDE","fields":{"roll":"NaN:0x7f800000"}}"#, "roll"),
            (br#"{"name":"ATTITUDE","fields":{"roll":"nan"}}"#, "roll"),
        ],
    );
    // The largest finite values and the named specials are fine.
    frames(
        &[],
        &[
            r#"{"name":"ATTITUDE","fields":{"roll":3.4028235e38,"pitch":-3.4028235e38,"yaw":"inf","rollspeed":"-inf","pitchspeed":"NaN","yawspeed":"NaN:0xffc00001"}}"#,
        ],
    );
}

#[test]
fn a_line_that_is_not_utf8_is_refused_and_the_rest_encoded() {
    assert_refused(
        &[],
        &[
            (b"\xff\xfe{}", "UTF-8"),
            (
                b"{\"name\":\"STATUSTEXT\",\"fields\":{\"text\":\"\xe9t\xe9\"}}",
                "UTF-8",
            ),
        ],
    );
}

#[test]
fn signed_without_a_signature_or_key_is_refused_not_sent_unsigned() {
    assert_refused(
        &[],
        &[
            (br#"{"name":"HEARTBEAT","signed":true,"fields":{}}"#, "signed"),
            // A partial signature would be completed with zeros.
            (br#"{"name":"HEARTBEAT","signed":true,"signature":"010203040506","fields":{}}"#, "link_id"),
            (br#"{"name":"HEARTBEAT","signed":false,"signature":"010203040506","link_id":0,"sign_timestamp":5,"fields":{}}"#, "signed"),
            (br#"{"name":"HEARTBEAT","version":1,"signed":true,"fields":{}}"#, "MAVLink 1"),
        ],
    );
    // With a key, `"signed": true` is honoured: the signed flag is set and
    // the frame carries 13 more bytes.
    let key = "0".repeat(64);
    let args = ["--sign-key", key.as_str(), "--sign-timestamp", "1000"];
    let signed = frames(
        &args,
        &[r#"{"name":"HEARTBEAT","signed":true,"fields":{}}"#],
    );
    let plain = frames(&[], &[r#"{"name":"HEARTBEAT","fields":{}}"#]);
    assert_eq!(&signed[0][4..6], "01", "incompat flags of {}", signed[0]);
    assert_eq!(signed[0].len(), plain[0].len() + 26);
    // A MAVLink 1 frame cannot be signed: refused rather than sent unsigned.
    let (_, err, code) = fbwag(
        &[&["encode"], &args[..]].concat(),
        br#"{"name":"HEARTBEAT","version":1,"fields":{}}"#,
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("line 1: "), "{err}");
}

#[test]
fn a_message_without_fields_is_refused_and_empty_fields_mean_zeros() {
    assert_refused(
        &[],
        &[
            (br#"{"name":"HEARTBEAT"}"#, "fields"),
            (br#"{"name":"HEARTBEAT","fields":null}"#, "fields"),
            (br#"{"msgid":0}"#, "fields"),
            (br#"{}"#, "name"),
        ],
    );
    // `"fields":{}` asks for zeros, and gets exactly that: a one-byte
    // MAVLink 2 payload (trailing zeros dropped, one kept).
    let zero = frames(&[], &[r#"{"name":"HEARTBEAT","fields":{}}"#]);
    assert_eq!(zero, ["fd010000000000000000002bb7"]);
}

#[test]
fn lossy_field_values_are_refused() {
    let cases: &[(&[u8], &str)] = &[
        (br#"{"name":"HEARTBEAT","fields":{"type":256}}"#, "type"),
        (br#"{"name":"HEARTBEAT","fields":{"type":-1}}"#, "type"),
        (br#"{"name":"HEARTBEAT","fields":{"custom_mode":4294967296}}"#, "custom_mode"),
        (br#"{"name":"HEARTBEAT","fields":{"custom_mode":-1}}"#, "custom_mode"),
        (br#"{"name":"HEARTBEAT","fields":{"type":1.5}}"#, "type"),
        (br#"{"name":"HEARTBEAT","fields":{"type":1.0}}"#, "type"),
        (br#"{"name":"HEARTBEAT","fields":{"type":"1"}}"#, "type"),
        (br#"{"name":"HEARTBEAT","fields":{"type":true}}"#, "type"),
        (br#"{"name":"HEARTBEAT","fields":{"type":null}}"#, "type"),
        (br#"{"name":"HEARTBEAT","fields":{"type":[1]}}"#, "type"),
        (br#"{"name":"SYSTEM_TIME","fields":{"time_unix_usec":18446744073709551616}}"#, "time_unix_usec"),
        (br#"{"name":"SCALED_PRESSURE","fields":{"temperature":32768}}"#, "temperature"),
        (br#"{"name":"SCALED_PRESSURE","fields":{"temperature":-32769}}"#, "temperature"),
        (br#"{"name":"ATTITUDE","fields":{"roll":"fast"}}"#, "roll"),
        (br#"{"name":"ATTITUDE","fields":{"roll":[1.0]}}"#, "roll"),
        (br#"{"name":"STATUSTEXT","fields":{"text":"AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA"}}"#, "text"),
        (br#"{"name":"STATUSTEXT","fields":{"text":[256]}}"#, "text"),
        (br#"{"name":"STATUSTEXT","fields":{"text":5}}"#, "text"),
        (br#"{"name":"WHEEL_DISTANCE","fields":{"distance":[0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0]}}"#, "distance"),
        (br#"{"name":"WHEEL_DISTANCE","fields":{"distance":[0,0]}}"#, "distance"),
        (br#"{"name":"WHEEL_DISTANCE","fields":{"distance":0}}"#, "distance"),
        (br#"{"name":"HEARTBEAT","fields":{"tipe":1}}"#, "tipe"),
        (br#"{"name":"HEARTBEAT","fields":{"type":1,"type":2}}"#, "type"),
        (br#"{"name":"HEARTBEAT","sigend":true,"fields":{}}"#, "sigend"),
        (br#"{"name":"HEARTBEAT","seq":256,"fields":{}}"#, "seq"),
        (br#"{"name":"HEARTBEAT","msgid":1,"fields":{}}"#, "msgid"),
        (br#"{"name":"NOT_A_MESSAGE","fields":{}}"#, "NOT_A_MESSAGE"),
        (br#"[1,2]"#, "object"),
        (br#"{"name":"HEARTBEAT","fields":{}"#, "JSON"),
    ];
    assert_refused(&[], cases);
}

#[test]
fn raw_frames_must_agree_with_their_keys() {
    // A frame of id 0x3039, which the dialect does not know (so it stays raw).
    let raw = "fd01000000010139300000aabb";
    let line = |extra: &str| {
        format!(
            r#"{{"version":2,"seq":0,"sysid":1,"compid":1,"msgid":12345,"name":null,"signed":false{extra},"raw":"{raw}"}}"#
        )
    };
    let good = frames(&[], &[&line("")]);
    assert_eq!(good, [raw]);
    let edited = line("").replace(r#""seq":0"#, r#""seq":7"#);
    let (_, err, code) = fbwag(&["encode"], edited.as_bytes());
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("line 1: ") && err.contains("seq"), "{err}");
    // An unsigned raw frame cannot be signed without redoing its checksum.
    let key = "0".repeat(64);
    let (_, err, code) = fbwag(&["encode", "--sign-key", &key], line("").as_bytes());
    assert_eq!(code, Some(1), "{err}");
}

#[test]
fn every_line_good_exits_0() {
    let (out, err, code) = fbwag(
        &["encode", "--hex"],
        format!("{GOOD}\n\n{LONG}\r\n").as_bytes(),
    );
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(String::from_utf8(out).unwrap().lines().count(), 2);
}

/// A line that is JSON of the wrong shape is named by its line alone:
/// serde_json's own "at line 1 column N" counts in the line, not the input.
#[test]
fn a_line_of_the_wrong_shape_names_only_its_line() {
    assert_refused(
        &[],
        &[(
            b"[1, 2]",
            "line 2: invalid type: sequence, expected a JSON object\n",
        )],
    );
}
