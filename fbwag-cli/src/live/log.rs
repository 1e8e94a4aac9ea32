//! A daemon's human-readable log.

use super::writer::{Lines, Output};
use super::Clock;
use std::io::Write;
use std::sync::Arc;

/// Human-readable log lines with the time since start, on stdout (or
/// anywhere), one flush per line so nothing is lost when the process is
/// killed, written by a thread of their own (see [`Lines`]): a stalled
/// reader never stops the daemon.
pub struct Log {
    out: Lines,
    clock: Clock,
    who: &'static str,
}

impl Log {
    pub fn new(out: Box<dyn Write + Send>, clock: Clock, who: &'static str) -> Self {
        let note = Arc::new(move |n| {
            let t = clock.secs();
            format!("[{t:>8.3} s] {who}: {n} log lines dropped (the output was not read)\n")
        });
        Log {
            out: Lines::new(Output::Open(out), note, None),
            clock,
            who,
        }
    }

    pub fn line(&mut self, what: &str) {
        let (t, who) = (self.clock.secs(), self.who);
        self.out.push(format!("[{t:>8.3} s] {who}: {what}\n"));
    }
}
