//! MAVLink as the model carries it: each side's framing (sequence numbers,
//! its signer) and its link parser (with the verifier that holds its replay
//! state), so every frame in flight is the real bytes a daemon would send.

use crate::state::Clock;
use core::hash::{Hash, Hasher};
use fbwag_delegation::digest::Digest;
use fbwag_delegation::{Moment, Peer};
use fbwag_dialect::mavframe::frame::MAX_FRAME_LEN;
use fbwag_dialect::mavframe::parser::Unsigned;
use fbwag_dialect::{encode, Frame, Header, Message, Parser, Signer, Verifier, Version};

/// The link key both sides share.
pub const KEY: [u8; 32] = [0x5a; 32];

/// Signing timestamps (10 µs units since 2015) at the model's time zero:
/// any value works as long as the clock only moves forward.
const SIGNING_EPOCH: u64 = 365 * 24 * 3600 * 100_000;

/// The signing timestamp of virtual time `t`.
pub fn signing_time(t: Moment) -> u64 {
    SIGNING_EPOCH + t.0 / 10
}

/// One side's MAVLink endpoint: what a daemon keeps across frames.
#[derive(Clone, Debug)]
pub struct Endpoint {
    id: Peer,
    /// The next frame's sequence number.
    pub seq: u8,
    signer: Signer,
    verifier: Verifier,
}

impl Endpoint {
    /// A freshly started endpoint at `now` without a signing state file:
    /// signer and verifier start from the clock.
    pub fn starting(id: Peer, link_id: u8, now: Moment) -> Self {
        Endpoint {
            id,
            seq: 0,
            signer: Signer::new(KEY, link_id, signing_time(now)),
            verifier: Verifier::with_timestamp(KEY, signing_time(now)),
        }
    }

    /// The same endpoint after a restart at `now`: the sequence restarts;
    /// the signing state survives when `kept` (a state file), else starts
    /// again from the clock.
    pub fn restarted(&self, kept: bool, now: Moment) -> Self {
        if kept {
            Endpoint {
                seq: 0,
                ..self.clone()
            }
        } else {
            Endpoint::starting(self.id, self.signer.link_id(), now)
        }
    }

    /// `message` framed with this side's ids, signed, at `now`.
    pub fn frame(&mut self, message: &Message, now: Moment) -> Vec<u8> {
        self.signer.advance_to(signing_time(now));
        let header = Header {
            seq: self.seq,
            sysid: self.id.sysid,
            compid: self.id.compid,
        };
        self.seq = self.seq.wrapping_add(1);
        let mut buf = [0u8; MAX_FRAME_LEN];
        let n = encode(
            Version::V2,
            header,
            message,
            Some(&mut self.signer),
            &mut buf,
        )
        .expect("a frame fits MAX_FRAME_LEN");
        buf[..n].to_vec()
    }

    /// Parses `bytes` (one datagram) with this side's verifier: the frame
    /// the link's parser accepts, and whether its signature verified.
    pub fn parse(&mut self, bytes: &[u8]) -> Option<(Vec<u8>, bool)> {
        let mut parser = Parser::with_signing(self.verifier.clone(), Unsigned::Accept);
        let mut input = bytes;
        let got = parser
            .next(&mut input)
            .map(|r| (r.frame().as_bytes().to_vec(), r.is_authenticated()))
            .or_else(|| {
                parser
                    .flush()
                    .map(|r| (r.frame().as_bytes().to_vec(), r.is_authenticated()))
            });
        if let Some(v) = parser.verifier() {
            self.verifier = v.clone();
        }
        got
    }

    /// Feeds `d` the signing state ([`Clock::signing`] counts its times):
    /// what the signer signs next, what the verifier accepts (its notion
    /// of now, floors, streams: a handful, in no order that matters below
    /// the table's 16 slots). A restart keeps the signer whole or starts
    /// it from the clock, so what it signed below is not read.
    pub fn digest(&self, d: &mut Clock) {
        d.signing(self.signer.timestamp());
        d.signing(self.verifier.newest_timestamp());
        for floor in self.verifier.floors() {
            d.signing(floor);
        }
        let mut streams: Vec<_> = self.verifier.streams().collect();
        streams.sort_by_key(|s| (s.link_id, s.sysid, s.compid));
        streams.len().hash(d);
        for s in streams {
            (s.link_id, s.sysid, s.compid).hash(d);
            d.signing(s.timestamp);
        }
    }
}

/// An unsigned frame as a stranger (no key) builds it, with any ids.
pub fn forged(id: Peer, seq: u8, message: &Message) -> Vec<u8> {
    let header = Header {
        seq,
        sysid: id.sysid,
        compid: id.compid,
    };
    let mut buf = [0u8; MAX_FRAME_LEN];
    let n = encode(Version::V2, header, message, None, &mut buf).expect("fits");
    buf[..n].to_vec()
}

/// The message in a whole frame's bytes, if the dialect knows it.
pub fn message_of(bytes: &[u8]) -> Option<Message> {
    let frame = Frame::new_checked(bytes).ok()?;
    <fbwag_dialect::Dialect as fbwag_dialect::mavframe::MessageSet>::parse(
        frame.msg_id(),
        frame.payload(),
    )
}

/// A frame's checked view of `bytes` (they came from a parser).
pub fn frame_of(bytes: &[u8]) -> Frame<&[u8]> {
    Frame::new_checked(bytes).expect("the parser accepted these bytes")
}

/// The sender's ids of a frame.
pub fn sender(bytes: &[u8]) -> Option<Peer> {
    let h = Frame::new_checked(bytes).ok()?.header();
    Some(Peer::new(h.sysid, h.compid))
}

/// Feeds `d` a frame as its receiver will judge it: header, payload, and
/// signature block, with its event ids, signing time and (`fc_seq`: a
/// frame of the FC) sequence number counted from `d`'s now. The signature
/// itself follows from the rest and the key, so it is not fed.
pub fn digest_frame(bytes: &[u8], fc_seq: bool, d: &mut Clock) {
    let Ok(frame) = Frame::new_checked(bytes) else {
        bytes.hash(d);
        return;
    };
    let h = frame.header();
    (h.sysid, h.compid, frame.msg_id(), frame.incompat_flags()).hash(d);
    if fc_seq {
        d.sequence(h.seq);
    }
    match message_of(bytes) {
        Some(Message::FbwagNotice(n)) => {
            (n.system_id, n.component_id, n.failsafe_status, n.text).hash(d);
            d.event(n.timestamp);
        }
        Some(Message::Statustext(t)) => {
            (t.severity, t.text, t.chunk_seq).hash(d);
            d.write_u16(t.id.wrapping_sub(d.event_now() as u16));
        }
        _ => frame.payload().hash(d),
    }
    if let Some(sig) = frame.signature() {
        sig.link_id().hash(d);
        d.signing(sig.timestamp());
    }
}
