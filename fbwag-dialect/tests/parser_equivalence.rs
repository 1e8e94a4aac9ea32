//! The linear-time parser makes exactly the decisions of the simple one it
//! replaced (kept in `support/reference_parser.rs`): call by call, the same
//! frame returned (bytes, known, authenticated), the same bytes held and the
//! same counters, for every chunking and every end of stream or datagram,
//! under the three signing policies, on the FBWAG dialect and on two made-up
//! dialects (every id known; a handful known, id 0 not among them), over
//! mixed traffic, damaged frames and start-byte-dense adversarial patterns.
// The FBWAG dialect's full message table is used.
#![cfg(not(feature = "cc-subset"))]

#[path = "support/reference_parser.rs"]
mod reference;

use fbwag_dialect::mavframe::frame::{finish, Header, Version};
use fbwag_dialect::mavframe::parser::Parser;
use fbwag_dialect::mavframe::{Dialect, MessageMeta, Signer, Verifier};
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

fn row(id: u32, crc_extra: u8) -> MessageMeta {
    MessageMeta {
        id,
        name: "X",
        crc_extra,
        min_len: 1,
        max_len: 255,
        target_system_offset: None,
        target_component_offset: None,
        fields: &[],
    }
}

/// Every id known (CRC_EXTRA from the id's low byte): every candidate costs
/// a checksum.
struct AllKnown;
static ALL_ROWS: [MessageMeta; 256] = {
    let mut t = [MessageMeta {
        id: 0,
        name: "X",
        crc_extra: 0,
        min_len: 1,
        max_len: 255,
        target_system_offset: None,
        target_component_offset: None,
        fields: &[],
    }; 256];
    let mut i = 0;
    while i < 256 {
        t[i].id = i as u32;
        t[i].crc_extra = (i as u8) ^ 0x5A;
        i += 1;
    }
    t
};
impl Dialect for AllKnown {
    type Message = ();
    type View<'a> = ();
    const MESSAGES: &'static [MessageMeta] = &[];
    fn meta(id: u32) -> Option<&'static MessageMeta> {
        Some(&ALL_ROWS[(id & 0xFF) as usize])
    }
    fn parse(_: u32, _: &[u8]) -> Option<()> {
        None
    }
    fn view(_: u32, _: &[u8]) -> Option<()> {
        None
    }
}

/// A few ids known, made of start bytes and small numbers, id 0 not among
/// them: most candidates are raw, and MAVLink 1 headers cut before their id
/// byte read as an unknown id.
struct Few;
static FEW_IDS: [u32; 6] = [1, 2, 0xFD, 0xFE, 0xFD_FD, 0x01_FE_FD];
static FEW_ROWS: [MessageMeta; 6] = {
    let mut t = [MessageMeta {
        id: 0,
        name: "X",
        crc_extra: 0,
        min_len: 1,
        max_len: 255,
        target_system_offset: None,
        target_component_offset: None,
        fields: &[],
    }; 6];
    let mut i = 0;
    while i < 6 {
        t[i].id = FEW_IDS[i];
        t[i].crc_extra = 7 * i as u8 + 1;
        i += 1;
    }
    t
};
impl Dialect for Few {
    type Message = ();
    type View<'a> = ();
    const MESSAGES: &'static [MessageMeta] = &FEW_ROWS;
    fn parse(_: u32, _: &[u8]) -> Option<()> {
        None
    }
    fn view(_: u32, _: &[u8]) -> Option<()> {
        None
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
    let header = Header {
        seq: rng.byte(),
        sysid: 1 + rng.below(3) as u8,
        compid: 1,
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
fn make_stream<D: Dialect>(rng: &mut Rng, known: &[MessageMeta], size: usize) -> Vec<u8> {
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

fn policy_parsers<D: Dialect>(policy: Policy) -> (Parser<D>, Reference<D>) {
    match policy {
        Policy::NoKey => (Parser::new(), Reference::new()),
        Policy::Lenient => (
            Parser::with_signing(Verifier::new(KEY), true),
            Reference::with_signing(Verifier::new(KEY), true),
        ),
        Policy::Strict => (
            Parser::with_signing(Verifier::new(KEY), false),
            Reference::with_signing(Verifier::new(KEY), false),
        ),
    }
}

fn got(r: Option<fbwag_dialect::mavframe::parser::Received<'_, impl Dialect>>) -> Option<Got> {
    r.map(|r| {
        (
            r.frame.as_bytes().to_vec(),
            r.meta.is_some(),
            r.authenticated,
        )
    })
}

/// Runs both parsers over `stream` in chunks of `chunk()` bytes, ending a
/// datagram after a chunk when `boundary()` says so, and compares them
/// after every call. Returns the frames.
fn compare<D: Dialect>(
    stream: &[u8],
    policy: Policy,
    mut chunk: impl FnMut() -> usize,
    mut boundary: impl FnMut() -> bool,
    what: &str,
) -> Vec<Got> {
    let (mut new, mut old) = policy_parsers::<D>(policy);
    let mut frames = Vec::new();
    let mut rest = stream;
    let mut calls = 0;
    let mut check = |a: Option<Got>, b: Option<Got>, new: &Parser<D>, old: &Reference<D>| {
        calls += 1;
        assert_eq!(a, b, "{what}: call {calls}: frames differ");
        assert_eq!(new.stats(), old.stats(), "{what}: call {calls}: counters");
        assert_eq!(new.pending(), old.pending(), "{what}: call {calls}: held");
        a
    };
    while !rest.is_empty() {
        let n = chunk().clamp(1, rest.len());
        let (mut a, tail) = rest.split_at(n);
        let mut b = a;
        rest = tail;
        loop {
            let x = got(new.next(&mut a));
            let y = old.next(&mut b);
            assert_eq!(a.len(), b.len(), "{what}: input consumed differs");
            match check(x, y, &new, &old) {
                Some(f) => frames.push(f),
                None => break,
            }
        }
        if boundary() {
            while let Some(f) = check(got(new.end_of_datagram()), old.flush(), &new, &old) {
                frames.push(f);
            }
        }
    }
    while let Some(f) = check(got(new.flush()), old.flush(), &new, &old) {
        frames.push(f);
    }
    let links: Vec<_> = new
        .links()
        .iter()
        .map(|l| (l.sysid, l.compid, l.received, l.lost, l.gaps))
        .collect();
    assert_eq!(links, old.links(), "{what}: per-sender counters");
    frames
}

fn run<D: Dialect>(known: &[MessageMeta], seed: u64, trials: usize, size: usize) {
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
