//! `fbwag sim`: the delegation protocol in the simulator.

use fbwag_delegation::sim::report::{self, Losses, Row};
use fbwag_delegation::sim::{Scenario, Trial};
use std::path::PathBuf;
use std::time::Instant;

/// What `fbwag sim` was asked.
pub struct SimArgs {
    pub table1: bool,
    pub sweep: bool,
    pub list: bool,
    pub scenario: Option<String>,
    pub loss: f64,
    pub burst: Option<f64>,
    pub trials: Option<u32>,
    pub seed: u64,
    pub json: bool,
    pub svg: Option<PathBuf>,
    pub model_check: bool,
    pub depth: Option<usize>,
}

fn scenario(name: &str) -> Result<Scenario, String> {
    Scenario::from_name(name).ok_or_else(|| {
        let names: Vec<_> = Scenario::ALL.iter().map(|s| s.name()).collect();
        format!("unknown scenario `{name}`; one of: {}", names.join(", "))
    })
}

fn violations(rows: &[Row]) -> Result<(), String> {
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
        Err(format!("invariants broken:\n  {}", broken.join("\n  ")))
    }
}

pub fn run(a: SimArgs) -> Result<bool, String> {
    if a.model_check {
        return model_check(&a);
    }
    if a.list {
        for s in Scenario::ALL {
            println!("{}", s.name());
        }
        return Ok(true);
    }
    if !(0.0..=1.0).contains(&a.loss) {
        return Err(format!("--loss must be from 0 to 1, not {}", a.loss));
    }
    let started = Instant::now();
    if a.table1 {
        let trials = a.trials.unwrap_or(10_000);
        eprintln!(
            "running Table I: 4 rows × {trials} trials (seed {})…",
            a.seed
        );
        let rows = report::table1(trials, a.seed);
        if a.json {
            for r in &rows {
                println!("{}", r.json());
            }
        } else {
            print!("{}", report::table1_text(&rows));
        }
        eprintln!("done in {:.1} s", started.elapsed().as_secs_f64());
        violations(&rows)?;
        return Ok(true);
    }
    if a.sweep {
        let s = scenario(a.scenario.as_deref().unwrap_or("message-loss"))?;
        let trials = a.trials.unwrap_or(1000);
        eprintln!(
            "sweeping {} over loss 0–90 % ({} loss): 10 rows × {trials} trials…",
            s.name(),
            if a.burst.is_some() {
                "bursty"
            } else {
                "independent"
            }
        );
        let losses = match a.burst {
            Some(mean_burst) => Losses::Bursty { mean_burst },
            None => Losses::Independent,
        };
        let rows = report::sweep(s, trials, a.seed, losses);
        if a.json {
            for r in &rows {
                println!("{}", r.json());
            }
        } else {
            print!("{}", report::sweep_text(&rows));
        }
        if let Some(path) = &a.svg {
            let title = format!("{}: success within 5 s and handover time vs frame loss ({trials} trials per point)", s.name());
            std::fs::write(path, report::sweep_svg(&rows, &title))
                .map_err(|e| format!("cannot write {}: {e}", path.display()))?;
            eprintln!("chart written to {}", path.display());
        }
        eprintln!("done in {:.1} s", started.elapsed().as_secs_f64());
        violations(&rows)?;
        return Ok(true);
    }
    let Some(name) = a.scenario.as_deref() else {
        return Err(
            "say what to run: --table1, --sweep, or --scenario NAME (--list shows the names)"
                .into(),
        );
    };
    let s = scenario(name)?;
    let trials = a.trials.unwrap_or(10_000);
    let (loss, burst) = (a.loss, a.burst);
    let row = report::run_many(s, loss, trials, a.seed, |seed| {
        let t = Trial::new(s, loss, seed);
        match burst {
            Some(len) => t.bursty(loss, len),
            None => t,
        }
    });
    if a.json {
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
    violations(&[row])?;
    Ok(true)
}

/// `fbwag sim --model-check`: the exhaustive check of the real nodes
/// (fbwag-model), breadth first to `--depth`; exit status 1 when an
/// invariant is broken.
fn model_check(a: &SimArgs) -> Result<bool, String> {
    let mut opts = fbwag_model::CheckOptions::default();
    if let Some(d) = a.depth {
        opts.depth = d;
    }
    eprintln!(
        "model check: breadth first to depth {} on {} threads…",
        opts.depth, opts.threads
    );
    let report = fbwag_model::check(opts, |states, depth| {
        eprintln!("  {states} states, depth {depth}");
    });
    print_model_report(&report, a.json);
    Ok(report.violations.is_empty())
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
        let line = serde_json::json!({
            "states": r.states,
            "generated": r.generated,
            "depth": r.depth,
            "complete": r.complete,
            "seconds": r.elapsed.as_secs_f64(),
            "invariants": r.invariants,
            "reached": r.reached.iter().map(|(n, steps)| serde_json::json!({"state": n, "steps": steps})).collect::<Vec<_>>(),
            "violations": violations,
        });
        println!("{line}");
    }
}
