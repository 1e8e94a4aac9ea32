//! Shared inputs for the benchmarks: the telemetry capture made by
//! `benches/scripts/make_telemetry.py` (pymavlink 2.4.50), cached under
//! `target/bench-data/`.

use std::path::PathBuf;
use std::process::Command;

/// The repository root.
pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The capture's bytes, made on first use (seed 1, default size ~4 MB).
pub fn telemetry() -> Vec<u8> {
    let path = repo().join("target/bench-data/telemetry.bin");
    if !path.exists() {
        std::fs::create_dir_all(path.parent().expect("parent")).expect("create target/bench-data");
        let py = Command::new("bash")
            .arg(repo().join("scripts/python-env.sh"))
            .output()
            .expect("python-env.sh");
        assert!(
            py.status.success(),
            "python-env.sh: {}",
            String::from_utf8_lossy(&py.stderr)
        );
        let python = String::from_utf8(py.stdout)
            .expect("utf-8")
            .trim()
            .to_string();
        let status = Command::new(python)
            .arg(repo().join("benches/scripts/make_telemetry.py"))
            .arg("-o")
            .arg(&path)
            .status()
            .expect("make_telemetry.py");
        assert!(status.success(), "make_telemetry.py failed");
    }
    std::fs::read(&path).expect("read capture")
}
