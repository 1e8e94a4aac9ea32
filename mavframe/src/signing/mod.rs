//! MAVLink 2 message signing: SHA-256 over a shared secret key, the frame
//! and a 48-bit timestamp, truncated to 6 bytes ([`signature`]); frames are
//! signed by a [`Signer`] and checked by a [`Verifier`], with replay
//! protection per (link id, system id, component id) stream as the MAVLink
//! spec (mavlink.io, "Message Signing") and the C library's
//! `mavlink_signature_check` do.
//!
//! # Timestamps
//!
//! Timestamps count 10 µs since 2015-01-01 00:00 UTC (`timestamp_now`, with
//! `std`; a clock before 2015 reads 0). Replay protection rests on them, and
//! clocks disagree (a companion board without a real-time clock boots in
//! 1970), so these are the rules, and what each is for.
//!
//! **What a verifier accepts.** A signed frame with timestamp `t` whose
//! signature matches the key is accepted when `t` passes its stream's check
//! (see [`Verifier`] for the table and its eviction):
//!
//! - a stream the verifier knows: `t` is greater than the stream's last
//!   accepted timestamp, however old `t` is (else [`SignatureError::Replay`]);
//! - a new stream: `t` is at most [`NEW_STREAM_WINDOW`] (one minute) before
//!   the verifier's notion of now (else [`SignatureError::TooOld`]), and
//!   above its bucket's eviction floor (else [`SignatureError::BelowFloor`]);
//! - there is no upper bound: a frame from the future is accepted, as in the
//!   C library and pymavlink. A receiver whose clock is behind (booted in
//!   1970, an hour slow) must accept a correctly clocked peer to learn the
//!   time from it (below); only key holders can sign, and a key holder can
//!   sign anything anyway.
//!
//! The timestamp is checked before the signature (a refused timestamp costs
//! no SHA-256), so a frame refused for it ([`SignatureError::is_stale`]) is
//! not known to be forged: it is a replay, a capture, or a genuine frame
//! from a peer whose clock is behind. Parsers count these apart from
//! signatures that do not match the key (`parser::Stats::stale_timestamp`
//! and `bad_signature`; frames of ids the dialect does not know, whose
//! checksum cannot vouch for them, count as bad signatures either way).
//!
//! **The verifier's notion of now** ([`Verifier::newest_timestamp`]) is the
//! greatest of: its start (the clock, or a saved value), every timestamp it
//! accepted, and, with a clock, the clock read whenever a new stream
//! appears. A clock that is behind never lowers it, and once a frame from a
//! correctly clocked peer is accepted, it is that peer's time: captures more
//! than a minute older than the peer's frames are then refused as new
//! streams, although the local clock would have called them fresh.
//!
//! **The window** is one minute ([`NEW_STREAM_WINDOW`]), the spec's and the
//! C library's `MAVLINK_SIGNING_TIMESTAMP_LIMIT`: a verifier that does not
//! know a stream (a fresh start without a state file, a stream evicted or
//! seen only on another link) accepts its captures up to a minute old, once.
//! A longer window would widen that; a shorter one would refuse peers whose
//! clocks are a little behind before they adopt (below).
//!
//! **A signer never goes back:** every frame carries a timestamp greater
//! than the previous one ([`Signer::advance_to`] only raises it); with a
//! clock (`Framer`, the connections) it keeps up with the clock before each
//! frame.
//!
//! **A signer adopts the newest timestamp its link verified:** after a frame
//! with timestamp `t` is accepted by the link's verifier, the link's signer
//! signs its next frame at `max(own, t)` or later (the C library's
//! `mavlink_signature_check` sets its signing timestamp so). The front ends
//! do it on every link that verifies and signs (the link core of
//! `crate::link` under the router's links, the blocking connections, split
//! halves too, and the `embedded` `Link`s); elsewhere call
//! `Framer::adopt_from` with the parser's verifier.
//! So a clock skew between two signers of the key does not stop their link:
//! the frames of the one ahead are accepted by the one behind (no upper
//! bound), which jumps forward, and its next frames are accepted by the one
//! ahead. Until then, the one ahead refuses the frames of the one behind as
//! stale (if the skew is over a minute).
//!
//! Limits, as they follow from the rules:
//!
//! - If neither side sends before it has accepted a frame of the other (a
//!   listener that waits for a peer to answer), and the clocks differ by more
//!   than a minute, the side ahead refuses the other's frames as stale and
//!   neither adopts: the side ahead must be heard first. A parser under
//!   `Unsigned::Accept` therefore returns a frame of a known id that the
//!   key signed but whose timestamp is stale as unauthenticated (as it
//!   would an unsigned one; [`Verifier::signed_with_key`] tells it, at the
//!   cost of a SHA-256), so the listener can answer its sender with a
//!   signed frame of its own without trusting it: `fbwag_delegation`'s
//!   nodes send their heartbeat, once a second at most, to such a sender
//!   of the peer's ids while they answer nobody yet.
//! - A key holder whose clock is far ahead (or who signs ahead on purpose)
//!   drags every adopting signer with it, and verifiers that accepted its
//!   frames then refuse correctly clocked new streams as too old until those
//!   adopt in turn (a new stream must be heard by them first). The C library
//!   does the same: the protocol trusts the key.
//! - A verifier whose clock is behind and that has no saved state accepts
//!   any capture less than a minute older than its clock, once per stream
//!   (in 1970: every capture). Keep the state across restarts
//!   (`signing::state`, with `std`), which also keeps the stream table.
//!
//! **Starting points.** A [`Verifier`] on a live link starts from the clock
//! (`Verifier::starting_now` (std), or [`Verifier::with_clock`] /
//! [`Verifier::with_timestamp`] without `std`); [`Verifier::new`] starts at 0
//! and accepts any capture as a new stream, so it is for decoding recordings
//! and for tests only. A [`Signer`] starts at the clock and never below what
//! it signed before a restart (the spec asks signers to keep their
//! timestamps increasing across restarts): `signing::state` (with `std`)
//! keeps that bound, and the verifier's table, in a small state file,
//! without moving the signer ahead at each restart (see there).

use crate::frame::SIGNATURE_LEN;
use core::fmt;
use sha2::digest::generic_array::{typenum::U64, GenericArray};
use sha2::{Digest, Sha256};

/// Seconds from 1970-01-01 to 2015-01-01 00:00 UTC, the signing epoch.
pub const EPOCH_UNIX_SECS: u64 = 1_420_070_400;

/// How far behind the verifier's notion of now a new stream may start (one
/// minute, in 10 µs units, as the spec and the C library).
pub const NEW_STREAM_WINDOW: u64 = 6_000_000;

#[cfg(feature = "std")]
pub mod state;
mod verifier;

pub use verifier::{StreamState, Verifier, FLOOR_BUCKETS};

/// SHA-256's initial state (FIPS 180-4, 5.3.3).
const SHA256_H0: [u32; 8] = [
    0x6a09_e667,
    0xbb67_ae85,
    0x3c6e_f372,
    0xa54f_f53a,
    0x510e_527f,
    0x9b05_688c,
    0x1f83_d9ab,
    0x5be0_cd19,
];

/// Blocks of the padded message [`signature`] hashes in one call: enough for
/// the signed part of any frame (header, 255-byte payload, checksum: 267
/// bytes; with the key, link id, timestamp and padding, 315 bytes).
const MAX_BLOCKS: usize = 5;

type Block = GenericArray<u8, U64>;

/// The 6-byte signature of `signed_part` (header, payload, checksum) with
/// `link_id` and `timestamp` under `key`: the first 6 bytes of
/// SHA-256(key ‖ signed part ‖ link id ‖ timestamp's low 6 bytes).
pub fn signature(key: &[u8; 32], signed_part: &[u8], link_id: u8, timestamp: u64) -> [u8; 6] {
    let ts = timestamp.to_le_bytes();
    let tail = [link_id, ts[0], ts[1], ts[2], ts[3], ts[4], ts[5], 0x80];
    sha256_prefix(key, signed_part, &tail)
        .unwrap_or_else(|| signature_streamed(key, signed_part, link_id, timestamp))
}

/// The first 6 bytes of SHA-256(key ‖ `body` ‖ `tail` without its last
/// byte); `tail` ends with the padding's 0x80 (`[0x80]` when `body` is the
/// frame's bytes up to and including the timestamp). `None` when the message
/// takes more than [`MAX_BLOCKS`] blocks (longer than any frame).
///
/// For speed, the padded message is laid out in stack blocks and given to
/// SHA-256's compression function (sha2's, with SHA-NI where the CPU has it)
/// in one call, without the `Sha256` hasher's block buffer and its
/// bookkeeping: 5–10 % of a signed frame's encode, measured. The tests check
/// it against `sha2::Sha256` for every length up to past the longest frame.
#[inline]
pub(crate) fn sha256_prefix(key: &[u8; 32], body: &[u8], tail: &[u8]) -> Option<[u8; 6]> {
    let tail_at = 32 + body.len();
    let end = tail_at + tail.len();
    // The padded message: the bytes, 0x80, zeros, the length in bits (8).
    let blocks = (end + 8).div_ceil(64);
    if blocks > MAX_BLOCKS {
        return None;
    }
    let bits = ((end as u64 - 1) * 8).to_be_bytes();
    let mut buf = [Block::default(); MAX_BLOCKS];
    for (i, block) in buf[..blocks].iter_mut().enumerate() {
        let (lo, hi) = (i * 64, i * 64 + 64);
        let block: &mut [u8] = block;
        if i == 0 {
            block[..32].copy_from_slice(key);
        }
        // The bytes of `body`, then of `tail`, that fall in this block.
        let (from, to) = (lo.max(32), hi.min(tail_at));
        if from < to {
            block[from - lo..to - lo].copy_from_slice(&body[from - 32..to - 32]);
        }
        let (from, to) = (lo.max(tail_at), hi.min(end));
        if from < to {
            block[from - lo..to - lo].copy_from_slice(&tail[from - tail_at..to - tail_at]);
        }
    }
    buf[blocks - 1][56..].copy_from_slice(&bits);
    let mut state = SHA256_H0;
    sha2::compress256(&mut state, &buf[..blocks]);
    let (a, b) = (state[0].to_be_bytes(), state[1].to_be_bytes());
    Some([a[0], a[1], a[2], a[3], b[0], b[1]])
}

/// [`signature`] for a signed part longer than any frame's, with the hasher.
#[cold]
pub(crate) fn signature_streamed(
    key: &[u8; 32],
    signed_part: &[u8],
    link_id: u8,
    timestamp: u64,
) -> [u8; 6] {
    let ts = timestamp.to_le_bytes();
    let mut h = Sha256::new();
    h.update(key);
    h.update(signed_part);
    h.update([link_id]);
    h.update(&ts[..6]);
    let digest = h.finalize();
    let mut out = [0u8; 6];
    out.copy_from_slice(&digest[..6]);
    out
}

/// The current time as a signing timestamp (10 µs units since 2015-01-01).
#[cfg(feature = "std")]
pub fn timestamp_now() -> u64 {
    let since_unix = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap_or_default();
    // In u64 (`as_micros` is a u128); a clock before 2015 gives 0.
    match since_unix.as_secs().checked_sub(EPOCH_UNIX_SECS) {
        Some(secs) => secs * 100_000 + u64::from(since_unix.subsec_nanos() / 10_000),
        None => 0,
    }
}

/// Signs outgoing frames on one link.
#[derive(Clone)]
pub struct Signer {
    key: [u8; 32],
    link_id: u8,
    timestamp: u64,
    /// Above every timestamp signed (see [`Signer::signed_below`]).
    signed_below: u64,
}

impl fmt::Debug for Signer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Never print the key.
        f.debug_struct("Signer")
            .field("link_id", &self.link_id)
            .field("timestamp", &self.timestamp)
            .field("signed_below", &self.signed_below)
            .finish_non_exhaustive()
    }
}

impl Signer {
    /// A signer for `link_id` whose next frame carries `timestamp`, that
    /// has signed nothing yet ([`signed_below`](Self::signed_below) 0).
    pub fn new(key: [u8; 32], link_id: u8, timestamp: u64) -> Self {
        Signer {
            key,
            link_id,
            timestamp,
            signed_below: 0,
        }
    }

    /// The timestamp the next frame will carry.
    pub fn timestamp(&self) -> u64 {
        self.timestamp
    }

    /// One past the greatest timestamp signed (0: none): every frame this
    /// signer signed, and for one restored from a state file
    /// (`signing::state`) every frame signed before the restart, carries a
    /// smaller one. Unlike [`timestamp`](Self::timestamp), it does not move
    /// when the signer adopts a timestamp or keeps up with a clock: it is
    /// what a restart must stay above, and no more.
    pub fn signed_below(&self) -> u64 {
        self.signed_below
    }

    /// Moves the timestamp forward to `now` (never back: receivers reject a
    /// stream whose timestamps do not increase). Also how a signer adopts a
    /// timestamp its link verified (see the module docs).
    pub fn advance_to(&mut self, now: u64) {
        self.timestamp = self.timestamp.max(now);
    }

    /// Link id of this signer.
    pub fn link_id(&self) -> u8 {
        self.link_id
    }

    /// Fills the last 13 bytes of `frame` (a whole MAVLink 2 frame with the
    /// signed flag set and its checksum written) with the signature block,
    /// then advances the timestamp. Frames shorter than a signature block are
    /// left alone.
    pub fn sign_frame(&mut self, frame: &mut [u8]) {
        if frame.len() < SIGNATURE_LEN {
            return;
        }
        let at = frame.len() - SIGNATURE_LEN;
        let ts = self.timestamp.to_le_bytes();
        let (signed, block) = frame.split_at_mut(at + 7);
        signed[at] = self.link_id;
        signed[at + 1..].copy_from_slice(&ts[..6]);
        // Hashed: the key, then the frame's bytes up to the timestamp.
        let sig = sha256_prefix(&self.key, signed, &[0x80]).unwrap_or_else(|| {
            signature_streamed(&self.key, &signed[..at], self.link_id, self.timestamp)
        });
        block.copy_from_slice(&sig);
        self.timestamp += 1;
        self.signed_below = self.signed_below.max(self.timestamp);
    }
}

/// Why a frame's signature was not accepted (see [`Verifier`] for the
/// rules).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum SignatureError {
    /// The frame is not signed.
    Unsigned,
    /// The signature does not match the key.
    Mismatch,
    /// The timestamp is not newer than the last one of its stream.
    Replay,
    /// A new stream starts more than a minute ([`NEW_STREAM_WINDOW`]) before
    /// the verifier's notion of now.
    TooOld,
    /// A new stream's timestamp is not newer than the floor that evicted
    /// streams left in its bucket: an old frame of an evicted stream, or a
    /// signer whose clock is behind one that was evicted.
    BelowFloor,
    /// The verifier has no stream slot at all (`Verifier<0>`); with one or
    /// more, the least recently used stream is evicted instead.
    TooManyStreams,
}

impl fmt::Display for SignatureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SignatureError::Unsigned => "frame is not signed",
            SignatureError::Mismatch => "signature does not match the key",
            SignatureError::Replay => "timestamp not newer than the stream's last (replay)",
            SignatureError::TooOld => "new stream's timestamp is more than a minute old",
            SignatureError::BelowFloor => {
                "new stream's timestamp not newer than evicted streams' (replay or clock behind)"
            }
            SignatureError::TooManyStreams => "verifier has no stream slots",
        })
    }
}

impl SignatureError {
    /// Whether the frame was refused for its timestamp ([`Replay`],
    /// [`TooOld`], [`BelowFloor`]): a replay, or a frame from a signer
    /// whose clock is behind. The timestamp is checked first, so such a
    /// frame is not known to be forged (see the module docs).
    ///
    /// [`Replay`]: SignatureError::Replay
    /// [`TooOld`]: SignatureError::TooOld
    /// [`BelowFloor`]: SignatureError::BelowFloor
    pub fn is_stale(&self) -> bool {
        matches!(
            self,
            SignatureError::Replay | SignatureError::TooOld | SignatureError::BelowFloor
        )
    }
}

impl core::error::Error for SignatureError {}

#[cfg(test)]
mod tests {
    use super::*;
    use sha2::{Digest, Sha256};

    /// The oracle: the well-kept hasher, fed the pieces as the spec lists them.
    fn oracle(key: &[u8; 32], signed_part: &[u8], link_id: u8, timestamp: u64) -> [u8; 6] {
        let mut h = Sha256::new();
        h.update(key);
        h.update(signed_part);
        h.update([link_id]);
        h.update(&timestamp.to_le_bytes()[..6]);
        h.finalize()[..6].try_into().unwrap()
    }

    #[test]
    fn signature_equals_sha256_for_every_length() {
        let keys = [
            [0u8; 32],
            [0xff; 32],
            core::array::from_fn(|i| (i * 37 + 1) as u8),
        ];
        let timestamps = [0, 1, 0x1234_5678_9abc, 0xffff_ffff_ffff, u64::MAX];
        let data: [u8; 400] = core::array::from_fn(|i| (i * 131 + 7) as u8);
        // Every signed-part length of a frame (0..=267) and beyond, into the
        // hasher fallback (more than 5 blocks from 273 bytes on).
        for len in 0..=400 {
            for (k, key) in keys.iter().enumerate() {
                for (t, &ts) in timestamps.iter().enumerate() {
                    let part = &data[(k + t) % 3..][..len.min(397)];
                    let link = (len + k + t) as u8;
                    assert_eq!(
                        signature(key, part, link, ts),
                        oracle(key, part, link, ts),
                        "len {} key {k} ts {ts:#x}",
                        part.len()
                    );
                }
            }
        }
    }

    /// Frames of every payload length (1..=255), signed by `Signer` through
    /// `frame::finish`: the block holds the link id, the timestamp and the
    /// oracle's signature; `Verifier` accepts each, and rejects a replay and
    /// a flipped bit.
    #[test]
    fn signed_frames_match_the_oracle_and_verify() {
        use crate::frame::{finish, Frame, Header, Version, MAX_FRAME_LEN};
        use crate::message::MessageMeta;
        let key: [u8; 32] = core::array::from_fn(|i| (i * 11 + 5) as u8);
        let mut signer = Signer::new(key, 7, 0xffff_ffff_0000);
        let mut verifier = Verifier::<4>::new(key);
        let mut buf = [0u8; MAX_FRAME_LEN];
        for len in 1..=255u8 {
            let meta = MessageMeta::new(0x01_2345, "TEST", len, len, len, &[]);
            for (i, b) in buf[10..10 + len as usize].iter_mut().enumerate() {
                *b = (i as u8).wrapping_mul(29) | 1;
            }
            let ts = signer.timestamp();
            let header = Header {
                seq: len,
                sysid: 1,
                compid: 2,
            };
            let n = finish(
                Version::V2,
                header,
                &meta,
                len as usize,
                Some(&mut signer),
                &mut buf,
            )
            .unwrap();
            let (part, block) = buf[..n].split_at(n - SIGNATURE_LEN);
            assert_eq!(block[0], 7);
            assert_eq!(&block[1..7], &ts.to_le_bytes()[..6]);
            assert_eq!(block[7..], oracle(&key, part, 7, ts), "payload {len}");
            assert_eq!(signer.timestamp(), ts + 1);
            let mut bad = buf;
            bad[n - 1] ^= 1;
            let forged = Frame::new_checked(&bad[..n]).unwrap();
            assert_eq!(verifier.verify(&forged), Err(SignatureError::Mismatch));
            let frame = Frame::new_checked(&buf[..n]).unwrap();
            assert_eq!(verifier.verify(&frame), Ok(()), "payload {len}");
            assert_eq!(verifier.verify(&frame), Err(SignatureError::Replay));
            // A replayed timestamp is refused before the signature is checked.
            assert_eq!(verifier.verify(&forged), Err(SignatureError::Replay));
        }
    }

    #[cfg(feature = "std")]
    #[test]
    fn timestamp_now_is_the_clock_in_10us_units_since_2015() {
        let before = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_micros() as u64
            / 10
            - EPOCH_UNIX_SECS * 100_000;
        let now = timestamp_now();
        let after = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_micros() as u64
            / 10
            - EPOCH_UNIX_SECS * 100_000;
        assert!(before <= now && now <= after, "{before} {now} {after}");
    }
}
