//! Many trials into rows: success rate, response percentiles, fallbacks,
//! false takeovers; Table I of the paper; loss sweeps as a table and SVG.

use super::{run, Outcome, Scenario, Trial, Violation};
use std::fmt::Write as _;
use std::time::Duration;

/// Aggregated trials of one scenario and link.
#[derive(Debug, Clone)]
pub struct Row {
    /// Scenario.
    pub scenario: Scenario,
    /// Loss rate of each link direction.
    pub loss: f64,
    /// Trials run.
    pub trials: u32,
    /// Trials meeting the scenario's success criterion.
    pub successes: u32,
    /// Trials with an RTL fallback.
    pub fallbacks: u32,
    /// Trials where companion control began where it must not.
    pub false_takeovers: u32,
    /// Response times of successful trials, sorted.
    pub responses: Vec<Duration>,
    /// The first broken invariants seen (must be empty), with their seed.
    pub violations: Vec<(u64, Violation)>,
    /// Frames sent in all trials.
    pub frames: u64,
}

impl Row {
    /// Share of successful trials.
    pub fn success_rate(&self) -> f64 {
        self.successes as f64 / self.trials.max(1) as f64
    }

    /// The `q` quantile of response times (nearest rank), in ms.
    pub fn quantile_ms(&self, q: f64) -> Option<f64> {
        if self.responses.is_empty() {
            return None;
        }
        let i =
            ((q * self.responses.len() as f64).ceil() as usize).clamp(1, self.responses.len()) - 1;
        Some(self.responses[i].as_secs_f64() * 1000.0)
    }

    /// Mean response time in ms.
    pub fn mean_ms(&self) -> Option<f64> {
        (!self.responses.is_empty()).then(|| {
            self.responses
                .iter()
                .map(Duration::as_secs_f64)
                .sum::<f64>()
                * 1000.0
                / self.responses.len() as f64
        })
    }

    /// One JSON object (the `--json` output of `fbwag sim`).
    pub fn json(&self) -> String {
        let num = |v: Option<f64>| v.map_or("null".to_string(), |v| format!("{v:.1}"));
        format!(
            "{{\"scenario\":\"{}\",\"loss\":{},\"trials\":{},\"success_rate\":{:.4},\"p50_ms\":{},\"p95_ms\":{},\"max_ms\":{},\"mean_ms\":{},\"fallbacks\":{},\"false_takeovers\":{},\"invariant_violations\":{},\"frames\":{}}}",
            self.scenario.name(),
            self.loss,
            self.trials,
            self.success_rate(),
            num(self.quantile_ms(0.5)),
            num(self.quantile_ms(0.95)),
            num(self.quantile_ms(1.0)),
            num(self.mean_ms()),
            self.fallbacks,
            self.false_takeovers,
            self.violations.len(),
            self.frames
        )
    }
}

/// Runs `trials` trials built by `make(seed)`, seeds `seed..seed+trials`,
/// on all cores; the result does not depend on the number of threads.
///
/// ```
/// use fbwag_delegation::sim::report::run_many;
/// use fbwag_delegation::sim::{Scenario, Trial};
///
/// let s = Scenario::MessageLoss;
/// let row = run_many(s, 0.5, 200, 1, |seed| Trial::new(s, 0.5, seed));
/// assert_eq!(row.false_takeovers, 0);
/// println!("{:.1} % handed over, p50 {:?} ms", row.success_rate() * 100.0, row.quantile_ms(0.5));
/// ```
pub fn run_many(
    scenario: Scenario,
    loss: f64,
    trials: u32,
    seed: u64,
    make: impl Fn(u64) -> Trial + Sync,
) -> Row {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(trials.max(1) as usize);
    let chunks: Vec<Vec<(u64, Outcome)>> = std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|w| {
                let make = &make;
                s.spawn(move || {
                    (0..trials as u64)
                        .filter(|i| (*i as usize) % threads == w)
                        .map(|i| (seed + i, run(&make(seed + i))))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        workers
            .into_iter()
            .map(|w| w.join().expect("trial thread panicked"))
            .collect()
    });
    let mut outcomes: Vec<(u64, Outcome)> = chunks.into_iter().flatten().collect();
    outcomes.sort_by_key(|(s, _)| *s);
    let mut row = Row {
        scenario,
        loss,
        trials,
        successes: 0,
        fallbacks: 0,
        false_takeovers: 0,
        responses: Vec::new(),
        violations: Vec::new(),
        frames: 0,
    };
    for (s, o) in outcomes {
        row.frames += o.frames;
        row.successes += u32::from(o.success);
        row.fallbacks += u32::from(o.fallback);
        row.false_takeovers += u32::from(o.false_takeover);
        if o.success {
            if let Some(r) = o.response {
                row.responses.push(r);
            }
        }
        for v in o.violations {
            if row.violations.len() < 10 {
                row.violations.push((s, v));
            }
        }
    }
    row.responses.sort();
    row
}

/// The rows of the paper's Table I, reproduced.
pub fn table1(trials: u32, seed: u64) -> Vec<Row> {
    [
        (Scenario::NormalRc, 0.0),
        (Scenario::RcLoss, 0.0),
        (Scenario::MessageLoss, 0.5),
        (Scenario::CcFailure, 0.0),
    ]
    .into_iter()
    .map(|(s, loss)| run_many(s, loss, trials, seed, |seed| Trial::new(s, loss, seed)))
    .collect()
}

/// Table I as text, beside the paper's figures (5 flights per test).
pub fn table1_text(rows: &[Row]) -> String {
    const PAPER: [(&str, &str, &str, &str); 4] = [
        (
            "Normal RC Operation",
            "100% (5/5)",
            "N/A",
            "Manual RC control",
        ),
        (
            "RC Loss → CC Takeover",
            "100% (5/5)",
            "0.3s",
            "CC controls UAV",
        ),
        (
            "Message Loss (Retry)",
            "80% (4/5)",
            "0.6s",
            "Retries up to 3 times, then RTL",
        ),
        (
            "CC Failure (Failsafe to RTL)",
            "100% (5/5)",
            "5s timeout",
            "RTL triggered",
        ),
    ];
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Table I reproduced: {} trials per row (paper: 5 flights per test)\n",
        rows.first().map_or(0, |r| r.trials)
    );
    let _ = writeln!(
        out,
        "{:<30} {:>11} {:>9} | {:>9} {:>9} {:>9} {:>9} | {:>10} {:>9} | backup behaviour (ours)",
        "test", "paper", "paper t", "success", "p50", "p95", "max", "fallbacks", "false TO",
    );
    for (row, paper) in rows.iter().zip(PAPER) {
        let ms = |v: Option<f64>| v.map_or("N/A".to_string(), |v| format!("{:.0} ms", v));
        let backup = match row.scenario {
            Scenario::NormalRc => "pilot keeps control; no notice sent",
            Scenario::RcLoss => "companion controls",
            Scenario::MessageLoss => "retries (at most 3), then RTL",
            _ => "RTL",
        };
        let _ = writeln!(
            out,
            "{:<30} {:>11} {:>9} | {:>8.2}% {:>9} {:>9} {:>9} | {:>10} {:>9} | {}",
            paper.0,
            paper.1,
            paper.2,
            row.success_rate() * 100.0,
            ms(row.quantile_ms(0.5)),
            ms(row.quantile_ms(0.95)),
            ms(row.quantile_ms(1.0)),
            row.fallbacks,
            row.false_takeovers,
            backup
        );
    }
    let _ = writeln!(
        out,
        "\nResponse time: RC loss (receiver failsafe) to companion control; for CC failure, to RTL.\nInvariant violations: {}.",
        rows.iter().map(|r| r.violations.len()).sum::<usize>()
    );
    out
}

/// How the frames of a [`sweep`]'s trials are lost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Losses {
    /// Each frame independently of the others.
    Independent,
    /// In bursts (Gilbert–Elliott, [`Trial::bursty`]) of `mean_burst`
    /// frames on average.
    Bursty {
        /// Mean burst length in frames.
        mean_burst: f64,
    },
}

/// Rows for loss rates 0 %, 10 %, … 90 % of one scenario.
pub fn sweep(scenario: Scenario, trials: u32, seed: u64, losses: Losses) -> Vec<Row> {
    (0..10)
        .map(|k| {
            let loss = k as f64 / 10.0;
            run_many(scenario, loss, trials, seed, |seed| {
                let t = Trial::new(scenario, loss, seed);
                match losses {
                    Losses::Bursty { mean_burst } => t.bursty(loss, mean_burst),
                    Losses::Independent => t,
                }
            })
        })
        .collect()
}

/// A sweep as a text table.
pub fn sweep_text(rows: &[Row]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:>6} {:>9} {:>9} {:>9} {:>9} {:>10} {:>9}",
        "loss", "success", "p50", "p95", "max", "fallbacks", "false TO"
    );
    for r in rows {
        let ms = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.0}"));
        let _ = writeln!(
            out,
            "{:>5.0}% {:>8.2}% {:>9} {:>9} {:>9} {:>10} {:>9}",
            r.loss * 100.0,
            r.success_rate() * 100.0,
            ms(r.quantile_ms(0.5)),
            ms(r.quantile_ms(0.95)),
            ms(r.quantile_ms(1.0)),
            r.fallbacks,
            r.false_takeovers
        );
    }
    out
}

/// A sweep as an SVG chart: success rate (left axis) and handover time p50
/// and p95 (right axis, ms) against loss.
pub fn sweep_svg(rows: &[Row], title: &str) -> String {
    let max_ms = rows
        .iter()
        .filter_map(|r| r.quantile_ms(0.95))
        .fold(1000.0f64, f64::max);
    let chart = Chart {
        max_ms: (max_ms / 1000.0).ceil() * 1000.0,
        ..Chart::default()
    };
    let mut s = String::new();
    chart.frame(&mut s, title);
    chart.grid(&mut s, rows);
    chart.axis_names(&mut s);
    chart.series(&mut s, rows);
    chart.legend(&mut s);
    s.push_str("</svg>\n");
    s
}

/// The geometry of [`sweep_svg`]'s chart.
struct Chart {
    w: f64,
    h: f64,
    left: f64,
    right: f64,
    top: f64,
    bottom: f64,
    /// The right axis' top, in ms.
    max_ms: f64,
}

impl Default for Chart {
    fn default() -> Self {
        Chart {
            w: 720.0,
            h: 420.0,
            left: 70.0,
            right: 70.0,
            top: 50.0,
            bottom: 60.0,
            max_ms: 1000.0,
        }
    }
}

impl Chart {
    fn pw(&self) -> f64 {
        self.w - self.left - self.right
    }

    fn ph(&self) -> f64 {
        self.h - self.top - self.bottom
    }

    fn x(&self, loss: f64) -> f64 {
        self.left + loss / 0.9 * self.pw()
    }

    fn y_rate(&self, rate: f64) -> f64 {
        self.top + (1.0 - rate) * self.ph()
    }

    fn y_ms(&self, ms: f64) -> f64 {
        self.top + (1.0 - ms / self.max_ms) * self.ph()
    }

    /// The document and its title.
    fn frame(&self, s: &mut String, title: &str) {
        let (w, h) = (self.w, self.h);
        let _ = writeln!(
            s,
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" font-family="sans-serif" font-size="12">"#
        );
        let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
        let _ = writeln!(
            s,
            r#"<text x="{}" y="24" text-anchor="middle" font-size="15">{title}</text>"#,
            w / 2.0
        );
    }

    /// The axes' names.
    fn axis_names(&self, s: &mut String) {
        let (w, h, top, ph) = (self.w, self.h, self.top, self.ph());
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">frame loss per direction</text>"#,
            self.left + self.pw() / 2.0,
            h - 16.0
        );
        let _ = writeln!(
            s,
            r#"<text x="16" y="{}" transform="rotate(-90 16 {})" text-anchor="middle">success within 5 s</text>"#,
            top + ph / 2.0,
            top + ph / 2.0
        );
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" transform="rotate(90 {} {})" text-anchor="middle">handover time (ms)</text>"#,
            w - 14.0,
            top + ph / 2.0,
            w - 14.0,
            top + ph / 2.0
        );
    }

    /// Grid lines with both axes' ticks, and the losses under the x axis.
    fn grid(&self, s: &mut String, rows: &[Row]) {
        let (left, pw, top, ph) = (self.left, self.pw(), self.top, self.ph());
        for k in 0..=10 {
            let yy = top + ph * k as f64 / 10.0;
            let _ = writeln!(
                s,
                r##"<line x1="{left}" y1="{yy}" x2="{}" y2="{yy}" stroke="#e4e4e4"/>"##,
                left + pw
            );
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}" text-anchor="end">{}%</text>"#,
                left - 6.0,
                yy + 4.0,
                100 - k * 10
            );
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}">{:.0}</text>"#,
                left + pw + 6.0,
                yy + 4.0,
                self.max_ms * (10 - k) as f64 / 10.0
            );
        }
        for r in rows {
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}" text-anchor="middle">{:.0}%</text>"#,
                self.x(r.loss),
                top + ph + 18.0,
                r.loss * 100.0
            );
        }
    }

    /// The success rate (with its points) and the handover p50 and p95.
    fn series(&self, s: &mut String, rows: &[Row]) {
        let rate = rows
            .iter()
            .map(|r| (self.x(r.loss), self.y_rate(r.success_rate())));
        let ms = |q: f64| {
            rows.iter()
                .filter_map(move |r| r.quantile_ms(q).map(|m| (self.x(r.loss), self.y_ms(m))))
        };
        polyline(s, rate.clone(), "#1f77b4", "");
        polyline(s, ms(0.5), "#d62728", "");
        polyline(s, ms(0.95), "#d62728", r#"stroke-dasharray="6 4""#);
        for (cx, cy) in rate {
            let _ = writeln!(
                s,
                r##"<circle cx="{cx:.1}" cy="{cy:.1}" r="3" fill="#1f77b4"/>"##
            );
        }
    }

    fn legend(&self, s: &mut String) {
        let legend = [
            ("#1f77b4", "", "success rate"),
            ("#d62728", "", "handover p50"),
            ("#d62728", r#"stroke-dasharray="6 4""#, "handover p95"),
        ];
        for (i, (c, dash, label)) in legend.iter().enumerate() {
            let ly = self.top + 14.0 + i as f64 * 16.0;
            let _ = writeln!(
                s,
                r#"<line x1="{}" y1="{ly}" x2="{}" y2="{ly}" stroke="{c}" stroke-width="2" {dash}/>"#,
                self.left + 12.0,
                self.left + 36.0
            );
            let _ = writeln!(
                s,
                r#"<text x="{}" y="{}">{label}</text>"#,
                self.left + 42.0,
                ly + 4.0
            );
        }
    }
}

/// A line through `points`.
fn polyline(s: &mut String, points: impl Iterator<Item = (f64, f64)>, color: &str, dash: &str) {
    let d: Vec<String> = points.map(|(a, b)| format!("{a:.1},{b:.1}")).collect();
    let _ = writeln!(
        s,
        r#"<polyline fill="none" stroke="{color}" stroke-width="2" {dash} points="{}"/>"#,
        d.join(" ")
    );
}
