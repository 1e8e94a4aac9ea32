//! The thread that writes a daemon's log and events: lines go through a
//! bounded queue, so a reader that stops reading never stops the daemon.

use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

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
/// its own (`dropped`), once there is room, or at the end. Lines the
/// output refuses (a full disk, `/dev/full`) are counted the same way: the
/// note goes out before the next line written, and what was never written
/// is said on standard error at the end.
pub(super) struct Lines {
    queue: Option<SyncSender<String>>,
    /// Lines dropped since the queue last took one.
    dropped: u64,
    /// The line that says `n` lines were dropped.
    note: Note,
    /// Lines the output refused since it last took one, and why.
    refused: Arc<Mutex<Refused>>,
    /// What the output is, for the end's message (`None`: nothing said).
    name: Option<String>,
    /// Lines queued (for the end's message when the output never opened).
    queued: u64,
    /// Closed by the writer thread when it has written every line.
    written: Receiver<()>,
    /// Set by the writer thread once it has opened its output: until then
    /// (a FIFO nobody has opened to read) there is nothing to wait for at
    /// the end.
    opened: Arc<AtomicBool>,
}

/// The line that says `n` lines were dropped.
pub(super) type Note = Arc<dyn Fn(u64) -> String + Send + Sync>;

/// Lines a writer thread could not write since it last wrote one.
#[derive(Default)]
struct Refused {
    lines: u64,
    error: Option<io::Error>,
    /// The output took part of a line: the next text begins on a line of
    /// its own, so the broken one stays alone.
    broken: bool,
}

/// What a [`Lines`] writer thread writes to.
pub(super) enum Output {
    /// Open already.
    Open(Box<dyn Write + Send>),
    /// Opened by that thread: opening a FIFO for writing waits for a
    /// reader, and must not hold the daemon's start (its lines queue
    /// meanwhile, as for a stalled reader).
    Later(Box<dyn FnOnce() -> io::Result<Box<dyn Write + Send>> + Send>),
}

impl Lines {
    /// Lines to `output` (named `name` in the end's message about lines
    /// it refused; `None`: not said), `note` the line that counts those
    /// dropped.
    pub(super) fn new(output: Output, note: Note, name: Option<String>) -> Self {
        let (queue, lines) = mpsc::sync_channel::<String>(LINES_QUEUED);
        let (done, written) = mpsc::channel();
        let opened = Arc::new(AtomicBool::new(matches!(output, Output::Open(_))));
        let open_flag = opened.clone();
        let refused = Arc::new(Mutex::new(Refused::default()));
        let (thread_refused, thread_note) = (refused.clone(), note.clone());
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
                write_counted(&mut out, &line, &thread_refused, &thread_note);
            }
            drop(done);
        });
        Lines {
            queue: Some(queue),
            dropped: 0,
            note,
            refused,
            name,
            queued: 0,
            written,
            opened,
        }
    }

    /// Queues `line` (ending in a newline), after the note of lines dropped
    /// before it, if any.
    pub(super) fn push(&mut self, line: String) {
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
        match queue.try_send(line) {
            Ok(()) => self.queued += 1,
            Err(TrySendError::Full(_)) => self.dropped += 1,
            Err(TrySendError::Disconnected(_)) => {}
        }
    }
}

/// Writes `line`, after the note of the lines refused before it, if any;
/// a refused line is counted. (Nobody reading any more, a closed pipe,
/// fails each write: the lines are dropped here rather than filling the
/// queue.)
fn write_counted(out: &mut dyn Write, line: &str, refused: &Mutex<Refused>, note: &Note) {
    // Not held while writing: a reader that stalls the write must not
    // stall the end of the daemon, which reads the count.
    let lock = || refused.lock().unwrap_or_else(PoisonError::into_inner);
    let (before, broken) = {
        let r = lock();
        (r.lines, r.broken)
    };
    let result = match before {
        0 => write_line(out, line),
        n => {
            let note = format!("{}{}", if broken { "\n" } else { "" }, note(n));
            write_line(out, &note).and_then(|()| {
                *lock() = Refused::default();
                write_line(out, line)
            })
        }
    };
    if let Err((e, partly)) = result {
        let mut r = lock();
        r.lines += 1;
        r.error = Some(e);
        r.broken |= partly;
    }
}

/// Writes all of `text` and flushes; on error, whether part of it was
/// written.
fn write_line(out: &mut dyn Write, text: &str) -> Result<(), (io::Error, bool)> {
    let mut left = text.as_bytes();
    while !left.is_empty() {
        match out.write(left) {
            Ok(0) => {
                let partly = left.len() < text.len();
                return Err((io::ErrorKind::WriteZero.into(), partly));
            }
            Ok(n) => left = &left[n..],
            Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
            Err(e) => return Err((e, left.len() < text.len())),
        }
    }
    out.flush().map_err(|e| (e, false))
}

/// "1 line", "2 lines".
fn lines(n: u64) -> String {
    format!("{n} line{}", if n == 1 { "" } else { "s" })
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
        let opened = self.opened.load(Ordering::Acquire);
        if opened {
            let _ = self.written.recv_timeout(LINES_DRAIN);
        }
        let Some(name) = &self.name else {
            return;
        };
        let r = self.refused.lock().unwrap_or_else(PoisonError::into_inner);
        let lost = match &r.error {
            Some(e) => Some(format!("{} at the end not written: {e}", lines(r.lines))),
            None if !opened && self.queued > 0 => Some(format!(
                "{} not written: no reader opened it",
                lines(self.queued)
            )),
            None => None,
        };
        if let Some(lost) = lost {
            eprintln!("fbwag: {name}: {lost}");
            OUTPUT_LOST.store(true, Ordering::Relaxed);
        }
    }
}

/// A named output ([`Lines::new`]) lost its last lines: the program exits
/// with status 2 ("an output not written"), whatever else it did.
static OUTPUT_LOST: AtomicBool = AtomicBool::new(false);

/// Whether a named output lost its last lines.
pub fn output_lost() -> bool {
    OUTPUT_LOST.load(Ordering::Relaxed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Takes `room` bytes, then refuses `refusals` writes, then takes all.
    struct Short {
        room: usize,
        refusals: usize,
        kept: Arc<Mutex<String>>,
    }

    impl Write for Short {
        fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
            if self.room == 0 && self.refusals > 0 {
                self.refusals -= 1;
                return Err(io::Error::from(io::ErrorKind::StorageFull));
            }
            let n = if self.room > 0 {
                buf.len().min(self.room)
            } else {
                buf.len()
            };
            self.room -= n.min(self.room);
            let mut kept = self.kept.lock().unwrap();
            kept.push_str(std::str::from_utf8(&buf[..n]).unwrap());
            Ok(n)
        }

        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    #[test]
    fn lines_the_output_refused_are_counted_before_the_next_one_written() {
        let kept = Arc::new(Mutex::new(String::new()));
        let out = Short {
            room: 0,
            refusals: 2,
            kept: kept.clone(),
        };
        let note: Note = Arc::new(|n| format!("{n} dropped\n"));
        let mut lines = Lines::new(Output::Open(Box::new(out)), note, None);
        for line in ["a\n", "b\n", "c\n", "d\n"] {
            lines.push(line.to_string());
        }
        drop(lines);
        assert_eq!(*kept.lock().unwrap(), "2 dropped\nc\nd\n");
    }

    #[test]
    fn a_line_cut_short_stays_on_a_line_of_its_own() {
        let kept = Arc::new(Mutex::new(String::new()));
        let out = Short {
            room: 4,
            refusals: 1,
            kept: kept.clone(),
        };
        let note: Note = Arc::new(|n| format!("{n} dropped\n"));
        let mut lines = Lines::new(Output::Open(Box::new(out)), note, None);
        lines.push("{\"a\":1}\n".to_string());
        lines.push("{\"b\":2}\n".to_string());
        drop(lines);
        assert_eq!(*kept.lock().unwrap(), "{\"a\"\n1 dropped\n{\"b\":2}\n");
    }
}
