//! The adapters' state, blocking or async alike (`M`: [`Blocking`] or
//! `Async`): what they hold and the constructors and accessors they share.
//! The `blocking` and `asynch` modules add how each moves bytes.

#[cfg(doc)]
use super::RecvError;
use super::{inbox, Inbox};
use crate::framer::Framer;
use crate::link::LinkCore;
use crate::message::MessageSet;
use crate::parser::Parser;
use crate::received::ReceivedBuf;
use core::marker::PhantomData;

/// Marks the blocking adapters ([`Link`](super::Link),
/// [`Receiver`](super::Receiver), [`Sender`](super::Sender)).
#[derive(Debug, Clone, Copy)]
pub struct Blocking;

/// Marks the async adapters (`AsyncLink`, `AsyncReceiver`,
/// `AsyncSender`).
#[cfg(feature = "embedded-io-async")]
#[derive(Debug, Clone, Copy)]
pub struct Async;

/// MAVLink over one `Read + Write`: [`Link`](super::Link) (blocking) or
/// `AsyncLink` (async, `M` = `Async`, feature `embedded-io-async`).
pub struct LinkOf<M, T, D: MessageSet, const BUF: usize, const STREAMS: usize> {
    pub(super) io: T,
    pub(super) core: LinkCore<D, [u8; BUF], STREAMS>,
    pub(super) sysid: u8,
    pub(super) compid: u8,
    mode: PhantomData<M>,
}

/// The receiving half over a `Read`: [`Receiver`](super::Receiver) or
/// `AsyncReceiver`.
pub struct ReceiverOf<M, R, D: MessageSet, const BUF: usize, const STREAMS: usize> {
    pub(super) io: R,
    pub(super) inbox: Inbox<D, BUF, STREAMS>,
    mode: PhantomData<M>,
}

/// The sending half over a `Write`: [`Sender`](super::Sender) or
/// `AsyncSender`.
#[derive(Debug)]
pub struct SenderOf<M, W> {
    pub(super) io: W,
    pub(super) framer: Framer,
    pub(super) sysid: u8,
    pub(super) compid: u8,
    mode: PhantomData<M>,
}

impl<M, T, D: MessageSet, const BUF: usize, const STREAMS: usize> LinkOf<M, T, D, BUF, STREAMS> {
    /// A link over `io` sending as `sysid`/`compid`: MAVLink 2, unsigned;
    /// signed frames received are accepted unverified.
    pub fn new(io: T, sysid: u8, compid: u8) -> Self {
        Self::with_parts(io, Parser::new(), Framer::new(), sysid, compid)
    }

    /// A link receiving through `parser` (one made with
    /// [`Parser::with_signing`] verifies signatures) and sending through
    /// `framer` (its signer, version and sequence numbers).
    pub fn with_parts(
        io: T,
        parser: Parser<D, STREAMS>,
        framer: Framer,
        sysid: u8,
        compid: u8,
    ) -> Self {
        LinkOf {
            io,
            core: LinkCore {
                inbox: inbox(parser),
                framer,
            },
            sysid,
            compid,
            mode: PhantomData,
        }
    }

    /// The parser: its counters (bad checksums, signatures, sequence
    /// gaps…) and verifier.
    pub fn parser(&self) -> &Parser<D, STREAMS> {
        &self.core.inbox.parser
    }

    /// The framer.
    pub fn framer(&self) -> &Framer {
        &self.core.framer
    }

    /// The framer, to set a signer, a clock or the protocol version.
    pub fn framer_mut(&mut self) -> &mut Framer {
        &mut self.core.framer
    }

    /// The I/O.
    pub fn get_ref(&self) -> &T {
        &self.io
    }

    /// The I/O (reading or writing it directly bypasses the adapter).
    pub fn get_mut(&mut self) -> &mut T {
        &mut self.io
    }

    /// The I/O back; bytes read and not parsed yet are dropped.
    pub fn into_inner(self) -> T {
        self.io
    }

    /// At the end of the stream (after [`RecvError::Eof`]): the frames
    /// the held bytes still make, decided as if nothing follows. Call until
    /// `None`.
    pub fn recv_eof(&mut self) -> Option<ReceivedBuf<D>> {
        self.core.inbox.take_at_eof(|r| ReceivedBuf::from(&r))
    }
}

impl<M, R, D: MessageSet, const BUF: usize, const STREAMS: usize>
    ReceiverOf<M, R, D, BUF, STREAMS>
{
    /// A receiver accepting signed frames unverified.
    pub fn new(io: R) -> Self {
        Self::with_parser(io, Parser::new())
    }

    /// A receiver through `parser` (one made with
    /// [`Parser::with_signing`] verifies signatures).
    pub fn with_parser(io: R, parser: Parser<D, STREAMS>) -> Self {
        ReceiverOf {
            io,
            inbox: inbox(parser),
            mode: PhantomData,
        }
    }

    /// The parser: its counters and verifier.
    pub fn parser(&self) -> &Parser<D, STREAMS> {
        &self.inbox.parser
    }

    /// The reader.
    pub fn get_ref(&self) -> &R {
        &self.io
    }

    /// The reader (reading it directly bypasses the parser).
    pub fn get_mut(&mut self) -> &mut R {
        &mut self.io
    }

    /// The reader back; bytes read and not parsed yet are dropped.
    pub fn into_inner(self) -> R {
        self.io
    }

    /// As [`Link::recv_eof`](LinkOf::recv_eof).
    pub fn recv_eof(&mut self) -> Option<ReceivedBuf<D>> {
        self.inbox.take_at_eof(|r| ReceivedBuf::from(&r))
    }
}

impl<M, W> SenderOf<M, W> {
    /// A sender of unsigned MAVLink 2 frames.
    pub fn new(io: W, sysid: u8, compid: u8) -> Self {
        Self::with_framer(io, Framer::new(), sysid, compid)
    }

    /// A sender framing through `framer` (its signer, version and
    /// sequence numbers).
    pub fn with_framer(io: W, framer: Framer, sysid: u8, compid: u8) -> Self {
        SenderOf {
            io,
            framer,
            sysid,
            compid,
            mode: PhantomData,
        }
    }

    /// The framer.
    pub fn framer(&self) -> &Framer {
        &self.framer
    }

    /// The framer, to set a signer, a clock or the protocol version.
    pub fn framer_mut(&mut self) -> &mut Framer {
        &mut self.framer
    }

    /// The writer.
    pub fn get_ref(&self) -> &W {
        &self.io
    }

    /// The writer.
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.io
    }

    /// The writer back.
    pub fn into_inner(self) -> W {
        self.io
    }
}
