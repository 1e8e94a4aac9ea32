//! Stream decode of the same telemetry capture by fbwag-dialect and by the
//! `mavlink` crate (0.21, ardupilotmega), in the same run: one field read
//! (`fbwag/views`: ATTITUDE's roll; the owned decoders: the message passed
//! by reference to `black_box`), and every field of every frame read
//! (`*_all`: each view accessor, arrays copied out; owned: the variant's
//! struct copied out, on both sides).

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
    // The every-field decoders have an arm for each of the capture's types:
    // they count every frame (mavlink: every frame it knows).
    assert_eq!(benches::fbwag_views_all(&stream), frames, "views_all arms");
    assert_eq!(benches::fbwag_owned_all(&stream), frames, "owned_all arms");
    assert_eq!(
        benches::mavlink_owned_all(&stream) + benches::count_notices(&stream),
        frames,
        "mavlink owned_all arms"
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
