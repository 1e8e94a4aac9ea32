//! The RC-loss delegation protocol of the FBWAG paper, as two sans-IO state
//! machines either side can embed: [`fc::FlightController`] and
//! [`cc::Companion`]. Neither reads a clock nor touches a socket: the caller
//! feeds inputs and the current time, and drains actions and the next
//! deadline (`poll_action`, `poll_timeout`), so every timing path is testable
//! and simulated without sleeping. `docs/delegation.md` is the specification.
//!
//! The [`sim`] module (feature `std`) runs both machines over modelled links
//! with a virtual clock: Table I of the paper, scenarios and loss sweeps.
#![cfg_attr(not(feature = "std"), no_std)]
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod cc;
pub mod fc;
mod outbox;
#[cfg(feature = "std")]
pub mod sim;
mod time;
pub mod wire;

pub use fbwag_dialect::FbwagFailsafeStatus as Status;
pub use time::Instant;

/// A MAVLink endpoint: system and component id.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Peer {
    /// System id.
    pub sysid: u8,
    /// Component id.
    pub compid: u8,
}

impl Peer {
    /// The peer with these ids.
    pub const fn new(sysid: u8, compid: u8) -> Self {
        Peer { sysid, compid }
    }
}

/// Where a received message came from, and whether its signature verified.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Origin {
    /// The sender's ids (from the frame header).
    pub peer: Peer,
    /// The frame's MAVLink 2 signature verified with the link key.
    pub authenticated: bool,
    /// The frame's sequence number: tells a late frame from a new one when
    /// the link reorders.
    pub seq: u8,
}

/// True when sequence number `a` was sent after `b` (within half the
/// 8-bit wrap, plenty for one lease of frames).
pub(crate) fn seq_after(a: u8, b: u8) -> bool {
    (a.wrapping_sub(b) as i8) > 0
}

/// ArduPlane flight modes as HEARTBEAT `custom_mode` values, plus the
/// companion-control mode this protocol adds.
pub mod mode {
    /// MANUAL.
    pub const MANUAL: u32 = 0;
    /// CIRCLE: what the FC flies while the handshake runs (its short failsafe).
    pub const CIRCLE: u32 = 1;
    /// FBWA.
    pub const FBWA: u32 = 5;
    /// RTL: the fallback.
    pub const RTL: u32 = 11;
    /// GUIDED.
    pub const GUIDED: u32 = 15;
    /// FBWAG: companion control (FBWA stabilisation driven by the companion's
    /// RC overrides). Not an upstream ArduPlane number: chosen here, above the
    /// upstream range; see docs/delegation.md.
    pub const FBWAG: u32 = 30;
}

/// The STATUSTEXT the FC sends when the companion's takeover is confirmed.
pub const TEXT_CC_TOOK_OVER: &str = "FBWAG-ACK: CC has taken over!";
/// The STATUSTEXT the FC sends when the companion acknowledges the hand-back.
pub const TEXT_RC_TOOK_OVER: &str = "FBWAG-ACK: RC has taken over!";
