//! The command line: one clap `Args` struct per subcommand, each in a
//! module of its own with what turns it into the options of the code that
//! runs it.

mod cc;
pub mod config;
mod decode;
mod demo;
mod encode;
mod fc_sim;
mod help;
mod key;
mod router;
mod sim;
mod tlog;

use crate::error::{CliError, Outcome, EXIT_STATUS};
use crate::json;
use crate::live::net::LinkOptions;
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::ffi::OsString;
use std::net::SocketAddr;
use std::path::PathBuf;

/// Tools for the FBWAG MAVLink dialect (ardupilotmega + FBWAG_NOTICE, id 15001).
#[derive(Parser)]
#[command(name = "fbwag", version, after_help = after_help())]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
    /// What the `--config` files gave, to name a file's line when a
    /// daemon refuses a per-link option after the parse.
    #[arg(skip)]
    file: Option<config::FileArgs>,
}

fn after_help() -> String {
    format!("{}\n\n{EXIT_STATUS}", help::EXAMPLES)
}

#[derive(Subcommand)]
enum Command {
    Decode(decode::DecodeArgs),
    Encode(encode::EncodeArgs),
    Cc(cc::CcArgs),
    FcSim(fc_sim::FcSimArgs),
    Demo(demo::DemoArgs),
    Router(router::RouterArgs),
    Sim(sim::SimArgs),
    Key(key::KeyArgs),
}

impl Cli {
    /// The command line `argv`, with the options of `--config PATH` before
    /// its own ([`config`]); the command line's single-valued options win.
    /// Exits as clap does for `--help`, `--version` and a refused command
    /// line; a refused file, or a value of the file an option refuses, is
    /// an error naming the file's line.
    pub fn from_args(argv: Vec<OsString>) -> Result<Cli, CliError> {
        let mut command = Cli::command();
        for daemon in ["router", "cc"] {
            command = command.mut_subcommand(daemon, |c| c.args_override_self(true));
        }
        let (argv, file) = config::expand(&command, argv)?;
        let parsed = command
            .try_get_matches_from(argv)
            .and_then(|m| Cli::from_arg_matches(&m));
        match parsed {
            Ok(cli) => Ok(Cli { file, ..cli }),
            Err(e) => match file.as_ref().and_then(|f| f.blame(&e)) {
                Some(refused) => Err(refused.into()),
                None => e.exit(),
            },
        }
    }

    /// Runs the subcommand (or, with `--print-config`, prints what the
    /// files gave as TOML). A per-link option refused is named at the
    /// file's line when a `--config` file gave it.
    pub fn run(self) -> Result<Outcome, CliError> {
        let Cli { command, file } = self;
        let printed = |program| {
            let toml = file.as_ref().map(|f| f.toml(program));
            print!("{}", toml.unwrap_or_else(|| "# no --config given\n".into()));
            Outcome::Clean
        };
        let outcome = match command {
            // Checked as a run would check them, then printed.
            Command::Router(a) if a.print_config => router::check(a).map(|()| printed("router")),
            Command::Cc(a) if a.print_config => cc::check(a).map(|()| printed("cc")),
            command => run(command),
        };
        outcome.map_err(|e| match (e, &file) {
            (CliError::LinkOption { arg, source }, Some(f)) => match f.blame_link(&arg, &source) {
                Some(refused) => refused.into(),
                None => CliError::LinkOption { arg, source },
            },
            (e, _) => e,
        })
    }
}

/// Runs `command`.
fn run(command: Command) -> Result<Outcome, CliError> {
    match command {
        Command::Decode(a) => decode::run(a),
        Command::Encode(a) => encode::run(a),
        Command::Cc(a) => cc::run(a),
        Command::FcSim(a) => fc_sim::run(a),
        Command::Demo(a) => demo::run(a),
        Command::Router(a) => router::run(a),
        Command::Sim(a) => sim::run(a),
        Command::Key(a) => key::run(a),
    }
}

/// A 32-byte key from the 64 hex digits `--sign-key` checked.
fn key(hex: &str) -> Result<[u8; 32], CliError> {
    let bytes = json::unhex(hex).map_err(CliError::json)?;
    bytes
        .try_into()
        .map_err(|b: Vec<u8>| CliError::KeyLength(b.len()))
}

/// The options of a daemon's main link, from its arguments; nothing routed
/// to it is paced (the companion sets `routed_rate`).
fn link_options(
    link: &str,
    sign_key: Option<&str>,
    peer: Option<SocketAddr>,
    signing_state: Option<PathBuf>,
) -> Result<LinkOptions, CliError> {
    let (name, conn) = crate::args::split_link_name(link);
    Ok(LinkOptions {
        endpoint: conn.parse().map_err(CliError::endpoint("--link"))?,
        name: name.map(str::to_string),
        routed_rate: None,
        key: sign_key.map(key).transpose()?,
        peer,
        signing_state,
    })
}
