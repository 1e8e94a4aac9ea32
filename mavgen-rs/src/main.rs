//! `mavgen-rs`: generate, check and tabulate MAVLink XML dialects.

use clap::{Args, Parser, Subcommand};
use mavgen_rs::{Config, Diagnostic, Error, Schema};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// MAVLink XML dialects to Rust: zero-copy views, owned messages, CRC_EXTRA tables.
///
/// Every command reads the given XML files and everything they `<include>`
/// (relative to the including file), merges enums across files the way
/// pymavlink does, and checks the result. Problems are reported as
/// FILE:LINE:COL: error: … on stderr, and the exit status is 1.
///
/// Inputs must be regular files (or symbolic links to them): a directory,
/// FIFO, socket or device, given on the command line or named by an
/// `<include>`, is an error at that include. One file may hold at most
/// 8 MiB, all files of a run 64 MiB (upstream's common.xml is 0.6 MB).
/// Include chains of any depth are followed.
#[derive(Parser)]
#[command(name = "mavgen-rs", version, after_help = EXAMPLES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

const EXAMPLES: &str = "\
Examples:
  mavgen-rs check message_definitions/fbwag.xml
  mavgen-rs table message_definitions/fbwag.xml | grep FBWAG
      15001 FBWAG_NOTICE 30 12 12
  mavgen-rs generate message_definitions/fbwag.xml -o fbwag-dialect/bindings/fbwag
  mavgen-rs generate message_definitions/fbwag.xml -o cc/ --messages HEARTBEAT,FBWAG_NOTICE,RC_CHANNELS_OVERRIDE
  mavgen-rs generate message_definitions/fbwag.xml -o fbwag-dialect-cc/bindings --messages @fbwag-dialect-cc/messages.txt

Use the output with `include!(\"bindings/fbwag/mod.rs\");` in a crate that
depends on `mavframe`, or generate at build time with mavgen_rs::Config in build.rs.";

#[derive(Subcommand)]
enum Command {
    /// Write Rust bindings: DIR/mod.rs plus one module file per XML file.
    ///
    /// Nothing is written unless all input is valid. Unchanged files are left
    /// untouched; generated files of an earlier run that are no longer
    /// produced are removed (only files carrying mavgen-rs's header).
    Generate(GenerateArgs),
    /// Validate only: report errors and warnings, write nothing.
    Check {
        /// Dialect files.
        #[arg(required = true)]
        xml: Vec<PathBuf>,
    },
    /// Print `ID NAME CRC_EXTRA MIN_LEN MAX_LEN` for every message, by id.
    ///
    /// Covers the file and everything it includes, one line per message,
    /// nothing else on stdout (the format pymavlink's tables are compared in).
    Table {
        /// Dialect file.
        xml: PathBuf,
    },
}

/// The arguments of `generate`.
#[derive(Args)]
struct GenerateArgs {
    /// Dialect files (each becomes a module with a `Message` enum).
    #[arg(required = true)]
    xml: Vec<PathBuf>,
    /// Output directory (created if missing).
    #[arg(short, long, value_name = "DIR")]
    out: PathBuf,
    /// Only these messages and the enums they use: XML names, comma
    /// separated, or `@FILE` for a file of names (one or more per line,
    /// separated by commas or spaces; `#` starts a comment).
    #[arg(long, value_name = "A,B,…|@FILE", value_delimiter = ',')]
    messages: Option<Vec<String>>,
    /// Path of the runtime crate in the generated code.
    #[arg(long, value_name = "PATH", default_value = "::mavframe")]
    runtime: String,
    /// Attributes for generated messages and enums (repeatable):
    /// PATTERN is `.` for all or an XML message or enum name, ATTRS one
    /// or more attributes, e.g. `MAV_TYPE=#[derive(PartialOrd)]`.
    #[arg(long, value_name = "PATTERN=ATTRS", value_parser = pattern_and_attributes)]
    type_attribute: Vec<(String, String)>,
    /// Attributes for message fields (repeatable): PATTERN is `.`, an
    /// XML message name (all its fields) or MESSAGE.field, e.g.
    /// `HEARTBEAT.custom_mode=#[doc(alias = "mode")]`.
    #[arg(long, value_name = "PATTERN=ATTRS", value_parser = pattern_and_attributes)]
    field_attribute: Vec<(String, String)>,
}

/// `PATTERN=ATTRS`, split at the first `=` (patterns have none).
fn pattern_and_attributes(arg: &str) -> Result<(String, String), String> {
    match arg.split_once('=') {
        Some((pattern, attrs)) if !pattern.is_empty() => Ok((pattern.into(), attrs.into())),
        _ => Err("expected PATTERN=ATTRS, e.g. `HEARTBEAT=#[derive(Hash)]`".into()),
    }
}

/// Replaces every `@FILE` argument of `--messages` by the names in FILE.
fn expand_message_files(args: Vec<String>) -> Result<Vec<String>, String> {
    let mut names = Vec::new();
    for arg in args {
        let Some(path) = arg.strip_prefix('@') else {
            names.push(arg.trim().to_string());
            continue;
        };
        let listed = Config::message_list_file(Path::new(path))
            .map_err(|e| format!("--messages @{path}: {e}"))?;
        if listed.is_empty() {
            return Err(format!("--messages @{path}: the file names no message"));
        }
        names.extend(listed);
    }
    names.retain(|n| !n.is_empty());
    Ok(names)
}

fn report(diags: &[Diagnostic]) {
    for d in diags {
        eprintln!("{d}");
    }
}

fn main() -> ExitCode {
    match Cli::parse().command {
        Command::Generate(args) => generate(args),
        Command::Check { xml } => check(&xml),
        Command::Table { xml } => table(xml),
    }
}

fn generate(args: GenerateArgs) -> ExitCode {
    let mut config = Config::new();
    config
        .out_dir(&args.out)
        .runtime_crate(args.runtime)
        .cargo_output(false);
    for (pattern, attrs) in args.type_attribute {
        config.type_attribute(pattern, attrs);
    }
    for (pattern, attrs) in args.field_attribute {
        config.field_attribute(pattern, attrs);
    }
    if let Some(m) = args.messages {
        match expand_message_files(m) {
            Ok(names) => {
                config.messages(names);
            }
            Err(e) => {
                eprintln!("error: {e}");
                return ExitCode::FAILURE;
            }
        }
    }
    match config.compile(&args.xml) {
        Ok(g) => {
            report(&g.warnings);
            eprintln!(
                "wrote {} files to {} ({} messages, {} enums, from {} XML files)",
                g.output.files.len(),
                args.out.display(),
                g.messages,
                g.enums,
                g.inputs.len()
            );
            ExitCode::SUCCESS
        }
        Err(Error::Invalid(diags)) => {
            report(&diags);
            ExitCode::FAILURE
        }
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

fn check(xml: &[PathBuf]) -> ExitCode {
    match Schema::load(xml) {
        Ok(schema) => {
            report(schema.warnings());
            eprintln!(
                "ok: {} messages, {} enums in {} files",
                schema.messages().count(),
                schema.enums().count(),
                schema.paths().count()
            );
            ExitCode::SUCCESS
        }
        Err(diags) => {
            report(&diags);
            ExitCode::FAILURE
        }
    }
}

fn table(xml: PathBuf) -> ExitCode {
    match Schema::load(&[xml]) {
        Ok(schema) => {
            let mut rows: Vec<_> = schema.messages().collect();
            rows.sort_by_key(|m| m.id());
            let mut out = String::new();
            for m in rows {
                out.push_str(&format!(
                    "{} {} {} {} {}\n",
                    m.id(),
                    m.name(),
                    m.crc_extra(),
                    m.min_len(),
                    m.max_len()
                ));
            }
            print!("{out}");
            ExitCode::SUCCESS
        }
        Err(diags) => {
            report(&diags);
            ExitCode::FAILURE
        }
    }
}
