//! `fbwag sim`: the delegation protocol in the simulator.

use crate::error::Outcome;
use fbwag_delegation::sim::report::{self, Losses, Row};
use fbwag_delegation::sim::{Scenario, Trial};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `fbwag sim` was asked to do.
pub enum Request {
    /// Print the scenarios' names.
    List,
    /// The paper's Table I.
    Table1 { trials: u32, seed: u64, json: bool },
    /// A scenario over loss 0–90 %, and its chart.
    Sweep {
        scenario: Scenario,
        trials: u32,
        seed: u64,
        burst: Option<f64>,
        svg: Option<PathBuf>,
        json: bool,
    },
    /// One scenario at one loss.
    Scenario {
        scenario: Scenario,
        loss: f64,
        burst: Option<f64>,
        trials: u32,
        seed: u64,
        json: bool,
    },
    /// The exhaustive check of the real nodes, to `depth` steps.
    ModelCheck { depth: Option<usize>, json: bool },
}

/// Why `fbwag sim` could not do its work.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("unknown scenario `{name}`; one of: {}", scenario_names().join(", "))]
    UnknownScenario { name: String },
    #[error("say what to run: --table1, --sweep, or --scenario NAME (--list shows the names)")]
    NothingToRun,
    #[error("cannot write {}: {source}", path.display())]
    Chart {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Each broken invariant: scenario, seed, time and what broke.
    #[error("invariants broken:\n  {}", .0.join("\n  "))]
    Invariants(Vec<String>),
}

fn scenario_names() -> Vec<&'static str> {
    Scenario::ALL.iter().map(|s| s.name()).collect()
}

/// The scenario called `name`.
pub fn scenario(name: &str) -> Result<Scenario, SimError> {
    Scenario::from_name(name).ok_or_else(|| SimError::UnknownScenario { name: name.into() })
}

fn violations(rows: &[Row]) -> Result<(), SimError> {
    let broken: Vec<String> = rows
        .iter()
        .flat_map(|r| {
            r.violations.iter().map(move |(seed, v)| {
                format!(
                    "{} seed {seed} at {:?}: {}",
                    r.scenario.name(),
                    v.at,
                    v.what
                )
            })
        })
        .collect();
    if broken.is_empty() {
        Ok(())
    } else {
        Err(SimError::Invariants(broken))
    }
}

/// Runs `request`: [`Outcome::Flagged`] when the model check found a
/// violation; [`SimError::Invariants`] when a trial broke an invariant.
pub fn run(request: Request) -> Result<Outcome, SimError> {
    match request {
        Request::List => {
            for name in scenario_names() {
                println!("{name}");
            }
        }
        Request::Table1 { trials, seed, json } => table1(trials, seed, json)?,
        Request::Sweep {
            scenario,
            trials,
            seed,
            burst,
            svg,
            json,
        } => sweep(scenario, trials, seed, burst, svg.as_deref(), json)?,
        Request::Scenario {
            scenario,
            loss,
            burst,
            trials,
            seed,
            json,
        } => one_scenario(scenario, loss, burst, trials, seed, json)?,
        Request::ModelCheck { depth, json } => return Ok(model_check(depth, json)),
    }
    Ok(Outcome::Clean)
}

/// Rows as JSON lines, or as `text` renders them.
fn print_rows(rows: &[Row], json: bool, text: fn(&[Row]) -> String) {
    if json {
        for r in rows {
            println!("{}", r.json());
        }
    } else {
        print!("{}", text(rows));
    }
}

fn table1(trials: u32, seed: u64, json: bool) -> Result<(), SimError> {
    let started = Instant::now();
    eprintln!("running Table I: 4 rows × {trials} trials (seed {seed})…");
    let rows = report::table1(trials, seed);
    print_rows(&rows, json, report::table1_text);
    eprintln!("done in {:.1} s", started.elapsed().as_secs_f64());
    violations(&rows)
}

fn sweep(
    s: Scenario,
    trials: u32,
    seed: u64,
    burst: Option<f64>,
    svg: Option<&Path>,
    json: bool,
) -> Result<(), SimError> {
    let started = Instant::now();
    eprintln!(
        "sweeping {} over loss 0–90 % ({} loss): 10 rows × {trials} trials…",
        s.name(),
        if burst.is_some() {
            "bursty"
        } else {
            "independent"
        }
    );
    let losses = match burst {
        Some(mean_burst) => Losses::Bursty { mean_burst },
        None => Losses::Independent,
    };
    let rows = report::sweep(s, trials, seed, losses);
    print_rows(&rows, json, report::sweep_text);
    if let Some(path) = svg {
        let title = format!(
            "{}: success within 5 s and handover time vs frame loss ({trials} trials per point)",
            s.name()
        );
        std::fs::write(path, report::sweep_svg(&rows, &title)).map_err(|source| {
            SimError::Chart {
                path: path.to_owned(),
                source,
            }
        })?;
        eprintln!("chart written to {}", path.display());
    }
    eprintln!("done in {:.1} s", started.elapsed().as_secs_f64());
    violations(&rows)
}

fn one_scenario(
    s: Scenario,
    loss: f64,
    burst: Option<f64>,
    trials: u32,
    seed: u64,
    json: bool,
) -> Result<(), SimError> {
    let row = report::run_many(s, loss, trials, seed, |seed| {
        let t = Trial::new(s, loss, seed);
        match burst {
            Some(len) => t.bursty(loss, len),
            None => t,
        }
    });
    if json {
        println!("{}", row.json());
    } else {
        let ms = |v: Option<f64>| v.map_or("-".into(), |v| format!("{v:.0} ms"));
        println!(
            "{}: loss {:.0}%, {} trials: success {:.2}%, response p50 {} p95 {} max {}, fallbacks {}, false takeovers {}, invariant violations {}",
            s.name(),
            loss * 100.0,
            trials,
            row.success_rate() * 100.0,
            ms(row.quantile_ms(0.5)),
            ms(row.quantile_ms(0.95)),
            ms(row.quantile_ms(1.0)),
            row.fallbacks,
            row.false_takeovers,
            row.violations.len()
        );
    }
    violations(&[row])
}

/// `fbwag sim --model-check`: the exhaustive check of the real nodes
/// (fbwag-model), breadth first to `--depth`; exit status 1 when an
/// invariant is broken.
fn model_check(depth: Option<usize>, json: bool) -> Outcome {
    let mut opts = fbwag_model::CheckOptions::default();
    if let Some(d) = depth {
        opts.depth = d;
    }
    eprintln!(
        "model check: breadth first to depth {} on {} threads…",
        opts.depth, opts.threads
    );
    let report = fbwag_model::check(opts, |states, depth| {
        eprintln!("  {states} states, depth {depth}");
    });
    print_model_report(&report, json);
    Outcome::clean_if(report.violations.is_empty())
}

fn print_model_report(r: &fbwag_model::Report, json: bool) {
    let scope = if r.complete {
        format!("every state within {} steps", r.depth)
    } else {
        format!("stopped at the first violation, at depth {}", r.depth)
    };
    println!(
        "states explored: {} ({scope}; {} transitions), {:.1} s",
        r.states,
        r.generated,
        r.elapsed.as_secs_f64()
    );
    println!("invariants checked: {}", r.invariants.join(", "));
    let reached: Vec<String> = r
        .reached
        .iter()
        .map(|(name, steps)| format!("{name} ({steps} steps)"))
        .collect();
    println!("reached: {}", reached.join(", "));
    if r.violations.is_empty() {
        println!("violations: none");
    }
    for v in &r.violations {
        println!(
            "VIOLATION of {} (shortest counterexample, {} steps):",
            v.invariant, v.steps
        );
        for line in &v.trace {
            println!("  {line}");
        }
    }
    if json {
        println!("{}", model_report_json(r));
    }
}

/// The last line of `fbwag sim --model-check --json`.
fn model_report_json(r: &fbwag_model::Report) -> serde_json::Value {
    let violations: Vec<_> = r
        .violations
        .iter()
        .map(|v| {
            serde_json::json!({
                "invariant": v.invariant,
                "steps": v.steps,
                "trace": v.trace,
            })
        })
        .collect();
    serde_json::json!({
        "states": r.states,
        "generated": r.generated,
        "depth": r.depth,
        "complete": r.complete,
        "seconds": r.elapsed.as_secs_f64(),
        "invariants": r.invariants,
        "reached": r.reached.iter().map(|(n, steps)| serde_json::json!({"state": n, "steps": steps})).collect::<Vec<_>>(),
        "violations": violations,
    })
}
