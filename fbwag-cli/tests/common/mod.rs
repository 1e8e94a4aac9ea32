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

/// A child process the test started: killed when dropped (also on a
/// panic), so no test leaves processes behind.
pub struct Proc(Option<std::process::Child>);

impl Proc {
    /// Starts `cmd` with its output captured.
    pub fn spawn(cmd: &mut Command) -> Proc {
        let child = cmd
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .expect("spawn");
        Proc(Some(child))
    }

    /// Waits up to `limit` for it to end by itself, then kills it; its
    /// output either way.
    pub fn finish(mut self, limit: std::time::Duration) -> std::process::Output {
        let mut child = self.0.take().expect("not finished");
        let end = std::time::Instant::now() + limit;
        while std::time::Instant::now() < end {
            if child.try_wait().ok().flatten().is_some() {
                break;
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        let _ = child.kill();
        child.wait_with_output().expect("output")
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        if let Some(mut c) = self.0.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}
