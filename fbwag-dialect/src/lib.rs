//! The FBWAG MAVLink dialect: ArduPilot's `ardupilotmega.xml` (and all it
//! includes) plus `FBWAG_NOTICE` (id 15001), the RC-failsafe delegation
//! message, generated at build time by `mavgen-rs`.
#![no_std]
#![warn(missing_docs)]

#[cfg(feature = "std")]
extern crate std;

pub use mavwire;

/// Every generated module, one per XML file.
pub mod dialects {
    include!(concat!(env!("OUT_DIR"), "/mod.rs"));
}

pub use dialects::fbwag::{
    Dialect, FbwagFailsafeStatus, FbwagNotice, FbwagNoticeMut, FbwagNoticeView, Message,
    MessageView, MESSAGES,
};

pub use mavwire::frame::{encode, Frame, FrameError, Header, Version};
pub use mavwire::parser::{Received, Stats};
pub use mavwire::signing::{SignatureError, Signer, Verifier};

/// The streaming parser for this dialect (see [`mavwire::parser`]).
pub type Parser = mavwire::parser::Parser<Dialect>;

/// A link speaking this dialect, e.g.
/// `Connection::open(&"udpin:0.0.0.0:14550".parse()?)` (see [`mavwire::conn`]).
#[cfg(feature = "std")]
pub type Connection = mavwire::conn::Connection<Dialect>;

#[cfg(feature = "std")]
pub use mavwire::conn::{Endpoint, ReceivedFrame};
