//! `mavgen-rs`: MAVLink XML dialects to Rust.
//!
//! The pipeline is XML → [`model`] (via [`xml`], one file at a time) →
//! [`schema`] (includes resolved, enums merged, checked, [`layout`] and
//! CRC_EXTRA computed exactly as pymavlink does) → tokens ([`codegen`]) →
//! formatted Rust. Use [`Config`] from a build script, or the `mavgen-rs`
//! command line to write bindings to a directory.
//!
//! The generated code depends only on the `mavframe` runtime crate.
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
