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
    /// The exhaustive check of the real nodes: each of `worlds` (none: the
    /// default check's), to `depth` steps or to its fixpoint.
    ModelCheck {
        worlds: Vec<fbwag_model::World>,
        depth: Option<usize>,
        stop_at_first: bool,
        json: bool,
    },
}

/// Why `fbwag sim` could not do its work.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("unknown scenario `{name}`; one of: {}", scenario_names().join(", "))]
    UnknownScenario { name: String },
    #[error("unknown world `{name}`; one of: {}", fbwag_model::worlds::names().join(", "))]
    UnknownWorld { name: String },
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

/// The model check's world called `name`.
pub fn world(name: &str) -> Result<fbwag_model::World, SimError> {
    fbwag_model::worlds::by_name(name).ok_or_else(|| SimError::UnknownWorld { name: name.into() })
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
        Request::ModelCheck {
            worlds,
            depth,
            stop_at_first,
            json,
        } => return Ok(model_check(worlds, depth, stop_at_first, json)),
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
/// (fbwag-model), world by world, each to `depth` or to its fixpoint;
/// exit status 1 when an invariant is broken.
fn model_check(
    worlds: Vec<fbwag_model::World>,
    depth: Option<usize>,
    stop_at_first: bool,
    json: bool,
) -> Outcome {
    let worlds = if worlds.is_empty() {
        fbwag_model::worlds::default_worlds()
    } else {
        worlds
    };
    let opts = fbwag_model::CheckOptions {
        depth,
        stop_at_first,
        ..fbwag_model::CheckOptions::default()
    };
    let scope = match depth {
        Some(d) => format!("breadth first to depth {d}"),
        None => "depth first, every reachable state".into(),
    };
    let mut reports = Vec::new();
    for w in &worlds {
        eprintln!(
            "model check of world {} ({}): {scope}, on {} threads…",
            w.name, w.purpose, opts.threads
        );
        let report = fbwag_model::check_world(w, opts, |states, depth| {
            eprintln!("  {states} states, depth {depth}");
        });
        print_world(w.name, &report);
        reports.push((w.name, report));
    }
    // A search cut at its horizon is a failure too: some state kept time
    // going past every rule (a retry without end).
    let clean = reports
        .iter()
        .all(|(_, r)| r.violations.is_empty() && !r.cut);
    print_summary(&reports);
    if json {
        println!("{}", model_report_json(&reports));
    }
    Outcome::clean_if(clean)
}

fn print_world(name: &str, r: &fbwag_model::Report) {
    let scope = if r.fixpoint {
        format!("every reachable state, {} steps deep", r.depth)
    } else if r.cut {
        "CUT at the world's horizon: time went on past every rule, no fixpoint".to_string()
    } else if r.complete {
        format!("every state within {} steps", r.depth)
    } else {
        format!("stopped at the first violation, at depth {}", r.depth)
    };
    println!(
        "world {name}: {} states ({scope}; {} transitions; virtual time to {:.1} s), {:.1} s",
        r.states,
        r.generated,
        r.virtual_time.as_secs_f64(),
        r.elapsed.as_secs_f64()
    );
    for v in &r.violations {
        println!(
            "VIOLATION of {} in world {name} (counterexample, {} steps):",
            v.invariant, v.steps
        );
        for line in &v.trace {
            println!("  {line}");
        }
    }
}

fn print_summary(reports: &[(&str, fbwag_model::Report)]) {
    let invariants = reports.first().map(|(_, r)| r.invariants.join(", "));
    println!("invariants checked: {}", invariants.unwrap_or_default());
    let reached: Vec<String> = reached(reports)
        .iter()
        .map(|(name, steps)| format!("{name} ({steps} steps)"))
        .collect();
    println!("reached: {}", reached.join(", "));
    if reports.iter().all(|(_, r)| r.violations.is_empty()) {
        println!("violations: none");
    }
}

/// Each situation any world reached, with the fewest steps to it.
fn reached(reports: &[(&str, fbwag_model::Report)]) -> Vec<(&'static str, usize)> {
    let mut reached: Vec<(&'static str, usize)> = Vec::new();
    for (_, r) in reports {
        for &(name, steps) in &r.reached {
            match reached.iter_mut().find(|(n, _)| *n == name) {
                Some(seen) => seen.1 = seen.1.min(steps),
                None => reached.push((name, steps)),
            }
        }
    }
    reached
}

/// The last line of `fbwag sim --model-check --json`: totals over the
/// worlds, then each world.
fn model_report_json(reports: &[(&str, fbwag_model::Report)]) -> serde_json::Value {
    let violations: Vec<_> = reports
        .iter()
        .flat_map(|(world, r)| {
            r.violations.iter().map(move |v| {
                serde_json::json!({
                    "world": world,
                    "invariant": v.invariant,
                    "steps": v.steps,
                    "trace": v.trace,
                })
            })
        })
        .collect();
    let sum =
        |f: fn(&fbwag_model::Report) -> usize| reports.iter().map(|(_, r)| f(r)).sum::<usize>();
    let reached = reached(reports);
    let worlds: Vec<_> = reports
        .iter()
        .map(|(name, r)| {
            serde_json::json!({
                "world": name,
                "states": r.states,
                "generated": r.generated,
                "depth": r.depth,
                "complete": r.complete,
                "fixpoint": r.fixpoint,
                "cut": r.cut,
                "virtual_seconds": r.virtual_time.as_secs_f64(),
                "seconds": r.elapsed.as_secs_f64(),
            })
        })
        .collect();
    let invariants = reports
        .first()
        .map(|(_, r)| r.invariants.clone())
        .unwrap_or_default();
    serde_json::json!({
        "states": sum(|r| r.states),
        "generated": sum(|r| r.generated),
        "depth": reports.iter().map(|(_, r)| r.depth).max().unwrap_or(0),
        "complete": reports.iter().all(|(_, r)| r.complete),
        "fixpoint": reports.iter().all(|(_, r)| r.fixpoint),
        "virtual_seconds": reports.iter().map(|(_, r)| r.virtual_time.as_secs_f64()).fold(0.0, f64::max),
        "seconds": reports.iter().map(|(_, r)| r.elapsed.as_secs_f64()).sum::<f64>(),
        "invariants": invariants,
        "reached": reached.iter().map(|(n, steps)| serde_json::json!({"state": n, "steps": steps})).collect::<Vec<_>>(),
        "worlds": worlds,
        "violations": violations,
    })
}
