//! `fbwag cc`: the companion daemon's arguments.

use super::help;
use crate::args::{self, ControllerKind};
use crate::error::{CliError, Outcome};
use crate::live::cc::{check_trusted, run_cc, CcOptions};
use crate::live::net::{routed_rate, Named};
use fbwag_delegation::Peer;
use fbwag_dialect::Endpoint;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

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
/// fails, or is not there yet at start, is opened again every second.
#[derive(clap::Args)]
#[command(after_long_help = help::CC_EVENTS)]
#[command(group(clap::ArgGroup::new("logs").args(["tlog"]).multiple(true)))]
pub struct CcArgs {
    /// Connection string: udpin:IP:PORT, udpout:IP:PORT, tcp:IP:PORT,
    /// tcpin:IP:PORT, serial:PATH:BAUD. With udpin or tcpin, frames go to
    /// --peer, or else to the source of the FC's trusted frames (see
    /// below).
    #[arg(long, value_name = "CONN", value_parser = args::endpoint)]
    pub link: String,
    /// Read options from this TOML file first: one key per long option
    /// (`sign_key = "@/etc/fbwag/key"`, `require_signed = true`, lists
    /// for repeatable ones). A directory: its *.toml files in name order.
    /// Repeatable; a later file's single-valued options win (`false`
    /// turns a switch off), and the command line's over all, as does a
    /// later value given for the same link (LINK:VALUE); repeatable ones
    /// add up, the files' first. Example: deploy/cc.toml. A
    /// mavlink-router file (main.conf, or a directory of *.conf) is read
    /// as it is, its endpoints as --out links (the FC link stays --link):
    /// see `fbwag router --help`.
    #[arg(long, value_name = "PATH")]
    pub config: Vec<PathBuf>,
    /// Print the options the --config files give as one TOML file of
    /// fbwag's (checked as a run would check them), and exit.
    #[arg(long)]
    pub print_config: bool,
    /// udpin and tcpin only: send to this address (IP:PORT; for tcpin,
    /// the client connected from it) and no other.
    #[arg(long, value_name = "IP:PORT")]
    pub peer: Option<SocketAddr>,
    /// Also route to and from this link (repeatable): a ground station,
    /// MAVProxy, other onboard programs. MAVLink routing rules; frames
    /// are forwarded untouched (signed ones stay verifiable).
    #[arg(long = "out", value_name = "CONN", value_parser = args::endpoint)]
    pub outs: Vec<String>,
    /// Take in from link LINK only what RULE lets through; the rest goes
    /// nowhere and is counted as "filtered". LINK counts the --out links,
    /// then the --trusted-out links, then --autonomy, from 1 in the order
    /// given: with one --out and one --trusted-out, 2 is the trusted one.
    /// RULE as in `fbwag router --help`: allow-msg=, block-msg= (ids or
    /// names), allow-sys=, block-sys=, allow-comp=,
    /// block-comp= with a list (30,HEARTBEAT or 1,200-210); block lists
    /// outrank allow lists. Filters never touch the FC link's protocol
    /// frames, the companion's own, nor the autonomy's control (which
    /// the handover gates: a rule blocking it is refused). Repeatable. Example: --filter-in
    /// 1:block-msg=COMMAND_LONG,SET_MODE
    #[arg(long, value_name = "LINK:RULE", value_parser = args::link_rule)]
    pub filter_in: Vec<args::LinkRule>,
    /// Send on link LINK (as --filter-in counts) only what RULE lets
    /// through; the companion's own frames always go. Example:
    /// --filter-out 2:block-msg=ATTITUDE
    #[arg(long, value_name = "LINK:RULE", value_parser = args::link_rule)]
    pub filter_out: Vec<args::LinkRule>,
    /// Route a frame that arrives twice (the same bytes, on any links)
    /// within this many milliseconds once; the copies are counted as
    /// "duplicate". 0: off (the default). The FC's protocol frames reach
    /// the companion's own logic either way.
    #[arg(long, value_name = "MS", default_value_t = 0, allow_hyphen_values = true, value_parser = args::dedup_ms)]
    pub dedup: u64,
    /// Like --out, for a ground tool that cannot sign (MAVSDK, MAVProxy
    /// without a key) where the FC requires signatures: the link is
    /// trusted like --sign-key, and what arrives on it goes on to the
    /// FC signed with the key. Whoever can send into it can command
    /// the aircraft, so it must be local: only loopback addresses or a
    /// serial port, unless --trusted-out-remote. On a plain --out, an
    /// unsigned tool under --require-signed gets telemetry only.
    #[arg(long = "trusted-out", value_name = "CONN", value_parser = args::endpoint, requires = "sign_key")]
    pub trusted_outs: Vec<String>,
    /// Accept --trusted-out addresses that are not loopback (a trusted
    /// network of your own).
    #[arg(long, requires = "trusted_outs")]
    pub trusted_out_remote: bool,
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
    pub routed_rate: Option<args::RoutedRate>,
    /// The link of your own autonomy program (e.g. udpin:127.0.0.1:14560).
    /// It receives everything the FC sends and the companion's notices;
    /// its RC_CHANNELS_OVERRIDE, SET_ATTITUDE_TARGET and MANUAL_CONTROL
    /// go to the FC (re-addressed, signed with --sign-key) only while
    /// the companion holds control, and are dropped otherwise; its other
    /// messages go to the --out links only. Replaces --controller.
    #[arg(long, value_name = "CONN", value_parser = args::endpoint)]
    pub autonomy: Option<String>,
    /// The autonomy program's address (IP:PORT, the port it sends from):
    /// the autonomy link answers it only and drops frames from anyone
    /// else; a restarted program is heard again at once. Needed when
    /// --autonomy listens (udpin, tcpin, udpbcast): otherwise any local
    /// program that spoke first would fly the aircraft. `any` admits the
    /// first program heard, until it has been silent for 3 s: unsafe, for
    /// a machine that runs nothing else. An --autonomy that connects
    /// (udpout, tcp, serial) talks to its one far end and needs none.
    #[arg(long, value_name = "IP:PORT|any", requires = "autonomy", value_parser = args::autonomy_peer)]
    pub autonomy_peer: Option<args::AutonomyPeer>,
    /// What happens when the autonomy has sent nothing for 500 ms (it
    /// should stream its control, gated, at its own rate all the time):
    /// `decline`: the companion declines the FC's takeover (and gives
    /// back an episode it holds), so the FC's failsafe (RTL) runs at
    /// once rather than after its timeouts; `wings-level`: it takes
    /// over and flies wings level until the autonomy speaks.
    #[arg(long, value_enum, default_value = "decline", requires = "autonomy")]
    pub autonomy_fallback: args::AutonomyFallback,
    #[arg(long, value_name = "PATH", requires = "sign_key", help = help::SIGNING_STATE)]
    pub signing_state: Option<PathBuf>,
    #[arg(long, value_name = "PATH", help = help::EVENTS)]
    pub events: Option<PathBuf>,
    #[arg(long, value_enum, default_value = "info", help = help::LOG_LEVEL)]
    pub log_level: crate::live::Level,
    #[arg(long, value_name = "SECONDS|off", default_value = "10", allow_hyphen_values = true, value_parser = args::report, help = help::REPORT)]
    pub report: args::ReportEvery,
    /// Our system id (1–255).
    #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
    pub sysid: u8,
    /// Our component id (1–255; 191: onboard computer).
    #[arg(long, default_value_t = 191, allow_hyphen_values = true, value_parser = args::mavlink_id)]
    pub compid: u8,
    /// The flight controller's system id (1–255).
    #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
    pub fc_sysid: u8,
    /// The flight controller's component id (1–255).
    #[arg(long, default_value_t = 1, allow_hyphen_values = true, value_parser = args::mavlink_id)]
    pub fc_compid: u8,
    /// Control stream rate (Hz, 1–100).
    #[arg(long, default_value_t = 20.0, allow_hyphen_values = true, value_parser = args::rate_hz)]
    pub rate: f64,
    /// Controller: wings-level (cruise throttle) or circle.
    #[arg(long, value_enum, default_value = "wings-level")]
    pub controller: ControllerKind,
    /// Cruise throttle (PWM µs, 800–2200).
    #[arg(long, default_value_t = 1600, allow_hyphen_values = true, value_parser = args::pwm_us)]
    pub throttle: u16,
    /// Sign outgoing frames and verify incoming ones with this key: 64
    /// hex digits, @FILE holding them (readable by its owner only: `fbwag
    /// key new` makes one), or passphrase:TEXT (what MAVProxy's `signing
    /// setup TEXT` sets).
    #[arg(long, value_name = "HEX64", value_parser = args::sign_key)]
    pub sign_key: Option<String>,
    /// Act only on the FC's frames whose signature verified.
    #[arg(long, requires = "sign_key")]
    pub require_signed: bool,
    /// Stop after this many seconds (0–1,000,000).
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true, value_parser = args::seconds)]
    pub duration: Option<f64>,
    /// Exit once control has been handed back to the pilot.
    #[arg(long)]
    pub exit_after_handback: bool,
    #[command(flatten)]
    pub tlog: super::tlog::TlogArgs,
}

/// A `--trusted-out` link: local unless `remote` allows any.
fn trusted_out(conn: &str, remote: bool) -> Result<Named, CliError> {
    let e = endpoint("--trusted-out", conn)?;
    check_trusted(&e.endpoint, remote).map_err(|source| CliError::TrustedOut {
        conn: conn.into(),
        source,
    })?;
    Ok(e)
}

/// A link of `flag`: `[NAME=]CONN`.
fn endpoint(flag: &str, given: &str) -> Result<Named, CliError> {
    let (name, conn) = args::split_link_name(given);
    Ok(Named {
        endpoint: conn
            .parse()
            .map_err(CliError::endpoint(format!("{flag} {given}")))?,
        name: name.map(str::to_string),
    })
}

impl TryFrom<CcArgs> for CcOptions {
    type Error = CliError;

    fn try_from(a: CcArgs) -> Result<Self, CliError> {
        let outs = a.outs.iter().map(|e| endpoint("--out", e));
        let outs: Vec<Named> = outs.collect::<Result<_, _>>()?;
        let trusted = a.trusted_outs.iter();
        let trusted_outs = trusted.map(|e| trusted_out(e, a.trusted_out_remote));
        let trusted_outs: Vec<Named> = trusted_outs.collect::<Result<_, _>>()?;
        let autonomy = a.autonomy.as_deref().map(|e| endpoint("--autonomy", e));
        let autonomy = autonomy.transpose()?;
        if let Some(e) = &autonomy {
            check_autonomy_peer(&e.endpoint, a.autonomy_peer)?;
        }
        // Filters name the --out, --trusted-out and --autonomy links; a
        // name is one link's among all of them, the FC link's too.
        let filtered: Vec<&str> = (a.outs.iter().chain(&a.trusted_outs))
            .chain(&a.autonomy)
            .map(String::as_str)
            .collect();
        let names = args::link_names("--out", filtered).map_err(CliError::link_option)?;
        let fc_name = args::split_link_name(&a.link).0;
        if let Some(twice) = fc_name.filter(|n| names.contains(&Some(n.to_string()))) {
            let error = args::LinkOptionError::NameTwice(twice.to_string());
            return Err(CliError::link_option((format!("--link {}", a.link), error)));
        }
        let filters = args::link_filters(&a.filter_in, &a.filter_out, &names)
            .map_err(CliError::link_option)?;
        if autonomy.is_some() {
            let autonomy = names.len() - 1;
            args::check_autonomy_rules(&a.filter_in, autonomy, &names)
                .map_err(CliError::link_option)?;
        }
        let mut link =
            super::link_options(&a.link, a.sign_key.as_deref(), a.peer, a.signing_state)?;
        link.routed_rate = routed_rate(&link.endpoint, a.routed_rate);
        Ok(CcOptions {
            link,
            outs,
            filters,
            dedup: (a.dedup > 0).then(|| Duration::from_millis(a.dedup)),
            trusted_outs,
            trusted_out_remote: a.trusted_out_remote,
            autonomy,
            autonomy_peer: match a.autonomy_peer {
                Some(args::AutonomyPeer::At(addr)) => Some(addr),
                _ => None,
            },
            autonomy_fallback: a.autonomy_fallback.into(),
            own: Peer::new(a.sysid, a.compid),
            fc: Peer::new(a.fc_sysid, a.fc_compid),
            rate_hz: a.rate,
            controller: a.controller.build(a.throttle),
            require_signed: a.require_signed,
            duration: a.duration.map(Duration::from_secs_f64),
            exit_after_handback: a.exit_after_handback,
            events: a.events,
            log_level: a.log_level,
            report: a.report.0,
            tlog: a.tlog.options(),
            stop_on_signals: true,
        })
    }
}

/// A listening autonomy link (`udpin`, `tcpin`, `udpbcast`) must name its
/// program, or say `any` on purpose: the first local program that spoke
/// would fly the aircraft otherwise.
fn check_autonomy_peer(e: &Endpoint, peer: Option<args::AutonomyPeer>) -> Result<(), CliError> {
    let listens = matches!(
        e,
        Endpoint::UdpIn(_) | Endpoint::TcpIn(_) | Endpoint::UdpBcast(_)
    );
    match peer {
        None if listens => Err(CliError::AutonomyUnpinned(e.to_string())),
        _ => Ok(()),
    }
}

/// Runs the daemon: exit status 1 when the FC was never heard (a wrong
/// serial port, baud rate or key looks idle otherwise).
/// Checks `a` as a run would, without running.
pub fn check(a: CcArgs) -> Result<(), CliError> {
    CcOptions::try_from(a).map(drop)
}

pub fn run(a: CcArgs) -> Result<Outcome, CliError> {
    let opts = CcOptions::try_from(a)?;
    let report = run_cc(opts, Box::new(std::io::stdout())).map_err(CliError::daemon("cc"))?;
    Ok(Outcome::clean_if(report.fc_heard))
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cc {
        #[command(flatten)]
        args: CcArgs,
    }

    /// The options of `fbwag cc` with three filterable links and `filter`
    /// (`--filter-out=RULE`, or a whole `--filter-in=RULE` option).
    fn options(filter: &str) -> Result<CcOptions, CliError> {
        let filter = if filter.starts_with("--") {
            filter.to_owned()
        } else {
            format!("--filter-out={filter}")
        };
        let key = "ab".repeat(32);
        let args = Cc::try_parse_from([
            "cc",
            "--link=udpout:127.0.0.1:1",
            &format!("--sign-key={key}"),
            "--out=udpin:127.0.0.1:2",
            "--trusted-out=udpin:127.0.0.1:3",
            "--autonomy=udpin:127.0.0.1:4",
            "--autonomy-peer=127.0.0.1:5",
            &filter,
        ])
        .unwrap();
        CcOptions::try_from(args.args)
    }

    #[test]
    fn filters_count_the_out_then_the_trusted_then_the_autonomy_link() {
        let o = options("3:block-msg=ATTITUDE").unwrap();
        assert_eq!(o.filters.len(), 1);
        assert_eq!(o.filters[0].index, 2, "the autonomy's link");
        let e = options("4:block-msg=ATTITUDE").err().unwrap();
        assert!(e.to_string().contains("there are 3 links"), "{e}");
    }

    #[test]
    fn a_rule_blocking_the_autonomys_control_is_refused() {
        for rule in ["3:block-msg=RC_CHANNELS_OVERRIDE", "3:block-msg=0,82"] {
            let e = options(&format!("--filter-in={rule}")).err().unwrap();
            assert!(e.to_string().contains("is never filtered"), "{rule}: {e}");
        }
        // Other links' rules, the autonomy's other messages, and its
        // out-filter may name them.
        for rule in [
            "--filter-in=2:block-msg=RC_CHANNELS_OVERRIDE",
            "--filter-in=3:block-msg=HEARTBEAT",
            "--filter-in=3:allow-msg=HEARTBEAT",
            "--filter-out=3:block-msg=MANUAL_CONTROL",
        ] {
            assert!(options(rule).is_ok(), "{rule}");
        }
    }
}
