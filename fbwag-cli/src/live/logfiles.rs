//! Log files a thread of their own writes, for the telemetry log
//! ([`super::tlog`]: `.tlog`) and the flight stack's log
//! ([`super::flight_log`]: `.bin`), under the same rules.
//!
//! The daemon's loop only queues items ([`Files::push`]): frames with
//! their timestamp, log blocks at their place, or the end of a file. A
//! thread of its own writes them, through a bounded queue, so a slow disk
//! never slows routing; an item that finds the queue full is dropped and
//! counted. That thread begins a file when one is needed (a `.tlog` also
//! before the next frame would take it past `--tlog-max-size`), keeps at
//! most `--log-max-files` of its kind, keeps the file system's free space
//! above a floor by deleting this program's oldest files of its kind
//! (only files named as it names them), and stops writing, once said in
//! the log, while the floor cannot be kept, resuming when space returns.

use super::{Level, Log};
use fbwag_dialect::mavframe::frame::MAX_FRAME_LEN;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// Items queued for the writer, at most: about 1.2 MB, a few seconds of
/// a busy link's traffic while the disk stalls.
const QUEUED: usize = 4096;

/// The free space is looked at again after this long, or after
/// [`CHECK_BYTES`] written, whichever comes first.
const CHECK_EVERY: Duration = Duration::from_secs(1);

/// Files in a row that fail before the log is given up for the run: a
/// lasting write error (a file size limit below `--tlog-max-size`, a
/// failing card) would otherwise begin a file every second for ever.
const FAILED_FILES_MAX: u32 = 3;
const CHECK_BYTES: u64 = 1 << 20;

/// How long the end of a daemon waits for the queued items to be written.
const DRAIN: Duration = Duration::from_secs(2);

/// Notes from the writer waiting for the daemon's log, at most.
const NOTES_QUEUED: usize = 64;

/// The bytes of a flight log's block (REMOTE_LOG_DATA_BLOCK's `data`).
pub const BLOCK_LEN: usize = 200;

/// What a kind of log writes, and how its files are named.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// `.tlog`: frames after their time, one file after the other by size.
    Telemetry,
    /// `.bin`: the flight stack's blocks, each at its place; a file is one
    /// log of the flight stack, never cut (its formats come first).
    FlightLog,
}

impl Kind {
    /// The files' ending.
    fn suffix(self) -> &'static str {
        match self {
            Kind::Telemetry => "Z.tlog",
            Kind::FlightLog => "Z.bin",
        }
    }
}

/// Where and how much to log.
#[derive(Debug, Clone)]
pub struct FilesOptions {
    /// The directory of the files (created if missing).
    pub dir: PathBuf,
    /// A `.tlog` file is closed and the next begun before it would grow
    /// past this.
    pub max_size: u64,
    /// The free space kept on the directory's file system.
    pub min_free: u64,
    /// At most this many of the program's files of the kind are kept, the
    /// oldest deleted as a new one begins (`None`: no limit).
    pub max_files: Option<u32>,
}

/// One item on its way to the writer.
pub enum Item {
    /// A frame and its timestamp (`.tlog`).
    Frame {
        us: u64,
        len: usize,
        bytes: [u8; MAX_FRAME_LEN],
    },
    /// A block of the flight stack's log, at `seqno × 200` in its file.
    Block { seqno: u32, data: [u8; BLOCK_LEN] },
    /// The file ends here: the next item begins a new one.
    Close,
}

impl Item {
    /// A frame (its bytes as on the wire) and its timestamp.
    pub fn frame(us: u64, frame: &[u8]) -> Item {
        let len = frame.len().min(MAX_FRAME_LEN);
        let mut bytes = [0; MAX_FRAME_LEN];
        bytes[..len].copy_from_slice(&frame[..len]);
        Item::Frame { us, len, bytes }
    }

    /// Where it goes in its file, and its bytes: a frame after its
    /// timestamp at the end (`None`), a block at its place.
    fn bytes(&self) -> (Option<u64>, [&[u8]; 2]) {
        match self {
            Item::Frame { len, bytes, .. } => (None, [&[], &bytes[..*len]]),
            Item::Block { seqno, data } => {
                (Some(u64::from(*seqno) * BLOCK_LEN as u64), [data, &[]])
            }
            Item::Close => (None, [&[], &[]]),
        }
    }
}

/// Counts the writer keeps, read by the daemon for its reports.
#[derive(Debug, Default)]
struct Shared {
    written: AtomicU64,
    /// Items not written: below the floor, or the disk refused them.
    unwritten: AtomicU64,
    files: AtomicU64,
    deleted: AtomicU64,
}

/// What a log did, for reports and the summary.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counts {
    /// Items written.
    pub written: u64,
    /// Items dropped because the queue was full (the disk was slow).
    pub dropped: u64,
    /// Items not written: free space below the floor, or write errors.
    pub unwritten: u64,
    /// Files begun (one given up empty after a write error is not
    /// counted).
    pub files: u64,
    /// Old files deleted to keep the floor or the number of files.
    pub deleted: u64,
}

impl Counts {
    /// The counts as a JSON object, for `--events`.
    pub fn json(&self) -> serde_json::Value {
        serde_json::json!({
            "written": self.written,
            "dropped_queue_full": self.dropped,
            "not_written": self.unwritten,
            "files": self.files,
            "deleted": self.deleted,
        })
    }

    /// The counts in the log's words: `what` names the log (`tlog`),
    /// `items` what it writes (`frames`).
    pub fn line(&self, what: &str, items: &str) -> String {
        format!(
            "{what}: {} {items} written ({} files begun), {} dropped (disk too slow), {} not written (low space or write errors), {} old files deleted",
            self.written, self.files, self.dropped, self.unwritten, self.deleted
        )
    }
}

/// The daemon's side of a log's files: items in, notes and counts out.
pub struct Files {
    queue: Option<SyncSender<Item>>,
    dropped: u64,
    shared: Arc<Shared>,
    notes: Receiver<(Level, String)>,
    /// Closed by the writer thread when it has written every item.
    written: Receiver<()>,
}

impl Files {
    /// Creates `o.dir` if needed and starts the writer of files of `kind`;
    /// `program` names the files (`fbwag-router-…`). A directory that
    /// cannot be made (a card mounted read-only, a name taken by a file)
    /// is said in the log and tried again with each new file: routing
    /// never waits for the log. Only a writer thread that cannot start is
    /// an error; `option` names the option in it.
    pub fn start(o: &FilesOptions, program: &str, kind: Kind, option: &str) -> io::Result<Files> {
        let context =
            |e: io::Error| io::Error::new(e.kind(), format!("{option} {}: {e}", o.dir.display()));
        let (queue, items) = mpsc::sync_channel::<Item>(QUEUED);
        let (note_tx, notes) = mpsc::sync_channel(NOTES_QUEUED);
        let created = fs::create_dir_all(&o.dir);
        if let Err(e) = &created {
            let _ = note_tx.try_send((
                Level::Error,
                format!(
                    "{option}: cannot create {}: {e}; tried again with each new file, counted as not written meanwhile",
                    o.dir.display()
                ),
            ));
        }
        let (done, written) = mpsc::channel::<()>();
        let shared = Arc::new(Shared::default());
        let mut writer = Writer::new(o, program, kind, shared.clone(), note_tx, free_bytes);
        // Said already: the first file that cannot be made is not said again.
        writer.failing = created.is_err();
        std::thread::Builder::new()
            .name(option.trim_start_matches('-').into())
            .spawn(move || {
                writer.run(items);
                drop(done);
            })
            .map_err(context)?;
        Ok(Files {
            queue: Some(queue),
            dropped: 0,
            shared,
            notes,
            written,
        })
    }

    /// A writer that takes nothing from a queue of `len` items, for tests:
    /// the items queued, and the queue.
    #[cfg(test)]
    pub(super) fn stalled(len: usize) -> (Files, Receiver<Item>) {
        let (queue, items) = mpsc::sync_channel(len);
        let (_, notes) = mpsc::sync_channel(1);
        let (_, written) = mpsc::channel();
        let files = Files {
            queue: Some(queue),
            dropped: 0,
            shared: Arc::new(Shared::default()),
            notes,
            written,
        };
        (files, items)
    }

    /// Queues `item`. Never waits: a full queue drops it, counted; false
    /// then.
    pub fn push(&mut self, item: Item) -> bool {
        let Some(queue) = &self.queue else {
            return false;
        };
        if queue.try_send(item).is_err() {
            // Full (the disk is slow) or the writer is gone.
            self.dropped += 1;
            return false;
        }
        true
    }

    /// The writer's notes (files begun and deleted, the floor reached or
    /// left, write errors), into the daemon's log.
    pub fn notes(&mut self, log: &mut Log) {
        while let Ok((level, note)) = self.notes.try_recv() {
            log.at(level, &note);
        }
    }

    /// The counts so far.
    pub fn counts(&self) -> Counts {
        let get = |n: &AtomicU64| n.load(Ordering::Relaxed);
        Counts {
            written: get(&self.shared.written),
            dropped: self.dropped,
            unwritten: get(&self.shared.unwritten),
            files: get(&self.shared.files),
            deleted: get(&self.shared.deleted),
        }
    }

    /// Ends the log: the queued items are written (waiting [`DRAIN`] at
    /// most) and the file closed; the last notes go to `log`. The counts
    /// at the end.
    pub fn finish(&mut self, log: &mut Log) -> Counts {
        self.queue = None;
        let _ = self.written.recv_timeout(DRAIN);
        self.notes(log);
        self.counts()
    }
}

/// The file being written.
struct OpenFile {
    out: BufWriter<File>,
    path: PathBuf,
    /// Its length, the buffered bytes included: what rotation counts.
    size: u64,
    /// Where the next bytes written go.
    pos: u64,
    /// Its size at the last flush that succeeded: what is surely on disk.
    flushed: u64,
    /// Items buffered since that flush: counted as written once a flush
    /// succeeds, as not written if it fails.
    pending: u64,
}

/// The writer thread's state.
struct Writer {
    dir: PathBuf,
    kind: Kind,
    /// Every file's name begins with it; only such files are ever deleted.
    prefix: String,
    max_size: u64,
    min_free: u64,
    max_files: Option<u32>,
    file: Option<OpenFile>,
    /// Below the floor with nothing left to delete: items are counted, not
    /// written.
    stopped: bool,
    checked_at: Option<Instant>,
    since_check: u64,
    /// A write or open failed, said once until an item is written again.
    failing: bool,
    /// When a file could not be created or written: the next file is
    /// tried a second later, not with the next item.
    failed_at: Option<Instant>,
    /// Files in a row given up on a write error (a file closed whole
    /// resets it); at [`FAILED_FILES_MAX`] the log is given up.
    failed_files: u32,
    shared: Arc<Shared>,
    notes: SyncSender<(Level, String)>,
    /// The free space of a directory's file system ([`free_bytes`]).
    free: fn(&Path) -> io::Result<u64>,
}

impl Writer {
    fn new(
        o: &FilesOptions,
        program: &str,
        kind: Kind,
        shared: Arc<Shared>,
        notes: SyncSender<(Level, String)>,
        free: fn(&Path) -> io::Result<u64>,
    ) -> Writer {
        let max_size = match kind {
            Kind::Telemetry => o.max_size.max(MAX_FRAME_LEN as u64 + 8),
            Kind::FlightLog => u64::MAX,
        };
        Writer {
            dir: o.dir.clone(),
            kind,
            prefix: format!("fbwag-{program}-"),
            max_size,
            min_free: o.min_free,
            max_files: o.max_files.filter(|n| *n > 0),
            file: None,
            stopped: false,
            checked_at: None,
            since_check: 0,
            failing: false,
            failed_at: None,
            failed_files: 0,
            shared,
            notes,
            free,
        }
    }

    /// Writes items as they come, flushing whenever the queue is empty
    /// (so a file holds what arrived up to a moment ago), until the daemon
    /// ends the log.
    fn run(mut self, items: Receiver<Item>) {
        loop {
            match items.recv_timeout(CHECK_EVERY) {
                Ok(item) => {
                    self.write(&item);
                    while let Ok(item) = items.try_recv() {
                        self.write(&item);
                    }
                    self.flush();
                }
                // Idle: space may have come back.
                Err(RecvTimeoutError::Timeout) if self.stopped => self.check_space(),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => break,
            }
        }
        self.close();
    }

    fn note(&self, level: Level, what: String) {
        let _ = self.notes.try_send((level, what));
    }

    fn write(&mut self, item: &Item) {
        let (at, parts) = item.bytes();
        let stamp;
        let parts = match item {
            Item::Close => return self.close(),
            Item::Frame { us, .. } => {
                stamp = us.to_be_bytes();
                [&stamp[..], parts[1]]
            }
            Item::Block { .. } => parts,
        };
        let size = (parts[0].len() + parts[1].len()) as u64;
        let full = self
            .file
            .as_ref()
            .is_some_and(|f| f.size > 0 && f.size.saturating_add(size) > self.max_size);
        if full {
            self.close();
        }
        let due = self.checked_at.is_none_or(|t| t.elapsed() >= CHECK_EVERY);
        // Also before each new file; while stopped, only when due (a
        // directory listing per item would make the disk slower still).
        let new_file = self.file.is_none() && !self.stopped;
        if due || self.since_check >= CHECK_BYTES || new_file {
            self.check_space();
        }
        let retry = self.failed_at.is_none_or(|t| t.elapsed() >= CHECK_EVERY);
        let given_up = self.failed_files >= FAILED_FILES_MAX;
        if self.stopped || given_up || (self.file.is_none() && !(retry && self.open())) {
            self.shared.unwritten.fetch_add(1, Ordering::Relaxed);
            return;
        }
        let Some(f) = &mut self.file else {
            return;
        };
        let result = put(f, at, &parts);
        match result {
            Ok(()) => {
                f.pending += 1;
                self.since_check += size;
            }
            Err(e) => {
                self.shared.unwritten.fetch_add(1, Ordering::Relaxed);
                self.give_up_file(&e);
            }
        }
    }

    /// Says `what` once until a write succeeds again.
    fn fail(&mut self, what: String) {
        if !self.failing {
            self.failing = true;
            self.note(Level::Error, what);
        }
    }

    /// Hands what is buffered to the system: the items since the last
    /// flush are written when it takes them.
    fn flush(&mut self) {
        let label = self.label();
        let Some(f) = &mut self.file else {
            return;
        };
        match f.out.flush() {
            // Its directory removed (an operator's `rm -rf`): what went
            // to it is gone, and a new file (and directory) is begun.
            Ok(()) if unlinked(f.out.get_ref()) => {
                let gone = io::Error::new(io::ErrorKind::NotFound, "removed while written");
                self.give_up_file(&gone);
            }
            Ok(()) => {
                if f.flushed == 0 && f.size > 0 {
                    // Said once it holds an item: a file given up empty
                    // (a full disk) is never named.
                    let writing = format!("{label}: writing {}", f.path.display());
                    let _ = self.notes.try_send((Level::Info, writing));
                }
                self.shared.written.fetch_add(f.pending, Ordering::Relaxed);
                if f.pending > 0 {
                    self.failing = false;
                }
                f.pending = 0;
                f.flushed = f.size;
            }
            Err(e) => self.give_up_file(&e),
        }
    }

    /// The log's name in notes.
    fn label(&self) -> &'static str {
        match self.kind {
            Kind::Telemetry => "tlog",
            Kind::FlightLog => "flight log",
        }
    }

    /// Gives the open file up after a failed write (a full disk, a file
    /// size limit, an I/O error): cut back to what the last good flush
    /// wrote, so no half record stays, and removed if that is nothing; the
    /// items since are counted as not written. The next file is tried a
    /// second later: a lasting error makes neither a file nor a log line
    /// per item.
    fn give_up_file(&mut self, e: &io::Error) {
        let Some(f) = self.file.take() else {
            return;
        };
        self.shared
            .unwritten
            .fetch_add(f.pending, Ordering::Relaxed);
        // Not flushed on the way out: the buffer is what failed.
        let (file, _) = f.out.into_parts();
        let _ = file.set_len(f.flushed);
        drop(file);
        if f.flushed == 0 && fs::remove_file(&f.path).is_ok() {
            self.shared.files.fetch_sub(1, Ordering::Relaxed);
        }
        self.failed_at = Some(Instant::now());
        let label = self.label();
        self.fail(format!("{label}: cannot write {}: {e}", f.path.display()));
        self.failed_files += 1;
        if self.failed_files == FAILED_FILES_MAX {
            self.note(
                Level::Error,
                format!(
                    "{label}: given up: {FAILED_FILES_MAX} files in a row failed (the last: {e}); \
                 what comes is counted as not written until the end of the run"
                ),
            );
        }
    }

    fn close(&mut self) {
        self.flush();
        if self.file.take().is_some() {
            self.failed_files = 0;
        }
    }

    /// Begins a file named by the time now (microseconds, UTC): names sort
    /// in time order. A name taken already is tried a microsecond later.
    /// Then at most `max_files` of the kind are kept.
    fn open(&mut self) -> bool {
        // The directory may be new (it could not be made before) or gone.
        let _ = fs::create_dir_all(&self.dir);
        let mut us = now_us();
        let mut last = None;
        for _ in 0..1000 {
            let path = self.dir.join(file_name(&self.prefix, us, self.kind));
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(f) => {
                    self.failed_at = None;
                    self.shared.files.fetch_add(1, Ordering::Relaxed);
                    self.file = Some(OpenFile {
                        out: BufWriter::with_capacity(64 * 1024, f),
                        path,
                        size: 0,
                        pos: 0,
                        flushed: 0,
                        pending: 0,
                    });
                    self.keep_max_files();
                    return true;
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => us += 1,
                Err(e) => {
                    last = Some(format!(
                        "{}: cannot create {}: {e}",
                        self.label(),
                        path.display()
                    ));
                    break;
                }
            }
        }
        let what = last.unwrap_or_else(|| {
            format!(
                "{}: no free file name in {}",
                self.label(),
                self.dir.display()
            )
        });
        self.failed_at = Some(Instant::now());
        self.fail(what);
        false
    }

    /// The program's files of the kind in the directory, oldest first,
    /// but the open one.
    fn own_files(&self) -> Vec<PathBuf> {
        let open = self.file.as_ref().map(|f| f.path.clone());
        let Ok(entries) = fs::read_dir(&self.dir) else {
            return Vec::new();
        };
        let mut own: Vec<PathBuf> = entries
            .filter_map(Result::ok)
            .filter(|e| {
                e.file_name()
                    .to_str()
                    .is_some_and(|n| is_own(&self.prefix, n, self.kind))
            })
            .map(|e| e.path())
            .filter(|p| Some(p) != open.as_ref())
            .collect();
        own.sort();
        own
    }

    /// Deletes the oldest files of the kind while more than `max_files`
    /// are kept (the open one counted).
    fn keep_max_files(&mut self) {
        let Some(max) = self.max_files else {
            return;
        };
        let old = self.own_files();
        let extra = (old.len() + 1).saturating_sub(max as usize);
        for path in old.into_iter().take(extra) {
            if fs::remove_file(&path).is_ok() {
                self.shared.deleted.fetch_add(1, Ordering::Relaxed);
                self.note(
                    Level::Info,
                    format!(
                        "{}: deleted {}: {max} files at most (--log-max-files)",
                        self.label(),
                        path.display()
                    ),
                );
            }
        }
    }

    /// Keeps the floor: below it, this program's oldest files go (never the
    /// open one); still below, writing stops until space returns.
    fn check_space(&mut self) {
        self.checked_at = Some(Instant::now());
        self.since_check = 0;
        let Ok(mut free) = (self.free)(&self.dir) else {
            // Unknown: writing goes on (errors, if any, come with the writes).
            return;
        };
        if free < self.min_free {
            free = self.delete_oldest(free);
        }
        match (free < self.min_free, self.stopped) {
            (true, false) => {
                self.stopped = true;
                self.close();
                self.note(Level::Error, format!(
                    "{}: stopped writing: {free} bytes free in {}, below the floor of {} (--tlog-min-free), and no older log of this program left to delete; counted as not written until space returns",
                    self.label(),
                    self.dir.display(),
                    self.min_free
                ));
            }
            (false, true) => {
                self.stopped = false;
                self.note(
                    Level::Notice,
                    format!("{}: writing again: {free} bytes free", self.label()),
                );
            }
            _ => {}
        }
    }

    /// Deletes this program's files of the kind in `dir`, oldest first,
    /// until `free` reaches the floor; the free space then.
    fn delete_oldest(&mut self, mut free: u64) -> u64 {
        for path in self.own_files() {
            if free >= self.min_free {
                break;
            }
            let size = fs::metadata(&path).map_or(0, |m| m.len());
            if fs::remove_file(&path).is_err() {
                continue;
            }
            self.shared.deleted.fetch_add(1, Ordering::Relaxed);
            free = (self.free)(&self.dir).unwrap_or(free.saturating_add(size));
            self.note(
                Level::Info,
                format!(
                    "{}: deleted {} ({size} bytes): {free} bytes free, floor {}",
                    self.label(),
                    path.display(),
                    self.min_free
                ),
            );
        }
        free
    }
}

/// Writes `parts` into `f` at `at` (`None`: where the last write ended);
/// a write elsewhere flushes the buffer and moves there first.
fn put(f: &mut OpenFile, at: Option<u64>, parts: &[&[u8]; 2]) -> io::Result<()> {
    if let Some(at) = at.filter(|at| *at != f.pos) {
        f.out.seek(SeekFrom::Start(at))?;
        f.pos = at;
    }
    f.out.write_all(parts[0])?;
    f.out.write_all(parts[1])?;
    f.pos += (parts[0].len() + parts[1].len()) as u64;
    f.size = f.size.max(f.pos);
    Ok(())
}

/// Whether `file` was removed from its directory while open (writes to it
/// then reach no file anyone can read).
fn unlinked(file: &File) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        file.metadata().is_ok_and(|m| m.nlink() == 0)
    }
    #[cfg(not(unix))]
    {
        let _ = file;
        false
    }
}

/// Microseconds since the Unix epoch (0 for a clock set before it).
pub fn now_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// The free space of `dir`'s file system for an unprivileged writer.
#[cfg(unix)]
fn free_bytes(dir: &Path) -> io::Result<u64> {
    let s = rustix::fs::statvfs(dir)?;
    Ok(s.f_bavail.saturating_mul(s.f_frsize))
}

/// Elsewhere the floor cannot be checked: never below it.
#[cfg(not(unix))]
fn free_bytes(_dir: &Path) -> io::Result<u64> {
    Ok(u64::MAX)
}

/// `{prefix}YYYYMMDDTHHMMSS.uuuuuuZ.tlog` (or `.bin`), UTC: fixed width,
/// so names sort as times do (RFC 3339's basic form: its extended form
/// without the dashes and colons).
fn file_name(prefix: &str, us: u64, kind: Kind) -> String {
    let at = std::time::UNIX_EPOCH + Duration::from_micros(us);
    let stamp = humantime::format_rfc3339_micros(at).to_string();
    let basic: String = stamp
        .chars()
        .filter(|c| !matches!(c, '-' | ':' | 'Z'))
        .collect();
    format!("{prefix}{basic}{}", kind.suffix())
}

/// True for a name [`file_name`] gives with `prefix` and `kind`.
fn is_own(prefix: &str, name: &str, kind: Kind) -> bool {
    let Some(stamp) = name
        .strip_prefix(prefix)
        .and_then(|n| n.strip_suffix(kind.suffix()))
    else {
        return false;
    };
    let b = stamp.as_bytes();
    b.len() == 22
        && b.iter().enumerate().all(|(i, &c)| match i {
            8 => c == b'T',
            15 => c == b'.',
            _ => c.is_ascii_digit(),
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_utc_times_that_sort_and_are_recognised() {
        // 2024-02-29 23:59:59.000123 UTC.
        let us = 1_709_251_199_000_123;
        let name = file_name("fbwag-router-", us, Kind::Telemetry);
        assert_eq!(name, "fbwag-router-20240229T235959.000123Z.tlog");
        assert!(is_own("fbwag-router-", &name, Kind::Telemetry));
        assert!(!is_own("fbwag-cc-", &name, Kind::Telemetry));
        assert!(file_name("p-", us, Kind::Telemetry) < file_name("p-", us + 1, Kind::Telemetry));
        assert!(
            file_name("p-", 999_999, Kind::Telemetry) < file_name("p-", 1_000_000, Kind::Telemetry)
        );
        assert_eq!(
            file_name("p-", 0, Kind::Telemetry),
            "p-19700101T000000.000000Z.tlog"
        );
        for foreign in [
            "fbwag-router-notes.tlog",
            "fbwag-router-20240229T235959.000123Z.tlog.bak",
            "fbwag-router-2024022xT235959.000123Z.tlog",
            "other.tlog",
        ] {
            assert!(
                !is_own("fbwag-router-", foreign, Kind::Telemetry),
                "{foreign}"
            );
        }
    }

    /// The free space the writer under test sees.
    static FREE: AtomicU64 = AtomicU64::new(0);

    fn fake_free(_: &Path) -> io::Result<u64> {
        Ok(FREE.load(Ordering::Relaxed))
    }

    fn record(n: u8) -> Item {
        Item::frame(u64::from(n), &[n; 12])
    }

    fn options(dir: &Path, min_free: u64, max_files: Option<u32>) -> FilesOptions {
        FilesOptions {
            dir: dir.to_owned(),
            max_size: 1 << 20,
            min_free,
            max_files,
        }
    }

    #[test]
    fn below_the_floor_own_logs_go_oldest_first_then_writing_waits_for_space() {
        let dir = std::env::temp_dir().join(format!("fbwag-tlog-floor-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let old = [
            "fbwag-cc-20200101T000000.000000Z.tlog",
            "fbwag-cc-20200101T000001.000000Z.tlog",
        ];
        for name in old
            .iter()
            .chain(&["fbwag-router-20200101T000000.000000Z.tlog"])
        {
            fs::write(dir.join(name), b"x").unwrap();
        }
        let o = options(&dir, 1000, None);
        let shared = Arc::new(Shared::default());
        let (tx, notes) = mpsc::sync_channel(NOTES_QUEUED);
        let mut w = Writer::new(&o, "cc", Kind::Telemetry, shared.clone(), tx, fake_free);
        FREE.store(500, Ordering::Relaxed);
        for n in 0..3 {
            w.write(&record(n));
        }
        let said: Vec<String> = notes.try_iter().map(|(_, note)| note).collect();
        assert_eq!(shared.deleted.load(Ordering::Relaxed), 2, "{said:?}");
        assert!(
            said[0].contains(old[0]) && said[1].contains(old[1]),
            "oldest first: {said:?}"
        );
        let stops = said
            .iter()
            .filter(|n| n.contains("stopped writing"))
            .count();
        assert_eq!(stops, 1, "said once: {said:?}");
        assert_eq!(shared.unwritten.load(Ordering::Relaxed), 3);
        assert!(dir
            .join("fbwag-router-20200101T000000.000000Z.tlog")
            .exists());

        // Space returns: the next check (after a second) resumes writing.
        FREE.store(5000, Ordering::Relaxed);
        std::thread::sleep(CHECK_EVERY);
        w.write(&record(3));
        w.close();
        let said: Vec<String> = notes.try_iter().map(|(_, note)| note).collect();
        assert!(said.iter().any(|n| n.contains("writing again")), "{said:?}");
        assert_eq!(shared.written.load(Ordering::Relaxed), 1);
        let mut files: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok()?.file_name().into_string().ok())
            .filter(|n| is_own("fbwag-cc-", n, Kind::Telemetry))
            .collect();
        assert_eq!(files.len(), 1, "{files:?}");
        let bytes = fs::read(dir.join(files.pop().unwrap())).unwrap();
        assert_eq!(bytes[..8], 3u64.to_be_bytes());
        assert_eq!(bytes[8..], [3u8; 12]);
        let _ = fs::remove_dir_all(&dir);
    }

    /// The directory removed while a file is written (`rm -rf`): the
    /// frames that went to the removed file count as not written, it is
    /// said, and a second later a new directory and file are begun.
    #[cfg(unix)]
    #[test]
    fn a_file_removed_while_written_is_given_up_and_a_new_one_begun() {
        let dir = std::env::temp_dir().join(format!("fbwag-tlog-rm-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        let o = options(&dir, 0, None);
        let shared = Arc::new(Shared::default());
        let (tx, notes) = mpsc::sync_channel(NOTES_QUEUED);
        let mut w = Writer::new(&o, "router", Kind::Telemetry, shared.clone(), tx, |_| {
            Ok(u64::MAX)
        });
        w.write(&record(1));
        w.flush();
        fs::remove_dir_all(&dir).unwrap();
        w.write(&record(2));
        w.flush();
        assert_eq!(shared.written.load(Ordering::Relaxed), 1);
        assert_eq!(shared.unwritten.load(Ordering::Relaxed), 1);
        std::thread::sleep(CHECK_EVERY);
        w.write(&record(3));
        w.close();
        let said: Vec<String> = notes.try_iter().map(|(_, note)| note).collect();
        assert!(
            said.iter().any(|n| n.contains("removed while written")),
            "{said:?}"
        );
        assert_eq!(shared.written.load(Ordering::Relaxed), 2, "{said:?}");
        let files: Vec<_> = fs::read_dir(&dir).unwrap().collect();
        assert_eq!(files.len(), 1, "{said:?}");
        let bytes = fs::read(files[0].as_ref().unwrap().path()).unwrap();
        assert_eq!(bytes[8..], [3u8; 12]);
        let _ = fs::remove_dir_all(&dir);
    }

    #[test]
    fn file_names_are_the_utc_time_across_leap_years_and_centuries() {
        let name =
            |days: u64| file_name("p-", days * 86_400_000_000 + 3_723_000_042, Kind::Telemetry);
        assert_eq!(name(0), "p-19700101T010203.000042Z.tlog");
        assert_eq!(name(11_016), "p-20000229T010203.000042Z.tlog");
        assert_eq!(name(47_541), "p-21000301T010203.000042Z.tlog");
        assert_eq!(name(2_932_896), "p-99991231T010203.000042Z.tlog");
        assert!(is_own("p-", &name(11_016), Kind::Telemetry));
    }

    /// Blocks land at their place whatever their order; a new file begins
    /// after Close; the oldest go beyond the number of files kept, and
    /// only files of the kind (a .tlog stays).
    #[test]
    fn blocks_land_at_their_place_and_old_files_go_beyond_the_limit() {
        let dir = std::env::temp_dir().join(format!("fbwag-bin-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let tlog = "fbwag-router-20200101T000000.000000Z.tlog";
        let old = "fbwag-router-20200101T000000.000000Z.bin";
        fs::write(dir.join(tlog), b"x").unwrap();
        fs::write(dir.join(old), b"x").unwrap();
        let shared = Arc::new(Shared::default());
        let (tx, notes) = mpsc::sync_channel(NOTES_QUEUED);
        let o = options(&dir, 0, Some(2));
        let mut w = Writer::new(&o, "router", Kind::FlightLog, shared.clone(), tx, |_| {
            Ok(u64::MAX)
        });
        let block = |seqno: u32, b: u8| Item::Block {
            seqno,
            data: [b; BLOCK_LEN],
        };
        for (seqno, b) in [(0, 1), (2, 3), (1, 2), (2, 3)] {
            w.write(&block(seqno, b));
        }
        w.flush();
        let first = w.file.as_ref().unwrap().path.clone();
        w.write(&Item::Close);
        std::thread::sleep(Duration::from_micros(10));
        w.write(&block(0, 9));
        w.close();
        let bytes = fs::read(&first).unwrap();
        assert_eq!(bytes.len(), 3 * BLOCK_LEN);
        for (i, chunk) in bytes.chunks(BLOCK_LEN).enumerate() {
            assert!(chunk.iter().all(|&b| b == i as u8 + 1), "block {i}");
        }
        let said: Vec<String> = notes.try_iter().map(|(_, note)| note).collect();
        assert!(!dir.join(old).exists(), "{said:?}");
        assert!(dir.join(tlog).exists());
        assert_eq!(shared.deleted.load(Ordering::Relaxed), 1, "{said:?}");
        assert_eq!(shared.files.load(Ordering::Relaxed), 2);
        assert_eq!(shared.written.load(Ordering::Relaxed), 5);
        let _ = fs::remove_dir_all(&dir);
    }
}
