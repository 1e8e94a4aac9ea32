//! The adapters against UART-like readers and writers: any chunking,
//! garbage, read errors and lost bytes, end of stream, short and refused
//! writes, signing, readiness, and the async twins.

extern crate std;

// The hand-written dialect of conn's tests; conn needs std, these tests do
// not, so the file is compiled here again.
#[allow(clippy::duplicate_mod)]
#[path = "../conn/test_dialect.rs"]
mod test_dialect;

use super::*;
use crate::frame::{Version, IFLAG_SIGNED};
use crate::framer::Framer;
use crate::parser::Unsigned;
use crate::signing::{Signer, Verifier};
use core::cell::RefCell;
use embedded_io::{ErrorKind, ErrorType, Read, ReadReady, Write};
use std::collections::VecDeque;
use std::rc::Rc;
use std::string::ToString;
use std::vec::Vec;
use test_dialect::{Big, Ping, TestDialect};

/// A UART fault, as a HAL reports one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    Overrun,
    Interrupted,
    TxBroken,
}

impl fmt::Display for Fault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{self:?}")
    }
}

impl core::error::Error for Fault {}

impl embedded_io::Error for Fault {
    fn kind(&self) -> ErrorKind {
        match self {
            Fault::Interrupted => ErrorKind::Interrupted,
            Fault::Overrun | Fault::TxBroken => ErrorKind::Other,
        }
    }
}

/// Bytes delivered at most `chunk` per read; optionally one error when
/// the reader reaches `fail_at`; `Ok(0)` at the end.
struct Chunked {
    bytes: Vec<u8>,
    at: usize,
    chunk: usize,
    fail_at: Option<usize>,
    /// Claim `overclaim` more bytes than were copied (a buggy driver).
    overclaim: usize,
    reads: usize,
}

impl Chunked {
    fn new(bytes: &[u8], chunk: usize) -> Self {
        Chunked {
            bytes: bytes.to_vec(),
            at: 0,
            chunk,
            fail_at: None,
            overclaim: 0,
            reads: 0,
        }
    }
}

impl ErrorType for Chunked {
    type Error = Fault;
}

impl Read for Chunked {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Fault> {
        self.reads += 1;
        let mut end = self.bytes.len().min(self.at + self.chunk);
        if let Some(fail) = self.fail_at {
            if self.at == fail {
                self.fail_at = None;
                return Err(Fault::Overrun);
            }
            if (self.at..end).contains(&fail) {
                end = fail;
            }
        }
        let n = (end - self.at).min(buf.len());
        buf[..n].copy_from_slice(&self.bytes[self.at..self.at + n]);
        self.at += n;
        Ok(if n > 0 { n + self.overclaim } else { 0 })
    }
}

/// A writer taking at most `max` bytes per write, failing with
/// `Interrupted` every `interrupt_every`-th call, and taking nothing (or
/// failing) once `stop_after` bytes are in.
struct Trickle {
    out: Vec<u8>,
    max: usize,
    calls: usize,
    interrupt_every: usize,
    stop_after: Option<(usize, Option<Fault>)>,
}

impl Trickle {
    fn new(max: usize) -> Self {
        Trickle {
            out: Vec::new(),
            max,
            calls: 0,
            interrupt_every: 0,
            stop_after: None,
        }
    }
}

impl ErrorType for Trickle {
    type Error = Fault;
}

impl Write for Trickle {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Fault> {
        self.calls += 1;
        if self.interrupt_every > 0 && self.calls % self.interrupt_every == 0 {
            return Err(Fault::Interrupted);
        }
        let mut n = buf.len().min(self.max);
        if let Some((limit, fault)) = self.stop_after {
            if self.out.len() >= limit {
                return fault.map_or(Ok(0), Err);
            }
            n = n.min(limit - self.out.len());
        }
        self.out.extend_from_slice(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), Fault> {
        Ok(())
    }
}

/// One end of a serial line wired to another: writes go to the peer's
/// queue; reads take from ours, at most `chunk` bytes, `Ok(0)` when empty.
/// `ready` (for `ReadReady`) is whether bytes wait.
#[derive(Clone)]
struct Wire {
    rx: Rc<RefCell<VecDeque<u8>>>,
    tx: Rc<RefCell<VecDeque<u8>>>,
    chunk: usize,
}

fn wire_pair(chunk: usize) -> (Wire, Wire) {
    let (a, b) = (Rc::default(), Rc::default());
    (
        Wire {
            rx: Rc::clone(&a),
            tx: Rc::clone(&b),
            chunk,
        },
        Wire {
            rx: b,
            tx: a,
            chunk,
        },
    )
}

impl ErrorType for Wire {
    type Error = Fault;
}

impl Read for Wire {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Fault> {
        let mut rx = self.rx.borrow_mut();
        let n = rx.len().min(buf.len()).min(self.chunk);
        for (slot, b) in buf.iter_mut().zip(rx.drain(..n)) {
            *slot = b;
        }
        Ok(n)
    }
}

impl ReadReady for Wire {
    fn read_ready(&mut self) -> Result<bool, Fault> {
        Ok(!self.rx.borrow().is_empty())
    }
}

impl Write for Wire {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Fault> {
        let n = buf.len().min(self.chunk);
        self.tx.borrow_mut().extend(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), Fault> {
        Ok(())
    }
}

/// Frames `pings` values (seq 0, 1, …) from system 1, component 2.
fn ping_frames(framer: &mut Framer, values: &[u32]) -> Vec<Vec<u8>> {
    values
        .iter()
        .map(|&value| framer.frame(1, 2, &Ping { value }).unwrap().to_vec())
        .collect()
}

/// A deterministic byte generator (xorshift32).
fn noise(seed: u32, len: usize) -> Vec<u8> {
    let mut x = seed.max(1);
    (0..len)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as u8
        })
        .collect()
}

/// Receives until `Eof`: (value, seq) of every known frame.
fn drain<R: Read, const BUF: usize>(rx: &mut Receiver<R, TestDialect, BUF>) -> Vec<(u32, u8)> {
    drain_counting_raw(rx).0
}

/// As [`drain`], with the bytes of raw frames (unknown ids) returned.
fn drain_counting_raw<R: Read, const BUF: usize>(
    rx: &mut Receiver<R, TestDialect, BUF>,
) -> (Vec<(u32, u8)>, usize) {
    let (mut got, mut raw) = (Vec::new(), 0);
    loop {
        let next = rx.recv_with(|r| match r.message() {
            Some(m) => Ok((m.value, r.frame().header().seq)),
            None => Err(r.frame().as_bytes().len()),
        });
        match next {
            Ok(Ok(ping)) => got.push(ping),
            Ok(Err(len)) => raw += len,
            Err(RecvError::Eof) => return (got, raw),
            Err(e) => panic!("{e:?}"),
        }
    }
}

#[test]
fn frames_come_out_whole_in_any_chunking_with_garbage_between() {
    let values = [1, 0xdead_beef, 0, 77, u32::MAX];
    let frames = ping_frames(&mut Framer::new(), &values);
    // Garbage with start bytes in it before, between and after the frames.
    let mut stream = b"\xfd\xfe\x00junk\xfd\x05".to_vec();
    let mut garbage = stream.len();
    for (i, f) in frames.iter().enumerate() {
        stream.extend_from_slice(f);
        let g = noise(i as u32 + 1, 3 + 11 * i);
        garbage += g.len();
        stream.extend_from_slice(&g);
    }
    let expected: Vec<(u32, u8)> = values.iter().zip(0..).map(|(&v, s)| (v, s)).collect();
    for chunk in 1..=stream.len() {
        let mut one = Receiver::<_, TestDialect, 1>::new(Chunked::new(&stream, chunk));
        assert_eq!(drain(&mut one), expected, "1-byte buffer, chunk {chunk}");
        let mut rx = Receiver::<_, TestDialect>::new(Chunked::new(&stream, chunk));
        let (got, raw) = drain_counting_raw(&mut rx);
        assert_eq!(got, expected, "chunk {chunk}");
        let stats = rx.parser().stats();
        assert_eq!(stats.frames, values.len() as u64);
        // Every garbage byte is dropped, or (start bytes in the noise,
        // confirmed by chance) returned as a raw frame; none is taken from
        // a good frame.
        assert_eq!(
            stats.bytes_dropped + raw as u64,
            garbage as u64,
            "chunk {chunk}: {stats:?}"
        );
    }
}

#[test]
fn a_read_error_is_returned_typed_and_nothing_held_is_lost() {
    let frames = ping_frames(&mut Framer::new(), &[10, 20, 30]);
    let stream = frames.concat();
    // The error strikes in the middle of the second frame.
    let fail_at = frames[0].len() + 5;
    for chunk in [1, 3, 64] {
        let mut reader = Chunked::new(&stream, chunk);
        reader.fail_at = Some(fail_at);
        let mut rx = Receiver::<_, TestDialect, 8>::new(reader);
        assert_eq!(rx.recv().unwrap().message(), Some(Ping { value: 10 }));
        let err = rx.recv().unwrap_err();
        assert_eq!(err, RecvError::Read(Fault::Overrun));
        // Typed, and a `core::error::Error` whose source is the driver's.
        let source = core::error::Error::source(&err).unwrap();
        assert_eq!(source.downcast_ref::<Fault>(), Some(&Fault::Overrun));
        assert_eq!(err.to_string(), "reading from the link failed");
        // The bytes of frame 2 read before the error were kept.
        assert_eq!(drain(&mut rx), [(20, 1), (30, 2)], "chunk {chunk}");
    }
}

/// An overrun loses bytes inside a frame: that frame fails its checksum,
/// the parser resynchronises, and the frames around it come through.
#[test]
fn bytes_lost_by_the_uart_cost_only_their_frame() {
    let frames = ping_frames(&mut Framer::new(), &[1, 2, 3]);
    let mut stream = frames.concat();
    let lost = frames[0].len() + 6..frames[0].len() + 9;
    stream.drain(lost);
    for chunk in [1, 2, 5, 64] {
        let mut rx = Receiver::<_, TestDialect, 16>::new(Chunked::new(&stream, chunk));
        assert_eq!(drain(&mut rx), [(1, 0), (3, 2)], "chunk {chunk}");
        assert_eq!(rx.parser().stats().seq_lost, 1);
    }
}

#[test]
fn end_of_stream_then_recv_eof_confirms_a_trailing_raw_frame() {
    let mut framer = Framer::new();
    let mut stream = ping_frames(&mut framer, &[5]).concat();
    // A frame of id 42, which the dialect does not know: it is returned raw
    // once the byte after it shows a start byte, or the stream ends.
    stream.extend_from_slice(b"\xfd\x01\x00\x00\x07\x01\x01\x2a\x00\x00\x09\x12\x34");
    let mut rx = Receiver::<_, TestDialect>::new(Chunked::new(&stream, 4));
    assert_eq!(rx.recv().unwrap().message(), Some(Ping { value: 5 }));
    assert_eq!(rx.recv().unwrap_err(), RecvError::Eof);
    let raw = rx.recv_eof().expect("the raw frame");
    assert_eq!((raw.msg_id(), raw.meta().is_none()), (42, true));
    assert!(rx.recv_eof().is_none());
    // Still usable: the reader stays at its end.
    assert_eq!(rx.recv().unwrap_err(), RecvError::Eof);
}

#[test]
fn a_reader_claiming_more_than_it_read_does_not_panic() {
    let stream = ping_frames(&mut Framer::new(), &[1, 2]).concat();
    let mut reader = Chunked::new(&stream, 3);
    reader.overclaim = 1000;
    let mut rx = Receiver::<_, TestDialect, 4>::new(reader);
    // The claimed bytes are whatever the buffer held: nothing panics, the
    // parser sees at most the buffer, and the stream ends.
    let mut n = 0;
    while rx.recv().is_ok() {
        n += 1;
        assert!(n < 10);
    }
    assert!(rx.get_ref().reads > 0);
}

#[test]
fn short_and_interrupted_writes_send_the_whole_frame() {
    let mut expected_framer = Framer::new();
    let expected = ping_frames(&mut expected_framer, &[1, 2, 3]).concat();
    for max in 1..=7 {
        let mut writer = Trickle::new(max);
        writer.interrupt_every = 3;
        let mut tx = Sender::new(writer, 1, 2);
        for value in [1, 2, 3] {
            tx.send(&Ping { value }).unwrap();
        }
        assert_eq!(tx.get_ref().out, expected, "max {max}");
    }
}

#[test]
fn a_writer_that_takes_nothing_or_fails_gives_a_typed_error() {
    let mut writer = Trickle::new(4);
    writer.stop_after = Some((6, None));
    let mut tx = Sender::new(writer, 1, 2);
    assert_eq!(tx.send(&Ping { value: 1 }), Err(SendError::WriteZero));
    assert_eq!(tx.get_ref().out.len(), 6, "the frame was cut short");

    let mut writer = Trickle::new(4);
    writer.stop_after = Some((6, Some(Fault::TxBroken)));
    let mut tx = Sender::new(writer, 1, 2);
    let err = tx.send(&Ping { value: 1 }).unwrap_err();
    assert_eq!(err, SendError::Write(Fault::TxBroken));
    let source = core::error::Error::source(&err).unwrap();
    assert_eq!(source.downcast_ref::<Fault>(), Some(&Fault::TxBroken));
    // The sequence number moved on: the receiver counts the frame lost.
    assert_eq!(tx.framer().seq(), 1);
}

#[test]
fn a_message_mavlink1_cannot_carry_is_refused_before_writing() {
    let mut tx = Sender::new(Trickle::new(64), 1, 2);
    tx.framer_mut().set_version(Version::V1);
    let err = tx.send(&Big { value: 1 }).unwrap_err();
    assert_eq!(
        err,
        SendError::Frame(crate::FrameError::IdTooLargeForV1(300))
    );
    assert!(err.to_string().contains("300"));
    assert!(tx.get_ref().out.is_empty());
    // MAVLink 1 frames go out and come back.
    tx.send(&Ping { value: 9 }).unwrap();
    let mut rx = Receiver::<_, TestDialect>::new(Chunked::new(&tx.get_ref().out, 64));
    assert_eq!(rx.recv().unwrap().frame().version(), Version::V1);
}

/// A link with signing on both sides: a signed key holder's frames are
/// authenticated; a replay, a wrong key and unsigned frames are refused.
fn signed_link(wire: Wire, key: [u8; 32], link_id: u8, sysid: u8) -> Link<Wire, TestDialect> {
    // No clock on the board: the verifier starts from a saved timestamp.
    let parser = Parser::with_signing(Verifier::with_timestamp(key, 50_000), Unsigned::Refuse);
    let mut framer = Framer::new();
    framer.set_clock(None);
    framer.set_signer(Some(Signer::new(key, link_id, 60_000)));
    Link::with_parts(wire, parser, framer, sysid, 1)
}

#[test]
fn signing_round_trip_and_refusals_over_a_link() {
    let key = [0x5a; 32];
    let (a, b) = wire_pair(3);
    // Whoever else is on the line towards `cc` writes where `fc` does.
    let mut attacker = Sender::new(a.clone(), 9, 9);
    let mut fc = signed_link(a, key, 1, 1);
    let mut cc = signed_link(b, key, 2, 191);

    fc.send(&Ping { value: 7 }).unwrap();
    let got = cc.recv().unwrap();
    assert!(got.is_authenticated());
    assert_eq!(got.frame().incompat_flags() & IFLAG_SIGNED, IFLAG_SIGNED);
    assert_eq!(got.message(), Some(Ping { value: 7 }));
    cc.send(&Ping { value: 8 }).unwrap();
    assert!(fc.recv().unwrap().is_authenticated());

    // A replay of the captured frame, injected on the line.
    attacker.send_frame(got.as_bytes()).unwrap();
    assert_eq!(cc.recv().unwrap_err(), RecvError::Eof);
    assert_eq!(cc.parser().stats().stale_timestamp, 1);

    // A frame signed with another key, and an unsigned one.
    let mut forger = Framer::new();
    forger.set_signer(Some(Signer::new([1; 32], 1, 70_000)));
    attacker
        .send_frame(forger.frame(1, 1, &Ping::default()).unwrap())
        .unwrap();
    attacker.send(&Ping::default()).unwrap();
    assert_eq!(cc.recv().unwrap_err(), RecvError::Eof);
    // The line is quiet: decide what is held (bytes of the refused
    // signature block may have started a candidate frame).
    assert!(cc.recv_eof().is_none());
    let stats = cc.parser().stats();
    assert_eq!((stats.bad_signature, stats.unsigned_rejected), (1, 1));

    // The real sender still gets through.
    fc.send(&Ping { value: 9 }).unwrap();
    assert_eq!(cc.recv().unwrap().message(), Some(Ping { value: 9 }));
}

/// Two boards without clocks whose signers start far apart: the one
/// behind adopts the timestamp of the first frame it verified from the one
/// ahead, so its next frame is accepted by it (a new stream more than a
/// minute behind what the one ahead saw would be refused as stale).
#[test]
fn a_link_signs_at_the_newest_timestamp_it_verified() {
    let key = [0x5a; 32];
    let (a, b) = wire_pair(5);
    let mut ahead = signed_link(a, key, 1, 1);
    let mut behind = signed_link(b, key, 2, 191);
    ahead
        .framer_mut()
        .set_signer(Some(Signer::new(key, 1, 90_000_000)));
    ahead.send(&Ping { value: 1 }).unwrap();
    assert!(behind.recv().unwrap().is_authenticated());
    behind.send(&Ping { value: 2 }).unwrap();
    let got = ahead.recv().unwrap();
    assert!(got.is_authenticated());
    assert!(got.frame().signature().unwrap().timestamp() >= 90_000_000);
    assert_eq!(ahead.parser().stats().stale_timestamp, 0);
}

#[test]
fn try_recv_reads_only_while_bytes_wait() {
    let (a, b) = wire_pair(2);
    let mut tx = Link::<_, TestDialect>::new(a, 1, 1);
    let mut rx = Link::<_, TestDialect>::new(b, 2, 1);
    assert!(rx.try_recv().unwrap().is_none(), "nothing waiting");
    let frame = ping_frames(&mut Framer::new(), &[4]).concat();
    // Half a frame: read, held, no frame yet.
    tx.send_frame(&frame[..7]).unwrap();
    assert!(rx.try_recv().unwrap().is_none());
    assert!(rx.get_ref().rx.borrow().is_empty(), "what waited was read");
    tx.send_frame(&frame[7..]).unwrap();
    let got = rx.try_recv_with(|r| r.message()).unwrap();
    assert_eq!(got, Some(Some(Ping { value: 4 })));
    assert!(rx.try_recv().unwrap().is_none());
}

// --- async ---

/// Runs a future to completion by polling it: enough for futures that
/// wake themselves (as every one here does).
#[cfg(feature = "embedded-io-async")]
fn block_on<F: core::future::Future>(f: F) -> F::Output {
    let mut f = core::pin::pin!(f);
    let mut cx = core::task::Context::from_waker(core::task::Waker::noop());
    let mut polls = 0;
    loop {
        if let core::task::Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
        polls += 1;
        assert!(polls < 1_000_000, "the future never finished");
    }
}

/// Pending once, then ready: an I/O operation that has to wait.
#[cfg(feature = "embedded-io-async")]
struct WaitOnce(bool);

#[cfg(feature = "embedded-io-async")]
impl core::future::Future for WaitOnce {
    type Output = ();
    fn poll(
        mut self: core::pin::Pin<&mut Self>,
        cx: &mut core::task::Context<'_>,
    ) -> core::task::Poll<()> {
        if self.0 {
            return core::task::Poll::Ready(());
        }
        self.0 = true;
        cx.waker().wake_by_ref();
        core::task::Poll::Pending
    }
}

/// The async wire: every read and write waits once, then acts as
/// [`Wire`] does.
#[cfg(feature = "embedded-io-async")]
impl embedded_io_async::Read for Wire {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Fault> {
        WaitOnce(false).await;
        Read::read(self, buf)
    }
}

#[cfg(feature = "embedded-io-async")]
impl embedded_io_async::Write for Wire {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Fault> {
        WaitOnce(false).await;
        Write::write(self, buf)
    }

    async fn flush(&mut self) -> Result<(), Fault> {
        Ok(())
    }
}

#[cfg(feature = "embedded-io-async")]
impl embedded_io_async::Write for Trickle {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Fault> {
        WaitOnce(false).await;
        Write::write(self, buf)
    }

    async fn flush(&mut self) -> Result<(), Fault> {
        Ok(())
    }
}

#[cfg(feature = "embedded-io-async")]
#[test]
fn async_link_round_trip_signed_in_one_byte_steps() {
    let key = [7; 32];
    let (a, b) = wire_pair(1);
    let signed = |wire, link_id| {
        let parser = Parser::with_signing(Verifier::with_timestamp(key, 50_000), Unsigned::Refuse);
        let mut framer = Framer::new();
        framer.set_signer(Some(Signer::new(key, link_id, 60_000)));
        AsyncLink::<_, TestDialect>::with_parts(wire, parser, framer, link_id, 1)
    };
    let (mut fc, mut cc) = (signed(a, 1), signed(b, 2));
    block_on(async {
        for value in 0..5 {
            fc.send(&Ping { value }).await.unwrap();
        }
        for value in 0..5 {
            let got = cc.recv().await.unwrap();
            assert!(got.is_authenticated());
            assert_eq!(got.message(), Some(Ping { value }));
        }
        cc.send(&Ping { value: 99 }).await.unwrap();
        let seq = fc.recv_with(|r| r.frame().header().seq).await.unwrap();
        assert_eq!(seq, 0);
        assert_eq!(fc.recv().await.unwrap_err(), RecvError::Eof);
    });
}

#[cfg(feature = "embedded-io-async")]
#[test]
fn async_halves_handle_short_writes_errors_and_garbage() {
    let frames = ping_frames(&mut Framer::new(), &[1, 2]);
    block_on(async {
        let mut writer = Trickle::new(2);
        writer.interrupt_every = 2;
        let mut tx = AsyncSender::new(writer, 1, 2);
        tx.send(&Ping { value: 1 }).await.unwrap();
        tx.send(&Ping { value: 2 }).await.unwrap();
        assert_eq!(tx.get_ref().out, frames.concat());

        let mut writer = Trickle::new(2);
        writer.stop_after = Some((3, None));
        let mut tx = AsyncSender::new(writer, 1, 2);
        assert_eq!(tx.send(&Ping::default()).await, Err(SendError::WriteZero));

        // Garbage around the frames, read through an async wire.
        let (mut feed, wire) = wire_pair(5);
        Write::write_all(&mut feed, b"\xfd\x00garbage").unwrap();
        Write::write_all(&mut feed, &frames.concat()).unwrap();
        let mut rx = AsyncReceiver::<_, TestDialect, 3>::new(wire);
        assert_eq!(rx.recv().await.unwrap().message(), Some(Ping { value: 1 }));
        let value = rx.recv_with(|r| r.message().map(|m| m.value)).await;
        assert_eq!(value, Ok(Some(2)));
        assert_eq!(rx.recv().await.unwrap_err(), RecvError::Eof);
        assert_eq!(rx.parser().stats().bytes_dropped, 9);
    });
}

/// An async reader that is always ready with garbage (a flood into a large
/// driver buffer), 100 KB of it, then at its end: the receive must give the
/// executor a turn regularly, long before that end.
#[cfg(feature = "embedded-io-async")]
struct Flood {
    read: usize,
}

#[cfg(feature = "embedded-io-async")]
const FLOOD_LEN: usize = 100 * 1024;

#[cfg(feature = "embedded-io-async")]
impl ErrorType for Flood {
    type Error = Fault;
}

#[cfg(feature = "embedded-io-async")]
impl embedded_io_async::Read for Flood {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Fault> {
        let n = buf.len().min(FLOOD_LEN - self.read);
        let buf = &mut buf[..n];
        // Start bytes and junk: candidates to check, never a frame.
        for (i, b) in buf.iter_mut().enumerate() {
            *b = if (self.read + i) % 7 == 0 { 0xfd } else { 0x55 };
        }
        self.read += buf.len();
        Ok(buf.len())
    }
}

#[cfg(feature = "embedded-io-async")]
#[test]
fn an_async_receive_under_a_flood_yields_to_the_executor() {
    use core::future::Future;
    use core::task::{Context, Poll, Waker};
    let mut rx = AsyncReceiver::<_, TestDialect>::new(Flood { read: 0 });
    let mut pendings = 0;
    {
        let mut fut = core::pin::pin!(rx.recv());
        let mut cx = Context::from_waker(Waker::noop());
        for _ in 0..20 {
            match fut.as_mut().poll(&mut cx) {
                Poll::Pending => pendings += 1,
                Poll::Ready(r) => panic!("the receive ran on without a turn for others: {r:?}"),
            }
        }
    }
    assert_eq!(pendings, 20);
    // Each turn came after at most YIELD_AFTER bytes (plus one read).
    let read = rx.get_ref().read;
    assert!(read >= 20 * asynch::YIELD_AFTER, "{read}");
    assert!(read <= 21 * (asynch::YIELD_AFTER + DEFAULT_BUF), "{read}");
    assert_eq!(rx.parser().stats().frames, 0);
}
