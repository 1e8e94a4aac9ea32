//! The streaming parser on the FBWAG dialect: chunking, recovery, signing
//! policy, raw frames of unknown ids, counters, and no panics on any input.
// Uses messages outside the companion-computer subset.

use fbwag_dialect::dialects::{common, minimal};
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::mavframe::frame::{encode, Header, Version};
use fbwag_dialect::mavframe::parser::{Parser, Unsigned};
use fbwag_dialect::mavframe::{MessageSet as _, Signer, Verifier};
use fbwag_dialect::{Dialect, FbwagFailsafeStatus, FbwagNotice};

/// A small deterministic generator (xorshift), so failures reproduce.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn byte(&mut self) -> u8 {
        self.next() as u8
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn frame_of<M: fbwag_dialect::mavframe::MessageData>(
    seq: u8,
    m: &M,
    v: Version,
    signer: Option<&mut Signer>,
) -> Vec<u8> {
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    let h = Header {
        seq,
        sysid: 1,
        compid: 1,
    };
    let n = encode(v, h, m, signer, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// A mixed telemetry-like stream: notices (with 0xFD/0xFE inside their
/// payloads), heartbeats, attitude, RC overrides; MAVLink 1 and 2.
fn frames(n: usize, rng: &mut Rng) -> Vec<Vec<u8>> {
    (0..n)
        .map(|i| {
            let seq = i as u8;
            match i % 4 {
                0 => frame_of(
                    seq,
                    &FbwagNotice {
                        system_id: 0xFD,
                        component_id: 0xFE,
                        failsafe_status: FbwagFailsafeStatus(rng.byte() % 3),
                        text: chars("FBWAG"),
                        timestamp: rng.next() as u32 | 0xFD00_00FE,
                    },
                    Version::V2,
                    None,
                ),
                1 => frame_of(
                    seq,
                    &minimal::Heartbeat::default(),
                    if i % 8 == 1 { Version::V1 } else { Version::V2 },
                    None,
                ),
                2 => frame_of(
                    seq,
                    &common::Attitude {
                        time_boot_ms: rng.next() as u32,
                        roll: f32::from_bits(rng.next() as u32),
                        yaw: -1.5,
                        ..Default::default()
                    },
                    Version::V2,
                    None,
                ),
                _ => frame_of(
                    seq,
                    &common::RcChannelsOverride {
                        target_system: 1,
                        chan1_raw: 0xFDFE,
                        chan3_raw: 1500,
                        ..Default::default()
                    },
                    Version::V2,
                    None,
                ),
            }
        })
        .collect()
}

/// Feeds `stream` in chunks of `chunk` bytes; returns the frames' bytes.
fn parse_all(parser: &mut Parser<Dialect>, stream: &[u8], chunk: usize) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for mut piece in stream.chunks(chunk.max(1)) {
        while let Some(r) = parser.next(&mut piece) {
            out.push(r.frame().as_bytes().to_vec());
        }
    }
    while let Some(r) = parser.flush() {
        out.push(r.frame().as_bytes().to_vec());
    }
    out
}

#[test]
fn every_chunking_yields_the_same_frames() {
    let frames = frames(24, &mut Rng(1));
    let stream: Vec<u8> = frames.concat();
    for chunk in 1..=stream.len() {
        let mut p = Parser::<Dialect>::new();
        assert_eq!(
            parse_all(&mut p, &stream, chunk),
            frames,
            "chunk size {chunk}"
        );
        assert_eq!(
            (p.stats().frames, p.stats().bytes_dropped, p.stats().bad_crc),
            (24, 0, 0)
        );
    }
}

#[test]
fn frames_in_the_chunk_are_returned_without_copy() {
    let stream = frames(3, &mut Rng(2)).concat();
    let mut p = Parser::<Dialect>::new();
    let mut input: &[u8] = &stream;
    let r = p.next(&mut input).unwrap();
    assert!(
        core::ptr::eq(r.frame().as_bytes().as_ptr(), stream.as_ptr()),
        "borrowed from the input"
    );
    assert_eq!(
        r.view()
            .map(|v| matches!(v, fbwag_dialect::MessageView::FbwagNotice(_))),
        Some(true)
    );
}

/// After a chunk boundary cuts a candidate, the parser works from its
/// buffer; once the bytes held from the earlier chunk are dropped it goes
/// back to the input in place. Garbage returning a frame of an unknown id
/// every few bytes (the worst input of `benches/src/worst.rs`) kept it in
/// its buffer, copying every byte, up to the end of the chunk.
#[test]
fn the_parser_goes_back_in_place_after_a_chunk_boundary() {
    // A frame of unknown id 0xFF confirmed by the 0xFE after it, among
    // candidates of known ids with bad checksums.
    let pattern = [0xfe, 0x00, 0xfe, 0xfe, 0xfe, 0xff, 0xfe, 0xfe, 0xfe];
    let stream: Vec<u8> = pattern.iter().copied().cycle().take(40_000).collect();
    let (first, second) = stream.split_at(20_000);
    let mut p = Parser::<Dialect>::new();
    let mut input = first;
    while p.next(&mut input).is_some() {}
    let range = second.as_ptr_range();
    let (mut in_place, mut copied) = (0, 0);
    let mut input = second;
    while let Some(r) = p.next(&mut input) {
        assert_eq!(r.frame().as_bytes().len(), 8);
        if range.contains(&r.frame().as_bytes().as_ptr()) {
            in_place += 1;
        } else {
            copied += 1;
        }
    }
    // Frames within a buffer's length (1 KiB) of the boundary come from
    // the buffer; the rest of the chunk's 2,222 from the input.
    assert!(copied <= 1024 / 9, "{copied} frames from the buffer");
    assert!(in_place + copied >= 2_200, "{in_place} + {copied} frames");
}

#[test]
fn garbage_between_frames_loses_no_frame() {
    let mut rng = Rng(3);
    for trial in 0..200 {
        let frames = frames(12, &mut rng);
        let mut stream = Vec::new();
        let mut garbage = 0;
        for f in &frames {
            let n = rng.below(40);
            for _ in 0..n {
                // Plenty of false start bytes.
                stream.push(match rng.below(4) {
                    0 => 0xFD,
                    1 => 0xFE,
                    _ => rng.byte(),
                });
            }
            garbage += n;
            stream.extend_from_slice(f);
        }
        let chunk = 1 + rng.below(64);
        let mut p = Parser::<Dialect>::new();
        let got = parse_all(&mut p, &stream, chunk);
        let known: Vec<_> = got.iter().filter(|f| frames.contains(f)).cloned().collect();
        if known != frames {
            let raws: Vec<_> = got.iter().filter(|f| !frames.contains(f)).collect();
            eprintln!("chunk {chunk} raw: {raws:02x?}\nstats {:?}", p.stats());
        }
        assert_eq!(known, frames, "trial {trial}: every good frame, in order");
        let s = p.stats();
        assert_eq!(
            s.frames, 12,
            "trial {trial}: no garbage accepted as a known message"
        );
        let raw: usize = got
            .iter()
            .filter(|f| !frames.contains(f))
            .map(Vec::len)
            .sum();
        assert_eq!(
            s.bytes_dropped as usize + raw,
            garbage,
            "trial {trial}: every garbage byte accounted for"
        );
    }
}

/// Datagrams of garbage dense in start bytes, a good frame somewhere in
/// most (after garbage, so that the fast rejection loop reaches it), each
/// parsed alone (`next_in_datagram`, then `end_of_datagram`): every good
/// frame comes out, in order. The end of each datagram cuts most of its
/// garbage's frames, and what the parser knows of the positions just
/// before that end must not be carried to the next datagram's bytes, which
/// follow at the next positions.
#[test]
fn datagrams_of_dense_garbage_lose_no_frame() {
    let mut rng = Rng(11);
    for trial in 0..300 {
        let frames = frames(8, &mut rng);
        let mut p = Parser::<Dialect>::new();
        let (mut got, mut sent) = (Vec::new(), Vec::new());
        for f in &frames {
            let mut datagram = Vec::new();
            let garbage = |rng: &mut Rng, n: usize, d: &mut Vec<u8>| {
                for _ in 0..n {
                    d.push(match rng.below(8) {
                        0..=2 => 0xFE,
                        3..=5 => 0xFD,
                        _ => rng.byte(),
                    });
                }
            };
            let n = rng.below(90);
            garbage(&mut rng, n, &mut datagram);
            if rng.below(4) != 0 {
                datagram.extend_from_slice(f);
                sent.push(f.clone());
            }
            let n = rng.below(40);
            garbage(&mut rng, n, &mut datagram);
            let mut input = &datagram[..];
            while let Some(r) = p.next_in_datagram(&mut input) {
                got.push(r.frame().as_bytes().to_vec());
            }
            while let Some(r) = p.end_of_datagram() {
                got.push(r.frame().as_bytes().to_vec());
            }
        }
        let known: Vec<_> = got.iter().filter(|f| frames.contains(f)).cloned().collect();
        assert_eq!(known, sent, "trial {trial}: every good frame, in order");
    }
}

/// A flush not called until `None` (a caller that takes one frame at the
/// end of what it has, then gets more bytes): the bytes held after the
/// frame it returned are those of the stream that goes on, in chunks
/// whose ends are not the stream's (frames cut by them wait), and what the
/// parser decided for the end of the stream no longer holds once more
/// bytes come. Every good frame comes out, in order, but one that the
/// flush's end cut.
#[test]
fn bytes_after_a_flush_not_drained_continue_the_stream() {
    let mut rng = Rng(17);
    for trial in 0..300 {
        let frames = frames(10, &mut rng);
        let mut stream = Vec::new();
        for f in &frames {
            for _ in 0..rng.below(30) {
                stream.push(match rng.below(4) {
                    0 => 0xFD,
                    1 => 0xFE,
                    _ => rng.byte(),
                });
            }
            stream.extend_from_slice(f);
        }
        let split = rng.below(stream.len());
        let mut p = Parser::<Dialect>::new();
        let mut got = Vec::new();
        let mut first = &stream[..split];
        while let Some(r) = p.next(&mut first) {
            got.push(r.frame().as_bytes().to_vec());
        }
        // One frame of the flush, if any, and no more.
        if let Some(r) = p.flush() {
            got.push(r.frame().as_bytes().to_vec());
        }
        // The rest in small chunks: frames cut by a chunk's end wait for
        // their bytes, as in any stream.
        let chunk = 1 + rng.below(20);
        for mut piece in stream[split..].chunks(chunk) {
            while let Some(r) = p.next(&mut piece) {
                got.push(r.frame().as_bytes().to_vec());
            }
        }
        while let Some(r) = p.flush() {
            got.push(r.frame().as_bytes().to_vec());
        }
        let known: Vec<_> = got.iter().filter(|f| frames.contains(f)).cloned().collect();
        // The flush ended the stream where it decided: a frame its end cut
        // (before the frame it returned, or with none) is lost, and only
        // that one.
        let lost = frames.iter().filter(|f| !known.contains(f)).count();
        assert!(lost <= 1, "trial {trial} split {split}: {lost} frames lost");
        if lost == 1 {
            // Only one that straddles the split.
            let at = frames
                .iter()
                .position(|f| !known.contains(f))
                .expect("the lost frame");
            let start = find(&stream, &frames[at]);
            assert!(
                start < split && split < start + frames[at].len(),
                "trial {trial} split {split}: frame {at} lost, not cut by the flush"
            );
        }
    }
}

/// Where `needle` first occurs in `hay`.
fn find(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len())
        .position(|w| w == needle)
        .expect("in the stream")
}

#[test]
fn corrupted_and_truncated_frames_do_not_swallow_the_next() {
    let mut rng = Rng(4);
    let frames = frames(30, &mut rng);
    // Frame 5: a bit flip in its payload; frame 11: cut after 7 bytes;
    // frame 17: its length byte inflated so it claims the frames after it.
    let mut stream = Vec::new();
    let mut expected = Vec::new();
    for (i, f) in frames.iter().enumerate() {
        match i {
            5 => {
                let mut bad = f.clone();
                bad[12] ^= 0x10;
                stream.extend_from_slice(&bad);
            }
            11 => stream.extend_from_slice(&f[..7]),
            17 => {
                let mut bad = f.clone();
                bad[1] = 250;
                stream.extend_from_slice(&bad);
            }
            _ => {
                stream.extend_from_slice(f);
                expected.push(f.clone());
            }
        }
    }
    for chunk in [1, 3, 17, 64, 1000] {
        let mut p = Parser::<Dialect>::new();
        assert_eq!(parse_all(&mut p, &stream, chunk), expected, "chunk {chunk}");
        assert!(p.stats().bad_crc >= 2, "{:?}", p.stats());
    }
}

#[test]
fn unknown_incompat_flags_are_rejected() {
    let mut f = frames(1, &mut Rng(5)).remove(0);
    f[2] = 0x02;
    let good = frames(2, &mut Rng(6));
    let stream = [f, good[0].clone(), good[1].clone()].concat();
    let mut p = Parser::<Dialect>::new();
    assert_eq!(parse_all(&mut p, &stream, 7), good);
    assert!(p.stats().bad_incompat_flags >= 1);
}

#[test]
fn signing_policy_replay_and_wrong_key() {
    let key = [9u8; 32];
    let notice = FbwagNotice {
        failsafe_status: FbwagFailsafeStatus::CC_TAKEOVER_CONFIRMED,
        ..Default::default()
    };
    let mut signer = Signer::new(key, 0, 5_000);
    let signed1 = frame_of(0, &notice, Version::V2, Some(&mut signer));
    let signed2 = frame_of(1, &notice, Version::V2, Some(&mut signer));
    let mut wrong = Signer::new([1u8; 32], 0, 9_000);
    let forged = frame_of(2, &notice, Version::V2, Some(&mut wrong));
    let unsigned = frame_of(3, &notice, Version::V2, None);
    let stream = [
        signed1.clone(),
        signed1.clone(),
        forged,
        unsigned.clone(),
        signed2.clone(),
    ]
    .concat();

    let mut strict = Parser::<Dialect>::with_signing(Verifier::new(key), Unsigned::Refuse);
    let got: Vec<_> = parse_all(&mut strict, &stream, 5);
    assert_eq!(got, vec![signed1.clone(), signed2.clone()]);
    let s = strict.stats();
    assert_eq!(
        (s.stale_timestamp, s.bad_signature, s.unsigned_rejected),
        (1, 1, 1),
        "replay; forged; unsigned refused"
    );

    // Where unsigned frames are accepted (unauthenticated), so is the
    // replay, the key's frame with a stale timestamp: a key holder whose
    // clock is behind can be answered. The forgery is not.
    let mut lenient = Parser::<Dialect>::with_signing(Verifier::new(key), Unsigned::Accept);
    let mut got = Vec::new();
    let mut input = &stream[..];
    while let Some(r) = lenient.next(&mut input) {
        got.push((r.frame().as_bytes().to_vec(), r.is_authenticated()));
    }
    assert_eq!(
        got,
        vec![
            (signed1.clone(), true),
            (signed1, false),
            (unsigned, false),
            (signed2, true)
        ]
    );
    let s = lenient.stats();
    assert_eq!((s.stale_timestamp, s.bad_signature), (1, 1));

    let mut keyless = Parser::<Dialect>::new();
    assert_eq!(
        parse_all(&mut keyless, &stream, 5).len(),
        5,
        "no key: signatures not checked"
    );
}

#[test]
fn authenticated_flag_reports_verified_frames() {
    let key = [3u8; 32];
    let mut signer = Signer::new(key, 1, 1);
    let f = frame_of(
        0,
        &minimal::Heartbeat::default(),
        Version::V2,
        Some(&mut signer),
    );
    let mut p = Parser::<Dialect>::with_signing(Verifier::new(key), Unsigned::Accept);
    let mut input: &[u8] = &f;
    assert!(p.next(&mut input).unwrap().is_authenticated());
}

/// A frame of an id the dialect does not define (checksum seeded with 0).
fn raw_frame(id: u32, seq: u8, payload: &[u8]) -> Vec<u8> {
    raw_frame_signed(id, seq, payload, None)
}

/// The same, signed by `signer` when there is one.
fn raw_frame_signed(id: u32, seq: u8, payload: &[u8], signer: Option<&mut Signer>) -> Vec<u8> {
    let meta = fbwag_dialect::mavframe::MessageMeta::new(
        id,
        "X",
        0,
        payload.len() as u8,
        payload.len() as u8,
        &[],
    );
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    buf[10..10 + payload.len()].copy_from_slice(payload);
    let h = Header {
        seq,
        sysid: 1,
        compid: 1,
    };
    let n = fbwag_dialect::mavframe::frame::finish(
        Version::V2,
        h,
        &meta,
        payload.len(),
        signer,
        &mut buf,
    )
    .unwrap();
    buf[..n].to_vec()
}

const KEY: [u8; 32] = [0x42; 32];

/// Genuine signed frames of unknown ids, back to back, shortest and longest:
/// the budget for their signatures never runs out (a good signature is not
/// paid for; a failed one would cost the frame's length + 26 hashed bytes,
/// 52 for the shortest, 26 bytes, which earn 13).
#[test]
fn genuine_signed_frames_of_unknown_ids_never_exhaust_the_signature_budget() {
    let mut signer = Signer::new(KEY, 1, 1_000);
    let frames: Vec<Vec<u8>> = (0..600u32)
        .map(|i| {
            let payload = vec![0x07; [0, 1, 255][i as usize % 3]];
            raw_frame_signed(14_999, i as u8, &payload, Some(&mut signer))
        })
        .collect();
    // (MAVLink 2 keeps one payload byte: 26 bytes, the shortest signed frame.)
    assert_eq!(frames[0].len(), 26);
    let stream = frames.concat();
    for chunk in [1, 7, 4096] {
        let mut p = Parser::<Dialect>::with_signing(Verifier::new(KEY), Unsigned::Refuse);
        assert_eq!(parse_all(&mut p, &stream, chunk), frames, "chunk {chunk}");
        assert_eq!(p.stats().signatures_unchecked, 0);
        assert_eq!(p.stats().unknown_frames, 600);
    }
}

/// Forged signed candidates of unknown ids at every other byte (each would
/// need a SHA-256 over up to 304 bytes): the hashing is bounded by the
/// budget, nothing is accepted, and a genuine frame of an unknown id is
/// accepted again once the flood has stopped for long enough to earn its
/// cost (280 bytes hash 306: 612 bytes after the flood).
/// Known ids are never subject to the budget.
#[test]
fn a_flood_of_forged_signed_unknown_ids_is_bounded_by_the_signature_budget() {
    use fbwag_dialect::mavframe::parser::{BYTES_PER_RAW_SIGNATURE_BYTE, RAW_SIGNATURE_BURST};
    let flood: Vec<u8> = [0xFD, 0xFD, 0x01, 0x01].repeat(64 * 1024);
    let mut signer = Signer::new(KEY, 1, 1_000);
    let known = frame_of(
        0,
        &minimal::Heartbeat::default(),
        Version::V2,
        Some(&mut signer),
    );
    let genuine = raw_frame_signed(14_999, 1, &[0x07; 255], Some(&mut signer));
    // The flood, then a known frame at once, then quiet bytes, then the
    // genuine unknown one.
    let quiet = vec![0x00; 612];
    let stream = [flood.clone(), known.clone(), quiet, genuine.clone()].concat();
    let mut p = Parser::<Dialect>::with_signing(Verifier::new(KEY), Unsigned::Refuse);
    let got = parse_all(&mut p, &stream, 4096);
    assert_eq!(got, vec![known, genuine], "the flood yields nothing");
    let s = *p.stats();
    assert!(s.signatures_unchecked > 10_000, "{s:?}");
    // Each check of the flood hashes at least 52 bytes (its 26-byte
    // candidates); without the budget there was one per two bytes.
    let checks = p.work().signatures;
    let budget = stream.len() as u64 / BYTES_PER_RAW_SIGNATURE_BYTE + RAW_SIGNATURE_BURST;
    assert!(
        checks * 52 <= budget,
        "{checks} checks for {} bytes",
        stream.len()
    );
    assert!(checks < flood.len() as u64 / 64, "{checks}");
}

/// A genuine signed frame of an unknown id, then replays of it back to
/// back (an attacker without the key who captured it): the first is
/// returned, every replay fails its check and none gives the budget back
/// (only a good signature does), so once it is spent the replays are
/// refused unchecked. Known ids stay outside the budget: a genuine HEARTBEAT
/// after them is returned.
#[test]
fn replays_of_a_genuine_signed_unknown_id_spend_the_budget() {
    let mut signer = Signer::new(KEY, 1, 1_000);
    let genuine = raw_frame_signed(14_999, 1, &[0x07; 40], Some(&mut signer));
    let known = frame_of(
        0,
        &minimal::Heartbeat::default(),
        Version::V2,
        Some(&mut signer),
    );
    let replays = genuine.repeat(2_000);
    let stream = [replays, known.clone()].concat();
    for chunk in [1, 300, 4096] {
        let mut p = Parser::<Dialect>::with_signing(Verifier::new(KEY), Unsigned::Refuse);
        let got = parse_all(&mut p, &stream, chunk);
        assert_eq!(got, vec![genuine.clone(), known.clone()], "chunk {chunk}");
        let s = *p.stats();
        // 65 bytes each, costing 91 hashed bytes and earning 32.5: about
        // two in three are refused unchecked.
        assert!(s.signatures_unchecked > 1_000, "chunk {chunk}: {s:?}");
        assert!(p.work().signatures < 1_000, "chunk {chunk}: {:?}", p.work());
    }
}

/// Forged signed candidates of unknown ids, each with a good frame of a
/// known id inside (a signed HEARTBEAT whose signature is garbage): the
/// search inside them is paid from the budget as their hash would be, so
/// once it is spent they are refused before any search. (When a good frame
/// inside decided them for free, the budget stayed full and every one cost
/// a search: `found_g` of the parser's worst-case benchmark.)
#[test]
fn forged_signed_unknown_ids_with_a_good_frame_inside_spend_the_budget() {
    const PATTERN: &[u8] = &[
        0xfd, 0x01, 0x01, 0x00, 0x00, 0x01, 0x01, 0x00, 0x00, 0x00, 0x00, 0xf2, 0x00, 0xfe, 0xfd,
        0xfd, 0x01, 0x01, 0xfe, 0xfd, 0xfd, 0x01, 0x01, 0xfe, 0xfd, 0xfd, 0xfe, 0xfd, 0xfd, 0x01,
        0x01,
    ];
    let stream = PATTERN.repeat(8 * 1024);
    for chunk in [7, 300, 4096] {
        let mut p = Parser::<Dialect>::with_signing(Verifier::new(KEY), Unsigned::Refuse);
        assert!(
            parse_all(&mut p, &stream, chunk).is_empty(),
            "chunk {chunk}"
        );
        let s = *p.stats();
        // Five such candidates per 31 bytes, which earn a sixth of one.
        assert!(
            s.signatures_unchecked * 8 > stream.len() as u64,
            "chunk {chunk}: {s:?}"
        );
    }
}

#[test]
fn unknown_ids_are_surfaced_raw_and_confirmed() {
    let good = frames(2, &mut Rng(7));
    let raw = raw_frame(14_999, 9, b"\x01\x02\x03");
    let stream = [
        raw.clone(),
        good[0].clone(),
        raw.clone(),
        good[1].clone(),
        raw.clone(),
    ]
    .concat();
    for chunk in [1, 4, 100] {
        let mut p = Parser::<Dialect>::new();
        let got = parse_all(&mut p, &stream, chunk);
        assert_eq!(
            got,
            vec![
                raw.clone(),
                good[0].clone(),
                raw.clone(),
                good[1].clone(),
                raw.clone()
            ],
            "chunk {chunk}"
        );
        assert_eq!(p.stats().unknown_frames, 3);
    }
    // A raw candidate that would hide a good frame inside it loses to it.
    let mut hiding = raw_frame(14_999, 9, &[0x55u8; 60]);
    hiding.truncate(20);
    let stream = [hiding, good[0].clone(), good[1].clone()].concat();
    let mut p = Parser::<Dialect>::new();
    assert_eq!(parse_all(&mut p, &stream, 1), good);
}

/// The case where what a flush decided would be wrong afterwards. A
/// HEARTBEAT header `e` claims 263 bytes, so the parser waits there and
/// looks no further; the flush rejects it (cut), takes the raw frame `g`
/// after it (an unknown id, confirmed by the start byte after it) and, to
/// know whether a good frame starts inside `g` (a MAVLink 2 start byte
/// there may), scans as far as the bytes go: past `g`, to the start of a
/// good frame `f`, which the end cuts, so never good. More bytes then
/// complete `f`, inside a raw candidate `r`: `f` must win over `r`, as
/// without the flush.
#[test]
fn a_good_frame_cut_by_a_flush_not_drained_wins_once_its_bytes_come() {
    let f = frames(1, &mut Rng(5)).remove(0);
    let e = [0xFE, 0xFF, 0x01, 0x01, 0x01, 0x00];
    let g = raw_frame(14_999, 1, &[0x00, 0xFD, 0x05, 0x00, 0x01]);
    let r = raw_frame(14_998, 2, &[[0u8; 4].as_slice(), &f, &[0u8; 4]].concat());
    let stream = [e.as_slice(), &g, &r, &[0xFD, 0x00]].concat();
    let f_at = e.len() + g.len() + 10 + 4;
    for split in f_at + 1..f_at + f.len() {
        let mut p = Parser::<Dialect>::new();
        let mut got = Vec::new();
        let mut first = &stream[..split];
        while let Some(x) = p.next(&mut first) {
            got.push(x.frame().as_bytes().to_vec());
        }
        assert!(got.is_empty(), "split {split}: e waits for its bytes");
        let x = p.flush().expect("the flush takes g");
        got.push(x.frame().as_bytes().to_vec());
        let mut rest = &stream[split..];
        while let Some(x) = p.next(&mut rest) {
            got.push(x.frame().as_bytes().to_vec());
        }
        while let Some(x) = p.flush() {
            got.push(x.frame().as_bytes().to_vec());
        }
        assert_eq!(got, vec![g.clone(), f.clone()], "split {split}");
    }
}

#[test]
fn sequence_gaps_are_counted_per_sender() {
    let frames = frames(20, &mut Rng(8));
    let stream: Vec<u8> = frames
        .iter()
        .enumerate()
        .filter(|(i, _)| ![4, 5, 12].contains(i))
        .flat_map(|(_, f)| f.clone())
        .collect();
    let mut p = Parser::<Dialect>::new();
    parse_all(&mut p, &stream, 13);
    assert_eq!(p.stats().seq_lost, 3);
    let link = p.links()[0];
    assert_eq!(
        (link.sysid, link.compid, link.received, link.lost, link.gaps),
        (1, 1, 17, 3, 2)
    );
}

#[test]
fn no_panic_and_consistent_counts_on_random_input() {
    let mut rng = Rng(9);
    let good = frames(8, &mut rng);
    for _ in 0..3000 {
        let len = rng.below(700);
        let mut data: Vec<u8> = (0..len)
            .map(|_| match rng.below(8) {
                0 => 0xFD,
                1 => 0xFE,
                _ => rng.byte(),
            })
            .collect();
        // Splice in pieces of real frames, sometimes damaged.
        for _ in 0..rng.below(4) {
            let f = &good[rng.below(good.len())];
            let at = rng.below(data.len() + 1);
            let cut = rng.below(f.len() + 1);
            data.splice(at..at, f[..cut].iter().copied());
        }
        let mut p = Parser::<Dialect>::new();
        let got = parse_all(&mut p, &data, 1 + rng.below(50));
        let s = *p.stats();
        let accepted: usize = got.iter().map(Vec::len).sum();
        assert_eq!(
            accepted as u64 + s.bytes_dropped,
            data.len() as u64,
            "every byte is a frame or dropped"
        );
        for f in &got {
            let frame = fbwag_dialect::mavframe::Frame::new_checked(f).unwrap();
            if let Some(m) = Dialect::meta(frame.msg_id()) {
                assert!(frame.check_crc(m.crc_extra));
                let _ = Dialect::parse(frame.msg_id(), frame.payload())
                    .unwrap()
                    .emit(&mut [0u8; 255]);
            }
        }
    }
}

#[test]
fn fbwag_notice_round_trips_through_the_parser() {
    let n = FbwagNotice {
        system_id: 1,
        component_id: 1,
        failsafe_status: FbwagFailsafeStatus::RC_LOST,
        text: chars("FBWAG"),
        timestamp: 123_456,
    };
    let f = frame_of(0, &n, Version::V2, None);
    let mut p = Parser::<Dialect>::new();
    let mut input: &[u8] = &f;
    let r = p.next(&mut input).unwrap();
    assert_eq!(r.message(), Some(n.into()));
    assert_eq!(FbwagNotice::parse(r.frame().payload()), n);
}
