//! Signing state that survives restarts (std): the signer's next timestamp
//! and the verifier's notion of now, floors and stream table, in a small
//! text file written atomically.
//!
//! Why: a verifier that forgets its table accepts, after a restart, replays
//! of frames it had accepted (those less than a minute old with a clock,
//! all of them without one); a signer that forgets its timestamp and whose
//! clock went back (a reboot without a real-time clock) is rejected as a
//! replay by every receiver that saw its earlier frames, until its clock
//! catches up. The MAVLink spec asks signers to store their timestamp (at
//! least once a minute) and to start from the greater of the clock and the
//! stored value.
//!
//! # Use in a long-running program
//!
//! ```no_run
//! use mavframe::signing::state::{StateError, StateFile};
//! use mavframe::signing::{Signer, Verifier};
//! # fn main() -> Result<(), StateError> {
//! # let key = [0u8; 32];
//! // At start: load, or begin from the clock when there is no file yet.
//! let (mut file, loaded) = StateFile::open("cc.signing-state")?;
//! let mut verifier: Verifier = file.state().verifier(key);
//! let mut signer: Signer = file.state().signer(key, 0);
//! // In the loop, after handling input and sending (cheap when nothing is
//! // due): a checkpoint, which covers a crash.
//! if file.due(Some(&signer)) {
//!     file.save(Some(&signer), Some(&verifier))?;
//! }
//! // At exit, always, when nothing more is signed: exactly what was signed.
//! file.save_final(Some(&signer), Some(&verifier))?;
//! # let _ = loaded; Ok(()) }
//! ```
//!
//! # Guarantees and limits
//!
//! - The file's `signer` value is a *bound*: every timestamp signed before
//!   the save is below it. A signer built from the state
//!   ([`SigningState::signer`]) starts at the greater of the clock and the
//!   bound, and never below: nothing it signs can be refused as a replay of
//!   what it signed before the restart.
//! - The bound records what was signed ([`Signer::signed_below`]), not where
//!   the signer was: a signer that adopted a peer's timestamp or kept up
//!   with the clock without signing moves nothing. [`StateFile::save_final`]
//!   (at exit) writes it exactly; a checkpoint ([`StateFile::save`]) after
//!   new signatures writes it plus [`SIGNER_MARGIN`] (10 s of timestamps),
//!   which covers what the signer signs until the next checkpoint, due
//!   ([`StateFile::due`]) once it signed within half the margin of the
//!   bound. A save with nothing signed since the last keeps the bound.
//! - Hence a restart with nothing signed since the last save leaves the
//!   signer where it was; a clean restart (the exit's `save_final`) starts
//!   just above the last frame signed, so any number of quick restarts do
//!   not drift ahead of the clock; and a restart after a crash starts above
//!   everything signed, at most [`SIGNER_MARGIN`] above the last frame
//!   signed (each crash after signing can move the signer that far ahead of
//!   the clock; the clock catches up in 10 s).
//! - A save that fails (full disk) loses the crash guarantee until the next
//!   one succeeds: after a crash in that time, the signer may restart below
//!   what receivers saw and be refused as a replay until its timestamp
//!   passes it, or it adopts a timestamp its link verified (unavailability,
//!   not a replay).
//! - A verifier built from the state rejects replays of every frame it had
//!   accepted up to the last save. Frames it accepted after the last save
//!   and before a crash (at most [`SAVE_INTERVAL`] of them, with the
//!   recommended loop) can be replayed once after the restart; a clean exit
//!   that saves leaves no such window.
//! - A saved notion of now is kept even when the clock is behind it (a
//!   receiver without a clock has nothing else). If it was saved from a
//!   clock that ran far ahead, new streams are `TooOld` until real time
//!   catches up: remove the file to start from the clock again.
//! - The state holds timestamps only, never the key, and restoring only
//!   raises values (see [`Verifier::restore`]). Whoever can write the file
//!   can lower them, so it belongs where the program's key is: writable by
//!   its user only. One file per process: two processes sharing one would
//!   overwrite each other's state.
//!
//! # Format (version 2)
//!
//! ASCII lines, each ending in `\n`, numbers in decimal, in this order:
//!
//! ```text
//! mavframe-signing-state 2
//! signer <the signer's bound (see above), or "none">
//! newest <the verifier's notion of now>
//! floors <16 numbers separated by one space: the eviction floors by bucket>
//! stream <link id> <system id> <component id> <last timestamp>
//! check <16 lowercase hex digits>
//! ```
//!
//! There are zero to [`MAX_STREAMS`] `stream` lines, least recently accepted
//! first. Timestamps are below 2^48 (the signature block's width). `check`
//! is the first 8 bytes of the SHA-256 of every byte before its line, so a
//! truncated or damaged file is an error rather than lowered timestamps.
//! Files are at most [`MAX_FILE_LEN`] bytes.
//!
//! Version 1 files are read too: the same lines, but `signer` was the
//! signer's next timestamp, to which a restart added [`SIGNER_MARGIN`]; it
//! is read as that sum (what a version 1 reader would have started from).
//! Files are written as version 2.

use super::{timestamp_now, Signer, StreamState, Verifier, FLOOR_BUCKETS};
use sha2::{Digest, Sha256};
use std::borrow::ToOwned;
use std::fmt::{self, Write as _};
use std::format;
use std::fs;
use std::io::{self, Read as _, Write as _};
use std::path::{Path, PathBuf};
use std::string::String;
use std::time::{Duration, Instant};
use std::vec::Vec;

/// Format version this code writes (it reads version 1 too).
pub const VERSION: u32 = 2;

/// How far above the last frame signed a checkpoint puts the signer's bound
/// (10 s of timestamps): more than it signs until the next checkpoint
/// (see the module docs).
pub const SIGNER_MARGIN: u64 = 1_000_000;

/// How often [`StateFile::due`] asks for a save when the state changed.
pub const SAVE_INTERVAL: Duration = Duration::from_secs(1);

/// Most `stream` lines a file may have.
pub const MAX_STREAMS: usize = 1024;

/// Largest file accepted (a full table of [`MAX_STREAMS`] fits well below).
pub const MAX_FILE_LEN: u64 = 64 * 1024;

/// Timestamps are 48-bit on the wire.
const MAX_TIMESTAMP: u64 = (1 << 48) - 1;

const MAGIC: &str = "mavframe-signing-state";

/// Why a state file could not be read or written.
#[derive(Debug)]
#[non_exhaustive]
pub enum StateError {
    /// There is no file at the path (a first start).
    Missing,
    /// The path is not a regular file (a directory, FIFO or device).
    NotAFile,
    /// The file is larger than [`MAX_FILE_LEN`].
    TooLarge {
        /// Its length in bytes.
        len: u64,
    },
    /// Reading or writing failed.
    Io(io::Error),
    /// The file ends before its `check` line (empty, or cut short).
    Truncated,
    /// The `check` line does not match the contents (damaged).
    Checksum,
    /// The file is of a format version this code does not read.
    UnsupportedVersion(u32),
    /// A line is not what the format says.
    Corrupt {
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        reason: &'static str,
    },
}

impl fmt::Display for StateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StateError::Missing => f.write_str("no signing state file"),
            StateError::NotAFile => f.write_str("signing state path is not a regular file"),
            StateError::TooLarge { len } => write!(
                f,
                "signing state file is {len} bytes, more than {MAX_FILE_LEN}"
            ),
            StateError::Io(e) => write!(f, "signing state file: {e}"),
            StateError::Truncated => f.write_str("signing state file is truncated"),
            StateError::Checksum => f.write_str("signing state file is damaged (checksum)"),
            StateError::UnsupportedVersion(v) => {
                write!(f, "signing state file has unsupported version {v}")
            }
            StateError::Corrupt { line, reason } => {
                write!(f, "signing state file, line {line}: {reason}")
            }
        }
    }
}

impl std::error::Error for StateError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            StateError::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<io::Error> for StateError {
    fn from(e: io::Error) -> Self {
        match e.kind() {
            io::ErrorKind::NotFound => StateError::Missing,
            _ => StateError::Io(e),
        }
    }
}

/// The saved signing state of one program (see the module docs).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct SigningState {
    /// The signer's bound, if the program signs: every timestamp it signed
    /// is below it, and a restarted signer starts there or later.
    pub signer: Option<u64>,
    /// The verifier's notion of now.
    pub newest: u64,
    /// The verifier's eviction floors.
    pub floors: [u64; FLOOR_BUCKETS],
    /// The verifier's streams, least recently accepted first.
    pub streams: Vec<StreamState>,
}

impl SigningState {
    /// The state of `signer` and `verifier` (either may be absent); the
    /// signer's bound exactly what it signed ([`Signer::signed_below`]).
    pub fn capture<const N: usize>(
        signer: Option<&Signer>,
        verifier: Option<&Verifier<N>>,
    ) -> Self {
        let mut s = SigningState {
            signer: signer.map(Signer::signed_below),
            ..SigningState::default()
        };
        if let Some(v) = verifier {
            s.newest = v.newest_timestamp();
            s.floors = v.floors();
            s.streams = v.streams().collect();
        }
        s
    }

    /// Where a restored signer starts when the clock reads `now`: the
    /// greater of `now` and the saved bound (which holds any margin a
    /// crash needs: see the module docs).
    pub fn signer_start(&self, now: u64) -> u64 {
        now.max(self.signer.unwrap_or(0))
    }

    /// A signer for `key` and `link_id` starting at
    /// [`signer_start`](Self::signer_start) of `now`, whose
    /// [`signed_below`](Signer::signed_below) is the saved bound (so saving
    /// it before it signs keeps the bound where it was).
    pub fn signer_at(&self, key: [u8; 32], link_id: u8, now: u64) -> Signer {
        let mut signer = Signer::new(key, link_id, self.signer_start(now));
        signer.signed_below = self.signer.unwrap_or(0);
        signer
    }

    /// [`signer_at`](Self::signer_at) the system clock.
    pub fn signer(&self, key: [u8; 32], link_id: u8) -> Signer {
        self.signer_at(key, link_id, timestamp_now())
    }

    /// A verifier for `key` on the system clock
    /// ([`Verifier::starting_now`]) with this state restored.
    pub fn verifier<const N: usize>(&self, key: [u8; 32]) -> Verifier<N> {
        self.verifier_with_clock(key, timestamp_now)
    }

    /// A verifier for `key` reading `clock` ([`Verifier::with_clock`]) with
    /// this state restored.
    pub fn verifier_with_clock<const N: usize>(
        &self,
        key: [u8; 32],
        clock: fn() -> u64,
    ) -> Verifier<N> {
        let mut v = Verifier::with_clock(key, clock);
        self.restore_into(&mut v);
        v
    }

    /// Raises `verifier` to this state ([`Verifier::restore`]).
    pub fn restore_into<const N: usize>(&self, verifier: &mut Verifier<N>) {
        verifier.restore(self.newest, &self.floors, self.streams.iter().copied());
    }

    /// The file's text (see the module docs).
    pub fn to_text(&self) -> String {
        let mut t = String::new();
        // Writing to a String cannot fail.
        let _ = writeln!(t, "{MAGIC} {VERSION}");
        let _ = match self.signer {
            Some(ts) => writeln!(t, "signer {ts}"),
            None => writeln!(t, "signer none"),
        };
        let _ = writeln!(t, "newest {}", self.newest);
        t.push_str("floors");
        for f in &self.floors {
            let _ = write!(t, " {f}");
        }
        t.push('\n');
        for s in &self.streams {
            let _ = writeln!(
                t,
                "stream {} {} {} {}",
                s.link_id, s.sysid, s.compid, s.timestamp
            );
        }
        let _ = writeln!(t, "check {}", check(t.as_bytes()));
        t
    }

    /// Parses a file's bytes (see the module docs; a version 1 file's
    /// `signer` is read with [`SIGNER_MARGIN`] added).
    pub fn from_text(bytes: &[u8]) -> Result<Self, StateError> {
        let (text, version) = parse::split(bytes)?;
        let mut state = parse::body(text)?;
        if version == 1 {
            state.signer = state
                .signer
                .map(|next| next.saturating_add(SIGNER_MARGIN).min(MAX_TIMESTAMP));
        }
        Ok(state)
    }

    /// Reads the file at `path`.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, StateError> {
        let path = path.as_ref();
        // Refuse FIFOs and devices before opening: opening a FIFO blocks.
        let meta = fs::metadata(path)?;
        if !meta.is_file() {
            return Err(StateError::NotAFile);
        }
        let mut bytes = Vec::new();
        fs::File::open(path)?
            .take(MAX_FILE_LEN + 1)
            .read_to_end(&mut bytes)?;
        if bytes.len() as u64 > MAX_FILE_LEN {
            return Err(StateError::TooLarge {
                len: meta.len().max(bytes.len() as u64),
            });
        }
        Self::from_text(&bytes)
    }

    /// Writes the file at `path` atomically: a temporary file next to it,
    /// flushed to disk, then renamed over it, so a crash leaves either the
    /// old file or the new one, never a mix.
    pub fn save(&self, path: impl AsRef<Path>) -> Result<(), StateError> {
        let path = path.as_ref();
        let tmp = temp_path(path);
        let result =
            write_synced(&tmp, self.to_text().as_bytes()).and_then(|()| fs::rename(&tmp, path));
        if let Err(e) = result {
            // Best effort: do not leave the temporary file behind.
            let _ = fs::remove_file(&tmp);
            return Err(StateError::Io(e));
        }
        sync_dir(path);
        Ok(())
    }
}

/// `PATH.<pid>.tmp`, in the same directory (a rename within one file
/// system is atomic).
fn temp_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(format!(".{}.tmp", std::process::id()));
    PathBuf::from(name)
}

fn write_synced(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut f = fs::File::create(path)?;
    f.write_all(bytes)?;
    f.sync_all()
}

/// Makes the rename durable: on Unix, sync the directory. Best effort: some
/// platforms cannot open a directory, and the file's own data is synced.
fn sync_dir(path: &Path) {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    if let Ok(d) = fs::File::open(dir) {
        let _ = d.sync_all();
    }
}

/// The `check` value of `body`: 8 bytes of its SHA-256, in hex.
fn check(body: &[u8]) -> String {
    let digest = Sha256::digest(body);
    let mut hex = String::with_capacity(16);
    for b in &digest[..8] {
        let _ = write!(hex, "{b:02x}");
    }
    hex
}

/// The parser, line by line.
mod parse {
    use super::*;

    /// Checks the header, the ending and the checksum; returns the text
    /// before the `check` line and the format version.
    pub(super) fn split(bytes: &[u8]) -> Result<(&str, u32), StateError> {
        let version = version(bytes)?;
        let Some(content) = bytes.strip_suffix(b"\n") else {
            return Err(StateError::Truncated);
        };
        let at = content
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1);
        let (body, last) = bytes.split_at(at);
        let Some(sum) = last.strip_prefix(b"check ") else {
            return Err(StateError::Truncated);
        };
        if sum != format!("{}\n", check(body)).as_bytes() {
            return Err(StateError::Checksum);
        }
        // The checksum matched, so this is what was written; still, a file
        // written by hand with a fresh checksum must be ASCII.
        let text = std::str::from_utf8(body).map_err(|_| StateError::Corrupt {
            line: 1,
            reason: "not text",
        })?;
        Ok((text, version))
    }

    /// The first line: the magic and a version this code reads (1 or 2).
    fn version(bytes: &[u8]) -> Result<u32, StateError> {
        let bad = StateError::Corrupt {
            line: 1,
            reason: "not a mavframe signing state file",
        };
        let first = bytes.split(|&b| b == b'\n').next().unwrap_or_default();
        let Some(rest) = first.strip_prefix(MAGIC.as_bytes()) else {
            // An empty file or a cut magic: truncated, not foreign.
            return Err(if MAGIC.as_bytes().starts_with(first) {
                StateError::Truncated
            } else {
                bad
            });
        };
        let Some(digits) = rest.strip_prefix(b" ") else {
            return Err(if rest.is_empty() {
                StateError::Truncated
            } else {
                bad
            });
        };
        match std::str::from_utf8(digits).ok().and_then(decimal) {
            Some(v) if (1..=u64::from(VERSION)).contains(&v) => Ok(v as u32),
            Some(v) => Err(StateError::UnsupportedVersion(
                u32::try_from(v).unwrap_or(u32::MAX),
            )),
            // The line may be cut: the checksum step tells.
            None if bytes.len() == first.len() => Err(StateError::Truncated),
            None => Err(bad),
        }
    }

    /// The lines between the header and `check`.
    pub(super) fn body(text: &str) -> Result<SigningState, StateError> {
        let end = text.lines().count() + 1;
        let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l)).skip(1);
        let mut next = |key: &'static str, what: &'static str| {
            let (n, l) = lines.next().ok_or(StateError::Corrupt {
                line: end,
                reason: what,
            })?;
            let rest = l
                .strip_prefix(key)
                .and_then(|r| r.strip_prefix(' '))
                .ok_or(StateError::Corrupt {
                    line: n,
                    reason: what,
                })?;
            Ok::<_, StateError>((n, rest))
        };
        let (n, signer) = next("signer", "expected `signer <timestamp>|none`")?;
        let signer = match signer {
            "none" => None,
            s => Some(timestamp(s, n)?),
        };
        let (n, newest) = next("newest", "expected `newest <timestamp>`")?;
        let newest = timestamp(newest, n)?;
        let (n, floors) = next("floors", "expected `floors` and 16 timestamps")?;
        let floors = floor_list(floors, n)?;
        let mut streams = Vec::new();
        for (n, line) in lines {
            if streams.len() == MAX_STREAMS {
                return Err(corrupt(n, "more stream lines than allowed"));
            }
            streams.push(stream(line, n)?);
        }
        Ok(SigningState {
            signer,
            newest,
            floors,
            streams,
        })
    }

    fn floor_list(s: &str, n: usize) -> Result<[u64; FLOOR_BUCKETS], StateError> {
        let mut floors = [0; FLOOR_BUCKETS];
        let mut words = s.split(' ');
        for f in &mut floors {
            *f = timestamp(words.next().unwrap_or_default(), n)?;
        }
        match words.next() {
            None => Ok(floors),
            Some(_) => Err(corrupt(n, "more than 16 floors")),
        }
    }

    fn stream(line: &str, n: usize) -> Result<StreamState, StateError> {
        let bad = || corrupt(n, "expected `stream <link> <sysid> <compid> <timestamp>`");
        let mut w = line.strip_prefix("stream ").ok_or_else(bad)?.split(' ');
        let mut id = || {
            w.next()
                .and_then(decimal)
                .and_then(|v| u8::try_from(v).ok())
                .ok_or_else(bad)
        };
        let (link_id, sysid, compid) = (id()?, id()?, id()?);
        let timestamp = timestamp(w.next().ok_or_else(bad)?, n)?;
        if w.next().is_some() {
            return Err(bad());
        }
        Ok(StreamState {
            link_id,
            sysid,
            compid,
            timestamp,
        })
    }

    fn timestamp(s: &str, n: usize) -> Result<u64, StateError> {
        match decimal(s) {
            Some(t) if t <= MAX_TIMESTAMP => Ok(t),
            Some(_) => Err(corrupt(n, "timestamp wider than 48 bits")),
            None => Err(corrupt(n, "expected a decimal number")),
        }
    }

    /// Plain decimal digits only (no sign, no spaces), as written.
    fn decimal(s: &str) -> Option<u64> {
        if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
            return None;
        }
        s.parse().ok()
    }

    fn corrupt(line: usize, reason: &'static str) -> StateError {
        StateError::Corrupt { line, reason }
    }
}

/// Whether a state file existed when [`StateFile::open`] ran.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Loaded {
    /// The file was read: its state is restored.
    Existing,
    /// There was no file: the state is empty (start from the clock).
    Fresh,
}

/// A state file and the save policy of the module docs: the state last
/// read or written, and when.
///
/// ```
/// # use mavframe::{BufferTooSmall, MessageSet, MessageData, MessageMeta};
/// # #[derive(Clone, Debug, PartialEq, Default)] struct Ping(u8);
/// # impl MessageData for Ping {
/// #   const META: MessageMeta = MessageMeta::new(4, "PING", 237, 1, 1, &[]);
/// #   type View<'a> = u8;
/// #   fn parse(p: &[u8]) -> Self { Ping(p.first().copied().unwrap_or(0)) }
/// #   fn emit(&self, p: &mut [u8]) -> Result<usize, BufferTooSmall> {
/// #     *p.first_mut().ok_or(BufferTooSmall { needed: 1, got: 0 })? = self.0; Ok(1) }
/// #   fn view(p: &[u8]) -> u8 { p.first().copied().unwrap_or(0) }
/// # }
/// # struct D;
/// # impl MessageSet for D { type Message = Ping; type View<'a> = u8;
/// #   const MESSAGES: &'static [MessageMeta] = &[Ping::META];
/// #   fn parse(id: u32, p: &[u8]) -> Option<Ping> { (id == 4).then(|| Ping::parse(p)) }
/// #   fn view(id: u32, p: &[u8]) -> Option<u8> { (id == 4).then(|| Ping::view(p)) } }
/// // `D`, `Ping`: a stand-in dialect of one message, declared out of sight
/// // (this crate sits below the generator); use a generated crate's
/// // `MessageSet` and messages, e.g. `fbwag_dialect::Dialect`.
/// use mavframe::signing::state::{Loaded, StateFile};
/// use mavframe::{Framer, Verifier};
///
/// let path = std::env::temp_dir().join(format!("mavframe-doc-{}.state", std::process::id()));
/// let key = [7u8; 32];
///
/// // First run: no file yet; the signer starts from the clock.
/// let (mut file, loaded) = StateFile::open(path.clone())?;
/// assert_eq!(loaded, Loaded::Fresh);
/// let mut framer = Framer::new();
/// framer.set_signer(Some(file.state().signer(key, 0)));
/// framer.frame(1, 191, &Ping(1))?; // signed
/// let signed = framer.signer().unwrap().signed_below();
/// // At exit (and at checkpoints, when `due`): what was signed, to the file.
/// file.save_final(framer.signer(), None::<&Verifier>)?;
///
/// // A restart whose clock reads 0 (a board without a real-time clock): the
/// // signer still starts above everything it signed, so no receiver takes
/// // its frames for replays.
/// let (file, loaded) = StateFile::open(path.clone())?;
/// assert_eq!(loaded, Loaded::Existing);
/// assert!(file.state().signer_at(key, 0, 0).timestamp() >= signed);
/// std::fs::remove_file(&path)?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct StateFile {
    path: PathBuf,
    state: SigningState,
    saved_at: Instant,
    interval: Duration,
    /// When the last save failed, if it did: the next waits an interval
    /// (a file that cannot be written was tried again at every frame).
    failed_at: Option<Instant>,
    /// The signer's bound as loaded: what runs before this one may have
    /// signed, which no save goes below.
    loaded_bound: u64,
    /// The signer's [`Signer::signed_below`] at the last save (the loaded
    /// bound before any): signatures above it are new since.
    signed_at_save: u64,
}

impl StateFile {
    /// Reads `path`, or starts empty when there is no file there yet
    /// ([`Loaded::Fresh`]). Any other failure (unreadable, truncated,
    /// damaged, foreign) is an error for the caller to report.
    pub fn open(path: impl Into<PathBuf>) -> Result<(Self, Loaded), StateError> {
        let path = path.into();
        let (state, loaded) = match SigningState::load(&path) {
            Ok(s) => (s, Loaded::Existing),
            Err(StateError::Missing) => (SigningState::default(), Loaded::Fresh),
            Err(e) => return Err(e),
        };
        let bound = state.signer.unwrap_or(0);
        let file = StateFile {
            path,
            state,
            saved_at: Instant::now(),
            interval: SAVE_INTERVAL,
            failed_at: None,
            loaded_bound: bound,
            signed_at_save: bound,
        };
        Ok((file, loaded))
    }

    /// The same file with saves due every `interval` instead of
    /// [`SAVE_INTERVAL`] (the replay window after a crash, see the module
    /// docs).
    pub fn with_interval(mut self, interval: Duration) -> Self {
        self.interval = interval;
        self
    }

    /// The path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The state last read or saved.
    pub fn state(&self) -> &SigningState {
        &self.state
    }

    /// Whether a save is due: the signer signed since the last save and
    /// came within half of [`SIGNER_MARGIN`] of the saved bound (or past
    /// it), or the interval has passed since the last save; after a failed
    /// save, not before [`SAVE_INTERVAL`] (or the interval, if shorter) has
    /// passed since (a file that cannot be written was tried again at every
    /// frame). Cheap: call it every loop iteration.
    pub fn due(&self, signer: Option<&Signer>) -> bool {
        let bound = self.state.signer.unwrap_or(0);
        let ran_ahead = signer.is_some_and(|s| {
            let signed = s.signed_below();
            signed > self.signed_at_save && signed.saturating_add(SIGNER_MARGIN / 2) > bound
        });
        let retry_after = self.interval.min(SAVE_INTERVAL);
        let retry = self.failed_at.is_none_or(|t| t.elapsed() >= retry_after);
        retry && (ran_ahead || self.saved_at.elapsed() >= self.interval)
    }

    /// A checkpoint while the program runs: captures `signer` and
    /// `verifier` and writes them when they differ from the last saved
    /// state (an idle link writes nothing). The signer's bound moves only
    /// when it signed since the last save and came within half the margin
    /// of the bound: then to [`SIGNER_MARGIN`] above its last signature,
    /// which covers a crash before the next checkpoint. Returns whether it
    /// wrote. On error, the last saved state stays the reference, so
    /// [`due`](Self::due) asks again, a [`SAVE_INTERVAL`] later at most.
    pub fn save<const N: usize>(
        &mut self,
        signer: Option<&Signer>,
        verifier: Option<&Verifier<N>>,
    ) -> Result<bool, StateError> {
        let bound = signer.map(|s| self.checkpoint_bound(s.signed_below()));
        self.write(signer, verifier, bound)
    }

    /// The save at exit, when nothing more will be signed: as
    /// [`save`](Self::save), but the signer's bound is exactly above its
    /// last signature (never below the bound loaded at
    /// [`open`](Self::open)), so a restart does not start ahead of what was
    /// signed. A program that goes on signing after it is covered again by
    /// the next checkpoint, due at its next signature.
    pub fn save_final<const N: usize>(
        &mut self,
        signer: Option<&Signer>,
        verifier: Option<&Verifier<N>>,
    ) -> Result<bool, StateError> {
        let bound = signer.map(|s| s.signed_below().max(self.loaded_bound));
        self.write(signer, verifier, bound)
    }

    /// The bound a checkpoint writes for a signer that signed below
    /// `signed` (see [`save`](Self::save)).
    fn checkpoint_bound(&self, signed: u64) -> u64 {
        let bound = self.state.signer.unwrap_or(0).max(self.loaded_bound);
        if signed <= self.signed_at_save || signed.saturating_add(SIGNER_MARGIN / 2) <= bound {
            bound.max(signed)
        } else {
            signed.saturating_add(SIGNER_MARGIN).min(MAX_TIMESTAMP)
        }
    }

    fn write<const N: usize>(
        &mut self,
        signer: Option<&Signer>,
        verifier: Option<&Verifier<N>>,
        bound: Option<u64>,
    ) -> Result<bool, StateError> {
        let now = SigningState {
            signer: bound,
            ..SigningState::capture(signer, verifier)
        };
        let wrote = now != self.state;
        if wrote {
            if let Err(e) = now.save(&self.path) {
                self.failed_at = Some(Instant::now());
                return Err(e);
            }
        }
        self.failed_at = None;
        self.state = now;
        self.saved_at = Instant::now();
        if let Some(s) = signer {
            self.signed_at_save = s.signed_below();
        }
        Ok(wrote)
    }
}
