//! The streaming parser as it was before it was made linear (commit
//! eaaeb8e, `mavframe/src/parser.rs`), kept as the oracle of the
//! equivalence tests: the same decisions, written the simple quadratic way
//! (a checksum per candidate, a scan of every start byte inside a raw
//! frame). Only the public API of mavframe is used, so `Frame::new_checked`
//! stands in for the crate-private `Frame::from_delimited`.
// Each test file uses part of it.
#![allow(dead_code)]

use fbwag_dialect::mavframe::frame::{
    frame_len, Frame, FrameError, Header, IFLAG_SIGNED, MAX_FRAME_LEN, SIGNATURE_LEN, STX_V1,
    STX_V2,
};
use fbwag_dialect::mavframe::parser::{
    Stats, Unsigned, BYTES_PER_RAW_SIGNATURE_BYTE, RAW_SIGNATURE_BURST,
};
use fbwag_dialect::mavframe::signing::{SignatureError, Verifier};
use fbwag_dialect::mavframe::{MessageMeta, MessageSet};
use std::marker::PhantomData;

const BUF_LEN: usize = 2 * MAX_FRAME_LEN;

/// The signature budget, in units of 1 / BYTES_PER_RAW_SIGNATURE_BYTE
/// hashed byte: a byte consumed earns one.
const CREDIT_CAP: u64 = RAW_SIGNATURE_BURST * BYTES_PER_RAW_SIGNATURE_BYTE;

/// What checking a signed frame of `len` bytes costs the budget (SHA-256
/// over the key and the frame less its 6 signature bytes).
fn cost(len: usize) -> u64 {
    (len as u64 + 26) * BYTES_PER_RAW_SIGNATURE_BYTE
}
const MAX_TRACKED_LINKS: usize = 16;

/// (sysid, compid, received, lost, gaps, last_seq)
type Link = (u8, u8, u64, u64, u64, u8);

/// A frame the reference accepted: bytes, known, authenticated.
pub type Got = (Vec<u8>, bool, bool);

enum Verdict {
    Need(usize),
    Accept {
        len: usize,
        meta: Option<&'static MessageMeta>,
        authenticated: bool,
    },
    Skip(usize),
    Reject,
}

pub struct Reference<D: MessageSet> {
    buf: [u8; BUF_LEN],
    len: usize,
    returned_from_buf: usize,
    stats: Stats,
    links: [Link; MAX_TRACKED_LINKS],
    tracked: usize,
    verifier: Option<Verifier<16>>,
    accept_unsigned: bool,
    at_eof: bool,
    /// Bytes checksummed plus positions examined: the old algorithm's work.
    pub work: u64,
    /// Bytes of the frames returned (with `bytes_dropped`: the stream
    /// position of the candidate).
    returned: u64,
    /// The parser's budget for unknown ids' signatures (a policy, not an
    /// optimisation: modelled here as the parser has it), in hashed bytes as
    /// of a stream position, and the candidate whose signature was paid.
    sig_credit: u64,
    sig_credit_at: u64,
    sig_paid_at: Option<u64>,
    _dialect: PhantomData<D>,
}

impl<D: MessageSet> Reference<D> {
    pub fn new() -> Self {
        Reference {
            buf: [0; BUF_LEN],
            len: 0,
            returned_from_buf: 0,
            stats: Stats::default(),
            links: [(0, 0, 0, 0, 0, 0); MAX_TRACKED_LINKS],
            tracked: 0,
            verifier: None,
            accept_unsigned: true,
            at_eof: false,
            work: 0,
            returned: 0,
            sig_credit: CREDIT_CAP,
            sig_credit_at: 0,
            sig_paid_at: None,
            _dialect: PhantomData,
        }
    }

    pub fn with_signing(verifier: Verifier<16>, unsigned: Unsigned) -> Self {
        let mut p = Self::new();
        p.verifier = Some(verifier);
        p.accept_unsigned = unsigned == Unsigned::Accept;
        p
    }

    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// (sysid, compid, received, lost, gaps) per tracked sender.
    pub fn links(&self) -> Vec<(u8, u8, u64, u64, u64)> {
        self.links[..self.tracked]
            .iter()
            .map(|l| (l.0, l.1, l.2, l.3, l.4))
            .collect()
    }

    pub fn pending(&self) -> usize {
        self.len
    }

    pub fn next(&mut self, input: &mut &[u8]) -> Option<Got> {
        self.release_returned();
        if !input.is_empty() {
            self.at_eof = false;
        }
        enum Found {
            InInput(usize, Option<&'static MessageMeta>, bool),
            InBuf(usize, Option<&'static MessageMeta>, bool),
        }
        let found = loop {
            if self.len == 0 {
                let Some(start) = input.iter().position(|&b| b == STX_V2 || b == STX_V1) else {
                    self.stats.bytes_dropped += input.len() as u64;
                    *input = &[];
                    return None;
                };
                self.stats.bytes_dropped += start as u64;
                *input = &input[start..];
                match self.check(input) {
                    Verdict::Need(_) => {
                        self.buf[..input.len()].copy_from_slice(input);
                        self.len = input.len();
                        *input = &[];
                        return None;
                    }
                    Verdict::Accept {
                        len,
                        meta,
                        authenticated,
                    } => break Found::InInput(len, meta, authenticated),
                    Verdict::Skip(len) => {
                        self.stats.bytes_dropped += len as u64;
                        *input = &input[len..];
                    }
                    Verdict::Reject => {
                        self.stats.bytes_dropped += 1;
                        *input = &input[1..];
                    }
                }
            } else {
                let held = self.buf;
                match self.check(&held[..self.len]) {
                    Verdict::Need(needed) if needed <= self.len => {
                        self.stats.bytes_dropped += 1;
                        self.drop_front(1);
                    }
                    Verdict::Need(needed) => {
                        let take = (needed - self.len).min(input.len());
                        self.buf[self.len..self.len + take].copy_from_slice(&input[..take]);
                        self.len += take;
                        *input = &input[take..];
                        if self.len < needed {
                            self.at_eof = false;
                            return None;
                        }
                    }
                    Verdict::Accept {
                        len,
                        meta,
                        authenticated,
                    } => break Found::InBuf(len, meta, authenticated),
                    Verdict::Skip(len) => {
                        self.stats.bytes_dropped += len as u64;
                        self.drop_front(len);
                    }
                    Verdict::Reject => {
                        self.stats.bytes_dropped += 1;
                        self.drop_front(1);
                    }
                }
            }
        };
        let (bytes, meta, authenticated): (Vec<u8>, _, _) = match found {
            Found::InInput(len, meta, auth) => {
                let (frame, rest) = input.split_at(len);
                *input = rest;
                (frame.to_vec(), meta, auth)
            }
            Found::InBuf(len, meta, auth) => {
                self.returned_from_buf = len;
                (self.buf[..len].to_vec(), meta, auth)
            }
        };
        self.returned += bytes.len() as u64;
        let h = Frame::new_checked(&bytes).unwrap().header();
        self.record(h, meta.is_some());
        Some((bytes, meta.is_some(), authenticated))
    }

    fn release_returned(&mut self) {
        let n = std::mem::take(&mut self.returned_from_buf);
        if n > 0 {
            self.buf.copy_within(n..self.len, 0);
            self.len -= n;
        }
    }

    pub fn flush(&mut self) -> Option<Got> {
        self.at_eof = true;
        self.next(&mut &[][..])
    }

    fn drop_front(&mut self, n: usize) {
        let rest = &self.buf[n..self.len];
        let next = rest
            .iter()
            .position(|&b| b == STX_V2 || b == STX_V1)
            .unwrap_or(rest.len());
        self.stats.bytes_dropped += next as u64;
        self.buf.copy_within(n + next..self.len, 0);
        self.len -= n + next;
    }

    fn record(&mut self, h: Header, known: bool) {
        if known {
            self.stats.frames += 1;
        } else {
            self.stats.unknown_frames += 1;
        }
        let slot = match self.links[..self.tracked]
            .iter()
            .position(|l| (l.0, l.1) == (h.sysid, h.compid))
        {
            Some(i) => i,
            None => {
                let i = self.tracked.min(MAX_TRACKED_LINKS - 1);
                self.links[i] = (h.sysid, h.compid, 0, 0, 0, h.seq.wrapping_sub(1));
                self.tracked = (self.tracked + 1).min(MAX_TRACKED_LINKS);
                i
            }
        };
        let link = &mut self.links[slot];
        link.2 += 1;
        // A repeat of the sender's last sequence number is a duplicate.
        if link.2 > 1 && h.seq == link.5 {
            self.stats.duplicates += 1;
            return;
        }
        let lost = h.seq.wrapping_sub(link.5.wrapping_add(1)) as u64;
        if lost != 0 {
            link.3 += lost;
            link.4 += 1;
            self.stats.seq_lost += lost;
        }
        link.5 = h.seq;
    }

    /// The candidate's stream position.
    fn at(&self) -> u64 {
        self.stats.bytes_dropped + self.returned
    }

    /// The budget with what the bytes up to the candidate earned.
    fn earn(&mut self) {
        let at = self.at();
        self.sig_credit = (self.sig_credit + at - self.sig_credit_at).min(CREDIT_CAP);
        self.sig_credit_at = at;
    }

    /// Pays for the check of the candidate, `len` bytes long, once: false
    /// when the budget cannot.
    fn pay(&mut self, len: usize) -> bool {
        let at = self.at();
        if self.sig_paid_at == Some(at) {
            return true;
        }
        self.earn();
        if self.sig_credit < cost(len) {
            return false;
        }
        self.sig_credit -= cost(len);
        self.sig_paid_at = Some(at);
        true
    }

    fn check(&mut self, bytes: &[u8]) -> Verdict {
        let at_eof = self.at_eof;
        let need = |n: usize| {
            if at_eof {
                Verdict::Reject
            } else {
                Verdict::Need(n)
            }
        };
        let len = match frame_len(bytes) {
            Ok(len) if bytes.len() >= len => len,
            Ok(len) => {
                if D::meta(msg_id(bytes)).is_none()
                    && known_frame_inside::<D>(bytes, bytes.len(), &mut self.work) == Inside::Yes
                {
                    // A signed one pays as it would whole.
                    let signed =
                        matches!(bytes, [STX_V2, _, flags, ..] if flags & IFLAG_SIGNED != 0);
                    if signed && self.verifier.is_some() && !self.pay(len) {
                        self.stats.signatures_unchecked += 1;
                    }
                    return Verdict::Reject;
                }
                return need(len);
            }
            Err(FrameError::Incomplete { needed }) => return need(needed),
            Err(FrameError::UnknownIncompatFlags(_)) => {
                self.stats.bad_incompat_flags += 1;
                return Verdict::Reject;
            }
            Err(_) => return Verdict::Reject,
        };
        let frame = Frame::new_checked(&bytes[..len]).unwrap();
        let meta = D::meta(frame.msg_id());
        self.work += 1;
        if let Some(m) = meta {
            self.work += len as u64;
            if !frame.check_crc(m.crc_extra) {
                self.stats.bad_crc += 1;
                return Verdict::Reject;
            }
        } else {
            let checked = frame.is_signed() && self.verifier.is_some();
            // Paid before the search inside: a good signature gives it back
            // (below).
            if checked && !self.pay(len) {
                self.stats.signatures_unchecked += 1;
                return Verdict::Reject;
            }
            match known_frame_inside::<D>(bytes, len, &mut self.work) {
                Inside::Yes => return Verdict::Reject,
                Inside::Undecided(needed) if !at_eof => return Verdict::Need(needed),
                Inside::Undecided(_) | Inside::No => {}
            }
            let authenticated_raw = frame.is_signed()
                && self
                    .verifier
                    .as_mut()
                    .is_some_and(|v| v.verify(&frame).is_ok());
            if checked && authenticated_raw {
                self.earn();
                self.sig_credit = (self.sig_credit + cost(len)).min(CREDIT_CAP);
            }
            match bytes.get(len) {
                _ if authenticated_raw => {
                    return Verdict::Accept {
                        len,
                        meta: None,
                        authenticated: true,
                    }
                }
                None if at_eof => {}
                None => return Verdict::Need(len + 1),
                Some(&b) if b != STX_V1 && b != STX_V2 => return Verdict::Reject,
                Some(_) => {}
            }
        }
        let mut authenticated = false;
        if let Some(v) = &mut self.verifier {
            match v.verify(&frame) {
                Ok(()) => authenticated = true,
                Err(SignatureError::Unsigned) if self.accept_unsigned => {}
                Err(SignatureError::Unsigned) => {
                    self.stats.unsigned_rejected += 1;
                    return Verdict::Skip(len);
                }
                // A frame of a known id the key signed, stale: returned
                // unauthenticated where unsigned frames are.
                Err(e)
                    if meta.is_some()
                        && e.is_stale()
                        && self.accept_unsigned
                        && v.signed_with_key(&frame) =>
                {
                    self.stats.stale_timestamp += 1;
                }
                Err(e) => {
                    // Frames of known ids refused for their timestamp are
                    // counted apart (their checksum vouches for them).
                    if meta.is_some() && e.is_stale() {
                        self.stats.stale_timestamp += 1;
                    } else {
                        // A known id's checksum vouches for its header,
                        // and so names whom a wrong key belongs to.
                        self.stats.bad_signature += 1;
                        self.stats.bad_signature_sender = meta.map(|_| {
                            let h = frame.header();
                            (h.sysid, h.compid)
                        });
                    }
                    return if meta.is_some() {
                        Verdict::Skip(len - SIGNATURE_LEN)
                    } else {
                        Verdict::Reject
                    };
                }
            }
        }
        Verdict::Accept {
            len,
            meta,
            authenticated,
        }
    }
}

#[derive(Debug, PartialEq, Eq)]
enum Inside {
    Yes,
    No,
    Undecided(usize),
}

fn known_frame_inside<D: MessageSet>(bytes: &[u8], len: usize, work: &mut u64) -> Inside {
    let mut undecided = None;
    for at in 1..len.min(bytes.len()) {
        *work += 1;
        let b = bytes[at];
        if b != STX_V1 && b != STX_V2 {
            continue;
        }
        let inner = &bytes[at..];
        match frame_len(inner) {
            Ok(n) if inner.len() >= n => {
                *work += n as u64;
                if let Ok(f) = Frame::new_checked(inner) {
                    if D::meta(f.msg_id()).is_some_and(|m| f.check_crc(m.crc_extra)) {
                        return Inside::Yes;
                    }
                }
            }
            Ok(n) if D::meta(msg_id(inner)).is_some() => {
                undecided.get_or_insert(at + n);
            }
            Err(FrameError::Incomplete { needed }) => {
                undecided.get_or_insert(at + needed);
            }
            _ => {}
        }
    }
    undecided.map_or(Inside::No, Inside::Undecided)
}

fn msg_id(bytes: &[u8]) -> u32 {
    match bytes.first() {
        Some(&STX_V2) => u32::from_le_bytes([
            bytes.get(7).copied().unwrap_or(0),
            bytes.get(8).copied().unwrap_or(0),
            bytes.get(9).copied().unwrap_or(0),
            0,
        ]),
        _ => bytes.get(5).copied().unwrap_or(0) as u32,
    }
}
