//! The RC-loss delegation protocol of the FBWAG paper, sans-IO: nothing here
//! reads a clock or touches a socket. The caller feeds received frames and
//! the current time, and drains what to send and do, and the next deadline,
//! so every timing path is testable and simulated without sleeping.
//! `docs/delegation.md` is the specification.
//!
//! - [`node`]: what to embed. A program that speaks the protocol is a
//!   MAVLink node with several links: [`node::CompanionNode`],
//!   [`node::FcNode`] and [`node::RouterNode`] take every frame a link
//!   delivers (with its source address and whether its signature verified)
//!   and decide its fate once: protocol input, control through the
//!   companion's gate, the links it is routed to, or a drop with a counted
//!   reason; and whom each listening link answers. The simulator and the
//!   `fbwag` daemons drive these nodes, so what the simulator checks is
//!   what the live programs run.
//! - [`engine`]: inside each node, [`engine::FcEngine`] (the flight
//!   controller's side) and [`engine::CcEngine`] (the companion's): which
//!   messages are inputs, who is trusted (configured ids, and a verified
//!   signature when signing is required), which control messages are
//!   accepted and applied, the protocol's timers.
//! - [`fc::FlightController`] and [`cc::Companion`]: the two state machines
//!   inside the engines, with typed inputs already judged trustworthy.
//! - [`control`]: the control the companion sends and the FC applies.
//! - [`sim`] (feature `sim`): the FC's and the companion's nodes over
//!   modelled links on a virtual clock, strangers included: Table I of the
//!   paper, scenarios and loss sweeps.
//!
//! # Call order
//!
//! Every machine, engine and node follows the same contract, as quinn-proto does:
//! after **every** `handle_*` call, drain the outputs (`poll_output` /
//! `poll_action`) until `None`, then ask `poll_timeout` for the next
//! deadline and call `handle_timeout` at (or after) it. Outputs queue in a
//! small fixed buffer; a caller that does not drain loses the newest ones
//! (a debug assertion flags it).
//!
//! # Example: a takeover, frame by frame
//!
//! The flight controller's and the companion's engines, wired to each
//! other through real MAVLink frames (encoded, then parsed) on a virtual
//! clock: the pilot's radio is lost, the FC asks, the companion takes
//! over. A live program does the same with a `Connection` per link and
//! the system clock (the `fbwag` daemons drive [`node`]s this way).
//!
//! ```
//! use fbwag_delegation::cc::{CcConfig, CcState};
//! use fbwag_delegation::engine::{CcEngine, CcOutput, FcEngine, FcOutput};
//! use fbwag_delegation::fc::{Authority, FcConfig};
//! use fbwag_delegation::{Moment, Peer};
//! use fbwag_dialect::mavframe::frame::MAX_FRAME_LEN;
//! use fbwag_dialect::{encode, Frame, Header, Message, Parser, Version};
//!
//! /// `msg` framed as `from` sends it, then parsed as its peer receives it.
//! fn deliver(from: Peer, msg: &Message, rx: &mut Parser, mut to: impl FnMut(&Frame<&[u8]>, bool)) {
//!     let mut buf = [0u8; MAX_FRAME_LEN];
//!     let header = Header { seq: 0, sysid: from.sysid, compid: from.compid };
//!     let len = encode(Version::V2, header, msg, None, &mut buf).expect("fits");
//!     let mut input = &buf[..len];
//!     while let Some(received) = rx.next(&mut input) {
//!         to(&received.frame(), received.is_authenticated());
//!     }
//! }
//!
//! let (fc_cfg, cc_cfg) = (FcConfig::default(), CcConfig::default());
//! let mut fc = FcEngine::new(fc_cfg, Moment::ZERO)?;
//! let mut cc = CcEngine::new(cc_cfg, Moment::ZERO)?;
//! let (mut fc_rx, mut cc_rx) = (Parser::new(), Parser::new());
//!
//! fc.set_receiver_ok(false); // the pilot's radio link is gone
//! let mut now = Moment::ZERO;
//! while fc.authority() != Authority::Companion {
//!     // Drain both engines; what one transmits, the other receives.
//!     let mut idle = true;
//!     while let Some(out) = fc.poll_output() {
//!         idle = false;
//!         if let FcOutput::Transmit(msg) = out {
//!             deliver(fc_cfg.own, &msg, &mut cc_rx, |f, auth| {
//!                 let _ = cc.handle_frame(now, f, auth);
//!             });
//!         }
//!     }
//!     while let Some(out) = cc.poll_output() {
//!         idle = false;
//!         if let CcOutput::Transmit(msg) = out {
//!             deliver(cc_cfg.own, &msg, &mut fc_rx, |f, auth| {
//!                 let _ = fc.handle_frame(now, f, auth);
//!             });
//!         }
//!     }
//!     if idle {
//!         // Nothing left to say: on to the next deadline of either side.
//!         now = fc.poll_timeout().into_iter().chain(cc.poll_timeout()).min().unwrap();
//!         fc.handle_timeout(now);
//!         cc.handle_timeout(now);
//!     }
//!     assert!(now < Moment::from_millis(2_000), "no takeover");
//! }
//! assert_eq!(cc.state(), CcState::Controlling);
//! # Ok::<(), fbwag_delegation::ConfigError>(())
//! ```
#![cfg_attr(not(feature = "std"), no_std)]
#![cfg_attr(docsrs, feature(doc_cfg))]
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod cc;
pub mod command;
pub mod control;
pub mod digest;
pub mod engine;
pub mod fc;
pub mod node;
mod outbox;
pub mod protected;
#[cfg(feature = "sim")]
pub mod sim;
mod time;
pub mod wire;

use core::fmt;

pub use fbwag_dialect::FbwagFailsafeStatus as Status;
pub use time::Moment;

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

/// Who a side listens to: the configured peer's ids, and a verified
/// signature when signing is required. The one trust rule of the protocol.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Trust {
    /// The only sender whose protocol messages count.
    pub peer: Peer,
    /// Its frames count only when their MAVLink 2 signature verified.
    pub require_signed: bool,
}

impl Trust {
    /// True when a frame from `from` counts.
    pub fn admits(&self, from: Origin) -> bool {
        from.peer == self.peer && (from.authenticated || !self.require_signed)
    }
}

/// A setting that cannot work.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum ConfigError {
    /// This period or count is zero.
    Zero(&'static str),
    /// The first setting must be below the second.
    Order(&'static str, &'static str),
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ConfigError::Zero(name) => write!(f, "{name} must be above zero"),
            ConfigError::Order(a, b) => write!(f, "{a} must be below {b}"),
        }
    }
}

impl core::error::Error for ConfigError {}

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

/// The STATUSTEXT the FC sends when the companion's takeover is confirmed
/// (the paper's Fig. 6).
pub const TEXT_CC_TOOK_OVER: &str = "FBWAG-ACK: CC has taken over!";
/// The STATUSTEXT the FC sends when the companion acknowledges the hand-back.
pub const TEXT_RC_TOOK_OVER: &str = "FBWAG-ACK: RC has taken over!";
