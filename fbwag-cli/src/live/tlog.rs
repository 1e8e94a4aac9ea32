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
//! [`Tlog::sent`]): a thread of its own writes them, through a bounded queue, so a slow disk never slows
//! routing; a frame that finds the queue full is dropped and counted. That
//! thread rotates files by size, keeps the file system's free space above
//! a floor by deleting this program's oldest logs (only files named as it
//! names them), and stops writing, once said in the log, while the floor
//! cannot be kept, resuming when space returns.

use super::{Level, Log};
use fbwag_dialect::mavframe::frame::MAX_FRAME_LEN;
use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, SyncSender};
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// The timestamp's low bits of the program's own frames (MAVProxy's mark
/// of what it sent).
pub const OWN_FRAMES: u8 = 3;

/// Frames queued for the writer, at most: about 1.2 MB, a few seconds of
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

/// How long the end of a daemon waits for the queued frames to be written.
const DRAIN: Duration = Duration::from_secs(2);

/// Notes from the writer waiting for the daemon's log, at most.
const NOTES_QUEUED: usize = 64;

/// Where and how much to log.
#[derive(Debug, Clone)]
pub struct TlogOptions {
    /// The directory of the files (created if missing).
    pub dir: PathBuf,
    /// A file is closed and the next begun before it would grow past this.
    pub max_size: u64,
    /// The free space kept on the directory's file system.
    pub min_free: u64,
}

/// One frame and its timestamp, on its way to the writer.
struct Record {
    us: u64,
    len: usize,
    bytes: [u8; MAX_FRAME_LEN],
}

/// Counts the writer keeps, read by the daemon for its reports.
#[derive(Debug, Default)]
struct Shared {
    written: AtomicU64,
    /// Frames not written: below the floor, or the disk refused them.
    unwritten: AtomicU64,
    files: AtomicU64,
    deleted: AtomicU64,
}

/// What the log did, for reports and the summary.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct TlogCounts {
    /// Frames written.
    pub written: u64,
    /// Frames dropped because the queue was full (the disk was slow).
    pub dropped: u64,
    /// Frames not written: free space below the floor, or write errors.
    pub unwritten: u64,
    /// Files begun (one given up empty after a write error is not
    /// counted).
    pub files: u64,
    /// Old files deleted to keep the floor.
    pub deleted: u64,
}

impl TlogCounts {
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

    /// The counts in the log's words.
    pub fn line(&self) -> String {
        format!(
            "tlog: {} frames written ({} files begun), {} dropped (disk too slow), {} not written (low space or write errors), {} old files deleted",
            self.written, self.files, self.dropped, self.unwritten, self.deleted
        )
    }
}

/// The daemon's side of the log: frames in, notes and counts out.
pub struct Tlog {
    queue: Option<SyncSender<Record>>,
    dropped: u64,
    shared: Arc<Shared>,
    notes: Receiver<(Level, String)>,
    /// Closed by the writer thread when it has written every frame.
    written: Receiver<()>,
}

impl Tlog {
    /// Creates `o.dir` if needed and starts the writer; `program` names the
    /// files (`fbwag-router-…`). A directory that cannot be made (a card
    /// mounted read-only, a name taken by a file) is said in the log and
    /// tried again with each new file: routing never waits for the log.
    /// Only a writer thread that cannot start is an error.
    pub fn start(o: &TlogOptions, program: &str) -> io::Result<Tlog> {
        let context =
            |e: io::Error| io::Error::new(e.kind(), format!("--tlog {}: {e}", o.dir.display()));
        let (queue, records) = mpsc::sync_channel::<Record>(QUEUED);
        let (note_tx, notes) = mpsc::sync_channel(NOTES_QUEUED);
        let created = fs::create_dir_all(&o.dir);
        if let Err(e) = &created {
            let _ = note_tx.try_send((
                Level::Error,
                format!(
                    "tlog: cannot create {}: {e}; tried again with each new file, frames counted as not written meanwhile",
                    o.dir.display()
                ),
            ));
        }
        let (done, written) = mpsc::channel::<()>();
        let shared = Arc::new(Shared::default());
        let mut writer = Writer::new(o, program, shared.clone(), note_tx, free_bytes);
        // Said already: the first file that cannot be made is not said again.
        writer.failing = created.is_err();
        std::thread::Builder::new()
            .name("tlog".into())
            .spawn(move || {
                writer.run(records);
                drop(done);
            })
            .map_err(context)?;
        Ok(Tlog {
            queue: Some(queue),
            dropped: 0,
            shared,
            notes,
            written,
        })
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

    /// Queues `frame` with the timestamp's low bits `tag`. Never waits: a
    /// full queue drops it, counted.
    fn push(&mut self, tag: u8, frame: &[u8]) {
        let Some(queue) = &self.queue else {
            return;
        };
        let len = frame.len().min(MAX_FRAME_LEN);
        let mut record = Record {
            us: (now_us() & !3) | u64::from(tag),
            len,
            bytes: [0; MAX_FRAME_LEN],
        };
        record.bytes[..len].copy_from_slice(&frame[..len]);
        if queue.try_send(record).is_err() {
            // Full (the disk is slow) or the writer is gone.
            self.dropped += 1;
        }
    }

    /// The writer's notes (files begun and deleted, the floor reached or
    /// left, write errors), into the daemon's log.
    pub fn notes(&mut self, log: &mut Log) {
        while let Ok((level, note)) = self.notes.try_recv() {
            log.at(level, &note);
        }
    }

    /// The counts so far.
    pub fn counts(&self) -> TlogCounts {
        let get = |n: &AtomicU64| n.load(Ordering::Relaxed);
        TlogCounts {
            written: get(&self.shared.written),
            dropped: self.dropped,
            unwritten: get(&self.shared.unwritten),
            files: get(&self.shared.files),
            deleted: get(&self.shared.deleted),
        }
    }

    /// Ends the log: the queued frames are written (waiting [`DRAIN`] at
    /// most) and the file closed; the last notes go to `log`. The counts
    /// at the end.
    pub fn finish(&mut self, log: &mut Log) -> TlogCounts {
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
    /// Bytes written to it, the buffered ones included: what rotation
    /// counts.
    size: u64,
    /// Its size at the last flush that succeeded: what is surely on disk.
    flushed: u64,
    /// Frames buffered since that flush: counted as written once a flush
    /// succeeds, as not written if it fails.
    pending: u64,
}

/// The writer thread's state.
struct Writer {
    dir: PathBuf,
    /// Every file's name begins with it; only such files are ever deleted.
    prefix: String,
    max_size: u64,
    min_free: u64,
    file: Option<OpenFile>,
    /// Below the floor with nothing left to delete: frames are counted, not
    /// written.
    stopped: bool,
    checked_at: Option<Instant>,
    since_check: u64,
    /// A write or open failed, said once until a frame is written again.
    failing: bool,
    /// When a file could not be created or written: the next file is
    /// tried a second later, not with the next frame.
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
        o: &TlogOptions,
        program: &str,
        shared: Arc<Shared>,
        notes: SyncSender<(Level, String)>,
        free: fn(&Path) -> io::Result<u64>,
    ) -> Writer {
        Writer {
            dir: o.dir.clone(),
            prefix: format!("fbwag-{program}-"),
            max_size: o.max_size.max(MAX_FRAME_LEN as u64 + 8),
            min_free: o.min_free,
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

    /// Writes records as they come, flushing whenever the queue is empty
    /// (so a file holds what arrived up to a moment ago), until the daemon
    /// ends the log.
    fn run(mut self, records: Receiver<Record>) {
        loop {
            match records.recv_timeout(CHECK_EVERY) {
                Ok(r) => {
                    self.write(&r);
                    while let Ok(r) = records.try_recv() {
                        self.write(&r);
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

    fn write(&mut self, r: &Record) {
        let size = 8 + r.len as u64;
        let full = self
            .file
            .as_ref()
            .is_some_and(|f| f.size > 0 && f.size + size > self.max_size);
        if full {
            self.close();
        }
        let due = self.checked_at.is_none_or(|t| t.elapsed() >= CHECK_EVERY);
        // Also before each new file; while stopped, only when due (a
        // directory listing per frame would make the disk slower still).
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
        let result = f
            .out
            .write_all(&r.us.to_be_bytes())
            .and_then(|()| f.out.write_all(&r.bytes[..r.len]));
        match result {
            Ok(()) => {
                f.size += size;
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

    /// Hands what is buffered to the system: the frames since the last
    /// flush are written when it takes them.
    fn flush(&mut self) {
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
                    // Said once it holds a frame: a file given up empty
                    // (a full disk) is never named.
                    let writing = format!("tlog: writing {}", f.path.display());
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

    /// Gives the open file up after a failed write (a full disk, a file
    /// size limit, an I/O error): cut back to what the last good flush
    /// wrote, so no half record stays, and removed if that is nothing; the
    /// frames since are counted as not written. The next file is tried a
    /// second later: a lasting error makes neither a file nor a log line
    /// per frame.
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
        self.fail(format!("tlog: cannot write {}: {e}", f.path.display()));
        self.failed_files += 1;
        if self.failed_files == FAILED_FILES_MAX {
            self.note(
                Level::Error,
                format!(
                    "tlog: given up: {FAILED_FILES_MAX} files in a row failed (the last: {e}); \
                 frames are counted as not written until the end of the run"
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
    fn open(&mut self) -> bool {
        // The directory may be new (it could not be made before) or gone.
        let _ = fs::create_dir_all(&self.dir);
        let mut us = now_us();
        let mut last = None;
        for _ in 0..1000 {
            let path = self.dir.join(file_name(&self.prefix, us));
            match OpenOptions::new().write(true).create_new(true).open(&path) {
                Ok(f) => {
                    self.failed_at = None;
                    self.shared.files.fetch_add(1, Ordering::Relaxed);
                    self.file = Some(OpenFile {
                        out: BufWriter::with_capacity(64 * 1024, f),
                        path,
                        size: 0,
                        flushed: 0,
                        pending: 0,
                    });
                    return true;
                }
                Err(e) if e.kind() == io::ErrorKind::AlreadyExists => us += 1,
                Err(e) => {
                    last = Some(format!("tlog: cannot create {}: {e}", path.display()));
                    break;
                }
            }
        }
        let what =
            last.unwrap_or_else(|| format!("tlog: no free file name in {}", self.dir.display()));
        self.failed_at = Some(Instant::now());
        self.fail(what);
        false
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
                    "tlog: stopped writing: {free} bytes free in {}, below the floor of {} (--tlog-min-free), and no older log of this program left to delete; frames are counted as not written until space returns",
                    self.dir.display(),
                    self.min_free
                ));
            }
            (false, true) => {
                self.stopped = false;
                self.note(
                    Level::Notice,
                    format!("tlog: writing again: {free} bytes free"),
                );
            }
            _ => {}
        }
    }

    /// Deletes this program's files in `dir`, oldest first, until `free`
    /// reaches the floor; the free space then.
    fn delete_oldest(&mut self, mut free: u64) -> u64 {
        let open = self.file.as_ref().map(|f| f.path.clone());
        let mut own: Vec<PathBuf> = match fs::read_dir(&self.dir) {
            Ok(entries) => entries
                .filter_map(Result::ok)
                .filter(|e| {
                    e.file_name()
                        .to_str()
                        .is_some_and(|n| is_own(&self.prefix, n))
                })
                .map(|e| e.path())
                .filter(|p| Some(p) != open.as_ref())
                .collect(),
            Err(_) => return free,
        };
        own.sort();
        for path in own {
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
                    "tlog: deleted {} ({size} bytes): {free} bytes free, floor {}",
                    path.display(),
                    self.min_free
                ),
            );
        }
        free
    }
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
fn now_us() -> u64 {
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

/// `{prefix}YYYYMMDDTHHMMSS.uuuuuuZ.tlog`, UTC: fixed width, so names
/// sort as times do (RFC 3339's basic form: its extended form without the
/// dashes and colons).
fn file_name(prefix: &str, us: u64) -> String {
    let at = std::time::UNIX_EPOCH + Duration::from_micros(us);
    let stamp = humantime::format_rfc3339_micros(at).to_string();
    let basic: String = stamp.chars().filter(|c| !matches!(c, '-' | ':')).collect();
    format!("{prefix}{basic}.tlog")
}

/// True for a name [`file_name`] gives with `prefix`.
fn is_own(prefix: &str, name: &str) -> bool {
    let Some(stamp) = name
        .strip_prefix(prefix)
        .and_then(|n| n.strip_suffix("Z.tlog"))
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
        let name = file_name("fbwag-router-", us);
        assert_eq!(name, "fbwag-router-20240229T235959.000123Z.tlog");
        assert!(is_own("fbwag-router-", &name));
        assert!(!is_own("fbwag-cc-", &name));
        assert!(file_name("p-", us) < file_name("p-", us + 1));
        assert!(file_name("p-", 999_999) < file_name("p-", 1_000_000));
        assert_eq!(file_name("p-", 0), "p-19700101T000000.000000Z.tlog");
        for foreign in [
            "fbwag-router-notes.tlog",
            "fbwag-router-20240229T235959.000123Z.tlog.bak",
            "fbwag-router-2024022xT235959.000123Z.tlog",
            "other.tlog",
        ] {
            assert!(!is_own("fbwag-router-", foreign), "{foreign}");
        }
    }

    /// The free space the writer under test sees.
    static FREE: AtomicU64 = AtomicU64::new(0);

    fn fake_free(_: &Path) -> io::Result<u64> {
        Ok(FREE.load(Ordering::Relaxed))
    }

    fn record(n: u8) -> Record {
        Record {
            us: u64::from(n),
            len: 12,
            bytes: [n; MAX_FRAME_LEN],
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
        let o = TlogOptions {
            dir: dir.clone(),
            max_size: 1 << 20,
            min_free: 1000,
        };
        let shared = Arc::new(Shared::default());
        let (tx, notes) = mpsc::sync_channel(NOTES_QUEUED);
        let mut w = Writer::new(&o, "cc", shared.clone(), tx, fake_free);
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
            .filter(|n| is_own("fbwag-cc-", n))
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
        let o = TlogOptions {
            dir: dir.clone(),
            max_size: 1 << 20,
            min_free: 0,
        };
        let shared = Arc::new(Shared::default());
        let (tx, notes) = mpsc::sync_channel(NOTES_QUEUED);
        let mut w = Writer::new(&o, "router", shared.clone(), tx, |_| Ok(u64::MAX));
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
    fn frames_that_find_the_queue_full_are_dropped_and_counted() {
        // A writer that takes nothing: the queue fills.
        let (queue, records) = mpsc::sync_channel(2);
        let (_note_tx, notes) = mpsc::sync_channel(1);
        let (_done, written) = mpsc::channel();
        let mut tlog = Tlog {
            queue: Some(queue),
            dropped: 0,
            shared: Arc::new(Shared::default()),
            notes,
            written,
        };
        for n in 0..5u8 {
            tlog.received(7, &[n; 21]);
        }
        tlog.sent(&[9; 300]);
        assert_eq!(tlog.counts().dropped, 4);
        let kept: Vec<Record> = records.try_iter().collect();
        assert_eq!(kept.len(), 2);
        assert_eq!(kept[0].bytes[..kept[0].len], [0; 21]);
        assert_eq!(kept[1].bytes[..kept[1].len], [1; 21]);
        // Link 7 is marked 2 (the last mark of a link), never 3.
        assert_eq!(kept[0].us & 3, 2);
    }

    #[test]
    fn file_names_are_the_utc_time_across_leap_years_and_centuries() {
        let name = |days: u64| file_name("p-", days * 86_400_000_000 + 3_723_000_042);
        assert_eq!(name(0), "p-19700101T010203.000042Z.tlog");
        assert_eq!(name(11_016), "p-20000229T010203.000042Z.tlog");
        assert_eq!(name(47_541), "p-21000301T010203.000042Z.tlog");
        assert_eq!(name(2_932_896), "p-99991231T010203.000042Z.tlog");
        assert!(is_own("p-", &name(11_016)));
    }
}
