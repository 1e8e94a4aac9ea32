//! Every documented difference between pymavlink 2.4.50, the MAVLink C
//! library and mavframe, each pinned by a test (docs/conformance.md lists
//! them). The bulk comparison (tests/wire.rs) applies the first three to its
//! expectations; none is a silent skip.

mod support;

use mavframe::frame::{Header, Version, HEADER_LEN_V2};
use mavframe::{MessageMeta, Signer};
use std::process::Command;
use support::frames::{build_frame, rust_decode, v1_with_extensions, Mode, KEY};
use support::streams::{rust_parse, Policy};
use support::three_way::{field, python, three_way};
use support::values::{hex, values_text, zero_extensions};
use support::{peers, repo};

fn fbwag(name: &str) -> &'static MessageMeta {
    fbwag_dialect::MESSAGES
        .iter()
        .find(|m| m.name == name)
        .unwrap()
}

fn set(meta: &MessageMeta, payload: &mut [u8], name: &str, bytes: &[u8]) {
    let f = meta.fields.iter().find(|f| f.name == name).unwrap();
    let at = f.offset as usize;
    payload[at..at + bytes.len()].copy_from_slice(bytes);
}

fn token(mode: Mode, seq: u8, values: &str) -> String {
    format!("ok:{}:{seq}:1:191:{values}", u8::from(mode == Mode::V2s))
}

/// pymavlink's `force_mavlink1=True` keeps the extension fields in the
/// payload; the C library and mavframe send the base fields only. Every
/// decoder reads extensions from the longer frame and zero from the shorter.
#[test]
fn pymavlink_mavlink1_frames_carry_extension_fields() {
    let meta = fbwag("SYS_STATUS");
    assert!(meta.max_len > meta.min_len);
    let payload: Vec<u8> = (0..meta.max_len).map(|i| 0x11 + i).collect();
    let t = three_way("fbwag", meta, Mode::V1, &payload);
    assert_eq!(t.rust.len(), 6 + meta.min_len as usize + 2);
    assert_eq!(t.c, t.rust, "C sends base fields only, like mavframe");
    let header = Header {
        seq: 7,
        sysid: 1,
        compid: 191,
    };
    assert_eq!(t.py, v1_with_extensions(meta, header, &payload));
    assert_eq!(t.py.len(), 6 + meta.max_len as usize + 2);
    let mut base = payload.clone();
    zero_extensions(meta, &mut base);
    let full = token(Mode::V1, 7, &values_text(meta, &payload));
    let short = token(Mode::V1, 7, &values_text(meta, &base));
    assert_eq!(
        t.py_decodes_rust, short,
        "pymavlink zero-fills the missing extensions"
    );
    assert_eq!(t.c_decodes_rust, short);
    assert_eq!(
        t.c_decodes_py, full,
        "C reads the extension bytes of pymavlink's frame"
    );
    let r = rust_decode::<fbwag_dialect::Dialect>(&t.py, false);
    assert_eq!(r.token, full, "mavframe reads them too");
    assert_eq!(
        r.reencoded.unwrap(),
        t.rust,
        "and sends MAVLink 1 without them"
    );
}

/// CPython's float32 unpacking converts to double, which quiets a
/// signalling NaN (bit 22 set): pymavlink decodes and re-sends 0x7fc00001
/// for 0x7f800001. The C library and mavframe keep the bits. doubles are
/// unaffected (Python floats are doubles).
#[test]
fn pymavlink_quiets_float32_signalling_nans() {
    let meta = fbwag("ATTITUDE");
    let mut payload = vec![0u8; meta.max_len as usize];
    set(meta, &mut payload, "roll", &0x7F80_0001u32.to_le_bytes());
    set(meta, &mut payload, "pitch", &0x7FC0_0001u32.to_le_bytes()); // quiet: kept
    set(meta, &mut payload, "time_boot_ms", &1234u32.to_le_bytes());
    let t = three_way("fbwag", meta, Mode::V2, &payload);
    assert_eq!(field(&t.py_decodes_rust, "roll"), "7fc00001");
    assert_eq!(field(&t.py_decodes_rust, "pitch"), "7fc00001");
    assert_eq!(field(&t.c_decodes_rust, "roll"), "7f800001");
    let r = rust_decode::<fbwag_dialect::Dialect>(&t.rust, false);
    assert_eq!(field(&r.token, "roll"), "7f800001");
    assert_eq!(t.c, t.rust);
    assert_ne!(t.py, t.rust, "pymavlink re-sends the quieted NaN");
    let mut quieted = payload.clone();
    set(meta, &mut quieted, "roll", &0x7FC0_0001u32.to_le_bytes());
    let header = Header {
        seq: 7,
        sysid: 1,
        compid: 191,
    };
    assert_eq!(
        t.py,
        build_frame(meta, Mode::V2, header, &quieted, 0, 0, &KEY)
    );
}

/// The C library's typed pack functions write HEARTBEAT.mavlink_version
/// (XML type `uint8_t_mavlink_version`) themselves: always 3. pymavlink and
/// mavframe send the value given. Decoding keeps what is on the wire.
#[test]
fn c_heartbeat_pack_forces_mavlink_version_3() {
    let meta = fbwag("HEARTBEAT");
    let mut payload = vec![0u8; meta.max_len as usize];
    set(meta, &mut payload, "custom_mode", &5u32.to_le_bytes());
    set(meta, &mut payload, "mavlink_version", &[7]);
    let t = three_way("fbwag", meta, Mode::V2s, &payload);
    assert_eq!(t.py, t.rust);
    assert_eq!(field(&t.c_decodes_rust, "mavlink_version"), "7");
    assert_eq!(field(&t.py_decodes_rust, "mavlink_version"), "7");
    let off = meta
        .fields
        .iter()
        .find(|f| f.name == "mavlink_version")
        .unwrap()
        .offset as usize;
    assert_eq!(t.c[HEADER_LEN_V2 + off], 3);
    let mut three = payload.clone();
    three[off] = 3;
    let header = Header {
        seq: 7,
        sysid: 1,
        compid: 191,
    };
    assert_eq!(
        t.c,
        build_frame(
            meta,
            Mode::V2s,
            header,
            &three,
            3,
            0x0000_1000_0000_0000,
            &KEY
        )
    );
}

/// pymavlink's char fields are `str`: cut at the first NUL, ASCII with
/// U+FFFD for each byte >= 0x80; the bytes stay in `_<name>_raw`. mavframe's
/// `CharArray` gives the bytes up to the first NUL (`to_str` fails when they
/// are not UTF-8); the C library gives the raw array.
#[test]
fn pymavlink_char_fields_are_ascii_strings() {
    let meta = fbwag("STATUSTEXT");
    let mut payload = vec![0u8; meta.max_len as usize];
    set(meta, &mut payload, "text", b"Hi\xffx");
    let header = Header {
        seq: 0,
        sysid: 1,
        compid: 1,
    };
    let frame = build_frame(meta, Mode::V2, header, &payload, 0, 0, &KEY);
    let out = python(&format!(
        "import fbwag_dialect\nmod = fbwag_dialect.load()\nm = mod.MAVLink(None).parse_char(bytes.fromhex('{}'))\nprint(ascii(m.text), m._text_raw.hex())",
        hex(&frame)
    ));
    assert_eq!(out.trim(), "'Hi\\ufffdx' 4869ff78");
    let v = fbwag_dialect::dialects::common::StatustextView::new(&payload);
    assert_eq!(v.text().as_bytes(), b"Hi\xffx");
    assert!(v.text().to_str().is_err());
}

/// A frame of an id the dialect lacks: pymavlink returns MAVLink_unknown
/// (it cannot check the CRC); the C library rejects it (its parser treats
/// a missing CRC_EXTRA as a bad CRC); mavframe returns it raw (for routing)
/// once confirmed by the start byte that follows.
#[test]
fn unknown_message_ids() {
    let hb = fbwag("HEARTBEAT");
    let mut unknown = *hb;
    (unknown.id, unknown.crc_extra) = (0xF0_0001, 0);
    let header = Header {
        seq: 1,
        sysid: 1,
        compid: 1,
    };
    let mut stream = build_frame(&unknown, Mode::V2, header, &[1; 9], 0, 0, &KEY);
    let good = build_frame(hb, Mode::V2, header, &[2; 9], 0, 0, &KEY);
    stream.extend_from_slice(&good);
    let (py, c) = peer_streams("fbwag", Policy::NoKey, &stream);
    assert_eq!(py, format!("{}\t-\t1", hex(&good)));
    assert_eq!(c, hex(&good));
    let (got, _) = rust_parse::<fbwag_dialect::Dialect>(&stream, Policy::NoKey, || 0);
    assert_eq!(got.len(), 2);
    assert!(!got[0].known && got[1].known);
}

/// Unknown incompatibility flags: pymavlink reads the frame's claimed
/// length before it looks at the flags and drops all of it (with the good
/// frame inside); the C library rejects at the flags byte and rescans, as
/// mavframe does.
#[test]
fn unknown_incompat_flags() {
    let hb = fbwag("HEARTBEAT");
    let header = Header {
        seq: 1,
        sysid: 1,
        compid: 1,
    };
    let inner = build_frame(hb, Mode::V2, header, &[3; 9], 0, 0, &KEY);
    let mut bad = vec![0xFD, 40, 0x02, 0, 9, 1, 1, 0, 0, 0];
    bad.extend_from_slice(&inner);
    bad.resize(10 + 40, 0x55);
    let crc = mavframe::crc::frame_crc(&bad[1..], hb.crc_extra);
    bad.extend_from_slice(&crc.to_le_bytes());
    let tail = build_frame(
        hb,
        Mode::V2,
        Header { seq: 2, ..header },
        &[4; 9],
        0,
        0,
        &KEY,
    );
    let mut stream = bad.clone();
    stream.extend_from_slice(&tail);
    let (py, c) = peer_streams("fbwag", Policy::NoKey, &stream);
    assert_eq!(
        py,
        format!("{}\t-\t0", hex(&tail)),
        "pymavlink loses the inner frame"
    );
    assert_eq!(
        c,
        format!("{} {}", hex(&inner), hex(&tail)),
        "C recovers it"
    );
    let (got, stats) = rust_parse::<fbwag_dialect::Dialect>(&stream, Policy::NoKey, || 0);
    let got: Vec<_> = got.iter().map(|g| g.bytes.clone()).collect();
    assert_eq!(got, vec![inner, tail]);
    assert_eq!(stats.bad_incompat_flags, 1);
}

/// pymavlink records a signed frame's timestamp for its stream before it
/// checks the signature: a frame with a forged signature and a later
/// timestamp makes it refuse the stream's next genuine frames as replays.
/// The C library and mavframe check the signature first.
#[test]
fn pymavlink_forged_signature_advances_stream_timestamp() {
    let hb = fbwag("HEARTBEAT");
    let header = Header {
        seq: 0,
        sysid: 1,
        compid: 1,
    };
    let f1 = build_frame(hb, Mode::V2s, header, &[1; 9], 0, 1000, &KEY);
    let mut forged = build_frame(
        hb,
        Mode::V2s,
        Header { seq: 1, ..header },
        &[1; 9],
        0,
        5000,
        &KEY,
    );
    let n = forged.len();
    forged[n - 1] ^= 0xFF; // signature wrong, checksum still good
    let f3 = build_frame(
        hb,
        Mode::V2s,
        Header { seq: 2, ..header },
        &[1; 9],
        0,
        1001,
        &KEY,
    );
    let stream = [f1.clone(), forged, f3.clone()].concat();
    let (py, c) = peer_streams("fbwag", Policy::KeyAcceptUnsigned, &stream);
    assert_eq!(py, format!("{}\t-\t0", hex(&f1)), "pymavlink refuses f3");
    assert_eq!(c, format!("{} {}", hex(&f1), hex(&f3)));
    let (got, stats) =
        rust_parse::<fbwag_dialect::Dialect>(&stream, Policy::KeyAcceptUnsigned, || 0);
    let got: Vec<_> = got.iter().map(|g| g.bytes.clone()).collect();
    assert_eq!(got, vec![f1, f3]);
    assert_eq!(stats.bad_signature, 1);
}

/// A replay (a frame the key signed, its timestamp not newer than its
/// stream's last) where unsigned frames are accepted: pymavlink and the C
/// library drop it; mavframe returns it unauthenticated, as it would the
/// same frame unsigned (it can act on nothing that needs a signature), so
/// that a listener can answer a key holder whose clock is behind. Counted
/// as a stale timestamp either way. Where unsigned frames are refused, all
/// three drop it.
#[test]
fn a_replay_is_returned_unauthenticated_where_unsigned_frames_are_accepted() {
    let hb = fbwag("HEARTBEAT");
    let header = Header {
        seq: 0,
        sysid: 1,
        compid: 1,
    };
    let f1 = build_frame(hb, Mode::V2s, header, &[1; 9], 0, 1000, &KEY);
    let stream = [f1.clone(), f1.clone()].concat();
    let (py, c) = peer_streams("fbwag", Policy::KeyAcceptUnsigned, &stream);
    assert_eq!(
        py,
        format!("{}\t-\t0", hex(&f1)),
        "pymavlink drops the replay"
    );
    assert_eq!(c, hex(&f1), "the C library drops the replay");
    let (got, stats) =
        rust_parse::<fbwag_dialect::Dialect>(&stream, Policy::KeyAcceptUnsigned, || 0);
    let got: Vec<_> = got
        .iter()
        .map(|g| (g.bytes.clone(), g.authenticated))
        .collect();
    assert_eq!(got, vec![(f1.clone(), true), (f1.clone(), false)]);
    assert_eq!(stats.stale_timestamp, 1);
    let (got, _) = rust_parse::<fbwag_dialect::Dialect>(&stream, Policy::KeyRejectUnsigned, || 0);
    assert_eq!(got.len(), 1);
}

/// A signed frame cut inside its signature block, followed by a good frame:
/// the checksum is intact, so without a key the cut frame plus the next
/// frame's first bytes is a valid frame for all three parsers, and that good
/// frame is lost to all (nothing can tell). tests/wire.rs counts such frames
/// apart. With a key see tests/fixed_bugs.rs (B2).
#[test]
fn truncated_signature_block_without_key() {
    let hb = fbwag("HEARTBEAT");
    let header = Header {
        seq: 0,
        sysid: 1,
        compid: 1,
    };
    let mut cut = build_frame(hb, Mode::V2s, header, &[1; 9], 0, 1000, &KEY);
    cut.truncate(cut.len() - 5);
    let g = build_frame(
        hb,
        Mode::V2,
        Header { seq: 1, ..header },
        &[2; 9],
        0,
        0,
        &KEY,
    );
    let h = build_frame(
        hb,
        Mode::V2,
        Header { seq: 2, ..header },
        &[3; 9],
        0,
        0,
        &KEY,
    );
    let stream = [cut.clone(), g.clone(), h.clone()].concat();
    let merged = [cut, g[..5].to_vec()].concat();
    let expect = format!("{} {}", hex(&merged), hex(&h));
    let (py, c) = peer_streams("fbwag", Policy::NoKey, &stream);
    assert_eq!(py, format!("{expect}\t-\t0"));
    assert_eq!(c, expect);
    let (got, _) = rust_parse::<fbwag_dialect::Dialect>(&stream, Policy::NoKey, || 0);
    let got: Vec<_> = got.iter().map(|g| hex(&g.bytes)).collect();
    assert_eq!(got.join(" "), expect);
}

/// pymavlink decodes a NUL scalar `char` (TEST_TYPES.c) as b'' and then
/// cannot pack the message it decoded (struct.error: the 'c' format needs one
/// byte). mavframe and the C library round-trip it.
#[test]
fn pymavlink_cannot_repack_a_decoded_nul_scalar_char() {
    let meta = conformance::all_xml::all::MESSAGES
        .iter()
        .find(|m| m.name == "TEST_TYPES")
        .unwrap();
    let payload = vec![0u8; meta.max_len as usize];
    let header = Header {
        seq: 0,
        sysid: 1,
        compid: 1,
    };
    let frame = build_frame(meta, Mode::V2, header, &payload, 0, 0, &KEY);
    let out = python(&format!(
        "import struct\nfrom pymavlink.dialects.v20 import all as mod\nmav = mod.MAVLink(None)\n\
         m = mav.parse_char(bytes.fromhex('{}'))\nprint(repr(m._c_raw))\n\
         try:\n    m.pack(mav)\n    print('packed')\nexcept struct.error as e:\n    print('struct.error')",
        hex(&frame)
    ));
    assert_eq!(
        out.split_whitespace().collect::<Vec<_>>(),
        ["b''", "struct.error"]
    );
    let r = rust_decode::<conformance::all_xml::all::Dialect>(&frame, false);
    assert_eq!(r.reencoded.unwrap(), frame);
}

/// FBWAG_NOTICE's fields system_id/component_id clash with the parameters
/// of the C generator's pack functions (docs/c-generator-name-clash.md): the
/// generated header does not compile; after c-lib.sh's rename of the
/// sender-id parameters it does, and `_pack_chan` gives pymavlink's and
/// mavframe's bytes.
#[test]
fn fbwag_notice_c_name_clash_and_work_around() {
    let _ = peers::c_harness("fbwag"); // generated and patched
    let patched = repo().join("target/conformance-c/fbwag/include");
    let dir = peers::scratch("fbwag", &format!("name-clash-{}", std::process::id()));
    let prog = dir.join("notice.c");
    std::fs::write(
        &prog,
        r#"#include <stdio.h>
#include "mavlink.h"
int main(void) {
    mavlink_message_t msg;
    uint8_t buf[MAVLINK_MAX_PACKET_LEN];
    mavlink_msg_fbwag_notice_pack_chan(1, 1, MAVLINK_COMM_0, &msg, 7, 9, 1, "FBWAG", 123456);
    uint16_t n = mavlink_msg_to_send_buffer(buf, &msg);
    for (uint16_t i = 0; i < n; i++) printf("%02x", buf[i]);
    printf("\n");
    return 0;
}
"#,
    )
    .unwrap();
    // Unpatched: pymavlink's own output for fbwag.xml.
    let raw = dir.join("unpatched");
    let gen = Command::new(support::python())
        .args([
            "-m",
            "pymavlink.tools.mavgen",
            "--lang=C",
            "--wire-protocol=2.0",
            "-o",
        ])
        .arg(&raw)
        .arg(repo().join("message_definitions/fbwag.xml"))
        .output()
        .unwrap();
    assert!(gen.status.success());
    let gcc = |include: &std::path::Path, out: &std::path::Path| {
        Command::new("gcc")
            .args(["-std=gnu11", "-O1", "-Wno-address-of-packed-member", "-I"])
            .arg(include.join("fbwag"))
            .arg("-o")
            .arg(out)
            .arg(&prog)
            .output()
            .unwrap()
    };
    let broken = gcc(&raw, &dir.join("broken"));
    assert!(!broken.status.success(), "the unpatched header compiled");
    let err = String::from_utf8_lossy(&broken.stderr);
    assert!(
        err.contains("redefinition of parameter") && err.contains("system_id"),
        "{err}"
    );
    let ok = gcc(&patched, &dir.join("notice"));
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let run = Command::new(dir.join("notice")).output().unwrap();
    let c_hex = String::from_utf8(run.stdout).unwrap();
    assert_eq!(
        c_hex.trim(),
        "fd0c0000000101993a0040e2010007090146425741477aba"
    );
    // mavframe, same fields and sender.
    let notice = fbwag_dialect::FbwagNotice {
        system_id: 7,
        component_id: 9,
        failsafe_status: fbwag_dialect::FbwagFailsafeStatus::RC_LOST,
        text: *b"FBWAG",
        timestamp: 123_456,
    };
    let mut out = [0u8; 300];
    let n = mavframe::encode(
        Version::V2,
        Header {
            seq: 0,
            sysid: 1,
            compid: 1,
        },
        &notice,
        None::<&mut Signer>,
        &mut out,
    )
    .unwrap();
    assert_eq!(hex(&out[..n]), c_hex.trim());
    let _ = std::fs::remove_dir_all(&dir);
}

/// pymavlink's and the C library's accepted frames for one stream
/// (`wire.py streams` line, C harness line).
fn peer_streams(dialect: &str, policy: Policy, stream: &[u8]) -> (String, String) {
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = peers::scratch(dialect, &format!("stream-{}-{n}", std::process::id()));
    let input = dir.join("stream.txt");
    std::fs::write(&input, format!("{}\n", hex(stream))).unwrap();
    let key = if policy == Policy::NoKey {
        "-".to_string()
    } else {
        hex(&KEY)
    };
    let accept = if policy == Policy::KeyRejectUnsigned {
        "0"
    } else {
        "1"
    };
    let py = peers::pymavlink(
        &[
            "streams",
            "--dialect",
            dialect,
            "--key",
            &key,
            "--accept-unsigned",
            accept,
        ],
        &input,
    );
    let harness = peers::c_harness(dialect);
    let c = peers::c_lib(&harness, &["streams", &key, accept], &input);
    let _ = std::fs::remove_dir_all(&dir);
    (py[0].clone(), c[0].clone())
}
