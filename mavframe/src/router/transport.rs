//! A link's transport, opened from its endpoint.

use super::hub::Way;
use super::udp::Datagram;
use super::LinkConfig;
use crate::conn::{AnyTransport, Endpoint};
use std::boxed::Box;
use std::io;
use std::net::SocketAddr;
use std::sync::Arc;
use tokio::io::{AsyncRead, AsyncWrite};
use tokio::net::{TcpListener, TcpStream};

/// A link's transport, open.
pub(super) enum Transport {
    Udp {
        socket: Arc<Datagram>,
        /// `udpout`'s target, or `udpbcast`'s broadcast address (where
        /// frames go while the link has no peer).
        to: Option<SocketAddr>,
    },
    Stream(Box<dyn AsyncStream>),
    Server(TcpListener),
}

/// An async byte stream (TCP client, serial port).
pub(super) trait AsyncStream: AsyncRead + AsyncWrite + Send + Unpin {
    /// The far end's address, for a TCP stream.
    fn peer(&self) -> Option<SocketAddr> {
        None
    }
}
impl AsyncStream for TcpStream {
    fn peer(&self) -> Option<SocketAddr> {
        self.peer_addr().ok()
    }
}
impl AsyncStream for tokio_serial::SerialStream {}

impl Transport {
    /// How the link's frames leave through it.
    pub(super) fn way(&self) -> Way {
        match self {
            Transport::Udp { socket, to } => Way::Udp {
                socket: socket.clone(),
                target: *to,
            },
            Transport::Stream(_) => Way::Stream,
            Transport::Server(_) => Way::Server {
                clients: std::vec::Vec::new(),
            },
        }
    }

    /// Opens `config`'s endpoint: resolved and opened as the blocking
    /// transports are ([`conn::open`](crate::conn::open): `udpout`
    /// connected to its target, `udpbcast` with `SO_BROADCAST`), on a
    /// blocking thread, then handed to tokio; refused when
    /// [`LinkConfig::loopback_only`] and it is not on a loopback address.
    pub(super) async fn open(config: &LinkConfig) -> io::Result<Transport> {
        let transport = Self::open_any(config).await?;
        if config.loopback_only {
            transport.check_loopback(&config.endpoint)?;
        }
        Ok(transport)
    }

    /// The address the transport talks to (`udpout`, TCP) or listens on.
    fn address(&self) -> io::Result<Option<SocketAddr>> {
        Ok(match self {
            Transport::Udp { to: Some(to), .. } => Some(*to),
            Transport::Udp { socket, .. } => Some(socket.local_addr()?),
            Transport::Server(listener) => Some(listener.local_addr()?),
            // A serial port, or a TCP stream (its peer, below).
            Transport::Stream(_) => None,
        })
    }

    /// Refuses a transport whose address is not loopback.
    fn check_loopback(&self, endpoint: &Endpoint) -> io::Result<()> {
        let address = match self {
            Transport::Stream(s) => s.peer(),
            other => other.address()?,
        };
        match address {
            Some(a) if !a.ip().is_loopback() => Err(io::Error::new(
                io::ErrorKind::PermissionDenied,
                std::format!("{endpoint} resolved to {a}, not a loopback address"),
            )),
            _ => Ok(()),
        }
    }

    async fn open_any(config: &LinkConfig) -> io::Result<Transport> {
        let endpoint = config.endpoint.clone();
        let opened = match &endpoint {
            Endpoint::File(_) => {
                return Err(io::Error::new(
                    io::ErrorKind::Unsupported,
                    "file: endpoints are not routed: a capture cannot take frames",
                ))
            }
            Endpoint::Serial { path, baud } => {
                use tokio_serial::{FlowControl, SerialPortBuilderExt};
                let flow = if config.flow_control {
                    FlowControl::Hardware
                } else {
                    FlowControl::None
                };
                let port = tokio_serial::new(path, *baud)
                    .flow_control(flow)
                    .open_native_async()?;
                return Ok(Transport::Stream(Box::new(port)));
            }
            // (tokio's listener: SO_REUSEADDR, as the system's is not.)
            Endpoint::TcpIn(addr) => {
                let addr = addr.clone();
                let addrs = blocking(move || Ok(addr.resolve()?)).await?;
                return Ok(Transport::Server(
                    TcpListener::bind(addrs.as_slice()).await?,
                ));
            }
            _ => blocking(move || crate::conn::open(&endpoint)).await?,
        };
        let udp = |socket: &std::net::UdpSocket, to| {
            let socket = Arc::new(Datagram::new(socket.try_clone()?)?);
            io::Result::Ok(Transport::Udp { socket, to })
        };
        match opened {
            AnyTransport::UdpIn(t) => udp(t.get_ref(), None),
            AnyTransport::UdpOut(t) => udp(t.get_ref(), Some(t.target())),
            AnyTransport::UdpBcast(t) => udp(t.get_ref(), Some(t.target())),
            AnyTransport::Tcp(t) => {
                let stream = t.get_ref().try_clone()?;
                stream.set_nonblocking(true)?;
                let stream = TcpStream::from_std(stream)?;
                if config.bound_unsent {
                    bound_unsent(&stream);
                }
                Ok(Transport::Stream(Box::new(stream)))
            }
            _ => Err(io::ErrorKind::Unsupported.into()),
        }
    }
}

/// Runs `f` (a name lookup, a connect) on tokio's blocking threads.
pub(super) async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> io::Result<T> + Send + 'static,
) -> io::Result<T> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(io::Error::other)?
}

/// Bytes a TCP link with [`LinkConfig::bound_unsent`] lets the kernel hold
/// unsent (`TCP_NOTSENT_LOWAT`, Linux and Android; elsewhere the system
/// decides). Frames routed through a link go after its owner's own in the
/// link's queues, but the kernel's send buffer grows to
/// megabytes by itself: on a link slower than a flood routed to it, the
/// owner's frames then waited seconds behind the flood's. This bounds only
/// what is not sent yet, not what is in flight. (What the far end has
/// received and not yet passed on, a modem's or a relay's buffer, is out of
/// the sender's reach.)
#[cfg(any(target_os = "linux", target_os = "android"))]
pub(super) const TCP_UNSENT_MAX: u32 = 8 * 1024;

/// See [`TCP_UNSENT_MAX`]. (Best effort: without it the link works as
/// before, its owner's frames first in its queues.)
pub(super) fn bound_unsent(stream: &TcpStream) {
    #[cfg(any(target_os = "linux", target_os = "android"))]
    let _ = socket2::SockRef::from(stream).set_tcp_notsent_lowat(TCP_UNSENT_MAX);
    #[cfg(not(any(target_os = "linux", target_os = "android")))]
    let _ = stream;
}
