//! `mavgen-rs`: MAVLink XML dialects to Rust.
//!
//! The pipeline is XML → a parsed model (one file at a time) → a
//! [`Schema`] (includes resolved, enums merged, checked, wire layout and
//! CRC_EXTRA computed exactly as pymavlink does) → tokens → formatted Rust.
//! Use [`Config`] from a build script, or the `mavgen-rs` command line to
//! write bindings to a directory; [`Schema`] alone checks a dialect and
//! shows its messages and enums without generating code. Problems come back
//! as [`Diagnostic`]s with file, line and column.
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
//! The same generation without files, from a text, as a tool or a test
//! might run it:
//!
//! ```
//! let xml = r#"<mavlink><messages>
//!     <message id="42" name="PING_ME">
//!       <description>A ping.</description>
//!       <field type="uint32_t" name="seq">Sequence number.</field>
//!     </message>
//!   </messages></mavlink>"#;
//! let schema = mavgen_rs::Schema::from_text("ping.xml", xml).unwrap();
//! let generated = mavgen_rs::Config::new().generate_from(&schema).unwrap();
//! let names: Vec<&str> = generated.output.files.iter().map(|(n, _)| n.as_str()).collect();
//! assert_eq!(names, ["mod.rs", "ping.rs"]);
//! let code = &generated.output.files[1].1;
//! assert!(code.contains("pub struct PingMe {"));
//! assert!(code.contains("pub fn seq(&self) -> u32"));
//! ```
//!
//! [`Config`] shows the rest (writing files, message filters,
//! attributes); the repository's `examples/own-dialect` is a whole crate.
//!
//! # Output files
//!
//! `mod.rs` declares one module per XML file read (the dialects and their
//! includes), each in its own file `<module>.rs`. The module is the file
//! name without `.xml` in snake case (`uAvionix.xml` → `uavionix`), with
//! `_` appended when that is a Rust keyword (`fn.xml` → `fn_`, `self.xml` →
//! `self_`, `mod.xml` → `mod_`): a module read from a file cannot have a raw
//! name, and `mod.rs` is the root. Two files that would get one module (the
//! same name in two directories, or `fn.xml` next to `fn_.xml`) are an
//! error pointing at the second file, and nothing is written.
#![warn(missing_docs)]

mod codegen;
mod config;
mod defs;
mod diag;
mod input;
mod layout;
mod model;
mod names;
mod schema;
mod xml;

pub use codegen::Output;
pub use config::{AttributeError, AttributeProblem, Config, Error, Generated};
pub use defs::{EntryDef, EnumDef, FieldDef, MessageDef};
pub use diag::{Diagnostic, Position, Severity};
pub use input::{ReadError, MAX_FILE_BYTES, MAX_TOTAL_BYTES};
pub use schema::Schema;
