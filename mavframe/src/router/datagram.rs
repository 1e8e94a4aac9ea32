//! A UDP link's socket, as its task drives it: waited on for what it
//! receives only.
//!
//! tokio's `UdpSocket` waits on a socket for both directions, and on Linux
//! every datagram sent signals "writable" again once the kernel frees its
//! buffer: the runtime woke once more per frame routed, to find nothing to
//! do. A UDP send almost never finds the send buffer full (the kernel
//! drops at the receiver rather than block the sender); when it does, the
//! task waits [`SEND_RETRY`] and tries again.

use std::io;
use std::net::SocketAddr;

/// How long a send that found the socket's buffer full waits before it
/// tries again.
#[cfg(unix)]
const SEND_RETRY: std::time::Duration = std::time::Duration::from_millis(1);

/// A non-blocking UDP socket, waited on for readability.
#[cfg(unix)]
pub(super) struct Datagram(tokio::io::unix::AsyncFd<std::net::UdpSocket>);

#[cfg(unix)]
impl Datagram {
    /// Takes `socket` (set non-blocking here) into the runtime.
    // `with_interest` is deprecated for types whose `as_raw_fd` could
    // change or close under it (its replacement is `unsafe`, which this
    // crate forbids); a `std::net::UdpSocket` owns its descriptor for its
    // whole life, and the `AsyncFd` owns the socket.
    #[allow(deprecated)]
    pub fn new(socket: std::net::UdpSocket) -> io::Result<Datagram> {
        use tokio::io::{unix::AsyncFd, Interest};
        socket.set_nonblocking(true)?;
        Ok(Datagram(AsyncFd::with_interest(
            socket,
            Interest::READABLE,
        )?))
    }

    /// The next datagram, into `buf`.
    pub async fn recv_from(&self, buf: &mut [u8]) -> io::Result<(usize, SocketAddr)> {
        let readable = tokio::io::Interest::READABLE;
        self.0.async_io(readable, |s| s.recv_from(buf)).await
    }

    /// Sends `bytes` to `to`.
    pub async fn send_to(&self, bytes: &[u8], to: SocketAddr) -> io::Result<usize> {
        self.retry(|s| s.send_to(bytes, to)).await
    }

    /// Sends `bytes` to the connected peer.
    pub async fn send(&self, bytes: &[u8]) -> io::Result<usize> {
        self.retry(|s| s.send(bytes)).await
    }

    /// `send` until it does not find the send buffer full.
    async fn retry(
        &self,
        mut send: impl FnMut(&std::net::UdpSocket) -> io::Result<usize>,
    ) -> io::Result<usize> {
        loop {
            match send(self.0.get_ref()) {
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    tokio::time::sleep(SEND_RETRY).await;
                }
                other => return other,
            }
        }
    }
}

/// Elsewhere, tokio's socket (waited on both ways).
#[cfg(not(unix))]
pub(super) struct Datagram(tokio::net::UdpSocket);

#[cfg(not(unix))]
impl Datagram {
    pub fn new(socket: std::net::UdpSocket) -> io::Result<Datagram> {
        socket.set_nonblocking(true)?;
        Ok(Datagram(tokio::net::UdpSocket::from_std(socket)?))
    }

    pub async fn recv_from(&self, buf: &mut [u8]) -> io::Result<(usize, SocketAddr)> {
        self.0.recv_from(buf).await
    }

    pub async fn send_to(&self, bytes: &[u8], to: SocketAddr) -> io::Result<usize> {
        self.0.send_to(bytes, to).await
    }

    pub async fn send(&self, bytes: &[u8]) -> io::Result<usize> {
        self.0.send(bytes).await
    }
}
