//! How the machines' actions look on the wire: the one place that builds the
//! protocol's MAVLink messages, for the simulator and the real programs.

use crate::fc::Authority;
use crate::{mode, Peer, Status};
use fbwag_dialect::dialects::common::{MavSeverity, Statustext};
use fbwag_dialect::dialects::minimal::{Heartbeat, MavAutopilot, MavModeFlag, MavState, MavType};
use fbwag_dialect::mavframe::field::chars;
use fbwag_dialect::FbwagNotice;

/// A FBWAG_NOTICE of either side. Both put the FC's ids in `system_id` and
/// `component_id` (the paper's Figs. 4 and 8); the frame header says who
/// sent it.
pub fn notice(fc: Peer, status: Status, timestamp: u32) -> FbwagNotice {
    FbwagNotice {
        system_id: fc.sysid,
        component_id: fc.compid,
        failsafe_status: status,
        text: chars("FBWAG"),
        timestamp,
    }
}

/// The FC's confirmation STATUSTEXT; its `id` carries the event's low 16
/// bits so the companion can tell which event it confirms.
pub fn status_text(text: &str, event: u32) -> Statustext {
    Statustext {
        severity: MavSeverity::INFO,
        text: chars(text),
        id: event as u16,
        chunk_seq: 0,
    }
}

/// The FC's takeover confirmation: the paper's text
/// ([`TEXT_CC_TOOK_OVER`](crate::TEXT_CC_TOOK_OVER)) followed by the ids of
/// the companion it accepted ("… taken over! 1/191"), so a companion that
/// sees another accepted stops believing it flies at once; its `id`
/// carries the event's low 16 bits.
pub fn takeover_text(companion: Peer, event: u32) -> Statustext {
    let mut text = [0u8; 50];
    let mut at = 0;
    let mut put = |b: u8| {
        text[at] = b;
        at += 1;
    };
    crate::TEXT_CC_TOOK_OVER.bytes().for_each(&mut put);
    put(b' ');
    for (i, id) in [companion.sysid, companion.compid].into_iter().enumerate() {
        if i == 1 {
            put(b'/');
        }
        // Decimal, without leading zeros.
        let digits = [id / 100, id / 10 % 10, id % 10];
        let first = digits.iter().position(|&d| d != 0).unwrap_or(2);
        digits[first..].iter().for_each(|d| put(b'0' + d));
    }
    // At most 29 + 8 of 50 bytes: the NULs after end the text.
    Statustext {
        severity: MavSeverity::INFO,
        text,
        id: event as u16,
        chunk_seq: 0,
    }
}

/// Whom a STATUSTEXT's `text` says the FC accepted, when it is the
/// takeover confirmation: `Some(None)` for the paper's text alone (a
/// firmware that does not name the companion), `Some(Some(ids))` when it
/// names one; `None` for any other text.
pub fn takeover_by(text: &[u8]) -> Option<Option<Peer>> {
    let rest = text.strip_prefix(crate::TEXT_CC_TOOK_OVER.as_bytes())?;
    if rest.is_empty() {
        return Some(None);
    }
    let ids = rest.strip_prefix(b" ")?;
    let slash = ids.iter().position(|&b| b == b'/')?;
    let (sysid, compid) = (&ids[..slash], &ids[slash + 1..]);
    Some(Some(Peer::new(number(sysid)?, number(compid)?)))
}

/// A decimal id 0–255, as [`takeover_text`] writes it (no leading zeros).
fn number(digits: &[u8]) -> Option<u8> {
    let leading_zero = digits.len() > 1 && digits[0] == b'0';
    if digits.is_empty() || digits.len() > 3 || leading_zero {
        return None;
    }
    let n = digits.iter().try_fold(0u16, |n, &b| {
        b.is_ascii_digit().then(|| n * 10 + u16::from(b - b'0'))
    })?;
    u8::try_from(n).ok()
}

/// The HEARTBEAT `custom_mode` the FC reports for each authority.
pub fn custom_mode(a: Authority) -> u32 {
    match a {
        Authority::Pilot => mode::FBWA,
        Authority::Handshake => mode::CIRCLE,
        Authority::Companion => mode::FBWAG,
        Authority::Rtl => mode::RTL,
    }
}

/// The FC's HEARTBEAT: an armed ArduPlane flying the mode of `authority`.
pub fn fc_heartbeat(authority: Authority) -> Heartbeat {
    Heartbeat {
        r#type: MavType::FIXED_WING,
        autopilot: MavAutopilot::ARDUPILOTMEGA,
        base_mode: MavModeFlag::CUSTOM_MODE_ENABLED
            | MavModeFlag::STABILIZE_ENABLED
            | MavModeFlag::SAFETY_ARMED,
        custom_mode: custom_mode(authority),
        system_status: MavState::ACTIVE,
        mavlink_version: 3,
    }
}

/// The companion's HEARTBEAT: an onboard controller, not an autopilot.
pub fn cc_heartbeat() -> Heartbeat {
    Heartbeat {
        r#type: MavType::ONBOARD_CONTROLLER,
        autopilot: MavAutopilot::INVALID,
        system_status: MavState::ACTIVE,
        mavlink_version: 3,
        ..Heartbeat::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_takeover_text_names_the_companion_and_reads_back() {
        for ids in [Peer::new(1, 191), Peer::new(255, 0), Peer::new(7, 10)] {
            let t = takeover_text(ids, 70_000);
            let end = t.text.iter().position(|&b| b == 0).unwrap_or(50);
            assert_eq!(takeover_by(&t.text[..end]), Some(Some(ids)));
            assert_eq!(t.id, 70_000u32 as u16);
        }
        let named = takeover_text(Peer::new(1, 191), 0).text;
        assert!(named.starts_with(b"FBWAG-ACK: CC has taken over! 1/191\0"));
        // The paper's firmware names nobody; other texts are no confirmation.
        assert_eq!(takeover_by(crate::TEXT_CC_TOOK_OVER.as_bytes()), Some(None));
        for other in [
            &b"FBWAG-ACK: CC has taken over!1/191"[..],
            b"FBWAG-ACK: CC has taken over! 1/256",
            b"FBWAG-ACK: CC has taken over! 01/191",
            b"FBWAG-ACK: CC has taken over! 1/",
            b"FBWAG-ACK: CC has taken over! x",
            b"FBWAG-ACK: RC has taken over!",
        ] {
            assert_eq!(
                takeover_by(other),
                None,
                "{}",
                String::from_utf8_lossy(other)
            );
        }
    }
}
