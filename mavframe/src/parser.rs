//! A streaming frame parser: push bytes in any chunking, take frames out.
//!
//! # The algorithm
//!
//! The parser looks at one *candidate* at a time: the first start byte
//! (0xFD for MAVLink 2, 0xFE for MAVLink 1) not yet consumed, at a stream
//! position (the bytes pushed before it), and decides it from the bytes at
//! hand:
//!
//! - a header with unknown incompatibility flags, or a frame of a known id
//!   whose checksum is bad, is *rejected*: the start byte is dropped and the
//!   search resumes at the next byte, so a corrupted or truncated frame
//!   never swallows the good frames inside the length it claimed (which
//!   pymavlink and the C parser lose);
//! - a frame of a known id with a good checksum goes to the signing policy
//!   (below) and is returned, or skipped;
//! - a frame of an id the dialect does not know cannot be checked (its
//!   CRC_EXTRA is unknown), yet routers must forward it. Garbage holding a
//!   start byte almost always looks like one, so it is returned raw only
//!   when confirmed: the byte after it is a start byte (or the end of the
//!   stream, or its signature verifies with the key), and no good frame of
//!   a known id starts inside it: a known good frame always wins;
//! - a candidate whose bytes are not all there waits for them (held in a
//!   buffer inside the parser when the input runs out); at the end of the
//!   stream ([`Parser::flush`]) or of a datagram it is rejected.
//!
//! Done naively, dense start bytes make this quadratic: each candidate
//! checksums up to 263 bytes, and a raw one looks for a good frame at each
//! of up to 279 positions inside it. Here the cost per byte is bounded,
//! whatever the bytes (the private `memo` module): whether a good frame of
//! a known id starts at a position depends on the bytes only, so each
//! position is classified once, in stream order, and the verdict kept as a
//! bit; a position whose frame is not whole yet waits in a list keyed by
//! the position at which it will be, and is classified again then. A
//! checksum over fresh bytes is computed directly; one over bytes an
//! earlier checksum covered comes from two CRC prefix states, each computed
//! once (the CRC is affine over GF(2)). A raw candidate then asks "a good
//! bit inside me?" of at most five words. The parser counts the steps (for
//! its tests): at most a constant times the bytes pushed plus the calls
//! made.
//!
//! Signing: with a key ([`Parser::with_signing`]) a signed frame must
//! verify; an unsigned one is returned or dropped as [`Unsigned`] says. A
//! frame with a good checksum and a bad signature is skipped up to its
//! checksum (its 13 signature bytes may be the head of the next frame); one
//! refused for being unsigned is skipped whole. A raw candidate has no
//! checksum to vouch for it, and garbage can hold one at every other byte:
//! a signed one is checked (the search inside, then a SHA-256) only when a
//! budget pays for it, which earns one hashed byte per two bytes consumed
//! (up to eight of the longest signed frames' worth saved); a good
//! signature gives the cost back. A
//! candidate the budget cannot pay for is rejected
//! ([`Stats::signatures_unchecked`]): a flood of forged signed frames of
//! unknown ids can cost genuine ones of unknown ids, never known ones, and
//! never admits a forgery.
//!
//! One loop serves [`Parser::next`], [`Parser::next_in_datagram`],
//! [`Parser::flush`] and [`Parser::end_of_datagram`]: the last three only
//! tell it that no byte follows the ones at hand. A frame whole in the
//! input is returned in place (no copy); one that spans chunks is assembled
//! in the buffer, and once the buffer holds nothing but copies of the
//! current input the loop goes back to it in place. After a frame, pass
//! the rest of the input (what [`Parser::next`] left in it) on the next
//! call. A caller that drops it and pushes other bytes can make the parser
//! miss frames, never accept a bad one: a frame is taken only on its own
//! bytes' checksum.

mod memo;

use crate::frame::{
    frame_len, Frame, FrameError, Header, IFLAG_SIGNED, MAX_FRAME_LEN, STX_V1, STX_V2,
};
use crate::message::{MessageMeta, MessageSet};
use crate::signing::{SignatureError, Verifier};
use core::marker::PhantomData;
use memo::{Crc, Inside, Memo};

/// Counters of what the parser saw.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
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
    /// Frames whose sequence number repeats their sender's last one (a
    /// frame received twice, e.g. over redundant links): counted here, not
    /// as a gap.
    pub duplicates: u64,
    /// Signed candidates of unknown ids rejected without checking their
    /// signature, the budget for those being spent (see the module docs):
    /// a sign of forged frames.
    pub signatures_unchecked: u64,
    /// The sender (system, component) of the last frame of a known id
    /// refused for its signature, as its good checksum vouches: whom a
    /// wrong key belongs to.
    pub bad_signature_sender: Option<(u8, u8)>,
}

/// Bytes consumed per hashed byte that the budget for checking signed
/// candidates of unknown ids earns (see the module docs): an attacker
/// without the key makes the parser hash at most one byte per this many it
/// sends, beyond `RAW_SIGNATURE_BURST` (a good signature gives its cost
/// back).
#[doc(hidden)]
pub const BYTES_PER_RAW_SIGNATURE_BYTE: u64 = 2;

/// Hashed bytes of the budget saved up at most (and at the start): eight
/// of the longest signed frames.
#[doc(hidden)]
pub const RAW_SIGNATURE_BURST: u64 = 8 * raw_signature_cost(crate::frame::MAX_FRAME_LEN);

/// Per-sender sequence tracking.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
#[non_exhaustive]
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

/// How much work a parser did: see `Parser::work` (for tests: not part of
/// the API).
#[doc(hidden)]
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
/// As many as a verifier's signing streams by default: a link with more
/// senders than that is a swarm's, whose statistics fold.
pub const MAX_TRACKED_LINKS: usize = 16;
const _: () = assert!(MAX_TRACKED_LINKS <= u8::MAX as usize);

/// A frame the parser accepted, borrowed; [`ReceivedBuf`](crate::ReceivedBuf)
/// is the same copied out, with the same accessors.
pub struct Received<'a, D: MessageSet> {
    frame: Frame<&'a [u8]>,
    meta: Option<&'static MessageMeta>,
    authenticated: bool,
    _dialect: PhantomData<D>,
}

impl<'a, D: MessageSet> Received<'a, D> {
    /// A frame the parser (or a copy of one) vouches for.
    pub(crate) fn new(
        frame: Frame<&'a [u8]>,
        meta: Option<&'static MessageMeta>,
        authenticated: bool,
    ) -> Self {
        Received {
            frame,
            meta,
            authenticated,
            _dialect: PhantomData,
        }
    }

    /// The frame, borrowed from the input chunk or the parser's buffer.
    pub fn frame(&self) -> Frame<&'a [u8]> {
        self.frame
    }

    /// The frame's bytes, as received.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.frame.as_bytes()
    }

    /// The sender's header fields.
    pub fn header(&self) -> Header {
        self.frame.header()
    }

    /// Message id.
    pub fn msg_id(&self) -> u32 {
        self.frame.msg_id()
    }

    /// The message's table row; `None` for an id the dialect does not know
    /// (a raw frame: its checksum could not be verified).
    pub fn meta(&self) -> Option<&'static MessageMeta> {
        self.meta
    }

    /// True when the frame's signature was verified with the key.
    pub fn is_authenticated(&self) -> bool {
        self.authenticated
    }

    /// A zero-copy view of the message; `None` for an unknown id.
    pub fn view(&self) -> Option<D::View<'a>> {
        // The row's id is the frame's: no second read of the header.
        D::view(self.meta?.id, self.frame.payload())
    }

    /// The message, copied out; `None` for an unknown id.
    pub fn message(&self) -> Option<D::Message> {
        D::parse(self.meta?.id, self.frame.payload())
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

/// The longest candidate the parser waits for: a frame of an unknown id
/// whose last byte starts a frame of a known id (which must be decided
/// first), less one.
const MAX_NEEDED: usize = 2 * MAX_FRAME_LEN - 1;

/// The buffer: bytes are dropped from its front by moving a start index,
/// and move to the front only when its end needs room, after more than
/// `BUF_LEN - MAX_NEEDED` were dropped: less than two moves per byte.
const BUF_LEN: usize = 640;
const _: () = assert!(BUF_LEN > MAX_NEEDED);

/// What to do with the candidate at the start of some bytes.
enum Verdict {
    /// More bytes are needed: the candidate is this long (so far).
    Need(usize),
    /// A frame of this length.
    Accept {
        len: usize,
        meta: Option<&'static MessageMeta>,
        authenticated: bool,
    },
    /// A real frame (checksum good) that policy drops: these many bytes.
    Skip(usize),
    /// Not a frame: resume at the next byte.
    Reject,
}

/// The budget for checking signed candidates of unknown ids (see the
/// module docs), in units of 1 / `BYTES_PER_RAW_SIGNATURE_BYTE` hashed
/// byte: each byte consumed earns one.
struct Budget {
    credit: u64,
    /// The stream position the credit is as of.
    at: u64,
    /// Candidate position + 1 whose check is paid for (a candidate waiting
    /// for bytes is checked again, and paid for once)...
    paid: u64,
    /// ...and whose signature failed (it would fail again: the verifier
    /// changes only when a frame is accepted, which moves the candidate).
    failed: u64,
}

const CREDIT_CAP: u64 = RAW_SIGNATURE_BURST * BYTES_PER_RAW_SIGNATURE_BYTE;

impl Budget {
    /// Pays for the check of the candidate at `at`, `len` bytes long, once:
    /// false when the budget cannot.
    fn pay(&mut self, at: u64, len: usize) -> bool {
        if self.paid == at + 1 {
            return true;
        }
        self.earn(at);
        let cost = raw_signature_cost(len) * BYTES_PER_RAW_SIGNATURE_BYTE;
        if self.credit < cost {
            return false;
        }
        self.credit -= cost;
        self.paid = at + 1;
        true
    }

    /// A genuine frame is taken: its bytes pay for its check.
    fn refund(&mut self, at: u64, len: usize) {
        self.earn(at);
        let cost = raw_signature_cost(len) * BYTES_PER_RAW_SIGNATURE_BYTE;
        self.credit = (self.credit + cost).min(CREDIT_CAP);
    }

    fn earn(&mut self, at: u64) {
        self.credit = (self.credit + at - self.at).min(CREDIT_CAP);
        self.at = at;
    }
}

/// Bytes a signed frame of `len` bytes makes SHA-256 hash: the 32-byte key,
/// and the frame less the 6 signature bytes.
const fn raw_signature_cost(len: usize) -> u64 {
    len as u64 + 32 - 6
}

/// The streaming parser for dialect `D`, verifying signatures for up to
/// `STREAMS` signing streams when a key is configured. About 4 KiB, no heap.
///
/// ```
/// # use mavframe::{MessageSet, MessageMeta};
/// # struct D; impl MessageSet for D { type Message = (); type View<'a> = ();
/// #   const MESSAGES: &'static [MessageMeta] = &[];
/// #   fn parse(_: u32, _: &[u8]) -> Option<()> { None } fn view(_: u32, _: &[u8]) -> Option<()> { None } }
/// use mavframe::Parser;
///
/// let mut parser = Parser::<D>::new();
/// // A frame of an id this dialect does not know, cut across two reads,
/// // after garbage; the start byte after it confirms it.
/// let reads: [&[u8]; 2] = [b"junk\xfd\x01\x00\x00\x07\x01\x01", b"\x2a\x00\x00\x09\x12\x34\xfd"];
/// let mut frames = 0;
/// for mut chunk in reads {
///     while let Some(received) = parser.next(&mut chunk) {
///         assert_eq!(received.msg_id(), 42);
///         frames += 1;
///     }
/// }
/// while parser.flush().is_some() {}
/// assert_eq!((frames, parser.stats().bytes_dropped), (1, 5));
/// ```
// In this order (`repr(C)`): the fields every call reads first, within a
// byte's displacement of the parser's address (shorter instructions: about
// 400 bytes less code), the buffer last.
#[repr(C)]
pub struct Parser<D: MessageSet, const STREAMS: usize = 16> {
    head: usize,
    len: usize,
    /// A frame at the start of the bytes held, returned by the last call:
    /// dropped when the parser next runs.
    returned: usize,
    /// The last this many bytes held are copies of the first as many of
    /// the input, not consumed from it: once the bytes held before them are
    /// dropped, the parser goes back to the input in place (in garbage
    /// dense in start bytes the bytes held never run out: every byte after
    /// a chunk boundary would be copied and checked twice).
    shadow: usize,
    /// Stream position of the first byte not consumed (held, or of the
    /// input when none is).
    pos: u64,
    /// No more bytes will come ([`Parser::flush`], or the end of a
    /// datagram) until some are pushed.
    at_eof: bool,
    accept_unsigned: bool,
    keyed: Option<Keyed<STREAMS>>,
    stats: Stats,
    budget: Budget,
    signatures: u64,
    memo: Memo,
    links: Senders,
    verifier: Option<Verifier<STREAMS>>,
    /// Bytes held for a candidate that spans chunks: `buf[head..head + len]`.
    buf: [u8; BUF_LEN],
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
            returned: 0,
            shadow: 0,
            pos: 0,
            at_eof: false,
            memo: Memo::new(),
            budget: Budget {
                credit: CREDIT_CAP,
                at: 0,
                paid: 0,
                failed: 0,
            },
            stats: Stats::default(),
            links: Senders::new(),
            verifier: None,
            keyed: None,
            accept_unsigned: true,
            signatures: 0,
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
    /// # const PING: MessageMeta = MessageMeta::new(4242, "PING_EXAMPLE", 7, 1, 1, &[]);
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
    /// assert!(first.frame().is_signed()); // the unsigned frame was dropped
    /// assert_eq!(parser.stats().unsigned_rejected, 1);
    /// ```
    pub fn with_signing(verifier: Verifier<STREAMS>, unsigned: Unsigned) -> Self {
        let mut p = Self::new();
        p.verifier = Some(verifier);
        p.keyed = Some(Keyed {
            whole: check_keyed::<D, STREAMS>,
            cut: pay_for_cut::<STREAMS>,
        });
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
        &self.links.links[..usize::from(self.links.tracked)]
    }

    /// Bytes held for an incomplete frame (consumed from the input).
    pub fn pending(&self) -> usize {
        self.len - self.shadow
    }

    /// The work done so far, for the parser's tests (not part of the API):
    /// the steps are bounded by a constant times (bytes pushed + calls),
    /// whatever the bytes (the tests pin the constant).
    #[doc(hidden)]
    pub fn work(&self) -> Work {
        Work {
            // Each byte consumed was searched for a start byte and, when
            // it was part of a frame returned or skipped, checksummed once;
            // each frame returned was a check. Counted here rather than on
            // the hot path.
            steps: self.memo.steps + 2 * self.pos + self.stats.frames + self.stats.unknown_frames,
            signatures: self.signatures,
        }
    }

    /// Consumes bytes from `input` until a frame is complete and returns it;
    /// `None` once `input` is used up (a partial frame stays buffered for
    /// the next chunk). `input` is advanced past what was consumed.
    pub fn next<'r, 'i: 'r>(&'r mut self, input: &mut &'i [u8]) -> Option<Received<'r, D>> {
        self.parse(input, false)
    }

    /// [`next`](Self::next) for `input` that ends a datagram (on links
    /// where a frame never spans datagrams: MAVLink over UDP): the end of
    /// the input is the end of the stream, so a candidate cut by it is
    /// rejected at once and nothing waits for bytes that cannot come. The
    /// same frames, in the same order, as `next` and then
    /// `end_of_datagram`. Call `end_of_datagram` after the last call all
    /// the same.
    pub fn next_in_datagram<'r, 'i: 'r>(
        &'r mut self,
        input: &mut &'i [u8],
    ) -> Option<Received<'r, D>> {
        self.parse(input, true)
    }

    /// Ends the stream: call until `None`. Buffered bytes are parsed as if
    /// nothing follows them: an incomplete candidate is rejected and the
    /// bytes after its start byte are searched again (so a false start byte
    /// near the end loses no frame), and a raw frame of an unknown id that
    /// was waiting for the byte after it is returned. The parser stays
    /// usable: bytes pushed afterwards are parsed as a new stream.
    pub fn flush(&mut self) -> Option<Received<'_, D>> {
        self.parse(&mut &[][..], true)
    }

    /// Ends a datagram: call until `None` once a datagram's bytes are all
    /// pushed, on links where a frame never spans datagrams (MAVLink over
    /// UDP). The same as [`flush`](Self::flush): a candidate cut by the
    /// datagram's end can never be completed, so it is rejected now.
    pub fn end_of_datagram(&mut self) -> Option<Received<'_, D>> {
        self.flush()
    }

    /// The one loop behind every entry point: candidates in place in the
    /// input while nothing is held, else at the start of the bytes held
    /// (topped up from the input as a candidate needs). `ends`: nothing
    /// follows `input`.
    fn parse<'r, 'i: 'r>(
        &'r mut self,
        input: &mut &'i [u8],
        ends: bool,
    ) -> Option<Received<'r, D>> {
        self.release_returned();
        if input.len() < self.shadow {
            // Not the rest of the input the copies were taken from: they
            // are all there is.
            self.shadow = 0;
        }
        if ends {
            self.at_eof = true;
        } else if !input.is_empty() {
            self.at_eof = false;
        }
        // Decide first, borrow after: the frame borrows either the input or
        // the buffer.
        let (in_buf, len, meta, authenticated) = self.decide(input)?;
        let bytes = if in_buf {
            self.returned = len;
            &self.buf[self.head..self.head + len]
        } else {
            let (frame, rest) = input.split_at(len);
            *input = rest;
            self.pos += len as u64;
            frame
        };
        let frame = Frame::new_unchecked(bytes);
        self.links
            .record(&mut self.stats, frame.header(), meta.is_some());
        Some(Received {
            frame,
            meta,
            authenticated,
            _dialect: PhantomData,
        })
    }

    /// Candidates until one is accepted (where: the buffer, or the input),
    /// or `None` once the input is used up.
    #[inline(always)]
    fn decide(&mut self, input: &mut &[u8]) -> Option<Accepted> {
        loop {
            let held = self.len != 0;
            if held && self.len == self.shadow {
                // Only copies of the input are held: back to it in place.
                (self.head, self.len, self.shadow) = (0, 0, 0);
                continue;
            }
            if !held && !self.skip_to_start(input) {
                return None;
            }
            let (bytes, end) = if held {
                let end = input.len() == self.shadow;
                (&self.buf[self.head..self.head + self.len], end)
            } else {
                (*input, true)
            };
            let mut cx = Cx {
                at: self.pos,
                memo: &mut self.memo,
                budget: &mut self.budget,
                verifier: &mut self.verifier,
                accept_unsigned: self.accept_unsigned,
                stats: &mut self.stats,
                signatures: &mut self.signatures,
            };
            match check::<D, STREAMS>(bytes, self.at_eof && end, &mut cx, self.keyed) {
                Verdict::Accept {
                    len,
                    meta,
                    authenticated,
                } => {
                    if held {
                        self.settle(input, len);
                    }
                    return Some((held, len, meta, authenticated));
                }
                Verdict::Need(n) if held => {
                    self.memo.steps += 1;
                    if !self.top_up(input, n) {
                        // The input is all copied: consumed.
                        *input = &[];
                        self.shadow = 0;
                        return None;
                    }
                }
                Verdict::Need(_) => {
                    self.memo.steps += 1;
                    self.hold(input);
                    return None;
                }
                Verdict::Skip(n) => self.drop(input, n, held),
                Verdict::Reject => self.drop(input, 1, held),
            }
        }
    }

    /// A frame of `len` bytes at the start of the bytes held is returned:
    /// the copies of the input it holds are consumed, and when only copies
    /// follow it they are dropped from the buffer (the next call parses
    /// them in place).
    fn settle(&mut self, input: &mut &[u8], len: usize) {
        self.consume_copies(input, len);
        if self.len - len == self.shadow {
            (self.len, self.shadow) = (len, 0);
        }
    }

    /// The first `n` bytes held are taken: those of them that are copies of
    /// the input's head are consumed from it.
    fn consume_copies(&mut self, input: &mut &[u8], n: usize) {
        let copies = n.saturating_sub(self.len - self.shadow);
        *input = &input[copies..];
        self.shadow -= copies;
    }

    /// Drops the input up to its first start byte: false when it has none
    /// (all dropped).
    #[inline]
    fn skip_to_start(&mut self, input: &mut &[u8]) -> bool {
        if matches!(input.first(), Some(&(STX_V1 | STX_V2))) {
            return true;
        }
        let start = input.iter().position(|&b| b == STX_V2 || b == STX_V1);
        let n = start.unwrap_or(input.len());
        self.stats.bytes_dropped += n as u64;
        self.pos += n as u64;
        *input = &input[n..];
        start.is_some()
    }

    /// Drops the candidate's first `n` bytes (counted): from the input, or
    /// from the bytes held, then those up to the next start byte held.
    fn drop(&mut self, input: &mut &[u8], n: usize, held: bool) {
        // (The check that decided it.)
        self.memo.steps += 1;
        self.stats.bytes_dropped += n as u64;
        self.pos += n as u64;
        if !held {
            *input = &input[n..];
            return;
        }
        let rest = &self.buf[self.head + n..self.head + self.len];
        let skip = rest
            .iter()
            .position(|&b| b == STX_V2 || b == STX_V1)
            .unwrap_or(rest.len());
        self.stats.bytes_dropped += skip as u64;
        self.pos += skip as u64;
        self.consume_copies(input, n + skip);
        self.head += n + skip;
        self.len -= n + skip;
    }

    /// The candidate in place needs more than the input has: all of it is
    /// held (shorter than what it needs, less than [`MAX_NEEDED`]).
    fn hold(&mut self, input: &mut &[u8]) {
        let n = input.len().min(BUF_LEN);
        self.buf[..n].copy_from_slice(&input[..n]);
        (self.head, self.len) = (0, n);
        self.memo.steps += n as u64;
        *input = &input[n..];
    }

    /// Copies bytes of the input after those copied already until `needed`
    /// are held (not consumed: see [`Parser::shadow`]): false when the
    /// input ran out first (or had nothing to give).
    fn top_up(&mut self, input: &[u8], needed: usize) -> bool {
        let input = &input[self.shadow..];
        let needed = needed.min(MAX_NEEDED);
        let take = needed.saturating_sub(self.len).min(input.len());
        if self.head + self.len + take > BUF_LEN {
            self.buf.copy_within(self.head..self.head + self.len, 0);
            self.memo.steps += self.len as u64;
            self.head = 0;
        }
        let end = self.head + self.len;
        self.buf[end..end + take].copy_from_slice(&input[..take]);
        self.memo.steps += take as u64;
        self.len += take;
        self.shadow += take;
        take > 0 && self.len >= needed
    }

    #[inline]
    fn release_returned(&mut self) {
        if self.returned == 0 {
            return;
        }
        let n = core::mem::take(&mut self.returned);
        self.head += n;
        self.len -= n;
        self.pos += n as u64;
        if self.len == 0 {
            self.head = 0;
        }
    }
}

/// A frame accepted: in the buffer (else in the input), its length, its
/// message's row, authenticated.
type Accepted = (bool, usize, Option<&'static MessageMeta>, bool);

/// What a check of a candidate needs besides its bytes.
struct Cx<'a, const N: usize> {
    /// Stream position of the candidate (`bytes[0]`).
    at: u64,
    memo: &'a mut Memo,
    budget: &'a mut Budget,
    verifier: &'a mut Option<Verifier<N>>,
    accept_unsigned: bool,
    stats: &'a mut Stats,
    signatures: &'a mut u64,
}

/// The checks of a parser with a key ([`check_keyed`], [`pay_for_cut`]),
/// through pointers that only [`Parser::with_signing`] takes: without
/// `fast`, a parser never given one links neither them nor the verifier's
/// checks and SHA-256 (a small board's receiver). With `fast` they are
/// called directly (see [`check`]).
#[derive(Clone, Copy)]
#[cfg_attr(feature = "fast", allow(dead_code))]
struct Keyed<const N: usize> {
    whole: WholeCheck<N>,
    cut: fn(&[u8], usize, &mut Cx<'_, N>),
}

/// [`check_keyed`]'s signature.
type WholeCheck<const N: usize> =
    fn(&[u8], &Frame<&[u8]>, usize, Option<&'static MessageMeta>, bool, &mut Cx<'_, N>) -> Verdict;

/// The decision about the candidate at the start of `bytes` (a start byte:
/// the bytes at hand from it on); `end`: no byte follows them; `keyed`:
/// the checks of a parser with a key.
#[inline(always)]
fn check<D: MessageSet, const N: usize>(
    bytes: &[u8],
    end: bool,
    cx: &mut Cx<'_, N>,
    keyed: Option<Keyed<N>>,
) -> Verdict {
    let need = |n: usize| {
        if end {
            Verdict::Reject
        } else {
            Verdict::Need(n)
        }
    };
    let len = match frame_len(bytes) {
        Ok(len) if bytes.len() >= len => len,
        Ok(len) => {
            // An unverifiable candidate loses at once to a good frame inside.
            if !known::<D>(bytes) && cx.memo.inside::<D>(bytes, cx.at, bytes.len()) == Inside::Yes {
                #[cfg(feature = "fast")]
                pay_for_cut(bytes, len, cx);
                #[cfg(not(feature = "fast"))]
                if let Some(k) = keyed {
                    (k.cut)(bytes, len, cx);
                }
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
    let meta = D::meta(msg_id(bytes));
    if let Some(m) = meta {
        let covered = len
            - 3
            - if frame.is_signed() {
                crate::frame::SIGNATURE_LEN
            } else {
                0
            };
        if cx.memo.candidate::<D>(bytes, cx.at, covered, m.crc_extra) == Crc::Bad {
            cx.stats.bad_crc += 1;
            return Verdict::Reject;
        }
    }
    // With `fast` the key's checks are called directly (inlined: through
    // the pointer, the parser's state spills from registers, 10 % more
    // instructions per frame of a valid stream); without, through the
    // pointer only `with_signing` sets, so that a parser without a key
    // links none of them.
    #[cfg(feature = "fast")]
    {
        let _ = keyed;
        check_keyed::<D, N>(bytes, &frame, len, meta, end, cx)
    }
    #[cfg(not(feature = "fast"))]
    {
        if let Some(k) = keyed {
            return (k.whole)(bytes, &frame, len, meta, end, cx);
        }
        if meta.is_none() {
            if let Some(v) = check_raw_unkeyed::<D>(bytes, len, end, cx.memo, cx.at) {
                return v;
            }
        }
        Verdict::Accept {
            len,
            meta,
            authenticated: false,
        }
    }
}

/// The rest of [`check`] for a parser with a key: a whole candidate with a
/// good checksum, or of an unknown id.
fn check_keyed<D: MessageSet, const N: usize>(
    bytes: &[u8],
    frame: &Frame<&[u8]>,
    len: usize,
    meta: Option<&'static MessageMeta>,
    end: bool,
    cx: &mut Cx<'_, N>,
) -> Verdict {
    if meta.is_none() {
        if let Some(v) = check_raw::<D, N>(bytes, frame, len, end, cx) {
            return v;
        }
    }
    signing(frame, len, meta, cx)
}

/// A raw candidate of `len` bytes cut short, which loses to a good frame
/// inside, on a parser with a key: a signed one pays as it would whole
/// (how many of its bytes were there is a matter of read sizes, which must
/// not change the budget).
fn pay_for_cut<const N: usize>(bytes: &[u8], len: usize, cx: &mut Cx<'_, N>) {
    if signed_v2(bytes) && cx.verifier.is_some() && !cx.budget.pay(cx.at, len) {
        cx.stats.signatures_unchecked += 1;
    }
}

/// [`check_raw`] for a parser without a key (a small build's: see
/// [`check`]): a raw candidate is confirmed
/// by the start byte after it (or the end of the stream), with no good
/// frame of a known id inside.
#[cfg(not(feature = "fast"))]
fn check_raw_unkeyed<D: MessageSet>(
    bytes: &[u8],
    len: usize,
    end: bool,
    memo: &mut Memo,
    at: u64,
) -> Option<Verdict> {
    if bytes.get(len).is_some_and(|&b| b != STX_V1 && b != STX_V2) {
        return Some(Verdict::Reject);
    }
    match memo.inside::<D>(bytes, at, len) {
        Inside::Yes => Some(Verdict::Reject),
        Inside::Undecided(needed) if !end => Some(Verdict::Need(needed)),
        Inside::Undecided(_) | Inside::No if bytes.len() == len && !end => {
            Some(Verdict::Need(len + 1))
        }
        Inside::Undecided(_) | Inside::No => None,
    }
}

/// Whether the candidate's (maybe cut) header has a known id: out of line,
/// so that the hot path's look-up is the one inlined.
#[inline(never)]
fn known<D: MessageSet>(bytes: &[u8]) -> bool {
    D::meta(msg_id(bytes)).is_some()
}

/// The decision about a whole candidate `frame` of an unknown id, `len`
/// bytes long (see the module docs), or `None` when only the signing policy
/// is left to apply.
fn check_raw<D: MessageSet, const N: usize>(
    bytes: &[u8],
    frame: &Frame<&[u8]>,
    len: usize,
    end: bool,
    cx: &mut Cx<'_, N>,
) -> Option<Verdict> {
    let checked = frame.is_signed() && cx.verifier.is_some();
    // Paid before the search inside: a good signature gives it back.
    if checked && !cx.budget.pay(cx.at, len) {
        cx.stats.signatures_unchecked += 1;
        return Some(Verdict::Reject);
    }
    // Unconfirmed whatever is inside: no search.
    if !checked && bytes.get(len).is_some_and(|&b| b != STX_V1 && b != STX_V2) {
        return Some(Verdict::Reject);
    }
    match cx.memo.inside::<D>(bytes, cx.at, len) {
        Inside::Yes => return Some(Verdict::Reject),
        Inside::Undecided(needed) if !end => return Some(Verdict::Need(needed)),
        Inside::Undecided(_) | Inside::No => {}
    }
    let authenticated = checked && cx.budget.failed != cx.at + 1 && {
        *cx.signatures += 1;
        let ok = cx
            .verifier
            .as_mut()
            .is_some_and(|v| v.verify(frame).is_ok());
        if ok {
            cx.budget.refund(cx.at, len);
        } else {
            cx.budget.failed = cx.at + 1;
        }
        ok
    };
    match bytes.get(len) {
        _ if authenticated => {
            return Some(Verdict::Accept {
                len,
                meta: None,
                authenticated: true,
            })
        }
        None if end => {}
        None => return Some(Verdict::Need(len + 1)),
        Some(&b) if b != STX_V1 && b != STX_V2 => return Some(Verdict::Reject),
        Some(_) => {}
    }
    if checked {
        // Its signature failed: with an unverifiable checksum the "frame"
        // may be garbage, so resume inside it (and its header names no
        // one).
        cx.stats.bad_signature += 1;
        cx.stats.bad_signature_sender = None;
        return Some(Verdict::Reject);
    }
    None
}

/// The decision of the signing policy about a whole candidate `frame`,
/// `len` bytes long, that nothing else refuses. The length is the one
/// `check` delimited the frame with: read again from the header it would
/// cost every frame a dozen instructions.
fn signing<const N: usize>(
    frame: &Frame<&[u8]>,
    len: usize,
    meta: Option<&'static MessageMeta>,
    cx: &mut Cx<'_, N>,
) -> Verdict {
    let mut authenticated = false;
    if let Some(v) = cx.verifier {
        if frame.is_signed() {
            *cx.signatures += 1;
        }
        match v.verify(frame) {
            Ok(()) => authenticated = true,
            Err(SignatureError::Unsigned) if cx.accept_unsigned => {}
            Err(SignatureError::Unsigned) => {
                cx.stats.unsigned_rejected += 1;
                return Verdict::Skip(len);
            }
            // Under `Unsigned::Accept`, a frame the key signed whose
            // timestamp is stale is returned unauthenticated, as an
            // unsigned one would be: it can act on nothing that requires a
            // signature, and its sender (a key holder whose clock is
            // behind, or a replay) can be answered so that it catches up.
            Err(e) if e.is_stale() && cx.accept_unsigned && v.signed_with_key(frame) => {
                cx.stats.stale_timestamp += 1;
            }
            Err(e) => {
                if e.is_stale() {
                    cx.stats.stale_timestamp += 1;
                } else {
                    let h = frame.header();
                    cx.stats.bad_signature += 1;
                    cx.stats.bad_signature_sender = Some((h.sysid, h.compid));
                }
                // A good checksum vouches for the header and payload only:
                // the 13 bytes after it may be the head of the next frame.
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

/// Whether `bytes` start a MAVLink 2 header whose flags say signed.
fn signed_v2(bytes: &[u8]) -> bool {
    matches!(bytes, [STX_V2, _, flags, ..] if flags & IFLAG_SIGNED != 0)
}

/// The message id in a (possibly incomplete) header at `bytes[0]`.
fn msg_id(bytes: &[u8]) -> u32 {
    // A whole header first: one bounds check (every frame comes here).
    match *bytes {
        [STX_V2, _, _, _, _, _, _, a, b, c, ..] => u32::from_le_bytes([a, b, c, 0]),
        [STX_V2, ..] => u32::from_le_bytes([
            bytes.get(7).copied().unwrap_or(0),
            bytes.get(8).copied().unwrap_or(0),
            0,
            0,
        ]),
        _ => bytes.get(5).copied().unwrap_or(0) as u32,
    }
}

/// The senders tracked for sequence gaps: a slot each for the first
/// [`MAX_TRACKED_LINKS`], the last one taken over by any sender after them.
struct Senders {
    links: [LinkStats; MAX_TRACKED_LINKS],
    tracked: u8,
    /// The slot of the last frame's sender: most frames come from it.
    last: u8,
}

impl Senders {
    const fn new() -> Self {
        const EMPTY: LinkStats = LinkStats {
            sysid: 0,
            compid: 0,
            received: 0,
            lost: 0,
            gaps: 0,
            last_seq: 0,
        };
        Senders {
            links: [EMPTY; MAX_TRACKED_LINKS],
            tracked: 0,
            last: 0,
        }
    }

    /// Counts a frame returned, and its sender's sequence gap or repeat.
    #[inline]
    fn record(&mut self, stats: &mut Stats, h: Header, known: bool) {
        if known {
            stats.frames += 1;
        } else {
            stats.unknown_frames += 1;
        }
        let link = self.find(h.sysid, h.compid, h.seq);
        link.received += 1;
        if link.received > 1 && h.seq == link.last_seq {
            stats.duplicates += 1;
            return;
        }
        let lost = u64::from(h.seq.wrapping_sub(link.last_seq.wrapping_add(1)));
        if lost != 0 {
            link.lost += lost;
            link.gaps += 1;
            stats.seq_lost += lost;
        }
        link.last_seq = h.seq;
    }

    #[inline]
    fn find(&mut self, sysid: u8, compid: u8, seq: u8) -> &mut LinkStats {
        let same = |l: &LinkStats| (l.sysid, l.compid) == (sysid, compid);
        // (`last` is a slot: the modulo only spares a bounds check.)
        let tracked = usize::from(self.tracked);
        let last = usize::from(self.last) % MAX_TRACKED_LINKS;
        let slot = if tracked > 0 && same(&self.links[last]) {
            last
        } else if let Some(i) = self.links[..tracked].iter().position(same) {
            i
        } else {
            let i = tracked.min(MAX_TRACKED_LINKS - 1);
            self.links[i] = LinkStats {
                sysid,
                compid,
                last_seq: seq.wrapping_sub(1),
                ..LinkStats::default()
            };
            self.tracked = (tracked + 1).min(MAX_TRACKED_LINKS) as u8;
            i
        };
        self.last = slot as u8;
        &mut self.links[slot]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{FrameBuf, Version};
    use crate::{BufferTooSmall, Encode};

    const PING: MessageMeta = MessageMeta::new(4242, "PING_EXAMPLE", 7, 1, 1, &[]);

    struct D;
    impl MessageSet for D {
        type Message = ();
        type View<'a> = ();
        const MESSAGES: &'static [MessageMeta] = &[PING];
        fn parse(_: u32, _: &[u8]) -> Option<()> {
            Some(())
        }
        fn view(_: u32, _: &[u8]) -> Option<()> {
            Some(())
        }
    }

    struct Ping;
    impl Encode for Ping {
        fn meta(&self) -> &'static MessageMeta {
            &PING
        }
        fn emit_payload(&self, out: &mut [u8]) -> Result<usize, BufferTooSmall> {
            *out.first_mut()
                .ok_or(BufferTooSmall { needed: 1, got: 0 })? = 1;
            Ok(1)
        }
    }

    /// Frames of `seqs` from one sender, back to back.
    fn frames(seqs: &[u8]) -> ([u8; 128], usize) {
        let (mut out, mut n) = ([0; 128], 0);
        for &seq in seqs {
            let h = Header {
                seq,
                sysid: 1,
                compid: 1,
            };
            let f = FrameBuf::encode(Version::V2, h, &Ping, None).unwrap();
            out[n..n + f.len()].copy_from_slice(&f);
            n += f.len();
        }
        (out, n)
    }

    fn stats_of((bytes, n): ([u8; 128], usize)) -> (Stats, LinkStats) {
        let mut p = Parser::<D>::new();
        let mut input = &bytes[..n];
        while p.next(&mut input).is_some() {}
        (*p.stats(), p.links()[0])
    }

    /// The per-sender table (512 bytes) and the verifier (584 bytes) are most
    /// of it; the buffer and the memo are a frame's length or two each.
    #[test]
    fn the_parser_is_small() {
        let size = core::mem::size_of::<Parser<D>>();
        assert!(size <= 4096, "{size} bytes");
    }

    #[test]
    fn a_frame_received_twice_is_a_duplicate_not_a_gap() {
        // 3 arrives twice (redundant links): no frame is missing.
        let (stats, link) = stats_of(frames(&[1, 2, 3, 3, 4]));
        assert_eq!((stats.frames, stats.duplicates, stats.seq_lost), (5, 1, 0));
        assert_eq!((link.received, link.lost, link.gaps), (5, 0, 0));
        // A real gap is still one: 2 and 3 missing.
        let (stats, link) = stats_of(frames(&[1, 4, 4]));
        assert_eq!((stats.duplicates, stats.seq_lost, link.gaps), (1, 2, 1));
    }
}
