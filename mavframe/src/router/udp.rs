//! UDP links (`udpin`, `udpout`, `udpbcast`): the socket, and the link's
//! receiver, a thread of its own blocked in the socket's receive, which has
//! the policy judge each datagram's frames as it comes and sends them on
//! from there: a frame costs the receive that wakes the thread and the
//! sends it goes out in, as a program that only forwards costs (waited on
//! by the runtime, a datagram cost a wait for readiness and a receive that
//! found nothing besides). The receiver leaves its wait, at most
//! [`HOUSEKEEPING`], for the link's state, and at once when the router is
//! gone ([`Datagram::stop_receiving`]). What is
//! sent on the link goes out at once, never waiting, from whichever task
//! or thread sends it; what could not (a full socket buffer, the pace) is
//! sent by the link's task.
//!
//! At low rates each datagram's routed frames go before the next receive;
//! when datagrams arrive faster than they are judged (the socket holds a
//! backlog), the receiver takes those waiting without blocking, up to
//! [`DATAGRAMS_PER_BATCH`], and their routed frames leave together.

use super::hub::{judge, lock, Hub, SEND_RETRY};
use super::task::{Alarm, Ended, LinkTask};
use super::{Policy, RouterEvent};
use crate::link::{Inbox, SigningFile};
use crate::message::MessageSet;
use crate::route::LinkId;
use std::boxed::Box;
use std::io;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex, Weak};
use std::time::{Duration, Instant};

/// How long the receiver waits for a datagram before it looks at its
/// link's state (the router gone, a new key, the signing state due).
pub(super) const HOUSEKEEPING: Duration = Duration::from_millis(200);

/// A datagram coming within this of the receiver's last round of judging
/// was waiting already: others may be, taken without blocking.
const BACKLOG_GAP: Duration = Duration::from_micros(20);

/// Datagrams the receiver takes without blocking, judged under one lock,
/// their routed frames sent together.
const DATAGRAMS_PER_BATCH: usize = 32;

/// A UDP socket: received from by its link's receiver, blocking (for
/// [`HOUSEKEEPING`] at most); sent on by anyone, without waiting.
pub(super) struct Datagram(std::net::UdpSocket);

impl Datagram {
    /// Takes `socket` (set blocking here, with [`HOUSEKEEPING`] as its
    /// read timeout).
    pub fn new(socket: std::net::UdpSocket) -> io::Result<Datagram> {
        socket.set_nonblocking(false)?;
        socket.set_read_timeout(Some(HOUSEKEEPING))?;
        Ok(Datagram(socket))
    }

    /// The address the socket is bound to.
    pub fn local_addr(&self) -> io::Result<SocketAddr> {
        self.0.local_addr()
    }

    /// The next datagram, into `buf`: waits for it, [`HOUSEKEEPING`] at
    /// most (then `WouldBlock`).
    #[cfg(unix)]
    fn recv_from(&self, buf: &mut [u8]) -> io::Result<(usize, SocketAddr)> {
        self.recv(buf, rustix::net::RecvFlags::empty())
    }

    /// (Elsewhere std's receive.)
    #[cfg(not(unix))]
    fn recv_from(&self, buf: &mut [u8]) -> io::Result<(usize, SocketAddr)> {
        self.0.recv_from(buf)
    }

    /// A receive with `flags`. (Not std's: a receive on a socket shut for
    /// reading returns no sender's address, which std asserts against.)
    #[cfg(unix)]
    fn recv(
        &self,
        buf: &mut [u8],
        flags: rustix::net::RecvFlags,
    ) -> io::Result<(usize, SocketAddr)> {
        let room = buf.len();
        match rustix::net::recvfrom(&self.0, buf, flags)? {
            (_, n, Some(from)) => match SocketAddr::try_from(from) {
                Ok(from) => Ok((n.min(room), from)),
                Err(_) => Err(io::ErrorKind::InvalidData.into()),
            },
            // No sender: the socket was shut for reading.
            (_, _, None) => Err(io::ErrorKind::NotConnected.into()),
        }
    }

    /// Ends the wait of the receiver blocked on the socket, and has every
    /// receive from now on return at once, without a datagram: the router
    /// is gone. (Elsewhere than on Linux, a socket that is not connected
    /// may only see it when the wait times out, [`HOUSEKEEPING`] later.)
    #[cfg(unix)]
    pub fn stop_receiving(&self) {
        // Linux wakes the receiver even where it answers that the socket
        // is not connected.
        let _ = rustix::net::shutdown(&self.0, rustix::net::Shutdown::Read);
    }

    /// (Elsewhere the receiver sees it when its wait times out.)
    #[cfg(not(unix))]
    pub fn stop_receiving(&self) {}

    /// The next datagram if the socket holds one now.
    #[cfg(unix)]
    fn recv_now(&self, buf: &mut [u8]) -> Option<io::Result<(usize, SocketAddr)>> {
        match self.recv(buf, rustix::net::RecvFlags::DONTWAIT) {
            Err(e) if e.kind() == io::ErrorKind::WouldBlock => None,
            other => Some(other),
        }
    }

    /// (Elsewhere each datagram is judged alone.)
    #[cfg(not(unix))]
    fn recv_now(&self, _: &mut [u8]) -> Option<io::Result<(usize, SocketAddr)>> {
        None
    }

    /// Sends `bytes` to `to` now, or finds the buffer full
    /// (`WouldBlock`).
    #[cfg(unix)]
    pub fn try_send_to(&self, bytes: &[u8], to: SocketAddr) -> io::Result<usize> {
        use rustix::net::{sendto, SendFlags};
        Ok(sendto(&self.0, bytes, SendFlags::DONTWAIT, &to)?)
    }

    /// Sends `bytes` to `to` (a blocking send: a full send buffer waits).
    #[cfg(not(unix))]
    pub fn try_send_to(&self, bytes: &[u8], to: SocketAddr) -> io::Result<usize> {
        self.0.send_to(bytes, to)
    }

    /// Sends `bytes` to the connected peer (`udpout`) now. A send that
    /// reports an earlier datagram's ICMP error (Linux does on connected
    /// sockets, once per error) sent nothing: tried once more, so a target
    /// that is not up yet costs no frame once it is.
    pub fn try_send(&self, bytes: &[u8]) -> io::Result<usize> {
        match self.send(bytes) {
            Err(e) if crate::conn::is_refused(&e) => self.send(bytes),
            other => other,
        }
    }

    #[cfg(unix)]
    fn send(&self, bytes: &[u8]) -> io::Result<usize> {
        use rustix::net::{send, SendFlags};
        Ok(send(&self.0, bytes, SendFlags::DONTWAIT)?)
    }

    #[cfg(not(unix))]
    fn send(&self, bytes: &[u8]) -> io::Result<usize> {
        self.0.send(bytes)
    }
}

/// A UDP link's receiver: its parser and signing, on a thread of its own
/// while the link is open; given back to the link's task when the router
/// is gone.
pub(super) struct Receiver<D: MessageSet, P> {
    /// The links' hub, held only while a batch is judged: a receiver never
    /// keeps a router alive.
    hub: Weak<Mutex<Hub<P>>>,
    link: LinkId,
    socket: Arc<Datagram>,
    listening: bool,
    pub(super) inbox: Inbox<D, Box<[u8]>>,
    pub(super) signing: SigningFile,
}

impl<D: MessageSet + 'static, P: Policy<D>> Receiver<D, P> {
    /// Receives and has the policy judge until the router is gone.
    fn run(mut self) -> Self {
        let mut judged_at = Instant::now();
        loop {
            let got = self.socket.recv_from(self.inbox.space());
            let backlog = judged_at.elapsed() < BACKLOG_GAP;
            let Some(hub) = self.hub.upgrade() else {
                return self;
            };
            match got {
                Ok((n, from)) => self.inbox.received(n, Some(from), true),
                // No datagram: the wait timed out, the router stopped the
                // receives ([`Datagram::stop_receiving`]), or the receive
                // failed (an ICMP error on some systems, which says nothing
                // about the next one).
                Err(_) => {
                    let mut hub = lock(&hub);
                    if hub.closed {
                        return self;
                    }
                    self.rekey(&mut hub);
                    self.save(&mut hub);
                    continue;
                }
            }
            if !self.judge(&hub, backlog) {
                return self;
            }
            judged_at = Instant::now();
        }
    }

    /// Has the policy judge the datagram received and, with a `backlog`,
    /// those the socket holds (up to [`DATAGRAMS_PER_BATCH`]); false once
    /// the router is gone. A datagram's bytes without a frame are parsed a
    /// chunk at a time, the lock let go in between.
    fn judge(&mut self, hub: &Mutex<Hub<P>>, backlog: bool) -> bool {
        loop {
            let mut hub = lock(hub);
            if hub.closed {
                return false;
            }
            self.rekey(&mut hub);
            let more = self.batch(&mut hub, backlog);
            self.save(&mut hub);
            if !more {
                return true;
            }
            drop(hub);
            std::thread::yield_now();
        }
    }

    /// One batch under the lock: true when a datagram's bytes are left.
    fn batch(&mut self, hub: &mut Hub<P>, backlog: bool) -> bool {
        let (link, key, listening) = (self.link, self.signing.key(), self.listening);
        let (policy, mut out) = hub.parts();
        let mut taken = 1;
        let more = loop {
            let refused = self.inbox.parser.stats().bad_signature;
            let more = judge(policy, &mut out, link, &mut self.inbox, key, false).more;
            let stats = self.inbox.parser.stats();
            let bad = listening && stats.bad_signature > refused;
            if let (Some(sender), Some(source), true) =
                (stats.bad_signature_sender, self.inbox.source, bad)
            {
                let event = RouterEvent::BadSignature {
                    link,
                    source,
                    sender,
                };
                policy.event(event, &mut out);
            }
            if more || !backlog || taken == DATAGRAMS_PER_BATCH {
                break more;
            }
            taken += 1;
            match self.socket.recv_now(self.inbox.space()) {
                Some(Ok((n, from))) => self.inbox.received(n, Some(from), true),
                Some(Err(_)) => continue,
                None => break false,
            }
        };
        out.set_parser_stats(link, *self.inbox.parser.stats());
        more
    }

    /// Takes the key the policy gave the link ([`Out::set_key`](super::Out::set_key)),
    /// if any: the parser verifies with it from now on.
    fn rekey(&mut self, hub: &mut Hub<P>) {
        if let Some(key) = hub.outs[usize::from(self.link)].rekey.take() {
            self.signing.set_key(key);
            self.inbox.parser = self.signing.parser();
        }
    }

    /// Saves the signing state if due, with the key's replay window.
    fn save(&mut self, hub: &mut Hub<P>) {
        if !self.signing.keeps_state() {
            return;
        }
        let Hub { outs, windows, .. } = hub;
        let key = self.signing.key();
        let verifier = windows.iter().find(|(k, _)| Some(*k) == key).map(|w| &w.1);
        let o = &mut outs[usize::from(self.link)];
        if !self.signing.save(&o.framer, verifier, false) {
            o.counters.state_save_errors = o.counters.state_save_errors.saturating_add(1);
        }
    }
}

impl<D: MessageSet + 'static, P: Policy<D>> LinkTask<D, P> {
    /// A UDP link: its receiver on a thread of its own (with the link's
    /// inbox and signing, given back when the router is gone), and here
    /// what the link's queues hold, sent when woken or when the pace lets
    /// it go.
    pub(super) async fn udp(
        &mut self,
        socket: Arc<Datagram>,
        inbox: &mut Inbox<D, Box<[u8]>>,
    ) -> Ended {
        let receiver = Receiver::<D, P> {
            hub: Arc::downgrade(&self.hub),
            link: self.id,
            socket,
            listening: self.config.is_listening(),
            inbox: core::mem::replace(inbox, self.inbox(0)),
            signing: core::mem::take(&mut self.signing),
        };
        let mut receiving = tokio::task::spawn_blocking(move || receiver.run());
        let mut alarm = Alarm::default();
        let wake = self.wake.clone();
        let woken = wake.notified();
        tokio::pin!(woken);
        loop {
            tokio::select! {
                biased;
                r = &mut receiving => {
                    let receiver = r.unwrap_or_else(|e| std::panic::resume_unwind(e.into_panic()));
                    *inbox = receiver.inbox;
                    self.signing = receiver.signing;
                    return self.send_the_rest().await;
                }
                () = &mut woken => woken.set(wake.notified()),
                () = alarm.fired() => {}
            }
            let mut hub = lock(&self.hub);
            let closed = hub.closed;
            alarm.set(hub.outs[usize::from(self.id)].send_queued(closed));
        }
    }

    /// The router is gone: what the link's queues hold goes, unpaced.
    async fn send_the_rest(&mut self) -> Ended {
        loop {
            {
                let mut hub = lock(&self.hub);
                let o = &mut hub.outs[usize::from(self.id)];
                o.send_queued(true);
                if o.queues.is_empty() {
                    return Ended::RouterGone;
                }
            }
            tokio::time::sleep(SEND_RETRY).await;
        }
    }
}

#[cfg(all(test, target_os = "linux"))]
mod tests {
    use super::*;

    /// A receiver blocked in the receive leaves it when the router stops
    /// the receives, told so (not by the wait's timeout, nor a panic), and
    /// the next blocking receive returns at once the same way.
    #[test]
    fn stopped_receives_end_the_wait_and_say_so() {
        let socket = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let socket = Arc::new(Datagram::new(socket).unwrap());
        let receiver = Arc::clone(&socket);
        let waiting = std::thread::spawn(move || {
            let mut buf = [0u8; 64];
            let first = receiver.recv_from(&mut buf).map_err(|e| e.kind());
            let next = receiver.recv_from(&mut buf).map_err(|e| e.kind());
            (first, next)
        });
        std::thread::sleep(HOUSEKEEPING / 4);
        socket.stop_receiving();
        let (first, next) = waiting.join().expect("no panic in the receive");
        assert_eq!(first, Err(io::ErrorKind::NotConnected));
        assert_eq!(next, Err(io::ErrorKind::NotConnected));
    }
}
