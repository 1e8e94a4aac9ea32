//! MAVLink 1 and 2 frames: a view over frame bytes, and encoding into a
//! caller's buffer.
//!
//! ```text
//! MAVLink 2: FD len incompat compat seq sysid compid id0 id1 id2 payload… crc0 crc1 [link ts0…ts5 sig0…sig5]
//! MAVLink 1: FE len seq sysid compid id payload… crc0 crc1
//! ```
//!
//! [`Frame::new_checked`] checks the start byte and that the buffer holds the
//! whole frame its header announces; after that no accessor can panic. The
//! checksum and signature are separate checks ([`Frame::check_crc`],
//! [`crate::signing`]), because verifying them needs the dialect and a key.

use crate::crc::{frame_crc, Crc};
use crate::message::{Encode, MessageMeta};
use crate::signing::Signer;
use core::fmt;

/// Start byte of a MAVLink 1 frame.
pub const STX_V1: u8 = 0xFE;
/// Start byte of a MAVLink 2 frame.
pub const STX_V2: u8 = 0xFD;
/// MAVLink 1 header length, start byte included.
pub const HEADER_LEN_V1: usize = 6;
/// MAVLink 2 header length, start byte included.
pub const HEADER_LEN_V2: usize = 10;
/// Checksum length.
pub const CHECKSUM_LEN: usize = 2;
/// MAVLink 2 signature length: link id, 48-bit timestamp, 48-bit signature.
pub const SIGNATURE_LEN: usize = 13;
/// Longest possible frame (signed MAVLink 2 with a 255-byte payload).
pub const MAX_FRAME_LEN: usize = HEADER_LEN_V2 + 255 + CHECKSUM_LEN + SIGNATURE_LEN;
/// Incompatibility flag: the frame is signed.
pub const IFLAG_SIGNED: u8 = 0x01;
/// Every incompatibility flag this implementation understands; a frame with
/// another bit set must be dropped (MAVLink 2 spec, as pymavlink and C do).
pub const IFLAG_KNOWN: u8 = IFLAG_SIGNED;

/// Protocol version of a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Version {
    /// MAVLink 1 (start byte 0xFE, 8-bit ids, no extensions).
    V1,
    /// MAVLink 2 (start byte 0xFD, 24-bit ids, truncated payloads, signing).
    V2,
}

/// The sender-chosen header fields.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct Header {
    /// Sequence number (wraps at 255).
    pub seq: u8,
    /// Sender system id.
    pub sysid: u8,
    /// Sender component id.
    pub compid: u8,
}

/// Why bytes are not a frame, or a frame cannot be built.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameError {
    /// The first byte is not a start byte.
    NotStart,
    /// The buffer ends before the frame does; `needed` bytes make it whole.
    Incomplete {
        /// Total frame length announced by the header (or the header's own
        /// length while it is incomplete).
        needed: usize,
    },
    /// Incompatibility flags this implementation does not understand.
    UnknownIncompatFlags(u8),
    /// MAVLink 1 carries 8-bit ids only.
    IdTooLargeForV1(u32),
    /// The output buffer is too small.
    BufferTooSmall {
        /// Bytes the frame needs.
        needed: usize,
    },
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            FrameError::NotStart => write!(f, "not a MAVLink start byte"),
            FrameError::Incomplete { needed } => {
                write!(f, "incomplete frame: {needed} bytes needed")
            }
            FrameError::UnknownIncompatFlags(b) => {
                write!(f, "unknown incompatibility flags {b:#04x}")
            }
            FrameError::IdTooLargeForV1(id) => {
                write!(f, "message id {id} does not fit MAVLink 1 (at most 255)")
            }
            FrameError::BufferTooSmall { needed } => {
                write!(f, "output buffer too small: {needed} bytes needed")
            }
        }
    }
}

#[cfg(feature = "std")]
impl std::error::Error for FrameError {}

/// The length of the frame starting at `bytes[0]`, from its header.
///
/// `Err(Incomplete)` while the header itself is not complete (the needed
/// length is then the header's), `Err(NotStart)` if `bytes[0]` is not a start
/// byte. Unknown incompatibility flags are reported too: the frame cannot be
/// delimited reliably, since the flags may change its layout.
#[inline]
pub fn frame_len(bytes: &[u8]) -> Result<usize, FrameError> {
    match bytes.first() {
        Some(&STX_V2) => {
            if bytes.len() < HEADER_LEN_V2 {
                return Err(FrameError::Incomplete {
                    needed: HEADER_LEN_V2,
                });
            }
            let flags = bytes[2];
            if flags & !IFLAG_KNOWN != 0 {
                return Err(FrameError::UnknownIncompatFlags(flags));
            }
            let sig = if flags & IFLAG_SIGNED != 0 {
                SIGNATURE_LEN
            } else {
                0
            };
            Ok(HEADER_LEN_V2 + bytes[1] as usize + CHECKSUM_LEN + sig)
        }
        Some(&STX_V1) => match bytes.get(1) {
            Some(&len) => Ok(HEADER_LEN_V1 + len as usize + CHECKSUM_LEN),
            None => Err(FrameError::Incomplete {
                needed: HEADER_LEN_V1,
            }),
        },
        Some(_) => Err(FrameError::NotStart),
        None => Err(FrameError::Incomplete {
            needed: HEADER_LEN_V2.min(HEADER_LEN_V1),
        }),
    }
}

/// A whole frame (v1 or v2) over its bytes.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Frame<'a> {
    bytes: &'a [u8],
}

impl<'a> Frame<'a> {
    /// The frame at the start of `bytes`; bytes after it are not part of it.
    pub fn new_checked(bytes: &'a [u8]) -> Result<Frame<'a>, FrameError> {
        let len = frame_len(bytes)?;
        match bytes.get(..len) {
            Some(bytes) => Ok(Frame { bytes }),
            None => Err(FrameError::Incomplete { needed: len }),
        }
    }

    /// The frame over `bytes`, which the caller has delimited with
    /// [`frame_len`] (`bytes.len() == frame_len(bytes)`): what
    /// [`Frame::new_checked`] would return, without checking again.
    #[inline]
    pub(crate) fn from_delimited(bytes: &'a [u8]) -> Frame<'a> {
        debug_assert_eq!(frame_len(bytes), Ok(bytes.len()));
        Frame { bytes }
    }

    /// Protocol version.
    #[inline]
    pub fn version(&self) -> Version {
        if self.bytes[0] == STX_V2 {
            Version::V2
        } else {
            Version::V1
        }
    }

    #[inline]
    fn header_len(&self) -> usize {
        match self.version() {
            Version::V2 => HEADER_LEN_V2,
            Version::V1 => HEADER_LEN_V1,
        }
    }

    /// The frame's bytes.
    #[inline]
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// Payload length as sent (MAVLink 2 payloads may be truncated).
    #[inline]
    pub fn payload_len(&self) -> usize {
        self.bytes[1] as usize
    }

    /// Incompatibility flags (0 for MAVLink 1).
    #[inline]
    pub fn incompat_flags(&self) -> u8 {
        match self.version() {
            Version::V2 => self.bytes[2],
            Version::V1 => 0,
        }
    }

    /// Compatibility flags (0 for MAVLink 1).
    #[inline]
    pub fn compat_flags(&self) -> u8 {
        match self.version() {
            Version::V2 => self.bytes[3],
            Version::V1 => 0,
        }
    }

    /// The sender-chosen header fields.
    #[inline]
    pub fn header(&self) -> Header {
        // seq, sysid, compid follow the flags in MAVLink 2, the length in 1.
        let at = match self.version() {
            Version::V2 => 4,
            Version::V1 => 2,
        };
        Header {
            seq: self.bytes[at],
            sysid: self.bytes[at + 1],
            compid: self.bytes[at + 2],
        }
    }

    /// Message id.
    #[inline]
    pub fn msg_id(&self) -> u32 {
        match self.version() {
            Version::V2 => u32::from_le_bytes([self.bytes[7], self.bytes[8], self.bytes[9], 0]),
            Version::V1 => self.bytes[5] as u32,
        }
    }

    /// The payload bytes as sent.
    #[inline]
    pub fn payload(&self) -> &'a [u8] {
        let start = self.header_len();
        &self.bytes[start..start + self.payload_len()]
    }

    /// The checksum carried by the frame.
    #[inline]
    pub fn checksum(&self) -> u16 {
        let at = self.header_len() + self.payload_len();
        u16::from_le_bytes([self.bytes[at], self.bytes[at + 1]])
    }

    /// The checksum the frame should carry for a message with `crc_extra`.
    pub fn computed_checksum(&self, crc_extra: u8) -> u16 {
        frame_crc(
            &self.bytes[1..self.header_len() + self.payload_len()],
            crc_extra,
        )
    }

    /// True when the carried checksum matches `crc_extra`'s.
    #[inline]
    pub fn check_crc(&self, crc_extra: u8) -> bool {
        let end = self.header_len() + self.payload_len();
        match (
            self.bytes.get(1..end),
            self.bytes.get(end..end + CHECKSUM_LEN),
        ) {
            (Some(covered), Some(&[lo, hi])) => {
                frame_crc(covered, crc_extra) == u16::from_le_bytes([lo, hi])
            }
            _ => false,
        }
    }

    /// True for a signed MAVLink 2 frame.
    #[inline]
    pub fn is_signed(&self) -> bool {
        self.incompat_flags() & IFLAG_SIGNED != 0
    }

    /// The signature block of a signed frame.
    pub fn signature(&self) -> Option<SignatureBlock<'a>> {
        if !self.is_signed() {
            return None;
        }
        let at = self.bytes.len() - SIGNATURE_LEN;
        Some(SignatureBlock {
            bytes: &self.bytes[at..],
        })
    }

    /// The bytes a signature covers before the key-independent part: header,
    /// payload and checksum.
    pub(crate) fn signed_part(&self) -> &'a [u8] {
        &self.bytes[..self.bytes.len() - SIGNATURE_LEN]
    }
}

impl fmt::Debug for Frame<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let h = self.header();
        f.debug_struct("Frame")
            .field("version", &self.version())
            .field("seq", &h.seq)
            .field("sysid", &h.sysid)
            .field("compid", &h.compid)
            .field("msg_id", &self.msg_id())
            .field("payload_len", &self.payload_len())
            .field("signed", &self.is_signed())
            .finish()
    }
}

/// The 13-byte signature block of a signed MAVLink 2 frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SignatureBlock<'a> {
    bytes: &'a [u8],
}

impl<'a> SignatureBlock<'a> {
    /// Link id chosen by the signer.
    pub fn link_id(&self) -> u8 {
        self.bytes[0]
    }

    /// Timestamp in 10 µs units since 2015-01-01 00:00 UTC (48 bits).
    pub fn timestamp(&self) -> u64 {
        let mut t = [0u8; 8];
        t[..6].copy_from_slice(&self.bytes[1..7]);
        u64::from_le_bytes(t)
    }

    /// The 6-byte signature (truncated SHA-256).
    pub fn signature(&self) -> &'a [u8] {
        &self.bytes[7..13]
    }

    /// The whole block.
    pub fn as_bytes(&self) -> &'a [u8] {
        self.bytes
    }
}

/// Length of a MAVLink 2 payload once trailing zeros are dropped (one byte
/// is always kept, as the spec and the C library require).
pub fn truncated_len(payload: &[u8]) -> usize {
    payload.iter().rposition(|&b| b != 0).map_or(1, |i| i + 1)
}

/// Encodes a message into `out` and returns the frame length.
///
/// MAVLink 2 payloads lose their trailing zeros (at least one byte stays);
/// MAVLink 1 carries the base fields only (extensions are not sent) and
/// rejects ids above 255. `signer` signs a MAVLink 2 frame and advances its
/// timestamp; it is ignored for MAVLink 1, which has no signing.
pub fn encode<M: Encode + ?Sized>(
    version: Version,
    header: Header,
    message: &M,
    signer: Option<&mut Signer>,
    out: &mut [u8],
) -> Result<usize, FrameError> {
    let meta = message.meta();
    let start = match version {
        Version::V2 => HEADER_LEN_V2,
        Version::V1 => HEADER_LEN_V1,
    };
    let payload =
        out.get_mut(start..start + meta.max_len as usize)
            .ok_or(FrameError::BufferTooSmall {
                needed: start + meta.max_len as usize + CHECKSUM_LEN,
            })?;
    message
        .emit_payload(payload)
        .map_err(|e| FrameError::BufferTooSmall {
            needed: start + e.needed,
        })?;
    finish(version, header, meta, meta.max_len as usize, signer, out)
}

/// Encodes a payload already written at its place in `out` (`out[10..]` for
/// MAVLink 2, `out[6..]` for MAVLink 1, `written` bytes long): truncates,
/// fills in the header, checksum and signature, returns the frame length.
/// This is the encoder for messages known only by their table row (routers,
/// JSON tools).
pub fn finish(
    version: Version,
    header: Header,
    meta: &MessageMeta,
    written: usize,
    signer: Option<&mut Signer>,
    out: &mut [u8],
) -> Result<usize, FrameError> {
    match version {
        Version::V2 => {
            let max = (meta.max_len as usize).min(written);
            let len = out
                .get(HEADER_LEN_V2..HEADER_LEN_V2 + max)
                .map(truncated_len)
                .ok_or(FrameError::BufferTooSmall {
                    needed: HEADER_LEN_V2 + max,
                })?;
            let sign = signer.is_some();
            let total = HEADER_LEN_V2 + len + CHECKSUM_LEN + if sign { SIGNATURE_LEN } else { 0 };
            if out.len() < total {
                return Err(FrameError::BufferTooSmall { needed: total });
            }
            let id = meta.id.to_le_bytes();
            out[..HEADER_LEN_V2].copy_from_slice(&[
                STX_V2,
                len as u8,
                if sign { IFLAG_SIGNED } else { 0 },
                0,
                header.seq,
                header.sysid,
                header.compid,
                id[0],
                id[1],
                id[2],
            ]);
            let crc_at = HEADER_LEN_V2 + len;
            let crc = frame_crc(&out[1..crc_at], meta.crc_extra);
            out[crc_at..crc_at + 2].copy_from_slice(&crc.to_le_bytes());
            if let Some(signer) = signer {
                signer.sign_frame(&mut out[..total]);
            }
            Ok(total)
        }
        Version::V1 => {
            let id = u8::try_from(meta.id).map_err(|_| FrameError::IdTooLargeForV1(meta.id))?;
            // Base fields only; a short write is zero-filled.
            let len = meta.min_len as usize;
            let total = HEADER_LEN_V1 + len + CHECKSUM_LEN;
            if out.len() < total {
                return Err(FrameError::BufferTooSmall { needed: total });
            }
            if written < len {
                out[HEADER_LEN_V1 + written..HEADER_LEN_V1 + len].fill(0);
            }
            out[..HEADER_LEN_V1].copy_from_slice(&[
                STX_V1,
                len as u8,
                header.seq,
                header.sysid,
                header.compid,
                id,
            ]);
            let mut crc = Crc::new();
            crc.update(&out[1..HEADER_LEN_V1 + len]);
            crc.update(&[meta.crc_extra]);
            out[HEADER_LEN_V1 + len..total].copy_from_slice(&crc.get().to_le_bytes());
            Ok(total)
        }
    }
}
