//! `fbwag router`: the router's arguments.

use crate::args;
use crate::error::{CliError, Outcome};
use crate::live::router::{run_router, RouterOptions};
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
/// with a link that only forged its ids. A link that fails is opened
/// again every second; no link's error stops the others.
#[derive(clap::Args)]
pub struct RouterArgs {
    /// Links: udpin:IP:PORT, udpout:IP:PORT, tcp:IP:PORT,
    /// tcpin:IP:PORT, serial:PATH:BAUD (two or more).
    #[arg(value_name = "CONN", num_args = 2.., required = true)]
    pub links: Vec<String>,
    /// Verify every link's signatures with this key (64 hex digits, or
    /// @FILE holding them). Frames are still forwarded untouched: the
    /// router signs nothing on anyone's behalf. On a listening link
    /// (udpin, tcpin) only sources of verified frames are answered, and
    /// a tcpin client that sent one is never evicted.
    #[arg(long, value_name = "HEX64", value_parser = args::sign_key)]
    pub sign_key: Option<String>,
    /// Route only frames whose signature verified (the rest are dropped
    /// and counted as "unauthenticated").
    #[arg(long, requires = "sign_key")]
    pub require_signed: bool,
    /// Keep each link's signing timestamps across restarts: the first
    /// link's in PATH, link N's (from 1) in PATH.N (see `fbwag cc
    /// --help`).
    #[arg(long, value_name = "PATH", requires = "sign_key")]
    pub signing_state: Option<PathBuf>,
    /// Listening links (udpin, tcpin) answer this address only (for
    /// tcpin, the client connected from it; IP:0, from IP on any port).
    /// Without it they answer the sources that spoke recently (8 at
    /// most; a newcomer takes the place of one silent for 3 s, never of
    /// one still speaking).
    #[arg(long, value_name = "IP:PORT")]
    pub peer: Option<SocketAddr>,
    /// Write machine-readable events to this file (`-`: stdout): frames
    /// dropped by reason every report, and a summary at exit
    /// (`{"event":"summary","frames":N,"forwarded":N,"dropped":{...}}`).
    #[arg(long, value_name = "PATH")]
    pub events: Option<PathBuf>,
    /// Stop after this many seconds (0–1,000,000).
    #[arg(long, value_name = "SECONDS", allow_hyphen_values = true, value_parser = args::seconds)]
    pub duration: Option<f64>,
    /// Print a traffic summary every this many seconds.
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0, allow_hyphen_values = true, value_parser = args::seconds)]
    pub report: f64,
}

impl TryFrom<RouterArgs> for RouterOptions {
    type Error = CliError;

    fn try_from(a: RouterArgs) -> Result<Self, CliError> {
        let endpoints = a
            .links
            .iter()
            .map(|e| e.parse().map_err(CliError::endpoint(e)));
        Ok(RouterOptions {
            endpoints: endpoints.collect::<Result<_, _>>()?,
            key: a.sign_key.as_deref().map(super::key).transpose()?,
            require_signed: a.require_signed,
            signing_state: a.signing_state,
            peer: a.peer,
            duration: a.duration.map(Duration::from_secs_f64),
            report: Duration::from_secs_f64(a.report.max(0.1)),
            events: a.events,
        })
    }
}

pub fn run(a: RouterArgs) -> Result<Outcome, CliError> {
    let opts = RouterOptions::try_from(a)?;
    run_router(opts, Box::new(std::io::stdout())).map_err(CliError::daemon("router"))?;
    Ok(Outcome::Clean)
}
