//! The linear-time parser makes exactly the decisions of the simple one it
//! replaced (kept in `support/reference_parser.rs`): call by call, the same
//! frame returned (bytes, known, authenticated), the same bytes held and the
//! same counters, for every chunking and every end of stream or datagram,
//! under the three signing policies, on the FBWAG dialect and on two made-up
//! dialects (every id known; a handful known, id 0 not among them), over
//! mixed traffic, damaged frames and start-byte-dense adversarial patterns.
// The FBWAG dialect's full message table is used.

#[path = "support/dialects.rs"]
mod dialects;
#[path = "support/reference_parser.rs"]
mod reference;

use dialects::{row, AllKnown, Few, NoZero, ALL_ROWS, FEW_ROWS};
use fbwag_dialect::mavframe::frame::{finish, Header, Version};
use fbwag_dialect::mavframe::parser::{Parser, Stats, Unsigned};
use fbwag_dialect::mavframe::{MessageMeta, MessageSet, Signer, Verifier};
use reference::{Got, Reference};

const KEY: [u8; 32] = [0x42; 32];

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
    fn chance(&mut self, percent: usize) -> bool {
        self.below(100) < percent
    }
}

#[derive(Clone, Copy, Debug)]
enum Policy {
    NoKey,
    Lenient,
    Strict,
}

/// A frame of `meta` (any id: the parser only reads CRC_EXTRA), random
/// payload, maybe signed with the key or a wrong one.
fn make_frame(rng: &mut Rng, meta: &MessageMeta, unknown: bool) -> Vec<u8> {
    let v1 = meta.id <= 255 && rng.chance(25);
    let mut meta = *meta;
    if unknown {
        // Checksum seeded with something the dialect would not say.
        meta.crc_extra = rng.byte();
    }
    let len = match rng.below(4) {
        0 => 1 + rng.below(8),
        1 => 1 + rng.below(40),
        2 => 1 + rng.below(255),
        _ => 255,
    };
    meta.min_len = len as u8;
    meta.max_len = len as u8;
    let mut buf = [0u8; 300];
    for b in &mut buf[10..10 + len] {
        *b = match rng.below(5) {
            0 => 0xFD,
            1 => 0xFE,
            _ => rng.byte(),
        };
    }
    if v1 {
        let p: Vec<u8> = buf[10..10 + len].to_vec();
        buf[6..6 + len].copy_from_slice(&p);
    }
    // Mostly three senders; now and then any: more than the parser tracks,
    // so that the last slot is taken over again and again.
    let (sysid, compid) = match rng.chance(20) {
        true => (rng.below(40) as u8, rng.below(4) as u8),
        false => (1 + rng.below(3) as u8, 1),
    };
    let header = Header {
        seq: rng.byte(),
        sysid,
        compid,
    };
    let mut signer = match rng.below(6) {
        0 | 1 => Some(Signer::new(
            KEY,
            rng.byte() % 2,
            1_000 + rng.next() % 1_000_000,
        )),
        2 => Some(Signer::new([7; 32], 0, 5_000)),
        _ => None,
    };
    let version = if v1 { Version::V1 } else { Version::V2 };
    let n = finish(version, header, &meta, len, signer.as_mut(), &mut buf).unwrap();
    buf[..n].to_vec()
}

/// A stream: frames (known and unknown ids), garbage dense in start bytes,
/// damaged frames (cut, bit flips, inflated length), repeated short
/// patterns.
fn make_stream<D: MessageSet>(rng: &mut Rng, known: &[MessageMeta], size: usize) -> Vec<u8> {
    let mut s = Vec::new();
    let mut frames: Vec<Vec<u8>> = Vec::new();
    while s.len() < size {
        match rng.below(10) {
            0..=3 => {
                let unknown = rng.chance(30);
                let meta = if unknown {
                    let mut m = row(rng.next() as u32 & 0xFF_FFFF, 0);
                    if rng.chance(50) {
                        m.id &= 0xFF;
                    }
                    if D::meta(m.id).is_some() {
                        m.id = 0x77_7777;
                    }
                    m
                } else {
                    known[rng.below(known.len())]
                };
                let f = make_frame(rng, &meta, unknown);
                frames.push(f.clone());
                s.extend_from_slice(&f);
            }
            4 => {
                for _ in 0..rng.below(60) {
                    s.push(match rng.below(4) {
                        0 => 0xFD,
                        1 => 0xFE,
                        _ => rng.byte(),
                    });
                }
            }
            5 if !frames.is_empty() => {
                let mut f = frames[rng.below(frames.len())].clone();
                match rng.below(3) {
                    0 => f.truncate(rng.below(f.len())),
                    1 => {
                        let i = rng.below(f.len());
                        f[i] ^= 1 << rng.below(8);
                    }
                    _ => f[1] = f[1].wrapping_add(1 + rng.byte() % 200),
                }
                s.extend_from_slice(&f);
            }
            6 => {
                let alphabet = [0xFD, 0xFE, 0x00, 0x01, 0x02, 0x09, 0xFF, rng.byte()];
                let pattern: Vec<u8> = (0..1 + rng.below(12))
                    .map(|_| alphabet[rng.below(alphabet.len())])
                    .collect();
                for i in 0..rng.below(700) {
                    s.push(pattern[i % pattern.len()]);
                }
            }
            7 if !frames.is_empty() => {
                // A frame's head glued to the start of another frame.
                let f = &frames[rng.below(frames.len())];
                let cut = rng.below(f.len().min(14) + 1);
                s.extend_from_slice(&f[..cut]);
            }
            _ => s.push(if rng.chance(50) { 0xFD } else { 0xFE }),
        }
    }
    s
}

fn policy_parsers<D: MessageSet>(policy: Policy) -> (Parser<D>, Reference<D>) {
    match policy {
        Policy::NoKey => (Parser::new(), Reference::new()),
        Policy::Lenient => (
            Parser::with_signing(Verifier::new(KEY), Unsigned::Accept),
            Reference::with_signing(Verifier::new(KEY), Unsigned::Accept),
        ),
        Policy::Strict => (
            Parser::with_signing(Verifier::new(KEY), Unsigned::Refuse),
            Reference::with_signing(Verifier::new(KEY), Unsigned::Refuse),
        ),
    }
}

fn got(r: Option<fbwag_dialect::mavframe::parser::Received<'_, impl MessageSet>>) -> Option<Got> {
    r.map(|r| {
        (
            r.frame().as_bytes().to_vec(),
            r.meta().is_some(),
            r.is_authenticated(),
        )
    })
}

/// Runs both parsers over `stream` in chunks of `chunk()` bytes, ending a
/// datagram after a chunk when `boundary()` says so (the new parser told
/// so up front, by `next_in_datagram`, for every other such chunk; the
/// reference is flushed). Returns the frames.
///
/// The frames, the counters and the bytes held must be the same after each
/// end of datagram and at the end. In between, the new parser may be
/// ahead, never behind: with a candidate cut by the end of a chunk the old
/// one copied the bytes the candidate needed and returned, checking again
/// only on the next call, while the new one decides with every byte it has
/// (so a frame that was held back until the next chunk comes out now). So
/// after each chunk, the old parser's frames so far must begin the new
/// one's. (The same holds of a raw candidate whose next byte rules it out
/// while a position inside it is undecided: the old parser waited for that
/// position first.)
fn compare<D: MessageSet>(
    stream: &[u8],
    policy: Policy,
    mut chunk: impl FnMut() -> usize,
    mut boundary: impl FnMut() -> bool,
    what: &str,
) -> Vec<Got> {
    let (mut new, mut old) = policy_parsers::<D>(policy);
    let (mut a_frames, mut b_frames) = (Vec::new(), Vec::new());
    let mut rest = stream;
    let same = |new: &Parser<D>, old: &Reference<D>, a: &[Got], b: &[Got], at: &str| {
        assert_eq!(a, b, "{what}: {at}: frames differ");
        // Every counter, the budget for unknown ids' signatures included
        // (it once differed by a candidate or two: the two parsers decide
        // with different bytes at hand, and the budget must not care).
        assert_eq!(new.stats(), old.stats(), "{what}: {at}: counters");
        assert_eq!(new.pending(), old.pending(), "{what}: {at}: held");
    };
    let mut chunks = 0;
    while !rest.is_empty() {
        let n = chunk().clamp(1, rest.len());
        let (mut a, tail) = rest.split_at(n);
        let mut b = a;
        rest = tail;
        chunks += 1;
        let ends = boundary();
        // Every other chunk that ends a datagram says so up front, as a
        // UDP link's reader does; the others are ended after.
        let in_datagram = ends && chunks % 2 == 0;
        loop {
            let x = got(if in_datagram {
                new.next_in_datagram(&mut a)
            } else {
                new.next(&mut a)
            });
            let y = old.next(&mut b);
            if x.is_none() {
                assert!(a.is_empty(), "{what}: input left");
            }
            let done = x.is_none() && y.is_none();
            a_frames.extend(x);
            b_frames.extend(y);
            if done {
                break;
            }
        }
        if !a_frames.starts_with(&b_frames) {
            let i = a_frames
                .iter()
                .zip(&b_frames)
                .take_while(|(x, y)| x == y)
                .count();
            panic!(
                "{what}: chunk {chunks}: the new parser's frames ({}) do not extend the old one's ({}): from {i}: {:02x?}\n vs {:02x?}",
                a_frames.len(),
                b_frames.len(),
                a_frames.get(i..).map(|v| v.iter().map(|f| (f.0.len(), f.1, f.2)).collect::<Vec<_>>()),
                b_frames.get(i..).map(|v| v.iter().map(|f| (f.0.len(), f.1, f.2)).collect::<Vec<_>>()),
            );
        }
        if ends {
            while let Some(f) = got(new.end_of_datagram()) {
                a_frames.push(f);
            }
            while let Some(f) = old.flush() {
                b_frames.push(f);
            }
            same(
                &new,
                &old,
                &a_frames,
                &b_frames,
                &format!("datagram {chunks}"),
            );
        }
    }
    while let Some(f) = got(new.flush()) {
        a_frames.push(f);
    }
    while let Some(f) = old.flush() {
        b_frames.push(f);
    }
    same(&new, &old, &a_frames, &b_frames, "end");
    let links: Vec<_> = new
        .links()
        .iter()
        .map(|l| (l.sysid, l.compid, l.received, l.lost, l.gaps))
        .collect();
    assert_eq!(links, old.links(), "{what}: per-sender counters");
    a_frames
}

fn run<D: MessageSet>(known: &[MessageMeta], seed: u64, trials: usize, size: usize) {
    let mut rng = Rng(seed);
    let mut frames = 0;
    for trial in 0..trials {
        let stream = make_stream::<D>(&mut rng, known, size);
        let policy = [Policy::NoKey, Policy::Lenient, Policy::Strict][trial % 3];
        let style = rng.below(5);
        let seed = rng.next();
        let mut c = Rng(seed | 1);
        let mut d = Rng(seed.rotate_left(17) | 1);
        let what = format!("trial {trial} {policy:?} chunking {style}");
        let got = compare::<D>(
            &stream,
            policy,
            || match style {
                0 => 1,
                1 => 1 + c.below(8),
                2 => 1 + c.below(300),
                3 => usize::MAX,
                _ => 1 + c.below(2000),
            },
            || style == 4 && d.chance(50),
            &what,
        );
        frames += got.len();
    }
    assert!(frames > trials, "the streams hold frames ({frames})");
}

#[test]
fn same_decisions_as_the_reference_on_the_fbwag_dialect() {
    run::<fbwag_dialect::Dialect>(fbwag_dialect::MESSAGES, 1, 150, 3000);
}

#[test]
fn same_decisions_as_the_reference_when_every_id_is_known() {
    run::<AllKnown>(&ALL_ROWS, 2, 150, 3000);
}

#[test]
fn same_decisions_as_the_reference_when_few_ids_are_known() {
    run::<Few>(&FEW_ROWS, 3, 150, 3000);
}

/// The patterns the issue and the worst-case search name, byte by byte and
/// whole, in every dialect.
#[test]
fn same_decisions_on_adversarial_patterns() {
    let patterns: [&[u8]; 6] = [
        &[0xfe, 0xfe, 0xfe, 0xfd, 0xfd, 0x00, 0x00, 0xfe, 0x00, 0xfe],
        &[0xfd],
        &[0xfe],
        &[0xfd, 0xfd, 0x01, 0x01],
        &[0xfd, 0x01, 0x00],
        &[0xfe, 0x00],
    ];
    for (i, p) in patterns.iter().enumerate() {
        let stream: Vec<u8> = p.iter().copied().cycle().take(2500).collect();
        for policy in [Policy::NoKey, Policy::Strict] {
            for chunk in [1, 7, usize::MAX] {
                let what = format!("pattern {i} {policy:?} chunk {chunk}");
                compare::<fbwag_dialect::Dialect>(&stream, policy, || chunk, || false, &what);
                compare::<AllKnown>(&stream, policy, || chunk, || false, &what);
                compare::<Few>(&stream, policy, || chunk, || false, &what);
            }
        }
    }
}

/// The one decision that changed. A MAVLink 1 header cut before its id
/// byte, inside a raw candidate, used to be read as id 0: with a dialect
/// without id 0 the candidate was then taken as soon as its next byte was a
/// start byte, even when the MAVLink 1 frame it hides turns out whole and
/// good once its bytes come, so that frame was lost, or not, depending on
/// where a chunk ended. The new parser waits for the id byte: the same
/// frames for every chunking.
#[test]
fn a_cut_mavlink1_header_inside_a_raw_frame_no_longer_depends_on_chunking() {
    // A good MAVLink 1 frame of id 1 (known), sequence 0xFD.
    let mut v1 = [0u8; 16];
    let meta = FEW_ROWS[1];
    let mut m = meta;
    m.min_len = 1;
    m.max_len = 1;
    v1[6] = 0x33;
    let h = Header {
        seq: 0xFD,
        sysid: 1,
        compid: 1,
    };
    let n = finish(Version::V1, h, &m, 1, None, &mut v1).unwrap();
    let v1 = &v1[..n];
    // A raw frame of an unknown id whose "checksum" is the MAVLink 1
    // frame's first two bytes (a raw frame's checksum cannot be checked).
    let mut raw = vec![0xFD, 3, 0, 0, 0, 1, 1, 0x55, 0x55, 0x55, 9, 9, 9];
    raw.extend_from_slice(&v1[..2]);
    let stream: Vec<u8> = [&raw[..], &v1[2..], &[0xFE, 0x00][..]].concat();
    let cut = raw.len() + 1; // the raw frame and its confirmation byte
    let split = |n: usize| {
        let mut first = true;
        move || {
            let c = if first { n } else { usize::MAX };
            first = false;
            c
        }
    };
    let run_new = |chunk: &mut dyn FnMut() -> usize| {
        let mut p = Parser::<NoZero>::new();
        let mut out = Vec::new();
        let mut rest = &stream[..];
        while !rest.is_empty() {
            let (mut c, tail) = rest.split_at(chunk().min(rest.len()));
            rest = tail;
            while let Some(r) = p.next(&mut c) {
                out.push(r.frame().as_bytes().to_vec());
            }
        }
        while let Some(r) = p.flush() {
            out.push(r.frame().as_bytes().to_vec());
        }
        out
    };
    let whole = run_new(&mut split(usize::MAX));
    assert!(whole.contains(&v1.to_vec()), "the good frame is found");
    assert!(!whole.contains(&raw), "and the raw frame hiding it loses");
    assert_eq!(run_new(&mut split(cut)), whole);
    assert_eq!(run_new(&mut || 1), whole);
    // The old parser lost it when a chunk ended right after the raw frame.
    let run_old = |first: usize| {
        let mut p = Reference::<NoZero>::new();
        let (mut a, mut b) = stream.split_at(first.min(stream.len()));
        let mut out = Vec::new();
        while let Some(f) = p.next(&mut a) {
            out.push(f.0);
        }
        while let Some(f) = p.next(&mut b) {
            out.push(f.0);
        }
        while let Some(f) = p.flush() {
            out.push(f.0);
        }
        out
    };
    assert_eq!(run_old(usize::MAX), whole);
    let old_cut = run_old(cut);
    assert!(old_cut.contains(&raw) && !old_cut.contains(&v1.to_vec()));
}

/// The frames `p` returns from `stream` pushed in reads of `chunk()` bytes
/// and flushed, and its counters then.
fn parse_in_reads<D: MessageSet>(
    mut p: Parser<D>,
    stream: &[u8],
    chunk: &mut dyn FnMut() -> usize,
) -> (Vec<Vec<u8>>, Stats) {
    let mut out = Vec::new();
    let mut rest = stream;
    while !rest.is_empty() {
        let (mut c, tail) = rest.split_at(chunk().clamp(1, rest.len()));
        rest = tail;
        while let Some(r) = p.next(&mut c) {
            out.push(r.frame().as_bytes().to_vec());
        }
    }
    while let Some(r) = p.flush() {
        out.push(r.frame().as_bytes().to_vec());
    }
    (out, *p.stats())
}

/// With that change, the new parser gives the same frames for every
/// chunking in a dialect without id 0 too.
#[test]
fn same_frames_for_every_chunking_without_id_0() {
    let mut rng = Rng(4);
    for trial in 0..60 {
        let stream = make_stream::<NoZero>(&mut rng, &FEW_ROWS[1..], 3000);
        let parse = |chunk: &mut dyn FnMut() -> usize| {
            parse_in_reads(Parser::<NoZero>::new(), &stream, chunk)
        };
        let whole = parse(&mut || usize::MAX);
        let mut c = Rng(trial + 11);
        assert_eq!(parse(&mut || 1), whole, "trial {trial}: byte by byte");
        assert_eq!(parse(&mut || 1 + c.below(40)), whole, "trial {trial}");
    }
}

/// With a key, on hostile streams (forged and wrongly signed frames, frames
/// of unknown ids, garbage): the same frames and the same counters for
/// every chunking, the signature budget's included. The search inside a
/// signed candidate of an unknown id is paid for before it is made; a
/// candidate rejected for a good frame inside before all its bytes are
/// there must pay the same (`pay_for_signed_raw`), or read sizes change
/// what the budget holds (this test fails without it).
#[test]
fn same_frames_and_budget_for_every_chunking_with_a_key() {
    let mut rng = Rng(5);
    for trial in 0..40 {
        let stream =
            make_hostile::<fbwag_dialect::Dialect>(&mut rng, fbwag_dialect::MESSAGES, 3000);
        for unsigned in [Unsigned::Accept, Unsigned::Refuse] {
            let parse = |chunk: &mut dyn FnMut() -> usize| {
                let p =
                    Parser::<fbwag_dialect::Dialect>::with_signing(Verifier::new(KEY), unsigned);
                parse_in_reads(p, &stream, chunk)
            };
            let whole = parse(&mut || usize::MAX);
            let mut c = Rng(trial + 21);
            let what = format!("trial {trial} {unsigned:?}");
            assert_eq!(parse(&mut || 1), whole, "{what}: byte by byte");
            assert_eq!(parse(&mut || 1 + c.below(300)), whole, "{what}");
        }
    }
}

/// A caller that drops the rest of its input after a frame (it should pass
/// it again) and goes on with other bytes, or ends the stream there: the
/// parser remembers what it saw past the frame, and must not trust it for
/// the other bytes. Every known frame it returns has its checksum, every
/// call ends, in every dialect.
#[test]
fn dropping_input_after_a_frame_never_yields_a_bad_frame() {
    fn go<D: MessageSet>(known: &[MessageMeta], seed: u64) {
        let mut rng = Rng(seed);
        for trial in 0..40 {
            let a = make_stream::<D>(&mut rng, known, 4000);
            let b = make_stream::<D>(&mut rng, known, 4000);
            let mut p = Parser::<D>::new();
            let mut rest = &a[..];
            let mut calls = 0;
            while !rest.is_empty() {
                let n = (1 + rng.below(600)).min(rest.len());
                let mut chunk = &rest[..n];
                rest = &rest[n..];
                while let Some(r) = p.next(&mut chunk) {
                    calls += 1;
                    assert!(calls < 100_000, "trial {trial}: calls do not end");
                    if let Some(m) = D::meta(r.frame().msg_id()) {
                        assert!(r.frame().check_crc(m.crc_extra), "trial {trial}");
                    }
                    if rng.chance(30) {
                        // Drop the rest of this chunk; go on with `b`'s
                        // bytes (and sometimes end the stream first).
                        chunk = &[];
                        if rng.chance(50) {
                            while p.flush().is_some() {}
                        }
                        let k = rng.below(b.len());
                        rest = &b[k..(k + 600).min(b.len())];
                    }
                }
            }
            while let Some(r) = p.flush() {
                if let Some(m) = D::meta(r.frame().msg_id()) {
                    assert!(r.frame().check_crc(m.crc_extra), "trial {trial}");
                }
            }
        }
    }
    go::<fbwag_dialect::Dialect>(fbwag_dialect::MESSAGES, 21);
    go::<AllKnown>(&ALL_ROWS, 22);
    go::<Few>(&FEW_ROWS, 23);
}

// Hostile streams of frames of unknown ids, signed and not: a parser that
// trusts a remembered "whole frame of an unknown id" mark over the bytes at
// hand lets a frame of a known id with a bad checksum out as a raw frame
// (the tests below).

/// A frame of `id` (unknown to the dialect when `unknown`), payload of
/// `len` nonzero bytes rich in start bytes, signed by `signer` if any.
fn frame_of(
    rng: &mut Rng,
    id: u32,
    crc_extra: u8,
    len: usize,
    v1: bool,
    signer: Option<&mut Signer>,
) -> Vec<u8> {
    let mut meta = row(id, crc_extra);
    meta.min_len = len as u8;
    meta.max_len = len as u8;
    let mut buf = [0u8; 300];
    let off = if v1 { 6 } else { 10 };
    for b in &mut buf[off..off + len] {
        *b = match rng.below(4) {
            0 => 0xFD,
            1 => 0xFE,
            _ => 1 + rng.byte() % 255,
        };
    }
    let header = Header {
        seq: rng.byte(),
        sysid: 1 + rng.below(2) as u8,
        compid: 1,
    };
    let version = if v1 { Version::V1 } else { Version::V2 };
    let n = finish(version, header, &meta, len, signer, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// Dense start bytes, signed and unsigned frames of unknown ids (good
/// key, wrong key, replayed, cut, confirmed or not), good and damaged known
/// frames.
fn make_hostile<D: MessageSet>(rng: &mut Rng, known: &[MessageMeta], size: usize) -> Vec<u8> {
    let mut good = Signer::new(KEY, 1, 10_000);
    let mut wrong = Signer::new([7; 32], 1, 10_000);
    let mut s = Vec::new();
    let mut sent: Vec<Vec<u8>> = Vec::new();
    let mut tries = 0;
    let mut unknown_id = |rng: &mut Rng| loop {
        tries += 1;
        let id = match rng.below(3) {
            0 => rng.next() as u32 & 0xFF,
            1 => 0x77_7777,
            _ => rng.next() as u32 & 0xFF_FFFF,
        };
        if D::meta(id).is_none() || tries % 64 == 0 {
            break id;
        }
    };
    while s.len() < size {
        let len = match rng.below(3) {
            0 => 1 + rng.below(6),
            1 => 1 + rng.below(30),
            _ => 1 + rng.below(255),
        };
        match rng.below(14) {
            // Dense start bytes: refused flags, 0xFE runs, pairs.
            0 | 1 => {
                let alphabet = [0xFD, 0xFE, 0x00, 0x01, 0x02, 0x04, 0xFF];
                for _ in 0..rng.below(80) {
                    s.push(alphabet[rng.below(alphabet.len())]);
                }
            }
            2 => s.extend(std::iter::repeat_n(0xFD, rng.below(40))),
            // Frames of unknown ids, signed with the key.
            3 | 4 => {
                let id = unknown_id(rng);
                let f = {
                    let e = rng.byte();
                    frame_of(rng, id, e, len, false, Some(&mut good))
                };
                sent.push(f.clone());
                s.extend_from_slice(&f);
            }
            // ... with a wrong key.
            5 => {
                let id = unknown_id(rng);
                let f = {
                    let e = rng.byte();
                    frame_of(rng, id, e, len, false, Some(&mut wrong))
                };
                s.extend_from_slice(&f);
            }
            // ... unsigned (MAVLink 1 or 2).
            6 | 7 => {
                let id = unknown_id(rng);
                let v1 = id <= 255 && rng.chance(40);
                let f = {
                    let e = rng.byte();
                    frame_of(rng, id, e, len, v1, None)
                };
                s.extend_from_slice(&f);
            }
            // Known ids, good, signed or not.
            8 => {
                let m = known[rng.below(known.len())];
                let v1 = m.id <= 255 && rng.chance(30);
                let signer = if !v1 && rng.chance(50) {
                    Some(&mut good)
                } else {
                    None
                };
                let f = frame_of(rng, m.id, m.crc_extra, len, v1, signer);
                sent.push(f.clone());
                s.extend_from_slice(&f);
            }
            // A replay, a cut frame, a flipped bit.
            9 if !sent.is_empty() => {
                let mut f = sent[rng.below(sent.len())].clone();
                match rng.below(3) {
                    0 => {}
                    1 => f.truncate(rng.below(f.len())),
                    _ => {
                        let i = rng.below(f.len());
                        f[i] ^= 1 << rng.below(8);
                    }
                }
                s.extend_from_slice(&f);
            }
            // A frame's head glued on.
            10 if !sent.is_empty() => {
                let f = &sent[rng.below(sent.len())];
                s.extend_from_slice(&f[..rng.below(f.len().min(14) + 1)]);
            }
            // An unconfirmed byte after a frame.
            11 => s.push(rng.byte() | 1),
            _ => s.push(if rng.chance(50) { 0xFD } else { 0xFE }),
        }
    }
    s
}

fn hostile<D: MessageSet>(known: &[MessageMeta], seed: u64, trials: usize, size: usize) {
    let mut rng = Rng(seed);
    let mut frames = 0;
    let sizes = [
        1, 2, 3, 5, 8, 13, 17, 31, 64, 65, 100, 127, 255, 256, 299, 300,
    ];
    for trial in 0..trials {
        let stream = make_hostile::<D>(&mut rng, known, size);
        for policy in [Policy::NoKey, Policy::Lenient, Policy::Strict] {
            let style = rng.below(4);
            let fixed = sizes[rng.below(sizes.len())];
            let seed = rng.next();
            let mut c = Rng(seed | 1);
            let mut d = Rng(seed.rotate_left(17) | 1);
            let what =
                format!("hostile seed {seed} trial {trial} {policy:?} style {style} fixed {fixed}");
            let got = compare::<D>(
                &stream,
                policy,
                || match style {
                    0 => fixed,
                    1 => 1 + c.below(300),
                    2 => 1 + c.below(8),
                    _ => 1 + c.below(300),
                },
                || style == 3 && d.chance(30),
                &what,
            );
            frames += got.len();
        }
    }
    assert!(frames > trials, "the streams hold frames ({frames})");
}

#[test]
fn hostile_fbwag() {
    hostile::<fbwag_dialect::Dialect>(fbwag_dialect::MESSAGES, 101, 400, 3000);
}

#[test]
fn hostile_few() {
    hostile::<Few>(&FEW_ROWS, 102, 400, 3000);
}

#[test]
fn hostile_all_known() {
    hostile::<AllKnown>(&ALL_ROWS, 103, 200, 3000);
}

/// `dropping_input_after_a_frame_never_yields_a_bad_frame` under every
/// policy, on hostile streams: no known id with a bad checksum, no
/// unauthenticated frame when unsigned frames are refused, no signed frame
/// returned unauthenticated with a key.
#[test]
fn dropping_input_with_every_policy() {
    fn go<D: MessageSet>(known: &[MessageMeta], seed: u64) {
        let mut rng = Rng(seed);
        for trial in 0..20 {
            let a = make_hostile::<D>(&mut rng, known, 4000);
            let b = make_hostile::<D>(&mut rng, known, 4000);
            for policy in [Policy::NoKey, Policy::Lenient, Policy::Strict] {
                let (mut p, _) = policy_parsers::<D>(policy);
                let mut rest = &a[..];
                let mut calls = 0;
                let mut resets = 0;
                let check = |r: &fbwag_dialect::mavframe::parser::Received<'_, D>| {
                    if let Some(m) = D::meta(r.frame().msg_id()) {
                        assert!(
                            r.frame().check_crc(m.crc_extra),
                            "trial {trial} {policy:?}: bad checksum {:02x?}",
                            r.frame().as_bytes()
                        );
                    }
                    match policy {
                        Policy::NoKey => {}
                        // Signed and unauthenticated only with the key's
                        // signature (a stale timestamp: a replay).
                        Policy::Lenient => assert!(
                            !r.frame().is_signed()
                                || r.is_authenticated()
                                || Verifier::<1>::new(KEY).signed_with_key(&r.frame()),
                            "trial {trial}: signed unauthenticated"
                        ),
                        Policy::Strict => {
                            assert!(r.is_authenticated(), "trial {trial}: unauthenticated")
                        }
                    }
                };
                while !rest.is_empty() {
                    let n = (1 + rng.below(300)).min(rest.len());
                    let mut chunk = &rest[..n];
                    rest = &rest[n..];
                    while let Some(r) = p.next(&mut chunk) {
                        calls += 1;
                        assert!(calls < 100_000, "trial {trial}: calls do not end");
                        check(&r);
                        if resets < 30 && rng.chance(30) {
                            resets += 1;
                            chunk = &[];
                            if rng.chance(30) {
                                while let Some(r) = p.flush() {
                                    check(&r);
                                }
                            }
                            // Sometimes the same bytes at other ids.
                            let k = rng.below(b.len());
                            rest = &b[k..(k + 600).min(b.len())];
                        }
                    }
                }
                while let Some(r) = p.flush() {
                    check(&r);
                }
            }
        }
    }
    go::<fbwag_dialect::Dialect>(fbwag_dialect::MESSAGES, 121);
    go::<AllKnown>(&ALL_ROWS, 122);
    go::<Few>(&FEW_ROWS, 123);
}

/// A caller drops the rest of its input after a frame and passes the same
/// bytes with message ids changed (known ones in place of unknown ones and
/// back): other bytes at the positions the parser looked at. No known id
/// with a bad checksum comes out, under any policy.
#[test]
fn other_ids_at_the_same_positions_never_yield_a_bad_frame() {
    fn go<D: MessageSet>(known: &[MessageMeta], seed: u64) {
        let mut rng = Rng(seed);
        let mut hits = 0;
        for trial in 0..60 {
            let a = make_hostile::<D>(&mut rng, known, 3000);
            for policy in [Policy::NoKey, Policy::Lenient, Policy::Strict] {
                let (mut p, _) = policy_parsers::<D>(policy);
                let mut cur = a.clone();
                let mut off = 0;
                let mut resets = 0;
                let check = |f: &[u8], meta: bool, source: &str| {
                    let fr = fbwag_dialect::mavframe::frame::Frame::new_unchecked(f);
                    if let Some(m) = D::meta(fr.msg_id()) {
                        assert!(
                            fr.check_crc(m.crc_extra),
                            "seed {seed} trial {trial} {policy:?} {source}: a known id with a bad checksum (meta {meta}): {f:02x?}"
                        );
                    }
                };
                while off < cur.len() {
                    let n = (1 + rng.below(300)).min(cur.len() - off);
                    let mut chunk = &cur[off..off + n];
                    let mut mutate_from = None;
                    while let Some(r) = p.next(&mut chunk) {
                        check(r.frame().as_bytes(), r.meta().is_some(), "next");
                        if resets < 40 && rng.chance(40) {
                            resets += 1;
                            mutate_from = Some(off + n - chunk.len());
                            break;
                        }
                    }
                    match mutate_from {
                        None => off += n,
                        Some(from) => {
                            // The same bytes from `from` on, ids changed.
                            let mut b = cur[from..].to_vec();
                            for i in 0..b.len() {
                                if !rng.chance(50) {
                                    continue;
                                }
                                let id = if rng.chance(70) {
                                    known[rng.below(known.len())].id
                                } else {
                                    0x77_7777
                                };
                                match b[i] {
                                    0xFD if i + 10 <= b.len() => {
                                        b[i + 7..i + 10].copy_from_slice(&id.to_le_bytes()[..3])
                                    }
                                    0xFE if i + 6 <= b.len() && id <= 255 => b[i + 5] = id as u8,
                                    _ => {}
                                }
                            }
                            cur = b;
                            off = 0;
                            hits += 1;
                        }
                    }
                }
                while let Some(r) = p.flush() {
                    check(r.frame().as_bytes(), r.meta().is_some(), "flush");
                }
            }
        }
        assert!(hits > 0);
    }
    go::<fbwag_dialect::Dialect>(fbwag_dialect::MESSAGES, 131);
    go::<Few>(&FEW_ROWS, 133);
    go::<AllKnown>(&ALL_ROWS, 132);
}

/// The first case `other_ids_at_the_same_positions_never_yield_a_bad_frame`
/// found: the scan marks position 32 of the first input as a whole frame of
/// an unknown id (0x777777); the caller drops the rest after the first
/// frame and passes the same bytes with that id changed to a known one
/// (1, whose checksum the bytes do not carry). The fast rejection loop used
/// to trust the mark and let the frame out as a raw frame.
#[test]
fn a_stale_unknown_id_mark_never_lets_a_bad_frame_out() {
    let hex = |s: &str| -> Vec<u8> {
        (0..s.len())
            .step_by(2)
            .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
            .collect()
    };
    let raw = hex("fd04000000010177777711223344e09f");
    let dense = "fd".repeat(16);
    let a = hex(&format!(
        "fd04000000010177777711223344e09f{dense}fd04000000010177777740414243e3cafd"
    ));
    let b = hex(&format!("{dense}fd04000000010101000040414243e3cafd"));
    let mut returned = 0;
    for mut p in [
        Parser::<Few>::new(),
        Parser::with_signing(Verifier::new(KEY), Unsigned::Accept),
        Parser::with_signing(Verifier::new(KEY), Unsigned::Refuse),
    ] {
        let mut input = &a[..];
        if p.next(&mut input).map(|r| r.frame().as_bytes().to_vec()) != Some(raw.clone()) {
            // Refused unsigned.
            continue;
        }
        returned += 1;
        let mut input = &b[..];
        let mut out = Vec::new();
        while let Some(r) = p.next(&mut input) {
            out.push(r.frame().as_bytes().to_vec());
        }
        while let Some(r) = p.flush() {
            out.push(r.frame().as_bytes().to_vec());
        }
        for f in &out {
            let frame = fbwag_dialect::mavframe::frame::Frame::new_unchecked(&f[..]);
            if let Some(m) = Few::meta(frame.msg_id()) {
                assert!(
                    frame.check_crc(m.crc_extra),
                    "a bad frame of a known id: {f:02x?}"
                );
            }
        }
    }
    assert_eq!(
        returned, 2,
        "no key and unsigned accepted return the first frame"
    );
}

/// A frame of an unknown id in garbage dense in 0xFE (where the fast
/// rejection loop goes by masks and may decide "no good frame inside" from
/// them), with a good HEARTBEAT starting at each position of its payload
/// and checksum, the pair shifted across the loop's 64-byte blocks: the
/// same decisions as the reference, whole and byte by byte.
#[test]
fn a_good_frame_inside_a_raw_frame_wins_wherever_the_masks_end() {
    type D = fbwag_dialect::Dialect;
    let heartbeat = *D::meta(0).expect("HEARTBEAT");
    let unknown = (1..=255u32).find(|&id| D::meta(id).is_none()).unwrap();
    let mut good = [0u8; 300];
    good[6..6 + 9].fill(0xFE);
    let fe = 0xFE;
    let header = Header {
        seq: fe,
        sysid: fe,
        compid: fe,
    };
    let n = finish(Version::V1, header, &heartbeat, 9, None, &mut good).unwrap();
    let good = &good[..n];
    let mut cases = 0;
    for len in [12usize, 20, 40] {
        for k in 6..len {
            for pre in (0..70).step_by(3) {
                let mut raw = vec![0xFE, (len - 8) as u8, 1, 2, 3, unknown as u8];
                raw.resize(len, 0x11);
                let mut stream = vec![0xFE; pre];
                stream.extend_from_slice(&raw[..k]);
                stream.extend_from_slice(good);
                stream.extend(core::iter::repeat_n(0xFE, 300));
                for chunk in [usize::MAX, 1] {
                    let what = format!("len {len} good at {k} after {pre} bytes, chunk {chunk}");
                    let frames = compare::<D>(&stream, Policy::NoKey, || chunk, || false, &what);
                    assert!(
                        frames.iter().any(|f| f.0 == good),
                        "{what}: the good frame is returned"
                    );
                }
                cases += 1;
            }
        }
    }
    assert!(cases > 1000);
}
