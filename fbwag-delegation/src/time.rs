//! Time as the state machines see it: microseconds since an arbitrary origin
//! (the caller's clock, or the simulator's virtual one).

use core::ops::{Add, Sub};
use core::time::Duration;

/// A point in time, in microseconds since the caller's origin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Instant(pub u64);

impl Instant {
    /// The origin.
    pub const ZERO: Instant = Instant(0);

    /// From milliseconds.
    pub const fn from_millis(ms: u64) -> Self {
        Instant(ms * 1000)
    }

    /// As whole milliseconds (what FBWAG_NOTICE's timestamp carries, wrapping).
    pub const fn as_millis(self) -> u64 {
        self.0 / 1000
    }

    /// Time since `earlier` (zero if `earlier` is later).
    pub fn since(self, earlier: Instant) -> Duration {
        Duration::from_micros(self.0.saturating_sub(earlier.0))
    }
}

impl Add<Duration> for Instant {
    type Output = Instant;
    fn add(self, d: Duration) -> Instant {
        Instant(self.0.saturating_add(d.as_micros() as u64))
    }
}

impl Sub<Instant> for Instant {
    type Output = Duration;
    fn sub(self, other: Instant) -> Duration {
        self.since(other)
    }
}
