//! A daemon's machine-readable events (`--events`).

use super::writer::{Lines, Output};
use super::Clock;
use serde_json::{Map, Value};
use std::fs::File;
use std::io;
use std::path::Path;
use std::sync::Arc;

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
        let name = path.map(|p| format!("--events {}", p.display()));
        Ok(Events {
            out: out.map(|out| Lines::new(out, Arc::new(note), name)),
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
