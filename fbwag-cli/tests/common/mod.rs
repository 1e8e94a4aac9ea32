//! Shared by the integration tests: the repository, the pinned Pythons,
//! running the binary, free ports, child processes.
#![allow(dead_code)]

pub mod datagrams;
pub mod lines;

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Stdio};

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

    /// Its process id.
    pub fn id(&self) -> u32 {
        self.0.as_ref().map_or(0, std::process::Child::id)
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

/// The peer venv's python (MAVProxy, mavsdk with mavsdk_server, pymavlink
/// with the FBWAG dialect and module), or None, with the reason printed,
/// when the venv cannot be created (no network for pip, no python3-venv).
/// scripts/test.sh creates it in an earlier step and fails there, so under
/// the test command this never skips.
pub fn peer_python() -> Option<PathBuf> {
    let out = Command::new("bash")
        .arg(repo().join("scripts/peer-env.sh"))
        .output()
        .expect("bash scripts/peer-env.sh");
    if !out.status.success() {
        // Written straight to the process's stderr: libtest captures only
        // the print macros, and a skip must be seen.
        let _ = writeln!(
            std::io::stderr(),
            "SKIPPED: the peer venv (MAVProxy, mavsdk) could not be created:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
        return None;
    }
    Some(PathBuf::from(String::from_utf8(out.stdout).unwrap().trim()))
}

/// A free UDP port on 127.0.0.1 (bound then released).
pub fn free_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Waits until something has bound UDP `port` on 127.0.0.1 (a daemon
/// that listens there is up), for 10 s at most; whether it did.
pub fn udp_port_bound(port: u16) -> bool {
    let start = std::time::Instant::now();
    while start.elapsed() < std::time::Duration::from_secs(10) {
        if std::net::UdpSocket::bind(("127.0.0.1", port)).is_err() {
            return true;
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    false
}

/// Runs the binary with `input` on stdin (written from another thread, so
/// a large input cannot deadlock against a full stdout pipe): stdout,
/// stderr, exit code.
pub fn fbwag(args: &[&str], input: &[u8]) -> (Vec<u8>, String, Option<i32>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_fbwag"))
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run fbwag");
    let mut stdin = child.stdin.take().unwrap();
    let data = input.to_vec();
    let writer = std::thread::spawn(move || stdin.write_all(&data));
    let out = child.wait_with_output().unwrap();
    writer.join().unwrap().unwrap();
    (
        out.stdout,
        String::from_utf8_lossy(&out.stderr).into_owned(),
        out.status.code(),
    )
}

/// A free TCP port on every interface (mavsdk_server's gRPC listens on all
/// of them), bound then released.
pub fn free_tcp_port() -> u16 {
    std::net::TcpListener::bind("0.0.0.0:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// The mavsdk_server the pip package `mavsdk` ships, in `py`'s venv.
pub fn mavsdk_server(py: &std::path::Path) -> PathBuf {
    let out = Command::new(py)
        .args(["-W", "ignore::FutureWarning", "-c"])
        .arg("import mavsdk, os; print(os.path.join(os.path.dirname(mavsdk.__file__), 'bin', 'mavsdk_server'))")
        .output()
        .expect("python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    PathBuf::from(String::from_utf8(out.stdout).unwrap().trim())
}
