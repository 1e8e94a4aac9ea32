//! The parser's throughput on adversarial input next to random bytes
//! (the target: the worst case within 10× of random bytes): MB/s of
//! `Parser::next` over the inputs of `benches::worst` (random bytes,
//! garbage dense in start bytes, `issue_pattern`, the worst patterns
//! `examples/parser_worst.rs` found), in 64 KiB chunks as `fbwag decode`
//! reads, and byte by byte (every candidate then spans calls).

use benches::worst;
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use std::time::Duration;

fn parser_worst(c: &mut Criterion) {
    let mut g = c.benchmark_group("parser_worst");
    g.sample_size(10);
    g.warm_up_time(Duration::from_millis(500));
    g.measurement_time(Duration::from_secs(2));
    for (name, bytes, keyed) in worst::inputs() {
        let policy = if keyed { "keyed" } else { "nokey" };
        for (chunking, chunk) in [("64k", worst::CHUNK), ("1b", 1)] {
            // Byte by byte only where it adds something (it is slow for all).
            if chunk == 1 && !matches!(name.as_str(), "random" | "issue_pattern" | "dense_fd_fe") {
                continue;
            }
            let data = &bytes[..if chunk == 1 {
                bytes.len() / 4
            } else {
                bytes.len()
            }];
            g.throughput(Throughput::Bytes(data.len() as u64));
            let id = BenchmarkId::new(format!("{name}/{policy}"), chunking);
            g.bench_with_input(id, data, |b, data| {
                b.iter(|| {
                    let mut p = worst::parser(keyed);
                    worst::parse(&mut p, black_box(data), chunk)
                })
            });
        }
    }
    g.finish();
}

criterion_group!(benches, parser_worst);
criterion_main!(benches);
