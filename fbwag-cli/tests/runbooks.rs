//! docs/deployment.md's runbooks, run as written: each script of
//! docs/runbooks/ must appear in the page byte for byte, and must pass
//! (it checks what the page says to expect, and exits non-zero otherwise)
//! with `fbwag`, MAVProxy and the peers' Python (the pinned peer venv,
//! where scripts/peer-env.sh installed this repository's ./python) on PATH,
//! every port a free one.

use std::path::PathBuf;
use std::process::Command;
use std::sync::Mutex;
use std::time::{Duration, Instant};

mod common;

use common::{free_port, free_tcp_port, peer_python, repo};

/// One at a time: MAVProxy and mavsdk_server start slowly on two cores.
static SERIAL: Mutex<()> = Mutex::new(());

fn runbooks() -> Vec<PathBuf> {
    let mut all: Vec<PathBuf> = std::fs::read_dir(repo().join("docs/runbooks"))
        .expect("docs/runbooks")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "sh"))
        .collect();
    all.sort();
    all
}

#[test]
fn every_runbook_is_in_the_deployment_page_as_written() {
    let page = std::fs::read_to_string(repo().join("docs/deployment.md")).unwrap();
    let books = runbooks();
    assert!(books.len() >= 5, "{books:?}");
    for book in books {
        let name = book.strip_prefix(repo()).unwrap().display().to_string();
        let script = std::fs::read_to_string(&book).unwrap();
        let block = format!("<!-- {name} -->\n```sh\n{script}```\n");
        assert!(
            page.contains(&block),
            "docs/deployment.md lacks {name} as written (the block must follow `<!-- {name} -->`)"
        );
    }
}

/// The ports a runbook uses, each a free one.
struct Ports(Vec<(&'static str, u16)>);

impl Ports {
    fn free() -> Ports {
        let mut ports: Vec<_> = ["P_FC", "P_CC", "P_MAVPROXY", "P_MAVSDK", "P_AUTONOMY"]
            .into_iter()
            .map(|var| (var, free_port()))
            .collect();
        ports.push(("P_GRPC", free_tcp_port()));
        Ports(ports)
    }
}

/// `bash docs/runbooks/NAME` with `dirs` first on PATH, then `fbwag`'s
/// and the peers' Python's directories: its exit status and output.
fn run_script(name: &str, dirs: &[PathBuf], ports: &Ports) -> (bool, String) {
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_fbwag"));
    let mut first: Vec<PathBuf> = dirs.to_vec();
    first.push(bin.parent().unwrap().to_path_buf());
    if let Some(py) = peer_python() {
        first.push(py.parent().unwrap().to_path_buf());
    }
    let path = std::env::join_paths(first.into_iter().chain(std::env::split_paths(
        &std::env::var_os("PATH").unwrap_or_default(),
    )))
    .unwrap();
    let mut cmd = Command::new("timeout");
    cmd.args(["150", "bash"])
        .arg(repo().join("docs/runbooks").join(name))
        .current_dir(repo())
        .env("PATH", path);
    if let Some(py) = peer_python() {
        cmd.env("PYTHON", py);
    }
    for (var, port) in &ports.0 {
        cmd.env(var, port.to_string());
    }
    let out = cmd.output().expect("bash");
    let log = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    (out.status.success(), log)
}

/// Runs a runbook `times` times back to back on the same ports: each run
/// waits for its programs to exit, so the next finds its ports free.
fn run_times(name: &str, times: usize) {
    if peer_python().is_none() {
        return;
    }
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let ports = Ports::free();
    for round in 1..=times {
        let started = Instant::now();
        let (passed, log) = run_script(name, &[], &ports);
        assert!(
            passed && log.contains("runbook passed"),
            "{name} (run {round}) failed after {:?}:\n{log}",
            started.elapsed()
        );
        assert!(started.elapsed() < Duration::from_secs(150));
    }
}

fn run(name: &str) {
    run_times(name, 1);
}

/// A runbook that fails prints every program's log, not only the one
/// whose line it missed: here the FC never starts (a stand-in `fbwag`
/// answers `fc-sim`), and the companion's log says why nothing happened.
#[test]
fn a_failing_runbook_prints_every_log() {
    let dir = std::env::temp_dir().join(format!("fbwag-shim-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let shim = dir.join("fbwag");
    std::fs::write(
        &shim,
        format!(
            "#!/bin/sh\nif [ \"$1\" = fc-sim ]; then echo 'no FC on this bench'; exit 0; fi\nexec {} \"$@\"\n",
            env!("CARGO_BIN_EXE_fbwag")
        ),
    )
    .unwrap();
    use std::os::unix::fs::PermissionsExt;
    std::fs::set_permissions(&shim, std::fs::Permissions::from_mode(0o755)).unwrap();
    let started = Instant::now();
    let (passed, log) = run_script(
        "direct-signed.sh",
        std::slice::from_ref(&dir),
        &Ports::free(),
    );
    std::fs::remove_dir_all(&dir).ok();
    assert!(!passed, "{log}");
    assert!(log.contains("FAILED: no 'MODE CHANGE"), "{log}");
    assert!(log.contains("/fc.log\nno FC on this bench"), "{log}");
    assert!(log.contains("/cc.log\n"), "{log}");
    assert!(
        log.contains("cc: FC link udpin"),
        "the companion's own lines: {log}"
    );
    // The trap stopped the companion (its --duration is 12 s) and waited.
    assert!(
        started.elapsed() < Duration::from_secs(10),
        "{:?}",
        started.elapsed()
    );
}

#[test]
fn runbook_direct_signed_back_to_back() {
    run_times("direct-signed.sh", 2);
}

#[test]
fn runbook_mavproxy_between() {
    run("mavproxy-between.sh");
}

#[test]
fn runbook_cc_routes() {
    run("cc-routes.sh");
}

#[test]
fn runbook_mavsdk_trusted_out() {
    run("mavsdk-trusted-out.sh");
}

#[test]
fn runbook_autonomy() {
    run("autonomy.sh");
}

/// No runbook goes untested: each script has its test above.
#[test]
fn every_runbook_has_a_test() {
    let source = include_str!("runbooks.rs");
    for book in runbooks() {
        let name = book.file_name().unwrap().to_str().unwrap().to_string();
        assert!(
            source.contains(&format!("run(\"{name}\")"))
                || source.contains(&format!("run_times(\"{name}\"")),
            "{name} has no test"
        );
    }
}
