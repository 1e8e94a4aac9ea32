//! Stream decode of the same telemetry capture by fbwag-dialect and by the
//! `mavlink` crate (0.21, ardupilotmega), in the same run.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::hint::black_box;

fn decode(c: &mut Criterion) {
    let stream = benches::telemetry();
    let frames = benches::fbwag_views(&stream);
    // The mavlink crate's ardupilotmega has no FBWAG_NOTICE: it skips those.
    assert_eq!(
        frames,
        benches::mavlink_raw(&stream) + benches::count_notices(&stream),
        "both decoders must see the same frames"
    );
    let mut g = c.benchmark_group("stream_decode");
    g.throughput(Throughput::Bytes(stream.len() as u64));
    g.sample_size(20);
    for (name, f) in benches::decoders() {
        g.bench_with_input(BenchmarkId::new(name, frames), &stream[..], |b, s| {
            b.iter(|| f(black_box(s)))
        });
    }
    g.finish();
}

criterion_group!(benches, decode);
criterion_main!(benches);
