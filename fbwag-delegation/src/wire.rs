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
