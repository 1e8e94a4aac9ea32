//! The one error type of `fbwag`, and the exit status of each outcome
//! ([`EXIT_STATUS`], shown by `fbwag --help`).

use crate::args::{LinkOptionError, OutageError};
use crate::hexstream::HexError;
use crate::live::cc::TrustedOutError;
use crate::sim::SimError;
use fbwag_dialect::mavframe::conn::ParseEndpointError;
use std::io;
use std::process::ExitCode;

/// What `fbwag --help` says about exit statuses.
pub const EXIT_STATUS: &str = "\
Exit status:
  0  done, and nothing was wrong
  1  done, but something was found wrong: frames skipped (decode), lines
     refused (encode), an invariant broken (sim --model-check), no handover
     (demo)
  2  not done: an argument refused, an input that could not be opened or
     read, an output not written, a link not opened, an invariant broken
     (sim), a daemon's fatal error (a damaged signing state file, say)";

/// How a command that ran to its end went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// Exit status 0.
    Clean,
    /// Exit status 1: the work was done, but the input had problems or a
    /// check failed (counted on stderr).
    Flagged,
}

impl Outcome {
    /// [`Outcome::Clean`] when `clean`, else [`Outcome::Flagged`].
    pub fn clean_if(clean: bool) -> Self {
        if clean {
            Outcome::Clean
        } else {
            Outcome::Flagged
        }
    }

    pub fn exit_code(self) -> ExitCode {
        match self {
            Outcome::Clean => ExitCode::SUCCESS,
            Outcome::Flagged => ExitCode::from(1),
        }
    }
}

/// Why a command could not do its work (exit status 2).
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The input file (`None`: standard input) could not be opened.
    #[error("cannot open {}: {source}", path.as_ref().map_or("standard input".into(), |p| p.display().to_string()))]
    OpenInput {
        path: Option<std::path::PathBuf>,
        source: io::Error,
    },
    #[error("cannot read input: {0}")]
    ReadInput(#[source] io::Error),
    #[error("cannot write: {0}")]
    Write(#[source] io::Error),
    /// `decode --hex` input that is not hex.
    #[error(transparent)]
    Hex(#[from] HexError),
    /// A connection string, named by the argument that gave it.
    #[error("{arg}: {source}")]
    Endpoint {
        arg: String,
        source: ParseEndpointError,
    },
    /// A `--trusted-out` link that is not local.
    #[error("--trusted-out {conn}: {source}")]
    TrustedOut {
        conn: String,
        source: TrustedOutError,
    },
    /// Options given per link (`--filter-in`, `--peer 2:...`) that
    /// cannot apply, named by the argument at fault.
    #[error("{arg}: {source}")]
    LinkOption {
        arg: String,
        source: LinkOptionError,
    },
    /// `fbwag cc --autonomy` listening without `--autonomy-peer`.
    #[error("--autonomy {0} listens: any program on this machine that speaks first would fly the aircraft; name the autonomy's address with --autonomy-peer IP:PORT (the port it sends from), or --autonomy-peer any to admit anyone (unsafe)")]
    AutonomyUnpinned(String),
    /// `fbwag key new` could not write its file.
    #[error("cannot write a new key to {}: {source}{}", path.display(), if source.kind() == io::ErrorKind::AlreadyExists { " (a key is never overwritten: remove the file, or choose another path)" } else { "" })]
    KeyWrite {
        path: std::path::PathBuf,
        source: io::Error,
    },
    /// `fbwag router` with fewer than two links.
    #[error("a router needs two links or more (CONN), got {0}")]
    TooFewLinks(usize),
    /// A signing key of the wrong length.
    #[error("a signing key is 32 bytes (64 hex digits), got {0}")]
    KeyLength(usize),
    /// `fc-sim --rc-loss-at`/`--rc-back-at` that do not pair up.
    #[error(transparent)]
    Outages(#[from] OutageError),
    #[error(transparent)]
    Sim(#[from] SimError),
    /// A daemon (or the demo) that stopped on an error.
    #[error("{command}: {source}")]
    Daemon {
        command: &'static str,
        source: io::Error,
    },
    /// A `--config` file refused.
    #[error(transparent)]
    Config(#[from] crate::cmd::config::ConfigError),
    /// `decode --tlog` input that ends inside a record (a log cut short by
    /// a power loss, a copy interrupted): the records before it are
    /// decoded.
    #[error("tlog truncated: the record at byte offset {offset} has {left} bytes, it needs at least {needed}")]
    TlogTruncated {
        offset: u64,
        left: usize,
        needed: usize,
    },
    /// An error of the JSON conversions ([`crate::json`]), whatever its type.
    #[error("{0}")]
    Json(Box<dyn std::error::Error>),
}

impl CliError {
    /// Wraps an error of [`crate::json`].
    pub fn json(e: impl Into<Box<dyn std::error::Error>>) -> Self {
        CliError::Json(e.into())
    }

    /// Names the `command` a daemon's error came from.
    pub fn daemon(command: &'static str) -> impl FnOnce(io::Error) -> Self {
        move |source| CliError::Daemon { command, source }
    }

    /// A connection string `arg` could not be parsed.
    pub fn endpoint(arg: impl Into<String>) -> impl FnOnce(ParseEndpointError) -> Self {
        move |source| CliError::Endpoint {
            arg: arg.into(),
            source,
        }
    }

    /// Options per link that cannot apply (see [`crate::args::per_link`],
    /// [`crate::args::link_filters`]).
    pub fn link_option((arg, source): (String, LinkOptionError)) -> Self {
        CliError::LinkOption { arg, source }
    }

    /// Every error exits with status 2, as clap's own refusals do.
    pub fn exit_code(&self) -> ExitCode {
        ExitCode::from(2)
    }
}
