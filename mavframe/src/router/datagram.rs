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

    /// The address the socket is bound to.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.0.get_ref().local_addr()
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

    /// The address the socket is bound to.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.0.local_addr()
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

#[cfg(all(test, unix))]
mod tests {
    use super::*;

    /// A send that finds the buffer full is tried again every
    /// [`SEND_RETRY`] until it goes through (loopback never fills a UDP
    /// send buffer, so the full buffer is the closure's).
    #[tokio::test(start_paused = true)]
    async fn a_send_that_finds_the_buffer_full_is_tried_again() {
        let socket = Datagram::new(std::net::UdpSocket::bind("127.0.0.1:0").unwrap()).unwrap();
        let mut full = 3;
        let start = tokio::time::Instant::now();
        let sent = socket
            .retry(|_| match full {
                0 => Ok(7),
                _ => {
                    full -= 1;
                    Err(io::ErrorKind::WouldBlock.into())
                }
            })
            .await;
        assert_eq!(sent.unwrap(), 7);
        assert_eq!(start.elapsed(), SEND_RETRY * 3);
        // Any other error ends it at once.
        let refused = socket
            .retry(|_| Err(io::ErrorKind::ConnectionRefused.into()))
            .await;
        assert_eq!(
            refused.unwrap_err().kind(),
            io::ErrorKind::ConnectionRefused
        );
        assert_eq!(start.elapsed(), SEND_RETRY * 3);
    }
}
