//! The companion-computer listener of the paper (Fig. 8), on fbwag-dialect:
//! wait for the flight controller's heartbeat, then for FBWAG_NOTICE with
//! status 1 (RC lost), and answer with status 2 (CC takeover confirmed).
//!
//! ```text
//! cargo run -p fbwag-dialect --example cc_listener -- serial:/dev/serial0:460800
//! cargo run -p fbwag-dialect --example cc_listener -- udpin:0.0.0.0:14550
//! ```
//!
//! As in the paper, the acknowledgement carries the flight controller's ids
//! (`target_system`/`target_component` in pymavlink's listener); it also
//! echoes the notice's timestamp, which identifies the event. Sending the
//! flight-control commands is out of scope here, as it is in the paper;
//! `fbwag cc` is the full daemon. `--exit-after N` stops after N takeovers.

use fbwag_dialect::dialects::minimal::Heartbeat;
use fbwag_dialect::mavframe::conn::{Connection, Endpoint};
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::{Dialect, FbwagFailsafeStatus, FbwagNotice, Message};
use std::time::Duration;

/// Our own ids: an onboard computer (MAV_COMP_ID_ONBOARD_COMPUTER = 191).
const SYSID: u8 = 1;
const COMPID: u8 = 191;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let endpoint: Endpoint = args
        .next()
        .unwrap_or_else(|| "serial:/dev/serial0:460800".into())
        .parse()?;
    let exit_after: Option<u32> = match (args.next().as_deref(), args.next()) {
        (Some("--exit-after"), Some(n)) => Some(n.parse()?),
        (None, _) => None,
        _ => return Err("usage: cc_listener [CONNECTION] [--exit-after N]".into()),
    };
    run(Connection::<Dialect>::open(&endpoint)?, exit_after)
}

/// The listener loop; returns after `exit_after` takeovers, if given.
fn run(
    mut link: Connection<Dialect>,
    exit_after: Option<u32>,
) -> Result<(), Box<dyn std::error::Error>> {
    println!("Waiting for heartbeat...");
    let (target_system, target_component) = loop {
        if let Some(r) = link.recv(Some(Duration::from_secs(1)))? {
            if r.msg_id() == Heartbeat::ID {
                break (r.header().sysid, r.header().compid);
            }
        }
    };
    println!("Connected to MAVLink! (system {target_system}, component {target_component})");

    let mut takeovers = 0;
    loop {
        let Some(received) = link.recv(Some(Duration::from_secs(1)))? else {
            continue;
        };
        let Some(Message::FbwagNotice(notice)) = received.message() else {
            continue;
        };
        if notice.failsafe_status == FbwagFailsafeStatus::RC_LOST {
            println!("RC FailSafe Triggered! Sending CC takeover confirmation...");
            let ack = FbwagNotice {
                system_id: target_system,
                component_id: target_component,
                failsafe_status: FbwagFailsafeStatus::CC_TAKEOVER_CONFIRMED,
                text: chars("FBWAG"),
                timestamp: notice.timestamp,
            };
            link.send_auto(SYSID, COMPID, &ack)?;
            // Start sending control commands... (see `fbwag cc`)
            takeovers += 1;
            if exit_after.is_some_and(|n| takeovers >= n) {
                return Ok(());
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    /// A fake flight controller on 127.0.0.1 drives the listener through one
    /// RC loss; the acknowledgement must be status 2 echoing the timestamp.
    #[test]
    fn acknowledges_rc_loss_with_status_2() {
        // As on a real vehicle link, the FC sends to the companion: the
        // listener binds (udpin), the fake FC sends to it (udpout).
        let link = Connection::<Dialect>::open(&"udpin:127.0.0.1:0".parse().unwrap()).unwrap();
        let port = link.transport().local_addr().unwrap().port();
        let listener = std::thread::spawn(move || run(link, Some(1)).map_err(|e| e.to_string()));
        let mut fc =
            Connection::<Dialect>::open(&format!("udpout:127.0.0.1:{port}").parse().unwrap())
                .unwrap();

        let deadline = Instant::now() + Duration::from_secs(10);
        let mut ack = None;
        while Instant::now() < deadline && ack.is_none() {
            fc.send_auto(1, 1, &Heartbeat::default()).unwrap();
            let notice = FbwagNotice {
                system_id: 1,
                component_id: 1,
                failsafe_status: FbwagFailsafeStatus::RC_LOST,
                text: chars("FBWAG"),
                timestamp: 4242,
            };
            fc.send_auto(1, 1, &notice).unwrap();
            while let Some(r) = fc.recv(Some(Duration::from_millis(100))).unwrap() {
                if let Some(Message::FbwagNotice(n)) = r.message() {
                    ack = Some((r.header(), n));
                    break;
                }
            }
        }
        let (header, notice) = ack.expect("no acknowledgement within 10 s");
        assert_eq!(listener.join().unwrap(), Ok(()));
        assert_eq!((header.sysid, header.compid), (SYSID, COMPID));
        assert_eq!(
            notice.failsafe_status,
            FbwagFailsafeStatus::CC_TAKEOVER_CONFIRMED
        );
        assert_eq!(
            notice.timestamp, 4242,
            "the ack echoes the event's timestamp"
        );
        assert_eq!(
            (notice.system_id, notice.component_id),
            (1, 1),
            "the FC's ids, as in Fig. 8"
        );
    }
}
