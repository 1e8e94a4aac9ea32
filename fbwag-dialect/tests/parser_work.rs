//! The parser's work per byte is bounded, whatever the bytes: counted, not
//! timed (`Parser::work`). Every input, chunking, signing policy and dialect
//! here keeps `steps ≤ C × (bytes pushed + calls)`, and at most one
//! signature check per start byte and per 8 bytes (the budget for unknown
//! ids' signatures); the old algorithm (the reference
//! parser, with the same kind of count) breaks the bound on the same inputs
//! by two orders of magnitude.
//!
//! Why C = 16. Each byte is, at most: searched for a start byte three
//! times (in the input, in the buffer after a rejection, by the fast
//! rejection loop), copied into the buffer once and moved inside it 1.2
//! times on average (the buffer moves its bytes only after more than 465
//! were dropped), checksummed once directly and once as a prefix state,
//! passed once by the inside scan's frontier and once by its wake-up
//! positions: about 10 steps. Each start byte adds: a classification
//! (at most three: header cut, frame cut, whole) and its wake-up list entry,
//! and its checks as a candidate; each call adds a check (a candidate that
//! needs more bytes is checked again once per call or per byte copied).
//! What the tests measure stays below 11; 16 leaves room for inputs nobody
//! thought of, while the old algorithm needs hundreds.

#[path = "support/dialects.rs"]
mod dialects;
#[path = "support/reference_parser.rs"]
mod reference;

use dialects::{AllKnown, Few};
use fbwag_dialect::mavframe::frame::{finish, Header, Version};
use fbwag_dialect::mavframe::parser::{Parser, Unsigned};
use fbwag_dialect::mavframe::{MessageSet, Signer, Verifier};

/// The bound on steps per (byte + call).
const C: f64 = 16.0;

/// The bound on signature checks (SHA-256s) over `n` bytes: a known id's
/// bad signature skips its frame up to the signature (12 bytes at least);
/// an unknown id's good one returns its frame (26 bytes at least), a failed
/// one draws on the parser's budget, at least 52 hashed bytes each.
fn signature_bound(n: usize) -> u64 {
    use fbwag_dialect::mavframe::parser::{BYTES_PER_RAW_SIGNATURE_BYTE, RAW_SIGNATURE_BURST};
    let n = n as u64;
    n / 12 + n / 26 + 1 + (n / BYTES_PER_RAW_SIGNATURE_BYTE + RAW_SIGNATURE_BURST) / 52
}

const KEY: [u8; 32] = [0x42; 32];

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

fn repeat(p: &[u8], n: usize) -> Vec<u8> {
    p.iter().copied().cycle().take(n).collect()
}

/// The adversarial inputs: garbage dense in start bytes, the issue's
/// pattern, the worst patterns `examples/parser_worst.rs` found, patterns
/// that maximise undecided positions inside raw candidates, and signed
/// candidates of unknown ids (a signature check each, with a key).
fn inputs(n: usize) -> Vec<(&'static str, Vec<u8>)> {
    let mut rng = Rng(99);
    let random: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
    let dense: Vec<u8> = random
        .iter()
        .map(|b| if b & 1 == 0 { 0xFD } else { 0xFE })
        .collect();
    let mixed: Vec<u8> = random
        .iter()
        .enumerate()
        .map(|(i, &b)| match (b >> 1).wrapping_add(i as u8) % 4 {
            0 => 0xFD,
            1 => 0xFE,
            _ => b,
        })
        .collect();
    // A long raw candidate (unknown id) whose payload is MAVLink 1 headers
    // of HEARTBEAT (id 0, known) claiming 240 bytes: every one undecided
    // until 248 bytes after it, the raw candidate waiting on them.
    let mut undecided = vec![0xFD, 0xFF, 0, 0, 0, 1, 1, 0x77, 0x77, 0x77];
    undecided.extend(repeat(&[0xFE, 0xF0, 0, 1, 1, 0], 264));
    let mut v = vec![
        ("random", random.clone()),
        ("dense_fd_fe", dense),
        ("mixed_half_start", mixed),
        (
            "issue_pattern",
            repeat(
                &[0xfe, 0xfe, 0xfe, 0xfd, 0xfd, 0x00, 0x00, 0xfe, 0x00, 0xfe],
                n,
            ),
        ),
        ("all_fe", repeat(&[0xFE], n)),
        ("all_fd", repeat(&[0xFD], n)),
        ("fd_fd_01_01", repeat(&[0xFD, 0xFD, 0x01, 0x01], n)),
        (
            "signed_raw_confirmed",
            repeat(&[0xFD, 0xFD, 0x01, 0xFD, 0xFD], n),
        ),
        ("fe_00", repeat(&[0xFE, 0x00], n)),
        ("undecided_storm", repeat(&undecided, n)),
        ("headers_fe_f0", repeat(&[0xFE, 0xF0, 0, 1, 1, 0], n)),
    ];
    for (name, p) in FOUND {
        v.push((name, repeat(p, n)));
    }
    v
}

/// The worst patterns of the search (benches/src/worst.rs has them too).
const FOUND: &[(&str, &[u8])] = &[
    (
        "found_a",
        &[
            0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0x0f, 0xfe, 0xfe, 0xfe,
        ],
    ),
    (
        "found_b",
        &[
            0xfd, 0xfd, 0x00, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe,
        ],
    ),
    (
        "found_c",
        &[
            0xfe, 0x03, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe,
            0x00, 0xfe, 0xfe,
        ],
    ),
    ("found_d", &[0xfe, 0xfd, 0xfd, 0x01, 0x00]),
    ("found_e", &[0xfd, 0x07, 0x01, 0xfe]),
    (
        "found_f",
        &[0xfe, 0x00, 0xfe, 0xfe, 0xfe, 0xff, 0xfe, 0xfe, 0xfe],
    ),
    (
        "found_g",
        &[
            0xfd, 0x01, 0x01, 0x00, 0x00, 0x01, 0x01, 0x00, 0x00, 0x00, 0x00, 0xf2, 0x00, 0xfe,
            0xfd, 0xfd, 0x01, 0x01, 0xfe, 0xfd, 0xfd, 0x01, 0x01, 0xfe, 0xfd, 0xfd, 0xfe, 0xfd,
            0xfd, 0x01, 0x01,
        ],
    ),
    (
        "found_h",
        &[
            0xfd, 0x01, 0x01, 0xfe, 0xfe, 0xfe, 0xfe, 0x03, 0x00, 0x00, 0xfe, 0xfe, 0xfe, 0xfe,
            0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe,
        ],
    ),
    (
        "found_i",
        &[
            0xfe, 0xfe, 0x00, 0xfe, 0xfe, 0xfd, 0x0a, 0x00, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfd,
            0xfe, 0xfd,
        ],
    ),
    (
        "found_j",
        &[0xfe, 0xfe, 0xfe, 0xfe, 0xfd, 0x00, 0x00, 0xfe, 0xfe],
    ),
    (
        "found_k",
        &[
            0xfe, 0x00, 0xfe, 0xfe, 0xfd, 0x0a, 0x00, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe,
            0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfd,
        ],
    ),
    ("found_l", &[0xfe, 0x0b, 0xfe, 0x0f, 0xfe, 0xfd, 0xfe, 0x00]),
    (
        "found_m",
        &[
            0x0a, 0x03, 0x7e, 0xfe, 0xfd, 0xfe, 0xfd, 0xfe, 0x00, 0xfe, 0x01, 0xfe,
        ],
    ),
    (
        "found_n",
        &[
            0x00, 0x00, 0xfd, 0xfd, 0x00, 0x00, 0xfd, 0x01, 0xfe, 0x01, 0xfd, 0x00, 0x01, 0xfe,
            0x00, 0xfd, 0xfd, 0x00, 0x01, 0x71, 0x01, 0xfd, 0xfe,
        ],
    ),
];

#[derive(Clone, Copy, Debug)]
enum Chunking {
    Whole,
    Fixed(usize),
    Random,
    /// Random chunks, each ended as a datagram (told after it).
    Datagrams,
    /// Random chunks, each a datagram from its first byte
    /// (`next_in_datagram`, as the connections parse UDP).
    InDatagrams,
}

/// Steps per (byte + call), signature checks, start bytes, and the frames.
fn run<D: MessageSet>(bytes: &[u8], keyed: bool, chunking: Chunking, seed: u64) -> (f64, u64, u64) {
    let mut p = if keyed {
        Parser::<D>::with_signing(Verifier::new(KEY), Unsigned::Refuse)
    } else {
        Parser::<D>::new()
    };
    let mut rng = Rng(seed | 1);
    let mut calls = 0u64;
    let mut rest = bytes;
    while !rest.is_empty() {
        let n = match chunking {
            Chunking::Whole => rest.len(),
            Chunking::Fixed(n) => n,
            Chunking::Random | Chunking::Datagrams | Chunking::InDatagrams => 1 + rng.below(300),
        };
        let (mut c, tail) = rest.split_at(n.min(rest.len()));
        rest = tail;
        loop {
            calls += 1;
            assert!(calls < 10 * bytes.len() as u64 + 100, "calls do not end");
            let got = if matches!(chunking, Chunking::InDatagrams) {
                p.next_in_datagram(&mut c)
            } else {
                p.next(&mut c)
            };
            if got.is_none() {
                break;
            }
        }
        if matches!(chunking, Chunking::Datagrams | Chunking::InDatagrams) {
            loop {
                calls += 1;
                if p.end_of_datagram().is_none() {
                    break;
                }
            }
        }
    }
    loop {
        calls += 1;
        if p.flush().is_none() {
            break;
        }
    }
    let w = p.work();
    let starts = bytes.iter().filter(|&&b| b == 0xFD || b == 0xFE).count() as u64;
    (
        w.steps as f64 / (bytes.len() as u64 + calls) as f64,
        w.signatures,
        starts,
    )
}

fn check_all<D: MessageSet>(dialect: &str, n: usize) -> f64 {
    let chunkings = [
        Chunking::Whole,
        Chunking::Fixed(64 * 1024),
        Chunking::Fixed(1),
        Chunking::Fixed(7),
        Chunking::Random,
        Chunking::Datagrams,
        Chunking::InDatagrams,
    ];
    let mut worst: f64 = 0.0;
    let mut worst_at = String::new();
    // Per chunking: random bytes' steps (without and with a key), and the
    // worst input's ratio to them.
    let mut random = [[0.0f64; 2]; 7];
    let mut ratio: [(f64, String); 7] = Default::default();
    // ("random" comes first.)
    for (name, bytes) in inputs(n) {
        for keyed in [false, true] {
            for (c, chunking) in chunkings.into_iter().enumerate() {
                let (per, sigs, starts) = run::<D>(&bytes, keyed, chunking, 5);
                assert!(
                    per <= C,
                    "{dialect} {name} keyed {keyed} {chunking:?}: {per:.2} steps per byte + call"
                );
                assert!(
                    sigs <= starts,
                    "{dialect} {name} {chunking:?}: {sigs} signature checks for {starts} start bytes"
                );
                assert!(
                    sigs <= signature_bound(bytes.len()),
                    "{dialect} {name} {chunking:?}: {sigs} signature checks for {} bytes",
                    bytes.len()
                );
                if per > worst {
                    worst = per;
                    worst_at = format!("{name} keyed {keyed} {chunking:?}");
                }
                if name == "random" {
                    random[c][usize::from(keyed)] = per;
                }
                let r = per / random[c][usize::from(keyed)];
                if r > ratio[c].0 {
                    ratio[c] = (r, format!("{name} keyed {keyed}"));
                }
            }
        }
    }
    eprintln!("{dialect}: at most {worst:.2} steps per byte + call ({worst_at})");
    for (c, chunking) in chunkings.into_iter().enumerate() {
        let (r, at) = &ratio[c];
        eprintln!("{dialect} {chunking:?}: the worst input {r:.2}x random bytes ({at})");
    }
    worst
}

#[test]
fn work_per_byte_is_bounded_on_adversarial_inputs() {
    let n = 40_000;
    check_all::<fbwag_dialect::Dialect>("fbwag", n);
    check_all::<AllKnown>("all known", n);
    check_all::<Few>("few known", n);
}

/// Traffic with damage: frames of every kind (signed with the key and
/// without, unknown ids), cut, flipped, glued to garbage.
#[test]
fn work_per_byte_is_bounded_on_damaged_traffic() {
    let mut rng = Rng(7);
    let mut stream = Vec::new();
    let mut signer = Signer::new(KEY, 1, 1_000);
    let mut buf = [0u8; 300];
    while stream.len() < 200_000 {
        let meta = fbwag_dialect::MESSAGES[rng.below(fbwag_dialect::MESSAGES.len())];
        let mut meta = meta;
        if rng.below(4) == 0 {
            meta.id = 0x7F_7F7F;
        }
        let len = meta.max_len as usize;
        for b in &mut buf[10..10 + len] {
            *b = if rng.below(3) == 0 {
                0xFD
            } else {
                rng.next() as u8
            };
        }
        let h = Header {
            seq: rng.next() as u8,
            sysid: 1,
            compid: 1,
        };
        let sign = rng.below(2) == 0;
        let n = finish(
            Version::V2,
            h,
            &meta,
            len,
            sign.then_some(&mut signer),
            &mut buf,
        )
        .unwrap();
        let mut f = buf[..n].to_vec();
        match rng.below(4) {
            0 => f.truncate(rng.below(n)),
            1 => f[rng.below(n)] ^= 0x20,
            _ => {}
        }
        stream.extend_from_slice(&f);
        for _ in 0..rng.below(30) {
            stream.push(if rng.below(2) == 0 { 0xFE } else { 0xFD });
        }
    }
    for keyed in [false, true] {
        for chunking in [Chunking::Whole, Chunking::Fixed(1), Chunking::Datagrams] {
            let (per, sigs, starts) = run::<fbwag_dialect::Dialect>(&stream, keyed, chunking, 3);
            assert!(per <= C, "keyed {keyed} {chunking:?}: {per:.2}");
            assert!(sigs <= starts);
        }
    }
}

/// The same bound fails for the algorithm it replaced: the test would have
/// caught it.
#[test]
fn the_old_algorithm_breaks_the_bound() {
    for (name, bytes) in inputs(4_000) {
        if !matches!(name, "issue_pattern" | "all_fe" | "undecided_storm") {
            continue;
        }
        let mut old = reference::Reference::<fbwag_dialect::Dialect>::new();
        // Byte by byte where the old parser rescanned per byte received.
        let chunk = if name == "undecided_storm" {
            1
        } else {
            bytes.len()
        };
        let mut calls = 0u64;
        for mut input in bytes.chunks(chunk) {
            loop {
                calls += 1;
                if old.next(&mut input).is_none() {
                    break;
                }
            }
        }
        while old.flush().is_some() {
            calls += 1;
        }
        let per = old.work as f64 / (bytes.len() as u64 + calls) as f64;
        assert!(per > 10.0 * C, "{name}: the old parser's {per:.1} per byte");
        let chunking = if chunk == 1 {
            Chunking::Fixed(1)
        } else {
            Chunking::Whole
        };
        let (new, _, _) = run::<fbwag_dialect::Dialect>(&bytes, false, chunking, 1);
        eprintln!("{name}: old {per:.0} steps per byte + call, new {new:.2}");
    }
}

/// MAVLink 2 frames of the dialect's messages, every field random, back to
/// back, to `size` bytes at least; signed when a signer is given.
fn good_frames(seed: u64, size: usize, mut signer: Option<&mut Signer>) -> Vec<u8> {
    let mut rng = Rng(seed);
    let mut stream = Vec::new();
    let mut buf = [0u8; 300];
    while stream.len() < size {
        let meta = fbwag_dialect::MESSAGES[rng.below(fbwag_dialect::MESSAGES.len())];
        let len = meta.max_len as usize;
        for b in &mut buf[10..10 + len] {
            *b = rng.next() as u8;
        }
        let h = Header {
            seq: rng.next() as u8,
            sysid: 1,
            compid: 1,
        };
        let n = finish(Version::V2, h, &meta, len, signer.as_deref_mut(), &mut buf).unwrap();
        stream.extend_from_slice(&buf[..n]);
    }
    stream
}

/// Good frames read in chunks (as from a serial port or TCP) are parsed in
/// place again after each chunk boundary: the frame cut by the boundary is
/// assembled in the buffer, and the bytes copied after it go back to the
/// input. Before, every frame after the first boundary went through the
/// buffer (3.9 steps per byte instead of 2.0 on such a stream).
#[test]
fn chunked_good_frames_cost_what_whole_ones_do() {
    let stream = good_frames(11, 200_000, None);
    let steps = |chunk: usize| {
        let mut p = Parser::<fbwag_dialect::Dialect>::new();
        let mut frames = 0;
        for mut c in stream.chunks(chunk) {
            while p.next(&mut c).is_some() {
                frames += 1;
            }
        }
        (p.work().steps, frames)
    };
    let (whole, frames) = steps(stream.len());
    for chunk in [4096, 1000, 300] {
        let (chunked, chunked_frames) = steps(chunk);
        assert_eq!(chunked_frames, frames, "chunks of {chunk}");
        // Per boundary: the cut frame's bytes held, and at most a buffer's
        // window copied ahead and given back.
        let boundaries = (stream.len() / chunk) as u64;
        assert!(
            chunked <= whole + boundaries * 2 * 560,
            "chunks of {chunk}: {chunked} steps, whole {whole}"
        );
    }
}

/// Good frames after a burst of garbage cost what they cost alone: the
/// parser goes back to checking candidates directly once a run of its fast
/// rejection loop rejects nothing. (A frame returned among dense start
/// bytes makes the next call start with that loop; if the loop's "start
/// bytes are dense" outlived the garbage, every good frame after it would
/// pay a wasted run.) With a key and signed frames, and in chunks, so that
/// the frames go through the whole check.
#[test]
fn good_frames_after_garbage_cost_what_they_cost_alone() {
    let good = good_frames(5, 100_000, Some(&mut Signer::new(KEY, 1, 1_000)));
    // found_c: a raw frame of an unknown id every 17 bytes of garbage.
    let garbage = repeat(FOUND[2].1, 20_000);
    let run = |bytes: &[u8]| {
        let mut p =
            Parser::<fbwag_dialect::Dialect>::with_signing(Verifier::new(KEY), Unsigned::Accept);
        let mut frames = 0u64;
        for mut c in bytes.chunks(4096) {
            while p.next(&mut c).is_some() {
                frames += 1;
            }
        }
        while p.flush().is_some() {
            frames += 1;
        }
        (p.work().steps, frames)
    };
    let (garbage_steps, garbage_frames) = run(&garbage);
    let (good_steps, good_frames) = run(&good);
    let both: Vec<u8> = garbage.iter().chain(&good).copied().collect();
    let (both_steps, both_frames) = run(&both);
    assert_eq!(both_frames, garbage_frames + good_frames);
    // The junction: at most a buffer's window of the good frames looked
    // at by the garbage's last run, and the first good frame's run.
    assert!(
        both_steps <= garbage_steps + good_steps + 4 * 560,
        "garbage {garbage_steps} + good {good_steps} steps, together {both_steps}"
    );
}
