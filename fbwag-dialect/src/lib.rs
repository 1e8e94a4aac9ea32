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
