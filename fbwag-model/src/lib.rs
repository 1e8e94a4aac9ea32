//! An exhaustive model check of the FBWAG RC-loss delegation protocol with
//! [stateright](https://docs.rs/stateright), driving the real sans-IO nodes
//! of `fbwag-delegation` ([`FcNode`], [`CompanionNode`]): no copy of their
//! logic. The world around them (a lossy, reordering, duplicating link of
//! real signed MAVLink bytes, the pilot's receiver, restarts, a stranger
//! without the key, the companion's autonomy, the virtual clock) is the
//! model's; every decision is the nodes'. `docs/delegation.md`, section
//! "Model-checked", states the invariants and the bounds.
//!
//! Start with [`check`]: [`CheckOptions`] bound the world
//! ([`ModelConfig`]) and the search's depth, and the [`Report`] lists
//! every invariant broken with its shortest counterexample. A
//! [`ModelConfig::for_fault`] plants a known bug, which the check must find.
//!
//! ```
//! use fbwag_model::{check, CheckOptions};
//!
//! // Every state within three actions of the start (the command line's
//! // `fbwag sim --model-check` goes deeper: `DEFAULT_DEPTH`).
//! let report = check(CheckOptions { depth: 3, ..CheckOptions::default() }, |_, _| {});
//! assert!(report.complete);
//! assert!(report.violations.is_empty(), "{:?}", report.violations);
//! assert!(report.states > 1 && !report.invariants.is_empty());
//! ```
//!
//! [`FcNode`]: fbwag_delegation::node::FcNode
//! [`CompanionNode`]: fbwag_delegation::node::CompanionNode

pub mod model;
pub mod props;
pub mod setup;
pub mod state;
pub mod wire;

pub use model::{Action, DelegationModel, Forgery};
pub use props::{Invariant, INVARIANTS, REACHES};
pub use setup::{Fault, ModelConfig};
pub use state::State;

use stateright::{Checker, HasDiscoveries, Model};
use std::sync::atomic::Ordering;
use std::time::Duration;

/// A counterexample: the invariant and the shortest path breaking it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Violation {
    /// The invariant's name.
    pub invariant: &'static str,
    /// The steps (actions) from the initial state.
    pub steps: usize,
    /// The timeline of the path, one line per event (`t=... FC: ...`).
    pub trace: Vec<String>,
}

/// What a check found.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Report {
    /// Distinct states explored: each reached within `depth` steps, and
    /// checked against every invariant.
    pub states: usize,
    /// Transitions evaluated (successors generated, repeats and the
    /// unexplored level past `depth` included).
    pub generated: usize,
    /// Steps from the initial state to the deepest states explored.
    pub depth: usize,
    /// Every state within `depth` steps was explored (false when the
    /// search stopped at its first violation).
    pub complete: bool,
    /// The invariants checked, by name.
    pub invariants: Vec<&'static str>,
    /// Counterexamples, one per invariant broken.
    pub violations: Vec<Violation>,
    /// Each state of [`REACHES`] the search reached, with the length of
    /// the shortest path to it.
    pub reached: Vec<(&'static str, usize)>,
    /// Wall time.
    pub elapsed: Duration,
}

/// How to run a check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CheckOptions {
    /// The world's bounds and the planted fault.
    pub model: ModelConfig,
    /// Levels of the breadth-first search (actions from the start).
    pub depth: usize,
    /// Checker threads.
    pub threads: usize,
    /// Stop at the first violation (its counterexample is still the
    /// shortest: the search is breadth first).
    pub stop_at_first: bool,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            model: ModelConfig::default(),
            depth: DEFAULT_DEPTH,
            threads: 2,
            stop_at_first: false,
        }
    }
}

/// The default depth of `fbwag sim --model-check`.
pub const DEFAULT_DEPTH: usize = 8;

/// Runs the breadth-first check; `progress` is called about every second
/// with the states generated so far and the depth reached.
pub fn check(opts: CheckOptions, progress: impl FnMut(usize, usize)) -> Report {
    check_model(DelegationModel::new(opts.model), opts, progress)
}

/// [`check`] with the nodes' settings of `model` (`opts.model` is not
/// read): to check other settings of the product.
pub fn check_model(
    model: DelegationModel,
    opts: CheckOptions,
    mut progress: impl FnMut(usize, usize),
) -> Report {
    let started = std::time::Instant::now();
    let mut builder = model
        .clone()
        .checker()
        .threads(opts.threads.max(1))
        // stateright counts the initial state as depth 1 and does not
        // evaluate the states at the target depth.
        .target_max_depth(opts.depth + 2);
    if opts.stop_at_first {
        let invariants = INVARIANTS.iter().map(|i| i.name()).collect();
        builder = builder.finish_when(HasDiscoveries::AnyOf(invariants));
    }
    let checker = builder.spawn_bfs();
    let mut last = std::time::Instant::now();
    while !checker.is_done() {
        std::thread::sleep(Duration::from_millis(50));
        if last.elapsed() >= Duration::from_secs(1) {
            let explored = model.checked.load(Ordering::Relaxed);
            progress(explored, checker.max_depth().saturating_sub(2));
            last = std::time::Instant::now();
        }
    }
    let checker = checker.join();
    let discoveries = checker.discoveries();
    let mut reached: Vec<(&'static str, usize)> = discoveries
        .iter()
        .filter(|(name, _)| REACHES.contains(name))
        .map(|(name, path)| (*name, path.clone().into_actions().len()))
        .collect();
    reached.sort();
    let mut violations: Vec<Violation> = discoveries
        .into_iter()
        .filter(|(name, _)| !REACHES.contains(name))
        .map(|(name, path)| {
            let steps = path.into_vec();
            Violation {
                invariant: name,
                steps: steps.len().saturating_sub(1),
                trace: timeline(&model, steps),
            }
        })
        .collect();
    violations.sort_by_key(|v| (v.steps, v.invariant));
    Report {
        states: model.checked.load(Ordering::Relaxed),
        generated: checker.state_count(),
        depth: checker.max_depth().saturating_sub(2),
        complete: !opts.stop_at_first || violations.is_empty(),
        invariants: INVARIANTS.iter().map(|i| i.name()).collect(),
        violations,
        reached,
        elapsed: started.elapsed(),
    }
}

/// Replays a path, writing what happened at each step.
fn timeline(model: &DelegationModel, steps: Vec<(State, Option<Action>)>) -> Vec<String> {
    let mut lines = Vec::new();
    for (state, action) in steps {
        let Some(action) = action else { continue };
        let mut log = Some(Vec::new());
        let _ = model.step(&state, action, &mut log);
        let at = format!("t={:.3}", state.now.0 as f64 / 1e6);
        let mut got = log.unwrap_or_default();
        if got.is_empty() {
            got.push(format!("{at} model: {action:?}"));
        }
        lines.extend(got);
    }
    lines
}
