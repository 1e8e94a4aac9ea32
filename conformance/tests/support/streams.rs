//! Corrupted byte streams: good frames with bit flips, truncations, garbage
//! (with start bytes) between them, false start bytes inside payloads, wrong
//! checksums, unknown incompatibility flags, bad and foreign-key signatures,
//! replayed signed frames and frames of unknown ids; and what the Rust
//! parser makes of them.

use super::frames::{build_frame, Mode, KEY, OTHER_KEY};
use super::values::{fill_of, random_payload, Fill, Opts, Rng};
use mavframe::crc::frame_crc;
use mavframe::frame::{Frame, Header, Version, MAX_FRAME_LEN, SIGNATURE_LEN};
use mavframe::parser::Stats;
use mavframe::signing::signature;
use mavframe::{MessageMeta, MessageSet, Parser, Unsigned, Verifier};
use std::collections::BTreeMap;

/// What the receivers know and accept.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Policy {
    /// No key: signed frames are accepted unverified (all three do so).
    NoKey,
    /// Key set: signatures verified, unsigned frames accepted.
    KeyAcceptUnsigned,
    /// Key set: signatures verified, unsigned frames refused.
    KeyRejectUnsigned,
}

impl Policy {
    pub const ALL: [Policy; 3] = [
        Policy::NoKey,
        Policy::KeyAcceptUnsigned,
        Policy::KeyRejectUnsigned,
    ];

    pub fn label(self) -> &'static str {
        match self {
            Policy::NoKey => "no key",
            Policy::KeyAcceptUnsigned => "key, unsigned accepted",
            Policy::KeyRejectUnsigned => "key, unsigned refused",
        }
    }

    pub fn key(self) -> bool {
        self != Policy::NoKey
    }

    pub fn accept_unsigned(self) -> bool {
        self != Policy::KeyRejectUnsigned
    }
}

/// The damage done to one frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Damage {
    Intact,
    BitFlips,
    Truncated,
    GarbageBefore,
    WrongCrc,
    UnknownFlags,
    BadSignature,
    ForeignKey,
    Replay,
    UnknownId,
}

impl Damage {
    pub fn label(self) -> &'static str {
        match self {
            Damage::Intact => "intact",
            Damage::BitFlips => "bit flips",
            Damage::Truncated => "truncated",
            Damage::GarbageBefore => "garbage before",
            Damage::WrongCrc => "wrong CRC",
            Damage::UnknownFlags => "unknown incompat flag",
            Damage::BadSignature => "bad signature",
            Damage::ForeignKey => "foreign-key signature",
            Damage::Replay => "replayed signed frame",
            Damage::UnknownId => "unknown message id",
        }
    }
}

/// A corrupted stream and what a correct parser must return from it.
#[derive(Debug, Clone)]
pub struct Stream {
    pub bytes: Vec<u8>,
    /// Every frame (of a known message) that is intact and acceptable under
    /// the policy on its own, in stream order, and not inside a
    /// checksum-valid candidate that starts before it: what a parser that
    /// resynchronises after every rejected candidate recovers.
    pub expected: Vec<Vec<u8>>,
    /// Frames with false start bytes in their payloads (all intact).
    pub false_starts: usize,
    /// Good frames inside a checksum-valid candidate that is a valid frame
    /// for every parser under the policy (e.g. without a key, a signed frame
    /// truncated inside its signature block and completed by this frame's
    /// head): no parser can tell; not counted as recoverable.
    pub ambiguous: usize,
    /// Good frames inside such a candidate whose signature fails with the
    /// key: recoverable in principle, lost by all three parsers (mavframe's
    /// parser skips a bad-signature frame whole: see docs/conformance.md);
    /// not counted as recoverable.
    pub behind_bad_signature: usize,
    pub damage: BTreeMap<Damage, usize>,
}

const SENDERS: [(u8, u8); 3] = [(1, 1), (1, 191), (255, 190)];

fn pick(rng: &mut Rng, weights: &[(Damage, u64)]) -> Damage {
    let total: u64 = weights.iter().map(|w| w.1).sum();
    let mut x = rng.below(total);
    for &(d, w) in weights {
        if x < w {
            return d;
        }
        x -= w;
    }
    unreachable!()
}

/// Re-signs a signed frame in place after its header changed (CRC first).
fn recrc_and_resign(frame: &mut [u8], meta: &MessageMeta, key: &[u8; 32]) {
    let signed = frame[0] == 0xFD && frame[2] & 1 != 0;
    let sig = if signed { SIGNATURE_LEN } else { 0 };
    let crc_at = frame.len() - sig - 2;
    let crc = frame_crc(&frame[1..crc_at], meta.crc_extra);
    frame[crc_at..crc_at + 2].copy_from_slice(&crc.to_le_bytes());
    if signed {
        let at = frame.len() - SIGNATURE_LEN;
        let link = frame[at];
        let mut t = [0u8; 8];
        t[..6].copy_from_slice(&frame[at + 1..at + 7]);
        let s = signature(key, &frame[..at], link, u64::from_le_bytes(t));
        frame[at + 7..].copy_from_slice(&s);
    }
}

/// Builds one stream of `n` frames of dialect `D`.
pub fn build<D: MessageSet>(rng: &mut Rng, policy: Policy, n: usize) -> Stream {
    let msgs = D::MESSAGES;
    let mut bytes = Vec::new();
    let mut expected = Vec::new();
    let mut damage = BTreeMap::new();
    let mut false_starts = 0;
    let mut seq = [0u8; SENDERS.len()];
    let mut ts: u64 = 0x0000_1234_5678_0000 + rng.below(1 << 20);
    let mut sent_signed: Vec<Vec<u8>> = Vec::new();
    let acceptable_unsigned = policy.accept_unsigned();
    for _ in 0..n {
        let meta = &msgs[rng.below(msgs.len() as u64) as usize];
        let mode = match rng.below(10) {
            0..=3 => Mode::V2,
            4..=7 => Mode::V2s,
            _ if meta.id <= 255 => Mode::V1,
            _ => Mode::V2,
        };
        let s = rng.below(SENDERS.len() as u64) as usize;
        let header = Header {
            seq: seq[s],
            sysid: SENDERS[s].0,
            compid: SENDERS[s].1,
        };
        seq[s] = seq[s].wrapping_add(1);
        let link = rng.below(2) as u8;
        ts += 1 + rng.below(100);
        let start_bytes = rng.chance(1, 4);
        let fill = if rng.chance(1, 10) {
            fill_of(rng.range(0, 3))
        } else {
            Fill::Random
        };
        let payload = random_payload(
            meta,
            rng,
            fill,
            Opts {
                f32_snan: true,
                start_bytes,
                bytes_after_nul: true,
            },
        );
        let mut frame = build_frame(meta, mode, header, &payload, link, ts, &KEY);
        let signed = mode == Mode::V2s;
        let mut weights = vec![
            (Damage::Intact, 55),
            (Damage::BitFlips, 8),
            (Damage::Truncated, 7),
            (Damage::GarbageBefore, 7),
            (Damage::WrongCrc, 5),
            (Damage::UnknownId, 2),
        ];
        if mode != Mode::V1 {
            weights.push((Damage::UnknownFlags, 4));
        }
        if signed {
            weights.push((Damage::BadSignature, 5));
            weights.push((Damage::ForeignKey, 3));
        }
        if !sent_signed.is_empty() {
            weights.push((Damage::Replay, 4));
        }
        let d = pick(rng, &weights);
        *damage.entry(d).or_insert(0) += 1;
        // Whether the frame as emitted is a good frame under the policy.
        let policy_ok = |signed: bool| if signed { true } else { acceptable_unsigned };
        let mut good = false;
        match d {
            Damage::Intact => good = policy_ok(signed),
            Damage::BitFlips => {
                let flips = rng.range(1, 3);
                let mut in_sig_only = signed;
                for _ in 0..flips {
                    let at = rng.range(0, frame.len() - 1);
                    frame[at] ^= 1 << rng.below(8);
                    if !(signed && at >= frame.len() - SIGNATURE_LEN) {
                        in_sig_only = false;
                    }
                }
                // Without a key, nobody checks the signature block.
                good = in_sig_only && !policy.key();
            }
            Damage::Truncated => {
                let keep = rng.range(1, frame.len() - 1);
                frame.truncate(keep);
            }
            Damage::GarbageBefore => {
                let mut g: Vec<u8> = (0..rng.range(1, 48)).map(|_| rng.byte()).collect();
                match rng.below(4) {
                    0 => {
                        // A false header claiming a long frame of a known id.
                        let m = &msgs[rng.below(msgs.len() as u64) as usize];
                        let id = m.id.to_le_bytes();
                        let h = [
                            0xFD,
                            200 + rng.byte() % 56,
                            0,
                            0,
                            0,
                            1,
                            1,
                            id[0],
                            id[1],
                            id[2],
                        ];
                        g.splice(0..0, h);
                    }
                    1 => {
                        let at = rng.range(0, g.len() - 1);
                        g[at] = if rng.chance(1, 2) { 0xFD } else { 0xFE };
                    }
                    _ => {}
                }
                bytes.extend_from_slice(&g);
                good = policy_ok(signed);
            }
            Damage::WrongCrc => {
                let sig = if signed { SIGNATURE_LEN } else { 0 };
                let at = frame.len() - sig - 2 + rng.range(0, 1);
                frame[at] ^= 1 + rng.below(255) as u8;
            }
            Damage::UnknownFlags => {
                frame[2] |= 1 << rng.range(1, 7);
                recrc_and_resign(&mut frame, meta, &KEY);
            }
            Damage::BadSignature => {
                let at = frame.len() - 1 - rng.range(0, 5);
                frame[at] ^= 1 << rng.below(8);
                good = !policy.key();
            }
            Damage::ForeignKey => {
                frame = build_frame(meta, mode, header, &payload, link, ts, &OTHER_KEY);
                good = !policy.key();
            }
            Damage::Replay => {
                let old = &sent_signed[rng.below(sent_signed.len() as u64) as usize];
                bytes.extend_from_slice(old);
                if !policy.key() {
                    expected.push((bytes.len() - old.len(), old.clone()));
                }
                good = policy_ok(signed);
            }
            Damage::UnknownId => {
                // An id no shipped dialect uses, with a valid checksum under
                // an arbitrary CRC_EXTRA: only routers care about it.
                let id = 0x00F0_0000 + rng.below(0x1_0000) as u32;
                if frame[0] == 0xFD {
                    frame[7..10].copy_from_slice(&id.to_le_bytes()[..3]);
                    let mut fake = *meta;
                    fake.crc_extra = rng.byte();
                    recrc_and_resign(&mut frame, &fake, &KEY);
                } else {
                    // MAVLink 1 has 8-bit ids, all taken or not, per dialect:
                    // leave the frame alone (it stays intact).
                    good = policy_ok(signed);
                }
            }
        }
        if start_bytes && good {
            false_starts += 1;
        }
        if good {
            expected.push((bytes.len(), frame.clone()));
            if signed && d != Damage::BitFlips {
                sent_signed.push(frame.clone());
            }
        }
        bytes.extend_from_slice(&frame);
    }
    // Good frames that start inside a checksum-valid candidate frame (a
    // truncated frame completed by the next frame's head, its checksum
    // matching: always when the cut falls in a signature block, 1 in 256
    // when it falls between the checksum bytes).
    let mut recoverable = Vec::new();
    let mut ambiguous = 0;
    let mut behind_bad_signature = 0;
    for (pos, f) in expected {
        match shadow::<D>(&bytes, pos, policy) {
            None => recoverable.push(f),
            Some(Shadow::ValidFrame) => ambiguous += 1,
            Some(Shadow::BadSignature) => behind_bad_signature += 1,
        }
    }
    Stream {
        bytes,
        expected: recoverable,
        false_starts,
        ambiguous,
        behind_bad_signature,
        damage,
    }
}

/// A frame the Rust parser returned.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Got {
    pub bytes: Vec<u8>,
    pub known: bool,
    pub authenticated: bool,
}

/// Runs the Rust parser over `bytes` in chunks whose sizes `chunks` yields
/// (0 = the rest), then flushes. Returns the frames and the counters.
pub fn rust_parse<D: MessageSet>(
    bytes: &[u8],
    policy: Policy,
    mut chunks: impl FnMut() -> usize,
) -> (Vec<Got>, Stats) {
    let mut parser = match policy {
        Policy::NoKey => Parser::<D>::new(),
        p if p.accept_unsigned() => Parser::<D>::with_signing(Verifier::new(KEY), Unsigned::Accept),
        _ => Parser::<D>::with_signing(Verifier::new(KEY), Unsigned::Refuse),
    };
    let mut got = Vec::new();
    let mut rest = bytes;
    while !rest.is_empty() {
        let n = match chunks() {
            0 => rest.len(),
            n => n.min(rest.len()),
        };
        let (mut chunk, tail) = rest.split_at(n);
        rest = tail;
        while let Some(rx) = parser.next(&mut chunk) {
            got.push(Got {
                bytes: rx.frame().as_bytes().to_vec(),
                known: rx.meta().is_some(),
                authenticated: rx.is_authenticated(),
            });
        }
        assert!(chunk.is_empty(), "parser left input unconsumed");
    }
    while let Some(rx) = parser.flush() {
        got.push(Got {
            bytes: rx.frame().as_bytes().to_vec(),
            known: rx.meta().is_some(),
            authenticated: rx.is_authenticated(),
        });
    }
    (got, *parser.stats())
}

/// How many of `expected` appear in `got`, in order (greedy).
pub fn recovered(expected: &[Vec<u8>], got: &[&[u8]]) -> usize {
    let mut i = 0;
    let mut n = 0;
    for g in got {
        if let Some(k) = expected[i..].iter().position(|e| e.as_slice() == *g) {
            i += k + 1;
            n += 1;
        }
    }
    n
}

/// Version of a frame's bytes.
pub fn version(frame: &[u8]) -> Version {
    if frame[0] == 0xFE {
        Version::V1
    } else {
        Version::V2
    }
}

/// Why a good frame at some position cannot be told from the candidate
/// frame that starts before it and covers it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shadow {
    /// The candidate is a valid frame under the policy (checksum good, and
    /// no key or unsigned): every parser takes it, or refuses it whole by
    /// policy.
    ValidFrame,
    /// The candidate's checksum is good but its signature fails with the
    /// key: parsers drop it whole.
    BadSignature,
}

/// Whether the frame at `pos` starts inside a candidate of a known message,
/// starting before it, whose checksum is valid.
pub fn shadow<D: MessageSet>(bytes: &[u8], pos: usize, policy: Policy) -> Option<Shadow> {
    for q in pos.saturating_sub(MAX_FRAME_LEN)..pos {
        if bytes[q] != 0xFD && bytes[q] != 0xFE {
            continue;
        }
        let Ok(f) = Frame::new_checked(&bytes[q..]) else {
            continue;
        };
        if q + f.as_bytes().len() <= pos
            || !D::meta(f.msg_id()).is_some_and(|m| f.check_crc(m.crc_extra))
        {
            continue;
        }
        let sig_ok = f.signature().is_none_or(|b| {
            let at = f.as_bytes().len() - SIGNATURE_LEN;
            signature(&KEY, &f.as_bytes()[..at], b.link_id(), b.timestamp()) == b.signature()
        });
        return Some(if policy.key() && !sig_ok {
            Shadow::BadSignature
        } else {
            Shadow::ValidFrame
        });
    }
    None
}

/// Every start of `frame` in `bytes`.
pub fn positions(bytes: &[u8], frame: &[u8]) -> Vec<usize> {
    bytes
        .windows(frame.len())
        .enumerate()
        .filter(|(_, w)| *w == frame)
        .map(|(i, _)| i)
        .collect()
}
