//! Connection strings in MAVProxy's style, parsed into [`Endpoint`].

use core::fmt;
use core::str::FromStr;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr};
use std::string::{String, ToString};

/// Baud rate of a `serial:` string without one (MAVProxy's default).
pub const DEFAULT_BAUD: u32 = 57_600;

/// Where a connection goes: the parsed form of a connection string
/// (`"udpin:0.0.0.0:14550".parse()`), displayed back as one.
///
/// | string | meaning |
/// |---|---|
/// | `udpin:IP:PORT` | bind and listen; replies go to the last peer that sent a datagram |
/// | `udp:IP:PORT` | alias of `udpin` (MAVProxy's `udp:` listens too); displayed as `udpin:` |
/// | `udpout:IP:PORT` | send to `IP:PORT` from an ephemeral port; replies are received |
/// | `tcp:IP:PORT` | TCP client |
/// | `tcpin:IP:PORT` | TCP server: accepts clients, sends to all, receives from any |
/// | `serial:PATH[:BAUD]` | serial device, `BAUD` defaulting to [`DEFAULT_BAUD`] |
///
/// Addresses are IP literals: IPv4 as `127.0.0.1`, IPv6 in brackets as
/// `[::1]`. Host names are refused rather than resolved, so parsing never
/// touches the network and an `Endpoint` always names one address.
/// Port 0 is accepted where we bind (`udpin`, `tcpin`: the system picks a
/// free port) and refused where we send to (`udpout`, `tcp`).
///
/// Serial paths may contain `:` (Linux device paths normally do not): the
/// last `:`-separated part is the baud rate when it is non-empty and all
/// ASCII digits, otherwise it belongs to the path; a trailing `:` with
/// nothing after it is an error rather than part of the path. `Display`
/// always writes the baud rate, so a displayed endpoint parses back to
/// itself whatever its path.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub enum Endpoint {
    /// `udpin:` (or `udp:`): bind to this address and listen.
    UdpIn(SocketAddr),
    /// `udpout:`: send to this address from an ephemeral local port.
    UdpOut(SocketAddr),
    /// `tcp:`: connect to this server.
    Tcp(SocketAddr),
    /// `tcpin:`: listen on this address and serve every client that connects.
    TcpIn(SocketAddr),
    /// `serial:`: a serial device.
    Serial {
        /// Device path, e.g. `/dev/serial0` or `COM3`.
        path: String,
        /// Baud rate (never 0 when parsed).
        baud: u32,
    },
}

impl Endpoint {
    /// The canonical scheme, as [`Display`](fmt::Display) writes it
    /// (`udpin` for both `udpin:` and `udp:`).
    pub fn scheme(&self) -> &'static str {
        match self {
            Endpoint::UdpIn(_) => "udpin",
            Endpoint::UdpOut(_) => "udpout",
            Endpoint::Tcp(_) => "tcp",
            Endpoint::TcpIn(_) => "tcpin",
            Endpoint::Serial { .. } => "serial",
        }
    }
}

impl fmt::Display for Endpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Endpoint::UdpIn(a) | Endpoint::UdpOut(a) | Endpoint::Tcp(a) | Endpoint::TcpIn(a) => {
                // SocketAddr writes IPv6 in brackets, as we parse it.
                write!(f, "{}:{a}", self.scheme())
            }
            Endpoint::Serial { path, baud } => write!(f, "serial:{path}:{baud}"),
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
    /// The host part is not an IP literal.
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
    /// Port 0 where a destination port is needed (`udpout`, `tcp`).
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
}

const SCHEMES: &str = "udpin, udpout, udp, tcp, tcpin, serial";

/// An address to show in messages, fitting the scheme's role.
fn example(scheme: &str) -> &'static str {
    match scheme {
        "udpout" => "127.0.0.1:14550",
        "tcp" => "127.0.0.1:5760",
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
                "{scheme}: address `{address}` has no port: expected IP:PORT, e.g. {}",
                example(scheme)
            ),
            InvalidHost { scheme, host } => write!(
                f,
                "{scheme}: host `{host}` is not an IP address: expected IPv4 such as \
                 127.0.0.1 or IPv6 in brackets such as [::1] (host names are not resolved)"
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
        }
    }
}

impl std::error::Error for ParseEndpointError {}

impl FromStr for Endpoint {
    type Err = ParseEndpointError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let Some((scheme, rest)) = s.split_once(':') else {
            return Err(ParseEndpointError::MissingScheme {
                input: s.to_string(),
            });
        };
        match scheme {
            "udpin" | "udp" => Ok(Endpoint::UdpIn(socket_addr(scheme, rest, false)?)),
            "udpout" => Ok(Endpoint::UdpOut(socket_addr(scheme, rest, true)?)),
            "tcp" => Ok(Endpoint::Tcp(socket_addr(scheme, rest, true)?)),
            "tcpin" => Ok(Endpoint::TcpIn(socket_addr(scheme, rest, false)?)),
            "serial" => serial(rest),
            _ => Err(ParseEndpointError::UnknownScheme {
                scheme: scheme.to_string(),
            }),
        }
    }
}

/// `IP:PORT`, IPv6 in brackets; `destination` refuses port 0.
fn socket_addr(
    scheme: &str,
    address: &str,
    destination: bool,
) -> Result<SocketAddr, ParseEndpointError> {
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
    let Some(ip) = ip else {
        return Err(ParseEndpointError::InvalidHost {
            scheme: scheme.to_string(),
            host: host.to_string(),
        });
    };
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
    Ok(SocketAddr::new(ip, port))
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
