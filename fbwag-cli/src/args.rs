//! Validators for the numeric (and key) arguments of every subcommand, used
//! as clap `value_parser`s: a bad value is refused while the command line is
//! parsed, with a message saying what is allowed (exit status 2), instead of
//! panicking or running forever later. NaN, infinities and negative numbers
//! are refused everywhere; each kind of value has a range. main.rs marks
//! these arguments `allow_hyphen_values`, so `-1` or `-inf` reaches the
//! validator (clap would otherwise take it for an unknown flag).

use fbwag_delegation::control::Control;
use fbwag_delegation::node::{Direction, Filter, FilterError, FilterRules, MAX_LINKS};
use std::io::{self, Read};
use std::net::SocketAddr;

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
        "expected LINK:RULE, LINK a link's place from 1 to {MAX_LINKS} (2:block-msg=COMMAND_LONG)"
    )]
    LinkRule,
    /// A routed rate without its link's place.
    #[error("expected LINK:RATE, LINK a link's place from 1 to {MAX_LINKS}, RATE bytes a second or `off` (2:5760)")]
    LinkRate,
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

/// `LINK:REST`: a link's place (1 to [`MAX_LINKS`]) and what follows it.
fn link_place(s: &str) -> Option<(usize, &str)> {
    let (link, rest) = s.split_once(':')?;
    let link = link.trim().parse::<usize>().ok()?;
    (1..=MAX_LINKS).contains(&link).then_some((link, rest))
}

/// A value of an option given per link: `LINK:VALUE` for the link at that
/// place (from 1), or `VALUE` alone for every link without its own.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ForLink<T> {
    /// The link's place, from 1; `None`: every link.
    pub link: Option<usize>,
    pub value: T,
}

impl<T> ForLink<T> {
    /// `[LINK:]VALUE`, VALUE read by `parse`. (A value never starts with
    /// a number and a colon: hex digits, `@PATH`, an IPv4 address have
    /// none; an IPv6 one is in brackets.)
    fn parse(s: &str, parse: impl Fn(&str) -> Result<T, ArgError>) -> Result<Self, ArgError> {
        let (link, value) = match link_place(s) {
            Some((link, value)) => (Some(link), value),
            None => (None, s),
        };
        Ok(ForLink {
            link,
            value: parse(value)?,
        })
    }
}

/// `[LINK:]KEY`: a signing key (see [`sign_key`]), for one link or all.
pub fn link_sign_key(s: &str) -> Result<ForLink<String>, ArgError> {
    ForLink::parse(s, sign_key)
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

/// `[LINK:]IP:PORT`: a peer address, for one link or all.
pub fn link_peer(s: &str) -> Result<ForLink<SocketAddr>, ArgError> {
    ForLink::parse(s, |v| v.trim().parse().map_err(|_| ArgError::Address))
}

/// Each of `links` links' value of option `flag` from what was `given`:
/// the link's own, else the one given for every link, else none. A later
/// value replaces an earlier one for the same link (or for every link),
/// as single-valued options do: a `--config` file's come first, so the
/// command line's win.
pub fn per_link<T: Clone>(
    flag: &str,
    given: &[ForLink<T>],
    links: usize,
) -> Result<Vec<Option<T>>, (String, LinkOptionError)> {
    let mut every: Option<T> = None;
    let mut own: Vec<Option<T>> = vec![None; links];
    for g in given {
        let slot = match g.link {
            None => &mut every,
            Some(link) => own.get_mut(link - 1).ok_or_else(|| {
                let error = LinkOptionError::NoSuchLink { link, links };
                (format!("{flag} {link}"), error)
            })?,
        };
        *slot = Some(g.value.clone());
    }
    Ok(own
        .into_iter()
        .map(|v| v.or_else(|| every.clone()))
        .collect())
}

/// A link's place among a daemon's links, from 1.
pub fn link_number(s: &str) -> Result<usize, ArgError> {
    integer_in(s, 1, MAX_LINKS, "a link's place (from 1)")
}

/// The 0-based index of the link at place `link` (from 1) of `links`.
fn link_index(link: usize, links: usize) -> Option<usize> {
    link.checked_sub(1).filter(|i| *i < links)
}

/// The 0-based indices of the links `places` (from 1) name, over
/// `links` links; `flag` names the option in an error.
pub fn link_indices(
    flag: &str,
    places: &[usize],
    links: usize,
) -> Result<Vec<usize>, (String, LinkOptionError)> {
    places
        .iter()
        .map(|&link| match link_index(link, links) {
            Some(index) => Ok(index),
            None => Err((
                format!("{flag} {link}"),
                LinkOptionError::NoSuchLink { link, links },
            )),
        })
        .collect()
}

/// `fbwag router --routed-rate LINK:RATE`: the pace of what is routed to
/// the link at that place (from 1), both checked as they are read; LINK
/// is required.
pub fn link_rate(s: &str) -> Result<ForLink<RoutedRate>, ArgError> {
    let (link, rate) = link_place(s).ok_or(ArgError::LinkRate)?;
    Ok(ForLink {
        link: Some(link),
        value: routed_rate(rate)?,
    })
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
/// checked as it is read, kept as given.
pub fn endpoint(s: &str) -> Result<String, ArgError> {
    s.parse::<fbwag_dialect::Endpoint>()?;
    Ok(s.to_string())
}

/// A 32-byte signing key as exactly 64 hex digits, or `@PATH`: a file
/// holding them (surrounding whitespace ignored), so that the key need not
/// appear in the process list. Returns the hex digits.
pub fn sign_key(s: &str) -> Result<String, ArgError> {
    if let Some(path) = s.strip_prefix('@') {
        return sign_key_file(path);
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

/// The key of `--sign-key @PATH`: the file is read up to 4 KiB (a key file,
/// not whatever the path names).
fn sign_key_file(path: &str) -> Result<String, ArgError> {
    let mut text = String::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(4096).read_to_string(&mut text))
        .map_err(|source| ArgError::KeyFileUnreadable {
            path: path.into(),
            source,
        })?;
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

/// A rule of `--filter-in`/`--filter-out`: `LINK:RULE`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkRule {
    /// The link's place among the links given, from 1.
    pub link: usize,
    /// The rule, as given (it parses).
    pub rule: String,
}

/// `LINK:RULE`, the rule checked as it is read (see
/// `fbwag_delegation::node::FilterRules::parse`).
pub fn link_rule(s: &str) -> Result<LinkRule, ArgError> {
    let (link, rule) = link_place(s).ok_or(ArgError::LinkRule)?;
    FilterRules::new().parse(rule)?;
    Ok(LinkRule {
        link,
        rule: rule.trim().to_string(),
    })
}

/// The filter of one direction of one link, from the rules given for it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkFilter {
    /// The link's place among the links it numbers, from 0.
    pub index: usize,
    /// Which way.
    pub direction: Direction,
    /// The filter.
    pub filter: Filter,
    /// Its rules as given, for the log.
    pub rules: Vec<String>,
}

/// Why options given per link (filters, keys, peers, paces) cannot
/// apply.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum LinkOptionError {
    /// A value for a link past the last one given.
    #[error("link {link}: {} (counted from 1)", match links { 1 => "there is 1 link".to_string(), n => format!("there are {n} links") })]
    NoSuchLink { link: usize, links: usize },
    /// Rules that together do not make a filter (too many message ids).
    #[error(transparent)]
    Rules(#[from] FilterError),
    /// A peer for a link that answers its target or its stream only.
    #[error("link {0} does not listen: a peer is for udpin and tcpin links")]
    NotListening(String),
    /// Port 0 (any port) for a link that sends to one address.
    #[error("a udpin link sends to one port: IP:0 (any port of IP) is for tcpin links")]
    AnyPort,
    /// A rule blocking the autonomy's control message: the handover, not
    /// a filter, decides where that goes.
    #[error("the autonomy's {0} is never filtered: the handover gates it (leave out --autonomy to keep any program from steering)")]
    AutonomyControl(&'static str),
    /// An IPv6 peer for a link that listens on IPv4: it can never speak.
    #[error("link {0} listens on IPv4: an IPv6 peer can never reach it")]
    OtherFamily(String),
}

/// `--peer` values where they apply: a listening link (`udpin`, `tcpin`);
/// `IP:0`, any port of IP, on `tcpin` only (a datagram needs a port). A
/// value for every link applies to the listening ones.
pub fn check_peers(
    given: &[ForLink<SocketAddr>],
    endpoints: &[fbwag_dialect::Endpoint],
) -> Result<(), (String, LinkOptionError)> {
    use fbwag_dialect::mavframe::conn::Address;
    use fbwag_dialect::Endpoint;
    for g in given {
        let arg = || g.link.map_or("--peer".into(), |l| format!("--peer {l}"));
        let on: Vec<&Endpoint> = match g.link {
            Some(link) => endpoints.get(link - 1).into_iter().collect(),
            None => endpoints.iter().collect(),
        };
        for endpoint in on {
            match endpoint {
                Endpoint::UdpIn(_) if g.value.port() == 0 => {
                    return Err((arg(), LinkOptionError::AnyPort))
                }
                Endpoint::UdpIn(Address::Ip(at)) | Endpoint::TcpIn(Address::Ip(at))
                    if at.is_ipv4() && g.value.is_ipv6() =>
                {
                    let link = endpoint.to_string();
                    return Err((arg(), LinkOptionError::OtherFamily(link)));
                }
                Endpoint::UdpIn(_) | Endpoint::TcpIn(_) => {}
                other if g.link.is_some() => {
                    return Err((arg(), LinkOptionError::NotListening(other.to_string())))
                }
                _ => {}
            }
        }
    }
    Ok(())
}

/// The filters `--filter-in` (`ins`) and `--filter-out` (`outs`) rules
/// make, over `links` links; an error names the flag and value at fault.
pub fn link_filters(
    ins: &[LinkRule],
    outs: &[LinkRule],
    links: usize,
) -> Result<Vec<LinkFilter>, (String, LinkOptionError)> {
    let mut filters: Vec<(usize, Direction, FilterRules, Vec<String>)> = Vec::new();
    let given = [(Direction::In, ins), (Direction::Out, outs)];
    for (direction, rules) in given {
        for r in rules {
            let flag = match direction {
                Direction::In => "--filter-in",
                Direction::Out => "--filter-out",
            };
            let fault = |e| (format!("{flag} {}:{}", r.link, r.rule), e);
            let Some(index) = link_index(r.link, links) else {
                return Err(fault(LinkOptionError::NoSuchLink {
                    link: r.link,
                    links,
                }));
            };
            let at = match filters
                .iter()
                .position(|f| f.0 == index && f.1 == direction)
            {
                Some(at) => at,
                None => {
                    filters.push((index, direction, FilterRules::new(), Vec::new()));
                    filters.len() - 1
                }
            };
            let entry = &mut filters[at];
            entry.2.parse(&r.rule).map_err(|e| fault(e.into()))?;
            entry.3.push(r.rule.clone());
        }
    }
    Ok(filters
        .into_iter()
        .map(|(index, direction, rules, text)| LinkFilter {
            index,
            direction,
            filter: rules.filter(),
            rules: text,
        })
        .collect())
}

/// Refuses a `--filter-in` rule of link `link` (the autonomy's place)
/// that blocks one of the control messages: filters never touch them, so
/// such a rule would only seem to keep the autonomy from steering.
pub fn check_autonomy_rules(
    ins: &[LinkRule],
    link: usize,
) -> Result<(), (String, LinkOptionError)> {
    for r in ins.iter().filter(|r| r.link == link) {
        let mut rules = FilterRules::new();
        // Checked as it was read: an error here cannot block anything.
        if rules.parse(&r.rule).is_err() {
            continue;
        }
        let control = Control::MESSAGES
            .into_iter()
            .find(|(id, _)| rules.blocks_msg(*id));
        if let Some((_, name)) = control {
            let arg = format!("--filter-in {}:{}", r.link, r.rule);
            return Err((arg, LinkOptionError::AutonomyControl(name)));
        }
    }
    Ok(())
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
    fn a_value_for_one_link_outranks_the_one_for_every_link() {
        let peers: Vec<_> = ["10.0.0.1:14550", "3:10.0.0.3:14550", "[::1]:5760"]
            .iter()
            .map(|s| link_peer(s).unwrap())
            .collect();
        assert_eq!(peers[0].link, None);
        assert_eq!(peers[1].link, Some(3));
        assert_eq!(peers[2].link, None, "an IPv6 address is no link");
        let each = per_link("--peer", &peers[..2], 3).unwrap();
        let addr = |s: &str| Some(s.parse::<SocketAddr>().unwrap());
        let every = addr("10.0.0.1:14550");
        assert_eq!(each, vec![every, every, addr("10.0.0.3:14550")]);
        assert_eq!(per_link("--peer", &peers[1..2], 3).unwrap()[0], None);
        let key = "ab".repeat(32);
        assert_eq!(link_sign_key(&format!("2:{key}")).unwrap().link, Some(2));
        assert_eq!(link_sign_key(&key).unwrap().link, None);
        assert!(link_peer("2:nowhere").is_err());
    }

    #[test]
    fn a_later_value_for_a_link_wins_and_one_past_the_last_is_refused() {
        let peer = |s: &str| link_peer(s).unwrap();
        let addr = |s: &str| Some(s.parse::<SocketAddr>().unwrap());
        let twice = [peer("2:10.0.0.1:1"), peer("2:10.0.0.2:1")];
        let got = per_link("--peer", &twice, 2).unwrap();
        assert_eq!(got, vec![None, addr("10.0.0.2:1")]);
        let both = [peer("10.0.0.1:1"), peer("10.0.0.2:1")];
        let got = per_link("--peer", &both, 2).unwrap();
        assert_eq!(got, vec![addr("10.0.0.2:1"); 2]);
        let past = [peer("3:10.0.0.1:1")];
        let err = per_link("--peer", &past, 2).unwrap_err().1;
        assert_eq!(err, LinkOptionError::NoSuchLink { link: 3, links: 2 });
    }

    /// A peer pinned on a link that does not listen would be ignored
    /// while the log said otherwise; IP:0 on udpin would answer nobody.
    #[test]
    fn a_peer_goes_only_where_it_applies() {
        let peer = |s: &str| link_peer(s).unwrap();
        let links: Vec<fbwag_dialect::Endpoint> =
            ["udpin:0.0.0.0:1", "udpout:10.0.0.9:2", "tcpin:0.0.0.0:3"]
                .map(|e| e.parse().unwrap())
                .into();
        assert!(check_peers(&[peer("10.0.0.1:1"), peer("3:10.0.0.2:0")], &links).is_ok());
        let err = check_peers(&[peer("2:10.0.0.1:1")], &links).unwrap_err();
        assert!(matches!(err.1, LinkOptionError::NotListening(_)), "{err:?}");
        let err = check_peers(&[peer("3:[::1]:5")], &links).unwrap_err();
        assert!(matches!(err.1, LinkOptionError::OtherFamily(_)), "{err:?}");
        for any_port in ["1:10.0.0.1:0", "10.0.0.1:0"] {
            let err = check_peers(&[peer(any_port)], &links).unwrap_err();
            assert_eq!(err.1, LinkOptionError::AnyPort, "{any_port}");
        }
    }

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
    fn keys_are_64_hex_digits() {
        let k = "0f".repeat(32);
        assert_eq!(sign_key(&k).ok(), Some(k.clone()));
        let dir = std::env::temp_dir().join(format!("fbwag-key-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("key.hex");
        std::fs::write(&file, format!("{k}\n")).unwrap();
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
    }

    #[test]
    fn a_link_is_named_by_its_place_among_those_given() {
        assert_eq!(link_number("3").ok(), Some(3));
        assert!(link_number("0").is_err() && link_number("x").is_err());
        assert_eq!(link_indices("--sniffer", &[3, 1], 3), Ok(vec![2, 0]));
        let (arg, e) = link_indices("--sniffer", &[4], 3).unwrap_err();
        assert_eq!(arg, "--sniffer 4");
        assert_eq!(e, LinkOptionError::NoSuchLink { link: 4, links: 3 });
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
