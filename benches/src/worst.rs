//! Inputs of the parser's worst-case benchmark (`benches/parser_worst.rs`)
//! and of the search for worst patterns (`examples/parser_worst.rs`): random
//! bytes, garbage dense in start bytes, a repeating pattern that made the
//! previous parser's cost quadratic, and the worst short patterns the
//! search found.

use fbwag_dialect::mavframe::parser::{Parser, Unsigned};
use fbwag_dialect::mavframe::signing::Verifier;
use fbwag_dialect::Dialect;
use std::hint::black_box;

/// Bytes per input: large enough for steady state, small enough that the
/// old quadratic parser finishes a criterion sample.
pub const INPUT_LEN: usize = 256 * 1024;

/// Chunks the inputs are pushed in: what `fbwag decode` reads at once.
pub const CHUNK: usize = 64 * 1024;

/// A 10-byte pattern dense in start bytes: 1 MB of it took `fbwag decode`
/// 3.6 s with the previous parser, which scanned every candidate for a
/// frame inside.
pub const ISSUE_PATTERN: &[u8] = &[0xfe, 0xfe, 0xfe, 0xfd, 0xfd, 0x00, 0x00, 0xfe, 0x00, 0xfe];

/// The worst repeating patterns `examples/parser_worst.rs` found (see
/// BENCHMARKS.md, "Parser worst case"), with the policy they were found
/// for (`true`: a key, unsigned frames refused).
pub const FOUND: &[(&str, &[u8], bool)] = &[
    (
        "found_a",
        &[
            0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0x0f, 0xfe, 0xfe, 0xfe,
        ],
        false,
    ),
    (
        "found_b",
        &[
            0xfd, 0xfd, 0x00, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe,
        ],
        false,
    ),
    (
        "found_c",
        &[
            0xfe, 0x03, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe,
            0x00, 0xfe, 0xfe,
        ],
        false,
    ),
    ("found_d", &[0xfe, 0xfd, 0xfd, 0x01, 0x00], false),
    ("found_e", &[0xfd, 0x07, 0x01, 0xfe], true),
    // Built by hand, not climbed: a frame of unknown id 0xFF,
    // 8 bytes, confirmed by the 0xFE after it, every 9 bytes of 0xFE
    // candidates of known ids.
    (
        "found_f",
        &[0xfe, 0x00, 0xfe, 0xfe, 0xfe, 0xff, 0xfe, 0xfe, 0xfe],
        false,
    ),
    // A signed HEARTBEAT (good checksum, bad signature), then signed
    // frames of unknown ids: the worst with a key in 300-byte reads.
    (
        "found_g",
        &[
            0xfd, 0x01, 0x01, 0x00, 0x00, 0x01, 0x01, 0x00, 0x00, 0x00, 0x00, 0xf2, 0x00, 0xfe,
            0xfd, 0xfd, 0x01, 0x01, 0xfe, 0xfd, 0xfd, 0x01, 0x01, 0xfe, 0xfd, 0xfd, 0xfe, 0xfd,
            0xfd, 0x01, 0x01,
        ],
        true,
    ),
    // Found by `search time 150 5`: a frame of unknown id 10 every 16
    // bytes, after more candidates than the parser's in-place path for the
    // next frame of an unknown id takes...
    (
        "found_i",
        &[
            0xfe, 0xfe, 0x00, 0xfe, 0xfe, 0xfd, 0x0a, 0x00, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfd,
            0xfe, 0xfd,
        ],
        false,
    ),
    // ...and a MAVLink 2 frame of an unknown id every 18 bytes.
    (
        "found_j",
        &[0xfe, 0xfe, 0xfe, 0xfe, 0xfd, 0x00, 0x00, 0xfe, 0xfe],
        false,
    ),
    // Built by hand, beyond what the search climbed to: found_i's frame of
    // unknown id 10 with eleven 0xFE candidates and a 0xFD after it. By far
    // the worst in 300- and 64-byte reads of a stream, where each 0xFE's
    // 262-byte frame is cut by the read (classified as pending, then again
    // when its bytes come).
    (
        "found_k",
        &[
            0xfe, 0x00, 0xfe, 0xfe, 0xfd, 0x0a, 0x00, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe,
            0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfd,
        ],
        false,
    ),
    // Climbed by the time search (`search time 150 7`): a frame of unknown
    // id 15 every 8 bytes, its successor's three candidates rejected by
    // their masks and one refused (a MAVLink 2 frame of an unknown id not
    // confirmed). Among the worst in 64 KiB reads.
    (
        "found_l",
        &[0xfe, 0x0b, 0xfe, 0x0f, 0xfe, 0xfd, 0xfe, 0x00],
        false,
    ),
    // Climbed by the time search in 300-byte datagrams (`search time 200 5
    // reads=d300`): a MAVLink 1 frame of unknown id 10 every 12 bytes,
    // confirmed by the 0xFE after it, among candidates the datagram's end
    // cuts. Among the slowest in those datagrams.
    (
        "found_m",
        &[
            0x0a, 0x03, 0x7e, 0xfe, 0xfd, 0xfe, 0xfd, 0xfe, 0x00, 0xfe, 0x01, 0xfe,
        ],
        false,
    ),
    // Climbed by the time search in 64 KiB reads (`search time 200 9`):
    // MAVLink 2 frames of unknown ids, a 12-byte one confirmed every 23
    // bytes, the others refused (not confirmed), now and then a confirmed
    // 268-byte one whose inside is scanned; too few candidates between
    // frames for the masks; two of its ids share a slot of the memo's
    // CRC_EXTRA cache, so their look-ups search the dialect (ids above the
    // dialect's largest skip the cache: `Dialect::MAX_ID`).
    (
        "found_n",
        &[
            0x00, 0x00, 0xfd, 0xfd, 0x00, 0x00, 0xfd, 0x01, 0xfe, 0x01, 0xfd, 0x00, 0x01, 0xfe,
            0x00, 0xfd, 0xfd, 0x00, 0x01, 0x71, 0x01, 0xfd, 0xfe,
        ],
        false,
    ),
    // A signed frame of unknown id 3 and long 0xFE candidates: the worst
    // with a key in 64-byte reads.
    (
        "found_h",
        &[
            0xfd, 0x01, 0x01, 0xfe, 0xfe, 0xfe, 0xfe, 0x03, 0x00, 0x00, 0xfe, 0xfe, 0xfe, 0xfe,
            0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe,
        ],
        true,
    ),
];

/// Deterministic pseudo-random bytes (xorshift).
pub fn random(len: usize, seed: u64) -> Vec<u8> {
    let mut x = seed | 1;
    (0..len)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect()
}

/// Every byte 0xFD or 0xFE, at random.
pub fn dense(len: usize, seed: u64) -> Vec<u8> {
    random(len, seed)
        .into_iter()
        .map(|b| if b & 1 == 0 { 0xFD } else { 0xFE })
        .collect()
}

/// Half the bytes 0xFD or 0xFE, the rest random.
pub fn mixed(len: usize, seed: u64) -> Vec<u8> {
    random(len, seed)
        .into_iter()
        .zip(random(len, seed ^ 0x9E37_79B9))
        .map(|(b, r)| match r % 4 {
            0 => 0xFD,
            1 => 0xFE,
            _ => b,
        })
        .collect()
}

/// Random bytes drawn from `(value, weight)`s: the worst mix
/// `examples/parser_worst.rs mix` found.
pub fn mix(weights: &[(u8, u32)], len: usize, seed: u64) -> Vec<u8> {
    let total: u32 = weights.iter().map(|w| w.1).sum();
    random(len, seed)
        .into_iter()
        .map(|r| {
            let mut x = u32::from(r) * total / 256;
            for &(v, w) in weights {
                if x < w {
                    return v;
                }
                x -= w;
            }
            weights[0].0
        })
        .collect()
}

/// The worst mix found: half 0xFE, a third 0xFD, some 0x09 and 0x00.
pub const FOUND_MIX: &[(u8, u32)] = &[(0xFE, 19), (0xFD, 13), (0x09, 4), (0x00, 1)];

/// `pattern` repeated to `len` bytes.
pub fn repeat(pattern: &[u8], len: usize) -> Vec<u8> {
    pattern.iter().copied().cycle().take(len).collect()
}

/// The named inputs of the benchmark: (name, bytes, keyed policy).
pub fn inputs() -> Vec<(String, Vec<u8>, bool)> {
    let mut v = vec![
        ("random".to_string(), random(INPUT_LEN, 1), false),
        ("dense_fd_fe".to_string(), dense(INPUT_LEN, 2), false),
        ("mixed_half_start".to_string(), mixed(INPUT_LEN, 3), false),
        ("found_mix".to_string(), mix(FOUND_MIX, INPUT_LEN, 4), false),
        (
            "issue_pattern".to_string(),
            repeat(ISSUE_PATTERN, INPUT_LEN),
            false,
        ),
        ("all_fe".to_string(), repeat(&[0xfe], INPUT_LEN), false),
        ("all_fd".to_string(), repeat(&[0xfd], INPUT_LEN), false),
        // Signed MAVLink 2 candidates of unknown ids (one signature check
        // each, with a key): 278 and 26 bytes long, and 278 confirmed by
        // the byte after them.
        (
            "signed_raw".to_string(),
            repeat(&[0xfd, 0xfd, 0x01, 0x01], INPUT_LEN),
            true,
        ),
        (
            "signed_raw_confirmed".to_string(),
            repeat(&[0xfd, 0xfd, 0x01, 0xfd, 0xfd], INPUT_LEN),
            true,
        ),
    ];
    for (name, p, keyed) in FOUND {
        v.push((name.to_string(), repeat(p, INPUT_LEN), *keyed));
    }
    v.push(("many_senders".to_string(), many_senders(INPUT_LEN), false));
    v
}

/// `found_f` with its frame of an unknown id sent by a new system id each
/// time (0 to 255, over and over): more senders than the parser tracks.
/// Built by hand, beyond the search's 48-byte patterns: a new sender for
/// every frame, against the parser's per-sender statistics. A slot-by-slot
/// look-up of the sender made it 13 % more work per byte than `found_f`;
/// the look-up is constant time (`mavframe/src/parser/senders.rs`).
pub fn many_senders(len: usize) -> Vec<u8> {
    let (_, found_f, _) = FOUND.iter().find(|(n, _, _)| *n == "found_f").unwrap();
    (0..=255u8)
        .flat_map(|sysid| {
            let mut p = found_f.to_vec();
            p[3] = sysid;
            p
        })
        .cycle()
        .take(len)
        .collect()
}

/// A parser of the FBWAG dialect: without a key, or with one refusing
/// unsigned frames.
pub fn parser(keyed: bool) -> Parser<Dialect> {
    if keyed {
        Parser::with_signing(Verifier::new(crate::KEY), Unsigned::Refuse)
    } else {
        Parser::new()
    }
}

/// How the bytes reach the parser: reads of a stream, or datagrams.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reads {
    /// Reads of this many bytes from a stream (serial, TCP, a file).
    Stream(usize),
    /// Datagrams of this many bytes (UDP): see [`parse_datagrams`].
    Datagrams(usize),
}

impl std::str::FromStr for Reads {
    type Err = std::num::ParseIntError;

    /// `N`: reads of N bytes; `dN`: datagrams of N bytes.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.strip_prefix('d') {
            Some(n) => Ok(Reads::Datagrams(n.parse()?)),
            None => Ok(Reads::Stream(s.parse()?)),
        }
    }
}

impl std::fmt::Display for Reads {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Reads::Stream(n) => write!(f, "{n}-byte reads"),
            Reads::Datagrams(n) => write!(f, "{n}-byte datagrams"),
        }
    }
}

/// Pushes `bytes` through `parser` as `reads` say; returns the frames.
pub fn parse_reads(parser: &mut Parser<Dialect>, bytes: &[u8], reads: Reads) -> usize {
    match reads {
        Reads::Stream(n) => parse(parser, bytes, n),
        Reads::Datagrams(n) => parse_datagrams(parser, bytes, n),
    }
}

/// Pushes `bytes` through `parser` as datagrams of `size` bytes, each
/// parsed by [`Parser::next_in_datagram`] and ended with
/// [`Parser::end_of_datagram`] (MAVLink over UDP, as the daemons' `udpin`
/// links parse it: no frame spans datagrams); returns the frames.
pub fn parse_datagrams(parser: &mut Parser<Dialect>, bytes: &[u8], size: usize) -> usize {
    let mut n = 0;
    for mut d in bytes.chunks(size) {
        while let Some(r) = parser.next_in_datagram(&mut d) {
            black_box(&r.frame());
            n += 1;
        }
        while parser.end_of_datagram().is_some() {
            n += 1;
        }
    }
    n
}

/// Pushes `bytes` through `parser` in `chunk`-byte chunks, then flushes;
/// returns the frames.
pub fn parse(parser: &mut Parser<Dialect>, bytes: &[u8], chunk: usize) -> usize {
    let mut n = 0;
    for mut c in bytes.chunks(chunk) {
        while let Some(r) = parser.next(&mut c) {
            black_box(&r.frame());
            n += 1;
        }
    }
    while parser.flush().is_some() {
        n += 1;
    }
    n
}
