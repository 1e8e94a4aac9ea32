//! [`FrameBuf`]: one whole frame, owned, in a fixed-size array.

use super::{encode, finish, Frame, FrameError, Header, Version, MAX_FRAME_LEN};
use crate::message::{Encode, MessageMeta};
use crate::signing::Signer;
use core::{fmt, ops::Deref};

/// One whole frame in an owned `[u8; MAX_FRAME_LEN]` (no allocation): what
/// encoding returns when the caller has no buffer of its own, and what a
/// received frame can be copied into to outlive the parser's buffer.
///
/// It derefs to the frame's bytes (only those: `len()` is the frame's
/// length). Every constructor checks that the bytes are a whole frame, so
/// [`FrameBuf::as_frame`] cannot fail; changes go through
/// [`FrameBuf::frame_mut`], whose setters keep the length and flags.
///
/// ```
/// use mavframe::frame::{Frame, FrameBuf, Header, Version};
/// use mavframe::{Encode, MessageMeta};
///
/// // A message type by hand (generated dialects implement `Encode` for
/// // every message and for their `Message` enum).
/// struct Ping(u32);
/// const PING: MessageMeta = MessageMeta::new(4242, "PING_EXAMPLE", 7, 4, 4, &[]);
/// impl Encode for Ping {
///     fn meta(&self) -> &'static MessageMeta { &PING }
///     fn emit_payload(&self, out: &mut [u8]) -> Result<usize, mavframe::BufferTooSmall> {
///         let got = out.len();
///         let slot = out.get_mut(..4).ok_or(mavframe::BufferTooSmall { needed: 4, got })?;
///         slot.copy_from_slice(&self.0.to_le_bytes());
///         Ok(4)
///     }
/// }
///
/// let header = Header { seq: 1, sysid: 255, compid: 190 };
/// let mut buf = FrameBuf::encode(Version::V2, header, &Ping(0x0102), None).unwrap();
/// assert_eq!(buf.len(), 10 + 2 + 2); // trailing zeros of the payload dropped
/// assert_eq!(buf.as_frame().msg_id(), 4242);
///
/// // Re-sequence it and redo the checksum.
/// let mut frame = buf.frame_mut();
/// frame.set_seq(2);
/// frame.fill_checksum(PING.crc_extra);
/// let view = Frame::new_checked(&buf[..]).unwrap();
/// assert_eq!(view.header().seq, 2);
/// assert!(view.check_crc(PING.crc_extra));
/// ```
#[derive(Clone)]
pub struct FrameBuf {
    bytes: [u8; MAX_FRAME_LEN],
    /// The frame's length; `bytes[..len]` is always a whole frame.
    len: u16,
}

impl FrameBuf {
    /// Encodes a message, as [`encode`] does into a caller's buffer.
    pub fn encode<M: Encode + ?Sized>(
        version: Version,
        header: Header,
        message: &M,
        signer: Option<&mut Signer>,
    ) -> Result<FrameBuf, FrameError> {
        let mut bytes = [0u8; MAX_FRAME_LEN];
        let len = encode(version, header, message, signer, &mut bytes)?;
        Ok(Self::whole(bytes, len))
    }

    /// Frames a payload known only by its table row, as [`finish`] does:
    /// `payload` is placed after the header (longer than the message's
    /// `max_len` is cut), then truncated, checksummed and signed.
    pub fn finish(
        version: Version,
        header: Header,
        meta: &MessageMeta,
        payload: &[u8],
        signer: Option<&mut Signer>,
    ) -> Result<FrameBuf, FrameError> {
        let mut bytes = [0u8; MAX_FRAME_LEN];
        let start = match version {
            Version::V2 => super::HEADER_LEN_V2,
            Version::V1 => super::HEADER_LEN_V1,
        };
        let n = payload.len().min(meta.max_len as usize);
        bytes[start..start + n].copy_from_slice(&payload[..n]);
        let len = finish(version, header, meta, n, signer, &mut bytes)?;
        Ok(Self::whole(bytes, len))
    }

    /// A copy of the frame at the start of `bytes` (bytes after it are left
    /// out), checked as [`Frame::new_checked`] checks.
    pub fn from_bytes(bytes: &[u8]) -> Result<FrameBuf, FrameError> {
        let frame = Frame::new_checked(bytes)?;
        let src = frame.as_bytes();
        let mut out = [0u8; MAX_FRAME_LEN];
        // A checked frame is never longer than MAX_FRAME_LEN.
        out[..src.len()].copy_from_slice(src);
        Ok(Self::whole(out, src.len()))
    }

    /// `len` comes from the encoder or a checked frame: at most
    /// MAX_FRAME_LEN (280), which fits u16.
    fn whole(bytes: [u8; MAX_FRAME_LEN], len: usize) -> FrameBuf {
        debug_assert_eq!(super::frame_len(&bytes[..len]), Ok(len));
        FrameBuf {
            bytes,
            len: len as u16,
        }
    }

    /// The frame, to read.
    #[inline]
    pub fn as_frame(&self) -> Frame<&[u8]> {
        Frame::new_unchecked(&self.bytes[..usize::from(self.len)])
    }

    /// The frame, to change through its setters.
    #[inline]
    pub fn frame_mut(&mut self) -> Frame<&mut [u8]> {
        Frame::new_unchecked(&mut self.bytes[..usize::from(self.len)])
    }

    /// The frame's bytes, mutable (for [`Signer::sign_frame`]).
    #[inline]
    pub fn as_bytes_mut(&mut self) -> &mut [u8] {
        &mut self.bytes[..usize::from(self.len)]
    }
}

impl Deref for FrameBuf {
    type Target = [u8];
    #[inline]
    fn deref(&self) -> &[u8] {
        &self.bytes[..usize::from(self.len)]
    }
}

impl AsRef<[u8]> for FrameBuf {
    #[inline]
    fn as_ref(&self) -> &[u8] {
        self
    }
}

impl PartialEq for FrameBuf {
    fn eq(&self, other: &FrameBuf) -> bool {
        **self == **other
    }
}

impl Eq for FrameBuf {}

impl fmt::Debug for FrameBuf {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.as_frame().fmt(f)
    }
}

impl<'a> From<Frame<&'a [u8]>> for FrameBuf {
    fn from(frame: Frame<&'a [u8]>) -> FrameBuf {
        let src = frame.as_bytes();
        let mut bytes = [0u8; MAX_FRAME_LEN];
        // A frame's length never exceeds MAX_FRAME_LEN; min() keeps this
        // total even on a `new_unchecked` frame.
        let n = src.len().min(MAX_FRAME_LEN);
        bytes[..n].copy_from_slice(&src[..n]);
        FrameBuf {
            bytes,
            len: n as u16,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::message::BufferTooSmall;

    const META: MessageMeta = MessageMeta::new(300, "T", 9, 3, 5, &[]);

    struct M([u8; 5]);
    impl Encode for M {
        fn meta(&self) -> &'static MessageMeta {
            &META
        }
        fn emit_payload(&self, out: &mut [u8]) -> Result<usize, BufferTooSmall> {
            out[..5].copy_from_slice(&self.0);
            Ok(5)
        }
    }

    #[test]
    fn encode_matches_the_slice_encoder() {
        let h = Header {
            seq: 3,
            sysid: 4,
            compid: 5,
        };
        let m = M([1, 2, 0, 4, 0]);
        let mut out = [0u8; MAX_FRAME_LEN];
        let n = encode(Version::V2, h, &m, None, &mut out).unwrap();
        let buf = FrameBuf::encode(Version::V2, h, &m, None).unwrap();
        assert_eq!(&buf[..], &out[..n]);
        assert_eq!(
            FrameBuf::finish(Version::V2, h, &META, &m.0, None).unwrap(),
            buf
        );
        assert_eq!(FrameBuf::from_bytes(&out).unwrap(), buf);
        assert_eq!(FrameBuf::from(buf.as_frame()), buf);
        assert!(buf.as_frame().check_crc(9));
    }

    #[test]
    fn v1_refuses_wide_ids_and_bad_bytes_are_errors() {
        let h = Header::default();
        assert_eq!(
            FrameBuf::encode(Version::V1, h, &M([0; 5]), None),
            Err(FrameError::IdTooLargeForV1(300))
        );
        assert_eq!(FrameBuf::from_bytes(&[0x00]), Err(FrameError::NotStart));
        assert_eq!(
            FrameBuf::from_bytes(&[0xFD, 9]),
            Err(FrameError::Incomplete { needed: 10 })
        );
    }
}
