//! The protocol engines: everything between MAVLink frames and the state
//! machines, once, for every program that speaks the protocol (the
//! simulator, `fbwag fc-sim`, `fbwag cc`, your own firmware or daemon).
//!
//! An engine takes the frames a parser accepted (with whether their
//! signature verified) and the time, and gives back [`FcOutput`] /
//! [`CcOutput`]: messages to send, mode changes, control to apply, events.
//! It decides:
//!
//! - **which messages are protocol inputs**: FBWAG_NOTICE and HEARTBEAT both
//!   ways; the FC's takeover STATUSTEXT (the paper's "FBWAG-ACK: CC has taken
//!   over!") becomes the typed [`crate::cc::CcInput::TakeoverConfirmed`];
//!   RC_CHANNELS_OVERRIDE, SET_ATTITUDE_TARGET and MANUAL_CONTROL are control;
//! - **who is trusted** ([`crate::Trust`]): only the configured peer's ids,
//!   and only frames whose signature verified when signing is required;
//!   every other frame is [`Verdict::Untrusted`] and changes nothing but a
//!   counter;
//! - **which control is applied**: the FC emits [`FcOutput::ApplyControl`]
//!   only for control from the trusted companion, addressed to this FC, while
//!   the FC is in companion control; the companion forwards its controller's
//!   or its autonomy's control only while it holds control;
//! - **the protocol's timers**: receiver sampling (10 Hz), heartbeats (the
//!   FC's 5 Hz confirmation stream in companion control), retries.
//!
//! Frames must come from a parser (`mavframe::Parser` or a `Connection`):
//! the engine trusts its checksum and signature verdicts and does not check
//! them again. Signing itself (keys, replay windows, state across restarts)
//! is the connection's job; the engine only reads the verdict.
//!
//! Call order: after every `handle_*` call, drain `poll_output` until `None`;
//! then call `handle_timeout` at `poll_timeout()` (see the crate docs).

mod cc;
mod fc;

pub use cc::{CcEngine, CcEngineStats, CcOutput, ControlVerdict};
pub use fc::{FcEngine, FcEngineStats, FcOutput};

use crate::{Moment, Origin, Peer};
use core::time::Duration;
use fbwag_dialect::Frame;

/// Whether a frame came from the trusted peer.
#[must_use]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// From the configured peer, with a verified signature when signing is
    /// required: its protocol messages were acted on.
    Trusted,
    /// From anyone else (or unsigned where signing is required): ignored,
    /// counted.
    Untrusted,
}

/// The sender of `frame`, as a parser judged it.
fn origin(frame: &Frame<&[u8]>, authenticated: bool) -> Origin {
    let h = frame.header();
    Origin {
        peer: Peer::new(h.sysid, h.compid),
        authenticated,
        seq: h.seq,
    }
}

/// The next tick of a periodic timer due at `due` with `period`: the
/// cadence is kept, but after a stall longer than a period the timer
/// restarts from `now` instead of firing a burst.
fn next_tick(due: Moment, period: Duration, now: Moment) -> Moment {
    let next = due + period;
    if next > now {
        next
    } else {
        now + period
    }
}

/// The earliest of some deadlines.
fn earliest(deadlines: impl IntoIterator<Item = Option<Moment>>) -> Option<Moment> {
    deadlines.into_iter().flatten().min()
}
