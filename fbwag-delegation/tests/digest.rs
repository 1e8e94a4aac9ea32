//! The nodes' digests (`fbwag_delegation::digest`): equal for states that
//! differ only by when they happened, blind to counters, and changed by
//! anything that changes what a node does next.

use fbwag_delegation::cc::CcConfig;
use fbwag_delegation::digest::Digest;
use fbwag_delegation::fc::FcConfig;
use fbwag_delegation::node::{
    Answers, Arrival, AutonomyFallback, CompanionNode, ControlSource, FcNode, LinkSpec, Output,
    Role, AUTONOMY_SILENCE,
};
use fbwag_delegation::{Moment, Peer};
use fbwag_dialect::dialects::common::RcChannelsOverride;
use fbwag_dialect::{encode, Frame, Header, Message, Version};
use std::collections::hash_map::DefaultHasher;
use std::hash::Hasher;
use std::net::SocketAddr;

/// A digest with times, events and sequence numbers counted from a now.
struct Relative {
    h: DefaultHasher,
    now: Moment,
    event_now: u32,
}

impl Relative {
    fn of(now: Moment, feed: impl FnOnce(&mut Self)) -> u64 {
        let mut d = Relative {
            h: DefaultHasher::new(),
            now,
            event_now: now.as_millis() as u32,
        };
        feed(&mut d);
        d.h.finish()
    }
}

impl Hasher for Relative {
    fn finish(&self) -> u64 {
        self.h.finish()
    }

    fn write(&mut self, bytes: &[u8]) {
        self.h.write(bytes);
    }
}

impl Digest for Relative {
    fn instant(&mut self, t: Moment) {
        self.h.write_i64(t.0 as i64 - self.now.0 as i64);
    }

    fn event(&mut self, event: u32) {
        self.h.write_i32(event.wrapping_sub(self.event_now) as i32);
    }

    fn sequence(&mut self, seq: u8) {
        self.h.write_u8(seq);
    }
}

const FC_LINK: u8 = 0;
const AUTONOMY_LINK: u8 = 2;
const AUTONOMY_ADDR: SocketAddr =
    SocketAddr::new(std::net::IpAddr::V4(std::net::Ipv4Addr::LOCALHOST), 14600);

fn nodes(start: Moment) -> (FcNode, CompanionNode) {
    let mut fc = FcNode::new(FcConfig::default(), start).unwrap();
    fc.add_link(FC_LINK, LinkSpec::new(Role::Peer, Answers::Target))
        .unwrap();
    let source = ControlSource::Autonomy {
        link: AUTONOMY_LINK,
        fallback: AutonomyFallback::Decline,
        silence: AUTONOMY_SILENCE,
    };
    let mut cc = CompanionNode::new(CcConfig::default(), source, start).unwrap();
    cc.add_link(FC_LINK, LinkSpec::new(Role::Peer, Answers::Target))
        .unwrap();
    cc.add_link(
        AUTONOMY_LINK,
        LinkSpec::new(Role::Autonomy, Answers::Chosen),
    )
    .unwrap();
    (fc, cc)
}

fn frame(from: Peer, seq: u8, message: &Message) -> Vec<u8> {
    let mut buf = [0u8; 280];
    let header = Header {
        seq,
        sysid: from.sysid,
        compid: from.compid,
    };
    let n = encode(Version::V2, header, message, None, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn arrival(bytes: &[u8], link: u8, source: Option<SocketAddr>) -> Arrival<'_> {
    Arrival {
        link,
        source,
        frame: Frame::new_checked(bytes).unwrap(),
        authenticated: false,
    }
}

/// A handover from `start` on: the receiver lost at 1 s, every frame
/// delivered at once, the autonomy speaking every 100 ms. The digests of
/// both nodes, counted from each step's now, after every step.
fn handover(start: Moment) -> Vec<(u64, u64)> {
    let (mut fc, mut cc) = nodes(start);
    let (mut fc_seq, mut cc_seq, mut autonomy_seq) = (0u8, 0u8, 0u8);
    let mut digests = Vec::new();
    let mut now = start;
    let end = Moment(start.0 + 4_000_000);
    while now < end {
        if now.0 - start.0 >= 1_000_000 {
            fc.set_receiver_ok(false);
        }
        if (now.0 - start.0) % 100_000 == 0 {
            let control = Message::RcChannelsOverride(RcChannelsOverride {
                target_system: 1,
                target_component: 1,
                chan1_raw: 1500,
                ..Default::default()
            });
            autonomy_seq = autonomy_seq.wrapping_add(1);
            let bytes = frame(Peer::new(1, 158), autonomy_seq, &control);
            let _ = cc.handle_frame(now, arrival(&bytes, AUTONOMY_LINK, Some(AUTONOMY_ADDR)));
        }
        if fc.poll_timeout().is_some_and(|t| t <= now) {
            fc.handle_timeout(now);
        }
        if cc.poll_timeout().is_some_and(|t| t <= now) {
            cc.handle_timeout(now);
        }
        // Carry every output across until both are quiet.
        loop {
            let mut quiet = true;
            while let Some(out) = fc.poll_output() {
                if let Output::Transmit { message, .. } = out {
                    quiet = false;
                    fc_seq = fc_seq.wrapping_add(1);
                    let bytes = frame(Peer::new(1, 1), fc_seq, &message);
                    let _ = cc.handle_frame(now, arrival(&bytes, FC_LINK, None));
                }
            }
            while let Some(out) = cc.poll_output() {
                if let Output::Transmit { message, .. } = out {
                    quiet = false;
                    cc_seq = cc_seq.wrapping_add(1);
                    let bytes = frame(Peer::new(1, 191), cc_seq, &message);
                    let _ = fc.handle_frame(now, arrival(&bytes, FC_LINK, None));
                }
            }
            if quiet {
                break;
            }
        }
        let fc_digest = Relative::of(now, |d| fc.digest(d));
        let cc_digest = Relative::of(now, |d| cc.digest(d));
        digests.push((fc_digest, cc_digest));
        now = Moment(now.0 + 50_000);
    }
    digests
}

#[test]
fn the_same_handover_later_digests_alike_step_by_step() {
    let early = handover(Moment::ZERO);
    let late = handover(Moment::from_millis(7_300));
    assert_eq!(early.len(), 80);
    let first = early.iter().zip(&late).position(|(a, b)| a != b);
    assert_eq!(first, None, "{:?}", first.map(|i| (i, early[i], late[i])));
    // Not vacuous: the states change along the way.
    let distinct: std::collections::HashSet<_> = early.iter().collect();
    assert!(distinct.len() > 20, "{} distinct states", distinct.len());
}

#[test]
fn counters_change_no_digest_and_state_does() {
    let (mut fc, _) = nodes(Moment::ZERO);
    let now = Moment::from_millis(10);
    let before = Relative::of(now, |d| fc.digest(d));
    // A stranger's frame: counted as untrusted, nothing else.
    let stranger = frame(Peer::new(7, 7), 0, &Message::Heartbeat(Default::default()));
    let _ = fc.handle_frame(now, arrival(&stranger, FC_LINK, None));
    while fc.poll_output().is_some() {}
    assert_eq!(fc.stats().untrusted_frames, 1);
    assert_eq!(Relative::of(now, |d| fc.digest(d)), before);
    // One bad receiver sample is not yet a loss, but it is state.
    fc.set_receiver_ok(false);
    fc.handle_timeout(now);
    while fc.poll_output().is_some() {}
    assert_ne!(Relative::of(now, |d| fc.digest(d)), before);
}
