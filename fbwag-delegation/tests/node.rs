//! The node policy, rule by rule: each row of the table in
//! `fbwag_delegation::node` (and docs/delegation.md) driven through the
//! nodes' public API with real frames.

use fbwag_delegation::cc::CcConfig;
use fbwag_delegation::engine::{CcOutput, FcOutput};
use fbwag_delegation::fc::{Authority, FcConfig};
use fbwag_delegation::node::{
    Answers, Arrival, AutonomyFallback, CompanionEvent, CompanionNode, ControlSource, DropReason,
    FcNode, LinkSpec, Links, Output, Peers, Role, RouterNode, AUTONOMY_SILENCE, MAX_PEERS,
    PEER_SILENCE,
};
use fbwag_delegation::{wire, Moment, Peer, Status};
use fbwag_dialect::dialects::common::{CommandLong, RcChannelsOverride};
use fbwag_dialect::dialects::standard::GlobalPositionInt;
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Frame, Header, Message, Version};
use std::net::SocketAddr;
use std::time::Duration;

const FC: Peer = Peer::new(1, 1);
const CC: Peer = Peer::new(1, 191);
const GCS: Peer = Peer::new(255, 190);
const FC_LINK: u8 = 0;
const GROUND: u8 = 1;
const AUTONOMY: u8 = 2;

fn bytes(from: Peer, msg: &(impl Encode + ?Sized)) -> Vec<u8> {
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    let h = Header {
        seq: 0,
        sysid: from.sysid,
        compid: from.compid,
    };
    let n = encode(Version::V2, h, msg, None, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn addr(port: u16) -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], port))
}

fn arrival(link: u8, source: Option<SocketAddr>, b: &[u8], authenticated: bool) -> Arrival<'_> {
    Arrival {
        link,
        source,
        frame: Frame::new_checked(b).unwrap(),
        authenticated,
    }
}

fn position() -> GlobalPositionInt {
    GlobalPositionInt {
        lat: 123,
        ..Default::default()
    }
}

fn heartbeat() -> Message {
    Message::Heartbeat(wire::fc_heartbeat(Authority::Pilot))
}

fn rc(chan1: u16) -> RcChannelsOverride {
    RcChannelsOverride {
        chan1_raw: chan1,
        ..Default::default()
    }
}

/// A signed companion with a ground-station port and an autonomy port.
fn companion(source: impl Fn(u8) -> ControlSource) -> CompanionNode {
    let cfg = CcConfig {
        require_signed: true,
        ..CcConfig::default()
    };
    let mut cc = CompanionNode::new(cfg, source(AUTONOMY), Moment::ZERO).unwrap();
    let spec = LinkSpec::new;
    cc.add_link(FC_LINK, spec(Role::Peer, Answers::Chosen))
        .unwrap();
    cc.add_link(GROUND, spec(Role::Ground, Answers::Chosen))
        .unwrap();
    cc.add_link(AUTONOMY, spec(Role::Autonomy, Answers::Chosen))
        .unwrap();
    cc
}

fn builtin(_: u8) -> ControlSource {
    ControlSource::Builtin
}

fn autonomy(fallback: AutonomyFallback) -> impl Fn(u8) -> ControlSource {
    move |link| ControlSource::Autonomy {
        link,
        fallback,
        silence: AUTONOMY_SILENCE,
    }
}

fn drain(cc: &mut CompanionNode) -> Vec<Output<CompanionEvent>> {
    std::iter::from_fn(|| cc.poll_output()).collect()
}

const FC_ADDR: u16 = 14551;

/// The companion has heard the FC (signed) from `FC_ADDR`.
fn heard_fc(cc: &mut CompanionNode, at: Moment) {
    let hb = bytes(FC, &heartbeat());
    let fate = cc.handle_frame(at, arrival(FC_LINK, Some(addr(FC_ADDR)), &hb, true));
    assert!(fate.input && fate.dropped.is_none(), "{fate:?}");
    drain(cc);
}

/// A companion without signing that heard the FC's unsigned heartbeat
/// from `FC_ADDR` at time zero; the heartbeat's bytes.
fn unsigned_companion_that_heard_the_fc() -> (CompanionNode, Vec<u8>) {
    let mut cc = CompanionNode::new(CcConfig::default(), ControlSource::Builtin, Moment::ZERO)
        .expect("valid settings");
    cc.add_link(FC_LINK, LinkSpec::new(Role::Peer, Answers::Chosen))
        .expect("a link");
    let hb = bytes(FC, &heartbeat());
    let fate = cc.handle_frame(
        Moment::ZERO,
        arrival(FC_LINK, Some(addr(FC_ADDR)), &hb, false),
    );
    assert!(fate.input, "{fate:?}");
    drain(&mut cc);
    (cc, hb)
}

/// Without signing, ids are the only credential: a frame with the FC's
/// ids from another address takes the FC link's peer only once the peer
/// has been silent for PEER_SILENCE (an FC restarted on a new port), never
/// at once (which would let anyone on the network redirect the link).
#[test]
fn without_signing_a_new_address_takes_the_peer_only_after_its_silence() {
    let (mut cc, hb) = unsigned_companion_that_heard_the_fc();
    let elsewhere = Some(addr(9999));
    let soon = Moment::from_millis(1000);
    let fate = cc.handle_frame(soon, arrival(FC_LINK, elsewhere, &hb, false));
    assert_eq!(fate.dropped, Some(DropReason::NotPeer));
    assert!(drain(&mut cc).is_empty(), "the peer stays");
    let fate = cc.handle_frame(
        Moment::ZERO + PEER_SILENCE,
        arrival(FC_LINK, elsewhere, &hb, false),
    );
    assert!(fate.input && fate.dropped.is_none(), "{fate:?}");
}

#[test]
fn unsigned_frames_with_the_fcs_ids_never_reach_the_autonomy_or_a_ground_station() {
    let mut cc = companion(autonomy(AutonomyFallback::Decline));
    heard_fc(&mut cc, Moment::ZERO);
    let forged = bytes(FC, &position());
    for source in [Some(addr(FC_ADDR)), Some(addr(9999)), None] {
        let fate = cc.handle_frame(Moment::ZERO, arrival(FC_LINK, source, &forged, false));
        assert_eq!(fate.route, Links::NONE, "{source:?}");
        assert!(fate.dropped.is_some() && !fate.input, "{source:?}");
    }
    // The genuine frame, signed, goes to both.
    let fate = cc.handle_frame(
        Moment::ZERO,
        arrival(FC_LINK, Some(addr(FC_ADDR)), &forged, true),
    );
    assert_eq!(fate.route, Links::only(GROUND).union(Links::only(AUTONOMY)));
    assert_eq!(cc.drops().get(DropReason::Unauthenticated), 2);
    assert_eq!(cc.drops().get(DropReason::NotPeer), 1);
}

#[test]
fn unauthenticated_traffic_of_other_ids_stays_on_the_ground_side() {
    let mut cc = companion(autonomy(AutonomyFallback::Decline));
    heard_fc(&mut cc, Moment::ZERO);
    let camera = bytes(Peer::new(1, 100), &position());
    let fate = cc.handle_frame(
        Moment::ZERO,
        arrival(FC_LINK, Some(addr(FC_ADDR)), &camera, false),
    );
    assert_eq!(fate.route, Links::only(GROUND));
    // A ground station's unsigned command to the FC goes nowhere that acts.
    let command = bytes(
        GCS,
        &CommandLong {
            target_system: 1,
            target_component: 1,
            ..Default::default()
        },
    );
    let fate = cc.handle_frame(
        Moment::ZERO,
        arrival(GROUND, Some(addr(14550)), &command, false),
    );
    assert_eq!(fate.dropped, Some(DropReason::Unauthenticated));
    // Signed, it reaches the FC.
    let fate = cc.handle_frame(
        Moment::ZERO,
        arrival(GROUND, Some(addr(14550)), &command, true),
    );
    assert_eq!(fate.route, Links::only(FC_LINK));
}

#[test]
fn the_fcs_and_the_companions_ids_are_dropped_where_they_do_not_live() {
    let mut cc = companion(autonomy(AutonomyFallback::Decline));
    let hb = bytes(FC, &heartbeat());
    for link in [GROUND, AUTONOMY] {
        let fate = cc.handle_frame(Moment::ZERO, arrival(link, Some(addr(5000)), &hb, true));
        assert_eq!(fate.dropped, Some(DropReason::Impersonation), "link {link}");
    }
    let own = bytes(CC, &heartbeat());
    for link in [FC_LINK, GROUND, AUTONOMY] {
        let fate = cc.handle_frame(Moment::ZERO, arrival(link, Some(addr(5001)), &own, true));
        assert_eq!(fate.dropped, Some(DropReason::OwnIds), "link {link}");
    }
}

#[test]
fn the_autonomy_is_one_program_and_flies_only_through_the_gate() {
    let mut cc = companion(autonomy(AutonomyFallback::Decline));
    let first = bytes(Peer::new(1, 196), &rc(1234));
    let fate = cc.handle_frame(
        Moment::ZERO,
        arrival(AUTONOMY, Some(addr(7000)), &first, false),
    );
    assert_eq!(fate.dropped, Some(DropReason::Gated), "not in control yet");
    let second = bytes(Peer::new(1, 197), &rc(1999));
    let fate = cc.handle_frame(
        Moment::ZERO,
        arrival(AUTONOMY, Some(addr(7001)), &second, false),
    );
    assert_eq!(fate.dropped, Some(DropReason::NotPeer));
    // Its other messages go to the ground side only, never to the FC.
    let telemetry = bytes(Peer::new(1, 196), &position());
    let fate = cc.handle_frame(
        Moment::ZERO,
        arrival(AUTONOMY, Some(addr(7000)), &telemetry, false),
    );
    assert_eq!(fate.route, Links::only(GROUND));
}

#[test]
fn a_station_keeps_its_answers_among_200_strangers() {
    let mut cc = companion(builtin);
    let station = addr(14550);
    let hb = bytes(GCS, &heartbeat());
    let mut peers = None;
    for i in 0..200u16 {
        let now = Moment::from_millis(u64::from(i) * 10);
        if i % 50 == 0 {
            let _ = cc.handle_frame(now, arrival(GROUND, Some(station), &hb, false));
        }
        let stranger = bytes(Peer::new(i as u8 + 2, 1), &heartbeat());
        let _ = cc.handle_frame(
            now,
            arrival(GROUND, Some(addr(20_000 + i)), &stranger, false),
        );
        for out in drain(&mut cc) {
            if let Output::Peers {
                link: GROUND,
                peers: p,
            } = out
            {
                peers = Some(p);
            }
        }
    }
    let peers = peers.unwrap();
    assert!(peers.contains(station));
    // Half the slots are for stations that sign: strangers without the key
    // get the other half at most.
    assert_eq!(peers.iter().count(), MAX_PEERS / 2);
    // A station that signs, arriving late, is answered all the same.
    let late = addr(14560);
    let now = Moment::from_millis(2000);
    let _ = cc.handle_frame(now, arrival(GROUND, Some(late), &hb, true));
    let out = drain(&mut cc);
    assert!(
        out.iter().any(|o| matches!(o, Output::Peers { link: GROUND, peers } if peers.contains(late) && peers.contains(station))),
        "{out:?}"
    );
}

#[test]
fn a_flood_of_stranger_ids_never_makes_the_companion_forget_the_fc() {
    let mut cc = companion(builtin);
    heard_fc(&mut cc, Moment::ZERO);
    for i in 0..1000u32 {
        let stranger = bytes(
            Peer::new((i % 250) as u8 + 2, (i / 250) as u8 + 1),
            &heartbeat(),
        );
        let source = Some(addr(20_000 + (i % 7) as u16));
        let _ = cc.handle_frame(Moment::ZERO, arrival(GROUND, source, &stranger, false));
    }
    let command = bytes(
        GCS,
        &CommandLong {
            target_system: 1,
            target_component: 1,
            ..Default::default()
        },
    );
    let fate = cc.handle_frame(
        Moment::ZERO,
        arrival(GROUND, Some(addr(14550)), &command, true),
    );
    assert_eq!(fate.route, Links::only(FC_LINK));
}

/// The FC's RC-loss notice of `event`, signed.
fn rc_lost(cc: &mut CompanionNode, at: Moment, event: u32) -> Vec<Output<CompanionEvent>> {
    let notice = bytes(
        FC,
        &Message::FbwagNotice(wire::notice(FC, Status::RC_LOST, event)),
    );
    let fate = cc.handle_frame(at, arrival(FC_LINK, Some(addr(FC_ADDR)), &notice, true));
    assert!(fate.input);
    drain(cc)
}

fn notices(out: &[Output<CompanionEvent>]) -> Vec<(Status, u32)> {
    out.iter()
        .filter_map(|o| match o {
            Output::Transmit {
                message: Message::FbwagNotice(n),
                ..
            } => Some((n.failsafe_status, n.timestamp)),
            _ => None,
        })
        .collect()
}

#[test]
fn a_silent_autonomy_declines_the_takeover() {
    let mut cc = companion(autonomy(AutonomyFallback::Decline));
    heard_fc(&mut cc, Moment::ZERO);
    let out = rc_lost(&mut cc, Moment::from_millis(2000), 2000);
    assert_eq!(notices(&out), [(Status::NORMAL, 2000)]);
    assert!(
        out.contains(&Output::Event(CompanionEvent::Engine(CcOutput::Declined {
            event: 2000
        })))
    );
}

#[test]
fn a_speaking_autonomy_takes_over_and_gives_back_when_it_falls_silent() {
    let mut cc = companion(autonomy(AutonomyFallback::Decline));
    heard_fc(&mut cc, Moment::ZERO);
    let control = bytes(Peer::new(1, 196), &rc(1234));
    let t = Moment::from_millis(1900);
    let _ = cc.handle_frame(t, arrival(AUTONOMY, Some(addr(7000)), &control, false));
    let out = rc_lost(&mut cc, Moment::from_millis(2000), 2000);
    assert_eq!(notices(&out), [(Status::CC_TAKEOVER_CONFIRMED, 2000)]);
    let fate = cc.handle_frame(
        Moment::from_millis(2010),
        arrival(AUTONOMY, Some(addr(7000)), &control, false),
    );
    assert!(fate.input && fate.dropped.is_none());
    // Silent from 2010 ms on: the episode is given back at 2510 ms.
    let silent = Moment::from_millis(2010) + AUTONOMY_SILENCE;
    let mut out = Vec::new();
    while let Some(t) = cc.poll_timeout().filter(|t| *t <= silent) {
        cc.handle_timeout(t);
        out.extend(drain(&mut cc));
    }
    assert!(notices(&out).contains(&(Status::NORMAL, 2000)), "{out:?}");
}

/// Found by the model check: a notice that arrives after the autonomy's
/// silence began, before the companion's timer noticed it, was answered
/// with a takeover (then given back), not with a decline.
#[test]
fn a_notice_after_the_autonomy_fell_silent_is_declined_before_any_timer() {
    let mut cc = companion(autonomy(AutonomyFallback::Decline));
    heard_fc(&mut cc, Moment::ZERO);
    let control = bytes(Peer::new(1, 196), &rc(1234));
    let t = Moment::from_millis(1000);
    let _ = cc.handle_frame(t, arrival(AUTONOMY, Some(addr(7000)), &control, false));
    drain(&mut cc);
    // Silent from 1500 ms; the notice comes first, at 1500 ms.
    let at = t + AUTONOMY_SILENCE;
    let out = rc_lost(&mut cc, at, 1500);
    assert_eq!(notices(&out), [(Status::NORMAL, 1500)], "{out:?}");
}

#[test]
fn a_silent_autonomy_with_the_wings_level_fallback_takes_over_and_flies() {
    let mut cc = companion(autonomy(AutonomyFallback::WingsLevel));
    heard_fc(&mut cc, Moment::ZERO);
    let mut out = rc_lost(&mut cc, Moment::from_millis(2000), 2000);
    assert_eq!(notices(&out)[0], (Status::CC_TAKEOVER_CONFIRMED, 2000));
    while let Some(t) = cc
        .poll_timeout()
        .filter(|t| *t <= Moment::from_millis(2200))
    {
        cc.handle_timeout(t);
        out.extend(drain(&mut cc));
    }
    let overrides = out
        .iter()
        .filter(|o| {
            matches!(o, Output::Transmit { links, message: Message::RcChannelsOverride(m) }
                if *links == Links::only(FC_LINK) && m.chan3_raw == 1500)
        })
        .count();
    assert!(overrides >= 3, "{out:?}");
}

fn fc_node() -> FcNode {
    let cfg = FcConfig {
        require_signed: true,
        ..FcConfig::default()
    };
    let mut fc = FcNode::new(cfg, Moment::ZERO).unwrap();
    let spec = LinkSpec::new(Role::Peer, Answers::Target);
    fc.add_link(0, spec).unwrap();
    fc
}

#[test]
fn the_fc_falls_back_at_once_when_the_companion_declines() {
    let mut fc = fc_node();
    fc.set_receiver_ok(false);
    let mut event = None;
    let mut t = Moment::ZERO;
    while event.is_none() {
        t = fc.poll_timeout().unwrap();
        fc.handle_timeout(t);
        while let Some(out) = fc.poll_output() {
            if let Output::Transmit {
                message: Message::FbwagNotice(n),
                ..
            } = out
            {
                event = Some(n.timestamp);
            }
        }
    }
    let decline = bytes(
        CC,
        &Message::FbwagNotice(wire::notice(FC, Status::NORMAL, event.unwrap())),
    );
    let later = t + Duration::from_millis(5);
    let _ = fc.handle_frame(later, arrival(0, None, &decline, true));
    let modes: Vec<_> = std::iter::from_fn(|| fc.poll_output())
        .filter_map(|o| match o {
            Output::Event(FcOutput::SetMode(a)) => Some(a),
            _ => None,
        })
        .collect();
    assert_eq!(modes, [Authority::Rtl]);
    // Unsigned, the same notice is dropped and changes nothing.
    let mut fc = fc_node();
    let fate = fc.handle_frame(later, arrival(0, None, &decline, false));
    assert_eq!(fate.dropped, Some(DropReason::Unauthenticated));
}

#[test]
fn a_signed_router_routes_only_authenticated_frames_and_answers_only_their_sources() {
    let mut router = RouterNode::new(true);
    router.add_link(0, Answers::Chosen, true).unwrap();
    router.add_link(1, Answers::Target, true).unwrap();
    let hb = bytes(GCS, &heartbeat());
    let fate = router.handle_frame(Moment::ZERO, arrival(0, Some(addr(6000)), &hb, false));
    assert_eq!(fate.dropped, Some(DropReason::Unauthenticated));
    assert!(
        router.poll_output().is_none(),
        "an unsigned source earned answers"
    );
    let fate = router.handle_frame(Moment::ZERO, arrival(0, Some(addr(6001)), &hb, true));
    assert_eq!(fate.route, Links::only(1));
    assert!(
        matches!(router.poll_output(), Some(Output::Peers { link: 0, peers }) if peers.contains(addr(6001)))
    );
    // Without signing required, on a keyed link, unsigned frames are
    // routed but earn no answers.
    let mut router = RouterNode::new(false);
    router.add_link(0, Answers::Chosen, true).unwrap();
    router.add_link(1, Answers::Target, false).unwrap();
    let fate = router.handle_frame(Moment::ZERO, arrival(0, Some(addr(6000)), &hb, false));
    assert_eq!(fate.route, Links::only(1));
    assert!(router.poll_output().is_none());
}

#[test]
fn a_key_holder_behind_in_time_gets_a_signed_heartbeat_and_never_the_peers_place() {
    let mut cc = companion(builtin);
    // Signed with the key, but stale to this companion's clock: its parser
    // returns such a frame unauthenticated.
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    let mut signer = fbwag_dialect::Signer::new([7; 32], 0, 1);
    let h = Header {
        seq: 0,
        sysid: 1,
        compid: 1,
    };
    let n = encode(Version::V2, h, &heartbeat(), Some(&mut signer), &mut buf).unwrap();
    let stale = &buf[..n];
    let fc = addr(FC_ADDR);
    let beacons = |out: &[Output<CompanionEvent>]| {
        out.iter()
            .filter(|o| {
                matches!(o, Output::TransmitTo { link: FC_LINK, to, message: Message::Heartbeat(_) }
                    if *to == fc)
            })
            .count()
    };
    let fate = cc.handle_frame(Moment::ZERO, arrival(FC_LINK, Some(fc), stale, false));
    assert_eq!(fate.dropped, Some(DropReason::NotPeer));
    assert_eq!(beacons(&drain(&mut cc)), 1);
    // At most one a second, and never for an unsigned frame.
    let soon = Moment::from_millis(500);
    let _ = cc.handle_frame(soon, arrival(FC_LINK, Some(fc), stale, false));
    assert_eq!(beacons(&drain(&mut cc)), 0);
    let unsigned = bytes(FC, &heartbeat());
    let later = Moment::from_millis(1500);
    let _ = cc.handle_frame(later, arrival(FC_LINK, Some(fc), &unsigned, false));
    assert_eq!(beacons(&drain(&mut cc)), 0);
    let _ = cc.handle_frame(later, arrival(FC_LINK, Some(fc), stale, false));
    let out = drain(&mut cc);
    assert_eq!(beacons(&out), 1);
    assert!(
        !out.iter().any(|o| matches!(o, Output::Peers { .. })),
        "{out:?}"
    );
}

/// Time beacons cannot be stolen and need no empty link: a replayer of
/// one old signed frame, 100 datagrams a second from its own address,
/// gets one beacon a second, and the genuine peer, restarted on a new
/// address (its clock behind, no state) while the link still answers the
/// old one, gets its own at its first frame; its next frame, fresh once it
/// adopted the beacon's time, makes it the peer at once.
#[test]
fn a_replayer_never_takes_the_beacons_of_a_peer_that_restarted() {
    let mut cc = companion(builtin);
    heard_fc(&mut cc, Moment::ZERO);
    let stale = |seq: u8| {
        let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
        let mut signer = fbwag_dialect::Signer::new([7; 32], 0, 1);
        let h = Header {
            seq,
            sysid: FC.sysid,
            compid: FC.compid,
        };
        let n = encode(Version::V2, h, &heartbeat(), Some(&mut signer), &mut buf).unwrap();
        buf[..n].to_vec()
    };
    let (replayer, restarted) = (addr(40_000), addr(FC_ADDR + 1));
    let old = stale(0);
    let beacons = |cc: &mut CompanionNode, to: SocketAddr| {
        drain(cc)
            .iter()
            .filter(|o| matches!(o, Output::TransmitTo { to: t, .. } if *t == to))
            .count()
    };
    let (mut to_replayer, mut to_peer) = (0, 0);
    for ms in (1_000..4_000u64).step_by(10) {
        let now = Moment::from_millis(ms);
        let _ = cc.handle_frame(now, arrival(FC_LINK, Some(replayer), &old, false));
        to_replayer += beacons(&mut cc, replayer);
        if ms % 1000 == 500 {
            let own = stale((ms / 1000) as u8);
            let fate = cc.handle_frame(now, arrival(FC_LINK, Some(restarted), &own, false));
            assert_eq!(fate.dropped, Some(DropReason::NotPeer));
            to_peer += beacons(&mut cc, restarted);
        }
    }
    assert_eq!((to_replayer, to_peer), (3, 3));
    // Fresh now: the restarted FC is the peer at once.
    let hb = bytes(FC, &heartbeat());
    let now = Moment::from_millis(4_000);
    let fate = cc.handle_frame(now, arrival(FC_LINK, Some(restarted), &hb, true));
    assert!(fate.input, "{fate:?}");
    let out = drain(&mut cc);
    assert!(
        out.iter().any(
            |o| matches!(o, Output::Peers { link: FC_LINK, peers } if peers.contains(restarted))
        ),
        "{out:?}"
    );
}

/// A frame of the FC's ids refused for its signature (another key) on
/// the listening FC link is answered with the companion's signed
/// heartbeat, once a second, while the link answers no FC: so an FC with
/// the wrong key sees the mismatch too. Once an FC is the peer (its key
/// right), a stranger's bad signatures get nothing; nor do other ids'.
#[test]
fn a_wrong_key_is_answered_only_while_the_link_has_no_peer() {
    let mut cc = companion(builtin);
    let (fc, stranger) = (addr(FC_ADDR), addr(40_001));
    let answers = |cc: &mut CompanionNode, to: SocketAddr| {
        drain(cc)
            .iter()
            .filter(|o| matches!(o, Output::TransmitTo { to: t, .. } if *t == to))
            .count()
    };
    let mut to_fc = 0;
    for ms in (0..3_000u64).step_by(100) {
        let now = Moment::from_millis(ms);
        cc.handle_bad_signature(now, FC_LINK, fc, FC);
        to_fc += answers(&mut cc, fc);
        cc.handle_bad_signature(now, FC_LINK, stranger, GCS);
        assert_eq!(answers(&mut cc, stranger), 0, "not the FC's ids");
    }
    assert_eq!(to_fc, 3, "once a second");
    heard_fc(&mut cc, Moment::from_millis(3_000));
    for ms in (3_000..6_000u64).step_by(100) {
        let now = Moment::from_millis(ms);
        cc.handle_bad_signature(now, FC_LINK, stranger, FC);
        assert_eq!(answers(&mut cc, stranger), 0, "the link has its FC");
    }
}

/// A link trusted like the key (`--trusted-out`): a tool's unsigned
/// command reaches the FC, to be signed on the way; the same command from
/// an ordinary ground link is dropped; the trusted link still cannot claim
/// the FC's ids, and a frame the dialect does not know (which cannot be
/// signed) stays on the ground side.
#[test]
fn a_trusted_link_reaches_the_fc_signed_on_the_way() {
    const TRUSTED: u8 = 3;
    let mut cc = companion(builtin);
    let trusted = LinkSpec {
        trusted: true,
        ..LinkSpec::new(Role::Ground, Answers::Chosen)
    };
    cc.add_link(TRUSTED, trusted).unwrap();
    heard_fc(&mut cc, Moment::ZERO);
    let command = bytes(
        GCS,
        &CommandLong {
            target_system: FC.sysid,
            target_component: FC.compid,
            ..Default::default()
        },
    );
    let tool = Some(addr(14560));
    let fate = cc.handle_frame(Moment::ZERO, arrival(TRUSTED, tool, &command, false));
    assert_eq!(
        (fate.route, fate.sign),
        (Links::only(FC_LINK), true),
        "{fate:?}"
    );

    let fate = cc.handle_frame(Moment::ZERO, arrival(GROUND, tool, &command, false));
    assert_eq!(fate.dropped, Some(DropReason::Unauthenticated));

    let forged = bytes(FC, &position());
    let fate = cc.handle_frame(Moment::ZERO, arrival(TRUSTED, tool, &forged, false));
    assert_eq!(fate.dropped, Some(DropReason::Impersonation));

    let mut unknown = bytes(GCS, &position());
    unknown[7..10].copy_from_slice(&[0xfe, 0xff, 0xff]); // an id no dialect defines
    let fate = cc.handle_frame(Moment::ZERO, arrival(TRUSTED, tool, &unknown, false));
    assert!(!fate.sign && !fate.route.contains(FC_LINK), "{fate:?}");
}

/// Who flies is decided on the ground: a trusted link's unsigned frame
/// that would change it (a delegation or failsafe parameter, the signing
/// key, control) is never signed on, and is counted; an ordinary
/// parameter write and a parameter read go on, signed on the way, and a
/// station that signs its own frames is trusted with the key as before.
#[test]
fn a_trusted_link_never_signs_on_what_changes_who_flies() {
    use fbwag_dialect::dialects::common::{ParamRequestRead, ParamSet, SetupSigning};
    use fbwag_dialect::mavframe::field::chars;
    const TRUSTED: u8 = 3;
    let mut cc = companion(builtin);
    let trusted = LinkSpec {
        trusted: true,
        ..LinkSpec::new(Role::Ground, Answers::Chosen)
    };
    cc.add_link(TRUSTED, trusted).unwrap();
    heard_fc(&mut cc, Moment::ZERO);
    let set = |name: &str, value: f32| {
        bytes(
            GCS,
            &ParamSet {
                target_system: FC.sysid,
                target_component: FC.compid,
                param_id: chars(name),
                param_value: value,
                ..Default::default()
            },
        )
    };
    let tool = Some(addr(14540));
    let to_fc = |cc: &mut CompanionNode, frame: &[u8], authenticated| {
        let fate = cc.handle_frame(Moment::ZERO, arrival(TRUSTED, tool, frame, authenticated));
        drain(cc);
        fate
    };
    for frame in [
        set("FBWAG_CC_COMPID", 77.0),
        set("FBWAG_CC_SYSID", 77.0),
        set("FS_SHORT_TIMEOUT", 25.5),
        bytes(GCS, &SetupSigning::default()),
        bytes(GCS, &rc(1999)),
    ] {
        let fate = to_fc(&mut cc, &frame, false);
        assert_eq!(fate.dropped, Some(DropReason::Protected), "{fate:?}");
        assert!(fate.route.is_empty() && !fate.sign);
    }
    assert_eq!(cc.drops().get(DropReason::Protected), 5);
    let read = bytes(
        GCS,
        &ParamRequestRead {
            target_system: FC.sysid,
            target_component: FC.compid,
            param_id: chars("FBWAG_CC_COMPID"),
            param_index: -1,
        },
    );
    for frame in [set("AIRSPEED_CRUISE", 20.0), read] {
        let fate = to_fc(&mut cc, &frame, false);
        assert_eq!((fate.route, fate.sign), (Links::only(FC_LINK), true));
    }
    // Signed by a station with the key: its own authority, untouched.
    let fate = to_fc(&mut cc, &set("FBWAG_CC_COMPID", 191.0), true);
    assert_eq!((fate.route, fate.sign), (Links::only(FC_LINK), false));
}

/// Ground tools hear the companion's heartbeat only once the FC is heard:
/// mavsdk_server 3.x takes the first component it hears for the vehicle
/// and, when that is the companion, never finds the autopilot.
#[test]
fn the_companions_heartbeat_reaches_ground_links_once_the_fc_is_heard() {
    let mut cc = companion(builtin);
    let heartbeats = |cc: &mut CompanionNode, at: Moment| -> Vec<Links> {
        cc.handle_timeout(at);
        drain(cc)
            .into_iter()
            .filter_map(|out| match out {
                Output::Transmit {
                    links,
                    message: Message::Heartbeat(_),
                } => Some(links),
                _ => None,
            })
            .collect()
    };
    let before = heartbeats(&mut cc, Moment::ZERO);
    assert_eq!(before, [Links::only(FC_LINK)], "only the FC link");

    heard_fc(&mut cc, Moment::from_millis(500));
    let after = heartbeats(&mut cc, Moment::from_millis(1000));
    assert_eq!(after.len(), 1, "{after:?}");
    assert!(
        after[0].contains(FC_LINK) && after[0].contains(GROUND),
        "{after:?}"
    );
}

/// The autonomy asks the FC for the telemetry it needs: its rate requests
/// go to the FC signed on by the companion; its other messages (a
/// parameter write, a command) never reach the FC.
#[test]
fn the_autonomys_rate_requests_reach_the_fc_and_nothing_else_does() {
    use fbwag_dialect::dialects::common::{CommandInt, MavCmd, ParamSet, RequestDataStream};
    let mut cc = companion(autonomy(AutonomyFallback::Decline));
    heard_fc(&mut cc, Moment::ZERO);
    let me = Peer::new(1, 196);
    let program = Some(addr(14561));
    let rate = bytes(
        me,
        &CommandLong {
            target_system: FC.sysid,
            target_component: FC.compid,
            command: MavCmd::SET_MESSAGE_INTERVAL,
            param1: 30.0,
            param2: 100_000.0,
            ..Default::default()
        },
    );
    let streams = bytes(
        me,
        &RequestDataStream {
            target_system: FC.sysid,
            target_component: FC.compid,
            req_stream_id: fbwag_dialect::dialects::common::MavDataStream::ALL,
            req_message_rate: 10,
            start_stop: 1,
        },
    );
    let once = bytes(
        me,
        &CommandInt {
            target_system: FC.sysid,
            target_component: FC.compid,
            command: MavCmd::REQUEST_MESSAGE,
            param1: 33.0,
            ..Default::default()
        },
    );
    for frame in [rate, streams, once] {
        let fate = cc.handle_frame(Moment::ZERO, arrival(AUTONOMY, program, &frame, false));
        drain(&mut cc);
        assert_eq!(
            (fate.route, fate.sign),
            (Links::only(FC_LINK), true),
            "{fate:?}"
        );
    }
    let reboot = bytes(
        me,
        &CommandLong {
            target_system: FC.sysid,
            target_component: FC.compid,
            command: MavCmd::PREFLIGHT_REBOOT_SHUTDOWN,
            ..Default::default()
        },
    );
    let write = bytes(
        me,
        &ParamSet {
            target_system: FC.sysid,
            target_component: FC.compid,
            ..Default::default()
        },
    );
    let reboot_int = bytes(
        me,
        &CommandInt {
            target_system: FC.sysid,
            target_component: FC.compid,
            command: MavCmd::PREFLIGHT_REBOOT_SHUTDOWN,
            ..Default::default()
        },
    );
    for frame in [reboot, reboot_int, write] {
        let fate = cc.handle_frame(Moment::ZERO, arrival(AUTONOMY, program, &frame, false));
        drain(&mut cc);
        assert!(!fate.route.contains(FC_LINK) && !fate.sign, "{fate:?}");
    }
}

/// A ground link with one far end (`udpout`) takes frames from that
/// address alone: another program sending to the companion's port is
/// dropped, not routed.
#[test]
fn a_ground_link_with_a_fixed_far_end_takes_frames_from_it_alone() {
    const OUT: u8 = 3;
    let mut cc = companion(builtin);
    let station = addr(14550);
    cc.add_link(OUT, LinkSpec::new(Role::Ground, Answers::Fixed(station)))
        .unwrap();
    heard_fc(&mut cc, Moment::ZERO);
    let hb = bytes(GCS, &heartbeat());
    let fate = cc.handle_frame(Moment::ZERO, arrival(OUT, Some(station), &hb, true));
    assert!(
        fate.dropped.is_none() && fate.route.contains(FC_LINK),
        "{fate:?}"
    );
    let fate = cc.handle_frame(Moment::ZERO, arrival(OUT, Some(addr(14549)), &hb, true));
    assert_eq!(fate.dropped, Some(DropReason::NotPeer), "{fate:?}");
    assert!(fate.route.is_empty());
}

/// A station's route learned from its signed frames is not shared with a
/// stranger who sends its ids unsigned on another ground link: the FC's
/// frames to the station go where the signed ones came from.
#[test]
fn a_stranger_with_a_stations_ids_never_gets_its_traffic() {
    const OTHER: u8 = 3;
    let mut cc = companion(builtin);
    cc.add_link(OTHER, LinkSpec::new(Role::Ground, Answers::Chosen))
        .unwrap();
    heard_fc(&mut cc, Moment::ZERO);
    let hb = bytes(GCS, &heartbeat());
    let fate = cc.handle_frame(Moment::ZERO, arrival(GROUND, Some(addr(14550)), &hb, true));
    assert!(fate.dropped.is_none(), "{fate:?}");
    let fate = cc.handle_frame(Moment::ZERO, arrival(OTHER, Some(addr(6000)), &hb, false));
    assert!(!fate.route.contains(FC_LINK), "{fate:?}");
    drain(&mut cc);
    let to_station = bytes(
        FC,
        &CommandLong {
            target_system: GCS.sysid,
            target_component: GCS.compid,
            ..Default::default()
        },
    );
    let from_fc = Some(addr(FC_ADDR));
    let fate = cc.handle_frame(Moment::ZERO, arrival(FC_LINK, from_fc, &to_station, true));
    assert_eq!(fate.route, Links::only(GROUND), "{fate:?}");
}

/// A link opened again (a serial port replugged, a socket rebound) forgets
/// whom it answered: the FC heard there from a new address is the link's
/// peer at once, without waiting out the old one's silence.
#[test]
fn a_reopened_link_takes_its_next_peer_at_once() {
    // Without signing (a signed frame moves a peer at once anyway).
    let (mut cc, hb) = unsigned_companion_that_heard_the_fc();
    let moved = Some(addr(FC_ADDR + 1));
    let soon = Moment::from_millis(100);
    let fate = cc.handle_frame(soon, arrival(FC_LINK, moved, &hb, false));
    assert_eq!(fate.dropped, Some(DropReason::NotPeer), "{fate:?}");
    cc.link_reopened(FC_LINK);
    let fate = cc.handle_frame(soon, arrival(FC_LINK, moved, &hb, false));
    assert!(fate.dropped.is_none(), "{fate:?}");
    let peers = drain(&mut cc).into_iter().find_map(|o| match o {
        Output::Peers { link, peers } if link == FC_LINK => Some(peers),
        _ => None,
    });
    let peers = peers.expect("the link's new peer");
    assert!(peers.contains(addr(FC_ADDR + 1)) && !peers.contains(addr(FC_ADDR)));
    assert!(!peers.is_empty() && Peers::default().is_empty());

    // The FC's node alike: its companion link.
    let mut fc = FcNode::new(FcConfig::default(), Moment::ZERO).unwrap();
    fc.add_link(0, LinkSpec::new(Role::Peer, Answers::Chosen))
        .unwrap();
    let cc_hb = bytes(CC, &Message::Heartbeat(wire::cc_heartbeat()));
    let first = Some(addr(14560));
    let fate = fc.handle_frame(Moment::ZERO, arrival(0, first, &cc_hb, false));
    assert!(fate.dropped.is_none(), "{fate:?}");
    let fate = fc.handle_frame(soon, arrival(0, moved, &cc_hb, false));
    assert_eq!(fate.dropped, Some(DropReason::NotPeer), "{fate:?}");
    fc.link_reopened(0);
    let fate = fc.handle_frame(soon, arrival(0, moved, &cc_hb, false));
    assert!(fate.dropped.is_none(), "{fate:?}");
}

/// The wings-level fallback flies only while the autonomy is silent: a
/// speaking autonomy's control is the only control the FC gets.
#[test]
fn the_wings_level_fallback_stays_out_while_the_autonomy_speaks() {
    let mut cc = companion(autonomy(AutonomyFallback::WingsLevel));
    heard_fc(&mut cc, Moment::ZERO);
    let control = bytes(Peer::new(1, 196), &rc(1234));
    let program = Some(addr(7000));
    let speak = |cc: &mut CompanionNode, at: Moment| {
        let _ = cc.handle_frame(at, arrival(AUTONOMY, program, &control, false));
    };
    speak(&mut cc, Moment::from_millis(1900));
    let mut out = rc_lost(&mut cc, Moment::from_millis(2000), 2000);
    assert_eq!(notices(&out)[0], (Status::CC_TAKEOVER_CONFIRMED, 2000));
    let mut spoke = Moment::from_millis(2000);
    let end = Moment::from_millis(2400);
    while let Some(t) = cc.poll_timeout().filter(|t| *t <= end) {
        while spoke + Duration::from_millis(50) <= t {
            spoke = spoke + Duration::from_millis(50);
            speak(&mut cc, spoke);
        }
        cc.handle_timeout(t);
        out.extend(drain(&mut cc));
    }
    let (mut autonomy, mut fallback) = (0, 0);
    for o in &out {
        if let Output::Transmit {
            message: Message::RcChannelsOverride(m),
            ..
        } = o
        {
            autonomy += usize::from(m.chan1_raw == 1234);
            fallback += usize::from(m.chan3_raw == 1500);
        }
    }
    assert_eq!(fallback, 0, "{out:?}");
    assert!(autonomy >= 3, "{out:?}");
}

/// The FC's node reports the settings in force and its drops, and new
/// settings take effect in its engine and its links' policy alike.
#[test]
fn the_fc_node_takes_new_settings_whole() {
    let mut fc = fc_node();
    assert!(fc.config().require_signed);
    let cc_hb = bytes(CC, &Message::Heartbeat(wire::cc_heartbeat()));
    let fate = fc.handle_frame(Moment::ZERO, arrival(0, None, &cc_hb, false));
    assert_eq!(fate.dropped, Some(DropReason::Unauthenticated));
    assert_eq!(fc.drops().get(DropReason::Unauthenticated), 1);

    let relaxed = FcConfig {
        require_signed: false,
        override_timeout: Duration::from_secs(4),
        ..FcConfig::default()
    };
    fc.reconfigure(relaxed, Moment::from_millis(10)).unwrap();
    assert_eq!(*fc.config(), relaxed);
    assert_eq!(
        fc.engine().machine().config().override_timeout,
        Duration::from_secs(4)
    );
    let fate = fc.handle_frame(Moment::from_millis(20), arrival(0, None, &cc_hb, false));
    assert!(fate.dropped.is_none() && fate.input, "{fate:?}");
    // A station's request is served, and no input of the engine.
    let gcs_hb = bytes(GCS, &heartbeat());
    let fate = fc.handle_frame(Moment::from_millis(20), arrival(0, None, &gcs_hb, false));
    assert!(fate.serve && !fate.input, "{fate:?}");
    let invalid = FcConfig {
        retry_interval: Duration::ZERO,
        ..relaxed
    };
    assert!(fc.reconfigure(invalid, Moment::from_millis(30)).is_err());
    assert_eq!(*fc.config(), relaxed, "a refused setting changes nothing");
}

/// The FC answers a companion with the wrong key with its own signed
/// heartbeat, once a second, so that the companion counts the mismatch
/// too; never a source with other ids.
#[test]
fn the_fc_answers_a_wrong_key_with_the_companions_ids_once_a_second() {
    let mut fc = FcNode::new(FcConfig::default(), Moment::ZERO).unwrap();
    fc.add_link(0, LinkSpec::new(Role::Peer, Answers::Chosen))
        .unwrap();
    // A ground station's port answers no wrong key: only the companion's.
    fc.add_link(1, LinkSpec::new(Role::Ground, Answers::Chosen))
        .unwrap();
    let (companion, stranger) = (addr(14560), addr(40_001));
    let mut answered = 0;
    for ms in (0..3_000u64).step_by(100) {
        let now = Moment::from_millis(ms);
        fc.handle_bad_signature(now, 0, companion, CC);
        fc.handle_bad_signature(now, 0, stranger, GCS);
        fc.handle_bad_signature(now, 1, stranger, CC);
        while let Some(out) = fc.poll_output() {
            match out {
                Output::TransmitTo {
                    to,
                    message: Message::Heartbeat(_),
                    ..
                } if to == companion => answered += 1,
                Output::TransmitTo { .. } => panic!("{out:?}"),
                _ => {}
            }
        }
    }
    assert_eq!(answered, 3, "once a second");
}

/// Drops by reason, as the programs' status events give them: every
/// reason once, under its documented name (docs/deployment.md,
/// "Monitoring"), with its count; set-up errors say which link.
#[test]
fn drops_are_counted_by_reason_under_their_documented_names() {
    let mut fc = fc_node();
    let cc_hb = bytes(CC, &Message::Heartbeat(wire::cc_heartbeat()));
    for _ in 0..2 {
        let _ = fc.handle_frame(Moment::ZERO, arrival(0, None, &cc_hb, false));
    }
    let counts: Vec<(&str, u64)> = fc.drops().counts().map(|(r, n)| (r.name(), n)).collect();
    assert_eq!(
        counts,
        [
            ("own_ids", 0),
            ("impersonation", 0),
            ("unauthenticated", 2),
            ("not_peer", 0),
            ("gated", 0),
            ("filtered", 0),
            ("duplicate", 0),
            ("protected", 0),
        ]
    );
    let err = fc
        .add_link(0, LinkSpec::new(Role::Peer, Answers::Target))
        .unwrap_err();
    assert_eq!(err.to_string(), "link 0 is taken or out of range");
}

/// The router's links alike: one with a fixed far end takes frames from
/// that address alone, and a reopened listening link forgets the stations
/// it answered.
#[test]
fn the_routers_fixed_and_reopened_links() {
    let station = addr(14550);
    let mut router = RouterNode::new(false);
    router.add_link(0, Answers::Fixed(station), false).unwrap();
    router.add_link(1, Answers::Chosen, false).unwrap();
    let hb = bytes(GCS, &heartbeat());
    let fate = router.handle_frame(Moment::ZERO, arrival(0, Some(station), &hb, false));
    assert_eq!((fate.dropped, fate.route), (None, Links::only(1)));
    let fate = router.handle_frame(Moment::ZERO, arrival(0, Some(addr(14549)), &hb, false));
    assert_eq!(fate.dropped, Some(DropReason::NotPeer));

    let fc_hb = bytes(FC, &heartbeat());
    let _ = router.handle_frame(Moment::ZERO, arrival(1, Some(addr(6000)), &fc_hb, false));
    while router.poll_output().is_some() {}
    router.link_reopened(1);
    let _ = router.handle_frame(Moment::ZERO, arrival(1, Some(addr(6001)), &fc_hb, false));
    let peers = std::iter::from_fn(|| router.poll_output()).find_map(|o| match o {
        Output::Peers { link: 1, peers } => Some(peers),
        _ => None,
    });
    let peers = peers.expect("the reopened link's peers");
    assert!(
        peers.contains(addr(6001)) && !peers.contains(addr(6000)),
        "{peers:?}"
    );
}
