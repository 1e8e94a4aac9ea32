//! [`Framer`]: one sender's framing state (sequence numbers, protocol
//! version, signer) and a frame buffer, without std or a heap.

use crate::frame::{
    finish, Frame, FrameError, Header, Version, HEADER_LEN_V1, HEADER_LEN_V2, MAX_FRAME_LEN,
};
use crate::message::{Encode, MessageMeta};
use crate::signing::{Signer, Verifier};
use core::fmt;

/// Frames messages for one sender: its sequence numbers (one per frame,
/// wrapping), protocol version and signer, into a buffer of its own. Every
/// link frames through it (the blocking connections, the router and the
/// `embedded` adapters); use it directly to frame once and send the bytes
/// on several links.
///
/// Signing timestamps must increase, and receivers refuse a new stream more
/// than a minute behind the newest timestamp they saw. The signer's
/// timestamp advances by one per frame; with a clock
/// ([`set_clock`](Self::set_clock)) it also keeps up with the clock before
/// each frame. With `std`, [`new`](Self::new) sets the system clock; without
/// it there is none until you set one (an RTC, or time since boot plus a
/// saved epoch). On a link that also verifies, the signer adopts what the
/// link's verifier accepted ([`adopt_from`](Self::adopt_from), after
/// receiving or before framing), so a peer whose clock is ahead is
/// followed (see `crate::signing`).
///
/// ```
/// # use mavframe::{MessageData, MessageMeta, BufferTooSmall};
/// # #[derive(Clone, Debug, PartialEq, Default)] struct Ping;
/// # impl MessageData for Ping {
/// #   const META: MessageMeta = MessageMeta::new(4, "PING", 237, 1, 1, &[]);
/// #   type View<'a> = ();
/// #   fn parse(_: &[u8]) -> Self { Ping }
/// #   fn emit(&self, p: &mut [u8]) -> Result<usize, BufferTooSmall> { p[0] = 7; Ok(1) }
/// #   fn view(_: &[u8]) {}
/// # }
/// use mavframe::frame::IFLAG_SIGNED;
/// use mavframe::Framer;
/// use mavframe::Signer;
///
/// let mut framer = Framer::new();
/// framer.set_signer(Some(Signer::new([7; 32], 0, 1_000)));
/// let first = framer.frame(1, 191, &Ping)?.to_vec();
/// let second = framer.frame(1, 191, &Ping)?;
/// assert_eq!((first[4], second[4]), (0, 1)); // sequence numbers
/// assert_eq!(second[2] & IFLAG_SIGNED, IFLAG_SIGNED);
/// # Ok::<(), mavframe::FrameError>(())
/// ```
#[derive(Clone)]
pub struct Framer {
    signer: Option<Signer>,
    version: Version,
    seq: u8,
    clock: Option<fn() -> u64>,
    buf: [u8; MAX_FRAME_LEN],
}

impl Default for Framer {
    fn default() -> Self {
        Self::new()
    }
}

impl fmt::Debug for Framer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // The buffer is scratch space: not part of the state worth printing.
        f.debug_struct("Framer")
            .field("signer", &self.signer)
            .field("version", &self.version)
            .field("seq", &self.seq)
            .field("clock", &self.clock.is_some())
            .finish_non_exhaustive()
    }
}

/// The clock [`Framer::new`] starts with: the system's where there is one.
#[cfg(feature = "std")]
const DEFAULT_CLOCK: Option<fn() -> u64> = Some(crate::signing::timestamp_now);
#[cfg(not(feature = "std"))]
const DEFAULT_CLOCK: Option<fn() -> u64> = None;

impl Framer {
    /// MAVLink 2, unsigned, starting at sequence 0; with `std`, signing
    /// timestamps keep up with the system clock (see [`Framer`]).
    pub fn new() -> Self {
        Framer {
            signer: None,
            version: Version::V2,
            seq: 0,
            clock: DEFAULT_CLOCK,
            buf: [0; MAX_FRAME_LEN],
        }
    }

    /// Signs every MAVLink 2 frame from now on (`None`: stop).
    pub fn set_signer(&mut self, signer: Option<Signer>) {
        self.signer = signer;
    }

    /// The signer, if frames are signed.
    pub fn signer(&self) -> Option<&Signer> {
        self.signer.as_ref()
    }

    /// The protocol version of the frames.
    pub fn set_version(&mut self, version: Version) {
        self.version = version;
    }

    /// The protocol version of the frames.
    pub fn version(&self) -> Version {
        self.version
    }

    /// The sequence number the next frame carries.
    pub fn seq(&self) -> u8 {
        self.seq
    }

    /// Adopts a timestamp `t` of a frame the link verified: the next frame
    /// is signed at `t` or later (never earlier than it would have been).
    /// Without a signer, nothing.
    pub fn adopt(&mut self, t: u64) {
        if let Some(signer) = &mut self.signer {
            signer.advance_to(t);
        }
    }

    /// Adopts `verifier`'s notion of now ([`Verifier::newest_timestamp`]:
    /// the newest timestamp it accepted, or its clock if that is ahead),
    /// as the C library's single signing timestamp does: call it with the
    /// link's parser's verifier (`parser.verifier()`) after receiving, or
    /// before framing. `None` (a parser without a key): nothing.
    pub fn adopt_from<const N: usize>(&mut self, verifier: Option<&Verifier<N>>) {
        if let Some(v) = verifier {
            self.adopt(v.newest_timestamp());
        }
    }

    /// The clock signing timestamps keep up with: a function returning the
    /// time in signing units (10 µs since 2015-01-01 00:00 UTC, as
    /// `signing::timestamp_now` with `std`); `None` for none.
    pub fn set_clock(&mut self, clock: Option<fn() -> u64>) {
        self.clock = clock;
    }

    /// Frames `msg` from `sysid`/`compid` with the next sequence number
    /// (which advances whatever happens next: a receiver counts a frame
    /// that failed to go out as lost).
    ///
    /// Errors: [`FrameError::IdTooLargeForV1`] for a MAVLink 1 frame of an
    /// id above 255; [`FrameError::BufferTooSmall`] only for an [`Encode`]
    /// implementation that writes past its own `max_len`.
    pub fn frame(
        &mut self,
        sysid: u8,
        compid: u8,
        msg: &(impl Encode + ?Sized),
    ) -> Result<&[u8], FrameError> {
        let header = self.next_header(sysid, compid);
        self.frame_as(self.version, header, msg)
    }

    /// Frames `msg` with `header` in `version`, whatever the framer's own
    /// sequence number and version (a caller that numbers frames itself);
    /// signed as [`frame`](Self::frame) signs.
    pub fn frame_as(
        &mut self,
        version: Version,
        header: Header,
        msg: &(impl Encode + ?Sized),
    ) -> Result<&[u8], FrameError> {
        let at = payload_at(version);
        let len =
            msg.emit_payload(&mut self.buf[at..])
                .map_err(|e| FrameError::BufferTooSmall {
                    needed: at + e.needed,
                })?;
        self.finish(version, header, msg.meta(), len)
    }

    /// Frames a message known by its table row and payload bytes (all of
    /// them, `meta.max_len` at most; shorter means zeros follow), as
    /// [`frame`](Self::frame) does: what a router uses to frame a message
    /// handed over as bytes.
    pub fn frame_payload(
        &mut self,
        sysid: u8,
        compid: u8,
        meta: &MessageMeta,
        payload: &[u8],
    ) -> Result<&[u8], FrameError> {
        let written = self.put_payload(self.version, meta, payload);
        let header = self.next_header(sysid, compid);
        self.finish(self.version, header, meta, written)
    }

    /// Frames again, as MAVLink 2 signed with this framer's signer (if
    /// any), a whole frame of `meta`'s message from elsewhere, keeping its
    /// header (sender, sequence number): what a router does with the
    /// frames of a link its owner trusts like the key, on their way to a
    /// link that requires signatures. Its own signature, if any, is
    /// dropped.
    ///
    /// Errors: the [`FrameError`] of `frame` when it is not a whole frame.
    pub fn resign(&mut self, frame: &[u8], meta: &MessageMeta) -> Result<&[u8], FrameError> {
        let frame = Frame::new_checked(frame)?;
        let written = self.put_payload(Version::V2, meta, frame.payload());
        self.finish(Version::V2, frame.header(), meta, written)
    }

    /// Copies `payload` (`meta.max_len` bytes at most; zeros follow a
    /// shorter one) where a `version` frame's payload goes; returns the
    /// length written.
    fn put_payload(&mut self, version: Version, meta: &MessageMeta, payload: &[u8]) -> usize {
        let at = payload_at(version);
        let max = meta.max_len as usize;
        let len = payload.len().min(max);
        // `at + max` is at most 10 + 255, inside the 280-byte buffer.
        self.buf[at..at + max].fill(0);
        self.buf[at..at + len].copy_from_slice(&payload[..len]);
        max
    }

    /// Sets the sequence number the next frame carries.
    pub fn set_seq(&mut self, seq: u8) {
        self.seq = seq;
    }

    /// The header of the next frame from `sysid`/`compid`; the sequence
    /// number advances.
    pub fn next_header(&mut self, sysid: u8, compid: u8) -> Header {
        let seq = self.seq;
        self.seq = seq.wrapping_add(1);
        Header { seq, sysid, compid }
    }

    fn finish(
        &mut self,
        version: Version,
        header: Header,
        meta: &MessageMeta,
        len: usize,
    ) -> Result<&[u8], FrameError> {
        if let (Some(signer), Some(clock)) = (&mut self.signer, self.clock) {
            signer.advance_to(clock());
        }
        let n = finish(
            version,
            header,
            meta,
            len,
            self.signer.as_mut(),
            &mut self.buf,
        )?;
        Ok(&self.buf[..n])
    }
}

fn payload_at(version: Version) -> usize {
    match version {
        Version::V2 => HEADER_LEN_V2,
        Version::V1 => HEADER_LEN_V1,
    }
}

#[cfg(feature = "std")]
impl From<FrameError> for std::io::Error {
    fn from(e: FrameError) -> Self {
        std::io::Error::new(std::io::ErrorKind::InvalidInput, e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::{Frame, IFLAG_SIGNED};
    use crate::message::{BufferTooSmall, MessageData};

    /// Id 300 (too large for MAVLink 1), two bytes.
    #[derive(Debug, Clone, Default, PartialEq)]
    struct Big(u16);

    impl MessageData for Big {
        const META: MessageMeta = MessageMeta::new(300, "BIG", 9, 2, 2, &[]);
        type View<'a> = ();
        fn parse(p: &[u8]) -> Self {
            Big(u16::from_le_bytes([
                p.first().copied().unwrap_or(0),
                p.get(1).copied().unwrap_or(0),
            ]))
        }
        fn emit(&self, p: &mut [u8]) -> Result<usize, BufferTooSmall> {
            let got = p.len();
            p.get_mut(..2)
                .ok_or(BufferTooSmall { needed: 2, got })?
                .copy_from_slice(&self.0.to_le_bytes());
            Ok(2)
        }
        fn view(_: &[u8]) {}
    }

    fn ticks() -> u64 {
        5_000
    }

    #[test]
    fn numbers_wrap_and_sign_with_the_clock() {
        let mut framer = Framer::new();
        framer.set_clock(Some(ticks));
        framer.set_signer(Some(Signer::new([3; 32], 2, 10)));
        for i in 0..=256u32 {
            let bytes = framer.frame(1, 2, &Big(7)).unwrap();
            let frame = Frame::new_checked(bytes).unwrap();
            assert_eq!(frame.header().seq, i as u8);
            assert_eq!(frame.incompat_flags(), IFLAG_SIGNED);
            // Caught up with the clock on the first frame, then one per frame.
            assert_eq!(frame.signature().unwrap().timestamp(), 5_000 + u64::from(i));
        }
        assert_eq!(framer.seq(), 1);
    }

    #[test]
    fn without_a_clock_timestamps_count_frames() {
        let mut framer = Framer::new();
        framer.set_clock(None);
        framer.set_signer(Some(Signer::new([3; 32], 2, 10)));
        framer.frame(1, 2, &Big(7)).unwrap();
        assert_eq!(framer.signer().unwrap().timestamp(), 11);
    }

    /// Adopting moves the next timestamp up to what the link verified,
    /// never down, and only with a signer; what was signed stays the
    /// signer's bound until it signs again.
    #[test]
    fn adopting_raises_the_next_timestamp_never_lowers_it() {
        let mut framer = Framer::new();
        framer.set_clock(Some(ticks));
        framer.adopt(1_000_000);
        assert!(framer.signer().is_none());
        framer.set_signer(Some(Signer::new([3; 32], 2, 10)));
        framer.frame(1, 2, &Big(7)).unwrap();
        framer.adopt(900_000);
        framer.adopt(100);
        let signer = framer.signer().unwrap();
        assert_eq!(
            (signer.timestamp(), signer.signed_below()),
            (900_000, 5_001)
        );
        let verifier = Verifier::<4>::with_timestamp([3; 32], 2_000_000);
        framer.adopt_from(Some(&verifier));
        framer.adopt_from::<4>(None);
        let bytes = framer.frame(1, 2, &Big(7)).unwrap();
        let frame = Frame::new_checked(bytes).unwrap();
        assert_eq!(frame.signature().unwrap().timestamp(), 2_000_000);
        assert_eq!(framer.signer().unwrap().timestamp(), 2_000_001);
    }

    #[test]
    fn mavlink1_refuses_large_ids_and_still_counts_the_frame() {
        let mut framer = Framer::new();
        framer.set_version(Version::V1);
        assert_eq!(
            framer.frame(1, 2, &Big(7)).map(<[u8]>::len),
            Err(FrameError::IdTooLargeForV1(300))
        );
        assert_eq!(framer.seq(), 1);
    }
}
