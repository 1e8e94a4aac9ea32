//! Property tests (proptest) of encode → decode identity for every message of
//! fbwag.xml and all.xml, through the generated owned messages and the
//! streaming parser:
//!
//! 1. payload identity: for any payload whose `char[N]` fields are strings
//!    (nothing after the first NUL; bytes after it: tests/fixed_bugs.rs), `emit(parse(p)) == p`;
//! 2. frame identity: that message framed as MAVLink 2, MAVLink 2 signed
//!    and MAVLink 1 (ids <= 255), with any header and signing link/timestamp,
//!    comes out of a fresh `Parser` exactly once, whole, authenticated when
//!    signed, with the same header, and its owned message re-emits the
//!    payload (extensions zero in MAVLink 1);
//! 3. normalisation: for any bytes of any length, `parse` then `emit` is
//!    idempotent.
//!
//! `PROPTEST_CASES` sets the cases per message (default 48).

mod support;

use mavframe::frame::Header;
use mavframe::{FieldType, MessageMeta, MessageSet, Parser, Unsigned, Verifier};
use proptest::collection::vec;
use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use support::frames::{build_frame, Mode, Owned, KEY};
use support::values::zero_extensions;

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(48)
}

fn strings_only(meta: &MessageMeta, payload: &mut [u8]) {
    for f in meta
        .fields
        .iter()
        .filter(|f| f.ty == FieldType::Char && f.array_len > 0)
    {
        let at = f.offset as usize;
        let field = &mut payload[at..at + f.array_len as usize];
        if let Some(nul) = field.iter().position(|&b| b == 0) {
            field[nul..].fill(0);
        }
    }
}

fn emit<M: Owned>(m: &M) -> Vec<u8> {
    let mut out = vec![0u8; 256];
    let n = m.emit_into(&mut out).expect("emit");
    out.truncate(n);
    out
}

fn identity<D: MessageSet>() -> usize
where
    D::Message: Owned,
{
    let mut checked = 0;
    for meta in D::MESSAGES {
        let max = meta.max_len as usize;
        let modes: Vec<Mode> = Mode::ALL
            .into_iter()
            .filter(|&m| m != Mode::V1 || meta.id <= 255)
            .collect();
        let strategy = (
            vec(any::<u8>(), max),
            any::<[u8; 3]>(),
            0..modes.len(),
            any::<u8>(),
            0u64..(1 << 48),
        );
        let mut runner = TestRunner::new(Config {
            cases: cases(),
            failure_persistence: None,
            ..Config::default()
        });
        let result = runner.run(&strategy, |(mut payload, h, mode, link, ts)| {
            strings_only(meta, &mut payload);
            let msg = D::parse(meta.id, &payload).expect("known id");
            prop_assert_eq!(msg.row().id, meta.id);
            prop_assert_eq!(&emit(&msg), &payload, "emit(parse(p)) != p");

            let mode = modes[mode];
            let header = Header {
                seq: h[0],
                sysid: h[1],
                compid: h[2],
            };
            let frame = build_frame(meta, mode, header, &emit(&msg), link, ts, &KEY);
            let mut parser = Parser::<D>::with_signing(Verifier::new(KEY), Unsigned::Accept);
            let mut input = &frame[..];
            let mut got = Vec::new();
            while let Some(rx) = parser.next(&mut input) {
                got.push((
                    rx.frame().as_bytes().to_vec(),
                    rx.frame().header(),
                    rx.is_authenticated(),
                    rx.message(),
                ));
            }
            while let Some(rx) = parser.flush() {
                got.push((
                    rx.frame().as_bytes().to_vec(),
                    rx.frame().header(),
                    rx.is_authenticated(),
                    rx.message(),
                ));
            }
            prop_assert_eq!(got.len(), 1, "one frame in, one frame out");
            let (bytes, hdr, auth, decoded) = got.pop().unwrap();
            prop_assert_eq!(&bytes, &frame);
            prop_assert_eq!(hdr, header);
            prop_assert_eq!(auth, mode == Mode::V2s);
            let mut expected = payload.clone();
            if mode == Mode::V1 {
                zero_extensions(meta, &mut expected);
            }
            prop_assert_eq!(&emit(&decoded.expect("known")), &expected);
            Ok(())
        });
        if let Err(e) = result {
            panic!("{} (id {}): {e}", meta.name, meta.id);
        }
        // 3. Any bytes, any length: parse/emit is idempotent.
        let mut runner = TestRunner::new(Config {
            cases: cases() / 4,
            failure_persistence: None,
            ..Config::default()
        });
        let result = runner.run(&vec(any::<u8>(), 0..=max + 8), |bytes| {
            let once = emit(&D::parse(meta.id, &bytes).expect("known id"));
            let twice = emit(&D::parse(meta.id, &once).expect("known id"));
            prop_assert_eq!(once, twice);
            Ok(())
        });
        if let Err(e) = result {
            panic!("{} (id {}): {e}", meta.name, meta.id);
        }
        checked += 1;
    }
    checked
}

#[test]
fn every_fbwag_message_round_trips() {
    let n = identity::<fbwag_dialect::Dialect>();
    assert!(n >= 300, "{n} messages");
}

#[test]
fn every_all_xml_message_round_trips() {
    let n = identity::<conformance::all_xml::all::Dialect>();
    assert!(n >= 350, "{n} messages");
}
