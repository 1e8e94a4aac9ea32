//! A child process whose output is read line by line as it comes, for
//! tests that wait for what a peer (MAVProxy, mavsdk_server, a daemon) says.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::thread;
use std::time::{Duration, Instant};

/// A started process whose stdout and stderr lines arrive on a channel. It
/// is killed when dropped, unless it already exited.
pub struct LineProc {
    pub child: Child,
    lines: Receiver<String>,
    /// Every line read so far.
    pub log: String,
}

impl LineProc {
    pub fn spawn(name: &str, cmd: &mut Command) -> LineProc {
        let mut child = cmd
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("starting {name}: {e}"));
        let (tx, lines) = channel();
        let out = child.stdout.take().unwrap();
        let err = child.stderr.take().unwrap();
        for stream in [Box::new(out) as Box<dyn Read + Send>, Box::new(err)] {
            let tx = tx.clone();
            thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    if tx.send(line).is_err() {
                        break;
                    }
                }
            });
        }
        LineProc {
            child,
            lines,
            log: String::new(),
        }
    }

    /// Collect lines until one contains `pat` (true) or the deadline passes
    /// or the process ends (false).
    pub fn wait_for(&mut self, pat: &str, within: Duration) -> bool {
        if self.log.contains(pat) {
            return true;
        }
        let end = Instant::now() + within;
        loop {
            let left = end.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(line) => {
                    self.log.push_str(&line);
                    self.log.push('\n');
                    if line.contains(pat) {
                        return true;
                    }
                }
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => return false,
            }
        }
    }

    /// Wait for the process to exit by itself (false if the deadline passed:
    /// it is then killed) and collect all of its output.
    pub fn wait_exit(&mut self, within: Duration) -> bool {
        let end = Instant::now() + within;
        let exited = loop {
            if let Ok(Some(_)) = self.child.try_wait() {
                break true;
            }
            if Instant::now() >= end {
                break false;
            }
            thread::sleep(Duration::from_millis(50));
        };
        self.stop();
        exited
    }

    /// Whether the process is still running.
    pub fn alive(&mut self) -> bool {
        matches!(self.child.try_wait(), Ok(None))
    }

    /// Kill (if running) and collect the rest of the output.
    pub fn stop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        // The readers end at EOF, once the pipes close.
        while let Ok(line) = self.lines.recv_timeout(Duration::from_secs(2)) {
            self.log.push_str(&line);
            self.log.push('\n');
        }
    }

    pub fn stdin(&mut self) -> ChildStdin {
        self.child.stdin.take().expect("stdin was not piped")
    }
}

impl Drop for LineProc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
