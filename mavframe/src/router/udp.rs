//! UDP links (`udpin`, `udpout`, `udpbcast`): the socket, and the link's
//! task, which receives datagrams and has the policy judge their frames.
//! What is sent on the link is written by whoever sends it (the task that
//! judged a frame routed here, the owner), without waking this task,
//! unless the link's queue holds something already; the task then sends
//! the queue.
//!
//! The socket is waited on for what it receives only: tokio's
//! `UdpSocket` waits on a socket for both directions, and on Linux every
//! datagram sent signals "writable" again once the kernel frees its
//! buffer: the runtime woke once more per frame routed, to find nothing to
//! do. A UDP send almost never finds the send buffer full (the kernel
//! drops at the receiver rather than block the sender); when it does, what
//! did not go is queued and the link's task tries again
//! [`SEND_RETRY`](super::hub::SEND_RETRY) later.

use super::hub::lock;
#[cfg(doc)]
use super::hub::Way;
use super::task::{Alarm, Ended, LinkTask, SaveTick};
use super::{Policy, RouterEvent};
use crate::link::Inbox;
use crate::message::MessageSet;
use std::boxed::Box;
use std::io;
use std::net::SocketAddr;
use std::sync::Arc;

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

    fn socket(&self) -> &std::net::UdpSocket {
        self.0.get_ref()
    }

    /// The address the socket is bound to.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.socket().local_addr()
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

    fn socket(&self) -> &tokio::net::UdpSocket {
        &self.0
    }

    /// The address the socket is bound to.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.0.local_addr()
    }
}

impl Datagram {
    /// Sends `bytes` to `to` now, or finds the buffer full
    /// (`WouldBlock`).
    pub fn try_send_to(&self, bytes: &[u8], to: SocketAddr) -> io::Result<usize> {
        self.socket().send_to(bytes, to)
    }

    /// Sends `bytes` to the connected peer (`udpout`) now. A send that
    /// reports an earlier datagram's ICMP error (Linux does on connected
    /// sockets, once per error) sent nothing: tried once more, so a target
    /// that is not up yet costs no frame once it is.
    pub fn try_send(&self, bytes: &[u8]) -> io::Result<usize> {
        match self.socket().send(bytes) {
            Err(e) if crate::conn::is_refused(&e) => self.socket().send(bytes),
            other => other,
        }
    }
}

impl<D: MessageSet + 'static, P: Policy<D>> LinkTask<D, P> {
    /// A UDP link's receive side, and its queue's: what is sent on the
    /// link goes as [`Way::Udp`] says.
    pub(super) async fn udp(
        &mut self,
        socket: Arc<Datagram>,
        inbox: &mut Inbox<D, Box<[u8]>>,
    ) -> Ended {
        let listening = self.config.is_listening();
        let mut tick = SaveTick::new(self.signing.keeps_state());
        let mut alarm = Alarm::default();
        loop {
            let mut send = false;
            tokio::select! {
                () = tick.next() => self.save(false),
                // A failed receive (an ICMP error on some systems) says
                // nothing about the next one: it is skipped.
                r = socket.recv_from(inbox.space()) => if let Ok((n, from)) = r {
                    inbox.received(n, Some(from), true);
                    let refused = inbox.parser.stats().bad_signature;
                    send = self.deliver(inbox, false).await.is_err();
                    let stats = inbox.parser.stats();
                    let bad = listening && stats.bad_signature > refused;
                    if let (Some(sender), true) = (stats.bad_signature_sender, bad) {
                        self.event(RouterEvent::BadSignature { link: self.id, source: from, sender });
                    }
                    self.save(false);
                },
                () = self.wake.notified() => {
                    self.rekeyed(Some(inbox));
                    send = true;
                }
                () = alarm.fired() => send = true,
            }
            if send {
                let mut hub = lock(&self.hub);
                let closed = hub.closed;
                let o = &mut hub.outs[usize::from(self.id)];
                let wait = o.send_queued(closed);
                if closed && o.queues.is_empty() {
                    return Ended::RouterGone;
                }
                alarm.set(wait);
            }
        }
    }
}
