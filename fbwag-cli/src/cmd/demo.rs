//! `fbwag demo`: both daemons over a lossy loopback relay.

use crate::args;
use crate::error::{CliError, Outcome};
use crate::live::demo::{demo, DemoOptions};

/// Both programs over loopback UDP through a lossy relay: the receiver
/// fails and returns several times; a timeline, and the handover times
/// (p50 and max).
///
/// The relay's losses depend only on the seed (each message's fate is
/// drawn from the seed, its direction, its id and its count): a seed
/// gives the same handovers on every run, up to scheduling jitter.
#[derive(clap::Args)]
pub struct DemoArgs {
    /// Share of datagrams the relay drops in each direction (0–1).
    #[arg(long, default_value_t = 0.2, allow_hyphen_values = true, value_parser = args::share)]
    pub loss: f64,
    /// Receiver failures (each followed by the receiver's return).
    #[arg(long, default_value_t = 5, allow_hyphen_values = true, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub cycles: u32,
    /// How long each failure lasts (s): past the FC's 5 s handshake
    /// timeout, so every failure ends in companion control or RTL.
    #[arg(long, default_value_t = 5.5, allow_hyphen_values = true, value_parser = args::seconds)]
    pub lost_for: f64,
    /// How long the receiver works between failures (s).
    #[arg(long, default_value_t = 1.5, allow_hyphen_values = true, value_parser = args::seconds)]
    pub back_for: f64,
    /// Seed of the relay's losses.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl From<DemoArgs> for DemoOptions {
    fn from(a: DemoArgs) -> Self {
        DemoOptions {
            loss: a.loss,
            cycles: a.cycles,
            lost_for: a.lost_for,
            back_for: a.back_for,
            seed: a.seed,
        }
    }
}

/// [`Outcome::Flagged`] when no failure was handed over.
pub fn run(a: DemoArgs) -> Result<Outcome, CliError> {
    let report = demo(a.into()).map_err(CliError::daemon("demo"))?;
    Ok(Outcome::clean_if(!report.handovers.is_empty()))
}
