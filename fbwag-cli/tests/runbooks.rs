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

fn run(name: &str) {
    let Some(py) = peer_python() else {
        return;
    };
    let _one = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_fbwag"));
    let path = std::env::join_paths(
        [bin.parent().unwrap(), py.parent().unwrap()]
            .into_iter()
            .map(PathBuf::from)
            .chain(std::env::split_paths(
                &std::env::var_os("PATH").unwrap_or_default(),
            )),
    )
    .unwrap();
    let mut cmd = Command::new("timeout");
    cmd.args(["150", "bash"])
        .arg(repo().join("docs/runbooks").join(name))
        .current_dir(repo())
        .env("PATH", path)
        .env("PYTHON", &py);
    for var in ["P_FC", "P_CC", "P_MAVPROXY", "P_MAVSDK", "P_AUTONOMY"] {
        cmd.env(var, free_port().to_string());
    }
    cmd.env("P_GRPC", free_tcp_port().to_string());
    let started = Instant::now();
    let out = cmd.output().expect("bash");
    let log = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success() && log.contains("runbook passed"),
        "{name} failed after {:?}:\n{log}",
        started.elapsed()
    );
    assert!(started.elapsed() < Duration::from_secs(150));
}

#[test]
fn runbook_direct_signed() {
    run("direct-signed.sh");
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
            source.contains(&format!("run(\"{name}\")")),
            "{name} has no test"
        );
    }
}
