//! A daemon's human-readable log: one line per thing said, each with its
//! level, in the form operators' tools read.
//!
//! On a terminal or into a file: `2026-12-07T20:23:01.123456Z WARN cc:
//! …`, the time the wall clock's UTC in RFC 3339. Under systemd, whose
//! journal stamps each line itself and files it by priority: `<4>cc: …`,
//! the sd-daemon convention (syslog's priority in angle brackets), chosen
//! when `JOURNAL_STREAM` names the standard output the log goes to.

use super::writer::{Lines, Output};
use std::io::Write;
use std::sync::Arc;
use std::time::SystemTime;

/// How much a line matters, as syslog ranks it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, clap::ValueEnum)]
pub enum Level {
    /// The daemon cannot do what it is for (a link that fails, a state
    /// file that cannot be saved).
    Error,
    /// Something an operator should look at (a lost receiver, refused
    /// frames, a silent FC).
    Warn,
    /// A normal but significant change (a mode change, a takeover, a link
    /// open again).
    Notice,
    /// What the daemon is doing (start, links, reports, notices heard).
    Info,
    /// Detail for a bench.
    Debug,
}

impl Level {
    /// syslog's priority: 3 (err) to 7 (debug).
    fn priority(self) -> u8 {
        match self {
            Level::Error => 3,
            Level::Warn => 4,
            Level::Notice => 5,
            Level::Info => 6,
            Level::Debug => 7,
        }
    }

    fn word(self) -> &'static str {
        match self {
            Level::Error => "ERROR",
            Level::Warn => "WARN",
            Level::Notice => "NOTICE",
            Level::Info => "INFO",
            Level::Debug => "DEBUG",
        }
    }
}

/// How a line begins.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// The time (UTC, RFC 3339) and the level's word.
    Stamped,
    /// `<N>`: the journal adds the time and files the line by priority.
    Journal,
}

impl Style {
    /// [`Style::Journal`] when standard output is the stream
    /// `JOURNAL_STREAM` names (`DEVICE:INODE`, set by systemd for a
    /// service's output), else [`Style::Stamped`].
    pub fn of_stdout() -> Style {
        match std::env::var("JOURNAL_STREAM") {
            Ok(stream) if stdout_is(&stream) => Style::Journal,
            _ => Style::Stamped,
        }
    }

    fn begin(self, level: Level, who: &str) -> String {
        match self {
            Style::Journal => format!("<{}>{who}: ", level.priority()),
            Style::Stamped => format!("{} {:<6} {who}: ", utc_now(), level.word()),
        }
    }
}

/// Whether standard output is the file `DEVICE:INODE` names.
#[cfg(unix)]
fn stdout_is(stream: &str) -> bool {
    rustix::fs::fstat(std::io::stdout())
        .is_ok_and(|stat| format!("{}:{}", stat.st_dev, stat.st_ino) == stream)
}

#[cfg(not(unix))]
fn stdout_is(_: &str) -> bool {
    false
}

/// The wall clock now, UTC, RFC 3339 to the microsecond.
pub fn utc_now() -> String {
    humantime::format_rfc3339_micros(SystemTime::now()).to_string()
}

/// The log: lines at `level` or more important, one flush per line so
/// nothing is lost when the process is killed, written by a thread of
/// their own (see [`Lines`]): a stalled reader never stops the daemon.
pub struct Log {
    out: Lines,
    who: &'static str,
    level: Level,
    style: Style,
}

impl Log {
    /// The log of daemon `who` into `out`, keeping lines at `level` and
    /// above, begun in `style`.
    pub fn new(out: Box<dyn Write + Send>, who: &'static str, level: Level, style: Style) -> Self {
        let note = Arc::new(move |n| {
            let begin = style.begin(Level::Warn, who);
            format!("{begin}{n} log lines dropped (the output was not read)\n")
        });
        Log {
            out: Lines::new(Output::Open(out), note, None),
            who,
            level,
            style,
        }
    }

    /// Says `what` at `level`.
    pub fn at(&mut self, level: Level, what: &str) {
        if level <= self.level {
            let begin = self.style.begin(level, self.who);
            self.out.push(format!("{begin}{what}\n"));
        }
    }

    pub fn error(&mut self, what: &str) {
        self.at(Level::Error, what);
    }

    pub fn warn(&mut self, what: &str) {
        self.at(Level::Warn, what);
    }

    pub fn notice(&mut self, what: &str) {
        self.at(Level::Notice, what);
    }

    pub fn info(&mut self, what: &str) {
        self.at(Level::Info, what);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_begin_with_the_time_and_level_or_the_journals_priority() {
        let stamped = Style::Stamped.begin(Level::Warn, "cc");
        // 2026-12-07T20:23:01.123456Z WARN   cc:
        let (time, rest) = stamped.split_once(' ').unwrap();
        assert_eq!(time.len(), 27, "{stamped}");
        assert!(time.ends_with('Z') && time.as_bytes()[10] == b'T');
        assert!(humantime::parse_rfc3339(time).is_ok(), "{time}");
        assert_eq!(rest, "WARN   cc: ");
        assert_eq!(Style::Journal.begin(Level::Error, "fc"), "<3>fc: ");
        assert_eq!(Style::Journal.begin(Level::Debug, "router"), "<7>router: ");
        assert!(Level::Error < Level::Info, "the order filters with <=");
    }

    #[test]
    fn the_journal_is_chosen_only_for_the_stream_it_names() {
        assert!(!stdout_is("garbage"));
        assert!(!stdout_is("0:0"));
    }
}
