//! `fbwag`: the FBWAG MAVLink toolbox.

mod json;
mod live;
mod sim;

use clap::{Parser as ClapParser, Subcommand};
use fbwag_dialect::mavframe::frame::{frame_len, Frame, MAX_FRAME_LEN};
use fbwag_dialect::mavframe::parser::Parser;
use fbwag_dialect::mavframe::Signer;
use fbwag_dialect::Dialect;
use std::io::{BufRead, BufWriter, Read, Write};
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
  ends the program. With udpin, frames go to --peer if given; otherwise nothing
  is sent until a trusted frame arrives (the configured peer's ids, and a
  verified signature with --require-signed), then to that frame's source. A
  trusted frame from another address moves the peer only when its signature
  verified, or when the current peer has been silent for 3 s. With a signing
  key, frames older than one minute (by their signing timestamp) are refused."
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
  {\"event\":\"summary\",\"takeovers\":N,\"handbacks\":N,\"trusted_frames\":N,
   \"untrusted_frames\":N,\"untrusted_notices\":N,\"controls_forwarded\":N,
   \"controls_dropped\":N}                               at exit
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
   \"gcs_unsigned_refused\":N, \"not_served\":{\"NAME\":N,...}}   at exit

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
  in the summary. On udpin, answers go where every frame goes (--peer, or the
  companion's address): put a router (e.g. MAVProxy) between fc-sim and
  several ground stations.
",
    link_rules!()
);

#[derive(Subcommand)]
enum Command {
    /// Print one JSON object per frame of a MAVLink stream.
    ///
    /// Fields are listed in wire order; integers and finite floats are JSON
    /// numbers (floats in shortest round-trip form), NaN and infinities the
    /// strings "NaN", "inf", "-inf", arrays JSON arrays, char arrays strings up
    /// to the first NUL. Bad frames are skipped and counted in a summary on
    /// stderr; the parser resynchronises after garbage and corrupted frames.
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
    /// `version` come from the JSON. `fbwag decode | fbwag encode` reproduces
    /// its input byte for byte, truncation and signatures included.
    Encode {
        /// Input file of JSON lines; `-` or nothing for stdin.
        file: Option<PathBuf>,
        /// Write hex text, one frame per line, instead of binary.
        #[arg(long)]
        hex: bool,
        /// Write MAVLink 1 frames (ids up to 255; extension fields dropped).
        #[arg(long)]
        v1: bool,
        /// Sign every MAVLink 2 frame with this 32-byte key (64 hex digits).
        #[arg(long, value_name = "HEX64")]
        sign_key: Option<String>,
        /// Link id of the signature.
        #[arg(long, default_value_t = 0, requires = "sign_key")]
        link_id: u8,
        /// Signing timestamp of the first frame (10 µs units since
        /// 2015-01-01), incremented per frame; default: now.
        #[arg(long, requires = "sign_key")]
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
        /// tcpin:IP:PORT, serial:PATH:BAUD. With udpin, frames go to --peer,
        /// or else to the source of the FC's trusted frames (see below).
        #[arg(long, value_name = "CONN")]
        link: String,
        /// udpin only: send to this address (IP:PORT) and no other.
        #[arg(long, value_name = "IP:PORT")]
        peer: Option<std::net::SocketAddr>,
        /// Write machine-readable events to this file (`-`: stdout), one
        /// JSON object per line (keys below).
        #[arg(long, value_name = "PATH")]
        events: Option<PathBuf>,
        /// Our system id.
        #[arg(long, default_value_t = 1)]
        sysid: u8,
        /// Our component id (191: onboard computer).
        #[arg(long, default_value_t = 191)]
        compid: u8,
        /// The flight controller's system id.
        #[arg(long, default_value_t = 1)]
        fc_sysid: u8,
        /// The flight controller's component id.
        #[arg(long, default_value_t = 1)]
        fc_compid: u8,
        /// Control stream rate (Hz).
        #[arg(long, default_value_t = 20.0)]
        rate: f64,
        /// Controller: wings-level (cruise throttle) or circle.
        #[arg(long, default_value = "wings-level")]
        controller: String,
        /// Cruise throttle (PWM µs).
        #[arg(long, default_value_t = 1600)]
        throttle: u16,
        /// Sign outgoing frames and verify incoming ones with this key (64 hex digits).
        #[arg(long, value_name = "HEX64")]
        sign_key: Option<String>,
        /// Act only on the FC's frames whose signature verified.
        #[arg(long, requires = "sign_key")]
        require_signed: bool,
        /// Stop after this many seconds.
        #[arg(long, value_name = "SECONDS")]
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
        /// udpin only: send to this address (IP:PORT) and no other.
        #[arg(long, value_name = "IP:PORT")]
        peer: Option<std::net::SocketAddr>,
        /// Write machine-readable events to this file (`-`: stdout), one
        /// JSON object per line (keys below).
        #[arg(long, value_name = "PATH")]
        events: Option<PathBuf>,
        /// Lose the receiver at this time (seconds after start).
        #[arg(long, value_name = "SECONDS")]
        rc_loss_at: Option<f64>,
        /// Get the receiver back at this time.
        #[arg(long, value_name = "SECONDS")]
        rc_back_at: Option<f64>,
        /// The companion allowed to take over: system id.
        #[arg(long, default_value_t = 1)]
        cc_sysid: u8,
        /// The companion allowed to take over: component id.
        #[arg(long, default_value_t = 191)]
        cc_compid: u8,
        /// Our system id.
        #[arg(long, default_value_t = 1)]
        sysid: u8,
        /// Our component id.
        #[arg(long, default_value_t = 1)]
        compid: u8,
        /// Run this long (seconds).
        #[arg(long, default_value_t = 20.0)]
        duration: f64,
        /// Sign and verify with this key (64 hex digits).
        #[arg(long, value_name = "HEX64")]
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
    /// Both programs over loopback UDP through a lossy relay: a timeline and
    /// the measured handover time.
    Demo {
        /// Share of datagrams the relay drops in each direction.
        #[arg(long, default_value_t = 0.2)]
        loss: f64,
        /// Receiver lost at (s).
        #[arg(long, default_value_t = 2.0)]
        rc_loss_at: f64,
        /// Receiver back at (s).
        #[arg(long, default_value_t = 7.0)]
        rc_back_at: f64,
        /// Total run time (s).
        #[arg(long, default_value_t = 9.0)]
        duration: f64,
        /// Seed of the relay's losses.
        #[arg(long, default_value_t = 1)]
        seed: u64,
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
        #[arg(long, default_value_t = 0.0)]
        loss: f64,
        /// Bursty (Gilbert–Elliott) loss with bursts of this many frames on
        /// average, instead of independent loss.
        #[arg(long, value_name = "FRAMES")]
        burst: Option<f64>,
        /// Trials per row (default 10,000; 1,000 per sweep point).
        #[arg(long)]
        trials: Option<u32>,
        /// Seed of the first trial (trial k uses seed + k).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// One JSON object per row.
        #[arg(long)]
        json: bool,
        /// With --sweep: write the chart (success rate and handover time
        /// against loss) as SVG.
        #[arg(long, value_name = "FILE", requires = "sweep")]
        svg: Option<PathBuf>,
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
    let mut tlog_records = (0u64, 0u64);
    if hex || tlog {
        // Hex text and tlog records are read whole: both are bounded captures.
        let mut raw = Vec::new();
        input
            .read_to_end(&mut raw)
            .map_err(|e| format!("cannot read input: {e}"))?;
        if hex {
            let text = String::from_utf8(raw).map_err(|_| "hex input is not text".to_string())?;
            let bytes = json::unhex(&text)?;
            let mut rest: &[u8] = &bytes;
            while let Some(r) = parser.next(&mut rest) {
                emit(json::frame_to_json(&r.frame, r.meta, None))?;
            }
        } else {
            tlog_records = decode_tlog(&raw, &mut parser, &mut emit)?;
        }
    } else {
        let mut chunk = vec![0u8; 64 * 1024];
        loop {
            let n = match input.read(&mut chunk) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(format!("cannot read input: {e}")),
            };
            let mut rest: &[u8] = &chunk[..n];
            while let Some(r) = parser.next(&mut rest) {
                emit(json::frame_to_json(&r.frame, r.meta, None))?;
            }
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
/// unreadable record is skipped by resynchronising one byte further.
fn decode_tlog(
    raw: &[u8],
    parser: &mut Parser<Dialect>,
    emit: &mut dyn FnMut(String) -> Result<(), String>,
) -> Result<(u64, u64), String> {
    let (mut at, mut good, mut bad) = (0usize, 0u64, 0u64);
    while at + 8 < raw.len() {
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
    Ok((good, bad))
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
            let key = json::unhex(&key_hex)?;
            let key: [u8; 32] = key.try_into().map_err(|k: Vec<u8>| {
                format!(
                    "--sign-key must be 32 bytes (64 hex digits), got {}",
                    k.len()
                )
            })?;
            let ts = ts.unwrap_or_else(fbwag_dialect::mavframe::signing::timestamp_now);
            Some(Signer::new(key, link_id, ts))
        }
        None => None,
    };
    let input = open_input(&file).map_err(|e| format!("cannot open input: {e}"))?;
    let stdout = std::io::stdout();
    let mut out = BufWriter::new(stdout.lock());
    let mut frame = [0u8; MAX_FRAME_LEN];
    let (mut written, mut errors) = (0u64, 0u64);
    for (i, line) in std::io::BufReader::new(input).lines().enumerate() {
        let line = line.map_err(|e| format!("cannot read input: {e}"))?;
        if line.trim().is_empty() {
            continue;
        }
        let mut opts = json::EncodeOptions {
            force_v1: v1,
            signer: signer.as_mut(),
        };
        match json::json_to_frame(&line, &mut opts, &mut frame) {
            Ok(n) => {
                let bytes = &frame[..n];
                let res = if hex {
                    writeln!(out, "{}", json::hex(bytes))
                } else if tlog {
                    let ts = serde_json::from_str::<serde_json::Value>(&line)
                        .ok()
                        .and_then(|v| v.get("tlog_us").and_then(|t| t.as_u64()))
                        .unwrap_or(0);
                    out.write_all(&ts.to_be_bytes())
                        .and_then(|()| out.write_all(bytes))
                } else {
                    out.write_all(bytes)
                };
                res.map_err(|e| format!("cannot write: {e}"))?;
                debug_assert!(Frame::new_checked(bytes).is_ok());
                written += 1;
            }
            Err(e) => {
                eprintln!("line {}: {e}", i + 1);
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
    let bytes = json::unhex(hex)?;
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
        }),
        Command::Cc {
            link,
            peer,
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
            let opts = live::cc::CcOptions {
                link: live::link::LinkOptions {
                    endpoint: link.parse().map_err(|e| format!("--link: {e}"))?,
                    key: sign_key.as_deref().map(key).transpose()?,
                    peer,
                },
                own: fbwag_delegation::Peer::new(sysid, compid),
                fc: fbwag_delegation::Peer::new(fc_sysid, fc_compid),
                rate_hz: rate,
                controller,
                require_signed,
                duration: duration.map(std::time::Duration::from_secs_f64),
                exit_after_handback,
                events,
            };
            live::cc::run_cc(opts, Box::new(std::io::stdout()))
                .map(|_| true)
                .map_err(|e| format!("cc: {e}"))
        })(),
        Command::FcSim {
            link,
            peer,
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
                link: live::link::LinkOptions {
                    endpoint: link.parse().map_err(|e| format!("--link: {e}"))?,
                    key: sign_key.as_deref().map(key).transpose()?,
                    peer,
                },
                own: fbwag_delegation::Peer::new(sysid, compid),
                companion: fbwag_delegation::Peer::new(cc_sysid, cc_compid),
                rc_loss_at,
                rc_back_at,
                duration,
                require_signed,
                events,
                home,
                pilot_mode,
            };
            live::fc::run_fc(opts, Box::new(std::io::stdout()))
                .map(|_| true)
                .map_err(|e| format!("fc-sim: {e}"))
        })(),
        Command::Demo {
            loss,
            rc_loss_at,
            rc_back_at,
            duration,
            seed,
        } => live::demo::demo(loss, rc_loss_at, rc_back_at, duration, seed)
            .map(|r| r.handover.is_some())
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
