//! The pace of the frames routed through a link ([`LinkConfig::routed_rate`]).
//!
//! A link's own frames go before routed ones in its queues, and a TCP link
//! can bound what its kernel holds unsent; neither reaches the far end's
//! buffer (a telemetry modem's, a serial bridge's), which a flood routed
//! to a link slower than the flood fills, seconds of it, ahead of the
//! owner's next frame. Routed frames that go no faster than the link
//! carries never fill it: then the owner's frame waits for at most a burst
//! of them (an eighth of a second of the pace).
//!
//! What the pace holds back waits in a [`Backlog`] of a second of the pace
//! at most, a queue per sender (the link and address a routed frame came
//! from), served in turn: a flood from one sender fills its own queue, whose
//! oldest frames are the ones dropped, and a ground station's command from
//! another goes at its turn, within a burst or two, not behind the flood.
//!
//! [`LinkConfig::routed_rate`]: super::LinkConfig::routed_rate

use crate::frame::MAX_FRAME_LEN;
use core::num::NonZeroU32;
use std::boxed::Box;
use std::collections::VecDeque;
use std::time::Duration;
use std::vec::Vec;
use tokio::time::Instant;

/// A token bucket of bytes: at most `rate` bytes a second after a burst.
#[derive(Debug, Clone)]
pub(super) struct Pace {
    rate: f64,
    /// What the bucket holds at most, in bytes: an eighth of a second of
    /// the rate, and a frame of the longest at least (so that every frame
    /// can go).
    burst: f64,
    tokens: f64,
    at: Instant,
}

impl Pace {
    /// A full bucket at `now`.
    pub(super) fn new(rate: NonZeroU32, now: Instant) -> Pace {
        let rate = f64::from(rate.get());
        let burst = (rate / 8.0).max(MAX_FRAME_LEN as f64);
        Pace {
            rate,
            burst,
            tokens: burst,
            at: now,
        }
    }

    /// Takes `len` bytes from the bucket when it holds them at `now`;
    /// else how long until it does (nothing taken).
    pub(super) fn admit(&mut self, len: usize, now: Instant) -> Result<(), Duration> {
        let elapsed = now.saturating_duration_since(self.at).as_secs_f64();
        self.tokens = (self.tokens + elapsed * self.rate).min(self.burst);
        self.at = now;
        // (A frame longer than the burst waits for a full bucket.)
        let len = (len as f64).min(self.burst);
        if self.tokens >= len {
            self.tokens -= len;
            Ok(())
        } else {
            Err(Duration::from_secs_f64((len - self.tokens) / self.rate))
        }
    }
}

/// Senders a [`Backlog`] queues apart; frames of further senders share the
/// last queue.
pub(super) const SENDER_QUEUES: usize = 8;

/// Routed frames the pace holds back, a second of the pace (or a frame of
/// the longest) at most, a queue per sender (a key the router gives each
/// link and source address), released from each queue in turn. A frame
/// that makes the backlog too long drops the oldest frame of the longest
/// queue (a flood's, not a quiet sender's).
#[derive(Debug)]
pub(super) struct Backlog<F = Box<[u8]>> {
    pace: Pace,
    /// The non-empty queues, in turn from `turn`.
    queues: Vec<SenderQueue<F>>,
    turn: usize,
    bytes: usize,
    cap: usize,
}

#[derive(Debug)]
struct SenderQueue<F> {
    from: u32,
    frames: VecDeque<F>,
    bytes: usize,
}

impl<F: AsRef<[u8]>> Backlog<F> {
    pub(super) fn new(rate: NonZeroU32, now: Instant) -> Backlog<F> {
        Backlog {
            pace: Pace::new(rate, now),
            queues: Vec::new(),
            turn: 0,
            bytes: 0,
            cap: (rate.get() as usize).max(MAX_FRAME_LEN),
        }
    }

    /// Holds back `frame` from sender `from`; returns how many frames it
    /// dropped (the oldest of the longest queue) to stay within the cap.
    pub(super) fn push(&mut self, from: u32, frame: F) -> u64 {
        let at = match self.queues.iter().position(|q| q.from == from) {
            Some(at) => at,
            None if self.queues.len() < SENDER_QUEUES => {
                self.queues.push(SenderQueue {
                    from,
                    frames: VecDeque::new(),
                    bytes: 0,
                });
                self.queues.len() - 1
            }
            None => SENDER_QUEUES - 1,
        };
        let q = &mut self.queues[at];
        q.bytes += frame.as_ref().len();
        self.bytes += frame.as_ref().len();
        q.frames.push_back(frame);
        let mut dropped = 0;
        while self.bytes > self.cap && self.len() > 1 {
            let longest = (0..self.queues.len()).max_by_key(|&i| self.queues[i].bytes);
            match longest {
                Some(i) if self.drop_oldest(i) => dropped += 1,
                _ => break,
            }
        }
        dropped
    }

    /// The next frame held, in turn, when the pace lets it go at `now`;
    /// `Ok(None)` when none is held; else how long until it may go.
    pub(super) fn release(&mut self, now: Instant) -> Result<Option<F>, Duration> {
        let Some(q) = self.queues.get(self.turn) else {
            return Ok(None);
        };
        let len = q.frames.front().map_or(0, |f| f.as_ref().len());
        self.pace.admit(len, now)?;
        Ok(self.pop())
    }

    /// The next frame held, in turn, whatever the pace (the router is gone).
    pub(super) fn pop(&mut self) -> Option<F> {
        let turn = self.turn;
        let q = self.queues.get_mut(turn)?;
        let frame = q.frames.pop_front()?;
        q.bytes -= frame.as_ref().len();
        self.bytes -= frame.as_ref().len();
        if q.frames.is_empty() {
            // The next queue moves into its place: its turn now.
            self.queues.remove(turn);
        } else {
            self.turn += 1;
        }
        if self.turn >= self.queues.len() {
            self.turn = 0;
        }
        Some(frame)
    }

    /// Drops the oldest frame of queue `i`, and the queue once empty.
    fn drop_oldest(&mut self, i: usize) -> bool {
        let Some(q) = self.queues.get_mut(i) else {
            return false;
        };
        let Some(frame) = q.frames.pop_front() else {
            return false;
        };
        q.bytes -= frame.as_ref().len();
        self.bytes -= frame.as_ref().len();
        if q.frames.is_empty() {
            self.queues.remove(i);
            if self.turn > i {
                self.turn -= 1;
            }
            if self.turn >= self.queues.len() {
                self.turn = 0;
            }
        }
        true
    }

    fn len(&self) -> usize {
        self.queues.iter().map(|q| q.frames.len()).sum()
    }

    pub(super) fn is_empty(&self) -> bool {
        self.queues.is_empty()
    }

    /// Drops every frame held (the link is down); returns how many.
    pub(super) fn clear(&mut self) -> u64 {
        let n = self.len() as u64;
        self.queues.clear();
        (self.turn, self.bytes) = (0, 0);
        n
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rate(r: u32) -> NonZeroU32 {
        NonZeroU32::new(r).unwrap()
    }

    #[test]
    fn a_burst_goes_at_once_then_the_rate() {
        let t0 = Instant::now();
        // 8,000 B/s: a burst of 1,000 bytes.
        let mut pace = Pace::new(rate(8_000), t0);
        for _ in 0..10 {
            assert_eq!(pace.admit(100, t0), Ok(()));
        }
        let wait = pace.admit(100, t0).unwrap_err();
        assert_eq!(wait, Duration::from_micros(12_500), "100 bytes at 8 kB/s");
        assert!(pace.admit(100, t0 + wait / 2).is_err());
        assert_eq!(pace.admit(100, t0 + wait), Ok(()));
        // Over a second, the rate: 8,000 bytes, and no more.
        let (mut sent, mut t) = (0, t0 + wait);
        let end = t + Duration::from_secs(1);
        while t < end {
            match pace.admit(80, t) {
                Ok(()) => sent += 80,
                Err(w) => t += w,
            }
        }
        assert!((7_920..=8_080).contains(&sent), "{sent} bytes in a second");
    }

    #[test]
    fn an_idle_bucket_holds_one_burst_and_every_frame_fits() {
        let t0 = Instant::now();
        // 100 B/s: the burst is one frame of the longest.
        let mut pace = Pace::new(rate(100), t0);
        assert_eq!(pace.admit(MAX_FRAME_LEN, t0), Ok(()));
        let later = t0 + Duration::from_secs(3600);
        assert_eq!(pace.admit(MAX_FRAME_LEN, later), Ok(()));
        assert!(
            pace.admit(1, later).is_err(),
            "an hour idle saves one burst"
        );
        // Longer than the burst: waits for a full bucket, then goes.
        let mut big = Pace::new(rate(100), t0);
        assert_eq!(big.admit(10 * MAX_FRAME_LEN, t0), Ok(()));
        assert!(big.admit(10 * MAX_FRAME_LEN, t0).is_err());
    }

    #[test]
    fn a_backlog_keeps_a_second_of_the_pace_the_newest_frames() {
        let t0 = Instant::now();
        // 1,000 B/s: a backlog of 1,000 bytes, a burst of 280.
        let mut backlog = Backlog::new(rate(1_000), t0);
        let dropped: u64 = (0..30u8)
            .map(|i| backlog.push(1, Box::from(&[i; 100][..])))
            .sum();
        assert_eq!(dropped, 20, "ten frames of 100 bytes kept");
        let first = |r: Result<Option<Box<[u8]>>, Duration>| r.map(|f| f.map(|f| f[0]));
        assert_eq!(first(backlog.release(t0)), Ok(Some(20)), "the oldest kept");
        assert_eq!(first(backlog.release(t0)), Ok(Some(21)));
        assert!(backlog.release(t0).is_err(), "the burst spent");
        assert_eq!(backlog.pop().map(|f| f[0]), Some(22), "unpaced");
        assert_eq!(backlog.clear(), 7);
        assert_eq!(first(backlog.release(t0)), Ok(None));
        // A frame longer than the cap is kept alone.
        let mut small = Backlog::new(rate(60), t0);
        assert_eq!(small.push(1, Box::from(&[1u8; 200][..])), 0);
        assert_eq!(small.push(1, Box::from(&[2u8; 280][..])), 1);
        assert_eq!(small.pop().map(|f| f.len()), Some(280));
    }

    #[test]
    fn a_backlog_serves_its_senders_in_turn_and_drops_the_floods_frames() {
        let t0 = Instant::now();
        // 10,000 B/s: a backlog of 10,000 bytes, a burst of 1,250.
        let mut backlog = Backlog::new(rate(10_000), t0);
        let frame = |b: u8| Box::from(&[b; 100][..]);
        // A flood from sender 1, then one frame from sender 2, then more
        // flood.
        let mut dropped = 0;
        for i in 0..150u8 {
            dropped += backlog.push(1, frame(i));
        }
        dropped += backlog.push(2, frame(200));
        for i in 150..200u8 {
            dropped += backlog.push(1, frame(i));
        }
        assert_eq!(dropped, 101, "the flood's oldest, 100 frames kept");
        let mut order = Vec::new();
        while let Ok(Some(f)) = backlog.release(t0) {
            order.push(f[0]);
        }
        assert_eq!(
            order[..3],
            [101, 200, 102],
            "sender 2 at its turn: {order:?}"
        );
        // Senders past the queues share the last one.
        let mut many = Backlog::new(rate(10_000), t0);
        for from in 0..20 {
            many.push(from, frame(from as u8));
        }
        assert_eq!(many.queues.len(), SENDER_QUEUES);
        assert_eq!(many.clear(), 20);
        assert!(many.is_empty());
    }
}
