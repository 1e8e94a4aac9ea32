//! One message of our own dialect and one of `common.xml`: each encoded
//! into a MAVLink 2 frame, parsed back by mavframe's streaming parser and
//! compared with what was sent, through the zero-copy view and the owned
//! message.

/// The generated code: one module per XML file (`my_dialect`, `common`,
/// `standard`, `minimal`).
pub mod dialects {
    include!(concat!(env!("OUT_DIR"), "/mod.rs"));
}

use dialects::common::{CommandLong, MavCmd};
use dialects::my_dialect::{Dialect, Message, MessageView, PayloadBayState, PayloadBayStatus};
use mavframe::field::chars;
use mavframe::frame::MAX_FRAME_LEN;
use mavframe::{encode, Header, Parser, Version};

fn main() {
    let bay = PayloadBayStatus {
        time_usec: 1_234_567,
        load: 2.5,
        bay: 1,
        state: PayloadBayState::OPEN,
        label: chars("rear"),
        cycles: 812,
    };
    let command = CommandLong {
        target_system: 1,
        target_component: 1,
        command: MavCmd::DO_SET_MODE,
        confirmation: 0,
        param1: 1.0,
        param2: 10.0,
        ..Default::default()
    };

    // Both frames in one stream, as a link would carry them.
    let mut stream = Vec::new();
    let mut buf = [0u8; MAX_FRAME_LEN];
    for (seq, message) in [Message::from(bay), Message::from(command)]
        .iter()
        .enumerate()
    {
        let header = Header {
            seq: seq as u8,
            sysid: 1,
            compid: 191,
        };
        let n = encode(Version::V2, header, message, None, &mut buf).expect("a frame fits");
        stream.extend_from_slice(&buf[..n]);
    }

    let mut parser = Parser::<Dialect>::new();
    let mut input = stream.as_slice();

    let rx = parser.next(&mut input).expect("the first frame");
    assert_eq!(rx.msg_id(), PayloadBayStatus::ID);
    assert_eq!(rx.meta().map(|m| m.name), Some("PAYLOAD_BAY_STATUS"));
    let Some(Message::PayloadBayStatus(back)) = rx.message() else {
        panic!("not PAYLOAD_BAY_STATUS: {rx:?}");
    };
    assert_eq!(back, bay);
    // The view reads the same fields in place, without copying the payload.
    let Some(MessageView::PayloadBayStatus(view)) = rx.view() else {
        panic!("no view of PAYLOAD_BAY_STATUS");
    };
    assert_eq!(view.state(), PayloadBayState::OPEN);
    assert_eq!(view.label().as_bytes(), b"rear");
    assert_eq!((view.load(), view.cycles()), (2.5, 812));
    println!("received {back:?}");

    let rx = parser.next(&mut input).expect("the second frame");
    assert_eq!(rx.message(), Some(Message::from(command)));
    println!("received {:?}", rx.message());

    assert!(parser.next(&mut input).is_none());
    assert_eq!(parser.stats().bytes_dropped, 0);
    println!("round trip: PAYLOAD_BAY_STATUS (id 61042) and COMMAND_LONG");
}
