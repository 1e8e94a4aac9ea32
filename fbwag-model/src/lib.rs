//! An exhaustive model check of the FBWAG RC-loss delegation protocol with
//! [stateright](https://docs.rs/stateright), driving the real sans-IO nodes
//! of `fbwag-delegation` ([`FcNode`], [`CompanionNode`]): no copy of their
//! logic. The world around them (a lossy, reordering, duplicating link of
//! real signed MAVLink bytes, the pilot's receiver, restarts, a stranger
//! without the key who forges and replays, the companion's autonomy, the
//! virtual clock) is the model's; every decision is the nodes'.
//! `docs/delegation.md`, section "Model-checked", states the invariants
//! and the bounds.
//!
//! Start with [`check`]: [`CheckOptions`] bound the world
//! ([`ModelConfig`]) and, if asked, the search's depth; without a depth the
//! search runs to its fixpoint, every reachable state of the bounded world
//! (a state is identified with every time counted from now: see
//! [`state`]). The [`Report`] lists every invariant broken with its
//! shortest counterexample. A [`ModelConfig::for_fault`] plants a known
//! bug, which the check must find.
//!
//! ```
//! use fbwag_model::{check, CheckOptions};
//!
//! // Every state within three actions of the start (the command line's
//! // `fbwag sim --model-check` explores every reachable state).
//! let report = check(CheckOptions { depth: Some(3), ..CheckOptions::default() }, |_, _| {});
//! assert!(report.complete);
//! assert!(report.violations.is_empty(), "{:?}", report.violations);
//! assert!(report.states > 1 && !report.invariants.is_empty());
//! ```
//!
//! [`FcNode`]: fbwag_delegation::node::FcNode
//! [`CompanionNode`]: fbwag_delegation::node::CompanionNode

mod check;
pub mod model;
pub mod props;
pub mod setup;
pub mod state;
pub mod wire;
pub mod worlds;

pub use model::{Action, DelegationModel, Forgery};
pub use props::{Invariant, Reach, INVARIANTS};
pub use setup::{Fault, ModelConfig};
pub use state::State;
pub use worlds::World;

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
    /// Distinct states explored, each checked against every invariant.
    pub states: usize,
    /// Transitions evaluated (successors generated, repeats included).
    pub generated: usize,
    /// Steps from the initial state to the deepest states explored.
    pub depth: usize,
    /// The search explored every state it was asked to: every reachable
    /// one (a fixpoint: [`Report::fixpoint`]), or every one within its
    /// depth (false when it stopped at its first violation).
    pub complete: bool,
    /// The search ran without a depth bound to its end, never cut by the
    /// world's horizon: every reachable state of the bounded world was
    /// explored.
    pub fixpoint: bool,
    /// A state past the world's horizon ([`ModelConfig::horizon`]) was
    /// left out: time went on further than any rule needs.
    pub cut: bool,
    /// The latest virtual time of a state explored.
    pub virtual_time: Duration,
    /// The invariants checked, by name.
    pub invariants: Vec<&'static str>,
    /// Counterexamples, one per invariant broken.
    pub violations: Vec<Violation>,
    /// Each situation of [`Reach`] the search reached, with the fewest
    /// steps to it.
    pub reached: Vec<(&'static str, usize)>,
    /// Wall time.
    pub elapsed: Duration,
}

/// How to run a check.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CheckOptions {
    /// The world's bounds and the planted fault.
    pub model: ModelConfig,
    /// Levels of a breadth-first search (actions from the start), whose
    /// counterexamples are the shortest; `None`: to the fixpoint, depth
    /// first (a counterexample is then one path, not the shortest).
    pub depth: Option<usize>,
    /// Checker threads.
    pub threads: usize,
    /// Stop at the first violation.
    pub stop_at_first: bool,
}

impl Default for CheckOptions {
    fn default() -> Self {
        CheckOptions {
            model: ModelConfig::default(),
            depth: None,
            threads: 2,
            stop_at_first: false,
        }
    }
}

/// Runs the check; `progress` is called about every second with the
/// states explored so far and the depth reached.
pub fn check(opts: CheckOptions, progress: impl FnMut(usize, usize)) -> Report {
    check_model(DelegationModel::new(opts.model), opts, progress)
}

/// [`check`] with the nodes' settings of `model` (`opts.model` is not
/// read): to check other settings of the product.
pub fn check_model(
    model: DelegationModel,
    opts: CheckOptions,
    progress: impl FnMut(usize, usize),
) -> Report {
    let started = std::time::Instant::now();
    let mut builder = model.clone().checker().threads(opts.threads.max(1));
    if let Some(depth) = opts.depth {
        // stateright counts the initial state as depth 1 and does not
        // evaluate the states at the target depth.
        builder = builder.target_max_depth(depth + 2);
    }
    if opts.stop_at_first {
        let invariants = INVARIANTS.iter().map(|i| i.name()).collect();
        builder = builder.finish_when(HasDiscoveries::AnyOf(invariants));
    }
    // To a fixpoint, depth first: the checker then keeps the states'
    // identities, not the states (a node is 36 KB), so memory stays small.
    if opts.depth.is_some() {
        finish(builder.spawn_bfs(), &model, &opts, progress, started)
    } else {
        finish(builder.spawn_dfs(), &model, &opts, progress, started)
    }
}

/// [`check`] of world `w` (its bounds and settings; `opts.model` is not
/// read).
pub fn check_world(w: &World, opts: CheckOptions, progress: impl FnMut(usize, usize)) -> Report {
    let opts = CheckOptions {
        model: w.bounds,
        ..opts
    };
    check_model(w.model(), opts, progress)
}

/// Waits for `checker`, then reports what it found.
fn finish(
    checker: impl Checker<DelegationModel>,
    model: &DelegationModel,
    opts: &CheckOptions,
    mut progress: impl FnMut(usize, usize),
    started: std::time::Instant,
) -> Report {
    let mut last = std::time::Instant::now();
    while !checker.is_done() {
        std::thread::sleep(Duration::from_millis(50));
        if last.elapsed() >= Duration::from_secs(1) {
            let explored = model.checked.load(Ordering::Relaxed);
            progress(explored, checker.max_depth().saturating_sub(1));
            last = std::time::Instant::now();
        }
    }
    let checker = checker.join();
    let mut violations: Vec<Violation> = checker
        .discoveries()
        .into_iter()
        .map(|(name, path)| {
            let steps = path.into_vec();
            Violation {
                invariant: name,
                steps: steps.len().saturating_sub(1),
                trace: timeline(model, steps),
            }
        })
        .collect();
    violations.sort_by_key(|v| (v.steps, v.invariant));
    let reached = Reach::ALL
        .iter()
        .filter_map(|r| {
            let steps = model.reached[*r as usize].load(Ordering::Relaxed);
            (steps != usize::MAX).then_some((r.name(), steps))
        })
        .collect();
    let complete = !opts.stop_at_first || violations.is_empty();
    let depth = checker.max_depth().saturating_sub(1);
    let cut = model.cut.load(Ordering::Relaxed);
    Report {
        states: model.checked.load(Ordering::Relaxed),
        generated: checker.state_count(),
        depth,
        complete,
        fixpoint: complete && opts.depth.is_none() && !cut,
        cut,
        virtual_time: Duration::from_micros(model.latest.load(Ordering::Relaxed)),
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
        let at = format!("t={:.3}", (state.now.0 as f64) / 1e6);
        let mut got = log.unwrap_or_default();
        if got.is_empty() {
            got.push(format!("{at} model: {action:?}"));
        }
        lines.extend(got);
    }
    lines
}
