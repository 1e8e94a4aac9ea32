//! The blocking adapters, over `embedded_io::{Read, Write}`.

use super::parts::{Blocking, LinkOf, ReceiverOf, SenderOf};
use super::{Inbox, RecvError, SendError, DEFAULT_BUF};
use crate::message::{Encode, MessageSet};
use crate::parser::Received;
use crate::received::ReceivedBuf;
#[cfg(doc)]
use crate::{framer::Framer, parser::Parser};
use embedded_io::{Error as _, ErrorKind, Read, ReadReady, Write};

/// Reads until `inbox` yields a frame, handed to `f`.
fn recv_with<R: Read, D: MessageSet, const BUF: usize, const S: usize, T>(
    io: &mut R,
    inbox: &mut Inbox<D, BUF, S>,
    f: impl FnOnce(Received<'_, D>) -> T,
) -> Result<T, RecvError<R::Error>> {
    let mut f = f;
    loop {
        f = match inbox.take(f) {
            Ok(t) => return Ok(t),
            Err(f) => f,
        };
        read(io, inbox)?;
    }
}

/// As [`recv_with`], reading only while the reader says bytes wait.
fn try_recv_with<R: Read + ReadReady, D: MessageSet, const BUF: usize, const S: usize, T>(
    io: &mut R,
    inbox: &mut Inbox<D, BUF, S>,
    f: impl FnOnce(Received<'_, D>) -> T,
) -> Result<Option<T>, RecvError<R::Error>> {
    let mut f = f;
    loop {
        f = match inbox.take(f) {
            Ok(t) => return Ok(Some(t)),
            Err(f) => f,
        };
        if !io.read_ready().map_err(RecvError::Read)? {
            return Ok(None);
        }
        read(io, inbox)?;
    }
}

/// One read into the inbox's free buffer.
fn read<R: Read, D: MessageSet, const BUF: usize, const S: usize>(
    io: &mut R,
    inbox: &mut Inbox<D, BUF, S>,
) -> Result<(), RecvError<R::Error>> {
    match io.read(inbox.space()) {
        Ok(0) => Err(RecvError::Eof),
        Ok(n) => {
            inbox.received(n, None, false);
            Ok(())
        }
        Err(e) => Err(RecvError::Read(e)),
    }
}

/// Writes all of `bytes`: again after a short write or `Interrupted`; a
/// write of 0 bytes is an error (embedded-io's `write_all` panics).
fn write_all<W: Write>(io: &mut W, mut bytes: &[u8]) -> Result<(), SendError<W::Error>> {
    while !bytes.is_empty() {
        match io.write(bytes) {
            Ok(0) => return Err(SendError::WriteZero),
            // A writer claiming more than it was given wrote it all.
            Ok(n) => bytes = bytes.get(n..).unwrap_or_default(),
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(SendError::Write(e)),
        }
    }
    Ok(())
}

/// MAVLink over one blocking `Read + Write` (a UART): receives frames with
/// the crate's [`Parser`] and sends messages framed by a [`Framer`] as
/// system `sysid`, component `compid`.
///
/// `BUF` is the read buffer (one read fills at most that much), `STREAMS`
/// the parser's signing streams. See the [module docs](super) for what
/// happens on partial reads and writes, read errors and end of stream.
///
/// ```
/// # use mavframe::{BufferTooSmall, MessageSet, MessageData, MessageMeta};
/// # #[derive(Clone, Debug, PartialEq, Default)] struct Ping(u8);
/// # impl MessageData for Ping {
/// #   const META: MessageMeta = MessageMeta::new(4, "PING", 237, 1, 1, &[]);
/// #   type View<'a> = u8;
/// #   fn parse(p: &[u8]) -> Self { Ping(p.first().copied().unwrap_or(0)) }
/// #   fn emit(&self, p: &mut [u8]) -> Result<usize, BufferTooSmall> {
/// #     *p.first_mut().ok_or(BufferTooSmall { needed: 1, got: 0 })? = self.0; Ok(1) }
/// #   fn view(p: &[u8]) -> u8 { p.first().copied().unwrap_or(0) }
/// # }
/// # struct MyDialect;
/// # impl MessageSet for MyDialect { type Message = Ping; type View<'a> = u8;
/// #   const MESSAGES: &'static [MessageMeta] = &[Ping::META];
/// #   fn parse(id: u32, p: &[u8]) -> Option<Ping> { (id == 4).then(|| Ping::parse(p)) }
/// #   fn view(id: u32, p: &[u8]) -> Option<u8> { (id == 4).then(|| Ping::view(p)) } }
/// use mavframe::embedded::{embedded_io, Link};
/// use mavframe::{Parser, Signer, Unsigned, Verifier};
///
/// /// A UART wired to itself: what is written is read back, one byte per
/// /// read.
/// struct Loopback { bytes: [u8; 64], len: usize, at: usize }
/// impl embedded_io::ErrorType for Loopback { type Error = core::convert::Infallible; }
/// impl embedded_io::Write for Loopback {
///     fn write(&mut self, buf: &[u8]) -> Result<usize, Self::Error> {
///         let n = buf.len().min(self.bytes.len() - self.len);
///         self.bytes[self.len..self.len + n].copy_from_slice(&buf[..n]);
///         self.len += n;
///         Ok(n)
///     }
///     fn flush(&mut self) -> Result<(), Self::Error> { Ok(()) }
/// }
/// impl embedded_io::Read for Loopback {
///     fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
///         let n = buf.len().min(self.len - self.at).min(1);
///         buf[..n].copy_from_slice(&self.bytes[self.at..self.at + n]);
///         self.at += n;
///         Ok(n)
///     }
/// }
///
/// let key = [42u8; 32];
/// // A verifier that refuses unsigned frames; its notion of now starts at a
/// // timestamp kept across restarts (no clock on this board).
/// let parser = Parser::with_signing(Verifier::with_timestamp(key, 1_000), Unsigned::Refuse);
/// let uart = Loopback { bytes: [0; 64], len: 0, at: 0 };
/// let mut link: Link<_, MyDialect> = Link::with_parts(uart, parser, Default::default(), 1, 191);
/// link.framer_mut().set_signer(Some(Signer::new(key, 0, 2_000)));
///
/// link.send(&Ping(7))?;
/// let frame = link.recv()?;
/// assert!(frame.is_authenticated());
/// assert_eq!((frame.message(), frame.header().compid), (Some(Ping(7)), 191));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub type Link<T, D, const BUF: usize = DEFAULT_BUF, const STREAMS: usize = 16> =
    LinkOf<Blocking, T, D, BUF, STREAMS>;

impl<T: Read, D: MessageSet, const BUF: usize, const STREAMS: usize>
    LinkOf<Blocking, T, D, BUF, STREAMS>
{
    /// Waits for the next frame and returns a copy of it.
    pub fn recv(&mut self) -> Result<ReceivedBuf<D>, RecvError<T::Error>> {
        self.recv_with(|r| ReceivedBuf::from(&r))
    }

    /// Waits for the next frame and hands it to `f` in place (a view over
    /// the read buffer or the parser's, no copy); returns what `f` returns.
    pub fn recv_with<U>(
        &mut self,
        f: impl FnOnce(Received<'_, D>) -> U,
    ) -> Result<U, RecvError<T::Error>> {
        recv_with(&mut self.io, &mut self.core.inbox, f)
    }
}

impl<T: Read + ReadReady, D: MessageSet, const BUF: usize, const STREAMS: usize>
    LinkOf<Blocking, T, D, BUF, STREAMS>
{
    /// The next frame if the bytes waiting make one, without blocking:
    /// reads only while the reader is ready, `Ok(None)` once it is not.
    pub fn try_recv(&mut self) -> Result<Option<ReceivedBuf<D>>, RecvError<T::Error>> {
        self.try_recv_with(|r| ReceivedBuf::from(&r))
    }

    /// [`try_recv`](Self::try_recv), handing the frame to `f` in place.
    pub fn try_recv_with<U>(
        &mut self,
        f: impl FnOnce(Received<'_, D>) -> U,
    ) -> Result<Option<U>, RecvError<T::Error>> {
        try_recv_with(&mut self.io, &mut self.core.inbox, f)
    }
}

impl<T: Write, D: MessageSet, const BUF: usize, const STREAMS: usize>
    LinkOf<Blocking, T, D, BUF, STREAMS>
{
    /// Frames `msg` (next sequence number, signed if the framer has a
    /// signer, no earlier than what the link's verifier accepted: see
    /// [`Framer::adopt_from`]) and writes the whole frame. Does not flush.
    pub fn send(&mut self, msg: &(impl Encode + ?Sized)) -> Result<(), SendError<T::Error>> {
        self.core.adopt();
        let frame = self.core.framer.frame(self.sysid, self.compid, msg);
        write_all(&mut self.io, frame.map_err(SendError::Frame)?)
    }

    /// Writes a frame's bytes as they are (to forward a received frame:
    /// [`ReceivedBuf::as_bytes`]).
    pub fn send_frame(&mut self, frame: &[u8]) -> Result<(), SendError<T::Error>> {
        write_all(&mut self.io, frame)
    }

    /// Waits until the writer's buffered bytes are out.
    pub fn flush(&mut self) -> Result<(), SendError<T::Error>> {
        self.io.flush().map_err(SendError::Write)
    }
}

/// The receiving half: MAVLink frames from a blocking `Read` (a UART's
/// `Rx`), through the crate's [`Parser`]. The same as [`Link`]'s receive
/// side; see the [module docs](super) for an example.
pub type Receiver<R, D, const BUF: usize = DEFAULT_BUF, const STREAMS: usize = 16> =
    ReceiverOf<Blocking, R, D, BUF, STREAMS>;

impl<R: Read, D: MessageSet, const BUF: usize, const STREAMS: usize>
    ReceiverOf<Blocking, R, D, BUF, STREAMS>
{
    /// As [`Link::recv`].
    pub fn recv(&mut self) -> Result<ReceivedBuf<D>, RecvError<R::Error>> {
        self.recv_with(|r| ReceivedBuf::from(&r))
    }

    /// As [`Link::recv_with`].
    pub fn recv_with<U>(
        &mut self,
        f: impl FnOnce(Received<'_, D>) -> U,
    ) -> Result<U, RecvError<R::Error>> {
        recv_with(&mut self.io, &mut self.inbox, f)
    }
}

impl<R: Read + ReadReady, D: MessageSet, const BUF: usize, const STREAMS: usize>
    ReceiverOf<Blocking, R, D, BUF, STREAMS>
{
    /// As [`Link::try_recv`].
    pub fn try_recv(&mut self) -> Result<Option<ReceivedBuf<D>>, RecvError<R::Error>> {
        self.try_recv_with(|r| ReceivedBuf::from(&r))
    }

    /// As [`Link::try_recv_with`].
    pub fn try_recv_with<U>(
        &mut self,
        f: impl FnOnce(Received<'_, D>) -> U,
    ) -> Result<Option<U>, RecvError<R::Error>> {
        try_recv_with(&mut self.io, &mut self.inbox, f)
    }
}

/// The sending half: messages framed by a [`Framer`] (sequence numbers,
/// signing) as system `sysid`, component `compid`, written whole to a
/// blocking `Write` (a UART's `Tx`). The same as [`Link`]'s send side;
/// see the [module docs](super) for an example.
pub type Sender<W> = SenderOf<Blocking, W>;

impl<W: Write> SenderOf<Blocking, W> {
    /// As [`Link::send`].
    pub fn send(&mut self, msg: &(impl Encode + ?Sized)) -> Result<(), SendError<W::Error>> {
        let frame = self.framer.frame(self.sysid, self.compid, msg);
        write_all(&mut self.io, frame.map_err(SendError::Frame)?)
    }

    /// As [`Link::send_frame`].
    pub fn send_frame(&mut self, frame: &[u8]) -> Result<(), SendError<W::Error>> {
        write_all(&mut self.io, frame)
    }

    /// As [`Link::flush`].
    pub fn flush(&mut self) -> Result<(), SendError<W::Error>> {
        self.io.flush().map_err(SendError::Write)
    }
}
