//! The signals that stop a daemon as at the end of its run.

use super::Log;

/// SIGTERM (`kill`, `systemctl stop`) and SIGINT (Ctrl-C, `kill -INT`),
/// and SIGHUP (the terminal closed, the ssh session dropped) when standard
/// input is a terminal: the daemon stops as at the end of its run (exit
/// status 0, its summary event written, its log and telemetry log
/// flushed, its links saving their signing state); a second signal ends
/// it at once. (Killed by any of them, it skipped that save: with
/// `--signing-state`, what it had accepted since the last periodic save
/// could be replayed into it once restarted.) SIGHUP is left alone
/// otherwise: a daemon `nohup` starts inherits it ignored, and keeps
/// running when its terminal goes.
pub struct StopSignals {
    #[cfg(unix)]
    interrupt: Option<tokio::signal::unix::Signal>,
    #[cfg(unix)]
    hangup: Option<tokio::signal::unix::Signal>,
    #[cfg(unix)]
    terminate: Option<tokio::signal::unix::Signal>,
}

impl StopSignals {
    pub fn new(enabled: bool, log: &mut Log) -> Self {
        #[cfg(unix)]
        {
            use std::io::IsTerminal;
            use tokio::signal::unix::{signal, SignalKind};
            let mut listen = |kind: SignalKind, name: &str| {
                signal(kind)
                    .map_err(|e| {
                        log.warn(&format!(
                            "cannot handle {name} ({e}): it ends the daemon unsaved"
                        ))
                    })
                    .ok()
            };
            let interactive = std::io::stdin().is_terminal();
            StopSignals {
                interrupt: enabled
                    .then(|| listen(SignalKind::interrupt(), "SIGINT"))
                    .flatten(),
                hangup: (enabled && interactive)
                    .then(|| listen(SignalKind::hangup(), "SIGHUP"))
                    .flatten(),
                terminate: enabled
                    .then(|| listen(SignalKind::terminate(), "SIGTERM"))
                    .flatten(),
            }
        }
        #[cfg(not(unix))]
        {
            let _ = (enabled, log);
            StopSignals {}
        }
    }

    /// Watches the signals from a task of its own: the first signal's name
    /// is sent to the receiver returned (a daemon's loop polls only that);
    /// a second one ends the process at once (exit status 128 + the
    /// signal's number: 130 for SIGINT, 129 for SIGHUP, 143 for SIGTERM),
    /// whatever the daemon is doing: the user does not wait.
    pub fn watch(mut self) -> tokio::sync::oneshot::Receiver<&'static str> {
        let (first, stopped) = tokio::sync::oneshot::channel();
        tokio::spawn(async move {
            let _ = first.send(self.recv().await);
            let again = self.recv().await;
            std::process::exit(match again {
                "SIGINT" => 130,
                "SIGHUP" => 129,
                _ => 143,
            });
        });
        stopped
    }

    /// The name of the next stop signal received (never, without them).
    async fn recv(&mut self) -> &'static str {
        #[cfg(unix)]
        {
            async fn next(s: &mut Option<tokio::signal::unix::Signal>) {
                match s {
                    // (`None`: the runtime is going away; nothing more.)
                    Some(s) => {
                        if s.recv().await.is_none() {
                            std::future::pending::<()>().await;
                        }
                    }
                    None => std::future::pending().await,
                }
            }
            tokio::select! {
                _ = next(&mut self.interrupt) => "SIGINT",
                _ = next(&mut self.hangup) => "SIGHUP",
                _ = next(&mut self.terminate) => "SIGTERM",
            }
        }
        #[cfg(not(unix))]
        std::future::pending().await
    }
}
