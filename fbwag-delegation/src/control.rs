//! The control a companion sends and the flight controller applies in
//! companion control: the three MAVLink messages the paper names or implies,
//! kept whole (every field, extensions included), and the built-in
//! controllers of the demo and the simulator.

use crate::{Moment, Peer};
use fbwag_dialect::dialects::common::{ManualControl, RcChannelsOverride, SetAttitudeTarget};
use fbwag_dialect::{Message, MessageView};

/// One control message of the companion.
///
/// ```
/// use fbwag_delegation::control::Control;
/// use fbwag_delegation::Peer;
///
/// let fc = Peer::new(1, 1);
/// // An autonomy wrote its own ids; the companion re-addresses to its FC.
/// let c = Control::rc(Peer::new(9, 9), [1600, 1500, 1700, 1500, 0, 0, 0, 0]).addressed_to(fc);
/// assert!(c.addresses(fc));
/// assert_eq!(c.rc_channels().unwrap()[0], 1600);
/// assert_eq!(c.name(), "RC_CHANNELS_OVERRIDE");
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Control {
    /// RC_CHANNELS_OVERRIDE: channel values in µs; per MAVLink, 0 releases a
    /// channel to the receiver and `u16::MAX` leaves it as it is.
    RcOverride(RcChannelsOverride),
    /// SET_ATTITUDE_TARGET (ArduPlane flies it in GUIDED).
    Attitude(SetAttitudeTarget),
    /// MANUAL_CONTROL: joystick axes in −1000…1000.
    Manual(ManualControl),
}

impl Control {
    /// The three control messages: (id, name).
    pub const MESSAGES: [(u32, &'static str); 3] = [
        (RcChannelsOverride::ID, RcChannelsOverride::NAME),
        (SetAttitudeTarget::ID, SetAttitudeTarget::NAME),
        (ManualControl::ID, ManualControl::NAME),
    ];

    /// The control carried by `message`, if it is one of the three control
    /// messages.
    pub fn from_message(message: &Message) -> Option<Control> {
        Some(match message {
            Message::RcChannelsOverride(m) => Control::RcOverride(*m),
            Message::SetAttitudeTarget(m) => Control::Attitude(*m),
            Message::ManualControl(m) => Control::Manual(*m),
            _ => return None,
        })
    }

    /// The control in a received message's view (copied out only for the
    /// three control messages).
    pub fn from_view(view: &MessageView<'_>) -> Option<Control> {
        Some(match view {
            MessageView::RcChannelsOverride(v) => Control::RcOverride(v.to_message()),
            MessageView::SetAttitudeTarget(v) => Control::Attitude(v.to_message()),
            MessageView::ManualControl(v) => Control::Manual(v.to_message()),
            _ => return None,
        })
    }

    /// Whom the message addresses: (system, component); MANUAL_CONTROL
    /// names only a system (component 0: any).
    pub fn target(&self) -> (u8, u8) {
        match self {
            Control::RcOverride(m) => (m.target_system, m.target_component),
            Control::Attitude(m) => (m.target_system, m.target_component),
            Control::Manual(m) => (m.target, 0),
        }
    }

    /// True when the message addresses `fc`: its system, and its component
    /// or every component (0).
    pub fn addresses(&self, fc: Peer) -> bool {
        let (system, component) = self.target();
        system == fc.sysid && (component == fc.compid || component == 0)
    }

    /// The same control addressed to `fc` (what a companion forwards for
    /// its autonomy, whatever ids the autonomy wrote).
    pub fn addressed_to(mut self, fc: Peer) -> Control {
        match &mut self {
            Control::RcOverride(m) => {
                m.target_system = fc.sysid;
                m.target_component = fc.compid;
            }
            Control::Attitude(m) => {
                m.target_system = fc.sysid;
                m.target_component = fc.compid;
            }
            Control::Manual(m) => m.target = fc.sysid,
        }
        self
    }

    /// The message to send.
    pub fn to_message(&self) -> Message {
        match *self {
            Control::RcOverride(m) => Message::RcChannelsOverride(m),
            Control::Attitude(m) => Message::SetAttitudeTarget(m),
            Control::Manual(m) => Message::ManualControl(m),
        }
    }

    /// Its MAVLink name.
    pub fn name(&self) -> &'static str {
        match self {
            Control::RcOverride(_) => "RC_CHANNELS_OVERRIDE",
            Control::Attitude(_) => "SET_ATTITUDE_TARGET",
            Control::Manual(_) => "MANUAL_CONTROL",
        }
    }

    /// Channels 1–8 of an RC override (what most airframes fly on).
    pub fn rc_channels(&self) -> Option<[u16; 8]> {
        match self {
            Control::RcOverride(m) => Some([
                m.chan1_raw,
                m.chan2_raw,
                m.chan3_raw,
                m.chan4_raw,
                m.chan5_raw,
                m.chan6_raw,
                m.chan7_raw,
                m.chan8_raw,
            ]),
            _ => None,
        }
    }

    /// An RC override of channels 1–8 (9–18 left as they are: `u16::MAX`
    /// would say "ignore", 0 "release"; MAVLink 2 truncation sends 0 for
    /// them, which releases them to the receiver, as ArduPilot expects).
    pub fn rc(fc: Peer, channels: [u16; 8]) -> Control {
        Control::RcOverride(RcChannelsOverride {
            target_system: fc.sysid,
            target_component: fc.compid,
            chan1_raw: channels[0],
            chan2_raw: channels[1],
            chan3_raw: channels[2],
            chan4_raw: channels[3],
            chan5_raw: channels[4],
            chan6_raw: channels[5],
            chan7_raw: channels[6],
            chan8_raw: channels[7],
            ..Default::default()
        })
    }
}

/// A companion's own flight control: asked for one control message each
/// control period while the companion controls (see
/// [`crate::engine::CcOutput::ControlDue`]).
pub trait Controller {
    /// The control to send now, addressed to `fc`.
    fn control(&mut self, now: Moment, fc: Peer) -> Control;
    /// A name for logs.
    fn name(&self) -> &'static str;
}

/// Wings level, cruise throttle, rudder centred: the simulator's and the
/// demo's default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WingsLevel {
    /// Throttle channel (3) in µs.
    pub throttle: u16,
}

impl Controller for WingsLevel {
    fn control(&mut self, _now: Moment, fc: Peer) -> Control {
        Control::rc(fc, [1500, 1500, self.throttle, 1500, 0, 0, 0, 0])
    }
    fn name(&self) -> &'static str {
        "wings-level"
    }
}

/// A gentle constant-bank circle (for ground tests of the override path).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Circle {
    /// Throttle channel (3) in µs.
    pub throttle: u16,
}

impl Controller for Circle {
    fn control(&mut self, _now: Moment, fc: Peer) -> Control {
        Control::rc(fc, [1650, 1500, self.throttle, 1500, 0, 0, 0, 0])
    }
    fn name(&self) -> &'static str {
        "circle"
    }
}
