//! `fbwag sim`: what to run in the simulator.

use crate::args;
use crate::error::{CliError, Outcome};
use crate::sim::{self, Request, SimError};
use std::path::PathBuf;

/// Run the delegation protocol in the deterministic simulator.
///
/// Both state machines exchange real MAVLink frames over modelled links
/// (latency, jitter, loss, bursts) on a virtual clock; every trial is
/// checked against the protocol's invariants (exit status 1 if any
/// breaks). Results depend only on the arguments and the seed.
#[derive(clap::Args)]
pub struct SimArgs {
    /// Reproduce the paper's Table I beside its figures.
    #[arg(long, conflicts_with_all = ["sweep", "scenario"])]
    pub table1: bool,
    /// Sweep loss 0–90 % for a scenario (default message-loss).
    #[arg(long)]
    pub sweep: bool,
    /// List the scenarios.
    #[arg(long)]
    pub list: bool,
    /// The scenario to run (see --list).
    #[arg(long, value_name = "NAME")]
    pub scenario: Option<String>,
    /// Share of frames lost in each direction, 0–1.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = args::share)]
    pub loss: f64,
    /// Bursty (Gilbert–Elliott) loss with bursts of this many frames on
    /// average (1–1,000,000), instead of independent loss.
    #[arg(long, value_name = "FRAMES", allow_hyphen_values = true, value_parser = args::burst)]
    pub burst: Option<f64>,
    /// Trials per row, 1–1,000,000 (default 10,000; 1,000 per sweep point).
    #[arg(long, allow_hyphen_values = true, value_parser = args::trials)]
    pub trials: Option<u32>,
    /// Seed of the first trial (trial k uses seed + k; at most
    /// 2^64 - 1,000,001).
    #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::sim_seed)]
    pub seed: u64,
    /// One JSON object per row.
    #[arg(long)]
    pub json: bool,
    /// With --sweep: write the chart (success rate and handover time
    /// against loss) as SVG.
    #[arg(long, value_name = "FILE", requires = "sweep")]
    pub svg: Option<PathBuf>,
    /// Check the protocol exhaustively instead (stateright, on the real
    /// nodes): every reachable state of each bounded world (docs/delegation.md,
    /// "Model-checked"); prints the states explored, the virtual time
    /// reached, the invariants checked and, for a violation, a
    /// counterexample as a timeline; exit status 1 on a violation. With
    /// --json the last line is one JSON object. About ten minutes.
    #[arg(long, conflicts_with_all = ["table1", "sweep", "scenario", "list"])]
    pub model_check: bool,
    /// With --model-check: the world to explore (repeat for several;
    /// default: every world of the default check). `quick` is the test
    /// command's, `all` every disturbance at once (with --depth).
    #[arg(long, value_name = "NAME", requires = "model_check")]
    pub world: Vec<String>,
    /// With --model-check: only the states within N steps of the start,
    /// breadth first, so that counterexamples are the shortest (default:
    /// every reachable state, depth first; --world all unless given).
    #[arg(long, value_name = "N", requires = "model_check", value_parser = clap::value_parser!(u16).range(1..=64))]
    pub depth: Option<u16>,
    /// With --model-check: stop each world at its first violation.
    #[arg(long, requires = "model_check")]
    pub stop_at_first: bool,
}

impl TryFrom<SimArgs> for Request {
    type Error = SimError;

    /// The first of: --model-check, --list, --table1, --sweep, --scenario.
    fn try_from(a: SimArgs) -> Result<Self, SimError> {
        let request = if a.model_check {
            let names = match (&a.world[..], a.depth) {
                ([], Some(_)) => vec!["all".to_string()],
                _ => a.world,
            };
            let worlds = names
                .iter()
                .map(|n| sim::world(n))
                .collect::<Result<Vec<_>, _>>()?;
            Request::ModelCheck {
                worlds,
                depth: a.depth.map(usize::from),
                stop_at_first: a.stop_at_first,
                json: a.json,
            }
        } else if a.list {
            Request::List
        } else if a.table1 {
            Request::Table1 {
                trials: a.trials.unwrap_or(10_000),
                seed: a.seed,
                json: a.json,
            }
        } else if a.sweep {
            Request::Sweep {
                scenario: sim::scenario(a.scenario.as_deref().unwrap_or("message-loss"))?,
                trials: a.trials.unwrap_or(1000),
                seed: a.seed,
                burst: a.burst,
                svg: a.svg,
                json: a.json,
            }
        } else {
            let name = a.scenario.as_deref().ok_or(SimError::NothingToRun)?;
            Request::Scenario {
                scenario: sim::scenario(name)?,
                loss: a.loss,
                burst: a.burst,
                trials: a.trials.unwrap_or(10_000),
                seed: a.seed,
                json: a.json,
            }
        };
        Ok(request)
    }
}

pub fn run(a: SimArgs) -> Result<Outcome, CliError> {
    match sim::run(Request::try_from(a)?) {
        // The run is done; what it found is a finding, as a model check's.
        Err(e @ SimError::Invariants(_)) => {
            eprintln!("{e}");
            Ok(Outcome::Flagged)
        }
        done => Ok(done?),
    }
}
