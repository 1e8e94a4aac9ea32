//! FBWAG_NOTICE per frame, fbwag-dialect next to the `mavlink` crate with
//! bindings made by its own generator (mavlink-bindgen 0.21, see build.rs):
//!
//! - `notice_encode/<lib>/{unsigned,signed}`: one frame;
//! - `notice_decode/<lib>/{views,owned}`: a stream of 1024 notices (a flight
//!   controller and a companion computer in turn), CRC checked; criterion's
//!   throughput is in frames, so the time per frame is 1 / (frames/s).

use benches::{mavlink_header, OurEncoder, TheirEncoder, Theirs};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use fbwag_dialect::{FbwagFailsafeStatus, FbwagNotice, Header, Message};
use std::hint::black_box;

const FRAMES: usize = 1024;

fn notice(c: &mut Criterion) {
    let stream = benches::notice_stream(FRAMES);
    assert_eq!(benches::fbwag_notice_views(&stream), FRAMES);
    assert_eq!(benches::fbwag_notice_owned(&stream), FRAMES);
    assert_eq!(benches::mavlink_notice_owned(&stream), FRAMES);

    let ours = Message::FbwagNotice(FbwagNotice {
        system_id: 1,
        component_id: 1,
        failsafe_status: FbwagFailsafeStatus::RC_LOST,
        text: fbwag_dialect::mavframe::field::chars("FBWAG"),
        timestamp: 123_456,
    });
    let header = Header {
        seq: 7,
        sysid: 1,
        compid: 1,
    };
    // The same notice for the mavlink crate, decoded from our frame.
    let frame = OurEncoder::new(false).encode(header, &ours).to_vec();
    let theirs = Theirs::Fbwag(
        mavlink::MavlinkReader::new(&frame[..])
            .read_any_message()
            .expect("mavlink decodes our FBWAG_NOTICE")
            .1,
    );
    assert_eq!(
        TheirEncoder::new(false).encode_any(mavlink_header(header), &theirs),
        &frame[..],
        "both libraries frame the notice identically"
    );

    let mut g = c.benchmark_group("notice_encode");
    for (name, signed) in [("unsigned", false), ("signed", true)] {
        let mut enc = OurEncoder::new(signed);
        g.bench_function(BenchmarkId::new("fbwag", name), |b| {
            b.iter(|| enc.encode(black_box(header), black_box(&ours)).len())
        });
        let mut enc = TheirEncoder::new(signed);
        let h = mavlink_header(header);
        g.bench_function(BenchmarkId::new("mavlink", name), |b| {
            b.iter(|| enc.encode_any(black_box(h), black_box(&theirs)).len())
        });
    }
    g.finish();

    let mut g = c.benchmark_group("notice_decode");
    g.throughput(Throughput::Elements(FRAMES as u64));
    for (name, f) in [
        (
            "fbwag/views",
            benches::fbwag_notice_views as benches::Decoder,
        ),
        ("fbwag/owned", benches::fbwag_notice_owned),
        ("mavlink/owned", benches::mavlink_notice_owned),
    ] {
        g.bench_with_input(name, &stream[..], |b, s| b.iter(|| f(black_box(s))));
    }
    g.finish();
}

criterion_group!(benches, notice);
criterion_main!(benches);
