//! Times the stream decoders of the `decode` benchmark outside criterion, in
//! the format of `benches/c/parse_stream.c`, so `benches/scripts/compare.sh`
//! can put them next to the C library and pymavlink in one run; also the
//! program to profile:
//!
//! ```sh
//! cargo run --release -p benches --example stream_decode -- [CAPTURE] [ITERATIONS] [DECODER...]
//! CARGO_PROFILE_RELEASE_DEBUG=true cargo build --release -p benches --example stream_decode
//! perf record target/release/examples/stream_decode - 200 fbwag/views
//! valgrind --tool=callgrind target/release/examples/stream_decode - 3 fbwag/owned
//! ```
//!
//! CAPTURE `-` (the default) is the telemetry capture of the benchmarks.
//! Decoders: `fbwag/views`, `mavlink/raw`, `fbwag/owned`, `mavlink/owned`
//! (one field read), `fbwag/views_all`, `fbwag/owned_all`,
//! `mavlink/owned_all` (every field read); all by default, interleaved pass
//! by pass. `BENCH_MIX=legacy` selects the older capture. The owned-decode
//! prototypes `proto/owned_typed` and `proto/owned_slot` run when named. Prints, per decoder:
//! `NAME frames N bytes B best_mibs X median_mibs Y`.

use std::time::Instant;

fn main() {
    let mut args = std::env::args().skip(1);
    let stream = match args.next().as_deref() {
        None | Some("-") => benches::telemetry(),
        Some(path) => std::fs::read(path).unwrap_or_else(|e| panic!("{path}: {e}")),
    };
    let iters: usize = args.next().map_or(20, |s| s.parse().expect("iterations"));
    let wanted: Vec<String> = args.collect();
    // The prototypes run only when named.
    let decoders: Vec<_> = benches::decoders()
        .into_iter()
        .filter(|(name, _)| wanted.is_empty() || wanted.iter().any(|w| w == name))
        .chain(
            benches::prototypes()
                .into_iter()
                .filter(|(name, _)| wanted.iter().any(|w| w == name)),
        )
        .collect();
    assert!(!decoders.is_empty(), "unknown decoder in {wanted:?}");
    let mut secs = vec![Vec::with_capacity(iters); decoders.len()];
    let mut frames = vec![0; decoders.len()];
    for _ in 0..iters.max(1) {
        for (i, (_, f)) in decoders.iter().enumerate() {
            let t = Instant::now();
            frames[i] = f(std::hint::black_box(&stream));
            secs[i].push(t.elapsed().as_secs_f64());
        }
    }
    let mib = stream.len() as f64 / f64::from(1 << 20);
    for (i, (name, _)) in decoders.iter().enumerate() {
        let s = &mut secs[i];
        s.sort_by(f64::total_cmp);
        println!(
            "{name} frames {} bytes {} best_mibs {:.1} median_mibs {:.1}",
            frames[i],
            stream.len(),
            mib / s[0],
            mib / s[s.len() / 2]
        );
    }
}
