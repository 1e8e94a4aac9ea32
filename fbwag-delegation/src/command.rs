//! The MAVLink command protocol, client side, sans-IO: send COMMAND_LONG or
//! COMMAND_INT to a component, match its COMMAND_ACK, resend on silence,
//! give up after a bounded number of tries; and the message-interval
//! requests a companion makes of its FC.
//!
//! The rules are mavlink.io's ("Command Protocol"): a command is resent
//! after a timeout with `confirmation` increased (COMMAND_LONG only); a
//! COMMAND_ACK from the target with the same command id ends it, except
//! `MAV_RESULT_IN_PROGRESS`, which keeps it open (and restarts its timer,
//! without resending); only one command of a given id may be in flight to
//! one target at a time.
//!
//! ```
//! use fbwag_delegation::command::{CommandClient, CommandOutput, Outcome, Request};
//! use fbwag_delegation::{Moment, Peer};
//! use fbwag_dialect::dialects::common::{CommandAck, MavCmd, MavResult};
//! use fbwag_dialect::Message;
//!
//! let fc = Peer::new(1, 1);
//! let mut client = CommandClient::<4>::new(Peer::new(1, 191));
//! // Ask the FC for ATTITUDE (id 30) at 50 Hz.
//! let id = client.send(Moment::ZERO, Request::message_interval(fc, 30, Some(20_000)))?;
//! let Some(CommandOutput::Transmit(Message::CommandLong(cmd))) = client.poll_output() else {
//!     panic!()
//! };
//! assert_eq!(cmd.command, MavCmd::SET_MESSAGE_INTERVAL);
//! // The FC accepts.
//! let ack = CommandAck {
//!     command: MavCmd::SET_MESSAGE_INTERVAL,
//!     result: MavResult::ACCEPTED,
//!     target_system: 1,
//!     target_component: 191,
//!     ..Default::default()
//! };
//! client.handle_ack(Moment::from_millis(30), fc, &ack);
//! assert_eq!(
//!     client.poll_output(),
//!     Some(CommandOutput::Finished { id, outcome: Outcome::Result(MavResult::ACCEPTED) })
//! );
//! # Ok::<(), fbwag_delegation::command::Busy>(())
//! ```

use crate::outbox::Outbox;
use crate::{Moment, Peer};
use core::fmt;
use core::time::Duration;
use fbwag_dialect::dialects::common::{CommandAck, CommandInt, CommandLong, MavCmd, MavResult};
use fbwag_dialect::{Frame, Message, MessageView};

/// A command to send.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// COMMAND_LONG (its `target_*` fields say where it goes).
    Long(CommandLong),
    /// COMMAND_INT (positions as integers; never resent with a new
    /// confirmation: the message has none).
    Int(CommandInt),
}

impl Request {
    /// MAV_CMD_SET_MESSAGE_INTERVAL: ask `target` to send message `msg_id`
    /// every `interval_us` microseconds (`None`: stop sending it).
    pub fn message_interval(target: Peer, msg_id: u32, interval_us: Option<u32>) -> Request {
        Request::Long(CommandLong {
            target_system: target.sysid,
            target_component: target.compid,
            command: MavCmd::SET_MESSAGE_INTERVAL,
            param1: msg_id as f32,
            param2: interval_us.map_or(-1.0, |us| us as f32),
            ..Default::default()
        })
    }

    /// MAV_CMD_REQUEST_MESSAGE: ask `target` to send message `msg_id` once.
    pub fn request_message(target: Peer, msg_id: u32) -> Request {
        Request::Long(CommandLong {
            target_system: target.sysid,
            target_component: target.compid,
            command: MavCmd::REQUEST_MESSAGE,
            param1: msg_id as f32,
            ..Default::default()
        })
    }

    /// The command id.
    pub fn command(&self) -> MavCmd {
        match self {
            Request::Long(c) => c.command,
            Request::Int(c) => c.command,
        }
    }

    /// The addressee.
    pub fn target(&self) -> Peer {
        match self {
            Request::Long(c) => Peer::new(c.target_system, c.target_component),
            Request::Int(c) => Peer::new(c.target_system, c.target_component),
        }
    }

    fn to_message(self, tries: u8) -> Message {
        match self {
            Request::Long(mut c) => {
                c.confirmation = tries;
                Message::CommandLong(c)
            }
            Request::Int(c) => Message::CommandInt(c),
        }
    }
}

/// How a command ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// The target answered (anything but IN_PROGRESS).
    Result(MavResult),
    /// No final answer after every try.
    TimedOut,
}

/// What the client must do or report.
#[allow(clippy::large_enum_variant)] // no_std: messages are carried by value
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CommandOutput {
    /// Send this message.
    Transmit(Message),
    /// The target reported progress (0–100, or 255 when unknown).
    Progress {
        /// The command.
        id: CommandId,
        /// COMMAND_ACK's `progress`.
        progress: u8,
    },
    /// The command ended.
    Finished {
        /// The command.
        id: CommandId,
        /// How.
        outcome: Outcome,
    },
}

/// A command sent by a [`CommandClient`], to match its outcome.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct CommandId(u32);

/// A command could not be sent now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Busy {
    /// A command with this id is already in flight to this target (the
    /// protocol allows one).
    SameCommandInFlight,
    /// Every slot of the client is taken.
    Full,
}

impl fmt::Display for Busy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Busy::SameCommandInFlight => "the same command is already in flight to this target",
            Busy::Full => "too many commands in flight",
        })
    }
}

impl core::error::Error for Busy {}

/// Timing of the command protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CommandConfig {
    /// Wait for an answer this long before resending (mavlink.io suggests
    /// 1.5 s for commands over a telemetry link).
    pub timeout: Duration,
    /// Sends in all, the first included.
    pub tries: u8,
}

impl Default for CommandConfig {
    fn default() -> Self {
        CommandConfig {
            timeout: Duration::from_millis(1500),
            tries: 3,
        }
    }
}

#[derive(Debug, Clone, Copy)]
struct Pending {
    id: CommandId,
    request: Request,
    sent: u8,
    deadline: Moment,
}

/// The client side of the command protocol for one sender (`own`), with
/// up to `N` commands in flight.
///
/// A target that never answers: the command goes out `tries` times, one
/// timeout apart (COMMAND_LONG's `confirmation` counting the resends),
/// then ends as [`Outcome::TimedOut`]. The module example shows an answer.
///
/// ```
/// use fbwag_delegation::command::{CommandClient, CommandConfig, CommandOutput, Outcome, Request};
/// use fbwag_delegation::{Moment, Peer};
/// use fbwag_dialect::Message;
///
/// let fc = Peer::new(1, 1);
/// let cfg = CommandConfig::default(); // 1.5 s, 3 tries
/// let mut client = CommandClient::<4>::with_config(Peer::new(1, 191), cfg);
/// let id = client.send(Moment::ZERO, Request::request_message(fc, 24))?; // GPS_RAW_INT
/// let mut confirmations = Vec::new();
/// let mut outcome = None;
/// let mut now = Moment::ZERO;
/// loop {
///     while let Some(out) = client.poll_output() {
///         match out {
///             CommandOutput::Transmit(Message::CommandLong(c)) => confirmations.push(c.confirmation),
///             CommandOutput::Finished { id: done, outcome: o } => outcome = Some((done, o)),
///             _ => {}
///         }
///     }
///     // Silence: run the client's timer until it has nothing left to wait for.
///     let Some(t) = client.poll_timeout() else { break };
///     now = t;
///     client.handle_timeout(now);
/// }
/// assert_eq!(confirmations, [0, 1, 2]);
/// assert_eq!(outcome, Some((id, Outcome::TimedOut)));
/// assert_eq!(now, Moment::from_millis(4_500));
/// # Ok::<(), fbwag_delegation::command::Busy>(())
/// ```
#[derive(Debug, Clone)]
pub struct CommandClient<const N: usize = 8> {
    own: Peer,
    cfg: CommandConfig,
    pending: [Option<Pending>; N],
    next_id: u32,
    out: Outbox<CommandOutput, 8>,
}

impl<const N: usize> CommandClient<N> {
    /// A client sending as `own`, with the default timing.
    pub fn new(own: Peer) -> Self {
        Self::with_config(own, CommandConfig::default())
    }

    /// A client with this timing (at least one try).
    pub fn with_config(own: Peer, cfg: CommandConfig) -> Self {
        CommandClient {
            own,
            cfg: CommandConfig {
                tries: cfg.tries.max(1),
                ..cfg
            },
            pending: [None; N],
            next_id: 0,
            out: Outbox::new(),
        }
    }

    /// Sends `request` now; its outcome comes as
    /// [`CommandOutput::Finished`] with the returned id.
    pub fn send(&mut self, now: Moment, request: Request) -> Result<CommandId, Busy> {
        let clash = self.pending.iter().flatten().any(|p| {
            p.request.command() == request.command() && p.request.target() == request.target()
        });
        if clash {
            return Err(Busy::SameCommandInFlight);
        }
        let slot = self
            .pending
            .iter_mut()
            .find(|p| p.is_none())
            .ok_or(Busy::Full)?;
        let id = CommandId(self.next_id);
        self.next_id = self.next_id.wrapping_add(1);
        *slot = Some(Pending {
            id,
            request,
            sent: 1,
            deadline: now + self.cfg.timeout,
        });
        self.out
            .push(CommandOutput::Transmit(request.to_message(0)));
        Ok(id)
    }

    /// The next output, if any.
    #[must_use]
    pub fn poll_output(&mut self) -> Option<CommandOutput> {
        self.out.pop()
    }

    /// When [`handle_timeout`](Self::handle_timeout) must next run.
    #[must_use]
    pub fn poll_timeout(&self) -> Option<Moment> {
        self.pending.iter().flatten().map(|p| p.deadline).min()
    }

    /// Resends what has waited its timeout, ends what has used every try.
    pub fn handle_timeout(&mut self, now: Moment) {
        let (tries, timeout) = (self.cfg.tries, self.cfg.timeout);
        for slot in self.pending.iter_mut() {
            let Some(p) = slot else { continue };
            if now < p.deadline {
                continue;
            }
            if p.sent >= tries {
                self.out.push(CommandOutput::Finished {
                    id: p.id,
                    outcome: Outcome::TimedOut,
                });
                *slot = None;
            } else {
                self.out
                    .push(CommandOutput::Transmit(p.request.to_message(p.sent)));
                p.sent += 1;
                p.deadline = now + timeout;
            }
        }
    }

    /// A received frame: a COMMAND_ACK from a command's target, addressed
    /// to this client (or to every system), answers it. Anything else is
    /// ignored.
    pub fn handle_frame(&mut self, now: Moment, frame: &Frame<&[u8]>) {
        if let Some(MessageView::CommandAck(v)) = MessageView::new(frame.msg_id(), frame.payload())
        {
            let h = frame.header();
            self.handle_ack(now, Peer::new(h.sysid, h.compid), &v.to_message());
        }
    }

    /// A COMMAND_ACK from `from`.
    pub fn handle_ack(&mut self, now: Moment, from: Peer, ack: &CommandAck) {
        // Acks name the requester in their extension fields (0: unknown,
        // as older autopilots send).
        let for_us = (ack.target_system == 0 || ack.target_system == self.own.sysid)
            && (ack.target_component == 0 || ack.target_component == self.own.compid);
        if !for_us {
            return;
        }
        let timeout = self.cfg.timeout;
        let Some(slot) = self.pending.iter_mut().find(|p| {
            p.is_some_and(|p| {
                let target = p.request.target();
                p.request.command() == ack.command
                    && target.sysid == from.sysid
                    && (target.compid == 0 || target.compid == from.compid)
            })
        }) else {
            return;
        };
        let Some(p) = slot else { return };
        if ack.result == MavResult::IN_PROGRESS {
            // Still working: wait again, without resending.
            p.deadline = now + timeout;
            p.sent = 1;
            self.out.push(CommandOutput::Progress {
                id: p.id,
                progress: ack.progress,
            });
            return;
        }
        self.out.push(CommandOutput::Finished {
            id: p.id,
            outcome: Outcome::Result(ack.result),
        });
        *slot = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::vec::Vec;

    const FC: Peer = Peer::new(1, 1);
    const CC: Peer = Peer::new(1, 191);

    fn drain<const N: usize>(c: &mut CommandClient<N>) -> ([u8; 8], usize, Option<Outcome>) {
        let (mut confirmations, mut sent, mut outcome) = ([0u8; 8], 0, None);
        while let Some(o) = c.poll_output() {
            match o {
                CommandOutput::Transmit(Message::CommandLong(m)) => {
                    confirmations[sent] = m.confirmation;
                    sent += 1;
                }
                CommandOutput::Finished { outcome: o, .. } => outcome = Some(o),
                _ => {}
            }
        }
        (confirmations, sent, outcome)
    }

    fn ack(result: MavResult) -> CommandAck {
        CommandAck {
            command: MavCmd::SET_MESSAGE_INTERVAL,
            result,
            target_system: CC.sysid,
            target_component: CC.compid,
            ..Default::default()
        }
    }

    #[test]
    fn resends_with_a_new_confirmation_then_times_out() {
        let mut c = CommandClient::<2>::new(CC);
        c.send(
            Moment::ZERO,
            Request::message_interval(FC, 30, Some(100_000)),
        )
        .unwrap();
        let first = drain(&mut c);
        assert_eq!((first.0[0], first.1), (0, 1), "confirmation 0 first");
        let mut all = Vec::new();
        while let Some(t) = c.poll_timeout() {
            c.handle_timeout(t);
            all.push(drain(&mut c));
        }
        let sent: usize = all.iter().map(|d| d.1).sum();
        assert_eq!(sent, 2, "3 tries in all: the first and two resends");
        assert_eq!(all[0].0[0], 1);
        assert_eq!(all[1].0[0], 2);
        assert_eq!(all.last().unwrap().2, Some(Outcome::TimedOut));
    }

    #[test]
    fn an_ack_from_the_target_ends_it_others_do_not() {
        let mut c = CommandClient::<2>::new(CC);
        let req = Request::message_interval(FC, 30, None);
        c.send(Moment::ZERO, req).unwrap();
        assert_eq!(c.send(Moment::ZERO, req), Err(Busy::SameCommandInFlight));
        drain(&mut c);
        // From another system, or for another requester: ignored.
        c.handle_ack(Moment::ZERO, Peer::new(2, 1), &ack(MavResult::ACCEPTED));
        let mut other = ack(MavResult::ACCEPTED);
        other.target_component = 190;
        c.handle_ack(Moment::ZERO, FC, &other);
        assert_eq!(drain(&mut c).2, None);
        // In progress: kept open, not resent.
        c.handle_ack(Moment::from_millis(1000), FC, &ack(MavResult::IN_PROGRESS));
        c.handle_timeout(Moment::from_millis(1600));
        assert_eq!(drain(&mut c).1, 0, "the timer restarted at 1 s");
        c.handle_ack(Moment::from_millis(1700), FC, &ack(MavResult::DENIED));
        assert_eq!(drain(&mut c).2, Some(Outcome::Result(MavResult::DENIED)));
        assert_eq!(c.poll_timeout(), None);
    }

    #[test]
    fn slots_are_bounded() {
        let mut c = CommandClient::<1>::new(CC);
        c.send(Moment::ZERO, Request::request_message(FC, 148))
            .unwrap();
        assert_eq!(
            c.send(Moment::ZERO, Request::message_interval(FC, 30, None)),
            Err(Busy::Full)
        );
    }
}
