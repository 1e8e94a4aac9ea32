//! Signature verification (`Verifier::verify`), the receive side of signing:
//!
//! - `verify/known_streams`: 1024 signed FBWAG_NOTICE frames from 4 streams
//!   the verifier already tracks, in turn (the hot path of a live link: one
//!   SHA-256 block layout, a table lookup, a timestamp update);
//! - `verify/new_streams_evicting`: 1024 frames of 1024 streams the
//!   verifier has not seen, into a full table of 16 (the cold path: a clock
//!   read, the window and floor checks, the eviction of the least recently
//!   accepted stream).
//!
//! - `verify/mavlink_known_streams`: the same frames as `known_streams`
//!   through the `mavlink` crate's `SigningData::verify_signature` (its
//!   receive-side check: stream table, timestamps, SHA-256), each frame
//!   already in its `MAVLinkV2MessageRaw`. Its check reads the clock on
//!   every frame (its design; ours only for a stream it does not know).
//!
//! Criterion's throughput is in frames. Each batch verifies the same frames
//! with a fresh copy of a primed verifier, so every frame is accepted.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use fbwag_dialect::mavframe::frame::{encode, Frame, MAX_FRAME_LEN};
use fbwag_dialect::mavframe::signing::{timestamp_now, Signer, Verifier};
use fbwag_dialect::{FbwagFailsafeStatus, FbwagNotice, Header, Version};
use mavlink::{MAVLinkV2MessageRaw, SigningConfig, SigningData};
use std::hint::black_box;

const FRAMES: usize = 1024;
const STREAMS: usize = 4;

/// `n` signed notices from `streams` signers (sysid 1..=255, then link ids),
/// in turn, signer `i` starting at `start + i` (so a stream new to a
/// verifier is newer than those it evicted); each frame's bytes.
fn frames(n: usize, streams: usize, start: u64) -> Vec<Vec<u8>> {
    let mut signers: Vec<Signer> = (0..streams)
        .map(|i| Signer::new(benches::KEY, (i / 255) as u8, start + i as u64))
        .collect();
    let mut buf = [0u8; MAX_FRAME_LEN];
    (0..n)
        .map(|i| {
            let s = i % streams;
            let notice = FbwagNotice {
                system_id: 1,
                component_id: 1,
                failsafe_status: FbwagFailsafeStatus::RC_LOST,
                text: fbwag_dialect::mavframe::field::chars("FBWAG"),
                timestamp: i as u32,
            };
            let header = Header {
                seq: i as u8,
                sysid: (s % 255) as u8 + 1,
                compid: 1,
            };
            let signer = &mut signers[s];
            let len = encode(Version::V2, header, &notice, Some(signer), &mut buf)
                .expect("the buffer fits any frame");
            buf[..len].to_vec()
        })
        .collect()
}

/// A verifier that has accepted one frame of each of `streams` streams.
fn primed(streams: usize, now: u64) -> Verifier<16> {
    let mut v = Verifier::<16>::starting_now(benches::KEY);
    for f in frames(streams, streams, now - 100_000) {
        let frame = Frame::new_checked(&f).expect("a whole frame");
        v.verify(&frame).expect("accepted");
    }
    v
}

fn verify(c: &mut Criterion) {
    let now = timestamp_now();
    let mut g = c.benchmark_group("verify");
    g.throughput(Throughput::Elements(FRAMES as u64));
    let known = frames(FRAMES, STREAMS, now);
    bench(&mut g, "known_streams", primed(STREAMS, now), &known);
    // Streams 1..=16 fill the table; the frames come from 1024 others.
    let mut fresh = frames(16 + FRAMES, 16 + FRAMES, now);
    fresh.rotate_left(16);
    fresh.truncate(FRAMES);
    bench(&mut g, "new_streams_evicting", primed(16, now), &fresh);
    bench_mavlink(&mut g, &frames(STREAMS, STREAMS, now - 100_000), &known);
    g.finish();
}

/// The frame's bytes in the `mavlink` crate's frame buffer.
fn raw(frame: &[u8]) -> MAVLinkV2MessageRaw {
    let mut raw = MAVLinkV2MessageRaw::new();
    raw.as_mut_slice()[..frame.len()].copy_from_slice(frame);
    raw
}

/// The `mavlink` crate verifying `bytes` (each accepted), its signing state
/// primed with one frame of each stream per batch, as ours.
fn bench_mavlink(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    primer: &[Vec<u8>],
    bytes: &[Vec<u8>],
) {
    let primer: Vec<MAVLinkV2MessageRaw> = primer.iter().map(|f| raw(f)).collect();
    let stream: Vec<MAVLinkV2MessageRaw> = bytes.iter().map(|f| raw(f)).collect();
    let primed = || {
        let s = SigningData::from_config(SigningConfig::new(benches::KEY, 0, false, false));
        for f in &primer {
            assert!(s.verify_signature(f), "mavlink accepts the primer");
        }
        s
    };
    g.bench_function("mavlink_known_streams", |b| {
        b.iter_batched_ref(
            primed,
            |s| {
                let mut ok = 0;
                for f in &stream {
                    ok += usize::from(s.verify_signature(black_box(f)));
                }
                assert_eq!(ok, FRAMES);
                ok
            },
            BatchSize::SmallInput,
        )
    });
}

/// Verifies `bytes` (each accepted) with a fresh copy of `primed` per batch.
fn bench(
    g: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    name: &str,
    primed: Verifier<16>,
    bytes: &[Vec<u8>],
) {
    let stream: Vec<Frame<&[u8]>> = bytes
        .iter()
        .map(|f| Frame::new_checked(&f[..]).expect("a whole frame"))
        .collect();
    g.bench_function(name, |b| {
        b.iter_batched_ref(
            || primed.clone(),
            |v| {
                let mut ok = 0;
                for f in &stream {
                    ok += usize::from(v.verify(black_box(f)).is_ok());
                }
                assert_eq!(ok, FRAMES);
                ok
            },
            BatchSize::SmallInput,
        )
    });
}

criterion_group!(benches, verify);
criterion_main!(benches);
