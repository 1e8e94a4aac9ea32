//! Signature verification (`Verifier::verify`), the receive side of signing:
//!
//! - `verify/known_streams`: 1024 signed FBWAG_NOTICE frames from 4 streams
//!   the verifier already tracks, in turn (the hot path of a live link: one
//!   SHA-256 block layout, a table lookup, a timestamp update);
//!
//! Criterion's throughput is in frames. Each batch verifies the same frames
//! with a fresh copy of a verifier that has seen each stream once, so every
//! frame is accepted.

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use fbwag_dialect::mavframe::frame::{encode, Frame, MAX_FRAME_LEN};
use fbwag_dialect::mavframe::signing::{timestamp_now, Signer, Verifier};
use fbwag_dialect::{FbwagFailsafeStatus, FbwagNotice, Header, Version};
use std::hint::black_box;

const FRAMES: usize = 1024;
const STREAMS: u8 = 4;

/// `n` signed notices from `STREAMS` signers (sysid 1..=STREAMS), in turn,
/// starting at `start`; each frame's bytes.
fn frames(n: usize, start: u64) -> Vec<Vec<u8>> {
    let mut signers: Vec<Signer> = (0..STREAMS)
        .map(|_| Signer::new(benches::KEY, 0, start))
        .collect();
    let mut buf = [0u8; MAX_FRAME_LEN];
    (0..n)
        .map(|i| {
            let s = (i % STREAMS as usize) as u8;
            let notice = FbwagNotice {
                system_id: 1,
                component_id: 1,
                failsafe_status: FbwagFailsafeStatus::RC_LOST,
                text: fbwag_dialect::mavframe::field::chars("FBWAG"),
                timestamp: i as u32,
            };
            let header = Header {
                seq: i as u8,
                sysid: s + 1,
                compid: 1,
            };
            let signer = &mut signers[s as usize];
            let len = encode(Version::V2, header, &notice, Some(signer), &mut buf)
                .expect("the buffer fits any frame");
            buf[..len].to_vec()
        })
        .collect()
}

fn verify(c: &mut Criterion) {
    let now = timestamp_now();
    // One frame per stream, so the verifier tracks them all.
    let mut primed = Verifier::<16>::with_timestamp(benches::KEY, now);
    for f in frames(STREAMS as usize, now - 10) {
        let frame = Frame::new_checked(&f).expect("a whole frame");
        primed.verify(&frame).expect("accepted");
    }
    let bytes = frames(FRAMES, now);
    let stream: Vec<Frame<'_>> = bytes
        .iter()
        .map(|f| Frame::new_checked(f).expect("a whole frame"))
        .collect();
    let mut g = c.benchmark_group("verify");
    g.throughput(Throughput::Elements(FRAMES as u64));
    g.bench_function("known_streams", |b| {
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
    g.finish();
}

criterion_group!(benches, verify);
criterion_main!(benches);
