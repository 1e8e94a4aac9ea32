//! The bodies of the fuzz targets, one function per target. libFuzzer runs
//! them through `fuzz_targets/*.rs`; `conformance/tests/fuzz_regressions.rs`
//! compiles this file too (`#[path]`) and replays every file of
//! `fuzz/corpus/<target>/` and `fuzz/regressions/<target>/` through them
//! under `cargo test`. Each function panics exactly when an invariant breaks.
//!
//! - [`parser`]: the streaming parser over any bytes, any chunking, any
//!   signing policy: same result for every chunking, returned frames whole,
//!   in order, checksums valid, policy respected, every byte accounted for;
//!   cut into datagrams, the same frames and counters whether each
//!   datagram's end is told up front (`next_in_datagram`) or after.
//! - [`frame`]: `frame_len` / `Frame::new_checked` and every accessor over
//!   any bytes; signature check; canonical frames re-encode identically.
//! - [`view`]: every message's zero-copy view and owned message over any
//!   payload (any length): accessors never panic, view and owned message
//!   agree, emit writes what was read, parse/emit is idempotent.
//! - [`xml`]: mavgen-rs's whole front end (`Schema::from_text`) over any
//!   text: diagnostics instead of panics; accepted layouts sane.

use fbwag_dialect::mavframe::field::read;
use fbwag_dialect::mavframe::frame::{
    finish, frame_len, truncated_len, Frame, Version, HEADER_LEN_V1, HEADER_LEN_V2, MAX_FRAME_LEN,
    SIGNATURE_LEN,
};
use fbwag_dialect::mavframe::parser::{Parser, Stats, Unsigned};
use fbwag_dialect::mavframe::signing::Verifier;
use fbwag_dialect::mavframe::MessageSet as _;
use fbwag_dialect::{Dialect, Message, MessageView};

/// The key of the signing policies (frames in the corpus are signed with it).
pub const KEY: [u8; 32] = [0x42; 32];

type Got = (Vec<u8>, bool, bool);

/// How [`run_parser`] pushes its chunks.
#[derive(Clone, Copy)]
enum Ends {
    /// A stream, flushed at the end.
    Stream,
    /// Each chunk a datagram, ended by `end_of_datagram`; its end told up
    /// front (`next_in_datagram`, as the connections parse UDP) or not.
    Datagrams { told: bool },
}

/// The stream through a parser of the signing `policy`, in chunks of
/// `chunk(i)` bytes pushed as `ends` says: the frames and the counters.
fn run_parser(
    stream: &[u8],
    policy: u8,
    mut chunk: impl FnMut(usize) -> usize,
    ends: Ends,
) -> (Vec<Got>, Stats) {
    let mut p = match policy {
        0 => Parser::<Dialect>::new(),
        1 => Parser::<Dialect>::with_signing(Verifier::new(KEY), Unsigned::Accept),
        _ => Parser::<Dialect>::with_signing(Verifier::new(KEY), Unsigned::Refuse),
    };
    let got = |rx: fbwag_dialect::mavframe::parser::Received<'_, Dialect>| {
        (
            rx.frame().as_bytes().to_vec(),
            rx.meta().is_some(),
            rx.is_authenticated(),
        )
    };
    let mut out = Vec::new();
    let mut rest = stream;
    let mut i = 0;
    while !rest.is_empty() {
        let n = chunk(i).clamp(1, rest.len());
        i += 1;
        let (mut c, tail) = rest.split_at(n);
        rest = tail;
        loop {
            let rx = match ends {
                Ends::Datagrams { told: true } => p.next_in_datagram(&mut c),
                _ => p.next(&mut c),
            };
            match rx {
                Some(rx) => out.push(got(rx)),
                None => break,
            }
        }
        assert!(c.is_empty(), "input left unconsumed");
        if let Ends::Datagrams { .. } = ends {
            while let Some(rx) = p.end_of_datagram() {
                out.push(got(rx));
            }
            assert_eq!(p.pending(), 0, "bytes held after the end of a datagram");
        }
    }
    while let Some(rx) = p.flush() {
        out.push(got(rx));
    }
    (out, *p.stats())
}

/// Byte 0: signing policy (no key / key, unsigned accepted / key, unsigned
/// refused) and chunking; the rest is the stream.
pub fn parser(data: &[u8]) {
    let Some((&cfg, stream)) = data.split_first() else {
        return;
    };
    let policy = cfg % 3;
    let seed = (cfg / 3) as usize;
    let chunks = |i: usize| 1 + (seed * 7 + i * 13) % (seed + 1);
    let (chunked, stats) = run_parser(stream, policy, chunks, Ends::Stream);
    let (whole, whole_stats) = run_parser(stream, policy, |_| usize::MAX, Ends::Stream);
    assert_eq!(chunked, whole, "chunking changed the frames");
    assert_eq!(stats, whole_stats, "chunking changed the counters");
    // Datagrams: told their end up front, the same as ended after.
    let size = |i: usize| 1 + (seed * 11 + i * 29) % (4 * seed + 8);
    let told = run_parser(stream, policy, size, Ends::Datagrams { told: true });
    let ended = run_parser(stream, policy, size, Ends::Datagrams { told: false });
    assert_eq!(
        told, ended,
        "next_in_datagram changed the frames or counters"
    );
    assert_eq!(
        stats.frames + stats.unknown_frames,
        whole.len() as u64,
        "frame counters"
    );
    let mut at = 0;
    let mut returned = 0u64;
    for (bytes, known, authenticated) in &whole {
        let f = Frame::new_checked(bytes).expect("returned frames are whole");
        assert_eq!(f.as_bytes().len(), bytes.len());
        // In stream order, without overlap.
        let pos = stream[at..]
            .windows(bytes.len())
            .position(|w| w == &bytes[..])
            .expect("returned frame is in the stream after the previous one");
        at += pos + bytes.len();
        returned += bytes.len() as u64;
        if *known {
            let m = Dialect::meta(f.msg_id()).expect("known id");
            assert!(f.check_crc(m.crc_extra), "known frame with a bad checksum");
            // Signed and returned unverified only where unsigned frames
            // are accepted, and only with the key's signature (a frame
            // whose timestamp is stale).
            if policy != 0 && f.is_signed() && !*authenticated {
                assert_eq!(policy, 1, "signed frame accepted unverified");
                let key_signed = Verifier::<1>::new(KEY).signed_with_key(&f);
                assert!(key_signed, "forged signed frame accepted unverified");
            }
        }
        if policy == 2 {
            assert!(f.is_signed(), "unsigned frame accepted while refused");
        }
        if policy == 0 {
            assert!(!*authenticated);
        }
    }
    let total = stream.len() as u64;
    let skipped = stats.bad_signature + stats.stale_timestamp + stats.unsigned_rejected;
    assert!(
        returned + stats.bytes_dropped <= total,
        "more bytes than input"
    );
    let rest = total - returned - stats.bytes_dropped;
    assert!(
        rest <= skipped * MAX_FRAME_LEN as u64,
        "{rest} bytes neither returned, dropped nor in a counted rejected frame"
    );
}

/// Any bytes as a frame.
pub fn frame(data: &[u8]) {
    let len = frame_len(data);
    let f = match Frame::new_checked(data) {
        Ok(f) => f,
        Err(_) => {
            if let Ok(n) = len {
                assert!(data.len() < n, "new_checked refused a whole frame");
            }
            return;
        }
    };
    let n = f.as_bytes().len();
    assert_eq!(len, Ok(n));
    let (version, h, id, payload) = (f.version(), f.header(), f.msg_id(), f.payload());
    assert_eq!(payload.len(), f.payload_len());
    let _ = (f.checksum(), f.incompat_flags(), f.compat_flags());
    for extra in [0u8, 50, 255] {
        let _ = f.computed_checksum(extra);
    }
    if let Some(s) = f.signature() {
        assert!(f.is_signed());
        assert_eq!(s.as_bytes().len(), SIGNATURE_LEN);
        let _ = (s.link_id(), s.timestamp(), s.signature());
    }
    let mut v = Verifier::<2>::new(KEY);
    let _ = v.verify(&f);
    let _ = v.verify(&f);
    // A canonical frame of a known message re-encodes identically.
    let Some(m) = Dialect::meta(id) else {
        return;
    };
    if !f.check_crc(m.crc_extra) || f.is_signed() || f.compat_flags() != 0 {
        return;
    }
    let canonical = match version {
        Version::V2 => {
            payload.len() <= m.max_len as usize && truncated_len(payload) == payload.len()
        }
        Version::V1 => payload.len() == m.min_len as usize,
    };
    if canonical {
        let start = if version == Version::V2 {
            HEADER_LEN_V2
        } else {
            HEADER_LEN_V1
        };
        let mut out = [0u8; MAX_FRAME_LEN];
        out[start..start + payload.len()].copy_from_slice(payload);
        let n = finish(version, h, m, payload.len(), None, &mut out).expect("fits");
        assert_eq!(
            &out[..n],
            f.as_bytes(),
            "canonical frame re-encodes differently"
        );
    }
}

/// Bytes 0-1 choose a message (or, past the table, bytes 2-4 a raw id);
/// the rest is its payload, of any length.
pub fn view(data: &[u8]) {
    if data.len() < 2 {
        return;
    }
    let msgs = Dialect::MESSAGES;
    let pick = u16::from_le_bytes([data[0], data[1]]) as usize % (msgs.len() + 1);
    let (id, payload) = if pick < msgs.len() {
        (msgs[pick].id, &data[2..])
    } else {
        let raw = data.get(2..5).unwrap_or(&[]);
        let mut b = [0u8; 4];
        b[..raw.len()].copy_from_slice(raw);
        (u32::from_le_bytes(b), data.get(5..).unwrap_or(&[]))
    };
    let Some(view) = MessageView::new(id, payload) else {
        assert!(Dialect::meta(id).is_none());
        assert!(Message::parse(id, payload).is_none());
        return;
    };
    let meta = view.meta();
    assert_eq!(meta.id, id);
    let owned = view.to_message();
    assert_eq!(owned.id(), id);
    let mut a = [0u8; 256];
    let na = owned.emit(&mut a).expect("emit");
    assert_eq!(na, meta.max_len as usize);
    let mut b = [0u8; 256];
    let parsed = Message::parse(id, payload).expect("known");
    let nb = parsed.emit(&mut b).expect("emit");
    assert_eq!(a[..na], b[..nb], "view and parse disagree");
    // What was emitted is what was read, field by field.
    for f in meta.fields {
        let at = f.offset as usize;
        let len = f.wire_len();
        let wire: Vec<u8> = (0..len).map(|k| read::<u8>(payload, at + k)).collect();
        let out = &a[at..at + len];
        // Every byte, strings included (bytes after a NUL too: fixed bug B1).
        assert_eq!(out, &wire[..], "{}.{}", meta.name, f.name);
    }
    // Idempotent: parsing what was emitted emits the same bytes.
    let again = Message::parse(id, &a[..na]).expect("known");
    let mut c = [0u8; 256];
    let nc = again.emit(&mut c).expect("emit");
    assert_eq!(a[..na], c[..nc]);
    let _ = format!("{owned:?} {view:?}");
}

/// Any bytes as an XML dialect file, through the whole front end
/// (`Schema::from_text`: the reader, then includes, merging and checks).
/// The text is named as a file in a directory that does not exist, so
/// relative includes fail without reading the disk; an absolute include
/// is read with the generator's bounds (regular files, 8 MiB), as a user's
/// would be.
pub fn xml(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let path = "/nonexistent-fbwag-fuzz/fuzz.xml";
    match mavgen_rs::Schema::from_text(path, &text) {
        Ok(schema) => {
            for m in schema.messages() {
                assert!(m.min_len() <= m.max_len() && m.max_len() <= 255);
                for f in m.fields() {
                    assert!(f.offset() + f.wire_len() <= m.max_len(), "{}", m.name());
                }
            }
            for w in schema.warnings() {
                let _ = w.to_string();
            }
        }
        Err(diags) => {
            assert!(!diags.is_empty(), "refused without a diagnostic");
            for d in diags {
                let _ = d.to_string();
            }
        }
    }
}
