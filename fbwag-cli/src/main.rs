//! `fbwag`: the FBWAG MAVLink toolbox.

mod args;
mod hexstream;
mod json;
mod lines;
mod live;
mod sim;

use clap::{Parser as ClapParser, Subcommand};
use fbwag_dialect::mavframe::frame::{frame_len, Frame, MAX_FRAME_LEN};
use fbwag_dialect::mavframe::parser::Parser;
use fbwag_dialect::mavframe::Signer;
use fbwag_dialect::Dialect;
use std::io::{BufWriter, Read, Write};
use std::path::PathBuf;
use std::process::ExitCode;

/// Tools for the FBWAG MAVLink dialect (ardupilotmega + FBWAG_NOTICE, id 15001).
#[derive(ClapParser)]
#[command(name = "fbwag", version, after_help = EXAMPLES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

const EXAMPLES: &str = "\
Examples:
  echo fd0c0000000101993a0040e201000101014642574147d933 | fbwag decode --hex
  fbwag decode capture.bin > frames.jsonl
  fbwag decode --tlog flight.tlog | grep FBWAG_NOTICE
  fbwag decode capture.bin | fbwag encode > same.bin        # byte-exact
  fbwag encode --hex --sign-key $(printf '%064x' 0) --link-id 0 --sign-timestamp 1000 < frames.jsonl
  fbwag sim --table1                                        # the paper's Table I, 10,000 trials per row
  fbwag sim --scenario message-loss --loss 0.5 --trials 10000 --seed 7 --json
  fbwag sim --sweep --svg sweep.svg
  fbwag demo                                                # FC + companion over a lossy loopback relay
  fbwag cc --link serial:/dev/serial0:460800                # the companion daemon
  fbwag fc-sim --link udpout:127.0.0.1:14550 --rc-loss-at 3 --rc-back-at 12";

/// What both daemons' `--help` says about links and peers.
macro_rules! link_rules {
    () => {
        "
Links and peers:
  Every send and receive error is logged (at most 5 lines per 10 s) and never
  ends the program. With udpin or tcpin, frames go to --peer if given;
  otherwise nothing is sent until a trusted frame arrives (the configured
  peer's ids, and a verified signature with --require-signed), then to that
  frame's source (for tcpin: that client; other clients get nothing); frames
  from any other address are dropped (counted as not_peer). A trusted frame
  from another address moves the peer only when its signature verified, or
  when the current peer has been silent for 3 s. A datagram without a valid
  frame changes nothing. udpout sockets are connected to their target: the
  system drops datagrams from anyone else. tcpin serves 32 clients at once:
  another evicts the one that has shown the least (nothing, then unsigned
  frames only), never the peer nor a client that sent a verified frame;
  --peer IP:0 matches a tcpin client from IP on any port. With a signing
  key, frames older than one minute (by their signing timestamp) are
  refused, and a frame accepted once is refused again on any
  connection."
    };
}

const CC_EVENTS: &str = concat!(
    "\
Events (--events), one JSON object per line, all with \"t_ms\" (ms since start)
and \"event\":
  {\"event\":\"fc\",\"state\":\"found\"|\"lost\"|\"rebooted\"}
  {\"event\":\"fc_mode\",\"mode\":\"FBWA\"|\"CIRCLE\"|\"FBWAG\"|\"RTL\"|...}
  {\"event\":\"control\",\"state\":\"start\",\"fc_event\":N}   the companion took over
  {\"event\":\"control\",\"state\":\"stop\"}
  {\"event\":\"takeover\",\"decision\":\"declined\",\"reason\":\"autonomy silent\",
   \"fc_event\":N}                           the autonomy was silent: the FC falls back
  {\"event\":\"autonomy\",\"state\":\"silent\"|\"speaking\"}
  {\"event\":\"drops\",\"dropped\":{\"REASON\":N,...}}   frames dropped so far, by reason
                                          (own_ids, impersonation, unauthenticated,
                                          not_peer, gated), every 5 s while they change
  {\"event\":\"summary\",\"takeovers\":N,\"handbacks\":N,\"trusted_frames\":N,
   \"untrusted_frames\":N,\"untrusted_notices\":N,\"controls_forwarded\":N,
   \"controls_dropped\":N,\"dropped\":{\"REASON\":N,...}}   at exit
  {\"event\":\"dropped\",\"events\":N}   N events were dropped before this one:
                                          the reader had stopped reading (the
                                          daemon never waits for it; nor for
                                          its log, which says the same)
",
    link_rules!()
);

const FC_EVENTS: &str = concat!(
    "\
Events (--events), one JSON object per line, all with \"t_ms\" (ms since start)
and \"event\":
  {\"event\":\"mode\",\"mode\":\"FBWA\"|\"CIRCLE\"|\"FBWAG\"|\"RTL\"|...}   at start and every
                                          change (the pilot's: --pilot-mode)
  {\"event\":\"receiver\",\"state\":\"ok\"|\"lost\"}
  {\"event\":\"handover\",\"ms\":N}          receiver failure -> companion control
  {\"event\":\"control_applied\",\"sysid\":N,\"compid\":N,\"authenticated\":B,
   \"message\":\"RC_CHANNELS_OVERRIDE\"|..., \"channels\":[8 values]}   each control applied
  {\"event\":\"param\",\"name\":S,\"value\":X,\"sysid\":N,\"compid\":N}   a parameter set
  {\"event\":\"summary\",\"trusted_frames\":N,\"untrusted_frames\":N,
   \"untrusted_notices\":N,\"controls_applied\":N,\"controls_untrusted\":N,
   \"controls_misaddressed\":N,\"controls_outside_companion\":N,
   \"gcs_unsigned_refused\":N, \"not_served\":{\"NAME\":N,...},
   \"dropped\":{\"REASON\":N,...}}   at exit
  {\"event\":\"dropped\",\"events\":N}   N events were dropped before this one:
                                          the reader had stopped reading (the
                                          daemon never waits for it; nor for
                                          its log, which says the same)

Ground stations:
  Served for any sender (with --require-signed: only frames whose signature
  verified, as ArduPilot on a signed link): every COMMAND_LONG/COMMAND_INT to
  this FC gets a COMMAND_ACK (ACCEPTED when done; UNSUPPORTED otherwise;
  DENIED, with a STATUSTEXT saying why, for mode changes, arming, RTL,
  landing, reboot and the like: the delegation engine decides who flies);
  AUTOPILOT_VERSION (MAV_CMD_REQUEST_MESSAGE, ..._AUTOPILOT_CAPABILITIES);
  MAV_CMD_REQUEST_MESSAGE/SET_MESSAGE_INTERVAL/GET_MESSAGE_INTERVAL and
  REQUEST_DATA_STREAM for the telemetry above (ATTITUDE at most 50 Hz, the
  rest at most 10 Hz: the protocol shares the link); HOME_POSITION (every 5 s
  and on request), GPS_GLOBAL_ORIGIN on request; the parameter protocol:
  FS_SHORT_ACTN (always 5, FBWAG), FS_SHORT_TIMEOUT, FS_LONG_ACTN (always 1,
  RTL), FS_LONG_TIMEOUT (the handshake timeout), SYSID_THISMAV,
  FBWAG_CC_SYSID, FBWAG_CC_COMPID, FBWAG_RETRY_TIME, FBWAG_RETRY_MAX,
  FBWAG_OVRD_TIME, FBWAG_CC_TIMEOUT, FBWAG_SIGNED (writes take effect only
  while the pilot flies, else are refused with a STATUSTEXT); missions: a
  download is empty, an upload refused (but for an empty one); TIMESYNC.
  What is received and not served is logged (\"not served: ...\") and counted
  in the summary. On udpin and tcpin, answers go where every frame goes
  (--peer, or the companion's address): put a router (e.g. MAVProxy) between
  fc-sim and several ground stations.
",
    link_rules!()
);

#[derive(Subcommand)]
enum Command {
    /// Print one JSON object per frame of a MAVLink stream.
    ///
    /// Fields are listed in wire order; integers are JSON numbers, arrays JSON
    /// arrays, char arrays strings up to the first NUL (or arrays of byte
    /// values when bytes follow the NUL or the text is not UTF-8). Floats:
    /// finite values are numbers in shortest round-trip form (-0.0 and
    /// subnormals included); "inf" and "-inf"; "NaN" for the canonical quiet
    /// NaN (bits 0x7fc00000 for float, 0x7ff8000000000000 for double) and
    /// "NaN:0x" plus the bit pattern (8 or 16 hex digits) for any other NaN,
    /// so sign and payload bits survive. Payload bytes beyond the message's
    /// fields (a sender with a newer definition) are kept as "extra" (hex),
    /// with "payload_len". `fbwag decode | fbwag encode` gives back the same
    /// bytes. Bad frames are skipped and counted in a summary on stderr; the
    /// parser resynchronises after garbage and corrupted frames.
    Decode {
        /// Input file; `-` or nothing for stdin.
        file: Option<PathBuf>,
        /// The input is hex text (whitespace ignored), not binary.
        #[arg(long)]
        hex: bool,
        /// The input is a .tlog: each frame preceded by an 8-byte big-endian
        /// microsecond timestamp (kept as "tlog_us").
        #[arg(long, conflicts_with = "hex")]
        tlog: bool,
    },
    /// Read `fbwag decode` JSON lines and write the frames.
    ///
    /// Messages are named by `name` or `msgid`; `seq`, `sysid`, `compid` and
    /// `version` come from the JSON (0, 0, 0 and 2 when absent). `fbwag decode
    /// | fbwag encode` reproduces its input byte for byte, truncation,
    /// signatures, extra payload bytes and NaN bits included.
    ///
    /// A line is encoded exactly as it says, or not at all: refused are lines
    /// that are not UTF-8 or not one JSON object, unknown or repeated keys, a
    /// message without "fields" ("fields":{} asks for all zeros; fields left
    /// out of it are zero), unknown field names, values of the wrong JSON type
    /// or outside their field's range (integers out of range, negative for
    /// unsigned, finite floats beyond float/double, which would become
    /// infinities), strings longer than their char array, arrays not of the
    /// declared length, a "payload_len" that would cut off non-zero field
    /// bytes or exceeds the message without "extra" holding the bytes beyond,
    /// and "signed": true with neither a "signature" to copy nor --sign-key.
    /// Numbers are rounded once, to the nearest value of the field's type.
    /// A frame of an unknown message ("raw" hex) is copied as it is, and its
    /// other keys must agree with its bytes. Blank lines are skipped; lines
    /// longer than 1 MiB are refused.
    ///
    /// Each refused line is reported on stderr as `line N: reason`, no frame is
    /// written for it, and encoding goes on with the next line. Exit status: 0
    /// when every line was encoded, 1 when any was refused, 2 when the input
    /// could not be read or the output not written.
    Encode {
        /// Input file of JSON lines; `-` or nothing for stdin.
        file: Option<PathBuf>,
        /// Write hex text, one frame per line, instead of binary.
        #[arg(long)]
        hex: bool,
        /// Write MAVLink 1 frames of the base fields, whatever each line's
        /// version (ids up to 255; extension fields, "payload_len", "extra",
        /// "compat_flags" and signatures of the lines are dropped).
        #[arg(long, conflicts_with = "sign_key")]
        v1: bool,
        /// Sign every frame with this 32-byte key (64 hex digits, or @FILE), replacing
        /// any signature of the line. A MAVLink 1 frame cannot be signed: such
        /// lines are refused.
        #[arg(long, value_name = "HEX64", value_parser = args::sign_key)]
        sign_key: Option<String>,
        /// Link id of the signature.
        #[arg(long, default_value_t = 0, requires = "sign_key")]
        link_id: u8,
        /// Signing timestamp of the first frame (10 µs units since
        /// 2015-01-01, at most 2^48 - 1), incremented per frame; default: now.
        #[arg(long, requires = "sign_key", allow_hyphen_values = true, value_parser = args::sign_timestamp)]
        sign_timestamp: Option<u64>,
        /// Write a .tlog (timestamps from "tlog_us", else 0).
        #[arg(long, conflicts_with = "hex")]
        tlog: bool,
    },
    /// The companion-computer daemon: answer the FC's FBWAG notices.
    ///
    /// Waits for the flight controller, acknowledges RC-loss notices with
    /// status 2 (echoing the event timestamp), streams RC_CHANNELS_OVERRIDE
    /// from the controller while delegated, stops and acknowledges on status
    /// 0; recognises a rebooted FC. Sends a 1 Hz HEARTBEAT. Logs every
    /// transition with a timestamp.
    ///
    /// Only the configured FC's frames count (--fc-sysid/--fc-compid), and
    /// with --require-signed only those whose signature verified; everything
    /// else is ignored and counted (logged at most 5 lines per 10 s). No
    /// send or receive error ends the daemon; a TCP or serial link that
    /// fails is opened again every second.
    #[command(after_long_help = CC_EVENTS)]
    Cc {
        /// Connection string: udpin:IP:PORT, udpout:IP:PORT, tcp:IP:PORT,
        /// tcpin:IP:PORT, serial:PATH:BAUD. With udpin or tcpin, frames go to
        /// --peer, or else to the source of the FC's trusted frames (see
        /// below).
        #[arg(long, value_name = "CONN")]
        link: String,
        /// udpin and tcpin only: send to this address (IP:PORT; for tcpin,
        /// the client connected from it) and no other.
        #[arg(long, value_name = "IP:PORT")]
        peer: Option<std::net::SocketAddr>,
        /// Also route to and from this link (repeatable): a ground station,
        /// MAVProxy, other onboard programs. MAVLink routing rules; frames
        /// are forwarded untouched (signed ones stay verifiable).
        #[arg(long = "out", value_name = "CONN")]
        outs: Vec<String>,
        /// Like --out, for a ground tool that cannot sign (MAVSDK, MAVProxy
        /// without a key) where the FC requires signatures: the link is
        /// trusted like --sign-key, and what arrives on it goes on to the
        /// FC signed with the key. Whoever can send into it can command
        /// the aircraft, so it must be local: only loopback addresses or a
        /// serial port, unless --trusted-out-remote. On a plain --out, an
        /// unsigned tool under --require-signed gets telemetry only.
        #[arg(long = "trusted-out", value_name = "CONN", requires = "sign_key")]
        trusted_outs: Vec<String>,
        /// Accept --trusted-out addresses that are not loopback (a trusted
        /// network of your own).
        #[arg(long, requires = "trusted_outs")]
        trusted_out_remote: bool,
        /// What --out links route to the FC link goes at most this many
        /// bytes a second (or `off`); the companion's own frames are never
        /// held back. Keep it below what the FC link carries: then a flood
        /// from a ground station's side can never fill the buffer at the
        /// link's far end (a telemetry modem's, a serial bridge's) ahead of
        /// the companion's acknowledgement. At most a second of routed
        /// frames waits, each sender's (address) in turn; the busiest
        /// sender's oldest are dropped first, and counted. Default:
        /// half a serial link's byte rate (baud / 20), 8000 on other links.
        /// A ground station's commands and transfers need a few hundred;
        /// RTK corrections (GPS_RTCM_DATA) 1–5 kB/s more.
        #[arg(long, value_name = "BYTES_PER_S|off", allow_hyphen_values = true, value_parser = args::routed_rate)]
        routed_rate: Option<args::RoutedRate>,
        /// The link of your own autonomy program (e.g. udpin:127.0.0.1:14560).
        /// It receives everything the FC sends and the companion's notices;
        /// its RC_CHANNELS_OVERRIDE, SET_ATTITUDE_TARGET and MANUAL_CONTROL
        /// go to the FC (re-addressed, signed with --sign-key) only while
        /// the companion holds control, and are dropped otherwise; its other
        /// messages go to the --out links only. Replaces --controller.
        #[arg(long, value_name = "CONN")]
        autonomy: Option<String>,
        /// The autonomy program's address (IP:PORT): the autonomy link
        /// answers it only and drops frames from anyone else. Without it,
        /// the first program heard is the autonomy until it has been silent
        /// for 3 s.
        #[arg(long, value_name = "IP:PORT", requires = "autonomy")]
        autonomy_peer: Option<std::net::SocketAddr>,
        /// What happens when the autonomy has sent nothing for 500 ms (it
        /// should stream its control, gated, at its own rate all the time):
        /// `decline`: the companion declines the FC's takeover (and gives
        /// back an episode it holds), so the FC's failsafe (RTL) runs at
        /// once rather than after its timeouts; `wings-level`: it takes
        /// over and flies wings level until the autonomy speaks.
        #[arg(long, value_enum, default_value = "decline", requires = "autonomy")]
        autonomy_fallback: args::AutonomyFallback,
        /// Keep the signing timestamps (this signer's, and each peer
        /// stream's) in this file across restarts, so a restart neither
        /// replays old timestamps nor accepts replays of frames accepted
        /// before (saved every second and at exit, SIGINT and SIGTERM
        /// included; a damaged file, or one that cannot be written, stops
        /// the program: remove it to start from the clock). Without it, a
        /// restarted daemon accepts once, per stream, frames captured up to
        /// a minute before: use it whenever signing.
        #[arg(long, value_name = "PATH", requires = "sign_key")]
        signing_state: Option<PathBuf>,
        /// Write machine-readable events to this file (`-`: stdout), one
        /// JSON object per line (keys below). A FIFO is written once a
        /// reader opens it (events queue meanwhile, up to 4,096, then are
        /// counted as dropped); it never holds the daemon.
        #[arg(long, value_name = "PATH")]
        events: Option<PathBuf>,
        /// Our system id (1–255).
        #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
        sysid: u8,
        /// Our component id (1–255; 191: onboard computer).
        #[arg(long, default_value_t = 191, allow_hyphen_values = true, value_parser = args::mavlink_id)]
        compid: u8,
        /// The flight controller's system id (1–255).
        #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
        fc_sysid: u8,
        /// The flight controller's component id (1–255).
        #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
        fc_compid: u8,
        /// Control stream rate (Hz, 1–100).
        #[arg(long, default_value_t = 20.0, allow_hyphen_values = true, value_parser = args::rate_hz)]
        rate: f64,
        /// Controller: wings-level (cruise throttle) or circle.
        #[arg(long, default_value = "wings-level", value_parser = ["wings-level", "circle"])]
        controller: String,
        /// Cruise throttle (PWM µs, 800–2200).
        #[arg(long, default_value_t = 1600, allow_hyphen_values = true, value_parser = args::pwm_us)]
        throttle: u16,
        /// Sign outgoing frames and verify incoming ones with this key (64 hex digits, or @FILE holding them).
        #[arg(long, value_name = "HEX64", value_parser = args::sign_key)]
        sign_key: Option<String>,
        /// Act only on the FC's frames whose signature verified.
        #[arg(long, requires = "sign_key")]
        require_signed: bool,
        /// Stop after this many seconds (0–1,000,000).
        #[arg(long, value_name = "SECONDS", allow_hyphen_values = true, value_parser = args::seconds)]
        duration: Option<f64>,
        /// Exit once control has been handed back to the pilot.
        #[arg(long)]
        exit_after_handback: bool,
    },
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
    #[command(after_long_help = FC_EVENTS)]
    FcSim {
        /// Connection string (see `fbwag cc --help`).
        #[arg(long, value_name = "CONN")]
        link: String,
        /// udpin and tcpin only: send to this address (IP:PORT; for tcpin,
        /// the client connected from it) and no other.
        #[arg(long, value_name = "IP:PORT")]
        peer: Option<std::net::SocketAddr>,
        /// Keep the signing timestamps (this signer's, and each peer
        /// stream's) in this file across restarts, so a restart neither
        /// replays old timestamps nor accepts replays of frames accepted
        /// before (saved every second and at exit, SIGINT and SIGTERM
        /// included; a damaged file, or one that cannot be written, stops
        /// the program: remove it to start from the clock). Without it, a
        /// restarted daemon accepts once, per stream, frames captured up to
        /// a minute before: use it whenever signing.
        #[arg(long, value_name = "PATH", requires = "sign_key")]
        signing_state: Option<PathBuf>,
        /// Write machine-readable events to this file (`-`: stdout), one
        /// JSON object per line (keys below). A FIFO is written once a
        /// reader opens it (events queue meanwhile, up to 4,096, then are
        /// counted as dropped); it never holds the daemon.
        #[arg(long, value_name = "PATH")]
        events: Option<PathBuf>,
        /// Lose the receiver at this time (seconds after start, 0–1,000,000).
        /// Repeatable, with --rc-back-at, for several failures: the k-th
        /// --rc-back-at ends the k-th failure (the last may be left open).
        #[arg(long, value_name = "SECONDS", allow_hyphen_values = true, value_parser = args::seconds)]
        rc_loss_at: Vec<f64>,
        /// Get the receiver back at this time (seconds, 0–1,000,000).
        #[arg(long, value_name = "SECONDS", allow_hyphen_values = true, value_parser = args::seconds)]
        rc_back_at: Vec<f64>,
        /// The companion allowed to take over: system id (1–255).
        #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
        cc_sysid: u8,
        /// The companion allowed to take over: component id (1–255).
        #[arg(long, default_value_t = 191, allow_hyphen_values = true, value_parser = args::mavlink_id)]
        cc_compid: u8,
        /// Our system id (1–255).
        #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
        sysid: u8,
        /// Our component id (1–255).
        #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
        compid: u8,
        /// Run this long (seconds, 0–1,000,000).
        #[arg(long, default_value_t = 20.0, allow_hyphen_values = true, value_parser = args::seconds)]
        duration: f64,
        /// Sign and verify with this key (64 hex digits, or @FILE holding them).
        #[arg(long, value_name = "HEX64", value_parser = args::sign_key)]
        sign_key: Option<String>,
        /// Accept the companion's takeover only from signed frames; serve
        /// ground-station requests only from signed frames too.
        #[arg(long, requires = "sign_key")]
        require_signed: bool,
        /// Home (the model starts over it at 100 m, heading north, and RTL
        /// returns to it): latitude and longitude in degrees, ground
        /// altitude in metres above sea level. Default: ArduPilot SITL's.
        #[arg(
            long,
            value_name = "LAT,LON,ALT",
            default_value = "-35.363261,149.165230,584",
            allow_hyphen_values = true
        )]
        home: live::plane::Home,
        /// The mode the pilot flies while the receiver works, as reported
        /// (the model flies the pilot's centred sticks in any of them).
        #[arg(long, value_enum, default_value = "fbwa")]
        pilot_mode: live::fc::PilotMode,
    },
    /// Both programs over loopback UDP through a lossy relay: the receiver
    /// fails and returns several times; a timeline, and the handover times
    /// (p50 and max).
    ///
    /// The relay's losses depend only on the seed (each message's fate is
    /// drawn from the seed, its direction, its id and its count): a seed
    /// gives the same handovers on every run, up to scheduling jitter.
    Demo {
        /// Share of datagrams the relay drops in each direction (0–1).
        #[arg(long, default_value_t = 0.2, allow_hyphen_values = true, value_parser = args::share)]
        loss: f64,
        /// Receiver failures (each followed by the receiver's return).
        #[arg(long, default_value_t = 5, allow_hyphen_values = true, value_parser = clap::value_parser!(u32).range(1..=1000))]
        cycles: u32,
        /// How long each failure lasts (s): past the FC's 5 s handshake
        /// timeout, so every failure ends in companion control or RTL.
        #[arg(long, default_value_t = 5.5, allow_hyphen_values = true, value_parser = args::seconds)]
        lost_for: f64,
        /// How long the receiver works between failures (s).
        #[arg(long, default_value_t = 1.5, allow_hyphen_values = true, value_parser = args::seconds)]
        back_for: f64,
        /// Seed of the relay's losses.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Route MAVLink between links (a companion's FC port, ground stations,
    /// MAVProxy, onboard programs).
    ///
    /// Addressed frames go to the link where their addressee (system and
    /// component) was seen; broadcasts, and frames of ids the dialect does
    /// not know, go to every other link; nothing is sent back where it came
    /// from, and frames are forwarded byte for byte (signed frames stay
    /// verifiable end to end). A link that fails is opened again every
    /// second; no link's error stops the others.
    Router {
        /// Links: udpin:IP:PORT, udpout:IP:PORT, tcp:IP:PORT,
        /// tcpin:IP:PORT, serial:PATH:BAUD (two or more).
        #[arg(value_name = "CONN", num_args = 2.., required = true)]
        links: Vec<String>,
        /// Verify every link's signatures with this key (64 hex digits, or
        /// @FILE holding them). Frames are still forwarded untouched: the
        /// router signs nothing on anyone's behalf. On a listening link
        /// (udpin, tcpin) only sources of verified frames are answered, and
        /// a tcpin client that sent one is never evicted.
        #[arg(long, value_name = "HEX64", value_parser = args::sign_key)]
        sign_key: Option<String>,
        /// Route only frames whose signature verified (the rest are dropped
        /// and counted as "unauthenticated").
        #[arg(long, requires = "sign_key")]
        require_signed: bool,
        /// Keep each link's signing timestamps across restarts: the first
        /// link's in PATH, link N's (from 1) in PATH.N (see `fbwag cc
        /// --help`).
        #[arg(long, value_name = "PATH", requires = "sign_key")]
        signing_state: Option<PathBuf>,
        /// Listening links (udpin, tcpin) answer this address only (for
        /// tcpin, the client connected from it; IP:0, from IP on any port).
        /// Without it they answer the sources that spoke recently (8 at
        /// most; a newcomer takes the place of one silent for 3 s, never of
        /// one still speaking).
        #[arg(long, value_name = "IP:PORT")]
        peer: Option<std::net::SocketAddr>,
        /// Write machine-readable events to this file (`-`: stdout): frames
        /// dropped by reason every report, and a summary at exit
        /// (`{"event":"summary","frames":N,"forwarded":N,"dropped":{...}}`).
        #[arg(long, value_name = "PATH")]
        events: Option<PathBuf>,
        /// Stop after this many seconds (0–1,000,000).
        #[arg(long, value_name = "SECONDS", allow_hyphen_values = true, value_parser = args::seconds)]
        duration: Option<f64>,
        /// Print a traffic summary every this many seconds.
        #[arg(long, value_name = "SECONDS", default_value_t = 10.0, allow_hyphen_values = true, value_parser = args::seconds)]
        report: f64,
    },
    /// Run the delegation protocol in the deterministic simulator.
    ///
    /// Both state machines exchange real MAVLink frames over modelled links
    /// (latency, jitter, loss, bursts) on a virtual clock; every trial is
    /// checked against the protocol's invariants (exit status 1 if any
    /// breaks). Results depend only on the arguments and the seed.
    Sim {
        /// Reproduce the paper's Table I beside its figures.
        #[arg(long, conflicts_with_all = ["sweep", "scenario"])]
        table1: bool,
        /// Sweep loss 0–90 % for a scenario (default message-loss).
        #[arg(long)]
        sweep: bool,
        /// List the scenarios.
        #[arg(long)]
        list: bool,
        /// The scenario to run (see --list).
        #[arg(long, value_name = "NAME")]
        scenario: Option<String>,
        /// Share of frames lost in each direction, 0–1.
        #[arg(long, default_value_t = 0.0, allow_hyphen_values = true, value_parser = args::share)]
        loss: f64,
        /// Bursty (Gilbert–Elliott) loss with bursts of this many frames on
        /// average (1–1,000,000), instead of independent loss.
        #[arg(long, value_name = "FRAMES", allow_hyphen_values = true, value_parser = args::burst)]
        burst: Option<f64>,
        /// Trials per row, 1–1,000,000 (default 10,000; 1,000 per sweep point).
        #[arg(long, allow_hyphen_values = true, value_parser = args::trials)]
        trials: Option<u32>,
        /// Seed of the first trial (trial k uses seed + k; at most
        /// 2^64 - 1,000,001).
        #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::sim_seed)]
        seed: u64,
        /// One JSON object per row.
        #[arg(long)]
        json: bool,
        /// With --sweep: write the chart (success rate and handover time
        /// against loss) as SVG.
        #[arg(long, value_name = "FILE", requires = "sweep")]
        svg: Option<PathBuf>,
        /// Check the protocol exhaustively instead (stateright, breadth
        /// first, on the real nodes): prints the states explored, the
        /// invariants checked and, for a violation, its shortest
        /// counterexample as a timeline; exit status 1 on a violation.
        /// With --json the last line is one JSON object.
        #[arg(long, conflicts_with_all = ["table1", "sweep", "scenario", "list"])]
        model_check: bool,
        /// With --model-check: every state within N steps of the start is
        /// explored (default 8).
        #[arg(long, value_name = "N", requires = "model_check", value_parser = clap::value_parser!(u16).range(1..=64))]
        depth: Option<u16>,
    },
}

fn open_input(file: &Option<PathBuf>) -> std::io::Result<Box<dyn Read>> {
    match file {
        Some(p) if p.as_os_str() != "-" => Ok(Box::new(std::fs::File::open(p)?)),
        _ => Ok(Box::new(std::io::stdin().lock())),
    }
}

fn decode(file: Option<PathBuf>, hex: bool, tlog: bool) -> Result<bool, String> {
    let mut input = open_input(&file).map_err(|e| format!("cannot open input: {e}"))?;
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    let mut parser = Parser::<Dialect>::new();
    let mut emit = |line: String| -> Result<(), String> {
        writeln!(out, "{line}").map_err(|e| format!("cannot write: {e}"))
    };
    // Every form is read in chunks, so memory stays bounded whatever the
    // input's size (a device or an endless pipe included).
    let mut chunk = vec![0u8; 64 * 1024];
    let mut hex_text = hexstream::HexDecoder::default();
    let mut bytes = Vec::new();
    let mut tlog_records = (0u64, 0u64);
    loop {
        let n = match input.read(&mut chunk) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(format!("cannot read input: {e}")),
        };
        let end = n == 0;
        if hex {
            hex_text.push(&chunk[..n], &mut bytes)?;
            if end {
                hex_text.finish()?;
            }
        } else {
            bytes.extend_from_slice(&chunk[..n]);
        }
        if tlog {
            let (used, good, bad) = decode_tlog(&bytes, end, &mut parser, &mut emit)?;
            bytes.drain(..used);
            tlog_records = (tlog_records.0 + good, tlog_records.1 + bad);
        } else {
            let mut rest: &[u8] = &bytes;
            while let Some(r) = parser.next(&mut rest) {
                emit(json::frame_to_json(&r.frame, r.meta, None))?;
            }
            bytes.clear();
        }
        if end {
            break;
        }
    }
    while let Some(r) = parser.flush() {
        emit(json::frame_to_json(&r.frame, r.meta, None))?;
    }
    out.flush().map_err(|e| format!("cannot write: {e}"))?;
    let s = parser.stats();
    let mut summary = format!(
        "decoded {} frames ({} known, {} unknown ids); rejected: {} bad CRC, {} bad incompat flags; {} bytes dropped; {} frames missing by sequence",
        s.frames + s.unknown_frames,
        s.frames,
        s.unknown_frames,
        s.bad_crc,
        s.bad_incompat_flags,
        s.bytes_dropped,
        s.seq_lost
    );
    if tlog {
        summary.push_str(&format!(
            "; tlog: {} records, {} unreadable",
            tlog_records.0, tlog_records.1
        ));
    }
    eprintln!("{summary}");
    Ok(s.bad_crc == 0 && s.bytes_dropped == 0 && tlog_records.1 == 0)
}

/// Reads tlog records (8-byte big-endian µs timestamp, then one frame); an
/// unreadable record is skipped by resynchronising one byte further. Until
/// the `end` of the input, a record is read only when a whole frame of the
/// largest size could follow it, so the outcome does not depend on how the
/// input was chunked. Returns the bytes used and the good and bad records.
fn decode_tlog(
    raw: &[u8],
    end: bool,
    parser: &mut Parser<Dialect>,
    emit: &mut dyn FnMut(String) -> Result<(), String>,
) -> Result<(usize, u64, u64), String> {
    let (mut at, mut good, mut bad) = (0usize, 0u64, 0u64);
    let lookahead = if end { 1 } else { MAX_FRAME_LEN };
    while at + 8 + lookahead <= raw.len() {
        let ts = u64::from_be_bytes(raw[at..at + 8].try_into().expect("8 bytes"));
        let rest = &raw[at + 8..];
        let len = frame_len(rest)
            .ok()
            .filter(|&n| n <= rest.len() && n <= MAX_FRAME_LEN);
        let mut record: &[u8] = len.map_or(&[][..], |n| &rest[..n]);
        match parser.next(&mut record) {
            Some(r) if r.frame.as_bytes().len() == len.unwrap_or(0) => {
                emit(json::frame_to_json(&r.frame, r.meta, Some(ts)))?;
                at += 8 + len.unwrap_or(0);
                good += 1;
            }
            _ => {
                while parser.flush().is_some() {}
                bad += 1;
                at += 1;
            }
        }
    }
    Ok((at, good, bad))
}

fn encode(
    file: Option<PathBuf>,
    hex: bool,
    v1: bool,
    sign: Option<(String, u8, Option<u64>)>,
    tlog: bool,
) -> Result<bool, String> {
    let mut signer = match sign {
        Some((key_hex, link_id, ts)) => {
            let ts = ts.unwrap_or_else(fbwag_dialect::mavframe::signing::timestamp_now);
            Some(Signer::new(key(&key_hex)?, link_id, ts))
        }
        None => None,
    };
    let input = open_input(&file).map_err(|e| format!("cannot open input: {e}"))?;
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    let mut frame = [0u8; MAX_FRAME_LEN];
    let (mut written, mut errors) = (0u64, 0u64);
    let mut lines = lines::Lines::new(std::io::BufReader::new(input));
    while let Some((number, line)) = lines
        .next_line()
        .map_err(|e| format!("cannot read input: {e}"))?
    {
        let text = match line {
            lines::Line::Text(t) => t,
            lines::Line::NotUtf8 { valid_up_to } => {
                eprintln!("line {number}: not UTF-8 (byte {})", valid_up_to + 1);
                errors += 1;
                continue;
            }
            lines::Line::TooLong => {
                eprintln!("line {number}: longer than {} bytes", lines::MAX_LINE);
                errors += 1;
                continue;
            }
        };
        if text.trim().is_empty() {
            continue;
        }
        let mut opts = json::EncodeOptions {
            force_v1: v1,
            signer: signer.as_mut(),
        };
        match json::json_to_frame(&text, &mut opts, &mut frame) {
            Ok(encoded) => {
                let bytes = &frame[..encoded.len];
                debug_assert!(Frame::new_checked(bytes).is_ok());
                let res = if hex {
                    writeln!(out, "{}", json::hex(bytes))
                } else if tlog {
                    let ts = encoded.tlog_us.unwrap_or(0);
                    out.write_all(&ts.to_be_bytes())
                        .and_then(|()| out.write_all(bytes))
                } else {
                    out.write_all(bytes)
                };
                res.map_err(|e| format!("cannot write: {e}"))?;
                written += 1;
            }
            Err(e) => {
                eprintln!("line {number}: {e}");
                errors += 1;
            }
        }
    }
    out.flush().map_err(|e| format!("cannot write: {e}"))?;
    eprintln!("encoded {written} frames; {errors} lines rejected");
    Ok(errors == 0)
}

/// A 32-byte key from 64 hex digits.
fn key(hex: &str) -> Result<[u8; 32], String> {
    let bytes = json::unhex(hex).map_err(|e| e.to_string())?;
    bytes
        .try_into()
        .map_err(|b: Vec<u8>| format!("a signing key is 32 bytes (64 hex digits), got {}", b.len()))
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Decode { file, hex, tlog } => decode(file, hex, tlog),
        Command::Encode {
            file,
            hex,
            v1,
            sign_key,
            link_id,
            sign_timestamp,
            tlog,
        } => encode(
            file,
            hex,
            v1,
            sign_key.map(|k| (k, link_id, sign_timestamp)),
            tlog,
        ),
        Command::Router {
            links,
            sign_key,
            require_signed,
            signing_state,
            peer,
            events,
            duration,
            report,
        } => (|| {
            let endpoints = links
                .iter()
                .map(|e| e.parse().map_err(|err| format!("{e}: {err}")))
                .collect::<Result<Vec<_>, _>>()?;
            live::router::run_router(
                live::router::RouterOptions {
                    endpoints,
                    key: sign_key.as_deref().map(key).transpose()?,
                    require_signed,
                    signing_state,
                    peer,
                    duration: duration.map(std::time::Duration::from_secs_f64),
                    report: std::time::Duration::from_secs_f64(report.max(0.1)),
                    events,
                },
                Box::new(std::io::stdout()),
            )
            .map(|()| true)
            .map_err(|e| format!("router: {e}"))
        })(),
        Command::Sim {
            table1,
            sweep,
            list,
            scenario,
            loss,
            burst,
            trials,
            seed,
            json,
            svg,
            model_check,
            depth,
        } => sim::run(sim::SimArgs {
            table1,
            sweep,
            list,
            scenario,
            loss,
            burst,
            trials,
            seed,
            json,
            svg,
            model_check,
            depth: depth.map(usize::from),
        }),
        Command::Cc {
            link,
            peer,
            outs,
            trusted_outs,
            trusted_out_remote,
            routed_rate,
            autonomy,
            autonomy_peer,
            autonomy_fallback,
            signing_state,
            events,
            sysid,
            compid,
            fc_sysid,
            fc_compid,
            rate,
            controller,
            throttle,
            sign_key,
            require_signed,
            duration,
            exit_after_handback,
        } => (|| {
            use fbwag_delegation::control::{Circle, Controller, WingsLevel};
            let controller: Box<dyn Controller + Send> = match controller.as_str() {
                "wings-level" => Box::new(WingsLevel { throttle }),
                "circle" => Box::new(Circle { throttle }),
                other => {
                    return Err(format!(
                        "unknown controller `{other}` (wings-level or circle)"
                    ))
                }
            };
            let parse = |flag: &str, e: &str| {
                e.parse::<fbwag_dialect::Endpoint>()
                    .map_err(|err| format!("{flag} {e}: {err}"))
            };
            let opts = live::cc::CcOptions {
                outs: outs
                    .iter()
                    .map(|e| parse("--out", e))
                    .collect::<Result<_, _>>()?,
                trusted_outs: trusted_outs
                    .iter()
                    .map(|e| {
                        let endpoint = parse("--trusted-out", e)?;
                        live::cc::check_trusted(&endpoint, trusted_out_remote)
                            .map_err(|err| format!("--trusted-out {e}: {err}"))?;
                        Ok(endpoint)
                    })
                    .collect::<Result<_, String>>()?,
                autonomy: autonomy
                    .as_deref()
                    .map(|e| parse("--autonomy", e))
                    .transpose()?,
                autonomy_peer,
                autonomy_fallback: autonomy_fallback.into(),
                link: {
                    let endpoint = link.parse().map_err(|e| format!("--link: {e}"))?;
                    live::net::LinkOptions {
                        routed_rate: live::net::routed_rate(&endpoint, routed_rate),
                        endpoint,
                        key: sign_key.as_deref().map(key).transpose()?,
                        peer,
                        signing_state,
                    }
                },
                own: fbwag_delegation::Peer::new(sysid, compid),
                fc: fbwag_delegation::Peer::new(fc_sysid, fc_compid),
                rate_hz: rate,
                controller,
                require_signed,
                duration: duration.map(std::time::Duration::from_secs_f64),
                exit_after_handback,
                events,
                stop_on_signals: true,
            };
            live::cc::run_cc(opts, Box::new(std::io::stdout()))
                .map(|_| true)
                .map_err(|e| format!("cc: {e}"))
        })(),
        Command::FcSim {
            link,
            peer,
            signing_state,
            events,
            rc_loss_at,
            rc_back_at,
            cc_sysid,
            cc_compid,
            sysid,
            compid,
            duration,
            sign_key,
            require_signed,
            home,
            pilot_mode,
        } => (|| {
            let opts = live::fc::FcOptions {
                link: live::net::LinkOptions {
                    endpoint: link.parse().map_err(|e| format!("--link: {e}"))?,
                    key: sign_key.as_deref().map(key).transpose()?,
                    peer,
                    signing_state,
                    // Nothing is routed through the simulator.
                    routed_rate: None,
                },
                own: fbwag_delegation::Peer::new(sysid, compid),
                companion: fbwag_delegation::Peer::new(cc_sysid, cc_compid),
                outages: args::outages(&rc_loss_at, &rc_back_at)?,
                duration,
                require_signed,
                events,
                stop_on_signals: true,
                home,
                pilot_mode,
            };
            live::fc::run_fc(opts, Box::new(std::io::stdout()))
                .map(|_| true)
                .map_err(|e| format!("fc-sim: {e}"))
        })(),
        Command::Demo {
            loss,
            cycles,
            lost_for,
            back_for,
            seed,
        } => live::demo::demo(live::demo::DemoOptions {
            loss,
            cycles,
            lost_for,
            back_for,
            seed,
        })
        .map(|r| !r.handovers.is_empty())
        .map_err(|e| format!("demo: {e}")),
    };
    match result {
        Ok(true) => ExitCode::SUCCESS,
        // The work was done, but the input had problems (counted on stderr).
        Ok(false) => ExitCode::from(1),
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(2)
        }
    }
}
