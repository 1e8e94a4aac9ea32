//! `fbwag decode`: MAVLink frames to JSON lines.

use crate::error::{CliError, Outcome};
use crate::{hexstream, json};
use fbwag_dialect::mavframe::frame::{frame_len, Frame, FrameError, MAX_FRAME_LEN};
use fbwag_dialect::mavframe::parser::{Parser, Received, Stats};
use fbwag_dialect::mavframe::MessageSet;
use fbwag_dialect::Dialect;
use std::io::{BufWriter, Read, Write};
use std::path::PathBuf;

/// Print one JSON object per frame of a MAVLink stream.
///
/// Fields are listed in wire order; integers are JSON numbers, arrays JSON
/// arrays, char arrays strings up to the first NUL (or arrays of byte
/// values when bytes follow the NUL or the text is not UTF-8). Floats:
/// finite values are numbers in shortest round-trip form (-0.0 and
/// subnormals included); "inf" and "-inf"; "NaN" for the canonical quiet
/// NaN (bits 0x7fc00000 for float, 0x7ff8000000000000 for double) and
/// "NaN:0x" plus the bit pattern (8 or 16 hex digits) for any other NaN,
/// so sign and payload bits survive. Payload bytes beyond the message's
/// fields (a sender with a newer definition) are kept as "extra" (hex),
/// with "payload_len". `fbwag decode | fbwag encode` gives back the same
/// bytes. Bad frames are skipped and counted in a summary on stderr; the
/// parser resynchronises after garbage and corrupted frames.
#[derive(clap::Args)]
pub struct DecodeArgs {
    /// Input file; `-` or nothing for stdin.
    pub file: Option<PathBuf>,
    /// The input is hex text (whitespace ignored), not binary.
    #[arg(long)]
    pub hex: bool,
    /// The input is a .tlog: each frame preceded by an 8-byte big-endian
    /// microsecond timestamp (kept as "tlog_us").
    #[arg(long, conflicts_with = "hex")]
    pub tlog: bool,
}

/// Where each line goes: stdout, buffered.
type Emit<'a> = dyn FnMut(String) -> Result<(), CliError> + 'a;

/// What was read of a tlog.
#[derive(Debug, Default)]
struct TlogRead {
    /// Records decoded.
    good: u64,
    /// Records unreadable (each skipped one byte at a time).
    bad: u64,
    /// The byte offset of the first unreadable record.
    first_bad: Option<u64>,
    /// The input's offset of the bytes not used yet.
    offset: u64,
    /// The input ended inside a record.
    truncated: Option<CliError>,
}

/// Decodes the input to stdout; [`Outcome::Flagged`] when any bytes were
/// dropped (bad checksums, garbage, unreadable tlog records); an error for
/// a tlog that ends inside a record, once every record before it is out.
pub fn run(a: DecodeArgs) -> Result<Outcome, CliError> {
    let mut input = open_input(&a.file).map_err(|source| CliError::OpenInput {
        path: a.file.clone(),
        source,
    })?;
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    let mut parser = Parser::<Dialect>::new();
    let mut emit = |line: String| writeln!(out, "{line}").map_err(CliError::Write);
    let mut tlog = read_all(&mut input, &a, &mut parser, &mut emit)?;
    while let Some(r) = parser.flush() {
        emit(json::frame_to_json(&r.frame(), r.meta(), None))?;
    }
    out.flush().map_err(CliError::Write)?;
    let s = parser.stats();
    eprintln!("{}", summary(s, a.tlog.then_some(&tlog)));
    if let Some(e) = tlog.truncated.take() {
        return Err(e);
    }
    Ok(Outcome::clean_if(
        s.bad_crc == 0 && s.bytes_dropped == 0 && tlog.bad == 0,
    ))
}

/// Reads and decodes the whole input; what was read of a tlog. Every form
/// is read in chunks, so memory stays bounded whatever the input's size (a
/// device or an endless pipe included).
fn read_all(
    input: &mut dyn Read,
    a: &DecodeArgs,
    parser: &mut Parser<Dialect>,
    emit: &mut Emit<'_>,
) -> Result<TlogRead, CliError> {
    let mut chunk = vec![0u8; 64 * 1024];
    let mut hex_text = hexstream::HexDecoder::default();
    let mut bytes = Vec::new();
    let mut tlog = TlogRead::default();
    loop {
        let n = match input.read(&mut chunk) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(CliError::ReadInput(e)),
        };
        let end = n == 0;
        if a.hex {
            hex_text.push(&chunk[..n], &mut bytes)?;
            if end {
                hex_text.finish()?;
            }
        } else {
            bytes.extend_from_slice(&chunk[..n]);
        }
        if a.tlog {
            let used = decode_tlog(&bytes, end, parser, emit, &mut tlog)?;
            bytes.drain(..used);
        } else {
            let mut rest: &[u8] = &bytes;
            while let Some(r) = parser.next(&mut rest) {
                emit(json::frame_to_json(&r.frame(), r.meta(), None))?;
            }
            bytes.clear();
        }
        if end {
            return Ok(tlog);
        }
    }
}

/// The summary line on stderr.
fn summary(s: &Stats, tlog: Option<&TlogRead>) -> String {
    let mut summary = format!(
        "decoded {} frames ({} known, {} unknown ids); rejected: {} bad CRC, {} bad incompat flags; {} bytes dropped; {} frames missing by sequence",
        s.frames + s.unknown_frames,
        s.frames,
        s.unknown_frames,
        s.bad_crc,
        s.bad_incompat_flags,
        s.bytes_dropped,
        s.seq_lost
    );
    if let Some(t) = tlog {
        summary.push_str(&format!("; tlog: {} records, {} unreadable", t.good, t.bad));
        if let Some(at) = t.first_bad {
            summary.push_str(&format!(" (the first at byte offset {at})"));
        }
    }
    summary
}

/// The input file, or stdin for `-` or none.
pub fn open_input(file: &Option<PathBuf>) -> std::io::Result<Box<dyn Read>> {
    match file {
        Some(p) if p.as_os_str() != "-" => Ok(Box::new(std::fs::File::open(p)?)),
        _ => Ok(Box::new(std::io::stdin().lock())),
    }
}

/// Reads tlog records (8-byte big-endian µs timestamp, then one frame); an
/// unreadable record is skipped by resynchronising one byte further. Only
/// a record's whole frame ([`whole_record`]) reaches the parser, so garbage
/// never leaves bytes in it that would swallow the next good record, and
/// its counts are the frames printed. Until
/// the `end` of the input, a record is read only when a whole frame of the
/// largest size could follow it, so the outcome does not depend on how the
/// input was chunked. At the end, a record cut short (a timestamp, or a
/// frame whose header announces more bytes than are left) is reported in
/// `t.truncated`. Returns the bytes used.
fn decode_tlog(
    raw: &[u8],
    end: bool,
    parser: &mut Parser<Dialect>,
    emit: &mut Emit<'_>,
    t: &mut TlogRead,
) -> Result<usize, CliError> {
    let mut at = 0usize;
    // Until the end: room for the largest frame and the next record's
    // start byte ([`whole_record`]).
    let lookahead = if end { 1 } else { MAX_FRAME_LEN + 9 };
    // At the end, the first record the input seems to end inside, and the
    // counts before it: a truncation only if no whole record follows it
    // (else its start byte was garbage, skipped as such).
    let mut cut: Option<(usize, u64, Option<u64>)> = None;
    while at + 8 + lookahead <= raw.len() {
        let mut ts = [0u8; 8];
        ts.copy_from_slice(&raw[at..at + 8]);
        let rest = &raw[at + 8..];
        let len = match frame_len(rest) {
            Ok(n) if n <= rest.len() && n <= MAX_FRAME_LEN && whole_record(rest, n, end) => Some(n),
            Ok(n) if end && n > rest.len() && n <= MAX_FRAME_LEN => {
                cut.get_or_insert((at, t.bad, t.first_bad));
                None
            }
            Err(FrameError::Incomplete { .. }) if end => {
                cut.get_or_insert((at, t.bad, t.first_bad));
                None
            }
            _ => None,
        };
        let us = u64::from_be_bytes(ts);
        let taken = match len {
            Some(n) => emit_record(parser, &rest[..n], us, emit)?,
            None => false,
        };
        if taken {
            at += 8 + len.unwrap_or(0);
            t.good += 1;
            cut = None;
        } else {
            t.first_bad.get_or_insert(t.offset + at as u64);
            t.bad += 1;
            at += 1;
        }
    }
    if end && (cut.is_some() || at < raw.len()) {
        // The bytes from the cut record on are that record, not garbage.
        if let Some((from, bad, first_bad)) = cut {
            (at, t.bad, t.first_bad) = (from, bad, first_bad);
        }
        t.truncated = Some(truncated(&raw[at..], t.offset + at as u64));
        at = raw.len();
    }
    t.offset += at as u64;
    Ok(at)
}

/// Decodes a record's whole frame `bytes` and emits it with the record's
/// timestamp `us`; false when the parser does not take it whole. The
/// record's end is the frame's end, as a datagram's is: a frame of an
/// unknown id is not held back for the byte after it, which in a tlog is
/// the next record's timestamp.
fn emit_record(
    parser: &mut Parser<Dialect>,
    bytes: &[u8],
    us: u64,
    emit: &mut Emit<'_>,
) -> Result<bool, CliError> {
    let mut emit_whole = |r: Received<'_, Dialect>| {
        let whole = r.frame().as_bytes().len() == bytes.len();
        if whole {
            emit(json::frame_to_json(&r.frame(), r.meta(), Some(us)))?;
        }
        Ok::<bool, CliError>(whole)
    };
    let mut record = bytes;
    let mut taken = match parser.next_in_datagram(&mut record) {
        Some(r) => emit_whole(r)?,
        None => false,
    };
    if !taken {
        if let Some(r) = parser.end_of_datagram() {
            taken = emit_whole(r)?;
        }
    }
    while parser.end_of_datagram().is_some() {}
    Ok(taken)
}

/// Whether the `n` bytes `rest` begins with are a record's whole frame:
/// the length its header says, and the checksum right for a message the
/// dialect knows. An unknown message's checksum cannot be checked: its
/// record counts only when the next record starts where it ends (a start
/// byte after the next timestamp) or the input `end`s there, so garbage
/// claiming an unknown id is not taken for a record.
fn whole_record(rest: &[u8], n: usize, end: bool) -> bool {
    let Ok(frame) = Frame::new_checked(&rest[..n]) else {
        return false;
    };
    if frame.frame_len() != n {
        return false;
    }
    match <Dialect as MessageSet>::meta(frame.msg_id()) {
        Some(m) => frame.check_crc(m.crc_extra),
        None => rest.get(n + 8).map_or(end, |b| matches!(b, 0xfd | 0xfe)),
    }
}

/// The error for the record at `offset` whose bytes `left` end the input.
fn truncated(left: &[u8], offset: u64) -> CliError {
    let needed = match left.get(8..).map(frame_len) {
        Some(Ok(n)) => 8 + n,
        Some(Err(FrameError::Incomplete { needed })) => 8 + needed,
        // A timestamp, then at least a start byte.
        _ => 9,
    };
    CliError::TlogTruncated {
        offset,
        left: left.len(),
        needed,
    }
}
