//! MAVLink over a UART or any byte stream on `no_std` targets: adapters
//! over the [`embedded-io`](https://docs.rs/embedded-io) traits (feature
//! `embedded-io`: [`Link`], [`Receiver`], [`Sender`]) and their async
//! twins over [`embedded-io-async`](https://docs.rs/embedded-io-async)
//! (feature `embedded-io-async`, which implies `embedded-io`: `AsyncLink`,
//! `AsyncReceiver`, `AsyncSender`). No heap, no std, no panics.
//!
//! A [`Link`] owns one `Read + Write` (a UART); a [`Receiver`] and a
//! [`Sender`] own one half each (the `Rx` and `Tx` a HAL's `split()` gives,
//! for a receive task and a send task). Receiving runs the crate's
//! streaming [`Parser`]: checksums, signatures when it has a key,
//! resynchronisation after garbage. Sending frames with a [`Framer`]:
//! sequence numbers, and signing when it has a signer.
//!
//! Each received frame comes either copied ([`recv`](Link::recv), a
//! [`ReceivedBuf`]) or borrowed in place ([`recv_with`](Link::recv_with)
//! hands a [`Received`] view to a closure, with no copy).
//!
//! # What a UART gives, and what the adapters do with it
//!
//! - **Partial reads.** A read returns whatever the driver has (one byte,
//!   a FIFO's worth, a DMA half-buffer), at most the adapter's read buffer
//!   (`BUF` bytes, 64 by default). Frames may span any number of reads; the
//!   parser assembles them in its own buffer, so `BUF` bounds the read
//!   size, not the frame size, and `BUF = 1` works.
//! - **No data yet.** embedded-io has no `WouldBlock`: a blocking `read`
//!   waits for at least one byte, so [`Link::recv`] waits for a frame. In a
//!   super-loop use [`Link::try_recv`] (the reader must implement
//!   [`ReadReady`](embedded_io::ReadReady)): it reads only while bytes are
//!   waiting and returns `Ok(None)` when none are. The async adapters just
//!   await.
//! - **Read errors** (overrun, framing, parity, noise) come back as
//!   [`RecvError::Read`] with the driver's own error. Nothing the adapter
//!   holds is lost: call `recv` again to go on. Bytes the UART dropped
//!   cost the frame they were in (its checksum fails), and the parser
//!   resynchronises on the next start byte.
//! - **A read returning 0 bytes** is end of stream in embedded-io's
//!   contract: [`RecvError::Eof`]. The adapter stays usable (a reader may
//!   have more later, and a non-conforming driver may mean "nothing yet"),
//!   and keeps what it holds; at a real end of stream,
//!   [`recv_eof`](Link::recv_eof) decides the held bytes as if nothing
//!   followed (a frame of an unknown id waits for the next start byte to
//!   be confirmed: see [`crate::parser`]).
//! - **Partial writes.** A frame is written whole: the adapter writes
//!   again after a short write, and again after an `Interrupted` error, as
//!   `std`'s `write_all` does. A writer that accepts 0 bytes gives
//!   [`SendError::WriteZero`] (embedded-io's own `write_all` panics there);
//!   another error gives [`SendError::Write`]. Either way part of the frame
//!   may be out: the receiver drops it (bad checksum) and resynchronises on
//!   the next frame. `send` does not flush: call [`flush`](Link::flush)
//!   where the driver buffers and you must wait for the bytes to leave.
//!
//! # Signing without a clock
//!
//! A [`Verifier`](crate::Verifier) for a live link starts from a timestamp
//! you keep (`Verifier::with_timestamp`, from storage or an RTC, or
//! `Verifier::with_clock`); a [`Signer`](crate::Signer)'s timestamps must
//! keep increasing across restarts, so start it above the last one it
//! sent, and give the [`Framer`] a clock if you have one
//! ([`Framer::set_clock`]). A [`Link`]'s signer adopts what its verifier
//! accepted; with a [`Receiver`] and a [`Sender`], hand it over yourself
//! (`sender.framer_mut().adopt_from(receiver.parser().verifier())`). See
//! [`crate::signing`].
//!
//! # Async cancellation and fairness
//!
//! Dropping an `AsyncReceiver::recv` future loses nothing the adapter
//! holds; whether bytes are lost inside the driver is the driver's
//! `read`'s cancel-safety. Dropping an `AsyncSender::send` future may cut a
//! frame short on the wire (the receiver drops it).
//!
//! An async receive that has read 1 KB without finding a frame yields to
//! the executor once before reading on, so a reader that is always ready
//! (garbage flooding a large driver buffer) cannot starve other tasks.
//!
//! ```
//! # use mavframe::{BufferTooSmall, MessageSet, MessageData, MessageMeta};
//! # #[derive(Clone, Debug, PartialEq, Default)] struct Ping(u8);
//! # impl MessageData for Ping {
//! #   const META: MessageMeta = MessageMeta::new(4, "PING", 237, 1, 1, &[]);
//! #   type View<'a> = u8;
//! #   fn parse(p: &[u8]) -> Self { Ping(p.first().copied().unwrap_or(0)) }
//! #   fn emit(&self, p: &mut [u8]) -> Result<usize, BufferTooSmall> {
//! #     *p.first_mut().ok_or(BufferTooSmall { needed: 1, got: 0 })? = self.0; Ok(1) }
//! #   fn view(p: &[u8]) -> u8 { p.first().copied().unwrap_or(0) }
//! # }
//! # struct MyDialect;
//! # impl MessageSet for MyDialect { type Message = Ping; type View<'a> = u8;
//! #   const MESSAGES: &'static [MessageMeta] = &[Ping::META];
//! #   fn parse(id: u32, p: &[u8]) -> Option<Ping> { (id == 4).then(|| Ping::parse(p)) }
//! #   fn view(id: u32, p: &[u8]) -> Option<u8> { (id == 4).then(|| Ping::view(p)) } }
//! use mavframe::embedded::{Receiver, RecvError, Sender};
//!
//! // The Tx half of a UART; here, a byte slice (embedded-io implements
//! // `Write` for `&mut [u8]` and `Read` for `&[u8]`).
//! let mut wire = [0u8; 64];
//! let mut tx = Sender::new(&mut wire[..], 1, 191);
//! tx.send(&Ping(7))?;
//! tx.send(&Ping(8))?;
//!
//! // The Rx half: the two frames, read up to 64 bytes at a time.
//! let mut rx = Receiver::<_, MyDialect>::new(&wire[..]);
//! assert_eq!(rx.recv()?.message(), Some(Ping(7)));
//! let seq = rx.recv_with(|frame| {
//!     assert_eq!(frame.view(), Some(8)); // a view in place, no copy
//!     frame.header().seq
//! })?;
//! assert_eq!(seq, 1);
//! // Then zeros (not frames) and the end of the slice.
//! assert!(matches!(rx.recv(), Err(RecvError::Eof)));
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#[cfg(feature = "embedded-io-async")]
mod asynch;
mod blocking;
mod parts;
#[cfg(test)]
mod tests;

#[cfg(feature = "embedded-io-async")]
pub use asynch::{AsyncLink, AsyncReceiver, AsyncSender};
pub use blocking::{Link, Receiver, Sender};
/// The traits the blocking adapters take, re-exported so the version
/// always matches.
pub use embedded_io;
/// The traits the async adapters take, re-exported so the version always
/// matches.
#[cfg(feature = "embedded-io-async")]
pub use embedded_io_async;
#[cfg(feature = "embedded-io-async")]
pub use parts::Async;
pub use parts::{Blocking, LinkOf, ReceiverOf, SenderOf};

use crate::frame::FrameError;
#[cfg(doc)]
use crate::framer::Framer;
use crate::message::MessageSet;
use crate::parser::Parser;
#[cfg(doc)]
use crate::parser::Received;
#[cfg(doc)]
use crate::ReceivedBuf;
use core::fmt;

/// The read buffer's default length: what one read may fill.
pub const DEFAULT_BUF: usize = 64;

/// Why receiving stopped. `E` is the reader's error type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum RecvError<E> {
    /// The reader failed (for a UART: overrun, framing, parity, noise…).
    /// Nothing the adapter holds is lost: receive again to go on.
    Read(E),
    /// A read returned 0 bytes: the end of the stream, in embedded-io's
    /// contract. Receive again if more may come; `recv_eof` decides the
    /// bytes held as if nothing follows.
    Eof,
}

impl<E> fmt::Display for RecvError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // The reader's error is the source, not part of this message.
        f.write_str(match self {
            RecvError::Read(_) => "reading from the link failed",
            RecvError::Eof => "end of stream (a read returned 0 bytes)",
        })
    }
}

impl<E: core::error::Error + 'static> core::error::Error for RecvError<E> {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            RecvError::Read(e) => Some(e),
            RecvError::Eof => None,
        }
    }
}

/// Why a frame did not go out whole. `E` is the writer's error type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SendError<E> {
    /// The writer failed; part of the frame may be out (the receiver drops
    /// it and resynchronises).
    Write(E),
    /// The writer accepted 0 bytes of a non-empty frame, which embedded-io
    /// allows only for an empty buffer: it cannot take more.
    WriteZero,
    /// The message could not be framed (a MAVLink 1 frame of an id above
    /// 255); nothing was written.
    Frame(FrameError),
}

impl<E> fmt::Display for SendError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SendError::Write(_) => f.write_str("writing to the link failed"),
            SendError::WriteZero => f.write_str("the link accepted 0 bytes of a frame"),
            // FrameError is an error source only with std: say it here.
            SendError::Frame(e) => write!(f, "cannot frame the message: {e}"),
        }
    }
}

impl<E: core::error::Error + 'static> core::error::Error for SendError<E> {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            SendError::Write(e) => Some(e),
            SendError::WriteZero | SendError::Frame(_) => None,
        }
    }
}

/// The receive side of every adapter: the link core's, over a read buffer
/// of `BUF` bytes.
type Inbox<D, const BUF: usize, const STREAMS: usize> = crate::link::Inbox<D, [u8; BUF], STREAMS>;

/// An inbox over a read buffer of `BUF` bytes.
fn inbox<D: MessageSet, const BUF: usize, const S: usize>(
    parser: Parser<D, S>,
) -> Inbox<D, BUF, S> {
    // A read into an empty buffer returns 0, which would read as the end
    // of the stream forever: refuse it when the type is built.
    const { assert!(BUF > 0, "the read buffer must hold at least one byte") };
    Inbox::new(parser, [0; BUF])
}
