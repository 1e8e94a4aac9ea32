//! The engines' clock: time since the daemon started, on the wall clock.

use std::time::{Duration, Instant as WallInstant};

/// The engines' time from a wall clock started with the program.
#[derive(Clone, Copy)]
pub struct Clock(WallInstant);

impl Clock {
    pub fn start() -> Self {
        Clock(WallInstant::now())
    }

    pub fn now(&self) -> fbwag_delegation::Moment {
        fbwag_delegation::Moment(self.0.elapsed().as_micros() as u64)
    }

    pub fn secs(&self) -> f64 {
        self.0.elapsed().as_secs_f64()
    }

    pub fn millis(&self) -> u64 {
        self.0.elapsed().as_millis() as u64
    }

    /// Wall time until engine time `t` (zero if past).
    pub fn until(&self, t: fbwag_delegation::Moment) -> Duration {
        Duration::from_micros(t.0.saturating_sub(self.now().0))
    }
}
