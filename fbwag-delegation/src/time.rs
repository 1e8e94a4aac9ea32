//! Time as the state machines see it: microseconds since an arbitrary origin
//! (the caller's clock, or the simulator's virtual one).

use core::ops::{Add, Sub};
use core::time::Duration;

/// A point in time, in microseconds since the caller's origin. Named
/// apart from std's and tokio's `Moment`, which a program driving the
/// machines uses beside it (to read its clock).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Moment(pub u64);

impl Moment {
    /// The origin.
    pub const ZERO: Moment = Moment(0);

    /// From milliseconds.
    pub const fn from_millis(ms: u64) -> Self {
        Moment(ms * 1000)
    }

    /// As whole milliseconds (what FBWAG_NOTICE's timestamp carries, wrapping).
    pub const fn as_millis(self) -> u64 {
        self.0 / 1000
    }

    /// Time since `earlier` (zero if `earlier` is later).
    pub fn since(self, earlier: Moment) -> Duration {
        Duration::from_micros(self.0.saturating_sub(earlier.0))
    }
}

impl Add<Duration> for Moment {
    type Output = Moment;
    fn add(self, d: Duration) -> Moment {
        Moment(self.0.saturating_add(d.as_micros() as u64))
    }
}

impl Sub<Moment> for Moment {
    type Output = Duration;
    fn sub(self, other: Moment) -> Duration {
        self.since(other)
    }
}
