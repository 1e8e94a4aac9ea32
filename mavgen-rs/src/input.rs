//! Reading input files with bounds: only regular files, and never more than
//! a fixed number of bytes, so a path naming `/dev/zero`, a FIFO or a file
//! that keeps growing gives an error instead of exhausting memory or
//! blocking forever.

use std::fmt;
use std::fs::{File, FileType};
use std::io::{self, Read};
use std::path::Path;

/// Largest XML file read: 8 MiB. The largest upstream definition,
/// `common.xml`, is 0.6 MB, and all of `all.xml` with its includes is about
/// 1 MB, so this leaves room for a decade of growth while keeping a bad path
/// cheap.
pub const MAX_FILE_BYTES: u64 = 8 << 20;

/// Most bytes read over all files of one load (roots and every include):
/// 64 MiB. Bounds the memory of a load however many files the includes name.
pub const MAX_TOTAL_BYTES: u64 = 64 << 20;

/// Why a file could not be read.
#[derive(Debug)]
#[non_exhaustive]
pub enum ReadError {
    /// The operating system refused (missing file, no permission, …).
    Io(io::Error),
    /// The path names something other than a regular file (after following
    /// symbolic links): reading a FIFO may block forever, a device may never
    /// end.
    NotRegular(&'static str),
    /// The file holds more than `limit` bytes (checked while reading, so a
    /// file growing under the reader is caught too).
    TooLarge {
        /// The limit that was exceeded.
        limit: u64,
    },
    /// The file is not UTF-8 from this byte on.
    NotUtf8 {
        /// Length of the valid UTF-8 prefix.
        valid_up_to: usize,
    },
}

impl fmt::Display for ReadError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ReadError::Io(e) => write!(f, "{e}"),
            ReadError::NotRegular(kind) => write!(f, "it is {kind}, not a regular file"),
            ReadError::TooLarge { limit } => write!(
                f,
                "it is larger than {limit} bytes ({} MiB), the most mavgen-rs reads from one file",
                limit >> 20
            ),
            ReadError::NotUtf8 { valid_up_to } => {
                write!(f, "it is not UTF-8 (byte {valid_up_to})")
            }
        }
    }
}

impl std::error::Error for ReadError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ReadError::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<io::Error> for ReadError {
    fn from(e: io::Error) -> Self {
        ReadError::Io(e)
    }
}

/// Reads the regular file at `path`, at most `limit` bytes of it.
///
/// The file type is checked before opening (opening a FIFO for reading
/// blocks until a writer appears) and again on the open handle (the path may
/// have been replaced in between); on Unix the open itself does not block.
pub fn read_regular(path: &Path, limit: u64) -> Result<Vec<u8>, ReadError> {
    // One byte past the limit is enough to know it was exceeded.
    let bytes = read_prefix(path, limit.saturating_add(1))?;
    if bytes.len() as u64 > limit {
        return Err(ReadError::TooLarge { limit });
    }
    Ok(bytes)
}

/// The first `n` bytes of the regular file at `path` (all of it if shorter),
/// with the checks of [`read_regular`].
pub fn read_prefix(path: &Path, n: u64) -> Result<Vec<u8>, ReadError> {
    check_regular(&std::fs::metadata(path)?.file_type())?;
    let file = open_nonblocking(path)?;
    let meta = file.metadata()?;
    check_regular(&meta.file_type())?;
    // `take` stops at n bytes whatever the file does meanwhile (it may grow).
    let mut bytes = Vec::with_capacity(meta.len().min(n) as usize);
    file.take(n).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// [`read_regular`], then UTF-8.
pub fn read_regular_text(path: &Path, limit: u64) -> Result<String, ReadError> {
    String::from_utf8(read_regular(path, limit)?).map_err(|e| ReadError::NotUtf8 {
        valid_up_to: e.utf8_error().valid_up_to(),
    })
}

fn check_regular(t: &FileType) -> Result<(), ReadError> {
    if t.is_file() {
        Ok(())
    } else {
        Err(ReadError::NotRegular(describe(t)))
    }
}

#[cfg(unix)]
fn describe(t: &FileType) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "a special file"
    }
}

#[cfg(not(unix))]
fn describe(t: &FileType) -> &'static str {
    if t.is_dir() {
        "a directory"
    } else {
        "a special file"
    }
}

#[cfg(unix)]
fn open_nonblocking(path: &Path) -> io::Result<File> {
    use std::os::unix::fs::OpenOptionsExt;
    // O_NONBLOCK: should the path have become a FIFO since it was checked,
    // the open returns at once and the handle check rejects it. Reads of a
    // regular file ignore the flag.
    std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
}

#[cfg(not(unix))]
fn open_nonblocking(path: &Path) -> io::Result<File> {
    File::open(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> std::path::PathBuf {
        std::env::temp_dir().join(format!("mavgen-rs-input-{}-{name}", std::process::id()))
    }

    #[test]
    fn the_limits_are_the_ones_the_cli_help_states() {
        // `mavgen-rs --help` says "8 MiB" and "64 MiB".
        assert_eq!((MAX_FILE_BYTES, MAX_TOTAL_BYTES), (8 << 20, 64 << 20));
    }

    #[test]
    fn a_file_at_the_limit_is_read_and_one_byte_more_is_refused() {
        let p = temp("limit");
        std::fs::write(&p, [b'x'; 100]).unwrap();
        assert_eq!(read_regular(&p, 100).unwrap().len(), 100);
        assert!(matches!(
            read_regular(&p, 99),
            Err(ReadError::TooLarge { limit: 99 })
        ));
        std::fs::remove_file(&p).unwrap();
    }

    #[test]
    fn a_directory_is_not_a_regular_file() {
        let e = read_regular(&std::env::temp_dir(), 100).unwrap_err();
        assert!(matches!(e, ReadError::NotRegular("a directory")), "{e}");
    }

    #[cfg(unix)]
    #[test]
    fn dev_zero_is_refused_without_reading() {
        let e = read_regular(Path::new("/dev/zero"), MAX_FILE_BYTES).unwrap_err();
        assert!(
            matches!(e, ReadError::NotRegular("a character device")),
            "{e}"
        );
    }
}
