//! The pace of the frames routed through a link ([`LinkConfig::routed_rate`]).
//!
//! A link's own frames go before routed ones in its queues, and a TCP link
//! can bound what its kernel holds unsent; neither reaches the far end's
//! buffer (a telemetry modem's, a serial bridge's), which a flood routed
//! to a link slower than the flood fills, seconds of it, ahead of the
//! owner's next frame. Routed frames that go no faster than the link
//! carries never fill it: then the owner's frame waits for one routed frame
//! at most.
//!
//! [`LinkConfig::routed_rate`]: super::LinkConfig::routed_rate

use crate::frame::MAX_FRAME_LEN;
use core::num::NonZeroU32;
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
}
