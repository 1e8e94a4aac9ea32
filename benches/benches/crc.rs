//! The frame checksum alone: mavframe's slice-by-16 CRC-16/MCRF4XX, the
//! specification's byte loop (`mavframe::crc::update_bytewise`, what mavframe
//! used before) and crc-any's table (what the `mavlink` crate uses), over the
//! checksummed bytes of every frame of the telemetry capture.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use fbwag_dialect::mavframe::crc::{update_bytewise, Crc};
use fbwag_dialect::mavframe::parser::Parser;
use fbwag_dialect::Dialect;
use std::hint::black_box;

fn crc(c: &mut Criterion) {
    let stream = benches::telemetry();
    // (start, end) of the bytes each frame's checksum covers.
    let mut spans = Vec::new();
    let mut parser = Parser::<Dialect>::new();
    let mut input = &stream[..];
    let base = stream.as_ptr() as usize;
    while let Some(r) = parser.next(&mut input) {
        let f = r.frame();
        let start = f.as_bytes().as_ptr() as usize - base + 1;
        let end = start - 1 + f.as_bytes().len() - 2 - f.signature().map_or(0, |_| 13);
        spans.push((start, end));
    }
    let covered: usize = spans.iter().map(|(a, b)| b - a).sum();
    let all = |f: &dyn Fn(&[u8]) -> u16| {
        spans
            .iter()
            .fold(0u16, |acc, &(a, b)| acc ^ f(black_box(&stream[a..b])))
    };
    let ours = |b: &[u8]| {
        let mut c = Crc::new();
        c.update(b);
        c.get()
    };
    let crc_any = |b: &[u8]| {
        let mut c = crc_any::CRCu16::crc16mcrf4cc();
        c.digest(b);
        c.get_crc()
    };
    let bytewise = |b: &[u8]| update_bytewise(0xFFFF, b);
    assert_eq!(all(&ours), all(&crc_any));
    assert_eq!(all(&bytewise), all(&crc_any));

    let mut g = c.benchmark_group("crc");
    g.throughput(Throughput::Bytes(covered as u64))
        .sample_size(20);
    g.bench_function("mavframe_slice16", |b| b.iter(|| all(&ours)));
    g.bench_function("spec_bytewise", |b| b.iter(|| all(&bytewise)));
    g.bench_function("crc_any", |b| b.iter(|| all(&crc_any)));
    g.finish();
}

criterion_group!(benches, crc);
criterion_main!(benches);
