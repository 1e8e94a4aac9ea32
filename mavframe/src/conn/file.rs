//! `file:`: a capture file read as a link.

use super::transport::{recv_stream, Transport};
use std::fs::File;
use std::io::{self, BufReader, Read};
use std::path::Path;
use std::time::Duration;

/// `file:`: the bytes of a capture (raw MAVLink frames as they came off a
/// link, e.g. `fbwag capture` output or a serial dump) delivered as if a
/// link sent them, for replaying traffic through code written for live
/// links.
///
/// [`recv`](Transport::recv) returns the file's bytes in order, without
/// waiting (the timeout is not used: the bytes are all there), then, at
/// the end of the file, an [`UnexpectedEof`](io::ErrorKind::UnexpectedEof)
/// error, as a TCP link closed by its peer does; a
/// [`Connection`](super::Connection) returns every frame before that
/// error. [`send`](Transport::send) fails with
/// [`Unsupported`](io::ErrorKind::Unsupported): a capture is read-only, and
/// silently dropping frames would hide a program that expects its
/// commands to reach something.
///
/// A `.tlog` (MAVProxy's telemetry log) puts an 8-byte timestamp before
/// each frame: those bytes reach the parser as noise between frames and
/// are counted as dropped, while the frames come through.
///
/// ```no_run
/// use mavframe::conn::{Endpoint, FileLink, Transport};
/// use std::io;
///
/// let mut link = FileLink::open("flight.bin")?;
/// let mut buf = [0u8; 4096];
/// let mut total = 0;
/// loop {
///     match link.recv(&mut buf, None) {
///         Ok(n) => total += n,
///         Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => break,
///         Err(e) => return Err(e),
///     }
/// }
/// println!("{total} bytes");
/// # Ok::<(), io::Error>(())
/// ```
#[derive(Debug)]
pub struct FileLink {
    reader: BufReader<File>,
}

impl FileLink {
    /// Opens the capture at `path`.
    pub fn open(path: impl AsRef<Path>) -> io::Result<Self> {
        Ok(Self::from_file(File::open(path)?))
    }

    /// Reads an already opened file from its current position.
    pub fn from_file(file: File) -> Self {
        FileLink {
            reader: BufReader::new(file),
        }
    }
}

/// What sending to a capture is.
pub(crate) fn read_only() -> io::Error {
    io::Error::new(
        io::ErrorKind::Unsupported,
        "a file: link is read-only: frames cannot be sent to a capture",
    )
}

impl Transport for FileLink {
    fn send(&mut self, _frame: &[u8]) -> io::Result<()> {
        Err(read_only())
    }

    fn recv(&mut self, buf: &mut [u8], _timeout: Option<Duration>) -> io::Result<usize> {
        // A file never times out: its end is the end of the capture.
        recv_stream(buf, None, "end of the capture file", |buf, _| {
            self.reader.read(buf)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_dialect::{Ping, TestDialect};
    use super::super::{Connection, Endpoint};
    use crate::frame::Header;
    use crate::Framer;
    use std::io::Write;
    use std::vec::Vec;

    fn capture(name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let dir =
            std::env::temp_dir().join(std::format!("mavframe-file-{}-{name}", std::process::id()));
        let mut f = std::fs::File::create(&dir).unwrap();
        f.write_all(bytes).unwrap();
        dir
    }

    /// Every frame of the capture comes out in order, noise between frames
    /// is dropped, then the end of the file is `UnexpectedEof`, and sending
    /// is refused.
    #[test]
    fn a_capture_replays_its_frames_then_ends() {
        let mut out = Framer::new();
        let mut bytes = Vec::new();
        for v in 0..50u32 {
            bytes.extend_from_slice(&[0x55; 8]); // a tlog-like timestamp
            bytes.extend_from_slice(out.frame(1, 1, &Ping { value: v }).unwrap());
        }
        let path = capture("replay", &bytes);
        let endpoint: Endpoint = std::format!("file:{}", path.display()).parse().unwrap();
        let mut link = Connection::<TestDialect>::open(&endpoint).unwrap();
        for v in 0..50u32 {
            let f = link.recv(None).unwrap().unwrap();
            assert_eq!(f.message(), Some(Ping { value: v }));
        }
        let end = link.recv(None).unwrap_err();
        assert_eq!(end.kind(), std::io::ErrorKind::UnexpectedEof);
        assert_eq!(link.stats().bytes_dropped, 50 * 8);
        let err = link
            .send(Header::default(), &Ping { value: 1 })
            .unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::Unsupported);
        std::fs::remove_file(path).unwrap();
    }

    #[test]
    fn a_missing_file_fails_at_open() {
        let endpoint: Endpoint = "file:/nonexistent/mavframe/capture.bin".parse().unwrap();
        let err = Connection::<TestDialect>::open(&endpoint).unwrap_err();
        assert_eq!(err.kind(), std::io::ErrorKind::NotFound);
    }
}
