//! MAVLink 2 message signing: SHA-256 over a shared secret key, the frame
//! and a 48-bit timestamp, truncated to 6 bytes ([`signature`]); frames are
//! signed by a [`Signer`] and checked by a [`Verifier`], with replay
//! protection per (link id, system id, component id) stream as the MAVLink
//! spec (mavlink.io, "Message Signing") and the C library's
//! `mavlink_signature_check` do.
//!
//! Timestamps count 10 µs since 2015-01-01 00:00 UTC (`timestamp_now`, with
//! `std`). Replay protection rests on them, so where they start matters:
//!
//! - a [`Verifier`] on a live link starts from the clock
//!   (`Verifier::starting_now` (std), or [`Verifier::with_clock`] /
//!   [`Verifier::with_timestamp`] without `std`); [`Verifier::new`] starts
//!   at 0 and accepts any capture as a new stream, so it is for decoding
//!   recordings and for tests only;
//! - a [`Signer`] starts at the clock, and never below what it sent before a
//!   restart: the MAVLink spec asks signers to keep their timestamps
//!   increasing across restarts, which `signing::state` (with `std`) does
//!   with a small state file that also keeps the verifier's table.

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
}

impl fmt::Debug for Signer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // Never print the key.
        f.debug_struct("Signer")
            .field("link_id", &self.link_id)
            .field("timestamp", &self.timestamp)
            .finish_non_exhaustive()
    }
}

impl Signer {
    /// A signer for `link_id` whose next frame carries `timestamp`.
    pub fn new(key: [u8; 32], link_id: u8, timestamp: u64) -> Self {
        Signer {
            key,
            link_id,
            timestamp,
        }
    }

    /// The timestamp the next frame will carry.
    pub fn timestamp(&self) -> u64 {
        self.timestamp
    }

    /// Moves the timestamp forward to `now` (never back: receivers reject a
    /// stream whose timestamps do not increase).
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
            let meta = MessageMeta {
                id: 0x01_2345,
                name: "TEST",
                crc_extra: len,
                min_len: len,
                max_len: len,
                target_system_offset: None,
                target_component_offset: None,
                fields: &[],
            };
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
