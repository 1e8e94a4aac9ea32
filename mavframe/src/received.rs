//! [`ReceivedBuf`]: a frame the parser accepted, owned (no std, no heap).

use crate::frame::{Frame, Header, MAX_FRAME_LEN};
use crate::message::{MessageMeta, MessageSet};
use crate::parser::Received;
use core::fmt;
use core::marker::PhantomData;

/// A frame the parser accepted, copied out of it so it outlives the next
/// receive: what the blocking connections, the router and the `embedded`
/// adapters return, and what `ReceivedBuf::from(&received)` makes of any
/// [`Received`] (which borrows, as a [`Frame`] view does, where this owns, as
/// a [`FrameBuf`](crate::FrameBuf) does). No heap: the bytes sit inline (at
/// most [`MAX_FRAME_LEN`]).
///
/// ```
/// # use mavframe::{MessageSet, MessageMeta};
/// # struct D; impl MessageSet for D { type Message = (); type View<'a> = ();
/// #   const MESSAGES: &'static [MessageMeta] = &[];
/// #   fn parse(_: u32, _: &[u8]) -> Option<()> { None } fn view(_: u32, _: &[u8]) -> Option<()> { None } }
/// use mavframe::{Parser, ReceivedBuf};
///
/// let mut parser = Parser::<D>::new();
/// // A frame of an id this dialect does not know, confirmed by the start
/// // byte after it.
/// let mut bytes: &[u8] = b"\xfd\x01\x00\x00\x07\x01\x01\x2a\x00\x00\x09\x12\x34\xfd";
/// let owned = ReceivedBuf::from(&parser.next(&mut bytes).expect("a frame"));
/// drop(parser); // the copy outlives the parser
/// assert_eq!((owned.msg_id(), owned.header().seq), (42, 7));
/// assert!(owned.meta().is_none() && owned.message().is_none());
/// ```
pub struct ReceivedBuf<D: MessageSet> {
    bytes: [u8; MAX_FRAME_LEN],
    len: usize,
    meta: Option<&'static MessageMeta>,
    authenticated: bool,
    // fn() -> D: the dialect is a type-level tag, it does not make the frame
    // !Send or !Sync.
    _dialect: PhantomData<fn() -> D>,
}

impl<D: MessageSet> ReceivedBuf<D> {
    /// The frame.
    pub fn frame(&self) -> Frame<&[u8]> {
        // Only ever built from a frame the parser checked: cannot fail.
        Frame::new_checked(self.as_bytes())
            .unwrap_or_else(|_| unreachable!("ReceivedBuf holds a whole frame"))
    }

    /// The frame's bytes, as received.
    pub fn as_bytes(&self) -> &[u8] {
        &self.bytes[..self.len]
    }

    /// The sender's header fields.
    pub fn header(&self) -> Header {
        self.frame().header()
    }

    /// Message id.
    pub fn msg_id(&self) -> u32 {
        self.frame().msg_id()
    }

    /// The message's table row; `None` for an id the dialect does not know
    /// (a raw frame, forwarded unverified).
    pub fn meta(&self) -> Option<&'static MessageMeta> {
        self.meta
    }

    /// True when the frame's signature was verified with the parser's key.
    pub fn is_authenticated(&self) -> bool {
        self.authenticated
    }

    /// The copy, borrowed as the parser returns a frame: what takes a
    /// [`Received`] takes it.
    pub fn received(&self) -> Received<'_, D> {
        Received::new(self.frame(), self.meta, self.authenticated)
    }

    /// The message, parsed; `None` for an unknown id.
    pub fn message(&self) -> Option<D::Message> {
        D::parse(self.meta?.id, self.frame().payload())
    }

    /// A zero-copy view of the message; `None` for an unknown id.
    pub fn view(&self) -> Option<D::View<'_>> {
        D::view(self.meta?.id, self.frame().payload())
    }
}

impl<D: MessageSet> From<&Received<'_, D>> for ReceivedBuf<D> {
    fn from(r: &Received<'_, D>) -> Self {
        let src = r.frame().as_bytes();
        let mut bytes = [0u8; MAX_FRAME_LEN];
        // A frame is never longer than MAX_FRAME_LEN; min() keeps this total.
        let len = src.len().min(MAX_FRAME_LEN);
        bytes[..len].copy_from_slice(&src[..len]);
        ReceivedBuf {
            bytes,
            len,
            meta: r.meta(),
            authenticated: r.is_authenticated(),
            _dialect: PhantomData,
        }
    }
}

impl<D: MessageSet> Clone for ReceivedBuf<D> {
    fn clone(&self) -> Self {
        ReceivedBuf {
            bytes: self.bytes,
            len: self.len,
            meta: self.meta,
            authenticated: self.authenticated,
            _dialect: PhantomData,
        }
    }
}

impl<D: MessageSet> fmt::Debug for ReceivedBuf<D> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ReceivedBuf")
            .field("frame", &self.frame())
            .field("name", &self.meta.map(|m| m.name))
            .field("authenticated", &self.authenticated)
            .finish()
    }
}
