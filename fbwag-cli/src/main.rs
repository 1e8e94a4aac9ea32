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

use std::process::ExitCode;

fn main() -> ExitCode {
    let run = cmd::Cli::from_args(std::env::args_os().collect()).and_then(cmd::Cli::run);
    match run {
        // (Said on standard error as it happened.)
        Ok(_) if live::writer::output_lost() => ExitCode::from(2),
        Ok(outcome) => outcome.exit_code(),
        Err(e) => {
            eprintln!("error: {e}");
            e.exit_code()
        }
    }
}
