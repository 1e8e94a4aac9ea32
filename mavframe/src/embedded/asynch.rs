//! The async adapters, over `embedded_io_async::{Read, Write}`: the
//! blocking ones' twins (same state, same rules), awaiting instead of
//! blocking.

use super::parts::{Async, LinkOf, ReceiverOf, SenderOf};
use super::{Inbox, RecvError, SendError, DEFAULT_BUF};
use crate::message::{Encode, MessageSet};
use crate::parser::Received;
use crate::received::ReceivedBuf;
#[cfg(doc)]
use crate::{framer::Framer, parser::Parser};
use core::future::Future;
use core::pin::Pin;
use core::task::{Context, Poll};
use embedded_io_async::{Error as _, ErrorKind, Read, Write};

/// Bytes a receive reads without a frame before it lets the executor run
/// other tasks once: a reader that is always ready (a flood of garbage at
/// line rate into a large driver buffer) must not starve them.
pub(super) const YIELD_AFTER: usize = 1024;

/// Pending once (after waking its task), then ready: a turn for the other
/// tasks, on any executor.
struct YieldNow(bool);

impl Future for YieldNow {
    type Output = ();

    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        if self.0 {
            return Poll::Ready(());
        }
        self.0 = true;
        cx.waker().wake_by_ref();
        Poll::Pending
    }
}

/// Reads until `inbox` yields a frame, handed to `f`. Cancel-safe as far
/// as the adapter goes: the inbox changes only between awaits.
async fn recv_with<R: Read, D: MessageSet, const BUF: usize, const S: usize, T>(
    io: &mut R,
    inbox: &mut Inbox<D, BUF, S>,
    f: impl FnOnce(Received<'_, D>) -> T,
) -> Result<T, RecvError<R::Error>> {
    let mut f = f;
    let mut unproductive = 0;
    loop {
        f = match inbox.take(f) {
            Ok(t) => return Ok(t),
            Err(f) => f,
        };
        if unproductive >= YIELD_AFTER {
            YieldNow(false).await;
            unproductive = 0;
        }
        match io.read(inbox.space()).await {
            Ok(0) => return Err(RecvError::Eof),
            Ok(n) => {
                inbox.received(n, None, false);
                unproductive += n;
            }
            Err(e) => return Err(RecvError::Read(e)),
        }
    }
}

/// Writes all of `bytes`, as the blocking adapters' `write_all` does.
async fn write_all<W: Write>(io: &mut W, mut bytes: &[u8]) -> Result<(), SendError<W::Error>> {
    while !bytes.is_empty() {
        match io.write(bytes).await {
            Ok(0) => return Err(SendError::WriteZero),
            Ok(n) => bytes = bytes.get(n..).unwrap_or_default(),
            Err(e) if e.kind() == ErrorKind::Interrupted => {}
            Err(e) => return Err(SendError::Write(e)),
        }
    }
    Ok(())
}

/// MAVLink over one async `Read + Write` (an async UART): the async twin
/// of [`Link`](super::Link), with the same constructors and rules.
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
/// # /// The smallest executor: polls until ready (these futures never wait).
/// # fn block_on<F: core::future::Future>(f: F) -> F::Output {
/// #     let mut f = core::pin::pin!(f);
/// #     let mut cx = core::task::Context::from_waker(core::task::Waker::noop());
/// #     loop { if let core::task::Poll::Ready(v) = f.as_mut().poll(&mut cx) { return v; } }
/// # }
/// use mavframe::embedded::{AsyncReceiver, AsyncSender};
///
/// # block_on(async {
/// // embedded-io-async implements `Write` for `&mut [u8]`, `Read` for `&[u8]`.
/// let mut wire = [0u8; 32];
/// let mut tx = AsyncSender::new(&mut wire[..], 1, 191);
/// tx.send(&Ping(9)).await?;
///
/// let mut rx = AsyncReceiver::<_, MyDialect>::new(&wire[..]);
/// let value = rx.recv_with(|frame| frame.view()).await?;
/// assert_eq!(value, Some(9));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// # }).unwrap();
/// ```
pub type AsyncLink<T, D, const BUF: usize = DEFAULT_BUF, const STREAMS: usize = 16> =
    LinkOf<Async, T, D, BUF, STREAMS>;

impl<T: Read, D: MessageSet, const BUF: usize, const STREAMS: usize>
    LinkOf<Async, T, D, BUF, STREAMS>
{
    /// Waits for the next frame and returns a copy of it.
    pub async fn recv(&mut self) -> Result<ReceivedBuf<D>, RecvError<T::Error>> {
        self.recv_with(|r| ReceivedBuf::from(&r)).await
    }

    /// Waits for the next frame and hands it to `f` in place; returns what
    /// `f` returns.
    pub async fn recv_with<U>(
        &mut self,
        f: impl FnOnce(Received<'_, D>) -> U,
    ) -> Result<U, RecvError<T::Error>> {
        recv_with(&mut self.io, &mut self.core.inbox, f).await
    }
}

impl<T: Write, D: MessageSet, const BUF: usize, const STREAMS: usize>
    LinkOf<Async, T, D, BUF, STREAMS>
{
    /// As [`Link::send`](super::Link::send).
    pub async fn send(&mut self, msg: &(impl Encode + ?Sized)) -> Result<(), SendError<T::Error>> {
        self.core.adopt();
        let frame = self.core.framer.frame(self.sysid, self.compid, msg);
        write_all(&mut self.io, frame.map_err(SendError::Frame)?).await
    }

    /// As [`Link::send_frame`](super::Link::send_frame).
    pub async fn send_frame(&mut self, frame: &[u8]) -> Result<(), SendError<T::Error>> {
        write_all(&mut self.io, frame).await
    }

    /// Waits until the writer's buffered bytes are out.
    pub async fn flush(&mut self) -> Result<(), SendError<T::Error>> {
        self.io.flush().await.map_err(SendError::Write)
    }
}

/// The receiving half over an async `Read` (an async UART's `Rx`): the
/// async twin of [`Receiver`](super::Receiver).
pub type AsyncReceiver<R, D, const BUF: usize = DEFAULT_BUF, const STREAMS: usize = 16> =
    ReceiverOf<Async, R, D, BUF, STREAMS>;

impl<R: Read, D: MessageSet, const BUF: usize, const STREAMS: usize>
    ReceiverOf<Async, R, D, BUF, STREAMS>
{
    /// As [`AsyncLink::recv`].
    pub async fn recv(&mut self) -> Result<ReceivedBuf<D>, RecvError<R::Error>> {
        self.recv_with(|r| ReceivedBuf::from(&r)).await
    }

    /// As [`AsyncLink::recv_with`].
    pub async fn recv_with<U>(
        &mut self,
        f: impl FnOnce(Received<'_, D>) -> U,
    ) -> Result<U, RecvError<R::Error>> {
        recv_with(&mut self.io, &mut self.inbox, f).await
    }
}

/// The sending half over an async `Write` (an async UART's `Tx`): the
/// async twin of [`Sender`](super::Sender).
pub type AsyncSender<W> = SenderOf<Async, W>;

impl<W: Write> SenderOf<Async, W> {
    /// As [`AsyncLink::send`].
    pub async fn send(&mut self, msg: &(impl Encode + ?Sized)) -> Result<(), SendError<W::Error>> {
        let frame = self.framer.frame(self.sysid, self.compid, msg);
        write_all(&mut self.io, frame.map_err(SendError::Frame)?).await
    }

    /// As [`AsyncLink::send_frame`].
    pub async fn send_frame(&mut self, frame: &[u8]) -> Result<(), SendError<W::Error>> {
        write_all(&mut self.io, frame).await
    }

    /// As [`AsyncLink::flush`].
    pub async fn flush(&mut self) -> Result<(), SendError<W::Error>> {
        self.io.flush().await.map_err(SendError::Write)
    }
}
