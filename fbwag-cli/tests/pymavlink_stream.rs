//! `fbwag decode | fbwag encode` on telemetry captures made by pymavlink
//! 2.4.50 (`benches/scripts/make_telemetry.py`): byte for byte the same
//! bytes, and the same field values as pymavlink's own decoding.

use serde_json::Value;
use std::path::PathBuf;
use std::process::{Command, Stdio};

mod common;

use common::{python, repo};

fn scratch(name: &str) -> PathBuf {
    let dir = repo().join("target/test-scratch");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(format!("{}-{name}", std::process::id()))
}

/// Makes a capture with `make_telemetry.py ARGS`.
fn capture(name: &str, args: &[&str]) -> Vec<u8> {
    let path = scratch(name);
    let status = Command::new(python())
        .arg(repo().join("benches/scripts/make_telemetry.py"))
        .args(args)
        .arg("-o")
        .arg(&path)
        .stderr(Stdio::null())
        .status()
        .expect("make_telemetry.py");
    assert!(status.success());
    let bytes = std::fs::read(&path).unwrap();
    let _ = std::fs::remove_file(&path);
    bytes
}

/// `common::fbwag` with success as a bool.
fn fbwag(args: &[&str], input: &[u8]) -> (Vec<u8>, String, bool) {
    let (out, err, code) = common::fbwag(args, input);
    (out, err, code == Some(0))
}

fn round_trip(name: &str, bytes: &[u8], tlog: bool) -> Vec<u8> {
    let flag: &[&str] = if tlog { &["--tlog"] } else { &[] };
    let (json, err, ok) = fbwag(&[&["decode"], flag].concat(), bytes);
    assert!(ok, "{name}: decode reported problems: {err}");
    let (again, err, ok) = fbwag(&[&["encode"], flag].concat(), &json);
    assert!(ok, "{name}: encode failed: {err}");
    assert!(
        again == bytes,
        "{name}: decode | encode changed the bytes (first difference at {:?})",
        again.iter().zip(bytes).position(|(a, b)| a != b)
    );
    json
}

#[test]
fn plain_capture_round_trips_exactly() {
    let bytes = capture("plain", &["--bytes", "600K", "--seed", "3"]);
    let json = round_trip("plain", &bytes, false);
    let lines = json
        .split(|&b| b == b'\n')
        .filter(|l| !l.is_empty())
        .count();
    assert!(lines > 15_000, "{lines} frames");
}

#[test]
fn signed_and_mavlink1_capture_round_trips_exactly() {
    let key = "000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f";
    let bytes = capture(
        "signed",
        &[
            "--bytes",
            "300K",
            "--seed",
            "4",
            "--v1-fraction",
            "0.3",
            "--sign-key",
            key,
        ],
    );
    round_trip("signed", &bytes, false);
    // C-style MAVLink 1 (no extension bytes) too.
    let bytes = capture(
        "v1drop",
        &[
            "--bytes",
            "200K",
            "--seed",
            "5",
            "--v1-fraction",
            "0.5",
            "--v1-extensions",
            "drop",
        ],
    );
    round_trip("v1drop", &bytes, false);
}

#[test]
fn tlog_round_trips_exactly() {
    let bytes = capture("tlog", &["--bytes", "200K", "--seed", "6", "--tlog"]);
    round_trip("tlog", &bytes, true);
}

/// A JSON value compared the way the wire sees it: floats as f32 bit
/// patterns (pymavlink prints the f64 widening of each f32), strings as
/// pymavlink decodes chars (cut at the first NUL, bytes ≥ 0x80 as U+FFFD).
fn same(ours: &Value, theirs: &Value, is_f32: bool) -> bool {
    match (ours, theirs) {
        (Value::Number(a), Value::Number(b)) if is_f32 => {
            a.as_f64().map(|x| x as f32) == b.as_f64().map(|x| x as f32)
        }
        (Value::Number(a), Value::Number(b)) => {
            a.as_f64() == b.as_f64() && a.as_i64() == b.as_i64() && a.as_u64() == b.as_u64()
        }
        (Value::Array(a), Value::String(s)) => {
            let bytes: Vec<u8> = a.iter().map(|v| v.as_u64().unwrap_or(0) as u8).collect();
            let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
            let text: String = bytes[..end]
                .iter()
                .map(|&b| if b < 0x80 { b as char } else { '\u{FFFD}' })
                .collect();
            &text == s
        }
        (Value::Array(a), Value::Array(b)) => {
            a.len() == b.len() && a.iter().zip(b).all(|(x, y)| same(x, y, is_f32))
        }
        _ => ours == theirs,
    }
}

fn f32_fields(meta_name: &str) -> Vec<&'static str> {
    use fbwag_dialect::mavframe::{FieldType, MessageSet as _};
    fbwag_dialect::Dialect::MESSAGES
        .iter()
        .find(|m| m.name == meta_name)
        .map(|m| {
            m.fields
                .iter()
                .filter(|f| f.ty == FieldType::F32)
                .map(|f| f.name)
                .collect()
        })
        .unwrap_or_default()
}

#[test]
fn field_values_equal_pymavlink_decoding() {
    let bytes = capture(
        "compare",
        &["--bytes", "400K", "--seed", "7", "--v1-fraction", "0.2"],
    );
    let path = scratch("compare.bin");
    std::fs::write(&path, &bytes).unwrap();
    let theirs = Command::new(python())
        .arg(repo().join("conformance/pymavlink/decode_json.py"))
        .arg(&path)
        .stderr(Stdio::null())
        .output()
        .expect("decode_json.py");
    let _ = std::fs::remove_file(&path);
    assert!(theirs.status.success());
    let (ours, _, ok) = fbwag(&["decode"], &bytes);
    assert!(ok);
    let parse = |out: &[u8]| -> Vec<Value> {
        String::from_utf8_lossy(out)
            .lines()
            .map(|l| serde_json::from_str(l).expect("JSON line"))
            .collect()
    };
    let (ours, theirs) = (parse(&ours), parse(&theirs.stdout));
    assert_eq!(ours.len(), theirs.len(), "frame count");
    for (i, (a, b)) in ours.iter().zip(&theirs).enumerate() {
        for key in [
            "version", "seq", "sysid", "compid", "msgid", "name", "signed",
        ] {
            assert_eq!(a[key], b[key], "frame {i}: {key}");
        }
        let f32s = f32_fields(a["name"].as_str().unwrap());
        let (fa, fb) = (
            a["fields"].as_object().unwrap(),
            b["fields"].as_object().unwrap(),
        );
        let order_a: Vec<_> = fa.keys().collect();
        let order_b: Vec<_> = fb.keys().collect();
        assert_eq!(order_a, order_b, "frame {i}: same fields");
        for (k, va) in fa {
            assert!(
                same(va, &fb[k], f32s.contains(&k.as_str())),
                "frame {i} {}.{k}: ours {va}, pymavlink {}",
                a["name"],
                fb[k]
            );
        }
    }
}

#[test]
fn reference_frame_json_is_exactly_the_documented_line() {
    let (out, _, ok) = fbwag(
        &["decode", "--hex"],
        b"fd0c0000000101993a0040e201000101014642574147d933\n",
    );
    assert!(ok);
    assert_eq!(
        String::from_utf8(out).unwrap(),
        "{\"version\":2,\"seq\":0,\"sysid\":1,\"compid\":1,\"msgid\":15001,\"name\":\"FBWAG_NOTICE\",\"signed\":false,\"fields\":{\"timestamp\":123456,\"system_id\":1,\"component_id\":1,\"failsafe_status\":1,\"text\":\"FBWAG\"}}\n"
    );
}

#[test]
fn garbage_is_counted_not_fatal() {
    let (out, err, ok) = fbwag(&["decode"], b"\xfd\x05garbage\xfe\x01\x02 more");
    assert!(!ok, "problems give exit status 1");
    assert!(out.is_empty());
    assert!(err.contains("bytes dropped"), "{err}");
    let (_, err, ok) = fbwag(&["encode"], b"{\"name\":\"NOPE\"}\nnot json\n");
    assert!(!ok);
    assert!(
        err.contains("line 1: unknown message name `NOPE`") && err.contains("line 2: not JSON"),
        "{err}"
    );
}
