//! The build-script API, in the style of `prost-build`:
//!
//! ```no_run
//! // In build.rs's main:
//! mavgen_rs::Config::new()
//!     .messages(["HEARTBEAT", "FBWAG_NOTICE"]) // optional filter
//!     .compile(&["message_definitions/fbwag.xml"])
//!     .unwrap_or_else(|e| panic!("{e}"));
//! // In lib.rs: include!(concat!(env!("OUT_DIR"), "/mod.rs"));
//! ```

use crate::codegen::{self, Options, Output};
use crate::diag::{Diagnostic, Severity};
use crate::input::{self, ReadError, MAX_FILE_BYTES};
use crate::schema::Schema;
use std::fmt;
use std::path::{Path, PathBuf};

/// Builds Rust bindings from MAVLink XML.
///
/// In a build script, `Config::new().compile(&["my_dialect.xml"])` writes
/// `mod.rs` and one file per XML file into `OUT_DIR`, prints
/// `cargo:rerun-if-changed` for every file read, and the crate includes
/// the result with `include!(concat!(env!("OUT_DIR"), "/mod.rs"))`.
/// Elsewhere, name the directory ([`out_dir`](Self::out_dir)), or only
/// [`generate`](Self::generate) to get the text. Module and file names
/// follow the rule of the [crate's output files](crate#output-files)
/// (`fn.xml` → `fn_.rs`); no output file is ever written twice.
///
/// ```
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// let dir = std::env::temp_dir().join(format!("mavgen-rs-doc-{}", std::process::id()));
/// std::fs::create_dir_all(&dir)?;
/// let xml = dir.join("tiny.xml");
/// std::fs::write(
///     &xml,
///     r#"<mavlink><messages>
///          <message id="42" name="PING_ME">
///            <description>A ping.</description>
///            <field type="uint32_t" name="seq">Sequence number.</field>
///          </message>
///        </messages></mavlink>"#,
/// )?;
///
/// let generated = mavgen_rs::Config::new()
///     .out_dir(dir.join("out"))
///     .cargo_output(false) // not a build script: no `cargo:` lines
///     .compile(&[&xml])?;
/// assert_eq!(generated.messages, 1);
/// assert!(generated.warnings.is_empty());
///
/// // mod.rs declares one module per XML file, here `tiny`.
/// let module = std::fs::read_to_string(dir.join("out/mod.rs"))?;
/// assert!(module.contains("pub mod tiny"));
/// let code = std::fs::read_to_string(dir.join("out/tiny.rs"))?;
/// assert!(code.contains("pub struct PingMe"));
///
/// // Invalid input is an error listing every problem; nothing is written.
/// std::fs::write(&xml, r#"<mavlink><messages><message id="42" name="PING_ME">
///     <field type="uint33_t" name="seq">Bad type.</field></message></messages></mavlink>"#)?;
/// let err = mavgen_rs::Config::new().generate(&[&xml]).unwrap_err();
/// assert!(matches!(err, mavgen_rs::Error::Invalid(_)));
/// std::fs::remove_dir_all(&dir)?;
/// # Ok(())
/// # }
/// ```
#[derive(Debug, Clone, Default)]
pub struct Config {
    options: Options,
    out_dir: Option<PathBuf>,
    cargo_output: Option<bool>,
}

/// What a generation produced.
#[derive(Debug, Clone)]
pub struct Generated {
    /// The files (`mod.rs` first).
    pub output: Output,
    /// Warnings about the input.
    pub warnings: Vec<Diagnostic>,
    /// Every XML file read.
    pub inputs: Vec<PathBuf>,
    /// Messages generated.
    pub messages: usize,
    /// Enums generated.
    pub enums: usize,
}

/// Why generation failed.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// The input is invalid; nothing was written.
    Invalid(Vec<Diagnostic>),
    /// Writing the output failed.
    Io(PathBuf, std::io::Error),
    /// No output directory was given and `OUT_DIR` is not set.
    NoOutDir,
    /// An attribute given to [`Config::type_attribute`] or
    /// [`Config::field_attribute`] cannot be applied.
    Attribute(AttributeError),
}

/// An attribute of [`Config::type_attribute`] or [`Config::field_attribute`]
/// that cannot be applied; nothing was generated.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AttributeError {
    /// The pattern it was given for.
    pub pattern: String,
    /// The attribute text as given.
    pub attribute: String,
    /// What is wrong.
    pub problem: AttributeProblem,
}

/// What is wrong with an [`AttributeError`]'s attribute.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum AttributeProblem {
    /// The text is not one or more outer attributes (`#[…]`); syn's message.
    Syntax(String),
    /// The pattern names no message or enum (type attributes), or no
    /// message or field of a message (field attributes) of the dialect.
    NoMatch,
}

impl fmt::Display for AttributeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (pattern, attribute) = (&self.pattern, &self.attribute);
        match &self.problem {
            AttributeProblem::Syntax(e) => write!(
                f,
                "attribute `{attribute}` (for `{pattern}`) is not an attribute: {e}"
            ),
            AttributeProblem::NoMatch => write!(
                f,
                "pattern `{pattern}` of attribute `{attribute}` names nothing in the dialect \
                 (`.`, a message or enum name, or MESSAGE.field for fields)"
            ),
        }
    }
}

impl std::error::Error for AttributeError {}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Invalid(diags) => {
                let errors = diags
                    .iter()
                    .filter(|d| d.severity == Severity::Error)
                    .count();
                for d in diags {
                    writeln!(f, "{d}")?;
                }
                write!(f, "{errors} error(s): no bindings generated")
            }
            Error::Io(p, e) => write!(f, "cannot write {}: {e}", p.display()),
            Error::NoOutDir => write!(
                f,
                "no output directory: call Config::out_dir or run from a build script (OUT_DIR)"
            ),
            Error::Attribute(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Error::Io(_, e) => Some(e),
            Error::Attribute(e) => Some(e),
            Error::Invalid(_) | Error::NoOutDir => None,
        }
    }
}

impl Config {
    /// Default settings: every message, runtime crate `::mavframe`, output in
    /// `OUT_DIR`.
    pub fn new() -> Self {
        Self::default()
    }

    /// Where [`compile`](Self::compile) writes (default: `$OUT_DIR`).
    pub fn out_dir(&mut self, dir: impl Into<PathBuf>) -> &mut Self {
        self.out_dir = Some(dir.into());
        self
    }

    /// Generates only these messages (XML names) and the enums they use, so
    /// a flight-controller or companion build compiles only what it speaks.
    /// Frames of other messages are still routable as raw frames.
    pub fn messages<I, S>(&mut self, names: I) -> &mut Self
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        self.options.messages = Some(names.into_iter().map(Into::into).collect());
        self
    }

    /// [`Self::messages`] from a message-list file's text: XML names
    /// separated by commas or whitespace; `#` starts a comment (the format
    /// of `mavgen-rs generate --messages @FILE`).
    pub fn message_list(text: &str) -> Vec<String> {
        text.lines()
            .flat_map(|line| {
                line.split('#')
                    .next()
                    .unwrap_or("")
                    .split(|c: char| c == ',' || c.is_whitespace())
            })
            .filter(|name| !name.is_empty())
            .map(str::to_string)
            .collect()
    }

    /// [`Self::message_list`] of the file at `path`, read with the bounds of
    /// the XML input: a regular file (not a FIFO or device) of at most
    /// [`MAX_FILE_BYTES`], in UTF-8.
    pub fn message_list_file(path: impl AsRef<Path>) -> Result<Vec<String>, ReadError> {
        let text = input::read_regular_text(path.as_ref(), MAX_FILE_BYTES)?;
        Ok(Self::message_list(&text))
    }

    /// The path generated code uses for the runtime crate (default
    /// `::mavframe`), e.g. `::fbwag_dialect::mavframe` for a crate that only
    /// depends on a dialect crate re-exporting it.
    pub fn runtime_crate(&mut self, path: impl Into<String>) -> &mut Self {
        self.options.runtime = path.into();
        self
    }

    /// Adds attributes to generated types, as prost-build's method of the
    /// same name: `path` is `.` for every message and enum, or the XML name
    /// of one (`"HEARTBEAT"`, `"MAV_TYPE"`); `attribute` is the text of one
    /// or more outer attributes, placed after the generated derives.
    /// Attributes naming serde go inside the generated
    /// `#[cfg_attr(feature = "serde", …)]` only if written so.
    ///
    /// A text that does not parse, or a path naming nothing in the dialect,
    /// is an [`Error::Attribute`] from [`generate`](Self::generate).
    ///
    /// ```
    /// let xml = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
    ///     .join("../message_definitions/minimal.xml");
    /// let generated = mavgen_rs::Config::new()
    ///     .type_attribute("MAV_TYPE", "#[derive(PartialOrd)] #[repr(transparent)]")
    ///     .field_attribute("HEARTBEAT.custom_mode", "#[doc(alias = \"mode\")]")
    ///     .generate(&[xml])
    ///     .unwrap();
    /// let code = &generated.output.files[1].1;
    /// assert!(code.contains("#[repr(transparent)]\npub struct MavType(pub u8);"));
    /// assert!(code.contains("#[doc(alias = \"mode\")]\n    pub custom_mode: u32,"));
    ///
    /// let bad = mavgen_rs::Config::new()
    ///     .type_attribute("HEARTBEAT", "#[derive(Hash)")
    ///     .generate(&[std::path::Path::new("unused.xml")]);
    /// assert!(matches!(bad, Err(mavgen_rs::Error::Attribute(_))));
    /// ```
    pub fn type_attribute(
        &mut self,
        path: impl Into<String>,
        attribute: impl Into<String>,
    ) -> &mut Self {
        self.options
            .type_attributes
            .push((path.into(), attribute.into()));
        self
    }

    /// Adds attributes to generated message fields, as prost-build's method
    /// of the same name: `path` is `.` for every field of every message, a
    /// message's XML name for all its fields, or `MESSAGE.field` (XML names:
    /// `"HEARTBEAT.type"`). Errors as [`type_attribute`](Self::type_attribute).
    pub fn field_attribute(
        &mut self,
        path: impl Into<String>,
        attribute: impl Into<String>,
    ) -> &mut Self {
        self.options
            .field_attributes
            .push((path.into(), attribute.into()));
        self
    }

    /// A command shown in each generated file's header.
    pub fn regenerate_hint(&mut self, hint: impl Into<String>) -> &mut Self {
        self.options.regenerate_hint = Some(hint.into());
        self
    }

    /// Whether [`compile`](Self::compile) prints `cargo:rerun-if-changed`
    /// for every file read and `cargo:warning` for every warning (default:
    /// when `OUT_DIR` is set, i.e. inside a build script).
    pub fn cargo_output(&mut self, on: bool) -> &mut Self {
        self.cargo_output = Some(on);
        self
    }

    /// Loads, checks and renders `xml` (the dialect files) without writing.
    pub fn generate<P: AsRef<Path>>(&self, xml: &[P]) -> Result<Generated, Error> {
        // Before reading any file: a typo in an attribute is found at once.
        self.check_attribute_syntax()?;
        let schema = Schema::load(xml).map_err(Error::Invalid)?;
        self.generate_from(&schema)
    }

    /// Renders a schema already loaded (by [`Schema::load`] or
    /// [`Schema::from_text`]) without writing: for a tool that inspects the
    /// dialect first, or a text that is not a file.
    pub fn generate_from(&self, schema: &Schema) -> Result<Generated, Error> {
        self.check_attribute_syntax()?;
        self.check_attribute_paths(schema)?;
        let output = codegen::generate(schema, &self.options).map_err(|mut e| {
            e.extend(schema.warnings.iter().cloned());
            Error::Invalid(e)
        })?;
        let messages = output_messages(schema, &self.options);
        let enums = output.enums;
        Ok(Generated {
            output,
            warnings: schema.warnings.clone(),
            inputs: schema.paths().map(Path::to_path_buf).collect(),
            messages,
            enums,
        })
    }

    /// Generates and writes the files into the output directory. Nothing is
    /// written unless the whole input is valid; unchanged files are not
    /// rewritten (so cargo does not rebuild), and stale generated files left
    /// by an earlier run are removed.
    pub fn compile<P: AsRef<Path>>(&self, xml: &[P]) -> Result<Generated, Error> {
        let in_build_script = std::env::var_os("OUT_DIR").is_some();
        let cargo = self.cargo_output.unwrap_or(in_build_script);
        if cargo {
            // Even when the input is invalid: fixing it must trigger a rerun.
            for p in xml {
                println!("cargo:rerun-if-changed={}", p.as_ref().display());
            }
        }
        let out_dir = match (&self.out_dir, std::env::var_os("OUT_DIR")) {
            (Some(d), _) => d.clone(),
            (None, Some(d)) => PathBuf::from(d),
            (None, None) => return Err(Error::NoOutDir),
        };
        let generated = self.generate(xml)?;
        if cargo {
            for p in &generated.inputs {
                println!("cargo:rerun-if-changed={}", p.display());
            }
            for w in &generated.warnings {
                println!("cargo:warning={w}");
            }
        }
        write_output(&out_dir, &generated.output)?;
        Ok(generated)
    }
}

impl Config {
    /// Every attribute text parses (before any file is read).
    fn check_attribute_syntax(&self) -> Result<(), Error> {
        let all = self.options.type_attributes.iter();
        for (pattern, attribute) in all.chain(&self.options.field_attributes) {
            if let Err(e) = codegen::parse_attributes(attribute) {
                return Err(Error::Attribute(AttributeError {
                    pattern: pattern.clone(),
                    attribute: attribute.clone(),
                    problem: AttributeProblem::Syntax(e),
                }));
            }
        }
        Ok(())
    }

    /// Every pattern names something of the dialect (a typo must not
    /// silently drop an attribute). Items the message filter leaves out
    /// still count: the same configuration serves filtered builds.
    fn check_attribute_paths(&self, schema: &Schema) -> Result<(), Error> {
        let message = |name: &str| {
            schema
                .message_refs()
                .find(|&r| schema.message(r).name == name)
        };
        let is_type = |p: &str| p == "." || message(p).is_some() || schema.enums.contains_key(p);
        let is_field = |p: &str| match p.split_once('.') {
            _ if p == "." => true,
            None => message(p).is_some(),
            Some((m, f)) => {
                message(m).is_some_and(|r| schema.message(r).fields.iter().any(|x| x.name == f))
            }
        };
        let types = self
            .options
            .type_attributes
            .iter()
            .map(|a| (a, is_type(&a.0)));
        let fields = self
            .options
            .field_attributes
            .iter()
            .map(|a| (a, is_field(&a.0)));
        match types.chain(fields).find(|(_, ok)| !ok) {
            Some(((pattern, attribute), _)) => Err(Error::Attribute(AttributeError {
                pattern: pattern.clone(),
                attribute: attribute.clone(),
                problem: AttributeProblem::NoMatch,
            })),
            None => Ok(()),
        }
    }
}

fn output_messages(schema: &Schema, opts: &Options) -> usize {
    match &opts.messages {
        None => schema.message_refs().count(),
        Some(names) => names.len(),
    }
}

/// The first line every generated file starts with; files carrying it are
/// ours to replace or remove.
pub(crate) const GENERATED_MARK: &str = "// @generated by mavgen-rs";

fn write_output(dir: &Path, output: &Output) -> Result<(), Error> {
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |e| Error::Io(p, e)
    };
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    for (name, text) in &output.files {
        let path = dir.join(name);
        // Bounded by the new text's length (plus one, to see a longer old
        // file): an output path that is a FIFO or a device is replaced, not read.
        if crate::input::read_regular(&path, text.len() as u64)
            .is_ok_and(|old| old == text.as_bytes())
        {
            continue;
        }
        // Write then rename, so a reader never sees half a file.
        let tmp = dir.join(format!(".{name}.tmp"));
        std::fs::write(&tmp, text).map_err(io(&tmp))?;
        std::fs::rename(&tmp, &path).map_err(io(&path))?;
    }
    let keep: Vec<&str> = output.files.iter().map(|(n, _)| n.as_str()).collect();
    for entry in std::fs::read_dir(dir).map_err(io(dir))?.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.ends_with(".rs") && !keep.contains(&name.as_str()) {
            let path = entry.path();
            let mark = GENERATED_MARK.as_bytes();
            if crate::input::read_prefix(&path, mark.len() as u64).is_ok_and(|t| t == mark) {
                std::fs::remove_file(&path).map_err(io(&path))?;
            }
        }
    }
    Ok(())
}
