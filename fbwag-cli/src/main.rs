//! `fbwag`: the FBWAG MAVLink toolbox.

mod args;
mod cmd;
mod error;
mod fc_sim;
mod hexstream;
mod json;
mod lines;
mod live;
mod sim;

use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    match cmd::Cli::parse().run() {
        Ok(outcome) => outcome.exit_code(),
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}
