//! `fbwag fc-sim`: the flight-controller simulator's arguments.

use super::help;
use crate::args;
use crate::error::{CliError, Outcome};
use crate::fc_sim::plane::Home;
use crate::fc_sim::{run_fc, signing, FcOptions, PilotMode};
use fbwag_delegation::Peer;
use std::net::SocketAddr;
use std::path::PathBuf;

/// A flight-controller simulator speaking like ArduPlane.
///
/// Loses and regains its receiver on schedule, runs the FC state machine
/// and reports every mode change (companion control, RTL, the pilot)
/// with a timestamp. A kinematic fixed-wing model flies in the mode the
/// state machine chose (the pilot's sticks, CIRCLE, the companion's
/// applied control, RTL back to --home) and is reported as ArduPlane
/// does: HEARTBEAT (fixed wing, ArduPilot, ArduPlane's mode numbers;
/// companion control is FBWAG, 30), ATTITUDE, GLOBAL_POSITION_INT,
/// GPS_RAW_INT, VFR_HUD, SYS_STATUS (true health bits: the RC receiver
/// unhealthy while lost), RC_CHANNELS, EXTENDED_SYS_STATE, HOME_POSITION.
///
/// Control (RC_CHANNELS_OVERRIDE, SET_ATTITUDE_TARGET, MANUAL_CONTROL)
/// is applied only from the configured companion (--cc-sysid/--cc-compid),
/// addressed to this FC, in companion control, and with
/// --require-signed only when its signature verified.
///
/// Its own log goes over MAVLink to whoever asks, as ArduPilot's MAVLink
/// logging backend sends it (`fbwag router --flight-log`, mavlink-router's
/// Log): a REMOTE_LOG_BLOCK_STATUS with MAV_REMOTE_LOG_DATA_BLOCK_START
/// starts a DataFlash log (FMT, MSG, MODE at each change, ATT at 25 Hz,
/// POS at 5 Hz) in REMOTE_LOG_DATA_BLOCKs from component 110, each sent
/// again until acknowledged; STOP, or 10 s without an answer, ends it.
#[derive(clap::Args)]
#[command(after_long_help = help::FC_EVENTS)]
pub struct FcSimArgs {
    /// Connection string (see `fbwag cc --help`).
    #[arg(long, value_name = "CONN")]
    pub link: String,
    /// udpin and tcpin only: send to this address (IP:PORT; for tcpin,
    /// the client connected from it) and no other.
    #[arg(long, value_name = "IP:PORT")]
    pub peer: Option<SocketAddr>,
    /// As for `fbwag cc` (see there), and the key a SETUP_SIGNING set is
    /// kept in PATH.key and taken again at start when --sign-key is not
    /// given (then only signed frames count, as ArduPilot with a key).
    #[arg(long, value_name = "PATH")]
    pub signing_state: Option<PathBuf>,
    #[arg(long, value_name = "PATH", help = help::EVENTS)]
    pub events: Option<PathBuf>,
    #[arg(long, value_enum, default_value = "info", help = help::LOG_LEVEL)]
    pub log_level: crate::live::Level,
    #[arg(long, value_name = "SECONDS|off", default_value = "10", allow_hyphen_values = true, value_parser = args::report, help = help::REPORT)]
    pub report: args::ReportEvery,
    /// Lose the receiver at this time (seconds after start, 0–1,000,000).
    /// Repeatable, with --rc-back-at, for several failures: the k-th
    /// --rc-back-at ends the k-th failure (the last may be left open).
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true, value_parser = args::seconds)]
    pub rc_loss_at: Vec<f64>,
    /// Get the receiver back at this time (seconds, 0–1,000,000).
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true, value_parser = args::seconds)]
    pub rc_back_at: Vec<f64>,
    /// The companion allowed to take over: system id (1–255).
    #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
    pub cc_sysid: u8,
    /// The companion allowed to take over: component id (1–255).
    #[arg(long, default_value_t = 191, allow_hyphen_values = true, value_parser = args::mavlink_id)]
    pub cc_compid: u8,
    /// Our system id (1–255).
    #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
    pub sysid: u8,
    /// Our component id (1–255).
    #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
    pub compid: u8,
    /// Run this long (seconds, 0–1,000,000).
    #[arg(long, default_value_t = 20.0, allow_hyphen_values = true, value_parser = args::seconds)]
    pub duration: f64,
    /// Sign and verify with this key: 64 hex digits, @FILE holding them
    /// (readable by its owner only), or passphrase:TEXT (what MAVProxy's
    /// `signing setup TEXT` sets). Without it, SETUP_SIGNING sets one
    /// while disarmed.
    #[arg(long, value_name = "HEX64", value_parser = args::sign_key)]
    pub sign_key: Option<String>,
    /// Accept the companion's takeover only from signed frames; serve
    /// ground-station requests only from signed frames too.
    #[arg(long, requires = "sign_key")]
    pub require_signed: bool,
    /// Home (the model starts over it at 100 m, heading north, and RTL
    /// returns to it): latitude and longitude in degrees, ground
    /// altitude in metres above sea level. Default: ArduPilot SITL's.
    #[arg(
        long,
        value_name = "LAT,LON,ALT",
        default_value = "-35.363261,149.165230,584",
        allow_hyphen_values = true
    )]
    pub home: Home,
    /// The mode the pilot flies while the receiver works, as reported
    /// (the model flies the pilot's centred sticks in any of them).
    #[arg(long, value_enum, default_value = "fbwa")]
    pub pilot_mode: PilotMode,
    /// Arm at this time (seconds after start, 0–1,000,000; 0: armed from
    /// the start). Until then the FC is on the ground: its RC failsafe is
    /// not armed (a lost receiver delegates nothing), its heartbeat says
    /// disarmed, and the parameters that decide who flies (FS_*,
    /// FBWAG_*, SYSID_*) may be written; armed, they are refused.
    #[arg(long, value_name = "SECONDS", default_value_t = 0.0, allow_hyphen_values = true, value_parser = args::seconds)]
    pub arm_at: f64,
}

impl TryFrom<FcSimArgs> for FcOptions {
    type Error = CliError;

    fn try_from(a: FcSimArgs) -> Result<Self, CliError> {
        let key_file = a.signing_state.as_deref().map(signing::key_file);
        // The key SETUP_SIGNING set before, when none is given.
        let kept = match (&a.sign_key, &key_file) {
            (None, Some(path)) => signing::load(path).map_err(CliError::daemon("fc-sim"))?,
            _ => None,
        };
        let hex = kept.map(|k| k.iter().map(|b| format!("{b:02x}")).collect::<String>());
        let sign_key = a.sign_key.or(hex);
        // A state file keeps a key's timestamps: none without a key.
        let state = a.signing_state.filter(|_| sign_key.is_some());
        let link = super::link_options(&a.link, sign_key.as_deref(), a.peer, state)?;
        Ok(FcOptions {
            link,
            key_file,
            own: Peer::new(a.sysid, a.compid),
            companion: Peer::new(a.cc_sysid, a.cc_compid),
            outages: args::outages(&a.rc_loss_at, &a.rc_back_at)?,
            duration: a.duration,
            require_signed: a.require_signed || kept.is_some(),
            events: a.events,
            log_level: a.log_level,
            report: a.report.0,
            stop_on_signals: true,
            home: a.home,
            pilot_mode: a.pilot_mode,
            arm_at: a.arm_at,
        })
    }
}

pub fn run(a: FcSimArgs) -> Result<Outcome, CliError> {
    let opts = FcOptions::try_from(a)?;
    run_fc(opts, Box::new(std::io::stdout())).map_err(CliError::daemon("fc-sim"))?;
    Ok(Outcome::Clean)
}
