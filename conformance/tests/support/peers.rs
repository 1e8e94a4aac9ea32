//! The two other implementations, run as processes: pymavlink 2.4.50
//! (`conformance/pymavlink/wire.py`) and the MAVLink C library
//! (`conformance/c/harness.c`, built by `conformance/scripts/c-lib.sh`).
//! Input and output are whole files: one process per dialect and run.

use super::{python, repo};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Scratch directory for one dialect's run files.
pub fn scratch(dialect: &str, what: &str) -> PathBuf {
    let d = repo()
        .join("target/conformance/run")
        .join(dialect)
        .join(what);
    std::fs::create_dir_all(&d).expect("scratch dir");
    d
}

/// Runs `cmd` with `input` as stdin and returns stdout's lines; panics with
/// stderr on failure.
fn run(mut cmd: Command, input: &Path, what: &str) -> Vec<String> {
    let stdin = std::fs::File::open(input).expect("input file");
    let out = cmd
        .stdin(stdin)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .output()
        .unwrap_or_else(|e| panic!("{what}: cannot run: {e}"));
    assert!(
        out.status.success(),
        "{what} failed ({}):\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .expect("utf-8 output")
        .lines()
        .map(str::to_string)
        .collect()
}

/// The C harness for `dialect`, built (or found cached) by c-lib.sh.
pub fn c_harness(dialect: &str) -> PathBuf {
    let out = Command::new("bash")
        .arg(repo().join("conformance/scripts/c-lib.sh"))
        .arg(dialect)
        .output()
        .expect("run c-lib.sh");
    assert!(
        out.status.success(),
        "conformance/scripts/c-lib.sh {dialect} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    PathBuf::from(String::from_utf8(out.stdout).expect("utf-8").trim())
}

/// `wire.py ARGS < input`.
pub fn pymavlink(args: &[&str], input: &Path) -> Vec<String> {
    let mut cmd = Command::new(python());
    cmd.arg(repo().join("conformance/pymavlink/wire.py"))
        .args(args);
    run(cmd, input, "pymavlink wire.py")
}

/// `harness ARGS < input`.
pub fn c_lib(harness: &Path, args: &[&str], input: &Path) -> Vec<String> {
    let mut cmd = Command::new(harness);
    cmd.args(args);
    run(cmd, input, "C harness")
}
