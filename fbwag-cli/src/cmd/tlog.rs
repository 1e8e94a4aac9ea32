//! `--tlog DIR` and its limits, shared by `fbwag router` and `fbwag cc`.

use crate::args;
use crate::live::tlog::TlogOptions;
use std::path::PathBuf;

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
    /// Free space to keep on DIR's file system (checked every second or
    /// MiB written). Below it, the oldest .tlog files this program wrote
    /// in DIR (named as above; no other file is touched) are deleted, one
    /// by one; if that is not enough, writing stops (said once in the
    /// log; the frames are counted as not written) and resumes when
    /// space returns. Routing goes on either way.
    #[arg(long, value_name = "BYTES", default_value = "100M", value_parser = args::byte_size, requires = "tlog")]
    pub tlog_min_free: u64,
}

impl TlogArgs {
    /// The log's options, when `--tlog` is given.
    pub fn options(&self) -> Option<TlogOptions> {
        self.tlog.as_ref().map(|dir| TlogOptions {
            dir: dir.clone(),
            max_size: self.tlog_max_size,
            min_free: self.tlog_min_free,
        })
    }
}
