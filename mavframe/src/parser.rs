//! A streaming frame parser: push bytes in any chunking, take frames out.
//!
//! ```
//! # use mavframe::{parser::Parser, Dialect, MessageMeta};
//! # struct D; impl Dialect for D { type Message = (); type View<'a> = ();
//! #   const MESSAGES: &'static [MessageMeta] = &[];
//! #   fn parse(_: u32, _: &[u8]) -> Option<()> { None } fn view(_: u32, _: &[u8]) -> Option<()> { None } }
//! let mut parser = Parser::<D>::new();
//! let mut chunk: &[u8] = b"\x00garbage";
//! while let Some(received) = parser.next(&mut chunk) {
//!     println!("{:?}", received.frame);
//! }
//! assert_eq!(parser.stats().bytes_dropped, 8);
//! ```
//!
//! A frame that lies whole inside the chunk is returned in place (no copy);
//! one that spans chunks is assembled in a 280-byte buffer inside the parser.
//! When a candidate frame is rejected (bad checksum, unknown incompatibility
//! flags) the parser resumes at the byte after its start byte, so a corrupted
//! or truncated frame never swallows the good frames inside the length it
//! claimed, which pymavlink and the C parser do. Frames with a valid checksum
//! but a bad signature are skipped whole.
//!
//! Frames of message ids the dialect does not know cannot be checked (their
//! CRC_EXTRA is unknown), yet routers must forward them. Garbage holding a
//! start byte almost always looks like such a frame, so one is returned raw
//! only when confirmed: the byte after it is a start byte (or it is
//! authenticated by its signature), and no known frame with a valid checksum
//! starts inside it: a known good frame always wins. The last frame of a
//! stream is confirmed by [`Parser::flush`].

use crate::frame::{frame_len, Frame, FrameError, Header, MAX_FRAME_LEN, STX_V1, STX_V2};
use crate::message::{Dialect, MessageMeta};
use crate::signing::{SignatureError, Verifier};
use core::marker::PhantomData;

/// Counters of what the parser saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Frames of known messages returned (checksum verified).
    pub frames: u64,
    /// Frames of unknown message ids returned raw (checksum not verifiable).
    pub unknown_frames: u64,
    /// Candidate frames rejected for their checksum.
    pub bad_crc: u64,
    /// Frames rejected for a signature that does not verify (wrong key,
    /// replay, too old).
    pub bad_signature: u64,
    /// Unsigned frames rejected because the signing policy requires signatures.
    pub unsigned_rejected: u64,
    /// Candidate frames rejected for unknown incompatibility flags.
    pub bad_incompat_flags: u64,
    /// Bytes discarded: garbage, rejected candidates, and frames the signing
    /// policy refused. With the bytes of returned frames, they account for
    /// every byte pushed.
    pub bytes_dropped: u64,
    /// Frames missing according to sequence numbers, over all senders.
    pub seq_lost: u64,
}

/// Per-sender sequence tracking.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// Sender system id.
    pub sysid: u8,
    /// Sender component id.
    pub compid: u8,
    /// Frames received from this sender.
    pub received: u64,
    /// Frames missing according to sequence numbers.
    pub lost: u64,
    /// Sequence gaps seen (each gap may be several frames).
    pub gaps: u64,
    last_seq: u8,
}

const BUF_LEN: usize = 2 * MAX_FRAME_LEN;

/// Senders tracked for sequence gaps; more are folded into the last slot.
pub const MAX_TRACKED_LINKS: usize = 32;

/// A frame the parser accepted.
pub struct Received<'a, D: Dialect> {
    /// The frame, borrowed from the input chunk or the parser's buffer.
    pub frame: Frame<'a>,
    /// The message's table row; `None` for an id the dialect does not know
    /// (a raw frame: its checksum could not be verified).
    pub meta: Option<&'static MessageMeta>,
    /// True when the frame's signature was verified with the key.
    pub authenticated: bool,
    _dialect: PhantomData<D>,
}

impl<'a, D: Dialect> Received<'a, D> {
    /// A zero-copy view of the message; `None` for an unknown id.
    pub fn view(&self) -> Option<D::View<'a>> {
        self.meta?;
        D::view(self.frame.msg_id(), self.frame.payload())
    }

    /// The message, copied out; `None` for an unknown id.
    pub fn message(&self) -> Option<D::Message> {
        self.meta?;
        D::parse(self.frame.msg_id(), self.frame.payload())
    }
}

impl<D: Dialect> core::fmt::Debug for Received<'_, D> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Received")
            .field("frame", &self.frame)
            .field("name", &self.meta.map(|m| m.name))
            .field("authenticated", &self.authenticated)
            .finish()
    }
}

/// What to do with the candidate frame at the start of some bytes.
enum Verdict {
    /// More bytes are needed: the candidate is this long (so far).
    Need(usize),
    /// A frame of this length.
    Accept {
        len: usize,
        meta: Option<&'static MessageMeta>,
        authenticated: bool,
    },
    /// A real frame (checksum good) that policy drops whole.
    Skip(usize),
    /// Not a frame: resume at the next byte.
    Reject,
}

/// The streaming parser for dialect `D`, verifying signatures for up to
/// `STREAMS` signing streams when a key is configured.
pub struct Parser<D: Dialect, const STREAMS: usize = 16> {
    /// Twice a frame: confirming a raw frame may need the frame after it.
    buf: [u8; BUF_LEN],
    /// Bytes of a candidate frame held in `buf` (starting with a start byte).
    len: usize,
    /// Length of the frame at the start of `buf` returned by the last call;
    /// it is dropped (bytes after it are kept) when the parser next runs.
    returned_from_buf: usize,
    stats: Stats,
    links: [LinkStats; MAX_TRACKED_LINKS],
    tracked: usize,
    verifier: Option<Verifier<STREAMS>>,
    accept_unsigned: bool,
    /// Set by [`Parser::flush`]: no more bytes will come.
    at_eof: bool,
    // fn() -> D: the dialect is a type-level tag; the parser is Send and Sync
    // whatever the tag type is.
    _dialect: PhantomData<fn() -> D>,
}

impl<D: Dialect, const STREAMS: usize> Default for Parser<D, STREAMS> {
    fn default() -> Self {
        Self::new()
    }
}

impl<D: Dialect, const STREAMS: usize> core::fmt::Debug for Parser<D, STREAMS> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Parser")
            .field("pending", &self.len)
            .field("stats", &self.stats)
            .field("signing", &self.verifier.is_some())
            .finish()
    }
}

impl<D: Dialect, const STREAMS: usize> Parser<D, STREAMS> {
    /// A parser without signing: signed frames are accepted unverified
    /// (as pymavlink and the C library do when no key is set up).
    pub fn new() -> Self {
        Parser {
            buf: [0; BUF_LEN],
            len: 0,
            returned_from_buf: 0,
            stats: Stats::default(),
            links: [LinkStats::default(); MAX_TRACKED_LINKS],
            tracked: 0,
            verifier: None,
            accept_unsigned: true,
            at_eof: false,
            _dialect: PhantomData,
        }
    }

    /// A parser that verifies signatures with `verifier`; whether unsigned
    /// frames are accepted is the caller's policy.
    pub fn with_signing(verifier: Verifier<STREAMS>, accept_unsigned: bool) -> Self {
        let mut p = Self::new();
        p.verifier = Some(verifier);
        p.accept_unsigned = accept_unsigned;
        p
    }

    /// What the parser has seen so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The signature verifier, when signing is configured (to save its
    /// state: see [`crate::signing::state`]).
    pub fn verifier(&self) -> Option<&Verifier<STREAMS>> {
        self.verifier.as_ref()
    }

    /// Sequence statistics per sender (the first [`MAX_TRACKED_LINKS`]).
    pub fn links(&self) -> &[LinkStats] {
        &self.links[..self.tracked]
    }

    /// Bytes held for an incomplete frame.
    pub fn pending(&self) -> usize {
        self.len
    }

    /// Consumes bytes from `input` until a frame is complete and returns it;
    /// `None` once `input` is used up (a partial frame stays buffered for
    /// the next chunk). `input` is advanced past what was consumed.
    pub fn next<'r, 'i: 'r>(&'r mut self, input: &mut &'i [u8]) -> Option<Received<'r, D>> {
        self.release_returned();
        if !input.is_empty() {
            self.at_eof = false;
        }
        // Decide in the loop, borrow after it: the frame borrows either the
        // input or the buffer.
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
                match self.check_at_input(input) {
                    Verdict::Need(_) => {
                        // Shorter than the frame it starts, so it fits the buffer.
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
                match self.check_at_buf() {
                    // Cannot happen (a need is always for more than is held);
                    // rejecting keeps the loop making progress regardless.
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
        let (bytes, meta, authenticated) = match found {
            Found::InInput(len, meta, auth) => {
                let (frame, rest) = input.split_at(len);
                *input = rest;
                (frame, meta, auth)
            }
            Found::InBuf(len, meta, auth) => {
                self.returned_from_buf = len;
                (&self.buf[..len], meta, auth)
            }
        };
        // `check` delimited these bytes with `frame_len`.
        let frame = Frame::from_delimited(bytes);
        Self::record(
            &mut self.stats,
            &mut self.links,
            &mut self.tracked,
            frame.header(),
            meta.is_some(),
        );
        Some(Received {
            frame,
            meta,
            authenticated,
            _dialect: PhantomData,
        })
    }

    fn release_returned(&mut self) {
        let n = core::mem::take(&mut self.returned_from_buf);
        if n > 0 {
            self.buf.copy_within(n..self.len, 0);
            self.len -= n;
        }
    }

    /// Ends the stream: call until `None`. Buffered bytes are parsed as if
    /// nothing follows them: an incomplete candidate is rejected and the
    /// bytes after its start byte are searched again (so a false start byte
    /// near the end loses no frame), and a raw frame of an unknown id that
    /// was waiting for the byte after it is returned.
    pub fn flush(&mut self) -> Option<Received<'_, D>> {
        self.at_eof = true;
        self.next(&mut &[][..])
    }

    /// Drops `n` bytes of the buffered candidate, then everything up to the
    /// next start byte in what remains (counted as dropped).
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

    #[inline(always)]
    fn check_at_input(&mut self, bytes: &[u8]) -> Verdict {
        check::<D, STREAMS>(
            bytes,
            &mut self.verifier,
            self.accept_unsigned,
            self.at_eof,
            &mut self.stats,
        )
    }

    fn check_at_buf(&mut self) -> Verdict {
        check::<D, STREAMS>(
            &self.buf[..self.len],
            &mut self.verifier,
            self.accept_unsigned,
            self.at_eof,
            &mut self.stats,
        )
    }

    fn record(
        stats: &mut Stats,
        links: &mut [LinkStats; MAX_TRACKED_LINKS],
        tracked: &mut usize,
        h: Header,
        known: bool,
    ) {
        if known {
            stats.frames += 1;
        } else {
            stats.unknown_frames += 1;
        }
        let slot = match links[..*tracked]
            .iter()
            .position(|l| (l.sysid, l.compid) == (h.sysid, h.compid))
        {
            Some(i) => i,
            None => {
                let i = (*tracked).min(MAX_TRACKED_LINKS - 1);
                links[i] = LinkStats {
                    sysid: h.sysid,
                    compid: h.compid,
                    received: 0,
                    lost: 0,
                    gaps: 0,
                    last_seq: h.seq.wrapping_sub(1),
                };
                *tracked = (*tracked + 1).min(MAX_TRACKED_LINKS);
                i
            }
        };
        let link = &mut links[slot];
        let lost = h.seq.wrapping_sub(link.last_seq.wrapping_add(1)) as u64;
        if lost != 0 {
            link.lost += lost;
            link.gaps += 1;
            stats.seq_lost += lost;
        }
        link.last_seq = h.seq;
        link.received += 1;
    }
}

#[inline(always)]
fn check<D: Dialect, const N: usize>(
    bytes: &[u8],
    verifier: &mut Option<Verifier<N>>,
    accept_unsigned: bool,
    at_eof: bool,
    stats: &mut Stats,
) -> Verdict {
    // At the end of the stream an incomplete candidate is not a frame.
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
            // An unverifiable candidate loses at once to a good frame inside.
            if D::meta(msg_id(bytes)).is_none()
                && known_frame_inside::<D>(bytes, bytes.len()) == Inside::Yes
            {
                return Verdict::Reject;
            }
            return need(len);
        }
        Err(FrameError::Incomplete { needed }) => return need(needed),
        Err(FrameError::UnknownIncompatFlags(_)) => {
            stats.bad_incompat_flags += 1;
            return Verdict::Reject;
        }
        Err(_) => return Verdict::Reject,
    };
    let frame = Frame::from_delimited(&bytes[..len]);
    let meta = D::meta(frame.msg_id());
    if let Some(m) = meta {
        if !frame.check_crc(m.crc_extra) {
            stats.bad_crc += 1;
            return Verdict::Reject;
        }
    } else {
        // A raw frame: accept only once confirmed (see the module docs).
        match known_frame_inside::<D>(bytes, len) {
            Inside::Yes => return Verdict::Reject,
            Inside::Undecided(needed) if !at_eof => return Verdict::Need(needed),
            Inside::Undecided(_) | Inside::No => {}
        }
        let authenticated_raw =
            frame.is_signed() && verifier.as_mut().is_some_and(|v| v.verify(&frame).is_ok());
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
    if let Some(v) = verifier {
        match v.verify(&frame) {
            Ok(()) => authenticated = true,
            Err(SignatureError::Unsigned) if accept_unsigned => {}
            Err(SignatureError::Unsigned) => {
                stats.unsigned_rejected += 1;
                return Verdict::Skip(len);
            }
            Err(_) => {
                stats.bad_signature += 1;
                // A good checksum vouches for the header and payload only: the
                // 13 bytes after it may be the head of the next frame (a frame
                // cut inside its signature block), so those are searched
                // again. With an unverifiable checksum the "frame" may be
                // garbage: resume inside it.
                return if meta.is_some() {
                    Verdict::Skip(len - crate::frame::SIGNATURE_LEN)
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

/// Whether a known frame with a valid checksum starts inside the first `len`
/// bytes of `bytes` (after its first byte).
#[derive(Debug, PartialEq, Eq)]
enum Inside {
    Yes,
    No,
    /// A candidate inside needs this many bytes (from `bytes[0]`) to decide.
    Undecided(usize),
}

fn known_frame_inside<D: Dialect>(bytes: &[u8], len: usize) -> Inside {
    // A good frame anywhere decides; an undecided position only matters
    // when no good frame is found.
    let mut undecided = None;
    for at in 1..len.min(bytes.len()) {
        let b = bytes[at];
        if b != STX_V1 && b != STX_V2 {
            continue;
        }
        let inner = &bytes[at..];
        match frame_len(inner) {
            Ok(n) if inner.len() >= n => {
                if let Ok(f) = Frame::new_checked(inner) {
                    if D::meta(f.msg_id()).is_some_and(|m| f.check_crc(m.crc_extra)) {
                        return Inside::Yes;
                    }
                }
            }
            // Only a known id can make a good frame: wait for it whole.
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

/// The message id in a (possibly incomplete) header at `bytes[0]`.
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
