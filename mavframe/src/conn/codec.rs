//! MAVLink for `tokio_util::codec` (feature `tokio`): [`FrameCodec`]
//! decodes bytes into checked frames with the streaming parser, and encodes
//! frames (bytes) onto a stream; [`Framer`](crate::Framer) frames messages
//! (sequence numbers, signing) into those bytes.
//!
//! Wrap any async byte stream (TCP, a serial port from tokio-serial, a
//! pipe) with `tokio_util::codec::Framed::new(stream, FrameCodec::new())`,
//! or a UDP socket with `tokio_util::udp::UdpFramed`: `UdpFramed` ends every
//! datagram with `decode_eof`, where the codec tells the parser that nothing
//! follows, so no frame is ever assembled across datagrams.
//!
//! ```
//! # use mavframe::{MessageSet, MessageMeta};
//! # struct D; impl MessageSet for D { type Message = (); type View<'a> = ();
//! #   const MESSAGES: &'static [MessageMeta] = &[];
//! #   fn parse(_: u32, _: &[u8]) -> Option<()> { None } fn view(_: u32, _: &[u8]) -> Option<()> { None } }
//! use mavframe::conn::codec::FrameCodec;
//! use tokio_util::bytes::BytesMut;
//! use tokio_util::codec::Decoder;
//!
//! let mut codec = FrameCodec::<D>::new();
//! // A MAVLink 2 frame of an id this dialect does not know, then the next
//! // frame's start byte (which confirms it) and garbage.
//! let mut bytes = BytesMut::from(&b"\xfd\x01\x00\x00\x07\x01\x01\x2a\x00\x00\x09\x12\x34\xfd"[..]);
//! let frame = codec.decode(&mut bytes).unwrap().expect("a frame");
//! assert_eq!(frame.msg_id(), 42);
//! ```

use super::ReceivedBuf;
use crate::message::MessageSet;
use crate::parser::Parser;
use std::io;
use tokio_util::bytes::{Buf, BytesMut};
use tokio_util::codec::{Decoder, Encoder};

/// Bytes ⇄ MAVLink frames for `tokio_util::codec`.
///
/// Decoding runs the crate's streaming parser (resynchronising after
/// garbage, verifying signatures when it has a key, bounded work per byte);
/// every byte handed to [`decode`](Decoder::decode) is consumed, and a
/// partial frame waits inside the parser. Encoding writes frame bytes as
/// they are (use [`Framer`](crate::Framer) to make them).
///
/// With a `Stream` / `Sink` crate (futures' `StreamExt`), wrap the stream
/// in `tokio_util::codec::Framed` and `next().await` yields frames. Without
/// one, decode as the reads come:
///
/// ```
/// # use mavframe::{BufferTooSmall, MessageSet, MessageData, MessageMeta};
/// # #[derive(Clone, Debug, PartialEq, Default)] struct Ping(u8);
/// # impl MessageData for Ping {
/// #   const META: MessageMeta = MessageMeta::new(4, "PING", 237, 1, 1, &[]);
/// #   type View<'a> = u8;
/// #   fn parse(p: &[u8]) -> Self { Ping(p.first().copied().unwrap_or(0)) }
/// #   fn emit(&self, p: &mut [u8]) -> Result<usize, BufferTooSmall> {
/// #     *p.first_mut().ok_or(BufferTooSmall { needed: 1, got: 0 })? = self.0; Ok(1) }
/// #   fn view(p: &[u8]) -> u8 { p.first().copied().unwrap_or(0) }
/// # }
/// # struct D;
/// # impl MessageSet for D { type Message = Ping; type View<'a> = u8;
/// #   const MESSAGES: &'static [MessageMeta] = &[Ping::META];
/// #   fn parse(id: u32, p: &[u8]) -> Option<Ping> { (id == 4).then(|| Ping::parse(p)) }
/// #   fn view(id: u32, p: &[u8]) -> Option<u8> { (id == 4).then(|| Ping::view(p)) } }
/// // `D`, `Ping`: a stand-in dialect of one message, declared out of sight
/// // (this crate sits below the generator); use a generated crate's
/// // `MessageSet` and messages, e.g. `fbwag_dialect::Dialect`.
/// use mavframe::conn::codec::FrameCodec;
/// use mavframe::Framer;
/// use tokio::io::{AsyncReadExt, AsyncWriteExt};
/// use tokio::net::{TcpListener, TcpStream};
/// use tokio_util::bytes::BytesMut;
/// use tokio_util::codec::Decoder;
///
/// let runtime = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
/// runtime.block_on(async {
///     // A TCP link on this machine; a tokio-serial port reads the same way.
///     let listener = TcpListener::bind("127.0.0.1:0").await?;
///     let mut out = TcpStream::connect(listener.local_addr()?).await?;
///     let (mut input, _) = listener.accept().await?;
///
///     // Sending: the framer numbers (and signs) frames; the bytes go out as they are.
///     let mut framer = Framer::new();
///     out.write_all(framer.frame(1, 1, &Ping(7))?).await?;
///     out.write_all(framer.frame(1, 1, &Ping(8))?).await?;
///
///     // Receiving: bytes in as the reads cut them, checked frames out.
///     let mut codec = FrameCodec::<D>::new();
///     let mut bytes = BytesMut::new();
///     let mut got = Vec::new();
///     while got.len() < 2 {
///         match codec.decode(&mut bytes)? {
///             Some(frame) => got.push(frame.message()),
///             None => assert!(input.read_buf(&mut bytes).await? > 0, "closed"),
///         }
///     }
///     assert_eq!(got, [Some(Ping(7)), Some(Ping(8))]);
///     Ok::<(), Box<dyn std::error::Error>>(())
/// })?;
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct FrameCodec<D: MessageSet> {
    parser: Parser<D>,
}

impl<D: MessageSet> Default for FrameCodec<D> {
    fn default() -> Self {
        Self::new()
    }
}

impl<D: MessageSet> FrameCodec<D> {
    /// A codec whose parser verifies nothing (signed frames pass
    /// unverified, as in pymavlink without a key).
    pub fn new() -> Self {
        Self::with_parser(Parser::new())
    }

    /// A codec with this parser (one made with `Parser::with_signing`
    /// verifies signatures).
    pub fn with_parser(parser: Parser<D>) -> Self {
        FrameCodec { parser }
    }

    /// The parser (its counters, its verifier).
    pub fn parser(&self) -> &Parser<D> {
        &self.parser
    }

    /// The parser, to change (its verifier's state).
    pub fn parser_mut(&mut self) -> &mut Parser<D> {
        &mut self.parser
    }
}

impl<D: MessageSet> Decoder for FrameCodec<D> {
    type Item = ReceivedBuf<D>;
    type Error = io::Error;

    fn decode(&mut self, src: &mut BytesMut) -> io::Result<Option<ReceivedBuf<D>>> {
        let mut input: &[u8] = src;
        let frame = self.parser.next(&mut input).map(|r| ReceivedBuf::from(&r));
        let consumed = src.len() - input.len();
        src.advance(consumed);
        Ok(frame)
    }

    /// The end of the stream, or of a datagram: frames still undecided are
    /// decided as if nothing follows (see `Parser::flush`).
    fn decode_eof(&mut self, src: &mut BytesMut) -> io::Result<Option<ReceivedBuf<D>>> {
        if let Some(frame) = self.decode(src)? {
            return Ok(Some(frame));
        }
        Ok(self.parser.flush().map(|r| ReceivedBuf::from(&r)))
    }
}

impl<D: MessageSet> Encoder<&[u8]> for FrameCodec<D> {
    type Error = io::Error;

    fn encode(&mut self, frame: &[u8], dst: &mut BytesMut) -> io::Result<()> {
        dst.extend_from_slice(frame);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::conn::test_dialect::{Ping, TestDialect};
    use crate::message::MessageData;
    use crate::signing::{timestamp_now, Signer};
    use crate::Framer;

    fn frames(codec: &mut FrameCodec<TestDialect>, bytes: &[u8], eof: bool) -> std::vec::Vec<u32> {
        let mut src = BytesMut::from(bytes);
        let mut ids = std::vec::Vec::new();
        while let Some(f) = codec.decode(&mut src).unwrap() {
            ids.push(f.msg_id());
        }
        assert!(src.is_empty(), "decode consumes everything");
        if eof {
            while let Some(f) = codec.decode_eof(&mut src).unwrap() {
                ids.push(f.msg_id());
            }
        }
        ids
    }

    #[test]
    fn frames_come_out_in_any_chunking_and_garbage_is_skipped() {
        let mut framer = Framer::new();
        let mut stream = std::vec::Vec::from(&b"junk\xfd\x05"[..]);
        for _ in 0..3 {
            stream.extend_from_slice(framer.frame(1, 1, &Ping::default()).unwrap());
        }
        let mut codec = FrameCodec::<TestDialect>::new();
        let whole = frames(&mut codec, &stream, true);
        let mut codec = FrameCodec::<TestDialect>::new();
        let mut split = std::vec::Vec::new();
        for chunk in stream.chunks(3) {
            split.extend(frames(&mut codec, chunk, false));
        }
        split.extend(frames(&mut codec, &[], true));
        assert_eq!(whole, [Ping::META.id; 3]);
        assert_eq!(split, whole);
    }

    /// The end of a datagram ends a frame started in it: the next
    /// datagram's frame is not held back by a false start.
    #[test]
    fn a_false_start_at_a_datagram_end_does_not_hold_the_next_one() {
        let mut framer = Framer::new();
        let mut codec = FrameCodec::<TestDialect>::new();
        // A header claiming 200 payload bytes, alone in its datagram.
        assert!(frames(
            &mut codec,
            b"\xfd\xc8\x00\x00\x00\x01\x01\x00\x00\x00",
            true
        )
        .is_empty());
        let good = framer.frame(1, 1, &Ping::default()).unwrap().to_vec();
        assert_eq!(frames(&mut codec, &good, true), [Ping::META.id]);
    }

    /// Framing from the table row and payload bytes gives the frame
    /// framing the message gives (what a router hands its links).
    #[test]
    fn framing_a_payload_equals_framing_the_message() {
        let ping = Ping { value: 0x0102_0304 };
        let (mut a, mut b) = (Framer::new(), Framer::new());
        let direct = a.frame(1, 2, &ping).unwrap().to_vec();
        let mut payload = [0u8; 4];
        let n = ping.emit(&mut payload).unwrap();
        let via = b
            .frame_payload(1, 2, &Ping::META, &payload[..n])
            .unwrap()
            .to_vec();
        assert_eq!(direct, via);
        // Shorter payloads are zero-filled, then truncated as usual.
        let short = b.frame_payload(1, 2, &Ping::META, &[]).unwrap().to_vec();
        assert_eq!(short.len(), 10 + 1 + 2);
    }

    #[test]
    fn the_framer_numbers_and_signs() {
        let mut framer = Framer::new();
        framer.set_signer(Some(Signer::new([1; 32], 0, 5)));
        let before = timestamp_now();
        let a = framer.frame(1, 2, &Ping::default()).unwrap().to_vec();
        let b = framer.frame(1, 2, &Ping::default()).unwrap().to_vec();
        assert_eq!((a[4], b[4]), (0, 1));
        assert_eq!(
            a[2] & crate::frame::IFLAG_SIGNED,
            crate::frame::IFLAG_SIGNED
        );
        assert!(
            framer.signer().unwrap().timestamp() > before,
            "kept up with the clock"
        );
    }
}
