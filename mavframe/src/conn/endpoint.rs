//! Connection strings in MAVProxy's style, parsed into [`Endpoint`].

use core::fmt;
use core::str::FromStr;
use std::io;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, ToSocketAddrs};
use std::path::PathBuf;
use std::string::{String, ToString};
use std::vec::Vec;

/// Baud rate of a `serial:` string without one (MAVProxy's default).
pub const DEFAULT_BAUD: u32 = 57_600;

/// A network address in a connection string: an IP literal, or a host
/// name that [`resolve`](Address::resolve) looks up when the endpoint is
/// opened (never while parsing, so parsing never touches the network).
///
/// ```
/// use mavframe::conn::Address;
/// use std::net::SocketAddr;
///
/// let ip = Address::from(SocketAddr::from(([127, 0, 0, 1], 14550)));
/// assert_eq!(ip.resolve()?, vec![SocketAddr::from(([127, 0, 0, 1], 14550))]);
/// let name = Address::Name { host: "localhost".into(), port: 5760 };
/// assert_eq!(name.to_string(), "localhost:5760");
/// assert_eq!(name.port(), 5760);
/// # Ok::<(), mavframe::conn::ResolveError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Address {
    /// An IP address and port, used as they are.
    Ip(SocketAddr),
    /// A host name and port, resolved at open.
    Name {
        /// The host name as written (letters, digits, `-`, `.`).
        host: String,
        /// The port.
        port: u16,
    },
}

impl Address {
    /// The port.
    pub fn port(&self) -> u16 {
        match self {
            Address::Ip(a) => a.port(),
            Address::Name { port, .. } => *port,
        }
    }

    /// The addresses to use, IPv4 first (as pymavlink, which resolves with
    /// `gethostbyname`, only knows IPv4: `localhost` then means 127.0.0.1
    /// even where `::1` is listed first). An IP address is itself; a name
    /// is looked up now, through the system resolver (blocking).
    pub fn resolve(&self) -> Result<Vec<SocketAddr>, ResolveError> {
        let (host, port) = match self {
            Address::Ip(a) => return Ok(std::vec![*a]),
            Address::Name { host, port } => (host, *port),
        };
        let found =
            (host.as_str(), port)
                .to_socket_addrs()
                .map_err(|source| ResolveError::Lookup {
                    host: host.clone(),
                    port,
                    source,
                })?;
        resolved(host, port, found)
    }

    /// The first address [`resolve`](Self::resolve) gives: what a UDP
    /// socket binds or sends to.
    pub fn resolve_first(&self) -> Result<SocketAddr, ResolveError> {
        // resolve() never returns an empty list.
        self.resolve()?
            .first()
            .copied()
            .ok_or_else(|| self.no_address())
    }

    fn no_address(&self) -> ResolveError {
        ResolveError::NoAddress {
            host: self.to_string(),
            port: self.port(),
        }
    }
}

/// Sorts the lookup's answer IPv4 first; an empty answer is an error.
fn resolved(
    host: &str,
    port: u16,
    found: impl Iterator<Item = SocketAddr>,
) -> Result<Vec<SocketAddr>, ResolveError> {
    let mut all: Vec<SocketAddr> = found.collect();
    // Stable: the resolver's order is kept within each family.
    all.sort_by_key(|a| a.is_ipv6());
    if all.is_empty() {
        return Err(ResolveError::NoAddress {
            host: host.to_string(),
            port,
        });
    }
    Ok(all)
}

impl From<SocketAddr> for Address {
    fn from(a: SocketAddr) -> Self {
        Address::Ip(a)
    }
}

impl fmt::Display for Address {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            // SocketAddr writes IPv6 in brackets, as we parse it.
            Address::Ip(a) => write!(f, "{a}"),
            Address::Name { host, port } => write!(f, "{host}:{port}"),
        }
    }
}

/// A host name that gives no address to use, from
/// [`Address::resolve`]. Opening an endpoint returns it inside an
/// [`io::Error`] of kind [`NotFound`](io::ErrorKind::NotFound)
/// (`err.get_ref()` and `downcast_ref::<ResolveError>()` recover it).
#[derive(Debug)]
#[non_exhaustive]
pub enum ResolveError {
    /// The system resolver failed (unknown name, no resolver reachable).
    Lookup {
        /// The host name.
        host: String,
        /// The port.
        port: u16,
        /// The resolver's error.
        source: io::Error,
    },
    /// The resolver answered with no address.
    NoAddress {
        /// The host name.
        host: String,
        /// The port.
        port: u16,
    },
}

impl fmt::Display for ResolveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ResolveError::Lookup { host, port, source } => {
                write!(f, "cannot resolve host `{host}` (port {port}): {source}")
            }
            ResolveError::NoAddress { host, port } => {
                write!(f, "host `{host}` (port {port}) has no address")
            }
        }
    }
}

impl core::error::Error for ResolveError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            ResolveError::Lookup { source, .. } => Some(source),
            ResolveError::NoAddress { .. } => None,
        }
    }
}

impl From<ResolveError> for io::Error {
    fn from(e: ResolveError) -> Self {
        io::Error::new(io::ErrorKind::NotFound, e)
    }
}

/// Where a connection goes: the parsed form of a connection string
/// (`"udpin:0.0.0.0:14550".parse()`), displayed back as one.
///
/// | string | meaning |
/// |---|---|
/// | `udpin:HOST:PORT` | bind and listen; replies go to the senders of accepted frames (up to 8, see [`ReplyTo`](super::ReplyTo)) |
/// | `udp:HOST:PORT` | alias of `udpin` (MAVProxy's `udp:` listens too); displayed as `udpin:` |
/// | `udpout:HOST:PORT` | send to `HOST:PORT` from an ephemeral port connected to it; its replies, and only its, are received |
/// | `udpbcast:HOST:PORT` | broadcast to `HOST:PORT` (`SO_BROADCAST`) until a frame is accepted, then reply to the senders of accepted frames |
/// | `tcp:HOST:PORT` | TCP client |
/// | `tcpout:HOST:PORT` | alias of `tcp` (pymavlink's name); displayed as `tcp:` |
/// | `tcpin:HOST:PORT` | TCP server: accepts clients, sends to all, receives from any |
/// | `serial:PATH[:BAUD]` | serial device, `BAUD` defaulting to [`DEFAULT_BAUD`] |
/// | `file:PATH` | a capture of raw MAVLink bytes read as a link (receive only) |
///
/// `HOST` is an IP literal (IPv4 as `127.0.0.1`, IPv6 in brackets as
/// `[::1]`) or a host name (`localhost`), kept as an [`Address`] and
/// resolved once, when the endpoint is opened: parsing never touches the
/// network, and a name that does not resolve fails the open with a
/// [`ResolveError`]. Port 0 is accepted where we bind (`udpin`, `tcpin`:
/// the system picks a free port) and refused where we send to (`udpout`,
/// `udpbcast`, `tcp`).
///
/// Serial paths may contain `:` (Linux device paths normally do not): the
/// last `:`-separated part is the baud rate when it is non-empty and all
/// ASCII digits, otherwise it belongs to the path; a trailing `:` with
/// nothing after it is an error rather than part of the path. `Display`
/// always writes the baud rate, so a displayed endpoint parses back to
/// itself whatever its path. A `file:` path is everything after `file:`.
///
/// ```
/// use mavframe::conn::{Address, Endpoint, ParseEndpointError};
/// use std::net::SocketAddr;
///
/// let e: Endpoint = "tcpout:127.0.0.1:5760".parse()?;
/// assert_eq!(e, Endpoint::Tcp(SocketAddr::from(([127, 0, 0, 1], 5760)).into()));
/// assert_eq!(e.to_string(), "tcp:127.0.0.1:5760");
///
/// let e: Endpoint = "udpout:localhost:14550".parse()?;
/// assert_eq!(e, Endpoint::UdpOut(Address::Name { host: "localhost".into(), port: 14550 }));
///
/// let err = "udpout:127.0.0.1:x".parse::<Endpoint>().unwrap_err();
/// assert_eq!(err, ParseEndpointError::InvalidPort { scheme: "udpout".into(), port: "x".into() });
/// # Ok::<(), ParseEndpointError>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Endpoint {
    /// `udpin:` (or `udp:`): bind to this address and listen.
    UdpIn(Address),
    /// `udpout:`: send to this address from an ephemeral local port.
    UdpOut(Address),
    /// `udpbcast:`: broadcast to this address from an ephemeral local
    /// port until a frame is accepted, then send to the senders of
    /// accepted frames.
    UdpBcast(Address),
    /// `tcp:` (or `tcpout:`): connect to this server.
    Tcp(Address),
    /// `tcpin:`: listen on this address and serve every client that connects.
    TcpIn(Address),
    /// `serial:`: a serial device.
    Serial {
        /// Device path, e.g. `/dev/serial0` or `COM3`.
        path: String,
        /// Baud rate (never 0 when parsed).
        baud: u32,
    },
    /// `file:`: a capture file read as a link.
    File(PathBuf),
}

impl Endpoint {
    /// The canonical scheme, as [`Display`](fmt::Display) writes it
    /// (`udpin` for both `udpin:` and `udp:`, `tcp` for `tcp:` and
    /// `tcpout:`).
    pub fn scheme(&self) -> &'static str {
        match self {
            Endpoint::UdpIn(_) => "udpin",
            Endpoint::UdpOut(_) => "udpout",
            Endpoint::UdpBcast(_) => "udpbcast",
            Endpoint::Tcp(_) => "tcp",
            Endpoint::TcpIn(_) => "tcpin",
            Endpoint::Serial { .. } => "serial",
            Endpoint::File(_) => "file",
        }
    }

    /// The network address, for the schemes that have one (not `serial:`
    /// or `file:`).
    pub fn address(&self) -> Option<&Address> {
        match self {
            Endpoint::UdpIn(a)
            | Endpoint::UdpOut(a)
            | Endpoint::UdpBcast(a)
            | Endpoint::Tcp(a)
            | Endpoint::TcpIn(a) => Some(a),
            Endpoint::Serial { .. } | Endpoint::File(_) => None,
        }
    }
}

impl fmt::Display for Endpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Endpoint::UdpIn(a)
            | Endpoint::UdpOut(a)
            | Endpoint::UdpBcast(a)
            | Endpoint::Tcp(a)
            | Endpoint::TcpIn(a) => write!(f, "{}:{a}", self.scheme()),
            Endpoint::Serial { path, baud } => write!(f, "serial:{path}:{baud}"),
            // A path that is not UTF-8 cannot have come from a string.
            Endpoint::File(path) => write!(f, "file:{}", path.display()),
        }
    }
}

/// Why a connection string is not an [`Endpoint`]: which part is wrong, and
/// what is expected there (see the `Display` text).
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum ParseEndpointError {
    /// No `SCHEME:` prefix.
    MissingScheme {
        /// The whole string.
        input: String,
    },
    /// A scheme this crate does not know.
    UnknownScheme {
        /// The scheme as written.
        scheme: String,
    },
    /// A network address without `:PORT`.
    MissingPort {
        /// The scheme as written.
        scheme: String,
        /// The address part.
        address: String,
    },
    /// The host part is neither an IP literal nor a host name.
    InvalidHost {
        /// The scheme as written.
        scheme: String,
        /// The host part.
        host: String,
    },
    /// The port part is not a number in 0..=65535.
    InvalidPort {
        /// The scheme as written.
        scheme: String,
        /// The port part.
        port: String,
    },
    /// Port 0 where a destination port is needed (`udpout`, `udpbcast`,
    /// `tcp`).
    ZeroPort {
        /// The scheme as written.
        scheme: String,
    },
    /// `serial:` without a device path.
    MissingPath,
    /// A serial string ending in `:` with nothing after it.
    EmptyBaud,
    /// A serial baud rate of 0 or above `u32::MAX`.
    InvalidBaud {
        /// The baud part.
        baud: String,
    },
    /// `file:` without a path.
    MissingFilePath,
}

const SCHEMES: &str = "udpin, udp, udpout, udpbcast, tcp, tcpout, tcpin, serial, file";

/// An address to show in messages, fitting the scheme's role.
fn example(scheme: &str) -> &'static str {
    match scheme {
        "udpout" => "127.0.0.1:14550",
        "udpbcast" => "255.255.255.255:14550",
        "tcp" | "tcpout" => "127.0.0.1:5760",
        "tcpin" => "0.0.0.0:5760",
        _ => "0.0.0.0:14550",
    }
}

impl fmt::Display for ParseEndpointError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use ParseEndpointError::*;
        match self {
            MissingScheme { input } => write!(
                f,
                "`{input}` has no scheme: expected SCHEME:ADDRESS with SCHEME one of \
                 {SCHEMES} (e.g. udpin:0.0.0.0:14550)"
            ),
            UnknownScheme { scheme } => {
                write!(f, "unknown scheme `{scheme}`: expected one of {SCHEMES}")
            }
            MissingPort { scheme, address } => write!(
                f,
                "{scheme}: address `{address}` has no port: expected HOST:PORT, e.g. {}",
                example(scheme)
            ),
            InvalidHost { scheme, host } => write!(
                f,
                "{scheme}: host `{host}` is neither an IP address nor a host name: expected \
                 IPv4 such as 127.0.0.1, IPv6 in brackets such as [::1], or a name such \
                 as localhost"
            ),
            InvalidPort { scheme, port } => {
                write!(f, "{scheme}: port `{port}` is not a number in 0..=65535")
            }
            ZeroPort { scheme } => write!(
                f,
                "{scheme}: port 0 cannot be sent to: expected a port in 1..=65535"
            ),
            MissingPath => write!(
                f,
                "serial: missing device path: expected serial:PATH[:BAUD], \
                 e.g. serial:/dev/serial0:57600"
            ),
            EmptyBaud => write!(
                f,
                "serial: empty baud rate after the last ':': expected serial:PATH[:BAUD], \
                 e.g. serial:/dev/serial0:57600"
            ),
            InvalidBaud { baud } => {
                write!(f, "serial: baud rate `{baud}` is not in 1..=4294967295")
            }
            MissingFilePath => write!(
                f,
                "file: missing path: expected file:PATH, e.g. file:flight.bin"
            ),
        }
    }
}

impl core::error::Error for ParseEndpointError {}

impl FromStr for Endpoint {
    type Err = ParseEndpointError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let Some((scheme, rest)) = s.split_once(':') else {
            return Err(ParseEndpointError::MissingScheme {
                input: s.to_string(),
            });
        };
        match scheme {
            "udpin" | "udp" => Ok(Endpoint::UdpIn(address(scheme, rest, false)?)),
            "udpout" => Ok(Endpoint::UdpOut(address(scheme, rest, true)?)),
            "udpbcast" => Ok(Endpoint::UdpBcast(address(scheme, rest, true)?)),
            "tcp" | "tcpout" => Ok(Endpoint::Tcp(address(scheme, rest, true)?)),
            "tcpin" => Ok(Endpoint::TcpIn(address(scheme, rest, false)?)),
            "serial" => serial(rest),
            "file" if rest.is_empty() => Err(ParseEndpointError::MissingFilePath),
            "file" => Ok(Endpoint::File(PathBuf::from(rest))),
            _ => Err(ParseEndpointError::UnknownScheme {
                scheme: scheme.to_string(),
            }),
        }
    }
}

/// `HOST:PORT`, IPv6 in brackets; `destination` refuses port 0.
fn address(scheme: &str, address: &str, destination: bool) -> Result<Address, ParseEndpointError> {
    // The port follows the last ':'; an IPv6 host keeps its own inside brackets.
    let Some((host, port)) = address.rsplit_once(':') else {
        return Err(ParseEndpointError::MissingPort {
            scheme: scheme.to_string(),
            address: address.to_string(),
        });
    };
    // A bracketed host must be IPv6, a bare one IPv4: bare IPv6 would make
    // "::1:14550" ambiguous to a reader even though rsplit decides it.
    let ip = match host.strip_prefix('[').and_then(|h| h.strip_suffix(']')) {
        Some(v6) => v6.parse::<Ipv6Addr>().ok().map(IpAddr::V6),
        None => host.parse::<Ipv4Addr>().ok().map(IpAddr::V4),
    };
    if ip.is_none() && !is_host_name(host) {
        return Err(ParseEndpointError::InvalidHost {
            scheme: scheme.to_string(),
            host: host.to_string(),
        });
    }
    // u16::from_str accepts a leading '+'; a port is digits only.
    let port = match port.bytes().all(|b| b.is_ascii_digit()) {
        true => port.parse::<u16>().ok(),
        false => None,
    }
    .ok_or_else(|| ParseEndpointError::InvalidPort {
        scheme: scheme.to_string(),
        port: port.to_string(),
    })?;
    if destination && port == 0 {
        return Err(ParseEndpointError::ZeroPort {
            scheme: scheme.to_string(),
        });
    }
    Ok(match ip {
        Some(ip) => Address::Ip(SocketAddr::new(ip, port)),
        None => Address::Name {
            host: host.to_string(),
            port,
        },
    })
}

/// A DNS name (RFC 1123): dot-separated labels of 1 to 63 letters, digits
/// and inner hyphens, 253 characters at most, not all digits and dots (a
/// malformed IPv4 address such as `1.2.3` is an error, not a name).
fn is_host_name(host: &str) -> bool {
    let label_ok = |l: &str| {
        (1..=63).contains(&l.len())
            && l.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'-')
            && !l.starts_with('-')
            && !l.ends_with('-')
    };
    let numeric = host.bytes().all(|b| b.is_ascii_digit() || b == b'.');
    (1..=253).contains(&host.len()) && !numeric && host.split('.').all(label_ok)
}

/// `PATH[:BAUD]`: the last part is the baud rate when it is all digits.
fn serial(rest: &str) -> Result<Endpoint, ParseEndpointError> {
    let (path, baud) = match rest.rsplit_once(':') {
        Some((_, "")) => return Err(ParseEndpointError::EmptyBaud),
        Some((path, baud)) if baud.bytes().all(|b| b.is_ascii_digit()) => (path, Some(baud)),
        _ => (rest, None),
    };
    if path.is_empty() {
        return Err(ParseEndpointError::MissingPath);
    }
    let baud = match baud {
        None => DEFAULT_BAUD,
        Some(b) => match b.parse::<u32>() {
            Ok(n) if n > 0 => n,
            _ => {
                return Err(ParseEndpointError::InvalidBaud {
                    baud: b.to_string(),
                })
            }
        },
    };
    Ok(Endpoint::Serial {
        path: path.to_string(),
        baud,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::format;

    fn parse(s: &str) -> Result<Endpoint, ParseEndpointError> {
        s.parse()
    }

    fn ip(a: [u8; 4], port: u16) -> Address {
        Address::Ip(SocketAddr::from((a, port)))
    }

    #[test]
    fn tcpout_is_the_tcp_client() {
        let e = parse("tcpout:127.0.0.1:5760").unwrap();
        assert_eq!(e, Endpoint::Tcp(ip([127, 0, 0, 1], 5760)));
        assert_eq!(e.to_string(), "tcp:127.0.0.1:5760");
        assert_eq!(
            parse("tcpout:127.0.0.1:0"),
            Err(ParseEndpointError::ZeroPort {
                scheme: "tcpout".into()
            })
        );
    }

    #[test]
    fn udpbcast_parses_and_needs_a_port() {
        let e = parse("udpbcast:255.255.255.255:14550").unwrap();
        assert_eq!(e, Endpoint::UdpBcast(ip([255, 255, 255, 255], 14550)));
        assert_eq!(parse(&e.to_string()).unwrap(), e);
        assert_eq!(
            parse("udpbcast:10.0.0.255:0"),
            Err(ParseEndpointError::ZeroPort {
                scheme: "udpbcast".into()
            })
        );
    }

    #[test]
    fn host_names_are_kept_for_open_and_bad_ones_refused() {
        for (s, host) in [
            ("udpout:localhost:14550", "localhost"),
            ("tcp:my-host.example.org:5760", "my-host.example.org"),
            ("udpin:vm:14550", "vm"),
        ] {
            let e = parse(s).unwrap();
            let (Endpoint::UdpOut(a) | Endpoint::Tcp(a) | Endpoint::UdpIn(a)) = &e else {
                panic!("{e:?}")
            };
            assert_eq!(
                a,
                &Address::Name {
                    host: host.into(),
                    port: a.port()
                }
            );
            assert_eq!(e.to_string(), s);
        }
        for bad in ["-x", "a..b", "a_b", "1.2.3", "300.1.1.1", "::1", "", "x y"] {
            assert_eq!(
                parse(&format!("udpout:{bad}:1")),
                Err(ParseEndpointError::InvalidHost {
                    scheme: "udpout".into(),
                    host: bad.into()
                }),
                "{bad}"
            );
        }
        let long = ["a"; 127].join(".");
        assert!(parse(&format!("tcp:{long}:1")).is_ok(), "253 characters");
        assert!(parse(&format!("tcp:{long}.b:1")).is_err(), "255 characters");
        assert!(
            parse(&format!("tcp:{}:1", "a".repeat(64))).is_err(),
            "label of 64"
        );
    }

    #[test]
    fn names_resolve_at_open_ipv4_first_and_failures_are_typed() {
        let a = Address::Name {
            host: "localhost".into(),
            port: 14550,
        };
        let got = a.resolve().unwrap();
        assert_eq!(got[0], SocketAddr::from(([127, 0, 0, 1], 14550)));
        // RFC 6761: `.invalid` never resolves.
        let bad = Address::Name {
            host: "no-such-host.invalid".into(),
            port: 1,
        };
        let err = bad.resolve().unwrap_err();
        assert!(
            matches!(&err, ResolveError::Lookup { host, port: 1, .. } if host == "no-such-host.invalid")
        );
        assert!(core::error::Error::source(&err).is_some());
        let io = io::Error::from(err);
        assert_eq!(io.kind(), io::ErrorKind::NotFound);
        assert!(io
            .get_ref()
            .unwrap()
            .downcast_ref::<ResolveError>()
            .is_some());
    }

    #[test]
    fn file_takes_the_rest_as_its_path() {
        assert_eq!(
            parse("file:/tmp/a:b.bin").unwrap(),
            Endpoint::File(PathBuf::from("/tmp/a:b.bin"))
        );
        assert_eq!(parse("file:x").unwrap().to_string(), "file:x");
        assert_eq!(parse("file:"), Err(ParseEndpointError::MissingFilePath));
    }

    #[test]
    fn errors_name_the_offending_part() {
        assert_eq!(
            parse("udpsomething:1.2.3.4:5"),
            Err(ParseEndpointError::UnknownScheme {
                scheme: "udpsomething".into()
            })
        );
        assert_eq!(
            parse("tcpout:localhost"),
            Err(ParseEndpointError::MissingPort {
                scheme: "tcpout".into(),
                address: "localhost".into()
            })
        );
        assert_eq!(
            parse("udpbcast:1.2.3.4:+5"),
            Err(ParseEndpointError::InvalidPort {
                scheme: "udpbcast".into(),
                port: "+5".into()
            })
        );
        let text = parse("nothing").unwrap_err().to_string();
        assert!(text.contains("udpbcast") && text.contains("file"), "{text}");
    }
}
