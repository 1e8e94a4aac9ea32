//! Validators for the numeric (and key) arguments of every subcommand, used
//! as clap `value_parser`s: a bad value is refused while the command line is
//! parsed, with a message saying what is allowed (exit status 2), instead of
//! panicking or running forever later. NaN, infinities and negative numbers
//! are refused everywhere; each kind of value has a range. main.rs marks
//! these arguments `allow_hyphen_values`, so `-1` or `-inf` reaches the
//! validator (clap would otherwise take it for an unknown flag).

use fbwag_delegation::node::{FilterError, MAX_LINKS};
use std::io::{self, Read};
use std::net::SocketAddr;

mod links;
pub use links::*;

/// Longest time any time argument may name: 1,000,000 s (11.6 days). Keeps
/// every time well inside what `Duration`, `Instant` arithmetic and the
/// FC's 32-bit `time_boot_ms` (49.7 days) can hold.
pub const MAX_SECONDS: f64 = 1_000_000.0;

/// Most trials per row of `fbwag sim`: each trial's outcome is kept in
/// memory until the row is summarised.
pub const MAX_TRIALS: u32 = 1_000_000;

/// Largest seed of `fbwag sim`: trial k uses seed + k, which must not
/// overflow.
pub const MAX_SEED: u64 = u64::MAX - MAX_TRIALS as u64;

/// Lowest and highest control stream rate of `fbwag cc` (Hz).
pub const RATE_HZ: (f64, f64) = (1.0, 100.0);

/// PWM range of a throttle override (µs), as ArduPilot's RCn_MIN/MAX allow.
/// 0 and 65535 are not pulse widths in RC_CHANNELS_OVERRIDE: they release
/// or ignore the channel.
pub const PWM_US: (u16, u16) = (800, 2200);

/// Largest mean burst length of `fbwag sim --burst` (frames).
pub const MAX_BURST: f64 = 1_000_000.0;

/// Lowest and highest `fbwag cc --routed-rate` (bytes a second): from a
/// 1,200-baud line's share to far more than any MAVLink link carries.
pub const ROUTED_RATE: (u32, u32) = (60, 100_000_000);

/// Largest signing timestamp: the signature block holds 48 bits.
pub const MAX_SIGN_TIMESTAMP: u64 = (1 << 48) - 1;

/// A value a validator refused: shown by clap after the argument's name.
#[derive(Debug, thiserror::Error)]
pub enum ArgError {
    /// Not a number of the kind, or outside its range.
    #[error("expected {what} from {lo} to {hi}")]
    OutOfRange {
        what: &'static str,
        lo: String,
        hi: String,
    },
    /// A signing key that is not 64 hex digits.
    #[error("expected 64 hex digits (a 32-byte key), got {chars} characters{}",
        if *.non_hex { " with non-hex ones" } else { "" })]
    KeyDigits { chars: usize, non_hex: bool },
    /// `--sign-key @PATH` naming a file that cannot be read.
    #[error("cannot read the key file {path}: {source}")]
    KeyFileUnreadable { path: String, source: io::Error },
    /// A key file group or others may read.
    #[error("the key file {path} may be read by others (mode {mode:o}): chmod 600 {path}")]
    KeyFileOpen { path: String, mode: u32 },
    /// A key file naming another key file.
    #[error("the key file {0} must hold 64 hex digits")]
    KeyFileIndirect(String),
    /// A key file that does not hold a key.
    #[error("key file {path}: {source}")]
    KeyFile { path: String, source: Box<ArgError> },
    /// A connection string that does not parse.
    #[error(transparent)]
    Endpoint(#[from] fbwag_dialect::mavframe::conn::ParseEndpointError),
    /// A filter rule without its link's place.
    #[error(
        "expected LINK:RULE, LINK a link's name or its place from 1 to {MAX_LINKS} (2:block-msg=COMMAND_LONG)"
    )]
    LinkRule,
    /// A routed rate without its link.
    #[error("expected LINK:RATE, LINK a link's name or its place from 1 to {MAX_LINKS}, RATE bytes a second or `off` (2:5760)")]
    LinkRate,
    /// A serial link without its baud rate.
    #[error("serial:{0} gives no baud rate: add the rate the flight controller's port runs at, e.g. serial:{0}:921600 (ArduPilot's SERIALn_BAUD 921) or serial:{0}:57600")]
    SerialRate(String),
    /// Neither a link's place nor a name.
    #[error("expected a link's place from 1 to {MAX_LINKS}, or its name (NAME=CONN named it)")]
    Link,
    /// A filter rule that does not parse.
    #[error(transparent)]
    Filter(#[from] FilterError),
    /// Not an address and port.
    #[error("expected IP:PORT ([IPv6]:PORT), optionally after LINK: (2:10.0.0.5:14550)")]
    Address,
    /// `--autonomy-peer` that is neither `any` nor an address with a port.
    #[error("expected the autonomy program's IP:PORT (127.0.0.1:14561), or `any` (unsafe: any program that speaks first flies the aircraft)")]
    AutonomyPeer,
    /// `--autonomy-peer` with port 0 (any port of the host).
    #[error("port 0 admits every program on that host: give the port the autonomy sends from, or `any` to admit anyone on purpose")]
    AutonomyAnyPort,
}

/// A finite number from `lo` to `hi` (inclusive), else an error naming
/// `what` was expected.
fn number_in(s: &str, lo: f64, hi: f64, what: &'static str) -> Result<f64, ArgError> {
    let v: f64 = s.trim().parse().map_err(|_| out_of_range(lo, hi, what))?;
    // `contains` is false for NaN; the range bounds are finite.
    if (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err(out_of_range(lo, hi, what))
    }
}

/// An integer from `lo` to `hi` (inclusive).
fn integer_in<T>(s: &str, lo: T, hi: T, what: &'static str) -> Result<T, ArgError>
where
    T: std::str::FromStr + PartialOrd + std::fmt::Display + Copy,
{
    let v: T = s.trim().parse().map_err(|_| out_of_range(lo, hi, what))?;
    if lo <= v && v <= hi {
        Ok(v)
    } else {
        Err(out_of_range(lo, hi, what))
    }
}

fn out_of_range(
    lo: impl std::fmt::Display,
    hi: impl std::fmt::Display,
    what: &'static str,
) -> ArgError {
    ArgError::OutOfRange {
        what,
        lo: lo.to_string(),
        hi: hi.to_string(),
    }
}

/// A time in seconds: finite, from 0 to [`MAX_SECONDS`].
pub fn seconds(s: &str) -> Result<f64, ArgError> {
    number_in(s, 0.0, MAX_SECONDS, "a number of seconds")
}

/// A share (loss probability): from 0 to 1.
pub fn share(s: &str) -> Result<f64, ArgError> {
    number_in(s, 0.0, 1.0, "a share")
}

/// A stream rate in Hz, within [`RATE_HZ`].
pub fn rate_hz(s: &str) -> Result<f64, ArgError> {
    number_in(s, RATE_HZ.0, RATE_HZ.1, "a rate in Hz")
}

/// A mean burst length in frames: from 1 to [`MAX_BURST`].
pub fn burst(s: &str) -> Result<f64, ArgError> {
    number_in(s, 1.0, MAX_BURST, "a mean burst length in frames")
}

/// A trial count: from 1 to [`MAX_TRIALS`].
pub fn trials(s: &str) -> Result<u32, ArgError> {
    integer_in(s, 1, MAX_TRIALS, "a number of trials")
}

/// A simulator seed: from 0 to [`MAX_SEED`].
pub fn sim_seed(s: &str) -> Result<u64, ArgError> {
    integer_in(s, 0, MAX_SEED, "a seed")
}

/// Largest size `byte_size` takes: 1 EiB, beyond any disk.
pub const MAX_BYTES: u64 = 1 << 60;

/// A size in bytes, with an optional suffix K, M, G or T (powers of 1024,
/// `KiB` and `k` accepted too): from 0 to [`MAX_BYTES`].
pub fn byte_size(s: &str) -> Result<u64, ArgError> {
    let what = "a size in bytes (suffix K, M, G or T: powers of 1024)";
    let t = s.trim();
    let t = t
        .strip_suffix("iB")
        .or_else(|| t.strip_suffix('B'))
        .unwrap_or(t);
    let (digits, shift) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let shift = match c.to_ascii_uppercase() {
                'K' => 10,
                'M' => 20,
                'G' => 30,
                'T' => 40,
                _ => return Err(out_of_range(0, MAX_BYTES, what)),
            };
            (&t[..i], shift)
        }
        _ => (t, 0),
    };
    let n: u64 = integer_in(digits, 0, MAX_BYTES >> shift, what)
        .map_err(|_| out_of_range(0, MAX_BYTES, what))?;
    Ok(n << shift)
}

/// The smallest `.tlog` file: one record (8-byte time) of the largest
/// frame.
pub const MIN_TLOG_FILE: u64 = fbwag_dialect::mavframe::frame::MAX_FRAME_LEN as u64 + 8;

/// `--tlog-max-size`: a [`byte_size`] of [`MIN_TLOG_FILE`] at least.
pub fn tlog_file_size(s: &str) -> Result<u64, ArgError> {
    let what = "a .tlog file size in bytes (suffix K, M, G or T: powers of 1024)";
    byte_size(s)
        .ok()
        .filter(|n| *n >= MIN_TLOG_FILE)
        .ok_or_else(|| out_of_range(MIN_TLOG_FILE, MAX_BYTES, what))
}

/// A throttle pulse width in µs, within [`PWM_US`].
pub fn pwm_us(s: &str) -> Result<u16, ArgError> {
    integer_in(s, PWM_US.0, PWM_US.1, "a pulse width in µs")
}

/// Shortest report period (s).
pub const MIN_REPORT: f64 = 0.1;

/// `--report`'s period: `None` for no text report.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ReportEvery(pub Option<std::time::Duration>);

/// `--report SECONDS|off`: the period of the daemons' text report (and
/// their status events), `off` or 0 for no text report (status events
/// then every [`crate::live::STATUS_EVERY`]).
pub fn report(s: &str) -> Result<ReportEvery, ArgError> {
    if s.trim() == "off" || s.trim() == "0" {
        return Ok(ReportEvery(None));
    }
    let secs = number_in(s, MIN_REPORT, MAX_SECONDS, "seconds (or `off`, or 0)")?;
    Ok(ReportEvery(Some(std::time::Duration::from_secs_f64(secs))))
}

/// A value of `fbwag cc --routed-rate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RoutedRate {
    /// `off`: unpaced.
    Off,
    /// At most this many bytes a second.
    BytesPerSecond(u32),
}

/// `--routed-rate`: bytes a second within [`ROUTED_RATE`], or `off`.
pub fn routed_rate(s: &str) -> Result<RoutedRate, ArgError> {
    if s.trim() == "off" {
        return Ok(RoutedRate::Off);
    }
    integer_in(s, ROUTED_RATE.0, ROUTED_RATE.1, "bytes a second (or `off`)")
        .map(RoutedRate::BytesPerSecond)
}

/// Whom the autonomy link admits (`fbwag cc --autonomy-peer`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AutonomyPeer {
    /// The program sending from this address, and nobody else.
    At(SocketAddr),
    /// Whoever speaks first (until silent 3 s): unsafe, on purpose.
    Any,
}

/// `IP:PORT` (a port other than 0) or `any`.
pub fn autonomy_peer(s: &str) -> Result<AutonomyPeer, ArgError> {
    if s.trim() == "any" {
        return Ok(AutonomyPeer::Any);
    }
    let addr: SocketAddr = s.trim().parse().map_err(|_| ArgError::AutonomyPeer)?;
    if addr.port() == 0 {
        return Err(ArgError::AutonomyAnyPort);
    }
    Ok(AutonomyPeer::At(addr))
}

/// A MAVLink system or component id of a sender: 1 to 255 (0 addresses
/// every system or component and is no sender's id).
pub fn mavlink_id(s: &str) -> Result<u8, ArgError> {
    integer_in(s, 1, 255, "an id")
}

/// A signing timestamp (10 µs units since 2015-01-01): up to
/// [`MAX_SIGN_TIMESTAMP`].
pub fn sign_timestamp(s: &str) -> Result<u64, ArgError> {
    integer_in(s, 0, MAX_SIGN_TIMESTAMP, "a 48-bit signing timestamp")
}

/// A connection string (`udpin:IP:PORT`, `serial:PATH:BAUD`, ...),
/// after a link's name if given (`NAME=CONN`, see [`split_link_name`]),
/// checked as it is read, kept as given.
/// A serial link must say its baud rate: the library's default
/// (MAVProxy's 57,600) is seldom what a flight controller's port runs at,
/// and a wrong rate looks like a silent FC.
pub fn endpoint(s: &str) -> Result<String, ArgError> {
    let conn = split_link_name(s).1;
    let endpoint = conn.parse::<fbwag_dialect::Endpoint>()?;
    let rate_given = conn
        .rsplit_once(':')
        .is_some_and(|(_, baud)| baud.bytes().all(|b| b.is_ascii_digit()));
    if let (fbwag_dialect::Endpoint::Serial { path, .. }, false) = (endpoint, rate_given) {
        return Err(ArgError::SerialRate(path));
    }
    Ok(s.to_string())
}

/// A 32-byte signing key as exactly 64 hex digits; `@PATH`, a file
/// holding them (surrounding whitespace ignored), readable by its owner
/// only, so that the key need not appear in the process list; or
/// `passphrase:TEXT`, the SHA-256 of TEXT, as MAVProxy's `signing setup
/// TEXT` makes it (one secret for both). Returns the hex digits.
pub fn sign_key(s: &str) -> Result<String, ArgError> {
    if let Some(path) = s.strip_prefix('@') {
        return sign_key_file(path);
    }
    if let Some(passphrase) = s.strip_prefix("passphrase:") {
        use sha2::Digest;
        let key = sha2::Sha256::digest(passphrase.as_bytes());
        return Ok(key.iter().map(|b| format!("{b:02x}")).collect());
    }
    if s.len() == 64 && s.bytes().all(|b| b.is_ascii_hexdigit()) {
        Ok(s.to_string())
    } else {
        Err(ArgError::KeyDigits {
            chars: s.chars().count(),
            non_hex: !s.bytes().all(|b| b.is_ascii_hexdigit()),
        })
    }
}

/// A key file that group or others may read is refused: whoever reads
/// the key can fly the aircraft.
#[cfg(unix)]
fn check_key_file_mode(path: &str, file: &std::fs::File) -> Result<(), ArgError> {
    use std::os::unix::fs::PermissionsExt;
    let mode = file
        .metadata()
        .map_err(|source| ArgError::KeyFileUnreadable {
            path: path.into(),
            source,
        })?
        .permissions()
        .mode();
    if mode & 0o077 != 0 {
        return Err(ArgError::KeyFileOpen {
            path: path.into(),
            mode: mode & 0o777,
        });
    }
    Ok(())
}

#[cfg(not(unix))]
fn check_key_file_mode(_: &str, _: &std::fs::File) -> Result<(), ArgError> {
    Ok(())
}

/// The key of `--sign-key @PATH`: the file is read up to 4 KiB (a key file,
/// not whatever the path names).
fn sign_key_file(path: &str) -> Result<String, ArgError> {
    let mut text = String::new();
    let unreadable = |source| ArgError::KeyFileUnreadable {
        path: path.into(),
        source,
    };
    let file = std::fs::File::open(path).map_err(unreadable)?;
    check_key_file_mode(path, &file)?;
    file.take(4096)
        .read_to_string(&mut text)
        .map_err(unreadable)?;
    let key = text.trim();
    if key.starts_with('@') {
        return Err(ArgError::KeyFileIndirect(path.into()));
    }
    sign_key(key).map_err(|e| ArgError::KeyFile {
        path: path.into(),
        source: Box::new(e),
    })
}

/// Longest de-duplication window (ms): a minute, far more than redundant
/// links' copies are apart.
pub const MAX_DEDUP_MS: u64 = 60_000;

/// A de-duplication window in milliseconds (0: off).
pub fn dedup_ms(s: &str) -> Result<u64, ArgError> {
    integer_in(s, 0, MAX_DEDUP_MS, "milliseconds")
}

/// Receiver failures of `fbwag fc-sim` that do not pair up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OutageError {
    #[error("{lost} --rc-loss-at and {back} --rc-back-at: give one return per failure (the last may be left out)")]
    Count { lost: usize, back: usize },
    #[error("the failure at {0} s starts before the previous one ended")]
    Overlap(f64),
    #[error("--rc-back-at {back} is not after --rc-loss-at {lost}")]
    BackFirst { lost: f64, back: f64 },
}

/// The receiver failures of `fbwag fc-sim`: the k-th `--rc-back-at` ends
/// the k-th `--rc-loss-at` (the last failure may stay open); in order, each
/// return after its failure and before the next failure.
pub fn outages(lost: &[f64], back: &[f64]) -> Result<Vec<(f64, Option<f64>)>, OutageError> {
    if back.len() > lost.len() || back.len() + 1 < lost.len() {
        return Err(OutageError::Count {
            lost: lost.len(),
            back: back.len(),
        });
    }
    let outages: Vec<(f64, Option<f64>)> = lost
        .iter()
        .enumerate()
        .map(|(k, &l)| (l, back.get(k).copied()))
        .collect();
    let mut end = f64::NEG_INFINITY;
    for &(l, b) in &outages {
        if l < end {
            return Err(OutageError::Overlap(l));
        }
        match b {
            Some(b) if b <= l => return Err(OutageError::BackFirst { lost: l, back: b }),
            Some(b) => end = b,
            None => end = f64::INFINITY,
        }
    }
    Ok(outages)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_and_negative_numbers_are_refused_everywhere() {
        for bad in [
            "NaN", "nan", "inf", "-inf", "infinity", "-1", "-0.5", "1e400", "", "x",
        ] {
            assert!(seconds(bad).is_err(), "seconds {bad}");
            assert!(share(bad).is_err(), "share {bad}");
            assert!(rate_hz(bad).is_err(), "rate {bad}");
            assert!(burst(bad).is_err(), "burst {bad}");
            assert!(trials(bad).is_err(), "trials {bad}");
            assert!(sim_seed(bad).is_err(), "seed {bad}");
            assert!(pwm_us(bad).is_err(), "pwm {bad}");
            assert!(mavlink_id(bad).is_err(), "id {bad}");
            assert!(sign_timestamp(bad).is_err(), "timestamp {bad}");
            assert!(routed_rate(bad).is_err(), "routed rate {bad}");
            assert!(byte_size(bad).is_err(), "size {bad}");
        }
    }

    #[test]
    fn sizes_take_binary_suffixes() {
        assert_eq!(byte_size("4096").ok(), Some(4096));
        assert_eq!(byte_size("64M").ok(), Some(64 << 20));
        assert_eq!(byte_size("64MiB").ok(), Some(64 << 20));
        assert_eq!(byte_size("2k").ok(), Some(2048));
        assert_eq!(byte_size("1T").ok(), Some(1 << 40));
        assert_eq!(byte_size("1048576T").ok(), Some(MAX_BYTES));
        for bad in ["1048577T", "64X", "M", "1.5M", "-1K"] {
            assert!(byte_size(bad).is_err(), "size {bad}");
        }
    }

    #[test]
    fn the_bounds_are_inclusive() {
        assert_eq!(seconds("0").ok(), Some(0.0));
        assert_eq!(seconds("1000000").ok(), Some(MAX_SECONDS));
        assert!(seconds("1000000.001").is_err());
        assert_eq!(share("1").ok(), Some(1.0));
        assert!(share("1.0000001").is_err());
        assert_eq!(rate_hz("100").ok(), Some(100.0));
        assert!(rate_hz("0.5").is_err());
        assert_eq!(trials("1000000").ok(), Some(MAX_TRIALS));
        assert!(trials("0").is_err());
        assert_eq!(sim_seed(&MAX_SEED.to_string()).ok(), Some(MAX_SEED));
        assert!(sim_seed(&u64::MAX.to_string()).is_err());
        assert_eq!(pwm_us("800").ok(), Some(800));
        assert!(pwm_us("0").is_err() && pwm_us("65535").is_err());
        assert!(mavlink_id("0").is_err() && mavlink_id("256").is_err());
        assert_eq!(
            sign_timestamp("281474976710655").ok(),
            Some(MAX_SIGN_TIMESTAMP)
        );
        assert!(sign_timestamp("281474976710656").is_err());
        assert_eq!(routed_rate("60").ok(), Some(RoutedRate::BytesPerSecond(60)));
        assert_eq!(routed_rate("off").ok(), Some(RoutedRate::Off));
        assert!(routed_rate("59").is_err() && routed_rate("0").is_err());
        assert!(routed_rate("100000001").is_err());
    }

    #[test]
    fn a_serial_link_says_its_baud_rate() {
        let err = endpoint("serial:/dev/ttyAMA0").unwrap_err().to_string();
        assert!(err.contains("serial:/dev/ttyAMA0:921600"), "{err}");
        assert!(endpoint("fc=serial:/dev/ttyAMA0").is_err());
        assert!(endpoint("serial:/dev/ttyAMA0:921600").is_ok());
        assert!(endpoint("fc=serial:/dev/ttyAMA0:57600").is_ok());
        assert!(endpoint("udpin:0.0.0.0:14550").is_ok());
    }

    #[test]
    fn keys_are_64_hex_digits() {
        let k = "0f".repeat(32);
        assert_eq!(sign_key(&k).ok(), Some(k.clone()));
        let dir = std::env::temp_dir().join(format!("fbwag-key-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("key.hex");
        std::fs::write(&file, format!("{k}\n")).unwrap();
        // Readable by others (the umask's 644): refused, saying the fix.
        use std::os::unix::fs::PermissionsExt;
        let err = sign_key(&format!("@{}", file.display()))
            .unwrap_err()
            .to_string();
        assert!(err.contains("(mode 644): chmod 600"), "{err}");
        std::fs::set_permissions(&file, std::fs::Permissions::from_mode(0o600)).unwrap();
        assert_eq!(
            sign_key(&format!("@{}", file.display())).ok(),
            Some(k.clone())
        );
        std::fs::write(&file, &k[..62]).unwrap();
        assert!(sign_key(&format!("@{}", file.display())).is_err());
        assert!(sign_key(&format!("@{}", dir.join("absent").display())).is_err());
        let _ = std::fs::remove_dir_all(&dir);
        assert!(sign_key(&k[..62]).is_err());
        assert!(sign_key(&format!("{}zz", &k[..62])).is_err());
        // MAVProxy's `signing setup fbwag-bench` makes this key.
        assert_eq!(
            sign_key("passphrase:fbwag-bench").ok().as_deref(),
            Some("1eeb12caa5637aa80caed04c6ac2783bdae83ca2c99c9f8a4cb9fe3861365094")
        );
    }
}

#[cfg(test)]
mod outage_tests {
    use super::outages;

    #[test]
    fn failures_pair_with_returns_in_order() {
        assert_eq!(
            outages(&[1.0, 5.0], &[3.0]),
            Ok(vec![(1.0, Some(3.0)), (5.0, None)])
        );
        assert!(
            outages(&[1.0], &[1.0]).is_err(),
            "a return after its failure"
        );
        assert!(outages(&[1.0, 2.0], &[3.0, 4.0]).is_err(), "no overlap");
        assert!(
            outages(&[1.0], &[2.0, 3.0]).is_err(),
            "one return per failure"
        );
        assert!(
            outages(&[1.0, 2.0, 3.0], &[1.5]).is_err(),
            "only the last open"
        );
    }
}

/// `fbwag cc --autonomy-fallback`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum AutonomyFallback {
    /// Decline the takeover: the FC's failsafe runs at once.
    Decline,
    /// Take over and fly wings level until the autonomy speaks.
    WingsLevel,
}

impl From<AutonomyFallback> for fbwag_delegation::node::AutonomyFallback {
    fn from(f: AutonomyFallback) -> Self {
        match f {
            AutonomyFallback::Decline => Self::Decline,
            AutonomyFallback::WingsLevel => Self::WingsLevel,
        }
    }
}

/// `fbwag cc --controller`: what flies in companion control without an
/// autonomy program.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ControllerKind {
    WingsLevel,
    Circle,
}

impl ControllerKind {
    /// The controller, at cruise `throttle` (PWM µs).
    pub fn build(
        self,
        throttle: u16,
    ) -> Box<dyn fbwag_delegation::control::Controller + Send + Sync> {
        use fbwag_delegation::control::{Circle, WingsLevel};
        match self {
            ControllerKind::WingsLevel => Box::new(WingsLevel { throttle }),
            ControllerKind::Circle => Box::new(Circle { throttle }),
        }
    }
}
