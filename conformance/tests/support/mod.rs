//! Shared helpers: paths and the pinned pymavlink environment.
// Each test binary uses a different subset of these.
#![allow(dead_code)]

use std::path::PathBuf;
use std::process::Command;

/// The repository root.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .expect("repo root")
}

/// Python of the venv holding pymavlink 2.4.50, created on first use by
/// `scripts/python-env.sh` (cached under `target/`). A missing Python is a
/// test failure, not a skip: the comparison is the point of these tests.
pub fn python() -> PathBuf {
    let out = Command::new("bash")
        .arg(repo().join("scripts/python-env.sh"))
        .output()
        .expect("run scripts/python-env.sh");
    assert!(
        out.status.success(),
        "scripts/python-env.sh failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    PathBuf::from(String::from_utf8(out.stdout).expect("utf-8 path").trim())
}

/// Every XML file in `message_definitions/`, sorted.
pub fn xml_files() -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join("message_definitions"))
        .expect("message_definitions")
        .map(|e| e.expect("dir entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "xml"))
        .collect();
    v.sort();
    v
}

pub mod frames;
pub mod peers;
pub mod streams;
pub mod three_way;
pub mod values;
