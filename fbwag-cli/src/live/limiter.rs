//! Rate-limited log lines: a flood of bad frames cannot flood the log.

use super::{Level, Log};
use std::time::{Duration, Instant as WallInstant};

/// Lines about trusted frames (notices, the FC's texts) each daemon logs
/// per second at most: a handover is a few; without signing, anyone who
/// sends the peer's ids is trusted, and a flood of them logged every frame
/// (about 4,400 lines a second).
pub const HEARD_PER_SECOND: u32 = 20;

/// At most `per_window` lines of one kind per window; the rest are counted
/// and reported when the next window opens: a flood of bad frames cannot
/// flood the log.
pub struct Limiter {
    window: Duration,
    per_window: u32,
    opened: WallInstant,
    shown: u32,
    suppressed: u64,
}

impl Limiter {
    pub fn new(per_window: u32, window: Duration) -> Self {
        Limiter {
            window,
            per_window,
            opened: WallInstant::now(),
            shown: 0,
            suppressed: 0,
        }
    }

    /// Whether to show one more line now; `Some(n)` first says how many
    /// lines the last window suppressed.
    pub fn admit(&mut self) -> (bool, Option<u64>) {
        let mut report = None;
        if self.opened.elapsed() >= self.window {
            if self.suppressed > 0 {
                report = Some(self.suppressed);
            }
            self.opened = WallInstant::now();
            self.shown = 0;
            self.suppressed = 0;
        }
        if self.shown < self.per_window {
            self.shown += 1;
            (true, report)
        } else {
            self.suppressed += 1;
            (false, report)
        }
    }

    /// Logs `line()` at `level` through `log` if admitted, and the
    /// suppressed count.
    pub fn log(&mut self, log: &mut Log, level: Level, what: &str, line: impl FnOnce() -> String) {
        let (show, report) = self.admit();
        if let Some(n) = report {
            log.at(level, &format!("({n} more {what} suppressed)"));
        }
        if show {
            log.at(level, &line());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_limiter_shows_a_few_lines_per_window_then_counts_the_rest() {
        let mut limiter = Limiter::new(2, Duration::from_millis(30));
        let shown: Vec<_> = (0..1000).map(|_| limiter.admit()).collect();
        assert_eq!(shown.iter().filter(|(show, _)| *show).count(), 2);
        assert!(shown.iter().all(|(_, report)| report.is_none()));
        std::thread::sleep(Duration::from_millis(40));
        // The next window opens with the count of the last one.
        assert_eq!(limiter.admit(), (true, Some(998)));
        assert_eq!(limiter.admit(), (true, None));
        assert_eq!(limiter.admit(), (false, None));
    }
}
