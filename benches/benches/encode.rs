//! Encoding by fbwag-dialect and by the `mavlink` crate (0.21), MAVLink 2,
//! unsigned and signed, in the same run:
//!
//! - `encode/<lib>/<MESSAGE>`, `encode_signed/…`: one frame of each message
//!   type of the telemetry capture (FBWAG_NOTICE included), the values of
//!   its first frame there;
//! - `encode_mix/<lib>/{unsigned,signed}`: the capture's sequence of message
//!   types (all its frames: 115,675 in the default ArduPlane-like mix, see
//!   `benches::mix`; its mix and order, so the dispatch on the type is
//!   as unpredictable as on a real link), each type with its sample's values
//!   (which stay in cache: re-encoding 116,531 owned messages of ~270 bytes
//!   would time memory bandwidth instead).
//!
//! Both libraries go through their enum of all messages (`Message::emit` +
//! `frame::finish`; `MAVLinkV2MessageRaw::serialize_message`) into a reused
//! frame buffer. Signing reads the clock for every frame in both (ours as
//! `Connection::send` does). Before timing, the unsigned frames of both are
//! checked to be byte-identical to the capture's (made by pymavlink).

use benches::{mavlink_header, OurEncoder, TheirEncoder};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use std::hint::black_box;
use std::time::Duration;

fn encode(c: &mut Criterion) {
    let stream = benches::telemetry();
    let samples = benches::samples(&stream);
    for s in &samples {
        let ours = OurEncoder::new(false).encode(s.header, &s.ours).to_vec();
        let theirs = TheirEncoder::new(false)
            .encode_any(mavlink_header(s.header), &s.theirs)
            .to_vec();
        assert_eq!(ours, s.frame, "{}: ours differs from the capture", s.name);
        assert_eq!(
            theirs, s.frame,
            "{}: mavlink's differs from the capture",
            s.name
        );
    }
    for (group, signed) in [("encode", false), ("encode_signed", true)] {
        let mut g = c.benchmark_group(group);
        g.warm_up_time(Duration::from_millis(300))
            .measurement_time(Duration::from_secs(1))
            .sample_size(30);
        for s in &samples {
            let mut ours = OurEncoder::new(signed);
            g.bench_function(BenchmarkId::new("fbwag", s.name), |b| {
                b.iter(|| ours.encode(black_box(s.header), black_box(&s.ours)).len())
            });
            let mut theirs = TheirEncoder::new(signed);
            let h = mavlink_header(s.header);
            g.bench_function(BenchmarkId::new("mavlink", s.name), |b| {
                b.iter(|| theirs.encode_any(black_box(h), black_box(&s.theirs)).len())
            });
        }
        g.finish();
    }
}

fn encode_mix(c: &mut Criterion) {
    let stream = benches::telemetry();
    let samples = benches::samples(&stream);
    // The capture's sequence of message types, as indices into `samples`.
    let order = benches::type_sequence(&stream, &samples);
    let mut g = c.benchmark_group("encode_mix");
    g.throughput(Throughput::Elements(order.len() as u64))
        .sample_size(10)
        .measurement_time(Duration::from_secs(4));
    for (name, signed) in [("unsigned", false), ("signed", true)] {
        let mut ours = OurEncoder::new(signed);
        g.bench_function(BenchmarkId::new("fbwag", name), |b| {
            b.iter(|| {
                order
                    .iter()
                    .map(|&i| {
                        ours.encode(samples[i].header, black_box(&samples[i].ours))
                            .len()
                    })
                    .sum::<usize>()
            })
        });
        let mut theirs = TheirEncoder::new(signed);
        let headers: Vec<_> = samples.iter().map(|s| mavlink_header(s.header)).collect();
        g.bench_function(BenchmarkId::new("mavlink", name), |b| {
            b.iter(|| {
                order
                    .iter()
                    .map(|&i| {
                        theirs
                            .encode_any(headers[i], black_box(&samples[i].theirs))
                            .len()
                    })
                    .sum::<usize>()
            })
        });
    }
    g.finish();
}

criterion_group!(benches, encode, encode_mix);
criterion_main!(benches);
