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

mod buf;
pub use buf::FrameBuf;

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
#[non_exhaustive]
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
    /// MAVLink 2 carries 24-bit ids only.
    IdTooLarge(u32),
    /// MAVLink 1 has no compatibility flags.
    NoCompatFlagsInV1(u8),
    /// A signature was set on an unsigned frame.
    NotSigned,
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
            FrameError::IdTooLarge(id) => {
                write!(f, "message id {id} does not fit 24 bits")
            }
            FrameError::NoCompatFlagsInV1(b) => {
                write!(
                    f,
                    "MAVLink 1 has no compatibility flags (asked for {b:#04x})"
                )
            }
            FrameError::NotSigned => write!(f, "the frame is not signed"),
            FrameError::BufferTooSmall { needed } => {
                write!(f, "output buffer too small: {needed} bytes needed")
            }
        }
    }
}

impl core::error::Error for FrameError {}

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

/// A whole frame (v1 or v2) over a buffer, in the smoltcp style: `T` is
/// anything that derefs to bytes (`&[u8]`, `&mut [u8]`, [`FrameBuf`],
/// `Vec<u8>`...). Reading needs `T: AsRef<[u8]>`, the setters
/// `T: AsMut<[u8]>` too.
///
/// [`Frame::new_checked`] checks the start byte and that the buffer holds the
/// whole frame its header announces; after that no accessor can panic. The
/// buffer may run on past the frame: the frame's own length
/// ([`Frame::frame_len`]) comes from its header, and [`Frame::as_bytes`] ends
/// there. The setters change neither the length nor the flags, so a checked
/// frame stays whole.
///
/// ```
/// use mavframe::frame::{Frame, Header, Version};
///
/// // A MAVLink 2 HEARTBEAT (id 0, crc_extra 50) with a 9-byte payload.
/// let mut buf = [0u8; 64];
/// let mut frame = Frame::new_v2(&mut buf[..], 9, 0, 0).unwrap();
/// frame.set_header(Header { seq: 7, sysid: 1, compid: 1 });
/// frame.set_msg_id(0).unwrap();
/// frame.payload_mut()[4] = 1; // type: fixed wing
/// frame.fill_checksum(50);
/// let len = frame.frame_len();
///
/// // Read it back through a view of the bytes.
/// let view = Frame::new_checked(&buf[..len]).unwrap();
/// assert_eq!(view.version(), Version::V2);
/// assert_eq!(view.header().seq, 7);
/// assert_eq!(view.payload()[4], 1);
/// assert!(view.check_crc(50));
/// ```
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct Frame<T: AsRef<[u8]>> {
    buffer: T,
}

impl<T: AsRef<[u8]>> Frame<T> {
    /// The frame at the start of `buffer`; bytes after it are not part of
    /// it. Fails unless the buffer holds a start byte, a header with known
    /// incompatibility flags, and the whole frame that header announces.
    #[inline]
    pub fn new_checked(buffer: T) -> Result<Frame<T>, FrameError> {
        let bytes = buffer.as_ref();
        let len = frame_len(bytes)?;
        if bytes.len() < len {
            return Err(FrameError::Incomplete { needed: len });
        }
        Ok(Frame { buffer })
    }

    /// The frame over `buffer` without any check. For bytes the caller has
    /// already delimited (with [`frame_len`], or a [`Frame::new_checked`]
    /// before [`Frame::into_inner`]); on anything else the accessors may
    /// panic.
    #[inline]
    pub fn new_unchecked(buffer: T) -> Frame<T> {
        Frame { buffer }
    }

    /// The buffer, including any bytes after the frame.
    #[inline]
    pub fn into_inner(self) -> T {
        self.buffer
    }

    /// A borrowed view of the same frame (for the accessors that hand out
    /// slices, which live on `Frame<&[u8]>`).
    #[inline]
    pub fn as_view(&self) -> Frame<&[u8]> {
        Frame {
            buffer: self.buffer.as_ref(),
        }
    }

    #[inline]
    fn bytes(&self) -> &[u8] {
        self.buffer.as_ref()
    }

    /// Protocol version.
    #[inline]
    pub fn version(&self) -> Version {
        if self.bytes()[0] == STX_V2 {
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

    /// Payload length as sent (MAVLink 2 payloads may be truncated).
    #[inline]
    pub fn payload_len(&self) -> usize {
        self.bytes()[1] as usize
    }

    /// The frame's length: header, payload, checksum and signature.
    #[inline]
    pub fn frame_len(&self) -> usize {
        let sig = if self.is_signed() { SIGNATURE_LEN } else { 0 };
        self.header_len() + self.payload_len() + CHECKSUM_LEN + sig
    }

    /// Incompatibility flags (0 for MAVLink 1).
    #[inline]
    pub fn incompat_flags(&self) -> u8 {
        match self.version() {
            Version::V2 => self.bytes()[2],
            Version::V1 => 0,
        }
    }

    /// Compatibility flags (0 for MAVLink 1).
    #[inline]
    pub fn compat_flags(&self) -> u8 {
        match self.version() {
            Version::V2 => self.bytes()[3],
            Version::V1 => 0,
        }
    }

    /// Where seq, sysid, compid start: after the flags in MAVLink 2, after
    /// the length in 1.
    #[inline]
    fn header_at(&self) -> usize {
        match self.version() {
            Version::V2 => 4,
            Version::V1 => 2,
        }
    }

    /// The sender-chosen header fields.
    #[inline]
    pub fn header(&self) -> Header {
        // One bounds check (a checked frame holds its header).
        match self.bytes().get(self.header_at()..self.header_at() + 3) {
            Some(&[seq, sysid, compid]) => Header { seq, sysid, compid },
            _ => Header::default(),
        }
    }

    /// Message id.
    #[inline]
    pub fn msg_id(&self) -> u32 {
        // One bounds check (a checked frame holds its header).
        match *self.bytes() {
            [STX_V2, _, _, _, _, _, _, a, b, c, ..] => u32::from_le_bytes([a, b, c, 0]),
            [STX_V2, ..] => 0,
            [_, _, _, _, _, id, ..] => u32::from(id),
            _ => 0,
        }
    }

    /// The checksum carried by the frame.
    #[inline]
    pub fn checksum(&self) -> u16 {
        let at = self.header_len() + self.payload_len();
        u16::from_le_bytes([self.bytes()[at], self.bytes()[at + 1]])
    }

    /// The checksum the frame should carry for a message with `crc_extra`.
    pub fn computed_checksum(&self, crc_extra: u8) -> u16 {
        frame_crc(
            &self.bytes()[1..self.header_len() + self.payload_len()],
            crc_extra,
        )
    }

    /// True when the carried checksum matches `crc_extra`'s.
    #[inline]
    pub fn check_crc(&self, crc_extra: u8) -> bool {
        let end = self.header_len() + self.payload_len();
        let b = self.bytes();
        match (b.get(1..end), b.get(end..end + CHECKSUM_LEN)) {
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
}

impl<'a, T: AsRef<[u8]> + ?Sized> Frame<&'a T> {
    /// The frame's bytes (not the buffer's bytes after it).
    #[inline]
    pub fn as_bytes(&self) -> &'a [u8] {
        let len = self.frame_len();
        &self.buffer.as_ref()[..len]
    }

    /// The payload bytes as sent.
    #[inline]
    pub fn payload(&self) -> &'a [u8] {
        let start = self.header_len();
        &self.buffer.as_ref()[start..start + self.payload_len()]
    }

    /// The signature block of a signed frame.
    pub fn signature(&self) -> Option<SignatureBlock<'a>> {
        if !self.is_signed() {
            return None;
        }
        let at = self.header_len() + self.payload_len() + CHECKSUM_LEN;
        Some(SignatureBlock {
            bytes: &self.buffer.as_ref()[at..at + SIGNATURE_LEN],
        })
    }

    /// The bytes a signature covers before the key-independent part: header,
    /// payload and checksum.
    pub(crate) fn signed_part(&self) -> &'a [u8] {
        let end = self.header_len() + self.payload_len() + CHECKSUM_LEN;
        &self.buffer.as_ref()[..end]
    }
}

impl<T: AsRef<[u8]> + AsMut<[u8]>> Frame<T> {
    /// Lays out a MAVLink 2 frame at the start of `buffer`: start byte,
    /// payload length and flags. The rest (header fields, id, payload,
    /// checksum, signature) is what the buffer held, for the setters to
    /// fill. Fails on unknown incompatibility flags or a buffer too short for
    /// the frame.
    pub fn new_v2(
        mut buffer: T,
        payload_len: u8,
        incompat_flags: u8,
        compat_flags: u8,
    ) -> Result<Frame<T>, FrameError> {
        if incompat_flags & !IFLAG_KNOWN != 0 {
            return Err(FrameError::UnknownIncompatFlags(incompat_flags));
        }
        let b = buffer.as_mut();
        let start = b.get_mut(..4).ok_or(FrameError::BufferTooSmall {
            needed: HEADER_LEN_V2,
        })?;
        start.copy_from_slice(&[STX_V2, payload_len, incompat_flags, compat_flags]);
        Self::new_checked(buffer).map_err(too_small)
    }

    /// Lays out a MAVLink 1 frame at the start of `buffer` (start byte and
    /// payload length), as [`Frame::new_v2`] does.
    pub fn new_v1(mut buffer: T, payload_len: u8) -> Result<Frame<T>, FrameError> {
        let b = buffer.as_mut();
        let start = b.get_mut(..2).ok_or(FrameError::BufferTooSmall {
            needed: HEADER_LEN_V1,
        })?;
        start.copy_from_slice(&[STX_V1, payload_len]);
        Self::new_checked(buffer).map_err(too_small)
    }

    #[inline]
    fn bytes_mut(&mut self) -> &mut [u8] {
        self.buffer.as_mut()
    }

    /// The frame's bytes, mutable (for signing in place).
    #[inline]
    pub fn as_bytes_mut(&mut self) -> &mut [u8] {
        let len = self.frame_len();
        &mut self.bytes_mut()[..len]
    }

    /// Sets the sequence number.
    #[inline]
    pub fn set_seq(&mut self, seq: u8) {
        let at = self.header_at();
        self.bytes_mut()[at] = seq;
    }

    /// Sets the sender system id.
    #[inline]
    pub fn set_sysid(&mut self, sysid: u8) {
        let at = self.header_at() + 1;
        self.bytes_mut()[at] = sysid;
    }

    /// Sets the sender component id.
    #[inline]
    pub fn set_compid(&mut self, compid: u8) {
        let at = self.header_at() + 2;
        self.bytes_mut()[at] = compid;
    }

    /// Sets sequence number, system id and component id.
    #[inline]
    pub fn set_header(&mut self, header: Header) {
        let at = self.header_at();
        self.bytes_mut()[at..at + 3].copy_from_slice(&[header.seq, header.sysid, header.compid]);
    }

    /// Sets the compatibility flags of a MAVLink 2 frame (MAVLink 1 has
    /// none: refused unless 0).
    pub fn set_compat_flags(&mut self, flags: u8) -> Result<(), FrameError> {
        match self.version() {
            Version::V2 => self.bytes_mut()[3] = flags,
            Version::V1 if flags == 0 => {}
            Version::V1 => return Err(FrameError::NoCompatFlagsInV1(flags)),
        }
        Ok(())
    }

    /// Sets the message id: 24 bits in MAVLink 2, 8 in MAVLink 1.
    pub fn set_msg_id(&mut self, id: u32) -> Result<(), FrameError> {
        match self.version() {
            Version::V2 if id <= 0xFF_FFFF => {
                self.bytes_mut()[7..10].copy_from_slice(&id.to_le_bytes()[..3]);
            }
            Version::V2 => return Err(FrameError::IdTooLarge(id)),
            Version::V1 => {
                self.bytes_mut()[5] =
                    u8::try_from(id).map_err(|_| FrameError::IdTooLargeForV1(id))?;
            }
        }
        Ok(())
    }

    /// The payload bytes, mutable (its length is fixed by the header).
    #[inline]
    pub fn payload_mut(&mut self) -> &mut [u8] {
        let start = self.header_len();
        let end = start + self.payload_len();
        &mut self.bytes_mut()[start..end]
    }

    /// Computes and stores the checksum for a message with `crc_extra`
    /// (after the header and payload are final, before signing).
    #[inline]
    pub fn fill_checksum(&mut self, crc_extra: u8) {
        let crc = self.computed_checksum(crc_extra);
        let at = self.header_len() + self.payload_len();
        self.bytes_mut()[at..at + CHECKSUM_LEN].copy_from_slice(&crc.to_le_bytes());
    }

    /// Stores a signature block as given (copying a captured signature; to
    /// sign, pass [`Frame::as_bytes_mut`] to [`Signer::sign_frame`]). Refused
    /// on an unsigned frame, which has no room for it; `timestamp` keeps its
    /// low 48 bits.
    pub fn set_signature(
        &mut self,
        link_id: u8,
        timestamp: u64,
        signature: [u8; 6],
    ) -> Result<(), FrameError> {
        if !self.is_signed() {
            return Err(FrameError::NotSigned);
        }
        let at = self.header_len() + self.payload_len() + CHECKSUM_LEN;
        let block = &mut self.bytes_mut()[at..at + SIGNATURE_LEN];
        block[0] = link_id;
        block[1..7].copy_from_slice(&timestamp.to_le_bytes()[..6]);
        block[7..].copy_from_slice(&signature);
        Ok(())
    }
}

/// A buffer too short for the frame being laid out is the caller's buffer
/// being too small, not an incomplete input.
fn too_small(e: FrameError) -> FrameError {
    match e {
        FrameError::Incomplete { needed } => FrameError::BufferTooSmall { needed },
        e => e,
    }
}

impl<T: AsRef<[u8]>> AsRef<[u8]> for Frame<T> {
    /// The whole buffer, as [`Frame::into_inner`] would give it.
    fn as_ref(&self) -> &[u8] {
        self.buffer.as_ref()
    }
}

impl<T: AsRef<[u8]>> fmt::Debug for Frame<T> {
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
