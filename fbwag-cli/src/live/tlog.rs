//! Telemetry logs (`--tlog DIR`): frames written to `.tlog` files in the
//! format MAVProxy writes and pymavlink's `mavlogfile` reads: per frame, the
//! time in microseconds since the Unix epoch as 8 bytes big-endian, then the
//! frame's bytes as they are on the wire.
//!
//! pymavlink takes the timestamp's two low bits for the number of the link
//! a frame came in on (`msg._link`, `mavlogdump.py --link`), and MAVProxy
//! writes them so (3 for what it sends itself): here the link's index for
//! the first three links (0, 1, 2; 2 also for any link after them) and
//! [`OWN_FRAMES`] for the program's own frames.
//!
//! The daemon's loop only queues frames ([`Tlog::received`],
//! [`Tlog::sent`]); [`super::logfiles`] writes them (rotation, the number
//! of files kept, the free-space floor). With `--log-mode while-armed`
//! frames are logged only while the vehicle is armed (the daemon says so:
//! [`Tlog::set_armed`]), a new file for each arming.

use super::logfiles::{now_us, Counts, Files, FilesOptions, Item, Kind};
use super::Log;
use std::io;

/// The timestamp's low bits of the program's own frames (MAVProxy's mark
/// of what it sent).
pub const OWN_FRAMES: u8 = 3;

/// When a log writes (mavlink-router's `LogMode`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum LogMode {
    /// From start to end.
    #[default]
    Always,
    /// While the vehicle's HEARTBEAT says armed, a file for each arming.
    WhileArmed,
}

/// Where, how much and when a log (telemetry or flight) writes.
#[derive(Debug, Clone)]
pub struct LogOptions {
    pub files: FilesOptions,
    pub mode: LogMode,
}

/// What the telemetry log did.
pub type TlogCounts = Counts;

/// The daemon's side of the log: frames in, notes and counts out.
pub struct Tlog {
    files: Files,
    mode: LogMode,
    armed: bool,
    /// A file to end (disarmed) that found the queue full: ended before
    /// the next frame.
    close: bool,
}

impl Tlog {
    /// Starts the log's writer ([`Files::start`]); `program` names the
    /// files (`fbwag-router-…`).
    pub fn start(o: &LogOptions, program: &str) -> io::Result<Tlog> {
        let files = Files::start(&o.files, program, Kind::Telemetry, "--tlog")?;
        Ok(Tlog::with(files, o.mode))
    }

    fn with(files: Files, mode: LogMode) -> Tlog {
        Tlog {
            files,
            mode,
            armed: false,
            close: false,
        }
    }

    /// Queues `frame` (its bytes as on the wire), received on the link of
    /// index `link` and accepted.
    pub fn received(&mut self, link: u8, frame: &[u8]) {
        self.push(link.min(OWN_FRAMES - 1), frame);
    }

    /// Queues a frame of the program's own.
    pub fn sent(&mut self, frame: &[u8]) {
        self.push(OWN_FRAMES, frame);
    }

    /// The vehicle is armed, or not: under `while-armed`, frames are
    /// logged only while it is, and its file ends when it disarms.
    pub fn set_armed(&mut self, armed: bool) {
        if armed == self.armed {
            return;
        }
        self.armed = armed;
        if !armed && self.mode == LogMode::WhileArmed {
            self.close = !self.files.push(Item::Close);
        }
    }

    /// Queues `frame` with the timestamp's low bits `tag`, when the log
    /// writes now. Never waits: a full queue drops it, counted.
    fn push(&mut self, tag: u8, frame: &[u8]) {
        if self.mode == LogMode::WhileArmed && !self.armed {
            return;
        }
        if self.close {
            self.close = !self.files.push(Item::Close);
        }
        let us = (now_us() & !3) | u64::from(tag);
        self.files.push(Item::frame(us, frame));
    }

    /// The writer's notes, into the daemon's log.
    pub fn notes(&mut self, log: &mut Log) {
        self.files.notes(log);
    }

    /// The counts so far.
    pub fn counts(&self) -> TlogCounts {
        self.files.counts()
    }

    /// Ends the log ([`Files::finish`]).
    pub fn finish(&mut self, log: &mut Log) -> TlogCounts {
        self.files.finish(log)
    }
}

/// The counts in the log's words.
pub fn line(counts: &TlogCounts) -> String {
    counts.line("tlog", "frames")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What was queued: (timestamp's tag, the frame's first byte), `None`
    /// for the end of a file.
    fn queued(items: &std::sync::mpsc::Receiver<Item>) -> Vec<Option<(u64, u8)>> {
        items
            .try_iter()
            .map(|i| match i {
                Item::Frame { us, bytes, .. } => Some((us & 3, bytes[0])),
                _ => None,
            })
            .collect()
    }

    #[test]
    fn frames_that_find_the_queue_full_are_dropped_and_counted() {
        let (files, items) = Files::stalled(2);
        let mut tlog = Tlog::with(files, LogMode::Always);
        for n in 0..5u8 {
            tlog.received(7, &[n; 21]);
        }
        tlog.sent(&[9; 300]);
        assert_eq!(tlog.counts().dropped, 4);
        // Link 7 is marked 2 (the last mark of a link), never 3.
        assert_eq!(queued(&items), [Some((2, 0)), Some((2, 1))]);
    }

    #[test]
    fn while_armed_only_armed_frames_are_logged_a_file_each_arming() {
        let (files, items) = Files::stalled(16);
        let mut tlog = Tlog::with(files, LogMode::WhileArmed);
        tlog.received(0, &[1]);
        tlog.set_armed(true);
        tlog.received(0, &[2]);
        tlog.sent(&[3]);
        tlog.set_armed(false);
        tlog.received(1, &[4]);
        tlog.set_armed(true);
        tlog.received(1, &[5]);
        assert_eq!(
            queued(&items),
            [Some((0, 2)), Some((3, 3)), None, Some((1, 5))]
        );
    }
}
