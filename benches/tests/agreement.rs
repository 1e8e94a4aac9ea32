//! What the benchmarks rely on, checked without the telemetry capture: both
//! libraries see the same FBWAG_NOTICE, the generated `Dialect::meta` (a
//! `match`) is the table lookup it replaces, and the owned decoders'
//! constructor tables (`Message::parse`, `MessageView::to_message`) build
//! the variant of the frame's id from all of its bytes.

use benches::mavlink_fbwag::fbwag::MavMessage as TheirFbwag;
use benches::{mavlink_header, OurEncoder, TheirEncoder, Theirs, KEY};
use fbwag_dialect::mavframe::{MessageSet as _, Verifier};
use fbwag_dialect::{
    Dialect, FbwagNotice, Header, Message, MessageView, Parser, Unsigned, MESSAGES,
};
use mavlink::Message as _;

#[test]
fn generated_meta_equals_the_table_lookup() {
    let lookup = |id: u32| {
        MESSAGES
            .binary_search_by_key(&id, |m| m.id)
            .ok()
            .map(|i| &MESSAGES[i])
    };
    let ids = (0..=70_000u32)
        .chain(
            MESSAGES
                .iter()
                .flat_map(|m| [m.id.saturating_sub(1), m.id, m.id + 1]),
        )
        .chain([(1 << 24) - 1, 1 << 24, u32::MAX]);
    for id in ids {
        assert_eq!(Dialect::meta(id), lookup(id), "id {id}");
    }
}

#[test]
fn owned_decoders_build_the_variant_of_the_id_from_every_byte() {
    let mut out = [0u8; 255];
    for meta in MESSAGES {
        let max = usize::from(meta.max_len);
        // A byte pattern with no zero (zeros would hide a byte not copied),
        // different for each message; every truncation of it, empty included.
        let full: Vec<u8> = (0..max)
            .map(|i| (i as u32 * 7 + meta.id) as u8 | 1)
            .collect();
        for len in 0..=max {
            let payload = &full[..len];
            let owned = Message::parse(meta.id, payload).expect("a known id");
            let via_view = MessageView::new(meta.id, payload)
                .expect("a known id")
                .to_message();
            assert_eq!(owned.id(), meta.id, "{} len {len}", meta.name);
            assert_eq!(via_view.id(), meta.id, "{} len {len}", meta.name);
            // Compared as bytes: a float field may hold a NaN pattern.
            for msg in [owned, via_view] {
                assert_eq!(msg.emit(&mut out), Ok(max), "{}", meta.name);
                assert_eq!(&out[..len], payload, "{} len {len}", meta.name);
                assert!(
                    out[len..max].iter().all(|&b| b == 0),
                    "{} len {len}",
                    meta.name
                );
            }
        }
    }
}

#[test]
fn mavlink_bindgen_gives_fbwag_notice_our_crc_extra() {
    assert_eq!(
        TheirFbwag::extra_crc(FbwagNotice::ID),
        FbwagNotice::CRC_EXTRA
    );
}

#[test]
fn both_libraries_decode_the_notice_stream_alike() {
    let stream = benches::notice_stream(30);
    let mut ours = Vec::new();
    let mut parser = Parser::new();
    let mut input = &stream[..];
    while let Some(r) = parser.next(&mut input) {
        let Some(MessageView::FbwagNotice(v)) = r.view() else {
            panic!("not a notice")
        };
        ours.push((
            v.timestamp(),
            v.failsafe_status().to_raw(),
            v.text().to_array(),
        ));
    }
    let mut theirs = Vec::new();
    let mut reader = mavlink::MavlinkReader::new(&stream[..]);
    while let Ok((_, TheirFbwag::FBWAG_NOTICE(m))) = reader.read_any_message::<TheirFbwag>() {
        theirs.push((m.timestamp, m.failsafe_status as u8, *m.text));
    }
    assert_eq!(ours.len(), 30);
    assert_eq!(ours, theirs);
}

#[test]
fn signed_frames_of_each_library_verify_with_ours() {
    let notice = Message::FbwagNotice(FbwagNotice {
        timestamp: 42,
        ..Default::default()
    });
    let header = Header {
        seq: 1,
        sysid: 1,
        compid: 191,
    };
    let frame = OurEncoder::new(false).encode(header, &notice).to_vec();
    let theirs = Theirs::Fbwag(
        mavlink::MavlinkReader::new(&frame[..])
            .read_any_message()
            .expect("mavlink decodes it")
            .1,
    );
    let mut stream = OurEncoder::new(true).encode(header, &notice).to_vec();
    stream.extend_from_slice(TheirEncoder::new(true).encode_any(mavlink_header(header), &theirs));
    let mut parser = Parser::with_signing(Verifier::new(KEY), Unsigned::Refuse);
    let mut input = &stream[..];
    let mut authenticated = 0;
    while let Some(r) = parser.next(&mut input) {
        assert!(r.is_authenticated());
        authenticated += 1;
    }
    assert_eq!(authenticated, 2, "{:?}", parser.stats());
}
