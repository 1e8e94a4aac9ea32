//! `fbwag router`: the router's arguments.

use crate::args;
use crate::error::{CliError, Outcome};
use crate::live::router::{run_router, RouterOptions};
use crate::live::LogOptions;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// Route MAVLink between links (a companion's FC port, ground stations,
/// MAVProxy, onboard programs).
///
/// Addressed frames go to the link where their addressee (system and
/// component) was seen; broadcasts, and frames of ids the dialect does
/// not know, go to every other link; nothing is sent back where it came
/// from, and frames are forwarded byte for byte (signed frames stay
/// verifiable end to end). Every system and component seen is kept, on
/// every link it was seen on (a swarm or a flood of ids makes the router
/// forget nobody); a route learned from a verified frame is never shared
/// with a link that only forged its ids. A link that fails, or a TCP or
/// serial link not there yet at start, is opened again every second; no
/// link's error stops the others.
#[derive(clap::Args)]
#[command(after_long_help = super::help::ROUTER_EVENTS)]
#[command(group(clap::ArgGroup::new("logs").args(["tlog", "flight_log"]).multiple(true)))]
pub struct RouterArgs {
    /// Links: udpin:IP:PORT, udpout:IP:PORT, tcp:IP:PORT,
    /// tcpin:IP:PORT, serial:PATH:BAUD (two or more).
    // Counted after parsing, not by clap: a --config file's links and
    // the command line's are two runs of values, each may hold one.
    #[arg(value_name = "CONN", value_parser = args::endpoint, required = true)]
    pub links: Vec<String>,
    /// Read options from this TOML file first: one key per long option
    /// (`sign_key = "@/etc/fbwag/key"`, `require_signed = true`, lists
    /// for repeatable ones), `links = [...]` for the links. A directory:
    /// its *.toml files in name order. Repeatable; a later file's
    /// single-valued options win (`false` turns a switch off), and the
    /// command line's over all, as does a later value given for the same
    /// link (LINK:VALUE); repeatable ones add up, the files' first: links
    /// are numbered (LINK) files' links first, then CONN's; the log lists
    /// them at start. Example: deploy/router.toml. mavlink-router's
    /// configuration is read as it is: a file in its format (main.conf:
    /// named *.conf, or whose first section is `[General]` or
    /// `[UartEndpoint|UdpEndpoint|TcpEndpoint NAME]`) or a directory of
    /// *.conf files (its config.d; a directory mixing *.conf and *.toml is
    /// refused). Every such file adds to one configuration, as
    /// mavlink-router merges them, whose options come before the TOML
    /// files' and the command line's. An endpoint becomes a link named as
    /// its section (NAME=CONN), its keys the options naming it; a key
    /// without an equivalent is refused at its line, with the reason
    /// (docs/deployment.md, "Migrating from mavlink-router").
    #[arg(long, value_name = "PATH")]
    pub config: Vec<PathBuf>,
    /// Print the options the --config files give as one TOML file of
    /// fbwag's (checked as a run would check them), and exit: what a
    /// mavlink-router file stands for, or several files merged.
    #[arg(long)]
    pub print_config: bool,
    /// Verify signatures with this key (64 hex digits, @FILE holding
    /// them, readable by its owner only, or passphrase:TEXT as MAVProxy's
    /// `signing setup`): KEY for every link, LINK:KEY for link LINK (its
    /// name or its place among CONN, from 1), which then uses no other. Frames are still
    /// forwarded untouched: the router signs nothing on anyone's behalf.
    /// On a listening link (udpin, tcpin) with a key, only sources of
    /// verified frames are answered, and a tcpin client that sent one is
    /// never evicted. Repeatable. Example: --sign-key 1:@/etc/fbwag/fc.key
    #[arg(long, value_name = "[LINK:]KEY", value_parser = args::link_sign_key)]
    pub sign_key: Vec<args::ForLink<String>>,
    /// Route only frames whose signature verified (the rest are dropped
    /// and counted as "unauthenticated"): a link without a key routes
    /// nothing.
    #[arg(long, requires = "sign_key")]
    pub require_signed: bool,
    /// Keep each link's signing timestamps across restarts: the first
    /// link's in PATH, link N's (from 1) in PATH.N (see `fbwag cc
    /// --help`).
    #[arg(long, value_name = "PATH", requires = "sign_key")]
    pub signing_state: Option<PathBuf>,
    /// Listening links (udpin, tcpin) answer this address only: IP:PORT
    /// for every one, LINK:IP:PORT for link LINK (for tcpin, the client
    /// connected from it; IP:0, from IP on any port). Without it a
    /// listening link answers the sources that spoke recently (8 at most;
    /// a newcomer takes the place of one silent for 3 s, never of one
    /// still speaking). Repeatable. Example: --peer 2:192.168.1.20:14550
    #[arg(long, value_name = "[LINK:]IP:PORT", value_parser = args::link_peer)]
    pub peer: Vec<args::ForLink<SocketAddr>>,
    /// Take in from link LINK (its place among CONN, from 1) only what
    /// RULE lets through; the rest is dropped before routing and counted
    /// as "filtered". RULE is allow-msg=, block-msg= (message ids or
    /// names), allow-sys=, block-sys= (source systems), allow-comp=,
    /// block-comp= (source components) with a list: 30,HEARTBEAT or
    /// 1,200-210. An allow list admits only what it lists, a block list
    /// removes what it lists (and outranks an allow list); a frame goes
    /// on when message, system and component all pass. Repeatable; the
    /// rules of one link and direction add up (16 message ids at most
    /// each). Example: --filter-in 3:block-msg=COMMAND_LONG,SET_MODE
    #[arg(long, value_name = "LINK:RULE", value_parser = args::link_rule)]
    pub filter_in: Vec<args::LinkRule>,
    /// Send on link LINK only what RULE lets through (as --filter-in):
    /// a frame it refuses is not sent there, and still goes to the other
    /// links of its route. Example: --filter-out 2:allow-sys=1
    /// --filter-out 2:block-msg=ATTITUDE
    #[arg(long, value_name = "LINK:RULE", value_parser = args::link_rule)]
    pub filter_out: Vec<args::LinkRule>,
    /// Pace what is routed to link LINK (its place among CONN, from 1):
    /// at most RATE bytes a second (60–100,000,000), or `off`; at most a
    /// second of it is held back, the oldest dropped first (counted as
    /// lost in full link queues). For a link slower than what the others
    /// send it: a radio modem behind a UDP or TCP bridge, a serial link.
    /// Repeatable; unpaced by default. Example: --routed-rate 1:5760
    #[arg(long, value_name = "LINK:RATE", value_parser = args::link_rate)]
    pub routed_rate: Vec<args::ForLink<args::RoutedRate>>,
    /// Send link LINK (its place among CONN, from 1) every frame routed:
    /// those addressed to a system on another link as well as the
    /// broadcasts, through its --filter-out. For a logger or a tool that
    /// watches the whole network; what it sends is routed as any link's.
    /// Repeatable. Example: --sniffer 3
    #[arg(long, value_name = "LINK", value_parser = args::link)]
    pub sniffer: Vec<args::LinkRef>,
    /// Make every link system ID is heard on (its HEARTBEAT or any frame
    /// the router lets through; on a link with a key, a verified one) a
    /// --sniffer, from then on, said in the log: mavlink-router's
    /// SnifferSysid. A system id is whatever a sender claims: on a link
    /// without a key anyone who speaks as ID reads everything; prefer
    /// --sniffer LINK, or give such links keys.
    #[arg(long, value_name = "ID", allow_hyphen_values = true, value_parser = args::mavlink_id)]
    pub sniffer_sysid: Option<u8>,
    /// RTS/CTS hardware flow control on serial link LINK (its name or
    /// place): for a radio modem that says when its buffer is full.
    /// Repeatable. mavlink-router's FlowControl.
    #[arg(long, value_name = "LINK", value_parser = args::link)]
    pub flow_control: Vec<args::LinkRef>,
    /// Receive the flight stack's own log over MAVLink into DIR, as
    /// mavlink-router's Log does for ArduPilot (LOG_BACKEND_TYPE with its
    /// MAVLink bit): the router asks the vehicle (--log-sysid) for its
    /// DataFlash log (REMOTE_LOG_BLOCK_STATUS, MAV_REMOTE_LOG_DATA_BLOCK_START,
    /// as component 192 of the vehicle's system), acknowledges each
    /// REMOTE_LOG_DATA_BLOCK and asks again for missing ones, and writes
    /// the blocks to fbwag-router-YYYYMMDDTHHMMSS.uuuuuuZ.bin, one file
    /// per log (read by pymavlink's DFReader, mavlogdump.py, MAVExplorer),
    /// under --tlog-min-free, --log-max-files and --log-mode. Only the
    /// vehicle's blocks, on its link, verified where that link has a key,
    /// are written.
    #[arg(long, value_name = "DIR")]
    pub flight_log: Option<PathBuf>,
    /// The vehicle's system id (1-255), for --flight-log and --log-mode
    /// while-armed: the autopilot (component 1) of that system. Default:
    /// the first autopilot whose HEARTBEAT is heard. mavlink-router's
    /// LogSystemId.
    #[arg(long, value_name = "ID", allow_hyphen_values = true, value_parser = args::mavlink_id, requires = "logs")]
    pub log_sysid: Option<u8>,
    /// Forward a frame that arrives twice (the same bytes, on any links:
    /// redundant radios) within this many milliseconds once; the copies
    /// are dropped and counted as "duplicate". 0: off (the default).
    /// Up to 128 frames a window are remembered.
    #[arg(long, value_name = "MS", default_value_t = 0, allow_hyphen_values = true, value_parser = args::dedup_ms)]
    pub dedup: u64,
    /// Write machine-readable events to this file (`-`: stdout): frames
    /// dropped by reason every report, and a summary at exit
    /// (`{"event":"summary","frames":N,"forwarded":N,"dropped":{...}}`).
    /// With --tlog, every report also has `{"event":"tlog","written":N,
    /// "dropped_queue_full":N,"not_written":N,"files":N,"deleted":N}`, and
    /// the summary those counts as "tlog".
    #[arg(long, value_name = "PATH")]
    pub events: Option<PathBuf>,
    #[arg(long, value_enum, default_value = "info", help = super::help::LOG_LEVEL)]
    pub log_level: crate::live::Level,
    /// Stop after this many seconds (0–1,000,000).
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true, value_parser = args::seconds)]
    pub duration: Option<f64>,
    #[arg(long, value_name = "SECONDS|off", default_value = "10", allow_hyphen_values = true, value_parser = args::report, help = super::help::REPORT)]
    pub report: args::ReportEvery,
    #[command(flatten)]
    pub tlog: super::tlog::TlogArgs,
}

impl TryFrom<RouterArgs> for RouterOptions {
    type Error = CliError;

    fn try_from(a: RouterArgs) -> Result<Self, CliError> {
        if a.links.len() < 2 {
            return Err(CliError::TooFewLinks(a.links.len()));
        }
        let names = args::link_names("CONN", a.links.iter().map(String::as_str))
            .map_err(CliError::link_option)?;
        let endpoints = a.links.iter().map(|e| {
            let conn = args::split_link_name(e).1;
            conn.parse().map_err(CliError::endpoint(e))
        });
        let filters = args::link_filters(&a.filter_in, &a.filter_out, &names)
            .map_err(CliError::link_option)?;
        let routed_rates = args::per_link("--routed-rate", &a.routed_rate, &names)
            .map_err(CliError::link_option)?;
        let keys = args::per_link("--sign-key", &a.sign_key, &names)
            .map_err(CliError::link_option)?
            .into_iter()
            .map(|k| k.as_deref().map(super::key).transpose())
            .collect::<Result<_, _>>()?;
        let peers = args::per_link("--peer", &a.peer, &names).map_err(CliError::link_option)?;
        let endpoints: Vec<_> = endpoints.collect::<Result<_, _>>()?;
        args::check_peers(&a.peer, &endpoints, &names).map_err(CliError::link_option)?;
        let sniffers =
            args::link_indices("--sniffer", &a.sniffer, &names).map_err(CliError::link_option)?;
        let flow_control = args::link_indices("--flow-control", &a.flow_control, &names)
            .map_err(CliError::link_option)?;
        args::check_serial("--flow-control", &a.flow_control, &flow_control, &endpoints)
            .map_err(CliError::link_option)?;
        Ok(RouterOptions {
            endpoints,
            names,
            filters,
            routed_rates,
            dedup: (a.dedup > 0).then(|| Duration::from_millis(a.dedup)),
            keys,
            require_signed: a.require_signed,
            signing_state: a.signing_state,
            peers,
            sniffers,
            sniffer_sysid: a.sniffer_sysid,
            flow_control,
            flight_log: a.flight_log.as_deref().map(|dir| LogOptions {
                files: a.tlog.files(dir),
                mode: a.tlog.log_mode,
            }),
            log_sysid: a.log_sysid,
            duration: a.duration.map(Duration::from_secs_f64),
            report: a.report.0,
            events: a.events,
            log_level: a.log_level,
            tlog: a.tlog.options(),
        })
    }
}

/// Checks `a` as a run would, without running.
pub fn check(a: RouterArgs) -> Result<(), CliError> {
    RouterOptions::try_from(a).map(drop)
}

pub fn run(a: RouterArgs) -> Result<Outcome, CliError> {
    let opts = RouterOptions::try_from(a)?;
    run_router(opts, Box::new(std::io::stdout())).map_err(CliError::daemon("router"))?;
    Ok(Outcome::Clean)
}
