//! The delegation protocol on real links: the companion daemon (`fbwag
//! cc`), the router (`fbwag router`), and the companion with the
//! flight-controller simulator ([`crate::fc_sim`]) over a lossy loopback
//! relay (`fbwag demo`); and what every daemon shares: its links ([`net`]),
//! clock, log, events and rate-limited lines.
//!
//! Each daemon drives a node of `fbwag_delegation::node` (around the
//! protocol engines the simulator runs): which frames count, who is
//! trusted, whom a link answers, where a frame may go and which control is
//! applied is decided there. This module only moves bytes and time
//! ([`net`]) and reports ([`Events`], [`Log`]).

pub mod cc;
mod clock;
pub mod demo;
mod events;
pub mod flight_log;
mod health;
mod limiter;
mod log;
pub mod logfiles;
mod modes;
pub mod net;
pub mod router;
mod signals;
pub mod tlog;
pub mod vehicle;
pub mod writer;

pub use clock::Clock;
pub use events::Events;
pub use health::{Health, STATUS_EVERY};
pub use limiter::{Limiter, HEARD_PER_SECOND};
pub use log::{Level, Log, Style};
pub use modes::mode_name;
pub use tlog::{LogOptions, Tlog};
