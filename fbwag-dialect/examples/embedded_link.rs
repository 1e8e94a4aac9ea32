//! The FBWAG handshake over a UART on a `no_std` board, with mavframe's
//! `embedded-io` adapters: the flight controller (FC) sends a HEARTBEAT and
//! an FBWAG_NOTICE "RC lost", the companion computer (CC) answers "takeover
//! confirmed", every frame signed and every unsigned or replayed frame
//! refused. Then the same with the async adapters.
//!
//! ```text
//! cargo run -p fbwag-dialect --example embedded_link
//! ```
//!
//! So that it runs anywhere, the UART here is [`SerialLine`], an in-memory
//! serial line with a small FIFO (short reads and short writes, as a
//! UART's). On a board, give the adapters your HAL's UART instead: anything
//! implementing `embedded_io::{Read, Write}` (or the async traits). Nothing
//! else in `fc_*` and `cc_*` needs std or a heap. Dependencies:
//!
//! ```toml
//! fbwag-dialect = { version = "0.1", default-features = false, features = ["embedded-io"] }
//! ```

use fbwag_dialect::dialects::minimal::{Heartbeat, MavAutopilot, MavState, MavType};
use fbwag_dialect::mavframe::embedded::{
    embedded_io, embedded_io_async, AsyncLink, Link, RecvError, SendError,
};
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::mavframe::{Framer, Parser, Signer, Unsigned, Verifier};
use fbwag_dialect::{Dialect, FbwagFailsafeStatus, FbwagNotice, MessageView};
use std::cell::RefCell;
use std::collections::VecDeque;
use std::rc::Rc;

/// The shared signing key (from the board's secure storage).
const KEY: [u8; 32] = *b"fbwag example key, 32 bytes long";
/// The last signing timestamp saved before this boot (10 µs units since
/// 2015, 48 bits; this one is in 2026): without a clock, the verifier's
/// notion of now starts there and the signer starts above it, so frames
/// stay newer than any sent before.
const SAVED_TIMESTAMP: u64 = 34_700_000_000_000;

const FC: (u8, u8) = (1, 1);
/// MAV_COMP_ID_ONBOARD_COMPUTER.
const CC: (u8, u8) = (1, 191);

/// A signed link over `uart` for `ids`, signing with `link_id`, refusing
/// unsigned frames.
fn signed_link<T>(uart: T, ids: (u8, u8), link_id: u8) -> Link<T, Dialect> {
    let parser = Parser::with_signing(
        Verifier::with_timestamp(KEY, SAVED_TIMESTAMP),
        Unsigned::Refuse,
    );
    let mut framer = Framer::new();
    // No RTC on this board: timestamps count up from the signer's start.
    framer.set_clock(None);
    framer.set_signer(Some(Signer::new(KEY, link_id, SAVED_TIMESTAMP + 1)));
    Link::with_parts(uart, parser, framer, ids.0, ids.1)
}

fn heartbeat() -> Heartbeat {
    Heartbeat {
        r#type: MavType::FIXED_WING,
        autopilot: MavAutopilot::ARDUPILOTMEGA,
        system_status: MavState::ACTIVE,
        ..Heartbeat::default()
    }
}

fn notice(status: FbwagFailsafeStatus, ids: (u8, u8), timestamp: u32) -> FbwagNotice {
    FbwagNotice {
        system_id: ids.0,
        component_id: ids.1,
        failsafe_status: status,
        text: chars("FBWAG"),
        timestamp,
    }
}

/// The FC on RC loss: its heartbeat, then the notice (`now_ms` since boot
/// identifies the event).
fn fc_report_rc_loss<T: embedded_io::Write>(
    fc: &mut Link<T, Dialect>,
    now_ms: u32,
) -> Result<(), SendError<T::Error>> {
    fc.send(&heartbeat())?;
    fc.send(&notice(FbwagFailsafeStatus::RC_LOST, FC, now_ms))
}

/// The CC: waits for an "RC lost" notice from a system whose heartbeat it
/// saw (reading views in place, no copies), then confirms the takeover,
/// echoing the notice's timestamp. Returns that timestamp.
fn cc_confirm_takeover<T: embedded_io::Read + embedded_io::Write>(
    cc: &mut Link<T, Dialect>,
) -> Result<u32, LinkError<T::Error>> {
    let mut fc_seen = None;
    let rc_lost = loop {
        let event = cc.recv_with(|frame| {
            let from = frame.frame().header();
            match frame.view()? {
                MessageView::Heartbeat(_) => Some(Err((from.sysid, from.compid))),
                MessageView::FbwagNotice(n)
                    if n.failsafe_status() == FbwagFailsafeStatus::RC_LOST =>
                {
                    Some(Ok((from.sysid, n.timestamp())))
                }
                _ => None,
            }
        })?;
        match event {
            Some(Err(ids)) => fc_seen = Some(ids),
            Some(Ok((sysid, timestamp))) if fc_seen.is_some_and(|(s, _)| s == sysid) => {
                break timestamp;
            }
            _ => {}
        }
    };
    let ack = notice(FbwagFailsafeStatus::CC_TAKEOVER_CONFIRMED, CC, rc_lost);
    cc.send(&ack)?;
    Ok(rc_lost)
}

/// The FC: waits for the CC's confirmation of the event `timestamp`.
fn fc_await_confirmation<T: embedded_io::Read>(
    fc: &mut Link<T, Dialect>,
    timestamp: u32,
) -> Result<(), RecvError<T::Error>> {
    loop {
        let frame = fc.recv()?;
        if let Some(fbwag_dialect::Message::FbwagNotice(n)) = frame.message() {
            if n.failsafe_status == FbwagFailsafeStatus::CC_TAKEOVER_CONFIRMED
                && n.timestamp == timestamp
            {
                return Ok(());
            }
        }
    }
}

/// What the exchange showed (for the tests).
#[derive(Debug, PartialEq)]
struct Outcome {
    /// The event's timestamp the CC confirmed.
    confirmed: u32,
    /// Frames each side's parser accepted, and refused for their signing
    /// timestamp (replays).
    cc_frames: u64,
    cc_stale: u64,
    fc_frames: u64,
}

/// The blocking handshake over a serial line with a `fifo`-byte FIFO,
/// then a replay of the FC's frames, which the CC refuses.
fn blocking_handshake(fifo: usize) -> Result<Outcome, Box<dyn std::error::Error>> {
    let (fc_uart, cc_uart) = SerialLine::pair(fifo);
    let tap = fc_uart.clone();
    let mut fc = signed_link(fc_uart, FC, 0);
    let mut cc = signed_link(cc_uart, CC, 1);

    fc_report_rc_loss(&mut fc, 123_456)?;
    let recorded = tap.in_flight();
    let confirmed = cc_confirm_takeover(&mut cc)?;
    fc_await_confirmation(&mut fc, confirmed)?;

    // An attacker on the line replays what the FC sent: refused, and the
    // CC's `recv` finds the line empty.
    tap.inject(&recorded);
    if let Ok(frame) = cc.recv() {
        return Err(format!("replayed frame accepted: {frame:?}").into());
    }
    while cc.recv_eof().is_some() {}
    Ok(Outcome {
        confirmed,
        cc_frames: cc.parser().stats().frames,
        cc_stale: cc.parser().stats().stale_timestamp,
        fc_frames: fc.parser().stats().frames,
    })
}

/// The same handshake with the async adapters (on a board: an async HAL's
/// UART under an executor such as embassy).
async fn async_handshake(fifo: usize) -> Result<u32, LinkError<Fault>> {
    let (fc_uart, cc_uart) = SerialLine::pair(fifo);
    let signed = |uart, ids: (u8, u8), link_id| {
        let parser = Parser::with_signing(
            Verifier::with_timestamp(KEY, SAVED_TIMESTAMP),
            Unsigned::Refuse,
        );
        let mut framer = Framer::new();
        framer.set_clock(None);
        framer.set_signer(Some(Signer::new(KEY, link_id, SAVED_TIMESTAMP + 1)));
        AsyncLink::<SerialLine, Dialect>::with_parts(uart, parser, framer, ids.0, ids.1)
    };
    let (mut fc, mut cc) = (signed(fc_uart, FC, 0), signed(cc_uart, CC, 1));

    fc.send(&heartbeat()).await?;
    fc.send(&notice(FbwagFailsafeStatus::RC_LOST, FC, 777))
        .await?;
    let rc_lost = loop {
        let frame = cc.recv().await?;
        if let Some(fbwag_dialect::Message::FbwagNotice(n)) = frame.message() {
            break n.timestamp;
        }
    };
    cc.send(&notice(
        FbwagFailsafeStatus::CC_TAKEOVER_CONFIRMED,
        CC,
        rc_lost,
    ))
    .await?;
    let ack = fc.recv_with(|frame| frame.message()).await?;
    match ack {
        Some(fbwag_dialect::Message::FbwagNotice(n)) => Ok(n.timestamp),
        _ => Err(LinkError::Recv(RecvError::Eof)),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let outcome = blocking_handshake(16)?;
    println!("blocking: {outcome:?}");
    let confirmed = block_on(async_handshake(16))?;
    println!("async: takeover confirmed for event {confirmed}");
    Ok(())
}

/// Receiving or sending failed.
#[derive(Debug)]
enum LinkError<E> {
    Recv(RecvError<E>),
    Send(SendError<E>),
}

impl<E> From<RecvError<E>> for LinkError<E> {
    fn from(e: RecvError<E>) -> Self {
        LinkError::Recv(e)
    }
}

impl<E> From<SendError<E>> for LinkError<E> {
    fn from(e: SendError<E>) -> Self {
        LinkError::Send(e)
    }
}

impl<E> std::fmt::Display for LinkError<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LinkError::Recv(e) => e.fmt(f),
            LinkError::Send(e) => e.fmt(f),
        }
    }
}

impl<E: std::error::Error + 'static> std::error::Error for LinkError<E> {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            LinkError::Recv(e) => e.source(),
            LinkError::Send(e) => e.source(),
        }
    }
}

// --- The stand-in for a UART (not needed on a board) ---

/// One end of an in-memory serial line: what one end writes, the other
/// reads. Like a UART, a read returns at most a FIFO's worth and a write
/// takes at most that much; an empty line reads as end of stream (where a
/// UART would wait).
#[derive(Clone)]
struct SerialLine {
    rx: Rc<RefCell<VecDeque<u8>>>,
    tx: Rc<RefCell<VecDeque<u8>>>,
    fifo: usize,
}

/// A UART error (this line never fails).
#[derive(Debug)]
enum Fault {}

impl std::fmt::Display for Fault {
    fn fmt(&self, _: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {}
    }
}

impl std::error::Error for Fault {}

impl embedded_io::Error for Fault {
    fn kind(&self) -> embedded_io::ErrorKind {
        match *self {}
    }
}

impl SerialLine {
    fn pair(fifo: usize) -> (SerialLine, SerialLine) {
        let (a, b) = (Rc::default(), Rc::default());
        let fifo = fifo.max(1);
        let one = SerialLine {
            rx: Rc::clone(&a),
            tx: Rc::clone(&b),
            fifo,
        };
        (one, SerialLine { rx: b, tx: a, fifo })
    }

    /// The bytes this end wrote that the other end has not read.
    fn in_flight(&self) -> Vec<u8> {
        self.tx.borrow().iter().copied().collect()
    }

    /// Puts bytes on the line towards the other end.
    fn inject(&self, bytes: &[u8]) {
        self.tx.borrow_mut().extend(bytes);
    }
}

impl embedded_io::ErrorType for SerialLine {
    type Error = Fault;
}

impl embedded_io::Read for SerialLine {
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Fault> {
        let mut rx = self.rx.borrow_mut();
        let n = rx.len().min(buf.len()).min(self.fifo);
        for (slot, byte) in buf.iter_mut().zip(rx.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }
}

impl embedded_io::Write for SerialLine {
    fn write(&mut self, buf: &[u8]) -> Result<usize, Fault> {
        let n = buf.len().min(self.fifo);
        self.tx.borrow_mut().extend(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> Result<(), Fault> {
        Ok(())
    }
}

impl embedded_io_async::Read for SerialLine {
    async fn read(&mut self, buf: &mut [u8]) -> Result<usize, Fault> {
        embedded_io::Read::read(self, buf)
    }
}

impl embedded_io_async::Write for SerialLine {
    async fn write(&mut self, buf: &[u8]) -> Result<usize, Fault> {
        embedded_io::Write::write(self, buf)
    }

    async fn flush(&mut self) -> Result<(), Fault> {
        Ok(())
    }
}

/// The smallest executor: polls until ready (the in-memory line never
/// makes a future wait). On a board, the executor runs the tasks.
fn block_on<F: std::future::Future>(f: F) -> F::Output {
    let mut f = std::pin::pin!(f);
    let mut cx = std::task::Context::from_waker(std::task::Waker::noop());
    loop {
        if let std::task::Poll::Ready(out) = f.as_mut().poll(&mut cx) {
            return out;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Any FIFO size, down to one byte per read and per write: the
    /// handshake completes, every frame authenticated, the replay refused.
    #[test]
    fn the_signed_handshake_completes_and_a_replay_is_refused() {
        for fifo in [1, 2, 3, 16, 64, 300] {
            let outcome = blocking_handshake(fifo).unwrap();
            assert_eq!(
                outcome,
                Outcome {
                    confirmed: 123_456,
                    cc_frames: 2,
                    cc_stale: 2,
                    fc_frames: 1,
                },
                "fifo {fifo}"
            );
        }
    }

    #[test]
    fn the_async_handshake_completes() {
        for fifo in [1, 7, 64] {
            assert_eq!(block_on(async_handshake(fifo)).unwrap(), 777, "fifo {fifo}");
        }
    }

    /// An unsigned notice (a CC without the key, or an attacker) never
    /// reaches the FC's handshake.
    #[test]
    fn an_unsigned_notice_is_refused() {
        let (attacker_uart, fc_uart) = SerialLine::pair(8);
        let mut attacker = Link::<_, Dialect>::new(attacker_uart, CC.0, CC.1);
        let mut fc = signed_link(fc_uart, FC, 0);
        let forged = notice(FbwagFailsafeStatus::CC_TAKEOVER_CONFIRMED, CC, 1);
        attacker.send(&forged).unwrap();
        assert!(matches!(
            fc_await_confirmation(&mut fc, 1),
            Err(RecvError::Eof)
        ));
        assert_eq!(fc.parser().stats().unsigned_rejected, 1);
    }
}
