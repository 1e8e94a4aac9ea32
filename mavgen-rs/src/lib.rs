//! `mavgen-rs`: MAVLink XML dialects to Rust.
//!
//! The pipeline is XML → [`model`] (via [`xml`], one file at a time) →
//! [`schema`] (includes resolved, enums merged, checked, [`layout`] and
//! CRC_EXTRA computed exactly as pymavlink does) → tokens ([`codegen`]) →
//! formatted Rust. Use [`Config`] from a build script, or the `mavgen-rs`
//! command line to write bindings to a directory.
//!
//! The generated code depends only on the `mavframe` runtime crate.
//!
//! # Your own dialect
//!
//! A crate with its own XML depends on the runtime and, in its build
//! script, on this library without the `cli` feature (which adds the
//! command line's clap and mimalloc):
//!
//! ```toml
//! [dependencies]
//! mavframe = { version = "0.1", default-features = false }
//!
//! [build-dependencies]
//! mavgen-rs = { version = "0.1", default-features = false }
//!
//! [features]
//! # Generated serde impls are under `cfg(feature = "serde")`.
//! serde = ["mavframe/serde"]
//! ```
//!
//! ```no_run
//! // build.rs, in `fn main`:
//! mavgen_rs::Config::new()
//!     .compile(&["my_dialect.xml"])
//!     .unwrap_or_else(|e| panic!("{e}"));
//! ```
//!
//! ```text
//! // src/lib.rs (or main.rs): one module per XML file read.
//! pub mod dialects {
//!     include!(concat!(env!("OUT_DIR"), "/mod.rs"));
//! }
//! ```
//!
//! [`Config`] shows the rest (a tested example, message filters,
//! attributes); the repository's `examples/own-dialect` is a whole crate.
#![warn(missing_docs)]

pub mod codegen;
mod config;
pub mod diag;
pub mod input;
pub mod layout;
pub mod model;
pub mod names;
pub mod schema;
pub mod xml;

pub use config::{AttributeError, AttributeProblem, Config, Error, Generated};
pub use diag::{Diagnostic, Severity};
pub use schema::Schema;
