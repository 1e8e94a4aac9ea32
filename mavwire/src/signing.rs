//! MAVLink 2 message signing: SHA-256 over a shared secret key, the frame
//! and a 48-bit timestamp, truncated to 6 bytes; replay protection per
//! (link id, system id, component id) stream, as the MAVLink spec and the C
//! library's `mavlink_signature_check` do.

use crate::frame::{Frame, SIGNATURE_LEN};
use core::fmt;
use sha2::{Digest, Sha256};

/// Seconds from 1970-01-01 to 2015-01-01 00:00 UTC, the signing epoch.
pub const EPOCH_UNIX_SECS: u64 = 1_420_070_400;

/// How much older than the newest timestamp seen a new stream may start
/// (one minute, in 10 µs units, as the C library).
pub const NEW_STREAM_WINDOW: u64 = 6_000_000;

/// The 6-byte signature of `signed_part` (header, payload, checksum) with
/// `link_id` and `timestamp` under `key`.
pub fn signature(key: &[u8; 32], signed_part: &[u8], link_id: u8, timestamp: u64) -> [u8; 6] {
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
    (since_unix.as_micros() as u64 / 10).saturating_sub(EPOCH_UNIX_SECS * 100_000)
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
        let sig = signature(&self.key, &frame[..at], self.link_id, self.timestamp);
        let block = &mut frame[at..];
        block[0] = self.link_id;
        block[1..7].copy_from_slice(&ts[..6]);
        block[7..13].copy_from_slice(&sig);
        self.timestamp += 1;
    }
}

/// Why a frame's signature was not accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SignatureError {
    /// The frame is not signed.
    Unsigned,
    /// The signature does not match the key.
    Mismatch,
    /// The timestamp is not newer than the last one of its stream.
    Replay,
    /// A new stream starts more than a minute before the newest timestamp.
    TooOld,
    /// Every stream slot is taken.
    TooManyStreams,
}

impl fmt::Display for SignatureError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            SignatureError::Unsigned => "frame is not signed",
            SignatureError::Mismatch => "signature does not match the key",
            SignatureError::Replay => "timestamp not newer than the stream's last (replay)",
            SignatureError::TooOld => "new stream's timestamp is more than a minute old",
            SignatureError::TooManyStreams => "no free signing stream slot",
        })
    }
}

#[cfg(feature = "std")]
impl std::error::Error for SignatureError {}

#[derive(Debug, Clone, Copy, Default)]
struct Stream {
    link_id: u8,
    sysid: u8,
    compid: u8,
    timestamp: u64,
}

/// Checks signatures of incoming frames, with replay protection for up to
/// `N` streams (the C library's default is 16).
#[derive(Clone)]
pub struct Verifier<const N: usize = 16> {
    key: [u8; 32],
    newest: u64,
    streams: [Stream; N],
    used: usize,
}

impl<const N: usize> fmt::Debug for Verifier<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Verifier")
            .field("newest", &self.newest)
            .field("streams", &self.used)
            .finish_non_exhaustive()
    }
}

impl<const N: usize> Verifier<N> {
    /// A verifier for `key` that has seen no timestamp yet.
    pub fn new(key: [u8; 32]) -> Self {
        Verifier {
            key,
            newest: 0,
            streams: [Stream::default(); N],
            used: 0,
        }
    }

    /// A verifier whose notion of "now" starts at `timestamp`, so streams
    /// starting more than a minute before it are rejected.
    pub fn with_timestamp(key: [u8; 32], timestamp: u64) -> Self {
        let mut v = Self::new(key);
        v.newest = timestamp;
        v
    }

    /// The newest timestamp accepted so far.
    pub fn newest_timestamp(&self) -> u64 {
        self.newest
    }

    /// Checks `frame`'s signature and, when it is good, records its
    /// timestamp for its stream.
    pub fn verify(&mut self, frame: &Frame<'_>) -> Result<(), SignatureError> {
        let block = frame.signature().ok_or(SignatureError::Unsigned)?;
        let expected = signature(
            &self.key,
            frame.signed_part(),
            block.link_id(),
            block.timestamp(),
        );
        // Not constant-time: the signature is public once sent, and a
        // mismatch only drops the frame.
        if expected != block.signature() {
            return Err(SignatureError::Mismatch);
        }
        let h = frame.header();
        let ts = block.timestamp();
        let key = (block.link_id(), h.sysid, h.compid);
        let found = self.streams[..self.used]
            .iter_mut()
            .find(|s| (s.link_id, s.sysid, s.compid) == key);
        match found {
            Some(stream) => {
                if ts <= stream.timestamp {
                    return Err(SignatureError::Replay);
                }
                stream.timestamp = ts;
            }
            None => {
                if ts + NEW_STREAM_WINDOW < self.newest {
                    return Err(SignatureError::TooOld);
                }
                let slot = self
                    .streams
                    .get_mut(self.used)
                    .ok_or(SignatureError::TooManyStreams)?;
                *slot = Stream {
                    link_id: key.0,
                    sysid: key.1,
                    compid: key.2,
                    timestamp: ts,
                };
                self.used += 1;
            }
        }
        self.newest = self.newest.max(ts);
        Ok(())
    }
}
