//! Shared by the integration tests: the repository and the pinned Python.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

/// The repository root.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The venv's Python with pymavlink 2.4.50 (made by scripts/python-env.sh).
pub fn python() -> String {
    let out = Command::new("bash")
        .arg(repo().join("scripts/python-env.sh"))
        .output()
        .expect("python-env.sh");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap().trim().to_string()
}
