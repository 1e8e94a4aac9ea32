//! What decides who flies: the settings of the delegation and of the RC
//! failsafe, the signing key, the control streams. These are set on the
//! ground, before flight; a frame in flight never changes them on the
//! strength of a signature it did not carry itself.
//!
//! Two rules use this one list:
//!
//! - the companion's node never signs on such a frame for a link trusted
//!   like the key (`fbwag cc --trusted-out`, [`LinkSpec::trusted`]): a
//!   local tool that cannot sign reaches the FC with telemetry requests and
//!   rates, parameter reads and ordinary writes, missions and the commands
//!   the FC arbitrates, never with these (dropped, counted as
//!   [`DropReason::Protected`]);
//! - a flight controller refuses to change these parameters while armed
//!   (`fbwag fc-sim`, as a careful autopilot does).
//!
//! [`LinkSpec::trusted`]: crate::node::LinkSpec::trusted
//! [`DropReason::Protected`]: crate::node::DropReason::Protected

use crate::control::Control;
use fbwag_dialect::dialects::common::MavCmd;
use fbwag_dialect::MessageView;

/// What a protected frame would change.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Protected {
    /// A parameter of the delegation, the RC failsafe, the ids that say who
    /// is trusted, or the serial ports the companion speaks on (PARAM_SET,
    /// PARAM_EXT_SET; see [`is_protected_parameter`]).
    Parameter,
    /// A parameter named only by its index, or every parameter at once:
    /// MAV_CMD_DO_SET_PARAMETER, MAV_CMD_PREFLIGHT_STORAGE other than read
    /// or write (a reset to defaults).
    ParameterCommand,
    /// The signing key (SETUP_SIGNING).
    Signing,
    /// Files on the FC: MAVLink FTP's writes, removals and renames
    /// (parameter files, scripts that can fly the aircraft).
    FileWrite,
    /// The FC's serial devices and shell (SERIAL_CONTROL).
    SerialControl,
    /// Control of the aircraft: RC_CHANNELS_OVERRIDE, SET_ATTITUDE_TARGET,
    /// MANUAL_CONTROL (ArduPilot applies overrides from its ground
    /// station's system id in any mode).
    Control,
}

impl Protected {
    /// Its name in logs and docs.
    pub const fn name(self) -> &'static str {
        match self {
            Protected::Parameter => "protected parameter",
            Protected::ParameterCommand => "parameter command",
            Protected::Signing => "signing set-up",
            Protected::FileWrite => "file write",
            Protected::SerialControl => "serial control",
            Protected::Control => "control",
        }
    }
}

/// Parameter names (whole, or a prefix ending in `_`) that decide who
/// flies or whether and when the failsafe starts: ArduPlane's and this
/// protocol's. Compared without regard to case.
pub const PROTECTED_PARAMETERS: [&str; 9] = [
    // This protocol's settings: the companion's ids, retries, timeouts.
    "FBWAG_",
    // The short and long failsafe: action and timeout (FS_SHORT_ACTN,
    // FS_SHORT_TIMEOUT, FS_LONG_ACTN, FS_LONG_TIMEOUT, FS_GCS_ENABL…).
    "FS_",
    // Receiver loss detection by throttle.
    "THR_FAILSAFE",
    "THR_FS_",
    // RC input: override timeout, options (one ignores the failsafe),
    // protocols, the receiver's own failsafe timeout.
    "RC_",
    // Who the FC is, and which ground station may override.
    "SYSID_",
    "MAV_GCS_SYSID",
    // The ports and baud rates the companion's link runs on.
    "SERIAL",
    // Scripting, which can fly the aircraft.
    "SCR_",
];

/// Whether the PARAM_* `id` (NUL-terminated unless 16 long) names a
/// parameter of [`PROTECTED_PARAMETERS`].
pub fn is_protected_parameter(id: &[u8]) -> bool {
    let end = id.iter().position(|&b| b == 0).unwrap_or(id.len());
    let name = &id[..end];
    PROTECTED_PARAMETERS.iter().any(|p| {
        let p = p.as_bytes();
        let whole_or_prefix = if p.ends_with(b"_") || p == b"SERIAL" {
            name.len() >= p.len()
        } else {
            name.len() == p.len()
        };
        whole_or_prefix && name[..p.len()].eq_ignore_ascii_case(p)
    })
}

/// MAVLink FTP opcodes that change files (CreateFile, WriteFile,
/// RemoveFile, CreateDirectory, RemoveDirectory, OpenFileWO, TruncateFile,
/// Rename): the fourth byte of FILE_TRANSFER_PROTOCOL's payload.
const FTP_WRITES: core::ops::RangeInclusive<u8> = 6..=13;

/// What `view` would change of who flies, if anything.
pub fn protected(view: &MessageView<'_>) -> Option<Protected> {
    let parameter = |id: &[u8]| is_protected_parameter(id).then_some(Protected::Parameter);
    match view {
        MessageView::ParamSet(v) => parameter(v.param_id().as_bytes()),
        MessageView::ParamExtSet(v) => parameter(v.param_id().as_bytes()),
        MessageView::CommandLong(v) => parameter_command(v.command(), v.param1()),
        MessageView::CommandInt(v) => parameter_command(v.command(), v.param1()),
        MessageView::SetupSigning(_) => Some(Protected::Signing),
        MessageView::FileTransferProtocol(v) => v
            .payload()
            .get(3)
            .filter(|op| FTP_WRITES.contains(op))
            .map(|_| Protected::FileWrite),
        MessageView::SerialControl(_) => Some(Protected::SerialControl),
        _ => Control::from_view(view).map(|_| Protected::Control),
    }
}

/// Commands that set parameters past their names: by index
/// (DO_SET_PARAMETER), or all of them back to defaults (PREFLIGHT_STORAGE
/// with anything but 0, read, or 1, write, in `param1`).
fn parameter_command(command: MavCmd, param1: f32) -> Option<Protected> {
    let sets = match command {
        MavCmd::DO_SET_PARAMETER => true,
        MavCmd::PREFLIGHT_STORAGE => param1 != 0.0 && param1 != 1.0,
        _ => false,
    };
    sets.then_some(Protected::ParameterCommand)
}

#[cfg(test)]
mod tests {
    use super::*;
    use fbwag_dialect::dialects::common::{
        CommandLong, FileTransferProtocol, ParamRequestRead, ParamSet, RcChannelsOverride,
        SetupSigning,
    };
    use fbwag_dialect::mavframe::field::chars;
    use fbwag_dialect::mavframe::MessageData;

    fn judge<M: MessageData>(m: &M) -> Option<Protected> {
        let mut payload = [0u8; 255];
        let n = m.emit(&mut payload).unwrap();
        protected(&MessageView::new(M::META.id, &payload[..n]).unwrap())
    }

    fn set(name: &str) -> ParamSet {
        ParamSet {
            param_id: chars(name),
            ..Default::default()
        }
    }

    #[test]
    fn the_settings_of_who_flies_are_protected_and_others_are_not() {
        for name in [
            "FBWAG_CC_COMPID",
            "FBWAG_CC_SYSID",
            "FS_SHORT_ACTN",
            "FS_SHORT_TIMEOUT",
            "fs_long_timeout",
            "THR_FAILSAFE",
            "THR_FS_VALUE",
            "RC_OVERRIDE_TIME",
            "RC_OPTIONS",
            "SYSID_THISMAV",
            "SYSID_MYGCS",
            "MAV_GCS_SYSID",
            "SERIAL2_PROTOCOL",
            "SCR_ENABLE",
        ] {
            assert_eq!(judge(&set(name)), Some(Protected::Parameter), "{name}");
        }
        for name in [
            "AIRSPEED_CRUISE",
            "THR_MAX",
            "RC1_MIN",
            "FS",
            "SR0_POSITION",
        ] {
            assert_eq!(judge(&set(name)), None, "{name}");
        }
        // A 16-character name has no terminator; what follows a NUL is not
        // part of the name.
        assert!(is_protected_parameter(b"FS_SHORT_TIMEOUT"));
        assert!(!is_protected_parameter(b"TRIM\0FBWAG_CC_ID"));
        let read = ParamRequestRead {
            param_id: chars("FBWAG_CC_COMPID"),
            ..Default::default()
        };
        assert_eq!(judge(&read), None, "reads are free");
    }

    #[test]
    fn signing_files_serial_control_and_parameter_commands_are_protected() {
        assert_eq!(judge(&SetupSigning::default()), Some(Protected::Signing));
        assert_eq!(
            judge(&RcChannelsOverride::default()),
            Some(Protected::Control)
        );
        let command = |command, param1| CommandLong {
            command,
            param1,
            ..Default::default()
        };
        for (c, p1, want) in [
            (MavCmd::DO_SET_PARAMETER, 0.0, true),
            (MavCmd::PREFLIGHT_STORAGE, 2.0, true),
            (MavCmd::PREFLIGHT_STORAGE, 1.0, false),
            (MavCmd::SET_MESSAGE_INTERVAL, 33.0, false),
            (MavCmd::DO_SET_MODE, 1.0, false),
        ] {
            let got = judge(&command(c, p1));
            assert_eq!(got.is_some(), want, "{c:?} {p1}");
        }
        let ftp = |op: u8| {
            let mut payload = [0u8; 251];
            payload[3] = op;
            judge(&FileTransferProtocol {
                payload,
                ..Default::default()
            })
        };
        // Reads (OpenFileRO, ReadFile, BurstReadFile) pass; writes do not.
        for op in [3, 4, 5, 15] {
            assert_eq!(ftp(op), None, "opcode {op}");
        }
        for op in 6..=13 {
            assert_eq!(ftp(op), Some(Protected::FileWrite), "opcode {op}");
        }
    }
}
