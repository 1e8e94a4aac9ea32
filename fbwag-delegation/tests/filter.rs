//! Link filters, de-duplication and sniffers in the nodes: in-filters
//! drop before routing (counted as `filtered`), out-filters take links off
//! a route, copies within the window are dropped (counted as
//! `duplicate`), a sniffer link gets frames addressed to others, and on
//! the companion the engine's inputs and the node's own messages are
//! decided before any filter.

use fbwag_delegation::cc::CcConfig;
use fbwag_delegation::fc::Authority;
use fbwag_delegation::node::{
    Answers, Arrival, CompanionNode, ControlSource, Direction, DropReason, Filter, FilterRules,
    LinkSpec, Links, Output, Role, RouterNode,
};
use fbwag_delegation::{wire, Moment, Peer};
use fbwag_dialect::dialects::common::CommandLong;
use fbwag_dialect::dialects::standard::GlobalPositionInt;
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Frame, Header, Message, Version};
use std::time::Duration;

const FC: Peer = Peer::new(1, 1);
const GCS: Peer = Peer::new(255, 190);

fn bytes(from: Peer, seq: u8, msg: &(impl Encode + ?Sized)) -> Vec<u8> {
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    let h = Header {
        seq,
        sysid: from.sysid,
        compid: from.compid,
    };
    let n = encode(Version::V2, h, msg, None, &mut buf).unwrap();
    buf[..n].to_vec()
}

fn arrival(link: u8, b: &[u8]) -> Arrival<'_> {
    Arrival {
        link,
        source: None,
        frame: Frame::new_checked(b).unwrap(),
        authenticated: false,
    }
}

fn heartbeat(from: Peer, seq: u8) -> Vec<u8> {
    bytes(
        from,
        seq,
        &Message::Heartbeat(wire::fc_heartbeat(Authority::Pilot)),
    )
}

fn position(from: Peer, seq: u8) -> Vec<u8> {
    bytes(from, seq, &GlobalPositionInt::default())
}

fn filter(rules: &[&str]) -> Filter {
    let mut r = FilterRules::new();
    for rule in rules {
        r.parse(rule).unwrap();
    }
    r.filter()
}

/// A router of `n` links, each with one far end.
fn router(n: u8) -> RouterNode {
    let mut r = RouterNode::new(false);
    for link in 0..n {
        r.add_link(link, Answers::Target, false).unwrap();
    }
    r
}

fn links(ids: &[u8]) -> Links {
    ids.iter()
        .fold(Links::NONE, |acc, l| acc.union(Links::only(*l)))
}

#[test]
fn an_in_filter_drops_before_routing_and_counts_it() {
    let mut r = router(3);
    r.set_filter(0, Direction::In, filter(&["block-msg=GLOBAL_POSITION_INT"]))
        .unwrap();
    let t = Moment::ZERO;
    let fate = r.handle_frame(t, arrival(0, &position(FC, 0)));
    assert_eq!(fate.dropped, Some(DropReason::Filtered));
    assert!(fate.route.is_empty());
    assert_eq!(r.drops().get(DropReason::Filtered), 1);
    // Other messages of that link, and that message on other links, go on.
    let fate = r.handle_frame(t, arrival(0, &heartbeat(FC, 1)));
    assert_eq!((fate.dropped, fate.route), (None, links(&[1, 2])));
    let fate = r.handle_frame(t, arrival(1, &position(FC, 2)));
    assert_eq!((fate.dropped, fate.route), (None, links(&[0, 2])));
    assert_eq!(r.drops().total(), 1);
}

#[test]
fn a_refused_source_teaches_no_route() {
    let mut r = router(3);
    r.set_filter(1, Direction::In, filter(&["allow-sys=255"]))
        .unwrap();
    let t = Moment::ZERO;
    // 7/7 speaks on link 1, refused: a command to 7/7 has no route.
    let fate = r.handle_frame(t, arrival(1, &heartbeat(Peer::new(7, 7), 0)));
    assert_eq!(fate.dropped, Some(DropReason::Filtered));
    let command = CommandLong {
        target_system: 7,
        target_component: 7,
        ..Default::default()
    };
    let fate = r.handle_frame(t, arrival(0, &bytes(GCS, 0, &command)));
    assert!(fate.route.is_empty(), "{:?}", fate.route);
    // The allowed source does teach its route.
    let fate = r.handle_frame(t, arrival(1, &heartbeat(Peer::new(255, 7), 1)));
    assert_eq!(fate.route, links(&[0, 2]));
    let command = CommandLong {
        target_system: 255,
        target_component: 7,
        ..Default::default()
    };
    let fate = r.handle_frame(t, arrival(0, &bytes(GCS, 1, &command)));
    assert_eq!(fate.route, links(&[1]));
}

#[test]
fn an_out_filter_takes_its_link_off_the_route_without_a_drop() {
    let mut r = router(4);
    r.set_filter(2, Direction::Out, filter(&["block-msg=0"]))
        .unwrap();
    r.set_filter(3, Direction::Out, filter(&["allow-sys=1", "allow-msg=0"]))
        .unwrap();
    let t = Moment::ZERO;
    let fate = r.handle_frame(t, arrival(0, &heartbeat(FC, 0)));
    assert_eq!((fate.dropped, fate.route), (None, links(&[1, 3])));
    let fate = r.handle_frame(t, arrival(0, &position(FC, 1)));
    assert_eq!(fate.route, links(&[1, 2]));
    let fate = r.handle_frame(t, arrival(0, &heartbeat(GCS, 2)));
    assert_eq!(fate.route, links(&[1]));
    assert_eq!(r.drops().total(), 0);
    // Back to letting everything through.
    r.set_filter(2, Direction::Out, Filter::ALL).unwrap();
    r.set_filter(3, Direction::Out, Filter::ALL).unwrap();
    let fate = r.handle_frame(t, arrival(0, &heartbeat(GCS, 3)));
    assert_eq!(fate.route, links(&[1, 2, 3]));
    assert!(r.set_filter(9, Direction::In, Filter::ALL).is_err());
}

fn command_to(from: Peer, target: Peer, seq: u8) -> Vec<u8> {
    let cmd = CommandLong {
        target_system: target.sysid,
        target_component: target.compid,
        ..CommandLong::default()
    };
    bytes(from, seq, &cmd)
}

#[test]
fn a_sniffer_gets_frames_addressed_to_others_through_its_out_filter() {
    let mut r = router(4);
    let t = Moment::ZERO;
    // The FC is seen on link 0; the ground station's command for it goes
    // there alone.
    let _ = r.handle_frame(t, arrival(0, &heartbeat(FC, 0)));
    let fate = r.handle_frame(t, arrival(1, &command_to(GCS, FC, 0)));
    assert_eq!(fate.route, links(&[0]));
    r.set_sniffer(3).unwrap();
    let fate = r.handle_frame(t, arrival(1, &command_to(GCS, FC, 1)));
    assert_eq!(fate.route, links(&[0, 3]));
    // Broadcasts as before; nothing goes back where it came from.
    let fate = r.handle_frame(t, arrival(3, &heartbeat(GCS, 2)));
    assert_eq!(fate.route, links(&[0, 1, 2]));
    let fate = r.handle_frame(t, arrival(0, &command_to(FC, GCS, 1)));
    assert_eq!(fate.route, links(&[1, 3]), "GCS was seen on links 1 and 3");
    // Its out-filter still decides what it gets.
    r.set_filter(3, Direction::Out, filter(&["block-msg=COMMAND_LONG"]))
        .unwrap();
    let fate = r.handle_frame(t, arrival(1, &command_to(GCS, FC, 3)));
    assert_eq!(fate.route, links(&[0]));
    assert!(r.set_sniffer(9).is_err());
}

#[test]
fn a_copy_within_the_window_goes_on_once_and_after_it_again() {
    let mut r = router(3);
    r.set_dedup(Some(Duration::from_millis(100)));
    let frame = heartbeat(FC, 5);
    let at = Moment::from_millis;
    let fate = r.handle_frame(at(1000), arrival(0, &frame));
    assert_eq!(fate.route, links(&[1, 2]));
    // The same bytes over the redundant link, 30 ms later: dropped.
    let fate = r.handle_frame(at(1030), arrival(1, &frame));
    assert_eq!(fate.dropped, Some(DropReason::Duplicate));
    assert_eq!(r.drops().get(DropReason::Duplicate), 1);
    // Another frame (the next sequence number) is no copy.
    let fate = r.handle_frame(at(1040), arrival(1, &heartbeat(FC, 6)));
    assert_eq!(fate.dropped, None);
    // After the window the same bytes go on again.
    let fate = r.handle_frame(at(1100), arrival(1, &frame));
    assert_eq!((fate.dropped, fate.route), (None, links(&[0, 2])));
    // Off: every copy goes on.
    r.set_dedup(None);
    let fate = r.handle_frame(at(1101), arrival(0, &frame));
    assert_eq!(fate.dropped, None);
    r.set_dedup(Some(Duration::ZERO));
    let fate = r.handle_frame(at(1102), arrival(0, &frame));
    assert_eq!(fate.dropped, None);
}

#[test]
fn a_copy_one_link_refuses_does_not_make_anothers_a_duplicate() {
    let mut r = router(3);
    r.set_dedup(Some(Duration::from_secs(1)));
    r.set_filter(0, Direction::In, filter(&["block-sys=1"]))
        .unwrap();
    let frame = heartbeat(FC, 0);
    let fate = r.handle_frame(Moment::ZERO, arrival(0, &frame));
    assert_eq!(fate.dropped, Some(DropReason::Filtered));
    let fate = r.handle_frame(Moment::from_millis(5), arrival(1, &frame));
    assert_eq!((fate.dropped, fate.route), (None, links(&[0, 2])));
}

const FC_LINK: u8 = 0;
const GROUND: u8 = 1;

fn companion() -> CompanionNode {
    let mut cc =
        CompanionNode::new(CcConfig::default(), ControlSource::Builtin, Moment::ZERO).unwrap();
    cc.add_link(FC_LINK, LinkSpec::new(Role::Peer, Answers::Target))
        .unwrap();
    cc.add_link(GROUND, LinkSpec::new(Role::Ground, Answers::Target))
        .unwrap();
    cc
}

#[test]
fn the_companions_protocol_frames_are_decided_before_any_filter() {
    let mut cc = companion();
    let nothing = filter(&["allow-sys=99", "allow-msg=99"]);
    for direction in [Direction::In, Direction::Out] {
        cc.set_filter(FC_LINK, direction, nothing).unwrap();
    }
    // The FC's heartbeat is still the engine's input, routed nowhere,
    // and counted as no drop.
    let fate = cc.handle_frame(Moment::ZERO, arrival(FC_LINK, &heartbeat(FC, 0)));
    assert!(fate.input && fate.route.is_empty() && fate.dropped.is_none());
    assert_eq!(cc.drops().total(), 0);
    assert!(cc.engine().state() != fbwag_delegation::cc::CcState::Idle);
    // The companion's own messages still go to the FC link.
    cc.handle_timeout(Moment::from_millis(1500));
    let mut to_fc = 0;
    while let Some(out) = cc.poll_output() {
        if let Output::Transmit { links, .. } = out {
            to_fc += usize::from(links.contains(FC_LINK));
        }
    }
    assert!(to_fc > 0, "the companion's heartbeat reaches the FC link");
    // A ground station's frames do not reach the FC link.
    let fate = cc.handle_frame(
        Moment::from_millis(1600),
        arrival(GROUND, &heartbeat(GCS, 0)),
    );
    assert_eq!((fate.dropped, fate.route), (None, Links::NONE));
    // A frame of the FC link that is no input is dropped, counted.
    let fate = cc.handle_frame(
        Moment::from_millis(1700),
        arrival(FC_LINK, &heartbeat(GCS, 1)),
    );
    assert_eq!(fate.dropped, Some(DropReason::Filtered));
}

#[test]
fn the_companions_ground_links_are_filtered_both_ways() {
    let mut cc = companion();
    cc.set_filter(GROUND, Direction::In, filter(&["block-msg=COMMAND_LONG"]))
        .unwrap();
    cc.set_filter(
        GROUND,
        Direction::Out,
        filter(&["block-msg=GLOBAL_POSITION_INT"]),
    )
    .unwrap();
    let t = Moment::ZERO;
    let fate = cc.handle_frame(t, arrival(FC_LINK, &heartbeat(FC, 0)));
    assert!(fate.input && fate.route.contains(GROUND));
    let fate = cc.handle_frame(t, arrival(FC_LINK, &position(FC, 1)));
    assert_eq!((fate.dropped, fate.route), (None, Links::NONE));
    let command = CommandLong {
        target_system: 1,
        target_component: 1,
        ..Default::default()
    };
    let fate = cc.handle_frame(t, arrival(GROUND, &bytes(GCS, 0, &command)));
    assert_eq!(fate.dropped, Some(DropReason::Filtered));
    let fate = cc.handle_frame(t, arrival(GROUND, &heartbeat(GCS, 1)));
    assert_eq!(fate.route, Links::only(FC_LINK));
}

#[test]
fn the_companion_drops_a_copy_from_a_redundant_ground_link_and_still_hears_the_fc() {
    const SECOND_GROUND: u8 = 2;
    let mut cc = companion();
    cc.add_link(SECOND_GROUND, LinkSpec::new(Role::Ground, Answers::Target))
        .unwrap();
    cc.set_dedup(Some(Duration::from_millis(100)));
    let at = Moment::from_millis;
    let command = bytes(
        GCS,
        0,
        &CommandLong {
            target_system: 1,
            target_component: 1,
            ..Default::default()
        },
    );
    let fate = cc.handle_frame(at(900), arrival(FC_LINK, &heartbeat(FC, 9)));
    assert!(fate.input, "{fate:?}");
    let fate = cc.handle_frame(at(1000), arrival(GROUND, &command));
    assert_eq!((fate.dropped, fate.route), (None, Links::only(FC_LINK)));
    let fate = cc.handle_frame(at(1030), arrival(SECOND_GROUND, &command));
    assert_eq!(fate.dropped, Some(DropReason::Duplicate), "{fate:?}");
    // The FC's frames are the engine's inputs, copies or not.
    let hb = heartbeat(FC, 0);
    for t in [1040, 1050] {
        let fate = cc.handle_frame(at(t), arrival(FC_LINK, &hb));
        assert!(fate.input, "{fate:?}");
    }
}
