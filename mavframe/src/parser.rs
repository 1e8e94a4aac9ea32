//! A streaming frame parser: push bytes in any chunking, take frames out.
//!
//! ```
//! # use mavframe::{parser::Parser, MessageSet, MessageMeta};
//! # struct D; impl MessageSet for D { type Message = (); type View<'a> = ();
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
//! one that spans chunks is assembled in a buffer inside the parser (room
//! for two frames: confirming a raw frame, below, may need the head of the
//! next one; 1 KiB, so that dropping bytes from its front never moves more
//! than it drops, on average). The bytes the buffer takes ahead from the
//! new chunk stay in the input until they are consumed: once the bytes of
//! earlier chunks are dropped, the parser goes back to the input in place.
//! When a candidate frame is rejected (bad checksum, unknown
//! incompatibility flags) the parser resumes at the byte
//! after its start byte, so a corrupted or truncated frame never swallows
//! the good frames inside the length it claimed, which pymavlink and the C
//! parser do. A frame with a valid checksum but a bad signature is skipped
//! up to its checksum (its 13 signature bytes may be the head of the next
//! frame, and are searched again); one refused for being unsigned is
//! skipped whole.
//!
//! Frames of message ids the dialect does not know cannot be checked (their
//! CRC_EXTRA is unknown), yet routers must forward them. Garbage holding a
//! start byte almost always looks like such a frame, so one is returned raw
//! only when confirmed: the byte after it is a start byte (or it is
//! authenticated by its signature), and no known frame with a valid checksum
//! starts inside it: a known good frame always wins. The last frame of a
//! stream is confirmed by [`Parser::flush`], the last of a datagram by
//! [`Parser::end_of_datagram`]. A datagram's bytes are best pushed with
//! [`Parser::next_in_datagram`]: the same frames, but a candidate its end
//! cuts is rejected at once instead of waiting for the end to be told (in
//! garbage, most of a datagram's candidates claim frames longer than what
//! is left of it: the private `end_cut` module rejects them 64 at a time).
//!
//! The work per byte is bounded whatever the input, adversarial included:
//! a good frame's checksum is computed once, directly; a checksum over bytes
//! an earlier candidate covered comes from CRC prefix states, and whether a
//! good known frame starts at a position is decided once per position and
//! remembered (the private `memo` module; [`Parser::work`] counts the
//! steps). Verifying a signature (with a key) is one SHA-256 per signed
//! candidate with a good checksum or of an unknown id. A known id's bad
//! signature skips the frame up to its checksum (at least 12 bytes per
//! SHA-256), but an unknown id has no checksum to vouch for it, and garbage
//! can hold such a candidate at every other byte: their checks (the search
//! for a known frame inside, then the SHA-256) draw on a budget that earns
//! one hashed byte per [`BYTES_PER_RAW_SIGNATURE_BYTE`] bytes consumed (up
//! to [`RAW_SIGNATURE_BURST`] saved). A signed candidate is checked only
//! when the budget holds its cost (the frame's length + 26 hashed bytes),
//! which the check takes, as does a rejection for a good frame inside
//! before the candidate is whole; a good signature gives it back (the frame
//! is returned, its bytes pay for its check), so no stream of genuine
//! frames exhausts it. A candidate found when the budget cannot pay is not
//! authenticated, so it is rejected
//! ([`Stats::signatures_unchecked`]): a flood of forged signed frames of
//! unknown ids (or of frames signed with another key) can cost genuine ones
//! of unknown ids, never known ones, and
//! never admits a forgery. A candidate is
//! decided as soon as the bytes at hand decide it (with bytes held, the
//! parser copies ahead of the candidate rather than byte by byte).
//!
//! After a frame, pass the rest of the input (what [`Parser::next`] left in
//! it) on the next call, as a streaming parser expects. The parser may have
//! looked at bytes past the frame; a caller that drops them and pushes other
//! bytes can make it miss frames, never accept a bad one: a frame is taken
//! only on its own bytes' checksum.

mod end_cut;
mod memo;
mod senders;

use crate::frame::{
    frame_len, Frame, FrameError, Header, HEADER_LEN_V2, IFLAG_KNOWN, IFLAG_SIGNED, MAX_FRAME_LEN,
    STX_V1, STX_V2,
};
use crate::message::{MessageMeta, MessageSet};
use crate::signing::{SignatureError, Verifier};
use core::marker::PhantomData;
use memo::{span_mask, Block, Inside, Memo, Starts, Whole};
use senders::Senders;

/// Counters of what the parser saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Stats {
    /// Frames of known messages returned (checksum verified).
    pub frames: u64,
    /// Frames of unknown message ids returned raw (checksum not verifiable).
    pub unknown_frames: u64,
    /// Candidate frames rejected for their checksum.
    pub bad_crc: u64,
    /// Frames rejected for a signature that does not match the key (and
    /// signed frames of unknown ids refused for any signing reason: their
    /// checksum cannot vouch for them).
    pub bad_signature: u64,
    /// Frames of known ids refused for their signing timestamp (a replay,
    /// or a new stream more than a minute behind: see
    /// [`SignatureError::is_stale`]), counted apart from `bad_signature`:
    /// the timestamp is checked first, so these may be genuine frames from
    /// a signer whose clock is behind.
    pub stale_timestamp: u64,
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
    /// Signed candidates of unknown ids rejected without checking their
    /// signature, the budget for those being spent (see the module docs):
    /// a sign of forged frames.
    pub signatures_unchecked: u64,
}

/// Bytes consumed per hashed byte that the budget for checking signed
/// candidates of unknown ids earns (see the module docs): an attacker
/// without the key makes the parser hash at most one byte per this many it
/// sends, beyond [`RAW_SIGNATURE_BURST`] (a good signature gives its cost
/// back).
pub const BYTES_PER_RAW_SIGNATURE_BYTE: u64 = 2;

/// Hashed bytes of the budget saved up at most (and at the start): eight
/// of the longest signed frames.
pub const RAW_SIGNATURE_BURST: u64 = 8 * raw_signature_cost(crate::frame::MAX_FRAME_LEN);

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

/// The longest candidate the parser waits for: a frame of an unknown id
/// (up to a frame long) whose last byte starts a candidate of a known id
/// (another frame), less one.
const MAX_NEEDED: usize = 2 * MAX_FRAME_LEN - 1;

/// The buffer: more than twice [`MAX_NEEDED`]'s bytes would be too many
/// for no gain, fewer makes the front drops move bytes too often. Bytes are
/// dropped from its front by moving a start index; the bytes held move to
/// the front only when the end needs room, after more than
/// `BUF_LEN - MAX_NEEDED` bytes were dropped since they last moved.
const BUF_LEN: usize = 1024;

const _: () = assert!(BUF_LEN > MAX_NEEDED && BUF_LEN - MAX_NEEDED >= MAX_NEEDED * 4 / 5);

/// The bytes held are topped up to [`MAX_NEEDED`] once they fall this far
/// below it (a candidate that needs more asks for it).
const TOP_UP_SLACK: usize = 64;

/// How much work a parser did: see [`Parser::work`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
pub struct Work {
    /// Elementary steps: bytes checksummed (directly or as CRC prefix
    /// states), bytes scanned for a start byte, copied into or moved inside
    /// the buffer; candidate checks, positions classified, wake-up
    /// positions handled. Bounded by a constant times the bytes pushed
    /// plus the calls made, whatever the bytes.
    pub steps: u64,
    /// Signatures checked (one SHA-256 of the frame each).
    pub signatures: u64,
}

/// What a signing parser does with unsigned frames ([`Parser::with_signing`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Unsigned {
    /// Unsigned frames are returned (signed ones must still verify): a link
    /// in transition, or one where signing is a sender's choice.
    Accept,
    /// Unsigned frames are dropped and counted in
    /// [`Stats::unsigned_rejected`].
    Refuse,
}

/// Senders tracked for sequence gaps; more are folded into the last slot.
pub const MAX_TRACKED_LINKS: usize = 32;

/// A frame the parser accepted.
pub struct Received<'a, D: MessageSet> {
    /// The frame, borrowed from the input chunk or the parser's buffer.
    pub frame: Frame<&'a [u8]>,
    /// The message's table row; `None` for an id the dialect does not know
    /// (a raw frame: its checksum could not be verified).
    pub meta: Option<&'static MessageMeta>,
    /// True when the frame's signature was verified with the key.
    pub authenticated: bool,
    _dialect: PhantomData<D>,
}

impl<'a, D: MessageSet> Received<'a, D> {
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

impl<D: MessageSet> core::fmt::Debug for Received<'_, D> {
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

/// Where the frame a call returns lies.
enum Found {
    InInput(usize, Option<&'static MessageMeta>, bool),
    InBuf(usize, Option<&'static MessageMeta>, bool),
}

/// The counters a returned frame updates.
type Counters<'a> = (&'a mut Stats, &'a mut Senders);

/// What the hot path found at the start of the input.
enum InPlace {
    /// A good frame of a known id, this long, in place.
    Good(usize, &'static MessageMeta),
    /// A whole frame of a known id with a bad checksum: rejected.
    BadCrc,
    /// Anything else: for the general loop.
    Other,
}

/// What a step with bytes held decided.
enum Held {
    /// Go on.
    Next,
    /// The input is used up: more bytes are needed.
    Wait,
    /// A frame at the start of the bytes held.
    Found(Found),
}

/// The streaming parser for dialect `D`, verifying signatures for up to
/// `STREAMS` signing streams when a key is configured.
pub struct Parser<D: MessageSet, const STREAMS: usize = 16> {
    /// Bytes held for a candidate that spans chunks.
    buf: [u8; BUF_LEN],
    /// Where the bytes held start in `buf`.
    head: usize,
    /// Bytes of a candidate frame held in `buf` (starting with a start byte).
    len: usize,
    /// Length of the frame at the start of the bytes held returned by the
    /// last call; it is dropped (bytes after it are kept) when the parser
    /// next runs.
    returned_from_buf: usize,
    /// The last call returned a frame found among start bytes the
    /// rejection loop found dense: the next call starts with that loop (a
    /// frame of an unknown id every few bytes of garbage would otherwise
    /// cost a whole check of the candidate after each).
    resume_in_garbage: bool,
    /// Stream position (bytes pushed before it) of the first byte not
    /// consumed yet: the first byte held, or of the input when none is.
    pos: u64,
    /// The last this many bytes held are copies of the first as many of
    /// the input, taken ahead of the candidate without consuming them:
    /// once the bytes held before them are all dropped, the parser goes
    /// back to the input in place, where the caller passes them again.
    shadow: usize,
    /// What is known about the bytes after the candidate.
    memo: Memo,
    stats: Stats,
    links: Senders,
    verifier: Option<Verifier<STREAMS>>,
    accept_unsigned: bool,
    /// Set by [`Parser::flush`]: no more bytes will come.
    at_eof: bool,
    /// Set by [`Parser::next_in_datagram`] for the call it makes: the
    /// input ends where its datagram does.
    datagram_ends: bool,
    // fn() -> D: the dialect is a type-level tag; the parser is Send and Sync
    // whatever the tag type is.
    _dialect: PhantomData<fn() -> D>,
}

impl<D: MessageSet, const STREAMS: usize> Default for Parser<D, STREAMS> {
    fn default() -> Self {
        Self::new()
    }
}

impl<D: MessageSet, const STREAMS: usize> core::fmt::Debug for Parser<D, STREAMS> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Parser")
            .field("pending", &self.len)
            .field("stats", &self.stats)
            .field("signing", &self.verifier.is_some())
            .finish()
    }
}

impl<D: MessageSet, const STREAMS: usize> Parser<D, STREAMS> {
    /// A parser without signing: signed frames are accepted unverified
    /// (as pymavlink and the C library do when no key is set up).
    pub fn new() -> Self {
        Parser {
            buf: [0; BUF_LEN],
            head: 0,
            len: 0,
            returned_from_buf: 0,
            resume_in_garbage: false,
            pos: 0,
            shadow: 0,
            memo: Memo::new(),
            stats: Stats::default(),
            links: Senders::new(),
            verifier: None,
            accept_unsigned: true,
            at_eof: false,
            datagram_ends: false,
            _dialect: PhantomData,
        }
    }

    /// A parser that verifies signatures with `verifier`; whether unsigned
    /// frames are accepted is the caller's policy.
    ///
    /// ```
    /// use mavframe::parser::{Parser, Unsigned};
    /// use mavframe::signing::{Signer, Verifier};
    /// use mavframe::frame::{FrameBuf, Header, Version};
    /// # use mavframe::{MessageSet, MessageMeta, Encode, BufferTooSmall};
    /// # const PING: MessageMeta = MessageMeta { id: 4242, name: "PING_EXAMPLE",
    /// #   crc_extra: 7, min_len: 1, max_len: 1, target_system_offset: None,
    /// #   target_component_offset: None, fields: &[] };
    /// # struct D; impl MessageSet for D { type Message = (); type View<'a> = ();
    /// #   const MESSAGES: &'static [MessageMeta] = &[PING];
    /// #   fn parse(_: u32, _: &[u8]) -> Option<()> { Some(()) }
    /// #   fn view(_: u32, _: &[u8]) -> Option<()> { Some(()) } }
    /// # struct Ping; impl Encode for Ping { fn meta(&self) -> &'static MessageMeta { &PING }
    /// #   fn emit_payload(&self, out: &mut [u8]) -> Result<usize, BufferTooSmall> {
    /// #     *out.first_mut().ok_or(BufferTooSmall { needed: 1, got: 0 })? = 1; Ok(1) } }
    /// let key = [7u8; 32];
    /// let mut signer = Signer::new(key, 1, 1_000);
    /// let h = Header { seq: 0, sysid: 1, compid: 1 };
    /// let signed = FrameBuf::encode(Version::V2, h, &Ping, Some(&mut signer)).unwrap();
    /// let unsigned = FrameBuf::encode(Version::V2, h, &Ping, None).unwrap();
    ///
    /// let mut parser = Parser::<D>::with_signing(Verifier::new(key), Unsigned::Refuse);
    /// let mut input: &[u8] = &[&unsigned[..], &signed[..]].concat();
    /// let first = parser.next(&mut input).unwrap();
    /// assert!(first.frame.is_signed()); // the unsigned frame was dropped
    /// assert_eq!(parser.stats().unsigned_rejected, 1);
    /// ```
    pub fn with_signing(verifier: Verifier<STREAMS>, unsigned: Unsigned) -> Self {
        let mut p = Self::new();
        p.verifier = Some(verifier);
        p.accept_unsigned = unsigned == Unsigned::Accept;
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

    /// The signature verifier, to change: e.g. to swap in the state that
    /// several parsers of one link share (the router's `tcpin` clients), so
    /// that a frame accepted on one is a replay on the others.
    pub fn verifier_mut(&mut self) -> Option<&mut Verifier<STREAMS>> {
        self.verifier.as_mut()
    }

    /// Sequence statistics per sender (the first [`MAX_TRACKED_LINKS`]).
    pub fn links(&self) -> &[LinkStats] {
        self.links.links()
    }

    /// Bytes held for an incomplete frame (consumed from the input).
    pub fn pending(&self) -> usize {
        self.len - self.shadow
    }

    /// The work done so far, for tests and monitoring: the steps are
    /// bounded by a constant times (bytes pushed + calls), whatever the
    /// bytes (the parser tests pin the constant).
    pub fn work(&self) -> Work {
        Work {
            // Each byte consumed (dropped or returned) was looked at, each
            // frame returned checksummed once, and each candidate checked:
            // counted here rather than on the hot path.
            steps: self.memo.steps + 2 * self.pos + self.stats.frames + self.stats.unknown_frames,
            signatures: self.memo.signatures,
        }
    }

    /// Consumes bytes from `input` until a frame is complete and returns it;
    /// `None` once `input` is used up (a partial frame stays buffered for
    /// the next chunk). `input` is advanced past what was consumed.
    pub fn next<'r, 'i: 'r>(&'r mut self, input: &mut &'i [u8]) -> Option<Received<'r, D>> {
        if input.len() < self.shadow {
            // Not the rest of the input the copies were taken from (a
            // caller that dropped it, or a flush): they are all there is.
            self.shadow = 0;
        }
        self.release_returned();
        // (With bytes held from an earlier call, the held ones are checked
        // before the input's are all copied: the end of the stream is not
        // at hand, and the datagram is ended as usual.)
        let datagram_ends = core::mem::take(&mut self.datagram_ends) && self.len == 0;
        if !input.is_empty() {
            if self.at_eof && !datagram_ends {
                // More bytes after a flush not drained: what the memo
                // decided for the end of the stream no longer holds.
                self.memo.forget_from(self.pos);
            }
            self.at_eof = datagram_ends;
        }
        // The last verdict was a rejection: garbage, maybe dense in start
        // bytes, where `reject_run` is the fast way through.
        // (With bytes held, `step_held` takes it.)
        let mut rejected = self.len == 0 && core::mem::take(&mut self.resume_in_garbage);
        if self.len == 0 && self.verifier.is_none() && !rejected {
            // The hot path: a good frame of a known id whole in the input.
            match self.good_frame_in_place(input) {
                InPlace::Good(len, meta) => {
                    let (frame, rest) = input.split_at(len);
                    *input = rest;
                    self.pos += len as u64;
                    return Some(Self::received(
                        frame,
                        Some(meta),
                        false,
                        (&mut self.stats, &mut self.links),
                    ));
                }
                InPlace::BadCrc => rejected = true,
                InPlace::Other => {}
            }
        } else if rejected && self.len == 0 && self.verifier.is_none() {
            // After a frame of an unknown id: garbage's or a router's next
            // one, decided from what the memo knows.
            let found = match self.raw_frame_by_masks(input) {
                Some(found) => found,
                None if !self.memo.dense_starts => self.raw_frame_in_place(input),
                None => None,
            };
            if let Some(len) = found {
                let (frame, rest) = input.split_at(len);
                *input = rest;
                self.pos += len as u64;
                self.resume_in_garbage = true;
                return Some(Self::received(
                    frame,
                    None,
                    false,
                    (&mut self.stats, &mut self.links),
                ));
            }
        }
        // Decide in the loop, borrow after it: the frame borrows either the
        // input or the buffer.
        let found = loop {
            if self.len != 0 {
                match self.step_held(input) {
                    Held::Next => continue,
                    Held::Wait => return None,
                    Held::Found(f) => break f,
                }
            }
            let start = if matches!(input.first(), Some(&(STX_V1 | STX_V2))) {
                0
            } else {
                let Some(start) = input.iter().position(|&b| b == STX_V2 || b == STX_V1) else {
                    self.input_used_up(input);
                    return None;
                };
                start
            };
            self.drop_input(input, start);
            if core::mem::take(&mut rejected) {
                let run = reject_run::<D, STREAMS>(input, self.ctx());
                self.pos += run.dropped as u64;
                *input = &input[run.dropped..];
                match run.end {
                    RunEnd::Accepted { len, authenticated } => {
                        break Found::InInput(len, None, authenticated)
                    }
                    RunEnd::Policy(len) => {
                        // What `check` would decide, from its signing
                        // policy on.
                        let frame = Frame::new_unchecked(&input[..len]);
                        match signing(&frame, None, self.ctx()) {
                            Verdict::Accept {
                                len,
                                meta,
                                authenticated,
                            } => break Found::InInput(len, meta, authenticated),
                            verdict => self.drop_input(input, dropped_by(verdict)),
                        }
                        rejected = true;
                        continue;
                    }
                    RunEnd::Check if run.dropped > 0 => continue,
                    RunEnd::Check => {}
                }
            }
            match self.check_at_input(input) {
                Verdict::Need(_) => {
                    self.hold_input(input);
                    return None;
                }
                Verdict::Accept {
                    len,
                    meta,
                    authenticated,
                } => break Found::InInput(len, meta, authenticated),
                // A frame refused by the signing policy (unsigned, or a bad
                // signature) is garbage to this link: what follows it is
                // more of the same as often as after a rejection.
                Verdict::Skip(len) => {
                    self.drop_input(input, len);
                    rejected = true;
                }
                Verdict::Reject => {
                    self.drop_input(input, 1);
                    rejected = true;
                }
            }
        };
        let (bytes, meta, authenticated) = match found {
            Found::InInput(len, meta, auth) => {
                let (frame, rest) = input.split_at(len);
                *input = rest;
                self.pos += len as u64;
                (frame, meta, auth)
            }
            Found::InBuf(len, meta, auth) => {
                self.settle_returned(len, input);
                self.returned_from_buf = len;
                (&self.buf[self.head..self.head + len], meta, auth)
            }
        };
        // A frame of an unknown id is as likely garbage's as a router's:
        // the next call starts with the rejection loop, which decides a
        // candidate of either kind without `check`'s plumbing.
        self.resume_in_garbage = self.memo.dense_starts || meta.is_none();
        Some(Self::received(
            bytes,
            meta,
            authenticated,
            (&mut self.stats, &mut self.links),
        ))
    }

    /// The first candidate of `input` (garbage before it dropped) when it is
    /// a whole frame of a known id the memo knows nothing about: its
    /// checksum checked as without a memo. With a bad one it is rejected
    /// here, as `check` would (counted, its start byte dropped).
    #[inline(always)]
    fn good_frame_in_place(&mut self, input: &mut &[u8]) -> InPlace {
        let Some(start) = input.iter().position(|&b| b == STX_V2 || b == STX_V1) else {
            return InPlace::Other;
        };
        let cand = &input[start..];
        let at = self.pos + start as u64;
        let Ok(len) = frame_len(cand) else {
            return InPlace::Other;
        };
        let (Some(bytes), false) = (cand.get(..len), self.memo.busy_at(at)) else {
            return InPlace::Other;
        };
        let frame = Frame::new_unchecked(bytes);
        let Some(meta) = D::meta(frame.msg_id()) else {
            return InPlace::Other;
        };
        self.drop_input(input, start);
        if self.memo.frame_crc_ok(cand, at, &frame, meta.crc_extra) {
            InPlace::Good(len, meta)
        } else {
            self.stats.bad_crc += 1;
            self.drop_input(input, 1);
            InPlace::BadCrc
        }
    }

    /// Without a key, after a frame of an unknown id: drops the first
    /// candidates of `input` that [`reject_run`] would reject first and
    /// alone (MAVLink 1 frames the memo knows to be whole, of a known id,
    /// with a bad checksum; unknown incompatibility flags), counted as it
    /// counts them, and returns the length of the frame of an unknown id
    /// after them when [`check_raw`] and the signing policy would take it:
    /// confirmed by the start byte after it, and the memo finds no good
    /// known frame, and none undecided, inside it. `None` at the first
    /// candidate of another kind, left for the general loop. (In garbage
    /// returning a frame of an unknown id every few bytes, the general
    /// loop's set-up per call was nearly half the cost.)
    #[inline(always)]
    fn raw_frame_in_place(&mut self, input: &mut &[u8]) -> Option<usize> {
        let (mut at, mut bad_crc, mut bad_flags, mut refused_raw) = (0usize, 0u64, 0u64, 0u64);
        let found = loop {
            // (In garbage dense in start bytes the next byte is one, most
            // often: no search set up for it. The search's set-up cost a
            // third of the work per byte of `found_j`, a frame of an
            // unknown id every 18 bytes.)
            if !matches!(input.get(at), Some(&(STX_V1 | STX_V2))) {
                let Some(start) = input[at..].iter().position(|&b| b == STX_V2 || b == STX_V1)
                else {
                    break None;
                };
                at += start;
            }
            let cand = &input[at..];
            let pos = self.pos + at as u64;
            if cand[0] == STX_V1 && self.memo.v1_known_bad(pos) {
                bad_crc += 1;
            } else if cand[0] == STX_V2 && refused(cand) {
                bad_flags += 1;
            } else {
                match self.raw_alone_in_place(cand, pos, MaybeGood::UNKNOWN) {
                    RawAlone::Take(len) => break Some(len),
                    RawAlone::Refused => refused_raw += 1,
                    RawAlone::Other => break None,
                }
            }
            at += 1;
            if bad_crc + bad_flags + refused_raw == RAW_RUN_MAX {
                // Denser garbage: the general loop goes by masks.
                break None;
            }
        };
        self.stats.bad_crc += bad_crc;
        self.stats.bad_incompat_flags += bad_flags;
        self.memo.steps += at as u64 + bad_crc + bad_flags + refused_raw;
        self.drop_input(input, at);
        found
    }

    /// [`Parser::raw_frame_in_place`] by the masks of the 64 positions from
    /// the first byte of `input`, when the memo has them (`None`, nothing
    /// dropped, when it has not): drops at once the candidates
    /// [`reject_run`] rejects by their masks, then goes through the others
    /// in turn while each is a frame of an unknown id that `check_raw`
    /// refuses. Returns the length of the first it would take
    /// (`Some(Some(len))`), or `Some(None)` at the first candidate of
    /// another kind (or past the 64 positions), left for the general loop.
    /// In garbage returning such a frame every few bytes, the general
    /// loop's set-up per frame was a third of the work (`found_k`,
    /// `found_c`), and the candidates one by one half of `found_j`'s.
    #[inline(always)]
    fn raw_frame_by_masks(&mut self, input: &mut &[u8]) -> Option<Option<usize>> {
        if input.len() < 64 + HEADER_LEN_V2 {
            return None;
        }
        let Block {
            starts,
            bad_v1,
            refused,
        } = self.memo.block(input, self.pos)?;
        let maybe_good = starts & !bad_v1 & !refused;
        let mut others = maybe_good;
        let mut refused_raw = 0;
        let (j, found) = loop {
            if others == 0 {
                break (64, None);
            }
            let j = others.trailing_zeros() as usize;
            others &= others - 1;
            let maybe = MaybeGood {
                starts: maybe_good >> j,
                positions: 64 - j,
            };
            match self.raw_alone_in_place(&input[j..], self.pos + j as u64, maybe) {
                RawAlone::Take(len) => break (j, Some(len)),
                RawAlone::Refused => refused_raw += 1,
                RawAlone::Other => break (j, None),
            }
        };
        // The candidates before the one it stopped at are rejected.
        let before = span_mask(0, j as u64);
        let (bad_crc, bad_flags) = (ones(bad_v1 & before), ones(refused & before));
        self.stats.bad_crc += bad_crc;
        self.stats.bad_incompat_flags += bad_flags;
        self.memo.steps += j as u64 + bad_crc + bad_flags + refused_raw;
        self.drop_input(input, j);
        Some(found)
    }

    /// What [`Parser::raw_frame_in_place`] and
    /// [`Parser::raw_frame_by_masks`] make of their candidate at stream
    /// position `at`: a whole frame of an unknown id is taken or refused as
    /// [`check_raw`] would (without a key), anything else is left to the
    /// general loop. `maybe`: what the masks tell of the positions inside
    /// it.
    #[inline(always)]
    fn raw_alone_in_place(&mut self, cand: &[u8], at: u64, maybe: MaybeGood) -> RawAlone {
        let Some(w) = Whole::at(cand) else {
            return RawAlone::Other;
        };
        if self.memo.crc_extra::<D>(w.id).is_some() {
            return RawAlone::Other;
        }
        let Ok(len) = frame_len(cand) else {
            return RawAlone::Other;
        };
        match cand.get(len) {
            Some(&(STX_V1 | STX_V2)) => {}
            Some(_) => return RawAlone::Refused,
            None => return RawAlone::Other,
        }
        if maybe.none_inside(len) {
            return RawAlone::Take(len);
        }
        match self.memo.inside::<D>(cand, at, len, self.at_eof) {
            Inside::No => RawAlone::Take(len),
            Inside::Yes => RawAlone::Refused,
            Inside::Undecided(_) => RawAlone::Other,
        }
    }

    /// The frame `bytes` (delimited by `frame_len`), counted.
    #[inline(always)]
    fn received<'r>(
        bytes: &'r [u8],
        meta: Option<&'static MessageMeta>,
        authenticated: bool,
        (stats, links): Counters<'_>,
    ) -> Received<'r, D> {
        let frame = Frame::new_unchecked(bytes);
        Self::record(stats, links, frame.header(), meta.is_some());
        Received {
            frame,
            meta,
            authenticated,
            _dialect: PhantomData,
        }
    }

    /// One step with bytes held (out of line: the hot path, frames whole in
    /// the input, does not pay for it): back to the input in place once the
    /// bytes held from earlier calls are dropped, else a check of the
    /// candidate held.
    #[inline(never)]
    fn step_held(&mut self, input: &mut &[u8]) -> Held {
        if self.len == self.shadow {
            // All that is held is a copy of the head of the input (the
            // bytes before it are dropped): back to checking candidates in
            // place, where a rejection does not go through the buffer. What
            // the memo knows of these positions came from the copies: a
            // caller that passes other bytes than those it was given must
            // not have a frame taken on their checksum.
            (self.head, self.len, self.shadow) = (0, 0, 0);
            self.memo.forget_good_candidate();
            return Held::Next;
        }
        self.top_up(input);
        if core::mem::take(&mut self.resume_in_garbage) {
            return self.reject_run_held(input);
        }
        match self.check_at_buf() {
            // Cannot happen (a need is always for more than is held);
            // rejecting keeps the loop making progress regardless.
            Verdict::Need(needed) if needed <= self.len => self.drop_front(1, input),
            Verdict::Need(needed) => {
                if self.take_input(input, needed) {
                    // The input is all copied: consumed.
                    *input = &[];
                    self.shadow = 0;
                    self.at_eof = false;
                    return Held::Wait;
                }
            }
            Verdict::Accept {
                len,
                meta,
                authenticated,
            } => return Held::Found(Found::InBuf(len, meta, authenticated)),
            Verdict::Skip(len) => {
                self.drop_front(len, input);
                return self.reject_run_held(input);
            }
            Verdict::Reject => {
                self.drop_front(1, input);
                return self.reject_run_held(input);
            }
        }
        Held::Next
    }

    /// Tops the bytes held up from `input`: whatever the candidate needs,
    /// with bytes enough after it that what lies inside it is decided now
    /// (topped up once this many were used: a copy per step would cost
    /// more than the bytes).
    #[inline(always)]
    fn top_up(&mut self, input: &mut &[u8]) {
        if self.len + TOP_UP_SLACK < MAX_NEEDED && input.len() > self.shadow {
            self.take_input(input, self.len);
        }
    }

    /// After a rejection with bytes held: [`reject_run`] over them, as on
    /// the input (garbage dense in start bytes can keep a parser in its
    /// buffer for as long as it returns a frame every few bytes).
    fn reject_run_held(&mut self, input: &mut &[u8]) -> Held {
        // Until only copies of the input are held: then `step_held` goes
        // back to the input in place (topped up again and again, the run
        // would keep a parser refusing frame after frame in its buffer to
        // the end of the input, copying every byte).
        while self.len > self.shadow {
            // As before a check: what the run decides of a frame of an
            // unknown id depends on the bytes after it.
            self.top_up(input);
            let (held, cx) = self.held_and_ctx();
            let run = reject_run::<D, STREAMS>(held, cx);
            if run.dropped > 0 {
                self.consume_held(run.dropped, input);
            }
            let len = match run.end {
                RunEnd::Check => break,
                RunEnd::Accepted { len, authenticated } => {
                    return Held::Found(Found::InBuf(len, None, authenticated))
                }
                RunEnd::Policy(len) => len,
            };
            // What `check` would decide, from its signing policy on.
            let (held, cx) = self.held_and_ctx();
            let frame = Frame::new_unchecked(&held[..len]);
            match signing(&frame, None, cx) {
                Verdict::Accept {
                    len,
                    meta,
                    authenticated,
                } => return Held::Found(Found::InBuf(len, meta, authenticated)),
                verdict => self.drop_front(dropped_by(verdict), input),
            }
        }
        Held::Next
    }

    /// A frame of `len` bytes at the start of the bytes held is returned:
    /// the copies of the input it holds are consumed, and when only copies
    /// follow it they are dropped from the buffer, so that the next call
    /// finds it empty and parses in place (a stream of frames read in
    /// chunks would otherwise go through the buffer from its first chunk
    /// boundary on).
    fn settle_returned(&mut self, len: usize, input: &mut &[u8]) {
        self.consume_copies(len, input);
        if self.len - len == self.shadow {
            (self.len, self.shadow) = (len, 0);
        }
    }

    /// The input holds no start byte: all dropped.
    #[cold]
    fn input_used_up(&mut self, input: &mut &[u8]) {
        self.drop_input(input, input.len());
        if self.at_eof {
            // A flush has consumed everything: what follows is another
            // stream.
            self.memo.forget_from(self.pos);
        }
    }

    /// The candidate at the start of `input` needs more than the input has:
    /// all of it is held (shorter than what it needs, < MAX_NEEDED: fits).
    #[inline(never)]
    fn hold_input(&mut self, input: &mut &[u8]) {
        let n = input.len().min(BUF_LEN);
        self.buf[..n].copy_from_slice(&input[..n]);
        (self.head, self.len) = (0, n);
        self.memo.steps += n as u64;
        *input = &[];
    }

    fn release_returned(&mut self) {
        let n = core::mem::take(&mut self.returned_from_buf);
        if n > 0 {
            // (Consumed from the input when returned: no copy left in it.)
            self.consume_held(n, &mut &[][..]);
        }
    }

    /// Drops the first `n` bytes of `input` (counted as dropped).
    fn drop_input(&mut self, input: &mut &[u8], n: usize) {
        self.stats.bytes_dropped += n as u64;
        self.pos += n as u64;
        *input = &input[n..];
    }

    /// Copies bytes of `input` (after those copied already) to the buffer
    /// until `needed` are held, and more, up to the longest any candidate
    /// can need, when there is room without moving the bytes held: the
    /// candidates after this one are then decided without a check per byte
    /// copied. The input is not consumed: the copies are its head
    /// ([`Parser::shadow`]). True when `input` ran out before `needed`.
    #[inline(never)]
    fn take_input(&mut self, input: &[u8], needed: usize) -> bool {
        let input = &input[self.shadow..];
        // `needed` is at most MAX_NEEDED (< BUF_LEN); min() keeps this total.
        let needed = needed.min(MAX_NEEDED);
        let must = (needed - self.len).min(input.len());
        if self.head + self.len + must > BUF_LEN
            || (self.head + MAX_NEEDED > BUF_LEN && self.len < MAX_NEEDED)
        {
            // Room for what is needed, and for a whole window ahead of the
            // candidate. Either way more than BUF_LEN - MAX_NEEDED bytes
            // were dropped since the bytes held last moved (they start at
            // 0 then): at most MAX_NEEDED move, less often than that many
            // are dropped.
            self.buf.copy_within(self.head..self.head + self.len, 0);
            self.memo.steps += self.len as u64;
            self.head = 0;
        }
        let room = BUF_LEN - self.head - self.len;
        let take = (MAX_NEEDED.saturating_sub(self.len))
            .max(must)
            .min(room)
            .min(input.len());
        let end = self.head + self.len;
        self.buf[end..end + take].copy_from_slice(&input[..take]);
        self.len += take;
        self.shadow += take;
        self.memo.steps += take as u64;
        self.len < needed
    }

    /// Forgets the first `n` bytes held; those that are copies of the
    /// input's head are consumed from it.
    fn consume_held(&mut self, n: usize, input: &mut &[u8]) {
        self.consume_copies(n, input);
        self.head += n;
        self.len -= n;
        self.pos += n as u64;
        if self.len == 0 {
            self.head = 0;
        }
    }

    /// The first `n` bytes held are taken: those of them that are copies of
    /// the input's head (see [`Parser::shadow`]) are consumed from it.
    fn consume_copies(&mut self, n: usize, input: &mut &[u8]) {
        let copied = n.saturating_sub(self.len - self.shadow);
        *input = &input[copied..];
        self.shadow -= copied;
    }

    /// Ends the stream: call until `None`. Buffered bytes are parsed as if
    /// nothing follows them: an incomplete candidate is rejected and the
    /// bytes after its start byte are searched again (so a false start byte
    /// near the end loses no frame), and a raw frame of an unknown id that
    /// was waiting for the byte after it is returned. The parser stays
    /// usable: bytes pushed afterwards are parsed as a new stream.
    pub fn flush(&mut self) -> Option<Received<'_, D>> {
        self.at_eof = true;
        self.next(&mut &[][..])
    }

    /// [`next`](Self::next) for `input` that ends a datagram (on links
    /// where a frame never spans datagrams: MAVLink over UDP): the
    /// datagram's end is the end of the stream for every candidate, so a
    /// candidate cut by it is rejected at once (as
    /// [`end_of_datagram`](Self::end_of_datagram) would reject it), and
    /// nothing waits for bytes that cannot come. The same frames, in the
    /// same order, as `next` and then `end_of_datagram`; in a datagram of
    /// garbage whose candidates claim frames longer than what is left of
    /// it, without holding and searching again each one's bytes. Call
    /// `end_of_datagram` after the last call all the same.
    pub fn next_in_datagram<'r, 'i: 'r>(
        &'r mut self,
        input: &mut &'i [u8],
    ) -> Option<Received<'r, D>> {
        self.datagram_ends = true;
        self.next(input)
    }

    /// Ends a datagram: call until `None` once a datagram's bytes are all
    /// pushed, on links where a frame never spans datagrams (MAVLink over
    /// UDP). The same as [`flush`](Self::flush): a candidate cut by the
    /// datagram's end can never be completed, so it is rejected now and the
    /// good frames after its start byte are returned now, instead of waiting
    /// for the next datagram's bytes to make up the length it claims.
    pub fn end_of_datagram(&mut self) -> Option<Received<'_, D>> {
        self.flush()
    }

    /// Drops `n` bytes of the buffered candidate, then everything up to the
    /// next start byte in what remains (all counted as dropped).
    fn drop_front(&mut self, n: usize, input: &mut &[u8]) {
        let rest = &self.buf[self.head + n..self.head + self.len];
        let next = rest
            .iter()
            .position(|&b| b == STX_V2 || b == STX_V1)
            .unwrap_or(rest.len());
        self.stats.bytes_dropped += (n + next) as u64;
        self.memo.steps += next as u64;
        self.consume_held(n + next, input);
    }

    #[inline(always)]
    fn check_at_input(&mut self, bytes: &[u8]) -> Verdict {
        check::<D, STREAMS>(bytes, self.ctx())
    }

    /// What a check of the candidate at the stream position needs.
    #[inline(always)]
    fn ctx(&mut self) -> Ctx<'_, STREAMS> {
        Ctx {
            at: self.pos,
            memo: &mut self.memo,
            verifier: &mut self.verifier,
            accept_unsigned: self.accept_unsigned,
            at_eof: self.at_eof,
            stats: &mut self.stats,
        }
    }

    fn check_at_buf(&mut self) -> Verdict {
        self.memo.steps += 1;
        let (held, cx) = self.held_and_ctx();
        check::<D, STREAMS>(held, cx)
    }

    /// The bytes held, and what a check of the candidate at their start
    /// needs (disjoint fields: both at once).
    #[inline(always)]
    fn held_and_ctx(&mut self) -> (&[u8], Ctx<'_, STREAMS>) {
        (
            &self.buf[self.head..self.head + self.len],
            Ctx {
                at: self.pos,
                memo: &mut self.memo,
                verifier: &mut self.verifier,
                accept_unsigned: self.accept_unsigned,
                at_eof: self.at_eof,
                stats: &mut self.stats,
            },
        )
    }

    #[inline(always)]
    fn record(stats: &mut Stats, links: &mut Senders, h: Header, known: bool) {
        if known {
            stats.frames += 1;
        } else {
            stats.unknown_frames += 1;
        }
        let link = links.get(h.sysid, h.compid, h.seq);
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

/// Rejects, in one loop, the candidates at the start of `bytes` (a start
/// byte, at `cx.at`) while each is a whole frame of a known id with a bad
/// checksum, has unknown incompatibility flags, or is a frame of an unknown
/// id that [`check_raw`] refuses: what `check` would decide, with the same
/// counters, minus its per-candidate plumbing. This is the bulk of garbage
/// dense in start bytes, and the loop runs only after a rejection (good
/// frames go straight to `check`). Ends at the first candidate it leaves to
/// `check` (or the end of the bytes), or at a frame of an unknown id that
/// `check_raw` has taken or left to the signing policy (see [`RunEnd`]).
#[inline(never)]
fn reject_run<D: MessageSet, const N: usize>(bytes: &[u8], cx: Ctx<'_, N>) -> Run {
    let Ctx {
        at,
        memo,
        verifier,
        accept_unsigned,
        at_eof,
        stats,
    } = cx;
    // Apart from the memo, which the loop uses all the time (kept in a
    // register, not read through the context).
    let mut rest = Rest {
        verifier,
        accept_unsigned,
        at_eof,
        stats,
    };
    let mut count = Rejected::default();
    if memo.dense_starts {
        // The last run proved the start bytes dense: masks at once, while
        // they stay dense.
        let (i, end) = reject_masked::<D, N>(bytes, at, memo, &mut rest, &mut count);
        // A run that rejects nothing ends the garbage: good frames after it
        // go straight to `check` again.
        memo.dense_starts = count.rejected() > 0 && count.rejected() * DENSE as u64 >= i as u64;
        return count.record(i, end, memo, rest.stats);
    }
    // One by one, the way through sparse start bytes (random bytes: a
    // search for the next start byte, rarely more than one candidate); by
    // masks of 64 positions once the start bytes prove dense.
    let mut i = 0;
    for n in 1.. {
        if n % SHORT_RUN == 0 && i < DENSE * SHORT_RUN {
            memo.dense_starts = true;
            let (j, end) =
                reject_masked::<D, N>(&bytes[i..], at + i as u64, memo, &mut rest, &mut count);
            return count.record(i + j, end, memo, rest.stats);
        }
        let bytes = &bytes[i..];
        // The bytes this candidate drops.
        let mut drop = 1;
        match bytes.first() {
            Some(&STX_V2) if refused(bytes) => count.bad_flags += 1,
            Some(&STX_V1) if memo.v1_known_bad(at + i as u64) => count.bad_crc += 1,
            Some(_) => {
                match alone::<D, N>(bytes, at + i as u64, memo, &mut rest, MaybeGood::UNKNOWN) {
                    Alone::BadCrc => count.bad_crc += 1,
                    Alone::Refused => count.by_check_raw += 1,
                    Alone::Cut => count.cut += 1,
                    Alone::Ends(RunEnd::Policy(len)) => {
                        match policy::<N>(bytes, len, at + i as u64, memo, &mut rest, &mut count) {
                            Ok(skipped) => drop = skipped,
                            Err(end) => return count.record(i, end, memo, rest.stats),
                        }
                    }
                    Alone::Ends(end) => return count.record(i, end, memo, rest.stats),
                }
            }
            None => break,
        }
        i += drop
            + bytes[drop..]
                .iter()
                .position(|&b| b == STX_V1 || b == STX_V2)
                .unwrap_or(bytes.len() - drop);
    }
    count.record(i, RunEnd::Check, memo, rest.stats)
}

/// The signing policy ([`signing`]) on the frame of an unknown id, `len`
/// bytes at the start of `bytes` (stream position `at`), that `check_raw`
/// leaves to it: `Ok(n)` when it skips the frame (unsigned where
/// signatures are required), `n` bytes dropped and counted, and the run
/// goes on (not handed back for `next` to skip: a round trip per frame in
/// garbage of unsigned frames at a keyed parser); else how the run ends.
#[inline(always)]
fn policy<const N: usize>(
    bytes: &[u8],
    len: usize,
    at: u64,
    memo: &mut Memo,
    rest: &mut Rest<'_, N>,
    count: &mut Rejected,
) -> Result<usize, RunEnd> {
    let frame = Frame::new_unchecked(&bytes[..len]);
    match signing(&frame, None, rest.ctx(at, memo)) {
        Verdict::Skip(n) => {
            count.skipped += 1;
            Ok(n)
        }
        Verdict::Accept { authenticated, .. } => Err(RunEnd::Accepted { len, authenticated }),
        _ => Err(RunEnd::Policy(len)),
    }
}

/// What a check needs besides the bytes, the position and the memo: what
/// [`reject_run`] passes to [`check_raw`] for the rare candidate that gets
/// that far.
struct Rest<'a, const N: usize> {
    verifier: &'a mut Option<Verifier<N>>,
    accept_unsigned: bool,
    at_eof: bool,
    stats: &'a mut Stats,
}

impl<const N: usize> Rest<'_, N> {
    /// The context of a check of the candidate at stream position `at`.
    #[inline(always)]
    fn ctx<'c>(&'c mut self, at: u64, memo: &'c mut Memo) -> Ctx<'c, N> {
        Ctx {
            at,
            memo,
            verifier: self.verifier,
            accept_unsigned: self.accept_unsigned,
            at_eof: self.at_eof,
            stats: self.stats,
        }
    }
}

/// Candidates [`Parser::raw_frame_in_place`] rejects before it leaves the
/// rest to [`reject_run`] (which goes by masks through dense garbage). At
/// 8, a frame of an unknown id after 9 to 16 candidates paid for both
/// (`found_i`, `found_k`: 2.5-3 instructions per byte more than at 16);
/// above 16 nothing measured changed.
const RAW_RUN_MAX: u64 = 16;

/// What [`Parser::raw_frame_in_place`] makes of a candidate.
enum RawAlone {
    /// A frame of an unknown id, this long: taken.
    Take(usize),
    /// A frame of an unknown id that [`check_raw`] refuses.
    Refused,
    /// Anything else: for the general loop.
    Other,
}

/// [`reject_run`] looks at its start bytes' density every this many
/// candidates...
const SHORT_RUN: usize = 8;
/// ...and goes on by masks when they are fewer than this many bytes apart.
const DENSE: usize = 8;

/// What [`reject_run`] rejected.
#[derive(Default)]
struct Rejected {
    bad_crc: u64,
    bad_flags: u64,
    /// Those [`check_raw`] refused (and counted as it does).
    by_check_raw: u64,
    /// Whole frames of unknown ids the signing policy skipped (and counted
    /// as it does).
    skipped: u64,
    /// Frames not whole at the end of the stream.
    cut: u64,
}

/// Why [`check_raw`] refuses a whole candidate of an unknown id before
/// looking inside it ([`raw_refused_alone`]).
enum Why {
    /// A signed frame whose signature the budget cannot pay for (see the
    /// module docs): it cannot be authenticated.
    Unpaid,
    /// A frame that nothing can confirm: no signature to check, and the
    /// byte after it is not a start byte.
    Unconfirmed,
}

/// What [`reject_run`] makes of a candidate alone.
enum Alone {
    /// A whole frame of a known id with a bad checksum.
    BadCrc,
    /// A whole frame of an unknown id that [`check_raw`] refused (and
    /// counted as it does).
    Refused,
    /// A frame not whole at the end of the stream: rejected, uncounted (as
    /// `check` rejects it).
    Cut,
    /// The run ends at it.
    Ends(RunEnd),
}

/// How a run of [`reject_run`] ended: after `dropped` bytes, at `end`.
struct Run {
    dropped: usize,
    end: RunEnd,
}

/// The candidate a run of [`reject_run`] ended at.
enum RunEnd {
    /// One for [`check`] (or none: the end of the bytes).
    Check,
    /// A frame of an unknown id, this long, that [`check_raw`] leaves to
    /// the signing policy ([`signing`]).
    Policy(usize),
    /// A frame of an unknown id, `len` bytes long, taken: by [`check_raw`]
    /// for its good signature (`authenticated`), or by the signing policy.
    Accepted { len: usize, authenticated: bool },
}

impl Rejected {
    /// Counts the candidates of a block of [`reject_masked`] rejected by
    /// their masks (MAVLink 2 flags `refused`, MAVLink 1 checksums
    /// `bad_v1`) from bit `from` to bit `to` (exclusive; `from` < 64).
    #[inline(always)]
    fn masked(&mut self, refused: u64, bad_v1: u64, cut: u64, from: usize, to: usize) {
        let span = span_mask(from as u64, to as u64);
        self.cut += u64::from((cut & span).count_ones());
        self.bad_flags += u64::from((refused & span).count_ones());
        self.bad_crc += u64::from((bad_v1 & span).count_ones());
    }

    /// The candidates rejected.
    fn rejected(&self) -> u64 {
        self.bad_crc + self.bad_flags + self.by_check_raw + self.skipped + self.cut
    }

    /// Counts the rejections and the `dropped` bytes: the run's end.
    fn record(self, dropped: usize, end: RunEnd, memo: &mut Memo, stats: &mut Stats) -> Run {
        stats.bad_crc += self.bad_crc;
        stats.bad_incompat_flags += self.bad_flags;
        stats.bytes_dropped += dropped as u64;
        memo.steps += (dropped as u64) + self.rejected();
        Run { dropped, end }
    }
}

/// The bytes a verdict of [`signing`] other than an acceptance drops (it
/// only skips frames; a rejection would drop the start byte).
fn dropped_by(verdict: Verdict) -> usize {
    match verdict {
        Verdict::Skip(n) => n,
        _ => 1,
    }
}

/// The bits set in `x`. Without the CPU's population count instruction
/// (not in the x86-64 baseline) `count_ones` is a dozen instructions,
/// where the candidates rejected before a frame found every few bytes are
/// one or none (`found_f`).
#[inline(always)]
fn ones(x: u64) -> u64 {
    if x & x.wrapping_sub(1) == 0 {
        u64::from(x != 0)
    } else {
        u64::from(x.count_ones())
    }
}

/// A MAVLink 2 start byte whose whole header has unknown incompatibility
/// flags: what `frame_len` refuses (UnknownIncompatFlags).
#[inline(always)]
fn refused(rest: &[u8]) -> bool {
    rest.len() >= HEADER_LEN_V2 && rest[2] & !IFLAG_KNOWN != 0
}

/// [`reject_run`] past its first candidates (`bytes[0]` a start byte, at
/// `cx.at`): the start bytes 64 at a time, by mask. In garbage the kind of
/// each is unpredictable: a branch on it per byte would mostly be
/// mispredicted. Returns where the run ended, and how.
fn reject_masked<D: MessageSet, const N: usize>(
    bytes: &[u8],
    at: u64,
    memo: &mut Memo,
    rest: &mut Rest<'_, N>,
    count: &mut Rejected,
) -> (usize, RunEnd) {
    let mut base = 0;
    'blocks: while base < bytes.len() {
        let Starts { kinds, refused } = memo.starts(bytes, at, base, bytes.len());
        let cut = cut_by_the_end(bytes, at, base, kinds, memo, rest);
        // The MAVLink 1 frames with a bad checksum, all at once (each
        // position checked once, however many runs pass over it).
        let bad_v1 = memo.v1_bad_crc::<D>(
            &bytes[base..],
            at + base as u64,
            kinds[0] & !cut,
            rest.at_eof,
        );
        // Those are rejected by their count; the others one by one, those
        // the scan found whole with an unknown id straight to `check_raw`'s
        // policy once their id is read again.
        let mut others = (kinds[0] | kinds[1]) & !bad_v1 & !cut;
        let maybe_good = others;
        let n = (bytes.len() - base).min(64);
        let raw = memo.raw_starts(at + base as u64) & others;
        // The rejections by count are those from this bit on (those before
        // it were inside a frame the signing policy skipped).
        let mut from = 0;
        while others != 0 {
            let j = others.trailing_zeros() as usize;
            others &= others - 1;
            let i = base + j;
            if raw >> j & 1 != 0 && unpaid_signed(&bytes[i..], at + i as u64, memo, rest) {
                count.by_check_raw += 1;
                continue;
            }
            // The scan's "unknown id" was read from bytes a caller may not
            // have passed again (one that drops its input after a frame):
            // read again from these before `check_raw`'s policy may take
            // the frame, as `alone` does.
            let unknown = raw >> j & 1 != 0 && memo.crc_extra::<D>(msg_id(&bytes[i..])).is_none();
            let maybe = MaybeGood {
                starts: maybe_good >> j,
                positions: n - j,
            };
            let alone = if unknown {
                raw_alone::<D, N>(&bytes[i..], at + i as u64, memo, rest, maybe)
            } else {
                alone::<D, N>(&bytes[i..], at + i as u64, memo, rest, maybe)
            };
            let end = match alone {
                Alone::BadCrc => {
                    count.bad_crc += 1;
                    continue;
                }
                Alone::Refused => {
                    count.by_check_raw += 1;
                    continue;
                }
                Alone::Cut => {
                    count.cut += 1;
                    continue;
                }
                Alone::Ends(RunEnd::Policy(len)) => {
                    match policy::<N>(&bytes[i..], len, at + i as u64, memo, rest, count) {
                        Ok(skipped) => {
                            count.masked(refused, bad_v1, cut, from, j);
                            // On after the frame, in this block or from it.
                            let next = j + skipped;
                            if next < n {
                                from = next;
                                others &= u64::MAX << next;
                                continue;
                            }
                            base += next;
                            continue 'blocks;
                        }
                        Err(end) => end,
                    }
                }
                Alone::Ends(end) => end,
            };
            // The refused and bad before it are dropped with it.
            count.masked(refused, bad_v1, cut, from, j);
            return (i, end);
        }
        count.masked(refused, bad_v1, cut, from, 64);
        base += 64;
    }
    (bytes.len(), RunEnd::Check)
}

/// At the end of the stream, of the start bytes `kinds` of the block at
/// `bytes[base]` (`bytes[0]` at stream position `at`), those whose frame
/// the end cuts, all at once (in a datagram of garbage, most of them): none
/// can be good. Not the signed MAVLink 2 ones a key may have to pay for
/// ([`cut`]). None before the end.
#[inline(always)]
fn cut_by_the_end<const N: usize>(
    bytes: &[u8],
    at: u64,
    base: usize,
    kinds: [u64; 2],
    memo: &mut Memo,
    rest: &Rest<'_, N>,
) -> u64 {
    if !rest.at_eof {
        return 0;
    }
    let end = memo.end_cuts.at(bytes, at, base);
    let keyed = u64::from(rest.verifier.is_some()).wrapping_neg();
    end.cut & (kinds[0] | (kinds[1] & !(end.signed & keyed)))
}

/// What [`reject_run`] makes alone of the candidate at the start of `rest`
/// (stream position `at`): what [`check`] would decide of it, as far as it
/// can without the rest of the check.
#[inline(always)]
fn alone<D: MessageSet, const N: usize>(
    bytes: &[u8],
    at: u64,
    memo: &mut Memo,
    rest: &mut Rest<'_, N>,
    maybe: MaybeGood,
) -> Alone {
    let Some(w) = Whole::at(bytes) else {
        return cut::<D, N>(bytes, at, memo, rest);
    };
    match memo.crc_extra::<D>(w.id) {
        Some(extra) if memo.candidate_crc_ok(bytes, at, &w, extra) => Alone::Ends(RunEnd::Check),
        Some(_) => Alone::BadCrc,
        None => raw_alone::<D, N>(bytes, at, memo, rest, maybe),
    }
}

/// What [`reject_run`] makes alone of a candidate whose frame is not whole
/// in `bytes` (at stream position `at`): before the end of the stream, one
/// for `check` (which waits for its bytes). At the end (of a datagram, or a
/// flush) `check` rejects it, as its bytes can never come: rejected here,
/// in the run, as `check` rejects it (in a datagram of garbage whose
/// candidates claim long frames, each one left to `check` was a round trip
/// through the general loop per byte of the datagram's tail). A signed
/// frame of an unknown id that a key would check pays for its check first
/// when a good frame starts inside it, as `check` makes it pay
/// ([`pay_for_signed_raw`]); a MAVLink 2 header with unknown flags is left
/// to `check`, which counts it.
#[inline(always)]
fn cut<D: MessageSet, const N: usize>(
    bytes: &[u8],
    at: u64,
    memo: &mut Memo,
    rest: &mut Rest<'_, N>,
) -> Alone {
    if !rest.at_eof {
        return Alone::Ends(RunEnd::Check);
    }
    match frame_len(bytes) {
        Err(FrameError::UnknownIncompatFlags(_)) => Alone::Ends(RunEnd::Check),
        Ok(len)
            if rest.verifier.is_some() && signed_v2(bytes) && D::meta(msg_id(bytes)).is_none() =>
        {
            if memo.inside::<D>(bytes, at, bytes.len(), rest.at_eof) == Inside::Yes {
                pay_for_signed_raw(bytes, len, &mut rest.ctx(at, memo));
            }
            Alone::Cut
        }
        _ => Alone::Cut,
    }
}

/// What the masks of [`reject_masked`] tell of the positions from a
/// candidate on: which of the first `positions` may start a good frame of
/// a known id (`starts`, bit 0 the candidate); the rest are not known.
/// A frame of an unknown id with none inside needs no [`Memo::inside`].
#[derive(Clone, Copy)]
struct MaybeGood {
    starts: u64,
    positions: usize,
}

impl MaybeGood {
    /// Nothing known.
    const UNKNOWN: MaybeGood = MaybeGood {
        starts: !0,
        positions: 0,
    };

    /// Whether no position after the candidate and before its `len`th byte
    /// can start a good frame, as far as the masks tell.
    #[inline(always)]
    fn none_inside(self, len: usize) -> bool {
        len <= self.positions && len >= 1 && (self.starts >> 1) & ((1u64 << (len - 1)) - 1) == 0
    }
}

/// [`alone`] of a candidate of an unknown id (known to the caller): when
/// its frame is whole in `bytes`, what [`check_raw`] decides (its policy,
/// in line), else one for `check`. (What the scan saw is in these bytes
/// too, unless a caller passed other bytes since: then `check_raw` reads
/// them again.)
#[inline(always)]
fn raw_alone<D: MessageSet, const N: usize>(
    bytes: &[u8],
    at: u64,
    memo: &mut Memo,
    rest: &mut Rest<'_, N>,
    maybe: MaybeGood,
) -> Alone {
    let Some(len) = frame_len(bytes).ok().filter(|&n| bytes.len() >= n) else {
        return cut::<D, N>(bytes, at, memo, rest);
    };
    let frame = Frame::new_unchecked(&bytes[..len]);
    match raw_verdict::<D, N>(bytes, &frame, rest.ctx(at, memo), maybe) {
        Some(Verdict::Reject) => Alone::Refused,
        // Only an authenticated frame is taken there.
        Some(Verdict::Accept {
            len, authenticated, ..
        }) => Alone::Ends(RunEnd::Accepted { len, authenticated }),
        Some(_) => Alone::Ends(RunEnd::Check),
        None => Alone::Ends(RunEnd::Policy(len)),
    }
}

/// What `check_raw` decides of a whole candidate of an unknown id (`len`
/// bytes at the start of `bytes`, at stream position `at`) before looking
/// inside it, if anything: refused when nothing can confirm it (no
/// signature to check, and the byte after it is not a start byte), or when
/// its signature (`checked`: signed, and a key to check it) is one the
/// budget cannot pay for. Else a signed one's check is paid for here, the
/// search inside it as well as the hash (a good signature gives it back):
/// forged candidates with a good frame inside, back to back, are then
/// refused before any search. `None` also when the byte after it is not
/// there.
#[inline(always)]
fn raw_refused_alone(
    bytes: &[u8],
    len: usize,
    checked: bool,
    at: u64,
    memo: &mut Memo,
) -> Option<Why> {
    if !checked {
        let next = bytes.get(len)?;
        return (*next != STX_V1 && *next != STX_V2).then_some(Why::Unconfirmed);
    }
    (!memo.pay_for_raw_check(at, raw_signature_cost(len))).then_some(Why::Unpaid)
}

/// Whether `bytes` start a signed MAVLink 2 frame that a key would check
/// and the budget cannot pay for, however long it is: what
/// [`raw_refused_alone`] refuses (counted as it counts it), decided
/// without reading the frame's length and id again, for a start byte the
/// scan found to start a whole frame of an unknown id. In garbage of
/// signed frames of unknown ids most are refused so (`found_g`).
#[inline(always)]
fn unpaid_signed<const N: usize>(
    bytes: &[u8],
    at: u64,
    memo: &Memo,
    rest: &mut Rest<'_, N>,
) -> bool {
    if !signed_v2(bytes) || rest.verifier.is_none() || !memo.cannot_pay_any(at) {
        return false;
    }
    rest.stats.signatures_unchecked += 1;
    true
}

/// Whether `bytes` start a MAVLink 2 header whose flags say signed (its
/// flags byte there; the rest may be cut).
#[inline(always)]
fn signed_v2(bytes: &[u8]) -> bool {
    matches!(bytes, [STX_V2, _, flags, ..] if flags & IFLAG_SIGNED != 0)
}

/// Bytes a signed frame of `len` bytes makes SHA-256 hash: the 32-byte key,
/// and the frame less the 6 signature bytes.
const fn raw_signature_cost(len: usize) -> u64 {
    len as u64 + 32 - 6
}

/// What a candidate check needs besides its bytes.
struct Ctx<'a, const N: usize> {
    /// Stream position of the candidate (`bytes[0]`).
    at: u64,
    memo: &'a mut Memo,
    verifier: &'a mut Option<Verifier<N>>,
    accept_unsigned: bool,
    at_eof: bool,
    stats: &'a mut Stats,
}

impl<const N: usize> Ctx<'_, N> {
    /// The same context, for a call out of line (a reference to the context
    /// itself would keep it in memory on the hot path).
    fn reborrow(&mut self) -> Ctx<'_, N> {
        Ctx {
            at: self.at,
            memo: self.memo,
            verifier: self.verifier,
            accept_unsigned: self.accept_unsigned,
            at_eof: self.at_eof,
            stats: self.stats,
        }
    }
}

/// The decision about the candidate at the start of `bytes` (the bytes
/// available from its start byte on).
#[inline(always)]
fn check<D: MessageSet, const N: usize>(bytes: &[u8], mut cx: Ctx<'_, N>) -> Verdict {
    // At the end of the stream an incomplete candidate is not a frame.
    let at_eof = cx.at_eof;
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
                && cx.memo.inside::<D>(bytes, cx.at, bytes.len(), cx.at_eof) == Inside::Yes
            {
                pay_for_signed_raw(bytes, len, &mut cx);
                return Verdict::Reject;
            }
            return need(len);
        }
        Err(FrameError::Incomplete { needed }) => return need(needed),
        Err(FrameError::UnknownIncompatFlags(_)) => {
            cx.stats.bad_incompat_flags += 1;
            return Verdict::Reject;
        }
        Err(_) => return Verdict::Reject,
    };
    let frame = Frame::new_unchecked(&bytes[..len]);
    let meta = D::meta(frame.msg_id());
    if let Some(m) = meta {
        if !cx.memo.frame_crc_ok(bytes, cx.at, &frame, m.crc_extra) {
            cx.stats.bad_crc += 1;
            return Verdict::Reject;
        }
    } else if let Some(v) = check_raw::<D, N>(bytes, &frame, cx.reborrow()) {
        return v;
    }
    signing(&frame, meta, cx)
}

/// A signed candidate of an unknown id, `len` bytes long but not whole in
/// `bytes`, rejected for a good frame inside: with a key, paid for (or
/// counted unchecked) as its check would be, had all its bytes been there
/// (how many were is a matter of read sizes, which must not change the
/// budget).
#[cold]
fn pay_for_signed_raw<const N: usize>(bytes: &[u8], len: usize, cx: &mut Ctx<'_, N>) {
    if signed_v2(bytes)
        && cx.verifier.is_some()
        && !cx.memo.pay_for_raw_check(cx.at, raw_signature_cost(len))
    {
        cx.stats.signatures_unchecked += 1;
    }
}

/// The decision of the signing policy about a whole candidate `frame` that
/// nothing else refuses (a good checksum, or an unknown id that
/// [`check_raw`] leaves to the policy).
#[inline(always)]
fn signing<const N: usize>(
    frame: &Frame<&[u8]>,
    meta: Option<&'static MessageMeta>,
    cx: Ctx<'_, N>,
) -> Verdict {
    let len = frame.as_bytes().len();
    let mut authenticated = false;
    if let Some(v) = cx.verifier {
        if frame.is_signed() {
            cx.memo.signatures += 1;
        }
        match v.verify(frame) {
            Ok(()) => authenticated = true,
            Err(SignatureError::Unsigned) if cx.accept_unsigned => {}
            Err(SignatureError::Unsigned) => {
                cx.stats.unsigned_rejected += 1;
                return Verdict::Skip(len);
            }
            // Under `Unsigned::Accept`, a frame the key signed but whose
            // timestamp is stale is returned unauthenticated, as an
            // unsigned one would be: it can act on nothing that requires
            // a signature, and its sender (a key holder whose clock is
            // behind, or a replay) can be answered so that it catches up.
            Err(e) if e.is_stale() && cx.accept_unsigned && v.signed_with_key(frame) => {
                cx.stats.stale_timestamp += 1;
            }
            Err(e) => {
                if e.is_stale() {
                    cx.stats.stale_timestamp += 1;
                } else {
                    cx.stats.bad_signature += 1;
                }
                // A good checksum vouches for the header and payload only: the
                // 13 bytes after it may be the head of the next frame (a frame
                // cut inside its signature block), so those are searched
                // again. (Raw frames do not get here: see `check_raw`.)
                return Verdict::Skip(len - crate::frame::SIGNATURE_LEN);
            }
        }
    }
    Verdict::Accept {
        len,
        meta,
        authenticated,
    }
}

/// The decision about a whole candidate `frame` of an unknown id (see the
/// module docs), or `None` when only the signing policy is left to apply
/// (an unsigned frame, or any frame without a key). Out of line: `check`'s
/// hot path, good frames of known ids, does not pay for it.
#[inline(never)]
fn check_raw<D: MessageSet, const N: usize>(
    bytes: &[u8],
    frame: &Frame<&[u8]>,
    cx: Ctx<'_, N>,
) -> Option<Verdict> {
    raw_verdict::<D, N>(bytes, frame, cx, MaybeGood::UNKNOWN)
}

/// [`check_raw`], in line: in [`reject_run`], where frames of unknown ids
/// are the candidates it cannot reject by their checksum.
#[inline(always)]
fn raw_verdict<D: MessageSet, const N: usize>(
    bytes: &[u8],
    frame: &Frame<&[u8]>,
    cx: Ctx<'_, N>,
    maybe: MaybeGood,
) -> Option<Verdict> {
    let len = frame.as_bytes().len();
    let checked = frame.is_signed() && cx.verifier.is_some();
    // Refused whatever is inside: not confirmed and nothing can confirm it
    // (most garbage ends here), or it cannot be authenticated (no search,
    // which would cost what the budget spares).
    match raw_refused_alone(bytes, len, checked, cx.at, cx.memo) {
        Some(Why::Unpaid) => {
            cx.stats.signatures_unchecked += 1;
            return Some(Verdict::Reject);
        }
        Some(_) => return Some(Verdict::Reject),
        None => {}
    }
    let inside = if maybe.none_inside(len) {
        Inside::No
    } else {
        cx.memo.inside::<D>(bytes, cx.at, len, cx.at_eof)
    };
    match inside {
        Inside::Yes => return Some(Verdict::Reject),
        Inside::Undecided(needed) if !cx.at_eof => return Some(Verdict::Need(needed)),
        Inside::Undecided(_) | Inside::No => {}
    }
    // Checked once per candidate: while it waits for its next byte the
    // verifier cannot change (that needs an accepted frame).
    let authenticated = checked
        && !cx.memo.raw_signature_failed(cx.at)
        && match cx.verifier.as_mut() {
            Some(v) => {
                cx.memo.signatures += 1;
                let ok = v.verify(frame).is_ok();
                if ok {
                    // A genuine frame is taken: its bytes pay for its check.
                    cx.memo.refund_raw_signature(cx.at, raw_signature_cost(len));
                } else {
                    cx.memo.set_raw_signature_failed(cx.at);
                }
                ok
            }
            None => false,
        };
    match bytes.get(len) {
        _ if authenticated => {
            return Some(Verdict::Accept {
                len,
                meta: None,
                authenticated: true,
            })
        }
        None if cx.at_eof => {}
        None => return Some(Verdict::Need(len + 1)),
        Some(&b) if b != STX_V1 && b != STX_V2 => return Some(Verdict::Reject),
        Some(_) => {}
    }
    if checked {
        // Its signature failed (above): with an unverifiable checksum the
        // "frame" may be garbage, so resume inside it.
        cx.stats.bad_signature += 1;
        return Some(Verdict::Reject);
    }
    None
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

#[cfg(test)]
mod tests {
    use super::MaybeGood;

    #[test]
    fn maybe_good_answers_only_for_the_positions_its_masks_cover() {
        // The candidate at 0, another start byte at 9, masks of 20
        // positions.
        let m = MaybeGood {
            starts: 1 | 1 << 9,
            positions: 20,
        };
        assert!(m.none_inside(9), "inside: 1..=8");
        assert!(!m.none_inside(10), "inside: 1..=9");
        assert!(m.none_inside(1), "nothing inside");
        assert!(!m.none_inside(0), "no frame");
        assert!(!m.none_inside(21), "past the masks");
        assert!(!MaybeGood::UNKNOWN.none_inside(8));
        let all = MaybeGood {
            starts: 1,
            positions: 64,
        };
        assert!(all.none_inside(64));
        assert!(!all.none_inside(65));
    }
}
