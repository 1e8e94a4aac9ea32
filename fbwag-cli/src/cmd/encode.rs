//! `fbwag encode`: JSON lines to MAVLink frames.

use super::decode::open_input;
use crate::error::{CliError, Outcome};
use crate::{json, lines};
use fbwag_dialect::mavframe::frame::{Frame, MAX_FRAME_LEN};
use fbwag_dialect::mavframe::Signer;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

/// Read `fbwag decode` JSON lines and write the frames.
///
/// Messages are named by `name` or `msgid`; `seq`, `sysid`, `compid` and
/// `version` come from the JSON (0, 0, 0 and 2 when absent). `fbwag decode
/// | fbwag encode` reproduces its input byte for byte, truncation,
/// signatures, extra payload bytes and NaN bits included.
///
/// A line is encoded exactly as it says, or not at all: refused are lines
/// that are not UTF-8 or not one JSON object, unknown or repeated keys, a
/// message without "fields" ("fields":{} asks for all zeros; fields left
/// out of it are zero), unknown field names, values of the wrong JSON type
/// or outside their field's range (integers out of range, negative for
/// unsigned, finite floats beyond float/double, which would become
/// infinities), strings longer than their char array, arrays not of the
/// declared length, a "payload_len" that would cut off non-zero field
/// bytes or exceeds the message without "extra" holding the bytes beyond,
/// and "signed": true with neither a "signature" to copy nor --sign-key.
/// Numbers are rounded once, to the nearest value of the field's type.
/// A frame of an unknown message ("raw" hex) is copied as it is, and its
/// other keys must agree with its bytes. Blank lines are skipped; lines
/// longer than 1 MiB are refused.
///
/// Each refused line is reported on stderr as `line N: reason`, no frame is
/// written for it, and encoding goes on with the next line. Exit status: 0
/// when every line was encoded, 1 when any was refused, 2 when the input
/// could not be read or the output not written.
#[derive(clap::Args)]
pub struct EncodeArgs {
    /// Input file of JSON lines; `-` or nothing for stdin.
    pub file: Option<PathBuf>,
    /// Write hex text, one frame per line, instead of binary.
    #[arg(long)]
    pub hex: bool,
    /// Write MAVLink 1 frames of the base fields, whatever each line's
    /// version (ids up to 255; extension fields, "payload_len", "extra",
    /// "compat_flags" and signatures of the lines are dropped).
    #[arg(long, conflicts_with = "sign_key")]
    pub v1: bool,
    /// Sign every frame with this 32-byte key (64 hex digits, or @FILE), replacing
    /// any signature of the line. A MAVLink 1 frame cannot be signed: such
    /// lines are refused.
    #[arg(long, value_name = "HEX64", value_parser = crate::args::sign_key)]
    pub sign_key: Option<String>,
    /// Link id of the signature.
    #[arg(long, default_value_t = 0, requires = "sign_key")]
    pub link_id: u8,
    /// Signing timestamp of the first frame (10 µs units since
    /// 2015-01-01, at most 2^48 - 1), incremented per frame; default: now.
    #[arg(long, requires = "sign_key", allow_hyphen_values = true, value_parser = crate::args::sign_timestamp)]
    pub sign_timestamp: Option<u64>,
    /// Write a .tlog (timestamps from "tlog_us", else 0).
    #[arg(long, conflicts_with = "hex")]
    pub tlog: bool,
}

/// How each frame is written.
#[derive(Clone, Copy)]
enum Form {
    Binary,
    Hex,
    Tlog,
}

/// Encodes each line to stdout; [`Outcome::Flagged`] when any line was
/// refused (each reported on stderr as `line N: reason`).
pub fn run(a: EncodeArgs) -> Result<Outcome, CliError> {
    let mut signer = match &a.sign_key {
        Some(hex) => {
            let ts = a
                .sign_timestamp
                .unwrap_or_else(fbwag_dialect::mavframe::signing::timestamp_now);
            Some(Signer::new(super::key(hex)?, a.link_id, ts))
        }
        None => None,
    };
    let form = match (a.hex, a.tlog) {
        (true, _) => Form::Hex,
        (false, true) => Form::Tlog,
        (false, false) => Form::Binary,
    };
    let input = open_input(&a.file).map_err(|source| CliError::OpenInput {
        path: a.file.clone(),
        source,
    })?;
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    let mut frame = [0u8; MAX_FRAME_LEN];
    let (mut written, mut errors) = (0u64, 0u64);
    let mut lines = lines::Lines::new(std::io::BufReader::new(input));
    while let Some((number, line)) = lines.next_line().map_err(CliError::ReadInput)? {
        let Some(text) = line_text(number, line) else {
            errors += 1;
            continue;
        };
        if text.trim().is_empty() {
            continue;
        }
        let mut opts = json::EncodeOptions {
            force_v1: a.v1,
            signer: signer.as_mut(),
        };
        match json::json_to_frame(&text, &mut opts, &mut frame) {
            Ok(encoded) => {
                let bytes = &frame[..encoded.len];
                debug_assert!(Frame::new_checked(bytes).is_ok());
                write_frame(&mut out, form, bytes, encoded.tlog_us).map_err(CliError::Write)?;
                written += 1;
            }
            Err(e) => {
                eprintln!("line {number}: {e}");
                errors += 1;
            }
        }
    }
    out.flush().map_err(CliError::Write)?;
    eprintln!("encoded {written} frames; {errors} lines rejected");
    Ok(Outcome::clean_if(errors == 0))
}

/// The text of line `number`, or `None` (reported on stderr) when it is not
/// UTF-8 or too long.
fn line_text(number: u64, line: lines::Line) -> Option<String> {
    match line {
        lines::Line::Text(t) => Some(t),
        lines::Line::NotUtf8 { valid_up_to } => {
            eprintln!("line {number}: not UTF-8 (byte {})", valid_up_to + 1);
            None
        }
        lines::Line::TooLong => {
            eprintln!("line {number}: longer than {} bytes", lines::MAX_LINE);
            None
        }
    }
}

fn write_frame(
    out: &mut impl Write,
    form: Form,
    bytes: &[u8],
    tlog_us: Option<u64>,
) -> std::io::Result<()> {
    match form {
        Form::Hex => writeln!(out, "{}", json::hex(bytes)),
        Form::Tlog => {
            out.write_all(&tlog_us.unwrap_or(0).to_be_bytes())?;
            out.write_all(bytes)
        }
        Form::Binary => out.write_all(bytes),
    }
}
