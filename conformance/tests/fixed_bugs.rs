//! Bugs the conformance work found in the runtime, kept as regression tests:
//! each states the correct behaviour, which the fix made true
//! (docs/conformance.md).

mod support;

use mavframe::frame::Header;
use mavframe::{Parser, Unsigned, Verifier};
use support::frames::{build_frame, Mode, KEY};
use support::three_way::three_way;
use support::values::hex;

fn fbwag(name: &str) -> &'static mavframe::MessageMeta {
    fbwag_dialect::MESSAGES
        .iter()
        .find(|m| m.name == name)
        .unwrap()
}

/// B1. A `char[N]` field holding bytes after its first NUL (pymavlink packs
/// them from `_<name>_raw`, the C library memcpy's them) does not survive
/// mavframe's owned messages: `from_view` copies `CharArray::to_array()`,
/// which stops at the first NUL and zero-pads, so `parse` then `emit` changes
/// the payload and re-encoding a received frame changes its bytes (and its
/// CRC). The field-table path (`mavframe::field`, fbwag-cli) keeps them. Fix
/// in mavgen-rs's codegen (`from_view`: copy the field's N raw bytes) or in
/// mavframe (`CharArray::to_array` keeping the raw array).
#[test]
fn owned_messages_keep_char_bytes_after_the_first_nul() {
    let meta = fbwag("STATUSTEXT");
    let mut payload = vec![0u8; meta.max_len as usize];
    payload[1..6].copy_from_slice(b"ab\0cd"); // text at offset 1
                                              // The peers keep the bytes: pymavlink and C send exactly mavframe's frame.
    let t = three_way("fbwag", meta, Mode::V2, &payload);
    assert_eq!(t.py, t.rust);
    assert_eq!(t.c, t.rust);
    // mavframe's owned message does not.
    let msg = fbwag_dialect::Message::parse(meta.id, &payload).unwrap();
    let mut out = vec![0u8; meta.max_len as usize];
    msg.emit(&mut out).unwrap();
    assert_eq!(hex(&out), hex(&payload), "parse→emit changed the payload");
}

/// B2. With a key, a signed frame whose checksum is good but whose signature
/// fails is skipped whole (`parser::check`: `Verdict::Skip(len)`). When the
/// frame was cut inside its signature block, the "signature" is the head of
/// the next, good frame, which is lost with it: the parser does not
/// resynchronise inside the rejected frame's claimed length, as it must (a
/// rejected frame never swallows the good frames inside the length it
/// claimed). pymavlink and the C library lose it too. Fix: on a bad
/// signature, drop the frame up to its checksum and rescan the 13 signature
/// bytes (counting them dropped when nothing starts there).
#[test]
fn bad_signature_frame_does_not_hide_the_next_frame() {
    let hb = fbwag("HEARTBEAT");
    let header = Header {
        seq: 0,
        sysid: 1,
        compid: 1,
    };
    let mut cut = build_frame(hb, Mode::V2s, header, &[1; 9], 0, 1000, &KEY);
    cut.truncate(cut.len() - 5);
    let good = build_frame(
        hb,
        Mode::V2s,
        Header { seq: 1, ..header },
        &[2; 9],
        0,
        1001,
        &KEY,
    );
    let stream = [cut, good.clone()].concat();
    let mut p =
        Parser::<fbwag_dialect::Dialect>::with_signing(Verifier::new(KEY), Unsigned::Accept);
    let mut input = &stream[..];
    let mut got = Vec::new();
    while let Some(rx) = p.next(&mut input) {
        got.push(rx.frame().as_bytes().to_vec());
    }
    while let Some(rx) = p.flush() {
        got.push(rx.frame().as_bytes().to_vec());
    }
    assert_eq!(p.stats().bad_signature, 1);
    assert_eq!(got, vec![good], "the good frame after the cut one is lost");
}
