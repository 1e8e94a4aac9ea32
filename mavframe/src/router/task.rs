//! A link's task: it owns the transport and the parser, has the policy
//! judge what it receives (in this task: [`Hub::judge`]), sends what waits
//! in the link's queues, and opens the link again when it fails.

use super::hub::{lock, Batch, Hub, Way};
use super::queues::Next;
use super::transport::{AsyncStream, Transport};
use super::{
    LinkConfig, Policy, RouterEvent, DATAGRAM_ROOM, PARSE_CHUNK, REOPEN_INTERVAL, SENDS_PER_TURN,
};
use crate::link::{Inbox, SigningFile};
use crate::message::MessageSet;
use crate::route::LinkId;
use crate::signing::state::SAVE_INTERVAL;
use core::marker::PhantomData;
use core::pin::Pin;
use std::boxed::Box;
use std::io;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use std::vec;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::sync::Notify;
use tokio::time::{Instant, Sleep};

/// One link's task.
pub(super) struct LinkTask<D, P> {
    pub(super) id: LinkId,
    pub(super) config: LinkConfig,
    pub(super) hub: Arc<Mutex<Hub<P>>>,
    pub(super) signing: SigningFile,
    /// Wakes the task: something is queued for it, a new key, the
    /// router gone.
    pub(super) wake: Arc<Notify>,
    /// `tcpin`: clients accepted so far (each client's order).
    pub(super) clients_accepted: u64,
    pub(super) _dialect: PhantomData<fn() -> D>,
}

/// The router is gone: the task ends (after what is queued).
pub(super) struct Gone;

/// How a link's transport ended.
pub(super) enum Ended {
    /// The router was dropped: the task ends.
    RouterGone,
    /// The transport failed: reopen it.
    Failed(io::Error),
}

impl<D: MessageSet + 'static, P: Policy<D>> LinkTask<D, P> {
    /// An inbox with the link's key and `room` bytes to receive into.
    pub(super) fn inbox(&self, room: usize) -> Inbox<D, Box<[u8]>> {
        let mut inbox = Inbox::new(self.signing.parser(), vec![0u8; room].into_boxed_slice());
        inbox.set_chunk(PARSE_CHUNK);
        inbox
    }

    /// Runs the link until the router is gone, reopening it when it
    /// fails; `first` is its opening in [`Router::add`](super::Router::add).
    pub(super) async fn run(mut self, first: io::Result<Transport>) {
        let mut transport = match first {
            Ok(t) => Some(t),
            Err(error) => {
                self.event(RouterEvent::LinkDown {
                    link: self.id,
                    error,
                });
                if self.wait_reopen().await.is_err() {
                    return;
                }
                None
            }
        };
        let mut inbox = self.inbox(DATAGRAM_ROOM);
        loop {
            let t = match transport.take() {
                Some(t) => t,
                None => match Transport::open(&self.config).await {
                    Ok(t) => {
                        self.opened(t.way());
                        t
                    }
                    Err(_) => {
                        if self.wait_reopen().await.is_err() {
                            return;
                        }
                        continue;
                    }
                },
            };
            let ended = match t {
                Transport::Udp { socket, .. } => self.udp(socket, &mut inbox).await,
                Transport::Stream(stream) => self.stream(stream, &mut inbox).await,
                Transport::Server(listener) => self.server(listener).await,
            };
            self.save(true);
            let Ended::Failed(error) = ended else {
                lock(&self.hub).outs[usize::from(self.id)].set_way(Way::Down);
                return;
            };
            self.down(error);
            inbox = self.inbox(DATAGRAM_ROOM);
            if self.wait_reopen().await.is_err() {
                return;
            }
        }
    }

    /// The link is open again, as `way`: the policy is told.
    fn opened(&mut self, way: Way) {
        let mut hub = lock(&self.hub);
        hub.outs[usize::from(self.id)].set_way(way);
        let up = RouterEvent::LinkUp { link: self.id };
        hub.with(|policy, out| policy.event(up, out));
    }

    /// The transport failed: what was queued is dropped, the policy told,
    /// and signing goes on from where the transport was.
    fn down(&mut self, error: io::Error) {
        let mut hub = lock(&self.hub);
        hub.outs[usize::from(self.id)].set_way(Way::Down);
        let down = RouterEvent::LinkDown {
            link: self.id,
            error,
        };
        hub.with(|policy, out| policy.event(down, out));
        let Hub { outs, windows, .. } = &mut *hub;
        let key = self.signing.key();
        let verifier = windows.iter().find(|(k, _)| Some(*k) == key).map(|w| &w.1);
        self.signing
            .go_on_from(&outs[usize::from(self.id)].framer, verifier);
    }

    /// Tells the policy `event`.
    pub(super) fn event(&self, event: RouterEvent) {
        lock(&self.hub).with(|policy, out| policy.event(event, out));
    }

    /// Waits [`REOPEN_INTERVAL`] (a new key taken meanwhile); `Err` when
    /// the router is gone.
    async fn wait_reopen(&mut self) -> Result<(), Gone> {
        let until = Instant::now() + REOPEN_INTERVAL;
        loop {
            tokio::select! {
                _ = tokio::time::sleep_until(until) => return Ok(()),
                () = self.wake.notified() => {
                    if lock(&self.hub).closed {
                        return Err(Gone);
                    }
                    self.rekeyed(None);
                }
            }
        }
    }

    /// Takes the key the policy gave the link ([`Out::set_key`](super::Out::set_key)),
    /// if any: the parser verifies with it from now on. True when it did.
    pub(super) fn rekeyed(&mut self, inbox: Option<&mut Inbox<D, Box<[u8]>>>) -> bool {
        let Some(key) = lock(&self.hub).outs[usize::from(self.id)].rekey.take() else {
            return false;
        };
        self.signing.set_key(key);
        if let Some(inbox) = inbox {
            inbox.parser = self.signing.parser();
        }
        true
    }

    /// Has the policy judge every frame `inbox` holds (at the end of a
    /// stream, `eof`, those the held bytes still make), a chunk of bytes
    /// without a frame at a time, yielding in between, so one large
    /// datagram never holds the runtime (and the owner's timers) for long.
    pub(super) async fn deliver(
        &mut self,
        inbox: &mut Inbox<D, Box<[u8]>>,
        eof: bool,
    ) -> Result<Batch, Gone> {
        loop {
            let batch = {
                let mut hub = lock(&self.hub);
                if hub.closed {
                    return Err(Gone);
                }
                let batch = hub.judge(self.id, inbox, self.signing.key(), eof);
                hub.outs[usize::from(self.id)].counters.parser = *inbox.parser.stats();
                batch
            };
            if !batch.more {
                return Ok(batch);
            }
            tokio::task::yield_now().await;
        }
    }

    /// Saves the signing state if due, or now as at exit (`last`), with
    /// the key's replay window; failures are counted.
    pub(super) fn save(&mut self, last: bool) {
        if !self.signing.keeps_state() {
            return;
        }
        let mut hub = lock(&self.hub);
        let Hub { outs, windows, .. } = &mut *hub;
        let key = self.signing.key();
        let verifier = windows.iter().find(|(k, _)| Some(*k) == key).map(|w| &w.1);
        let o = &mut outs[usize::from(self.id)];
        if !self.signing.save(&o.framer, verifier, last) {
            o.counters.state_save_errors = o.counters.state_save_errors.saturating_add(1);
        }
    }

    /// A byte stream (TCP client, serial port): what it reads judged, what
    /// the link's queues hold written.
    async fn stream(
        &mut self,
        mut stream: Box<dyn AsyncStream>,
        inbox: &mut Inbox<D, Box<[u8]>>,
    ) -> Ended {
        let mut tick = SaveTick::new(self.signing.keeps_state());
        let mut alarm = Alarm::default();
        loop {
            let mut send = false;
            tokio::select! {
                () = tick.next() => self.save(false),
                r = stream.read(inbox.space()) => match r {
                    Ok(0) => {
                        let _ = self.deliver(inbox, true).await;
                        return Ended::Failed(io::Error::new(io::ErrorKind::UnexpectedEof, "closed by the peer"));
                    }
                    Ok(n) => {
                        inbox.received(n, None, false);
                        send = self.deliver(inbox, false).await.is_err();
                        self.save(false);
                    }
                    Err(e) => return Ended::Failed(e),
                },
                () = self.wake.notified() => {
                    self.rekeyed(Some(inbox));
                    send = true;
                }
                () = alarm.fired() => send = true,
            }
            if send {
                match self.write_queued(&mut stream).await {
                    Ok(wait) => alarm.set(wait),
                    Err(ended) => return ended,
                }
            }
        }
    }

    /// Writes what the link's queues hold, the owner's first, routed
    /// frames as the pace lets them go: `Ok(Some(wait))` when the rest
    /// waits that long for the pace.
    async fn write_queued(
        &mut self,
        stream: &mut Box<dyn AsyncStream>,
    ) -> Result<Option<Duration>, Ended> {
        for _ in 0..SENDS_PER_TURN {
            let (next, closed) = {
                let mut hub = lock(&self.hub);
                let closed = hub.closed;
                let o = &mut hub.outs[usize::from(self.id)];
                (o.queues.next(Instant::now(), closed), closed)
            };
            let packet = match next {
                Next::Send(_, packet) => packet,
                Next::Wait(wait) => return Ok(Some(wait)),
                Next::Idle if closed => return Err(Ended::RouterGone),
                Next::Idle => return Ok(None),
            };
            let written = stream.write_all(&packet.bytes).await;
            let mut hub = lock(&self.hub);
            let o = &mut hub.outs[usize::from(self.id)];
            match written {
                Ok(()) => o.count_out(packet.frames),
                Err(e) => {
                    o.count_send_error();
                    return Err(Ended::Failed(e));
                }
            }
        }
        self.wake.notify_one();
        Ok(None)
    }
}

/// A timer a task's loop waits on while it is set: one a task, reset, not
/// one made per turn.
#[derive(Default)]
pub(super) struct Alarm(Option<Pin<Box<Sleep>>>, bool);

impl Alarm {
    /// Fires `after` from now (`None`: never).
    pub(super) fn set(&mut self, after: Option<Duration>) {
        let Some(after) = after else {
            self.1 = false;
            return;
        };
        let at = Instant::now() + after;
        match &mut self.0 {
            Some(sleep) => sleep.as_mut().reset(at),
            None => self.0 = Some(Box::pin(tokio::time::sleep_until(at))),
        }
        self.1 = true;
    }

    /// Waits until it fires, then it is unset. Cancel-safe.
    pub(super) async fn fired(&mut self) {
        match (&mut self.0, self.1) {
            (Some(sleep), true) => {
                sleep.as_mut().await;
                self.1 = false;
            }
            _ => std::future::pending().await,
        }
    }
}

/// The tick that saves a link's signing state while the link is quiet:
/// a save is otherwise asked for after each batch of frames received, so
/// a link that fell silent right after accepting frames kept them
/// unsaved, and a crash then let them be replayed into the restarted
/// program. One timer a link, reset as it fires: none made per frame.
pub(super) struct SaveTick(Option<Pin<Box<Sleep>>>);

impl SaveTick {
    /// Every [`SAVE_INTERVAL`] for a link that `keeps` a state file;
    /// never for one that does not.
    pub(super) fn new(keeps: bool) -> SaveTick {
        SaveTick(keeps.then(|| Box::pin(tokio::time::sleep(SAVE_INTERVAL))))
    }

    /// Waits for the next tick. Cancel-safe (a `select!` branch): the
    /// timer lives in `self`.
    pub(super) async fn next(&mut self) {
        match &mut self.0 {
            Some(sleep) => {
                sleep.as_mut().await;
                let next = Instant::now() + SAVE_INTERVAL;
                sleep.as_mut().reset(next);
            }
            None => std::future::pending().await,
        }
    }
}
