//! The parser's worst inputs: measures the inputs of the `parser_worst`
//! benchmark, and searches for worse repeating patterns by hill climbing.
//!
//! ```sh
//! cargo run --release -p benches --example parser_worst -- measure [READS]
//! cargo run --release -p benches --example parser_worst -- ratio [ROUNDS] [READS]
//! cargo run --release -p benches --example parser_worst -- search steps|time [keyed] [SECONDS] [SEED] [reads=READS]
//! cargo run --release -p benches --example parser_worst -- mix [keyed] [SECONDS] [SEED]
//! cargo run --release -p benches --example parser_worst -- pattern HEX [READS]
//! cargo run --release -p benches --example parser_worst -- one NAME|hex:HEX [keyed] [passes=N] [chunk=N|datagram=N]
//! ```
//!
//! `measure` prints, per input: MB/s (best of 3 runs of 0.3 s, in CPU time: the time the
//! thread ran, so that waiting for a shared core does not count), the parser's work steps
//! and signature checks per byte ([`Parser::work`]). `search` climbs from
//! random and hand-made patterns (1–48 bytes, biased to start bytes and
//! small numbers), one byte changed, inserted, deleted or a stretch
//! duplicated per step, keeping changes that do not lower the score:
//! `steps` per byte (deterministic; signature checks weigh 64 steps each),
//! or `time` per byte (best of 3 runs). It prints the ten best patterns
//! with their MB/s. `mix` climbs the same way over random inputs instead:
//! bytes drawn independently from up to 8 values with weights (what a
//! repeating pattern cannot be: unpredictable for the branch predictor).
//!
//! [`Parser::work`]: fbwag_dialect::mavframe::parser::Parser::work

use benches::worst::{self, Reads};
use std::time::Instant;

/// Bytes of pattern pushed per evaluation.
const EVAL_LEN: usize = 32 * 1024;

/// CPU seconds of one timed run: `search`'s many evaluations...
const MIN_RUN: f64 = 0.04;

/// ...and `measure`'s figures (the clock may tick every few ms: a run of
/// 40 ms reads it to within 10 %).
const MEASURE_RUN: f64 = 0.3;

/// CPU seconds of each of `ratio`'s runs: many short rounds, interleaved.
const RATIO_RUN: f64 = 0.1;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn byte(&mut self) -> u8 {
        match self.below(10) {
            0..=2 => 0xFD,
            3..=5 => 0xFE,
            6 => 0x00,
            7 => 0x01,
            8 => self.below(16) as u8,
            _ => self.next() as u8,
        }
    }
}

/// Seconds this thread has run on a CPU (Linux), else since the first
/// call: on a shared machine, time spent waiting for a core is not the
/// parser's.
fn cpu_time() -> f64 {
    static START: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .map_or_else(
            || START.get_or_init(Instant::now).elapsed().as_secs_f64(),
            |ns| ns * 1e-9,
        )
}

/// (steps per byte, signatures per byte, CPU ns per byte, best of `runs`)
/// of `bytes`.
fn cost(bytes: &[u8], keyed: bool, reads: Reads, runs: usize) -> (f64, f64, f64) {
    cost_for(bytes, keyed, reads, runs, MIN_RUN)
}

/// [`cost`] with timed runs of at least `min_run` CPU seconds.
fn cost_for(bytes: &[u8], keyed: bool, reads: Reads, runs: usize, min_run: f64) -> (f64, f64, f64) {
    let mut best = f64::MAX;
    let mut work = Default::default();
    for _ in 0..runs {
        // Whole passes until the clock (ticks of a few ms) has moved well.
        let (t, mut passes) = (cpu_time(), 0u32);
        while passes == 0 || cpu_time() - t < min_run {
            let mut p = worst::parser(keyed);
            std::hint::black_box(worst::parse_reads(&mut p, bytes, reads));
            work = p.work();
            passes += 1;
        }
        best = best.min((cpu_time() - t) / f64::from(passes));
    }
    let n = bytes.len() as f64;
    (
        work.steps as f64 / n,
        work.signatures as f64 / n,
        best * 1e9 / n,
    )
}

fn score(pattern: &[u8], keyed: bool, by_time: bool, reads: Reads) -> f64 {
    let bytes = worst::repeat(pattern, EVAL_LEN);
    if by_time {
        cost(&bytes, keyed, reads, 3).2
    } else {
        let (steps, sigs, _) = cost(&bytes, keyed, reads, 1);
        steps + 64.0 * sigs
    }
}

fn mutate(p: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut q = p.to_vec();
    match rng.below(5) {
        0 | 1 => {
            let i = rng.below(q.len());
            q[i] = rng.byte();
        }
        2 if q.len() < 48 => q.insert(rng.below(q.len() + 1), rng.byte()),
        3 if q.len() > 1 => {
            q.remove(rng.below(q.len()));
        }
        _ if q.len() < 40 => {
            let a = rng.below(q.len());
            let b = (a + 1 + rng.below(4)).min(q.len());
            let piece = q[a..b].to_vec();
            let at = rng.below(q.len() + 1);
            q.splice(at..at, piece);
        }
        _ => {
            let i = rng.below(q.len());
            q[i] = rng.byte();
        }
    }
    q
}

fn search(by_time: bool, keyed: bool, seconds: f64, seed: u64, reads: Reads) {
    let mut rng = Rng(seed | 1);
    let seeds: Vec<Vec<u8>> = vec![
        worst::ISSUE_PATTERN.to_vec(),
        vec![0xFE],
        vec![0xFD],
        vec![0xFD, 0xFD, 0x01, 0x01],
        vec![0xFD, 0x01, 0x00],
        vec![0xFE, 0xFE, 0x00],
    ];
    let start = Instant::now();
    let mut best: Vec<(f64, Vec<u8>)> = Vec::new();
    let mut restart = 0;
    while start.elapsed().as_secs_f64() < seconds {
        let mut cur = match seeds.get(restart) {
            Some(s) => s.clone(),
            None => (0..1 + rng.below(16)).map(|_| rng.byte()).collect(),
        };
        restart += 1;
        let mut cur_score = score(&cur, keyed, by_time, reads);
        let mut stale = 0;
        while stale < 40 && start.elapsed().as_secs_f64() < seconds {
            let cand = mutate(&cur, &mut rng);
            let s = score(&cand, keyed, by_time, reads);
            if s >= cur_score {
                stale = if s > cur_score * 1.001 { 0 } else { stale + 1 };
                cur = cand;
                cur_score = s;
            } else {
                stale += 1;
            }
        }
        best.push((cur_score, cur));
        best.sort_by(|a, b| b.0.total_cmp(&a.0));
        best.dedup_by(|a, b| a.1 == b.1);
        best.truncate(10);
    }
    println!(
        "search by {} ({}, {reads}), {restart} climbs in {seconds} s; best patterns:",
        if by_time { "time" } else { "steps" },
        if keyed { "keyed, strict" } else { "no key" },
    );
    for (s, p) in &best {
        let (steps, sigs, ns) = cost(&worst::repeat(p, worst::INPUT_LEN), keyed, reads, 5);
        println!(
            "  score {s:9.2}  {:8.1} MB/s  steps/B {steps:6.2}  sigs/B {sigs:.4}  {}",
            1e3 / ns,
            hex(p)
        );
    }
}

/// `len` bytes drawn from `(value, weight)`s.
fn draw(mix: &[(u8, u32)], len: usize, seed: u64) -> Vec<u8> {
    let total: u32 = mix.iter().map(|m| m.1).sum::<u32>().max(1);
    let mut rng = Rng(seed | 1);
    (0..len)
        .map(|_| {
            let mut r = (rng.next() % u64::from(total)) as u32;
            for &(v, w) in mix {
                if r < w {
                    return v;
                }
                r -= w;
            }
            mix[0].0
        })
        .collect()
}

fn search_mix(keyed: bool, seconds: f64, seed: u64) {
    let mut rng = Rng(seed | 1);
    let start = Instant::now();
    let score = |mix: &[(u8, u32)]| {
        cost(
            &draw(mix, EVAL_LEN, 5),
            keyed,
            Reads::Stream(worst::CHUNK),
            3,
        )
        .2
    };
    let mut best: Vec<(f64, Vec<(u8, u32)>)> = Vec::new();
    let mut climbs = 0;
    while start.elapsed().as_secs_f64() < seconds {
        climbs += 1;
        let mut cur: Vec<(u8, u32)> = match climbs {
            1 => vec![(0xFD, 1), (0xFE, 1)],
            2 => vec![(0xFD, 1), (0xFE, 1), (0x00, 1), (0x01, 1)],
            _ => (0..2 + rng.below(6))
                .map(|_| (rng.byte(), 1 + rng.below(8) as u32))
                .collect(),
        };
        let mut cur_score = score(&cur);
        let mut stale = 0;
        while stale < 40 && start.elapsed().as_secs_f64() < seconds {
            let mut cand = cur.clone();
            let i = rng.below(cand.len());
            match rng.below(4) {
                0 => cand[i].0 = rng.byte(),
                1 => cand[i].1 = 1 + rng.below(16) as u32,
                2 if cand.len() < 8 => cand.push((rng.byte(), 1 + rng.below(8) as u32)),
                _ if cand.len() > 2 => {
                    cand.remove(i);
                }
                _ => cand[i].1 = 1 + rng.below(16) as u32,
            }
            let s = score(&cand);
            if s >= cur_score {
                stale = if s > cur_score * 1.01 { 0 } else { stale + 1 };
                (cur, cur_score) = (cand, s);
            } else {
                stale += 1;
            }
        }
        best.push((cur_score, cur));
        best.sort_by(|a, b| b.0.total_cmp(&a.0));
        best.truncate(10);
    }
    println!(
        "mix search ({}), {climbs} climbs in {seconds} s; worst mixes:",
        if keyed { "keyed, strict" } else { "no key" }
    );
    for (s, mix) in &best {
        let bytes = draw(mix, worst::INPUT_LEN, 9);
        let (steps, sigs, ns) = cost(&bytes, keyed, Reads::Stream(worst::CHUNK), 5);
        let desc: Vec<String> = mix.iter().map(|(v, w)| format!("{v:02x}x{w}")).collect();
        println!(
            "  score {s:7.2}  {:8.1} MB/s  steps/B {steps:6.2}  sigs/B {sigs:.4}  {}",
            1e3 / ns,
            desc.join(" ")
        );
    }
}

/// The bytes of a hex string (pairs of digits; anything else is an error).
/// A pattern given in hex (an even number of hex digits, at least two), or
/// a message and exit status 2.
fn unhex(s: &str) -> Vec<u8> {
    let digits: Option<Vec<u8>> = s.chars().map(|c| c.to_digit(16).map(|d| d as u8)).collect();
    match digits {
        Some(d) if !d.is_empty() && d.len() % 2 == 0 => {
            d.chunks_exact(2).map(|p| p[0] << 4 | p[1]).collect()
        }
        _ => {
            eprintln!("pattern {s:?}: expected an even number of hex digits, at least two");
            std::process::exit(2)
        }
    }
}

fn hex(p: &[u8]) -> String {
    p.iter().map(|b| format!("{b:02x}")).collect()
}

fn measure(reads: Reads) {
    println!(
        "Parser<fbwag_dialect::Dialect>: {} bytes",
        std::mem::size_of::<fbwag_dialect::mavframe::parser::Parser<fbwag_dialect::Dialect>>()
    );
    println!(
        "{:<28} {:>9} {:>8} {:>8}",
        "input", "MB/s", "steps/B", "sigs/B"
    );
    for (name, bytes, keyed) in worst::inputs() {
        for keyed in [keyed, true] {
            measure_row(&name, &bytes, keyed, reads);
        }
    }
}

/// One row of `measure`: MB/s, steps and signature checks per byte.
fn measure_row(name: &str, bytes: &[u8], keyed: bool, reads: Reads) {
    let (steps, sigs, ns) = cost_for(bytes, keyed, reads, 3, MEASURE_RUN);
    let policy = if keyed { "keyed" } else { "nokey" };
    println!(
        "{:<28} {:9.1} {steps:8.2} {sigs:8.4}",
        format!("{name}/{policy}"),
        1e3 / ns
    );
}

/// `ratio`: every input's speed against random bytes under the same
/// policy, from `rounds` rounds that each time every input once (so a
/// slow spell of a shared machine hits all of them alike); best time of
/// each input over the rounds.
fn ratio(rounds: usize, reads: Reads) {
    let rows: Vec<(String, Vec<u8>, bool)> = worst::inputs()
        .into_iter()
        .flat_map(|(name, bytes, keyed)| {
            let mut both = vec![(name.clone(), bytes.clone(), keyed)];
            if !keyed {
                both.push((name, bytes, true));
            }
            both
        })
        .collect();
    let mut best = vec![f64::MAX; rows.len()];
    for round in 0..rounds {
        eprint!("\rround {}/{rounds}", round + 1);
        for (row, (_, bytes, keyed)) in rows.iter().enumerate() {
            let (_, _, ns) = cost_for(bytes, *keyed, reads, 1, RATIO_RUN);
            best[row] = best[row].min(ns);
        }
    }
    eprintln!();
    let random = |keyed: bool| {
        rows.iter()
            .position(|(n, _, k)| n == "random" && *k == keyed)
            .map_or(f64::NAN, |i| best[i])
    };
    println!("({reads})");
    println!("{:<28} {:>9} {:>12}", "input", "MB/s", "x random");
    let mut worst_row = (0.0, String::new());
    for ((name, _, keyed), ns) in rows.iter().zip(&best) {
        let times = ns / random(*keyed);
        let label = format!("{name}/{}", if *keyed { "keyed" } else { "nokey" });
        println!("{label:<28} {:9.1} {times:12.1}", 1e3 / ns);
        if times > worst_row.0 {
            worst_row = (times, label);
        }
    }
    println!("worst: {} at {:.1}x random bytes", worst_row.1, worst_row.0);
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize| args.get(i).map(String::as_str);
    match arg(0) {
        Some("search") => {
            let by_time = arg(1) == Some("time");
            let keyed = args.iter().any(|a| a == "keyed");
            let nums: Vec<f64> = args.iter().filter_map(|a| a.parse().ok()).collect();
            let seconds = nums.first().copied().unwrap_or(60.0);
            let seed = nums.get(1).copied().unwrap_or(1.0) as u64;
            // reads=N or reads=dN: the reads to search in (default 64 KiB).
            let reads = args
                .iter()
                .find_map(|a| a.strip_prefix("reads=")?.parse().ok())
                .unwrap_or(Reads::Stream(worst::CHUNK));
            search(by_time, keyed, seconds, seed, reads);
        }
        Some("mix") => {
            let keyed = args.iter().any(|a| a == "keyed");
            let nums: Vec<f64> = args.iter().filter_map(|a| a.parse().ok()).collect();
            search_mix(
                keyed,
                nums.first().copied().unwrap_or(60.0),
                nums.get(1).copied().unwrap_or(1.0) as u64,
            );
        }
        Some("pattern") => {
            // One repeating pattern given in hex, with and without a key.
            let p = unhex(arg(1).unwrap_or("fe"));
            let bytes = worst::repeat(&p, worst::INPUT_LEN);
            let reads = arg(2)
                .and_then(|s| s.parse().ok())
                .unwrap_or(Reads::Stream(worst::CHUNK));
            for keyed in [false, true] {
                measure_row(&hex(&p), &bytes, keyed, reads);
            }
        }
        Some("one") => {
            // One input, many times: for a profiler.
            // (An input's name, or `hex:` and a pattern.)
            let name = arg(1).unwrap_or("issue_pattern");
            let keyed = args.iter().any(|a| a == "keyed");
            let bytes = match name.strip_prefix("hex:") {
                Some(p) => worst::repeat(&unhex(p), worst::INPUT_LEN),
                None => {
                    worst::inputs()
                        .into_iter()
                        .find(|(n, _, _)| n == name)
                        .unwrap_or_else(|| {
                            eprintln!("no input named {name:?} (see benches/src/worst.rs)");
                            std::process::exit(2)
                        })
                        .1
                }
            };
            let passes = args
                .iter()
                .find_map(|a| a.strip_prefix("passes=")?.parse().ok())
                .unwrap_or(20);
            // chunk=N: N-byte reads; datagram=N: N-byte datagrams.
            let reads = args
                .iter()
                .find_map(|a| {
                    let (key, n) = a.split_once('=')?;
                    let n = n.parse().ok()?;
                    match key {
                        "chunk" => Some(Reads::Stream(n)),
                        "datagram" => Some(Reads::Datagrams(n)),
                        _ => None,
                    }
                })
                .unwrap_or(Reads::Stream(worst::CHUNK));
            for _ in 0..passes {
                let mut p = worst::parser(keyed);
                std::hint::black_box(worst::parse_reads(&mut p, &bytes, reads));
            }
        }
        None | Some("measure") => measure(
            arg(1)
                .and_then(|s| s.parse().ok())
                .unwrap_or(Reads::Stream(worst::CHUNK)),
        ),
        Some("ratio") => {
            let rounds = arg(1).and_then(|s| s.parse().ok()).unwrap_or(5);
            ratio(
                rounds,
                arg(2)
                    .and_then(|s| s.parse().ok())
                    .unwrap_or(Reads::Stream(worst::CHUNK)),
            );
        }
        Some("-h" | "--help" | "help") => print!("{USAGE}"),
        Some(other) => {
            eprint!("unknown command {other:?}\n\n{USAGE}");
            std::process::exit(2);
        }
    }
}

/// What `--help` prints: the commands of the module documentation.
const USAGE: &str = "\
The parser's worst inputs: measure them, or search for worse ones.

usage: parser_worst [COMMAND] [ARGS]

  measure [READS]            MB/s (best of 3 runs of 0.3 s of CPU time), work steps and
                             signature checks per byte of every input of benches/src/worst.rs,
                             pushed as READS says (default 65536); the default command
  ratio [ROUNDS] [READS]     every input's time per byte against random bytes' (same policy),
                             best of ROUNDS (default 5) interleaved rounds of 0.1 s each
  search steps|time [keyed] [SECONDS] [SEED] [reads=READS]
                             hill-climb repeating patterns for the most work steps or time
                             per byte (default 60 s, seed 1, 64 KiB reads); prints the ten worst
  mix [keyed] [SECONDS] [SEED]
                             the same over random bytes drawn from weighted values
  pattern HEX [READS]        one repeating pattern, with and without a key
  one NAME|hex:HEX [keyed] [passes=N] [chunk=N|datagram=N]
                             parse one input N times (default 20), for valgrind or perf

READS: N for reads of N bytes from a stream (serial, TCP, a file), dN for datagrams of N
bytes (UDP: each parsed by next_in_datagram and ended by end_of_datagram).
`keyed`: the parser has a signing key and refuses unsigned frames.
";
