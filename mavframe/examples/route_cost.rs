//! What routing costs per frame, and what a full table weighs:
//! `cargo run --release -p mavframe --features alloc --example route_cost`.
//!
//! Each table holds the vehicle (1/1, link 0), a ground station (255/190,
//! link 1) and other senders (link 1); the station's COMMAND_LONG to the
//! vehicle is routed (its sender learned, its addressee looked up) again
//! and again. The heap a table holds is counted by the global allocator.

use mavframe::route::{FixedRoutingTable, Links, RoutingTable};
use mavframe::{Frame, MessageMeta};
use std::alloc::{GlobalAlloc, Layout, System};
use std::hint::black_box;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::time::Instant;

/// The system allocator, counting the bytes held.
struct Counting;

static HELD: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        HELD.fetch_add(layout.size(), Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        HELD.fetch_sub(layout.size(), Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

const COMMAND_LONG: MessageMeta =
    MessageMeta::new(76, "COMMAND_LONG", 152, 33, 33, &[]).with_target_offsets(Some(30), Some(31));

/// Routes per measurement.
const ROUNDS: u32 = 2_000_000;

/// `n` senders other than the vehicle and the station, system by system.
fn others(n: usize) -> impl Iterator<Item = (u8, u8)> {
    (2..=u8::MAX)
        .flat_map(|s| (0..=u8::MAX).map(move |c| (s, c)))
        .chain((0..=u8::MAX).map(|c| (1, c)))
        .filter(|&id| id != (1, 1) && id != (255, 190))
        .take(n)
}

/// Nanoseconds per routed frame: `route` called `ROUNDS` times.
fn per_frame(mut route: impl FnMut() -> Links) -> f64 {
    let start = Instant::now();
    for _ in 0..ROUNDS {
        assert_eq!(black_box(route()), Links::only(0));
    }
    start.elapsed().as_nanos() as f64 / f64::from(ROUNDS)
}

fn main() {
    let mut bytes = [0u8; 45];
    bytes[..10].copy_from_slice(&[0xfd, 33, 0, 0, 0, 255, 190, 76, 0, 0]);
    bytes[40..42].copy_from_slice(&[1, 1]);
    let frame = Frame::new_checked(&bytes[..]).expect("a frame");
    let links = Links::all(2);
    println!("| senders | map: ns/frame | map: heap | array of 256: ns/frame |");
    println!("|---|---|---|---|");
    for senders in [8, 64, 256, 1_000, 65_280] {
        let n: usize = senders - 2;
        let before = HELD.load(Relaxed);
        let mut map = RoutingTable::new();
        let mut fixed = FixedRoutingTable::<256>::new();
        map.learn(0, 1, 1, false);
        fixed.learn(0, 1, 1, false);
        for (s, c) in others(n) {
            map.learn(1, s, c, false);
        }
        let heap = HELD.load(Relaxed) - before;
        let map_ns = per_frame(|| map.route(1, &frame, Some(&COMMAND_LONG), links, false));
        // The array forgets the vehicle past 256 senders: it is measured
        // only while it holds it.
        let fixed_ns = if n <= 254 {
            for (s, c) in others(n) {
                fixed.learn(1, s, c, false);
            }
            let ns = per_frame(|| fixed.route(1, &frame, Some(&COMMAND_LONG), links, false));
            format!("{ns:.0}")
        } else {
            "(vehicle forgotten)".into()
        };
        println!("| {senders} | {map_ns:.0} | {heap} B | {fixed_ns} |");
    }
    let empty = RoutingTable::new();
    println!(
        "an empty map: {} bytes inline, clone allocates {} bytes; the array of 256: {} bytes",
        std::mem::size_of_val(&empty),
        {
            let before = HELD.load(Relaxed);
            let copy = black_box(empty.clone());
            let grew = HELD.load(Relaxed) - before;
            drop(copy);
            grew
        },
        std::mem::size_of::<FixedRoutingTable<256>>()
    );
}
