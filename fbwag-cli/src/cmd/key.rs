//! `fbwag key`: signing keys. `new` makes one; `push` sets a flight
//! controller's with SETUP_SIGNING, as MAVProxy's `signing setup` does.

use crate::args;
use crate::error::{CliError, Outcome};
use fbwag_dialect::dialects::common::SetupSigning;
use fbwag_dialect::dialects::minimal::MavAutopilot;
use fbwag_dialect::mavframe::conn::Connection;
use fbwag_dialect::mavframe::signing::timestamp_now;
use fbwag_dialect::{Dialect, MessageView, Signer, Verifier};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Signing keys: make one, set a flight controller's.
///
/// One key per airframe: the FC, its companion and the ground stations
/// that command it share it. `fbwag key new` makes it; `fbwag key push`
/// sets it on the FC; the daemons take it as `--sign-key @PATH`. A
/// MAVProxy passphrase is a key too: `--sign-key passphrase:TEXT` is what
/// MAVProxy's `signing setup TEXT` sets.
#[derive(clap::Args)]
pub struct KeyArgs {
    #[command(subcommand)]
    command: KeyCommand,
}

#[derive(clap::Subcommand)]
enum KeyCommand {
    New(NewArgs),
    Push(PushArgs),
}

/// Make a new key: 32 bytes from the operating system's random source,
/// written as 64 hex digits to PATH, which only its owner may read (mode
/// 600). An existing file is never overwritten.
#[derive(clap::Args)]
struct NewArgs {
    /// Where to write it (a file that does not exist yet).
    #[arg(value_name = "PATH")]
    path: PathBuf,
}

/// Set a flight controller's signing key with SETUP_SIGNING, as MAVProxy's
/// `signing setup` does: waits for the FC's heartbeat on LINK, sends the
/// key (with the time now as its first timestamp), and waits for the FC's
/// frames signed with it. ArduPilot (and fc-sim) take a new key only while
/// disarmed, and then require it on every link. Exit status 0 when the FC
/// signs with the key, 1 when it did not take it in time.
#[derive(clap::Args)]
struct PushArgs {
    /// The FC's link (connection string), e.g. udpin:0.0.0.0:14550 or
    /// serial:/dev/ttyACM0:115200.
    #[arg(long, value_name = "CONN", value_parser = args::endpoint)]
    link: String,
    /// The new key: 64 hex digits, @FILE, or passphrase:TEXT.
    #[arg(long, value_name = "KEY", value_parser = args::sign_key)]
    sign_key: String,
    /// The key the FC requires now, if it has one: the request is signed
    /// with it (an FC that requires signing ignores an unsigned one).
    #[arg(long, value_name = "KEY", value_parser = args::sign_key)]
    current_key: Option<String>,
    /// Give up after this many seconds (0–1,000,000).
    #[arg(long, value_name = "SECONDS", default_value_t = 10.0, allow_hyphen_values = true, value_parser = args::seconds)]
    timeout: f64,
}

pub fn run(a: KeyArgs) -> Result<Outcome, CliError> {
    match a.command {
        KeyCommand::New(n) => new_key(&n.path).map(|()| Outcome::Clean),
        KeyCommand::Push(p) => push(p),
    }
}

/// Writes a new key to `path`, mode 600, never over an existing file.
fn new_key(path: &Path) -> Result<(), CliError> {
    use rand::RngCore;
    let mut key = [0u8; 32];
    rand::rngs::OsRng.fill_bytes(&mut key);
    let hex: String = key.iter().map(|b| format!("{b:02x}")).collect();
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create_new(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    let written = options.open(path).and_then(|mut f| {
        f.write_all(format!("{hex}\n").as_bytes())
            .and_then(|()| f.sync_all())
    });
    written.map_err(|source| CliError::KeyWrite {
        path: path.to_path_buf(),
        source,
    })?;
    eprintln!("fbwag: a new key in {} (mode 600)", path.display());
    Ok(())
}

/// `fbwag key push`.
fn push(p: PushArgs) -> Result<Outcome, CliError> {
    let key = super::key(&p.sign_key)?;
    let current = p.current_key.as_deref().map(super::key).transpose()?;
    let endpoint = args::split_link_name(&p.link).1;
    let endpoint = endpoint
        .parse()
        .map_err(CliError::endpoint(format!("--link {}", p.link)))?;
    let daemon = CliError::daemon("key push");
    let mut link = Connection::<Dialect>::open(&endpoint).map_err(daemon)?;
    link.set_signer(current.map(|k| Signer::new(k, 0, timestamp_now())));
    let until = Instant::now() + Duration::from_secs_f64(p.timeout);
    let Some(fc) = wait_for_fc(&mut link, until).map_err(CliError::daemon("key push"))? else {
        eprintln!(
            "fbwag: no flight controller heard on {} within {} s",
            p.link, p.timeout
        );
        return Ok(Outcome::Flagged);
    };
    let request = SetupSigning {
        target_system: fc.0,
        target_component: fc.1,
        secret_key: key,
        initial_timestamp: timestamp_now(),
    };
    let signed =
        wait_signed(&mut link, &request, key, until).map_err(CliError::daemon("key push"))?;
    if signed {
        eprintln!("fbwag: the FC {}/{} signs with the new key", fc.0, fc.1);
    } else {
        eprintln!(
            "fbwag: the FC {}/{} did not sign with the new key within {} s (armed? requiring another key: --current-key)",
            fc.0, fc.1, p.timeout
        );
    }
    Ok(Outcome::clean_if(signed))
}

/// The ids of the first autopilot heard (a HEARTBEAT of an autopilot, not
/// a ground station's or a companion's), by `until`.
fn wait_for_fc(link: &mut Connection<Dialect>, until: Instant) -> io::Result<Option<(u8, u8)>> {
    while let Some(left) = until.checked_duration_since(Instant::now()) {
        let Some(rx) = link.recv(Some(left.min(Duration::from_millis(200))))? else {
            continue;
        };
        let f = rx.frame();
        if let Some(MessageView::Heartbeat(h)) = MessageView::new(f.msg_id(), f.payload()) {
            if h.autopilot() != MavAutopilot::INVALID {
                let head = f.header();
                return Ok(Some((head.sysid, head.compid)));
            }
        }
    }
    Ok(None)
}

/// Sends `request` every second until the FC's frames verify with `key`
/// (then true), or `until` (false). A STATUSTEXT of the FC is said.
fn wait_signed(
    link: &mut Connection<Dialect>,
    request: &SetupSigning,
    key: [u8; 32],
    until: Instant,
) -> io::Result<bool> {
    let mut verifier = Verifier::<16>::new(key);
    let mut next_send = Instant::now();
    while Instant::now() < until {
        if Instant::now() >= next_send {
            link.send_auto(255, 190, request)?;
            next_send = Instant::now() + Duration::from_secs(1);
        }
        let Some(rx) = link.recv(Some(Duration::from_millis(100)))? else {
            continue;
        };
        let f = rx.frame();
        let from_fc = (f.header().sysid, f.header().compid)
            == (request.target_system, request.target_component);
        if from_fc && verifier.verify(&f).is_ok() {
            return Ok(true);
        }
        if let (true, Some(MessageView::Statustext(t))) =
            (from_fc, MessageView::new(f.msg_id(), f.payload()))
        {
            eprintln!(
                "fbwag: the FC says: {}",
                String::from_utf8_lossy(t.text().as_bytes())
            );
        }
    }
    Ok(false)
}
