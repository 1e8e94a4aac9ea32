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
//! at most; older frames are dropped first, so that a ground station's
//! command sent into a flood goes within about a second, not after the
//! flood's whole queue.
//!
//! [`LinkConfig::routed_rate`]: super::LinkConfig::routed_rate

use crate::frame::MAX_FRAME_LEN;
use core::num::NonZeroU32;
use std::boxed::Box;
use std::collections::VecDeque;
use std::time::Duration;
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

/// Routed frames the pace holds back, a second of the pace (or a frame of
/// the longest) at most: a frame that would make it longer drops the oldest.
#[derive(Debug)]
pub(super) struct Backlog {
    pace: Pace,
    frames: VecDeque<Box<[u8]>>,
    bytes: usize,
    cap: usize,
}

impl Backlog {
    pub(super) fn new(rate: NonZeroU32, now: Instant) -> Backlog {
        Backlog {
            pace: Pace::new(rate, now),
            frames: VecDeque::new(),
            bytes: 0,
            cap: (rate.get() as usize).max(MAX_FRAME_LEN),
        }
    }

    /// Holds `frame` back; returns how many older frames it dropped.
    pub(super) fn push(&mut self, frame: Box<[u8]>) -> u64 {
        self.bytes += frame.len();
        self.frames.push_back(frame);
        let mut dropped = 0;
        while self.bytes > self.cap && self.frames.len() > 1 {
            if let Some(old) = self.frames.pop_front() {
                self.bytes -= old.len();
                dropped += 1;
            }
        }
        dropped
    }

    /// The oldest frame held when the pace lets it go at `now`; `Ok(None)`
    /// when none is held; else how long until it may go.
    pub(super) fn release(&mut self, now: Instant) -> Result<Option<Box<[u8]>>, Duration> {
        let Some(len) = self.frames.front().map(|f| f.len()) else {
            return Ok(None);
        };
        self.pace.admit(len, now)?;
        Ok(self.pop())
    }

    pub(super) fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// The oldest frame held, whatever the pace (the router is gone).
    pub(super) fn pop(&mut self) -> Option<Box<[u8]>> {
        let frame = self.frames.pop_front()?;
        self.bytes -= frame.len();
        Some(frame)
    }

    /// Drops every frame held (the link is down); returns how many.
    pub(super) fn clear(&mut self) -> u64 {
        let n = self.frames.len() as u64;
        self.frames.clear();
        self.bytes = 0;
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
            .map(|i| backlog.push(Box::from(&[i; 100][..])))
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
        assert_eq!(small.push(Box::from(&[1u8; 200][..])), 0);
        assert_eq!(small.push(Box::from(&[2u8; 280][..])), 1);
        assert_eq!(small.pop().map(|f| f.len()), Some(280));
    }
}
