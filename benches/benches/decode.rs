//! Stream decode of the same telemetry capture by fbwag-dialect and by the
//! `mavlink` crate (0.21, ardupilotmega), in the same run.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use fbwag_dialect::mavwire::parser::Parser;
use fbwag_dialect::{Dialect, MessageView};
use mavlink::dialects::ardupilotmega::MavMessage;
use std::hint::black_box;

fn ours_views(stream: &[u8]) -> usize {
    let mut parser = Parser::<Dialect>::new();
    let mut input = stream;
    let mut n = 0;
    while let Some(r) = parser.next(&mut input) {
        // A view is a pointer and a length; reading one field makes it real.
        if let Some(MessageView::Attitude(a)) = r.view() {
            black_box(a.roll());
        }
        n += 1;
    }
    n
}

fn ours_owned(stream: &[u8]) -> usize {
    let mut parser = Parser::<Dialect>::new();
    let mut input = stream;
    let mut n = 0;
    while let Some(r) = parser.next(&mut input) {
        black_box(r.message());
        n += 1;
    }
    n
}

fn theirs_raw(stream: &[u8]) -> usize {
    let mut reader = mavlink::MavlinkReader::new(stream);
    let mut n = 0;
    while let Ok(raw) = reader.read_any_raw_message::<MavMessage>() {
        black_box(&raw);
        n += 1;
    }
    n
}

fn theirs_owned(stream: &[u8]) -> usize {
    let mut reader = mavlink::MavlinkReader::new(stream);
    let mut n = 0;
    while let Ok(msg) = reader.read_any_message::<MavMessage>() {
        black_box(&msg);
        n += 1;
    }
    n
}

fn count_notices(stream: &[u8]) -> usize {
    let mut parser = Parser::<Dialect>::new();
    let mut input = stream;
    let mut n = 0;
    while let Some(r) = parser.next(&mut input) {
        n += usize::from(r.frame.msg_id() == fbwag_dialect::FbwagNotice::ID);
    }
    n
}

fn decode(c: &mut Criterion) {
    let stream = benches::telemetry();
    let frames = ours_views(&stream);
    // The mavlink crate's ardupilotmega has no FBWAG_NOTICE: it skips those.
    assert_eq!(
        frames,
        theirs_raw(&stream) + count_notices(&stream),
        "both decoders must see the same frames"
    );
    let mut g = c.benchmark_group("stream_decode");
    g.throughput(Throughput::Bytes(stream.len() as u64));
    g.sample_size(20);
    for (name, f) in [
        ("fbwag/views", ours_views as fn(&[u8]) -> usize),
        ("mavlink/raw", theirs_raw),
        ("fbwag/owned", ours_owned),
        ("mavlink/owned", theirs_owned),
    ] {
        g.bench_with_input(BenchmarkId::new(name, frames), &stream[..], |b, s| {
            b.iter(|| f(black_box(s)))
        });
    }
    g.finish();
}

criterion_group!(benches, decode);
criterion_main!(benches);
