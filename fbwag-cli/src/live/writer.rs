//! The thread that writes a daemon's log and events: lines go through a
//! bounded queue, so a reader that stops reading never stops the daemon.

use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::Arc;
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
/// its own (`dropped`), once there is room, or at the end.
pub(super) struct Lines {
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
pub(super) enum Output {
    /// Open already.
    Open(Box<dyn Write + Send>),
    /// Opened by that thread: opening a FIFO for writing waits for a
    /// reader, and must not hold the daemon's start (its lines queue
    /// meanwhile, as for a stalled reader).
    Later(Box<dyn FnOnce() -> io::Result<Box<dyn Write + Send>> + Send>),
}

impl Lines {
    pub(super) fn new(output: Output, note: Box<dyn Fn(u64) -> String + Send>) -> Self {
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
