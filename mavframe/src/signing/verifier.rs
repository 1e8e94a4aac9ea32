//! The receive side of signing: signature check and replay protection.

use super::{sha256_prefix, signature_streamed, SignatureError, NEW_STREAM_WINDOW};
use crate::frame::Frame;
use core::fmt;

/// Buckets of the eviction floor (see [`Verifier`]): evicted streams raise
/// the floor of their bucket only, so one evicted stream's timestamps hold
/// back 1/16 of the new streams rather than all of them.
pub const FLOOR_BUCKETS: usize = 16;

/// One stream's replay state: its key (link id, system id, component id)
/// and the last timestamp accepted from it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct StreamState {
    /// Link id of the signature block.
    pub link_id: u8,
    /// System id of the frame's header.
    pub sysid: u8,
    /// Component id of the frame's header.
    pub compid: u8,
    /// The last timestamp accepted from this stream.
    pub timestamp: u64,
}

impl StreamState {
    fn same_stream(&self, link_id: u8, sysid: u8, compid: u8) -> bool {
        (self.link_id, self.sysid, self.compid) == (link_id, sysid, compid)
    }

    /// The floor bucket of this stream (a multiplicative hash of its key).
    fn bucket(&self) -> usize {
        let k = u32::from(self.link_id) << 16 | u32::from(self.sysid) << 8 | u32::from(self.compid);
        // The top 4 bits of the product mix all 24 key bits.
        (k.wrapping_mul(0x9e37_79b1) >> 28) as usize % FLOOR_BUCKETS
    }
}

/// A table slot: a stream and when it was last accepted, in the verifier's
/// own count of accepted frames (for least-recently-used eviction).
#[derive(Debug, Clone, Copy, Default)]
struct Slot {
    stream: StreamState,
    used: u64,
}

/// Checks signatures of incoming frames, with replay protection for up to
/// `N` streams at a time (the C library's default is 16).
///
/// # What is accepted
///
/// A signed MAVLink 2 frame is accepted when its signature matches the key
/// and its timestamp `t` passes the check of its stream, the tuple (link id,
/// system id, component id):
///
/// - a stream in the table: `t` is greater than the stream's last accepted
///   timestamp (else [`SignatureError::Replay`]), as the spec says, however
///   old `t` is;
/// - a new stream (or one evicted since): `t + 1 minute` is at least the
///   verifier's notion of now (else [`SignatureError::TooOld`]: the spec's
///   rule for new streams) *and* `t` is greater than the floor of the
///   stream's bucket (else [`SignatureError::BelowFloor`], see eviction).
///
/// There is no upper bound: a correctly signed frame from the future is
/// accepted, as in the C library, so that a receiver whose clock is behind
/// learns the time from a correctly clocked peer (see `crate::signing`:
/// the link's signer then adopts it). The timestamp rules run before the
/// SHA-256; a frame they refuse is [stale](SignatureError::is_stale), not
/// known to be forged.
///
/// The notion of now is the greatest of: the start value (0 for
/// [`new`](Self::new), the clock for `starting_now` (std) and
/// [`with_clock`](Self::with_clock), the given value for
/// [`with_timestamp`](Self::with_timestamp)), every timestamp accepted, and,
/// with a clock, the clock read when a new stream appears (one read per new
/// stream, none on the per-frame path). So a verifier with a clock rejects
/// captures more than a minute old as new streams, from the first frame
/// and however long the link has been idle. That is what the spec asks of a
/// receiver ("accepted if it is not more than one minute behind the current
/// timestamp"); the C library and pymavlink use their local signing
/// timestamp, which the application sets from the clock or storage, and
/// which accepted timestamps raise as here. A clock that is behind never
/// lowers it: after a frame of a correctly clocked peer, captures more than
/// a minute older than that peer's frames are refused as new streams.
///
/// Which constructor:
///
/// - a live link on a machine with a trustworthy clock: `starting_now`
///   (std) or [`with_clock`](Self::with_clock);
/// - a live link without a clock: [`with_timestamp`](Self::with_timestamp)
///   from the last saved timestamp;
/// - either, after a restart: the same, then [`restore`](Self::restore) the
///   saved table (`signing::state`, with `std`, does both from a file);
/// - replaying recordings, and tests: [`new`](Self::new), which accepts any
///   first timestamp of a stream, so any capture, once.
///
/// # Eviction
///
/// When a new stream is accepted and all `N` slots are taken, the least
/// recently *accepted* stream (the one whose last frame came longest ago, in
/// this verifier's order of arrival) is evicted, and the floor of its bucket
/// (one of [`FLOOR_BUCKETS`], by a hash of the stream's key) is raised to its
/// last timestamp. A frame of a stream that is not in the table must be
/// newer than the floor of its bucket. Hence:
///
/// - *No replay hole*: every frame this verifier accepts, a verifier with an
///   unbounded table would accept too (a test checks it on random
///   sequences). An evicted stream's frames up to its last accepted one stay
///   rejected forever: the floors only rise.
/// - *No permanent lock-out*: a legitimate stream is accepted again as soon
///   as its timestamp passes its bucket's floor. Floors are timestamps other
///   signers of the key sent (and this verifier accepted), so a signer whose
///   clock is right is held back by at most the lead of the fastest clock in
///   its bucket; in practice not at all.
///
/// # Limits, as an attacker sees them
///
/// Without the key, an attacker can only replay frames signed by others.
/// Replays of frames the table has seen are rejected; frames of a stream the
/// table does not know (never seen here, e.g. captured on another link) are
/// accepted once if less than a minute old and above the floor, as the spec
/// allows. To evict a stream, the attacker needs `N` other streams' frames
/// to be accepted after its last one, i.e. `N` other live signers of the key
/// to capture from; then the evicted stream's frames newer than its last
/// accepted one (which an unbounded table would accept too) are all it
/// gains.
///
/// With the key, an attacker can sign anything anyway: it can also raise
/// the notion of now far into the future (then every new stream is
/// `TooOld`, as in the C library) or fill the table and the floors with
/// future timestamps. Signing authenticates holders of the key, not their
/// intent.
///
/// Any timestamp scheme lets an attacker delay frames: a captured frame
/// held back is accepted later as long as nothing newer of its stream got
/// through (and, for a new stream, within the minute).
///
/// Without a clock (`new`, `with_timestamp`), the notion of now moves only
/// with accepted timestamps and [`advance_to`](Self::advance_to): on an idle
/// link it stands still, and a capture of a stream not in the table passes
/// if it is less than a minute older than the last accepted frame, however
/// long ago that was.
#[derive(Clone)]
pub struct Verifier<const N: usize = 16> {
    key: [u8; 32],
    /// [`Verifier::check`] and [`expected_signature`], through pointers
    /// that only the constructor takes: a parser holds an
    /// `Option<Verifier>` and compiles its calls in whether or not one is
    /// ever given, so a program that builds no verifier would link the
    /// checks and SHA-256 if they were called directly.
    check: fn(&mut Self, &Frame<&[u8]>) -> Result<(), SignatureError>,
    expected: fn(&[u8; 32], &Frame<&[u8]>) -> [u8; 6],
    newest: u64,
    clock: Option<fn() -> u64>,
    floors: [u64; FLOOR_BUCKETS],
    slots: [Slot; N],
    used: usize,
    /// Frames accepted so far: the `used` mark of the newest slot.
    accepted: u64,
}

impl<const N: usize> fmt::Debug for Verifier<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Never print the key.
        f.debug_struct("Verifier")
            .field("newest", &self.newest)
            .field("clock", &self.clock.is_some())
            .field("streams", &self.used)
            .finish_non_exhaustive()
    }
}

impl<const N: usize> Verifier<N> {
    /// A verifier for `key` that has seen no timestamp yet and has no clock:
    /// the first frame of any stream is accepted, however old. For decoding
    /// recordings and for tests; a live link wants
    /// `starting_now` (std).
    pub fn new(key: [u8; 32]) -> Self {
        Verifier {
            key,
            check: Self::check,
            expected: expected_signature,
            newest: 0,
            clock: None,
            floors: [0; FLOOR_BUCKETS],
            slots: [Slot::default(); N],
            used: 0,
            accepted: 0,
        }
    }

    /// A verifier whose notion of now starts at `timestamp` (no clock), so
    /// streams starting more than a minute before it are rejected.
    pub fn with_timestamp(key: [u8; 32], timestamp: u64) -> Self {
        let mut v = Self::new(key);
        v.newest = timestamp;
        v
    }

    /// A verifier that reads `clock` (a signing timestamp, 10 µs units since
    /// 2015) now and whenever a new stream appears, so its notion of now
    /// keeps up with time even on an idle link.
    pub fn with_clock(key: [u8; 32], clock: fn() -> u64) -> Self {
        let mut v = Self::with_timestamp(key, clock());
        v.clock = Some(clock);
        v
    }

    /// [`with_clock`](Self::with_clock) with the system clock
    /// (`timestamp_now`): the constructor for a live
    /// link.
    #[cfg(feature = "std")]
    pub fn starting_now(key: [u8; 32]) -> Self {
        Self::with_clock(key, super::timestamp_now)
    }

    /// The verifier's notion of now: the greatest of its start, the
    /// timestamps accepted and the clock reads so far; what the link's
    /// signer adopts (`Framer::adopt_from`).
    pub fn newest_timestamp(&self) -> u64 {
        self.newest
    }

    /// Moves the notion of now forward to `now` (never back), for a caller
    /// that learns the time otherwise (GPS, a peer).
    pub fn advance_to(&mut self, now: u64) {
        self.newest = self.newest.max(now);
    }

    /// The eviction floors, by bucket (see the type's docs).
    pub fn floors(&self) -> [u64; FLOOR_BUCKETS] {
        self.floors
    }

    /// The streams in the table, least recently accepted first.
    pub fn streams(&self) -> impl Iterator<Item = StreamState> + '_ {
        // `used` marks are distinct: pick the next larger one each time
        // (quadratic in N, which is small; no allocation).
        let mut after = None;
        core::iter::from_fn(move || {
            let next = self.slots[..self.used]
                .iter()
                .filter(|s| after.is_none_or(|a| s.used > a))
                .min_by_key(|s| s.used)?;
            after = Some(next.used);
            Some(next.stream)
        })
    }

    /// Raises this verifier's state to a saved one: the notion of now and
    /// each floor to at least the saved values, and the `streams` (least
    /// recently accepted first) into the table, each at least at its saved
    /// timestamp; streams beyond `N` are evicted into the floors as usual.
    /// Nothing is ever lowered, so restoring an old or foreign state cannot
    /// reopen a replay.
    pub fn restore(
        &mut self,
        newest: u64,
        floors: &[u64; FLOOR_BUCKETS],
        streams: impl IntoIterator<Item = StreamState>,
    ) {
        self.advance_to(newest);
        for (mine, saved) in self.floors.iter_mut().zip(floors) {
            *mine = (*mine).max(*saved);
        }
        for s in streams {
            match self.find(s.link_id, s.sysid, s.compid) {
                Some(i) => {
                    let slot = &mut self.slots[i];
                    slot.stream.timestamp = slot.stream.timestamp.max(s.timestamp);
                    self.accepted += 1;
                    slot.used = self.accepted;
                }
                None => {
                    if self.insert(s).is_err() {
                        // No slots: the floor alone keeps its frames out.
                        self.raise_floor(&s);
                    }
                }
            }
            self.advance_to(s.timestamp);
        }
    }

    /// Checks `frame`'s signature and, when it is good and its timestamp
    /// passes its stream's check (see the type's docs), records the
    /// timestamp for its stream.
    pub fn verify<T: AsRef<[u8]>>(&mut self, frame: &Frame<T>) -> Result<(), SignatureError> {
        (self.check)(self, &frame.as_view())
    }

    /// [`verify`](Self::verify), reached through `self.check`.
    fn check(&mut self, frame: &Frame<&[u8]>) -> Result<(), SignatureError> {
        let block = frame.signature().ok_or(SignatureError::Unsigned)?;
        let h = frame.header();
        let stream = StreamState {
            link_id: block.link_id(),
            sysid: h.sysid,
            compid: h.compid,
            timestamp: block.timestamp(),
        };
        // The timestamp rules need no key: a frame they refuse is refused
        // before the SHA-256, so old captures and garbage with an
        // out-of-window timestamp cost a table look-up, not a hash.
        self.timestamp_check(&stream)?;
        if !self.signed_with_key(frame) {
            return Err(SignatureError::Mismatch);
        }
        self.accept(stream)
    }

    /// Whether `frame` carries this key's signature, whatever its
    /// timestamp (a SHA-256; nothing recorded). A frame refused as stale
    /// that the key signed comes from a key holder: a replay, or a peer
    /// whose clock is behind, which a signed answer lets catch up.
    pub fn signed_with_key<T: AsRef<[u8]>>(&self, frame: &Frame<T>) -> bool {
        let frame = frame.as_view();
        let Some(block) = frame.signature() else {
            return false;
        };
        // Not constant-time: the signature is public once sent, and a
        // mismatch only drops the frame.
        (self.expected)(&self.key, &frame) == block.signature()
    }

    /// The replay rules of [`accept`](Self::accept) without changing
    /// anything (no clock read: the notion of now only grows, so what this
    /// refuses `accept` would refuse too).
    fn timestamp_check(&self, s: &StreamState) -> Result<(), SignatureError> {
        match self.find(s.link_id, s.sysid, s.compid) {
            Some(i) if s.timestamp <= self.slots[i].stream.timestamp => Err(SignatureError::Replay),
            Some(_) => Ok(()),
            None if s.timestamp + NEW_STREAM_WINDOW < self.newest => Err(SignatureError::TooOld),
            None if s.timestamp <= self.floors[s.bucket()] => Err(SignatureError::BelowFloor),
            None => Ok(()),
        }
    }

    /// The replay check of a correctly signed frame of stream `s` (its
    /// timestamp in `s.timestamp`); records it when it passes.
    fn accept(&mut self, s: StreamState) -> Result<(), SignatureError> {
        match self.find(s.link_id, s.sysid, s.compid) {
            Some(i) => {
                let slot = &mut self.slots[i];
                if s.timestamp <= slot.stream.timestamp {
                    return Err(SignatureError::Replay);
                }
                slot.stream.timestamp = s.timestamp;
                self.accepted += 1;
                slot.used = self.accepted;
            }
            None => self.admit(s)?,
        }
        self.newest = self.newest.max(s.timestamp);
        Ok(())
    }

    #[inline]
    fn find(&self, link_id: u8, sysid: u8, compid: u8) -> Option<usize> {
        self.slots[..self.used]
            .iter()
            .position(|s| s.stream.same_stream(link_id, sysid, compid))
    }

    /// A stream not in the table: the new-stream rules, then a slot.
    #[cold]
    fn admit(&mut self, s: StreamState) -> Result<(), SignatureError> {
        if let Some(clock) = self.clock {
            self.advance_to(clock());
        }
        if s.timestamp + NEW_STREAM_WINDOW < self.newest {
            return Err(SignatureError::TooOld);
        }
        if s.timestamp <= self.floors[s.bucket()] {
            return Err(SignatureError::BelowFloor);
        }
        self.insert(s)
    }

    /// Puts `s` in a free slot, or in the least recently accepted stream's
    /// after raising that stream's floor; `TooManyStreams` when `N == 0`.
    fn insert(&mut self, s: StreamState) -> Result<(), SignatureError> {
        let i = if self.used < N {
            self.used += 1;
            self.used - 1
        } else {
            let (i, lru) = self
                .slots
                .iter()
                .enumerate()
                .min_by_key(|(_, slot)| slot.used)
                .ok_or(SignatureError::TooManyStreams)?;
            let evicted = lru.stream;
            self.raise_floor(&evicted);
            i
        };
        self.accepted += 1;
        self.slots[i] = Slot {
            stream: s,
            used: self.accepted,
        };
        Ok(())
    }

    fn raise_floor(&mut self, s: &StreamState) {
        let floor = &mut self.floors[s.bucket()];
        *floor = (*floor).max(s.timestamp);
    }
}

/// The signature `key` gives a signed `frame`: the first 6 bytes of
/// SHA-256 over the key, then the frame's bytes up to its timestamp.
fn expected_signature(key: &[u8; 32], frame: &Frame<&[u8]>) -> [u8; 6] {
    let bytes = frame.as_bytes();
    let signed = &bytes[..bytes.len().saturating_sub(6)];
    sha256_prefix(key, signed, &[0x80]).unwrap_or_else(|| {
        let (link_id, timestamp) = frame
            .signature()
            .map_or((0, 0), |b| (b.link_id(), b.timestamp()));
        signature_streamed(key, frame.signed_part(), link_id, timestamp)
    })
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    fn stream(id: u8, timestamp: u64) -> StreamState {
        StreamState {
            link_id: id % 3,
            sysid: id,
            compid: 1,
            timestamp,
        }
    }

    /// The verifier's replay rules with an unbounded table: what the
    /// eviction must never exceed.
    struct Unbounded {
        newest: u64,
        last: std::collections::BTreeMap<(u8, u8, u8), u64>,
    }

    impl Unbounded {
        fn accepts(&self, s: &StreamState) -> bool {
            match self.last.get(&(s.link_id, s.sysid, s.compid)) {
                Some(&last) => s.timestamp > last,
                None => s.timestamp + NEW_STREAM_WINDOW >= self.newest,
            }
        }

        fn record(&mut self, s: &StreamState) {
            self.last
                .insert((s.link_id, s.sysid, s.compid), s.timestamp);
            self.newest = self.newest.max(s.timestamp);
        }
    }

    /// xorshift64*: a deterministic sequence for the random test.
    fn rng(state: &mut u64) -> u64 {
        *state ^= *state >> 12;
        *state ^= *state << 25;
        *state ^= *state >> 27;
        state.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Random frames of 7 streams through 3 slots (frequent eviction):
    /// everything accepted is accepted by the unbounded table too (with the
    /// same notion of now), and each stream's own frames are accepted again
    /// after its eviction once it sends a newer one.
    #[test]
    fn eviction_accepts_no_more_than_an_unbounded_table() {
        let mut seed = 0x9e37_79b9_7f4a_7c15;
        let (mut ours_accepted, mut evictions_seen) = (0, 0);
        for _round in 0..200 {
            let mut v = Verifier::<3>::with_timestamp([0; 32], 10_000_000);
            let mut model = Unbounded {
                newest: 10_000_000,
                last: Default::default(),
            };
            let mut clocks = [10_000_000u64; 7];
            for _ in 0..300 {
                let r = rng(&mut seed);
                let id = (r % 7) as u8;
                // Mostly fresh frames (clock steps of up to 2 s), sometimes
                // a replay of anything up to 2 minutes back.
                let ts = if r >> 8 & 3 == 0 {
                    clocks[id as usize].saturating_sub(r >> 16 & 0xff_ffff)
                } else {
                    clocks[id as usize] += 1 + (r >> 16) % 200_000;
                    clocks[id as usize]
                };
                let s = stream(id, ts);
                let before = v.floors;
                let expected = model.accepts(&s);
                let got = v.accept(s);
                if got.is_ok() {
                    assert!(expected, "accepted what an unbounded table rejects: {s:?}");
                    model.record(&s);
                    ours_accepted += 1;
                }
                evictions_seen += usize::from(v.floors != before);
                assert_eq!(v.newest, model.newest);
            }
        }
        assert!(ours_accepted > 10_000 && evictions_seen > 1000);
    }

    /// The floors and table round-trip through `streams` and `restore`, in
    /// least-recently-accepted order, and restoring never lowers anything.
    #[test]
    fn restore_reproduces_the_table_and_never_lowers() {
        let mut v = Verifier::<4>::with_timestamp([0; 32], 0);
        for (i, id) in [1u8, 2, 3, 4, 5, 2, 6].into_iter().enumerate() {
            v.accept(stream(id, 1000 + i as u64)).unwrap();
        }
        let streams: Vec<_> = v.streams().collect();
        let ids: Vec<u8> = streams.iter().map(|s| s.sysid).collect();
        assert_eq!(ids, [4, 5, 2, 6], "1 and 3 evicted, 2 refreshed");
        let mut w = Verifier::<4>::new([0; 32]);
        w.restore(v.newest, &v.floors, streams.iter().copied());
        assert_eq!(w.streams().collect::<Vec<_>>(), streams);
        assert_eq!((w.floors, w.newest), (v.floors, v.newest));
        // Restoring older values changes nothing.
        let old: Vec<_> = streams.iter().map(|s| stream(s.sysid, 5)).collect();
        w.restore(0, &[0; FLOOR_BUCKETS], old);
        let after: Vec<_> = w.streams().map(|s| (s.sysid, s.timestamp)).collect();
        let want: Vec<_> = streams.iter().map(|s| (s.sysid, s.timestamp)).collect();
        assert_eq!(after, want);
        assert_eq!((w.floors, w.newest), (v.floors, v.newest));
        // Into a smaller table: the oldest go to the floors.
        let mut small = Verifier::<2>::new([0; 32]);
        small.restore(v.newest, &v.floors, streams.iter().copied());
        let ids: Vec<u8> = small.streams().map(|s| s.sysid).collect();
        assert_eq!(ids, [2, 6]);
        assert_eq!(
            small.accept(stream(4, 1003)),
            Err(SignatureError::BelowFloor)
        );
        assert_eq!(small.accept(stream(4, 1010)), Ok(()));
    }

    /// Without slots nothing can be recorded, so nothing is accepted.
    #[test]
    fn a_verifier_without_slots_accepts_nothing() {
        let mut v = Verifier::<0>::new([0; 32]);
        assert_eq!(v.accept(stream(1, 5)), Err(SignatureError::TooManyStreams));
        assert_eq!(v.streams().count(), 0);
    }

    /// The buckets spread the keys: no bucket gets more than twice its
    /// share of the 65,536 (sysid, compid) pairs of link 0.
    #[test]
    fn floor_buckets_spread_stream_keys() {
        let mut counts = [0usize; FLOOR_BUCKETS];
        for sysid in 0..=255u8 {
            for compid in 0..=255u8 {
                let s = StreamState {
                    link_id: 0,
                    sysid,
                    compid,
                    timestamp: 0,
                };
                counts[s.bucket()] += 1;
            }
        }
        let share = 65_536 / FLOOR_BUCKETS;
        assert!(
            counts.iter().all(|&c| c > share / 2 && c < share * 2),
            "{counts:?}"
        );
    }
}
