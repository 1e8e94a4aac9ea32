//! `--tlog DIR` and the limits of the daemons' logs, shared by `fbwag
//! router` and `fbwag cc` (whose `logs` group holds the options that give
//! a log: `--tlog`, and the router's `--flight-log`).

use crate::args;
use crate::live::logfiles::FilesOptions;
use crate::live::tlog::{LogMode, LogOptions};
use std::path::{Path, PathBuf};

/// Telemetry log arguments (flattened into each daemon's).
#[derive(clap::Args)]
pub struct TlogArgs {
    /// Write a telemetry log to .tlog files in DIR (created if missing),
    /// as MAVProxy writes them and pymavlink's mavlogdump.py reads them:
    /// per frame, 8 bytes big-endian of microseconds since 1970 (UTC),
    /// whose two low bits are the link's index (0, 1, 2; 2 for every
    /// later link) or 3 for this program's own frames, then the frame's
    /// bytes as on the wire (signed frames with their signature). Logged:
    /// every frame received and not dropped, whatever its destination
    /// (router: everything routed; cc: also the FC's frames the companion
    /// takes in), and the companion's own messages once each, as framed
    /// for the log (each link frames them again with its own sequence
    /// numbers and signature). Files are named
    /// fbwag-PROGRAM-YYYYMMDDTHHMMSS.uuuuuuZ.tlog (UTC: they sort in time
    /// order). A thread of its own writes them: a disk too slow for the
    /// traffic never slows routing; the frames it cannot take are dropped
    /// and counted in each report and in the summary.
    #[arg(long, value_name = "DIR")]
    pub tlog: Option<PathBuf>,
    /// Begin a new .tlog file before one would grow past this size
    /// (bytes, 288 at least: one record of the largest frame; suffix K,
    /// M, G or T: powers of 1024).
    #[arg(long, value_name = "BYTES", default_value = "64M", value_parser = args::tlog_file_size, requires = "tlog")]
    pub tlog_max_size: u64,
    /// Free space to keep on the log directory's file system (checked
    /// every second or MiB written), for every log (.tlog, and the
    /// router's .bin). Below it, the oldest files of the kind this
    /// program wrote there (named as above; no other file is touched) are
    /// deleted, one by one; if that is not enough, writing stops (said
    /// once in the log; counted as not written) and resumes when space
    /// returns. Routing goes on either way.
    #[arg(long, value_name = "BYTES", default_value = "100M", value_parser = args::byte_size, requires = "logs")]
    pub tlog_min_free: u64,
    /// Keep at most N files of each log's kind in its directory (this
    /// program's .tlog files; the router's .bin files apart): as one
    /// begins, the oldest beyond N are deleted. 0: no limit (the
    /// default). mavlink-router's MaxLogFiles.
    #[arg(long, value_name = "N", default_value_t = 0, value_parser = clap::value_parser!(u32), requires = "logs")]
    pub log_max_files: u32,
    /// When the logs write: `always`, or `while-armed`: only while the
    /// vehicle's HEARTBEAT says armed (its MAV_MODE_FLAG_SAFETY_ARMED
    /// bit), a new file for each arming. The vehicle: `fbwag cc`'s FC;
    /// `fbwag router`'s --log-sysid, or else the first autopilot heard
    /// (component 1), on a link with a key only from verified frames.
    /// Until its first HEARTBEAT nothing is logged. mavlink-router's
    /// LogMode.
    #[arg(
        long,
        value_name = "MODE",
        value_enum,
        default_value = "always",
        requires = "logs"
    )]
    pub log_mode: LogMode,
}

impl TlogArgs {
    /// The telemetry log's options, when `--tlog` is given.
    pub fn options(&self) -> Option<LogOptions> {
        self.tlog.as_ref().map(|dir| LogOptions {
            files: self.files(dir),
            mode: self.log_mode,
        })
    }

    /// The limits of a log's files in `dir`.
    pub fn files(&self, dir: &Path) -> FilesOptions {
        FilesOptions {
            dir: dir.to_owned(),
            max_size: self.tlog_max_size,
            min_free: self.tlog_min_free,
            max_files: Some(self.log_max_files).filter(|n| *n > 0),
        }
    }
}
