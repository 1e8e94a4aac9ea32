//! The delegation protocol on real links: the companion daemon (`fbwag
//! cc`), a flight-controller simulator speaking like ArduPlane (`fbwag
//! fc-sim`), and both over a lossy loopback relay (`fbwag demo`).
//!
//! Each daemon drives a node of `fbwag_delegation::node` (around the
//! protocol engines the simulator runs): which frames count, who is
//! trusted, whom a link answers, where a frame may go and which control is
//! applied is decided there. This module only moves bytes and time
//! ([`net`]) and reports ([`Events`], [`Log`]).

pub mod cc;
pub mod demo;
pub mod fc;
pub mod gcs;
pub mod net;
pub mod params;
pub mod plane;
pub mod router;
pub mod telemetry;

use serde_json::{Map, Value};
use std::fs::File;
use std::io::{self, Write};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant as WallInstant};

/// The engines' time from a wall clock started with the program.
#[derive(Clone, Copy)]
pub struct Clock(WallInstant);

impl Clock {
    pub fn start() -> Self {
        Clock(WallInstant::now())
    }

    pub fn now(&self) -> fbwag_delegation::Instant {
        fbwag_delegation::Instant(self.0.elapsed().as_micros() as u64)
    }

    pub fn secs(&self) -> f64 {
        self.0.elapsed().as_secs_f64()
    }

    pub fn millis(&self) -> u64 {
        self.0.elapsed().as_millis() as u64
    }

    /// Wall time until engine time `t` (zero if past).
    pub fn until(&self, t: fbwag_delegation::Instant) -> Duration {
        Duration::from_micros(t.0.saturating_sub(self.now().0))
    }
}

/// Lines queued for a writer (log or events) and not written yet, at
/// most: about a megabyte.
const LINES_QUEUED: usize = 4096;

/// How long the end of a daemon waits for its queued lines to be written
/// (the summary event is among the last).
const LINES_DRAIN: Duration = Duration::from_secs(1);

/// Lines written, each flushed, by a thread of their own, fed through a
/// bounded queue: a reader that stops reading (a full pipe, a stopped
/// terminal) stops that thread, never the daemon, whose timers and links
/// all run on one thread. (A blocking write there froze a daemon mid-flight
/// once 64 KiB of events waited in a pipe nobody read.) A line that finds
/// the queue full is dropped and counted; the count goes out, as a line of
/// its own (`dropped`), once there is room, or at the end.
struct Lines {
    queue: Option<SyncSender<String>>,
    /// Lines dropped since the queue last took one.
    dropped: u64,
    /// The line that says `n` lines were dropped.
    note: Box<dyn Fn(u64) -> String + Send>,
    /// Closed by the writer thread when it has written every line.
    written: Receiver<()>,
    /// Set by the writer thread once it has opened its output: until then
    /// (a FIFO nobody has opened to read) there is nothing to wait for at
    /// the end.
    opened: Arc<AtomicBool>,
}

/// What a [`Lines`] writer thread writes to.
enum Output {
    /// Open already.
    Open(Box<dyn Write + Send>),
    /// Opened by that thread: opening a FIFO for writing waits for a
    /// reader, and must not hold the daemon's start (its lines queue
    /// meanwhile, as for a stalled reader).
    Later(Box<dyn FnOnce() -> io::Result<Box<dyn Write + Send>> + Send>),
}

impl Lines {
    fn new(output: Output, note: Box<dyn Fn(u64) -> String + Send>) -> Self {
        let (queue, lines) = mpsc::sync_channel::<String>(LINES_QUEUED);
        let (done, written) = mpsc::channel();
        let opened = Arc::new(AtomicBool::new(matches!(output, Output::Open(_))));
        let open_flag = opened.clone();
        std::thread::spawn(move || {
            let mut out = match output {
                Output::Open(out) => out,
                // A failed open drops every line (the queue closes with the
                // thread): checked at start (`Events::open`), it can only
                // fail if the file changed since.
                Output::Later(open) => match open() {
                    Ok(out) => {
                        open_flag.store(true, Ordering::Release);
                        out
                    }
                    Err(_) => return,
                },
            };
            for line in lines {
                // Nobody reading any more (a closed pipe) fails each write:
                // the lines are dropped here rather than filling the queue.
                let _ = out.write_all(line.as_bytes()).and_then(|()| out.flush());
            }
            drop(done);
        });
        Lines {
            queue: Some(queue),
            dropped: 0,
            note,
            written,
            opened,
        }
    }

    /// Queues `line` (ending in a newline), after the note of lines dropped
    /// before it, if any.
    fn push(&mut self, line: String) {
        let Some(queue) = &self.queue else {
            return;
        };
        if self.dropped > 0 {
            match queue.try_send((self.note)(self.dropped)) {
                Ok(()) => self.dropped = 0,
                Err(TrySendError::Full(_)) => {
                    self.dropped += 1;
                    return;
                }
                Err(TrySendError::Disconnected(_)) => return,
            }
        }
        if let Err(TrySendError::Full(_)) = queue.try_send(line) {
            self.dropped += 1;
        }
    }
}

impl Drop for Lines {
    /// Queues the note of lines dropped, if any, then waits for the queued
    /// lines to be written, at most [`LINES_DRAIN`] (a stalled reader does
    /// not hold the exit).
    fn drop(&mut self) {
        if let (Some(queue), true) = (&self.queue, self.dropped > 0) {
            let _ = queue.try_send((self.note)(self.dropped));
        }
        self.queue = None;
        if self.opened.load(Ordering::Acquire) {
            let _ = self.written.recv_timeout(LINES_DRAIN);
        }
    }
}

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
        let note = Box::new(move |n| {
            let t = clock.secs();
            format!("[{t:>8.3} s] {who}: {n} log lines dropped (the output was not read)\n")
        });
        Log {
            out: Lines::new(Output::Open(out), note),
            clock,
            who,
        }
    }

    pub fn line(&mut self, what: &str) {
        let (t, who) = (self.clock.secs(), self.who);
        self.out.push(format!("[{t:>8.3} s] {who}: {what}\n"));
    }
}

/// Machine-readable events: one JSON object per line, `{"t_ms": <ms since
/// start>, "event": <name>, ...}`, flushed per line, written by a thread of
/// their own (see [`Lines`]): events that find a stalled reader's queue
/// full are dropped, then counted in `{"event": "dropped", "events": N}`.
/// `None` writes nothing.
pub struct Events {
    out: Option<Lines>,
    clock: Clock,
}

impl Events {
    /// Events to `path` (`-`: stdout), or none. A file is created now (an
    /// error ends the program before it starts); a FIFO is opened by the
    /// writer thread, once a reader opens it.
    pub fn open(path: Option<&Path>, clock: Clock) -> io::Result<Self> {
        let out = match path {
            None => None,
            Some(p) if p.as_os_str() == "-" => Some(Output::Open(Box::new(io::stdout()))),
            Some(p) if is_fifo(p) => {
                fifo_can_be_opened(p).map_err(|e| events_error(p, e))?;
                let p = p.to_owned();
                Some(Output::Later(Box::new(move || {
                    let fifo = std::fs::OpenOptions::new().write(true).open(p)?;
                    Ok(Box::new(fifo))
                })))
            }
            Some(p) => Some(Output::Open(Box::new(
                File::create(p).map_err(|e| events_error(p, e))?,
            ))),
        };
        let note = move |n| {
            let t_ms = clock.millis();
            format!("{{\"t_ms\":{t_ms},\"event\":\"dropped\",\"events\":{n}}}\n")
        };
        Ok(Events {
            out: out.map(|out| Lines::new(out, Box::new(note))),
            clock,
        })
    }

    /// Writes one event with `fields` (a JSON object's entries).
    pub fn emit(&mut self, event: &str, fields: Value) {
        let Some(out) = &mut self.out else {
            return;
        };
        let mut line = Map::new();
        line.insert("t_ms".into(), self.clock.millis().into());
        line.insert("event".into(), event.into());
        if let Value::Object(extra) = fields {
            line.extend(extra);
        }
        out.push(format!("{}\n", Value::Object(line)));
    }
}

/// `e`, naming the `--events` file it came from.
fn events_error(path: &Path, e: io::Error) -> io::Error {
    io::Error::new(e.kind(), format!("--events {}: {e}", path.display()))
}

/// Fails as opening the FIFO `path` for writing would (no permission, say),
/// except for having no reader yet: checked at start, where an error ends
/// the program, since the writer thread opens it later.
fn fifo_can_be_opened(path: &Path) -> io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        let probe = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path);
        match probe {
            Err(e) if e.raw_os_error() != Some(libc::ENXIO) => Err(e),
            _ => Ok(()),
        }
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        Ok(())
    }
}

/// Whether `path` is a FIFO (a named pipe).
fn is_fifo(path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        std::fs::metadata(path).is_ok_and(|m| m.file_type().is_fifo())
    }
    #[cfg(not(unix))]
    {
        let _ = path;
        false
    }
}

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

    /// Logs `line()` through `log` if admitted, and the suppressed count.
    pub fn log(&mut self, log: &mut Log, what: &str, line: impl FnOnce() -> String) {
        let (show, report) = self.admit();
        if let Some(n) = report {
            log.line(&format!("({n} more {what} suppressed)"));
        }
        if show {
            log.line(&line());
        }
    }
}

/// The ArduPlane name of a HEARTBEAT `custom_mode` (FBWAG: this protocol's
/// companion-control mode).
pub fn mode_name(custom_mode: u32) -> String {
    use fbwag_delegation::mode;
    match custom_mode {
        mode::MANUAL => "MANUAL".into(),
        mode::CIRCLE => "CIRCLE".into(),
        mode::FBWA => "FBWA".into(),
        mode::RTL => "RTL".into(),
        mode::GUIDED => "GUIDED".into(),
        mode::FBWAG => "FBWAG".into(),
        other => format!("MODE({other})"),
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
