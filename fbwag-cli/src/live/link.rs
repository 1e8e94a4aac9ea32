//! One daemon's MAVLink link, hardened: no send or receive error ends the
//! program, receive work per loop iteration is bounded, a `udpin` link
//! answers only the authenticated peer, and reports of untrusted traffic
//! are rate-limited with counts.
//!
//! The peer rule of `udpin` (what `fbwag cc --help` and docs/delegation.md
//! state): with `--peer ADDR`, frames go to ADDR only. Without it, nothing
//! is sent until a frame the engine trusts arrives (the configured peer's
//! ids, and a verified signature when signing is required); from then on
//! frames go to that frame's source address. A trusted frame from another
//! address moves the peer there only when its signature verified, or when
//! the current peer has been silent for [`PEER_SILENCE`] (an unsigned peer
//! that restarted on a new port). Frames from anyone else never redirect
//! anything.

use super::{Clock, Limiter, Log, PeerPin};
use fbwag_delegation::engine::Verdict;
use fbwag_dialect::mavframe::conn::{AnyTransport, Endpoint, ReplyTo};
use fbwag_dialect::mavframe::parser::Stats;
use fbwag_dialect::mavframe::signing::state::{Loaded, SigningState, StateFile};
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{Connection, Parser, ReceivedFrame, Verifier};
use std::io;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::{Duration, Instant as WallInstant};

/// An unsigned `udpin` peer silent this long may be replaced by another
/// source of trusted frames.
pub const PEER_SILENCE: Duration = Duration::from_secs(3);

/// Frames handled per loop iteration before the daemon services its
/// timers again: a flood delays the protocol's timers by at most this many
/// frames' work.
pub const RECV_BUDGET: usize = 64;

/// How often a link that failed (TCP peer gone, serial port unplugged) is
/// opened again.
const REOPEN_INTERVAL: Duration = Duration::from_secs(1);

/// How often the parser's counters (bad checksums, bad signatures, unsigned
/// frames refused) are summarised in the log, when they changed.
const STATS_INTERVAL: Duration = Duration::from_secs(5);

/// The settings of a link.
#[derive(Debug, Clone)]
pub struct LinkOptions {
    /// Where to connect or listen.
    pub endpoint: Endpoint,
    /// Sign what is sent and verify what comes with this key.
    pub key: Option<[u8; 32]>,
    /// `udpin` only: answer this address and no other.
    pub peer: Option<SocketAddr>,
    /// Keep the signer's and verifier's timestamps across restarts in this
    /// file (with `key`).
    pub signing_state: Option<PathBuf>,
}

/// A daemon's link.
pub struct Link {
    opts: LinkOptions,
    conn: Option<Connection>,
    /// The state file, and the signing state of a connection that failed
    /// (its replacement starts from it, not from nothing).
    state_file: Option<StateFile>,
    carried: SigningState,
    reopen_at: WallInstant,
    pin: PeerPin,
    send_errors: Limiter,
    recv_errors: Limiter,
    untrusted: Limiter,
    stats_seen: Stats,
    stats_at: WallInstant,
}

impl Link {
    /// Opens the link now: errors here (address in use, no such device)
    /// end the program before it starts; later errors never do.
    pub fn open(opts: LinkOptions, log: &mut Log) -> io::Result<Link> {
        let state_file = match (&opts.signing_state, opts.key) {
            (Some(path), Some(_)) => {
                let (file, loaded) = StateFile::open(path).map_err(|e| {
                    io::Error::other(format!(
                        "signing state {}: {e}; remove the file to start from the clock",
                        path.display()
                    ))
                })?;
                log.line(&match loaded {
                    Loaded::Existing => format!(
                        "signing state: loaded {} ({} streams)",
                        path.display(),
                        file.state().streams.len()
                    ),
                    Loaded::Fresh => format!(
                        "signing state: no file at {} yet, starting from the clock",
                        path.display()
                    ),
                });
                Some(file)
            }
            (Some(_), None) => {
                return Err(io::Error::new(
                    io::ErrorKind::InvalidInput,
                    "a signing state file needs a signing key",
                ))
            }
            (None, _) => None,
        };
        let carried = state_file
            .as_ref()
            .map_or_else(SigningState::default, |f| f.state().clone());
        let conn = connect(&opts, &carried)
            .map_err(|e| io::Error::new(e.kind(), format!("cannot open {}: {e}", opts.endpoint)))?;
        Ok(Link {
            opts,
            conn: Some(conn),
            state_file,
            carried,
            reopen_at: WallInstant::now(),
            pin: PeerPin::default(),
            send_errors: Limiter::new(5, Duration::from_secs(10)),
            recv_errors: Limiter::new(5, Duration::from_secs(10)),
            untrusted: Limiter::new(5, Duration::from_secs(10)),
            stats_seen: Stats::default(),
            stats_at: WallInstant::now(),
        })
    }

    /// Sends `msg` as `sysid`/`compid`; a failure is logged (rate-limited)
    /// and dropped: one unreachable peer never stops the daemon.
    pub fn send(&mut self, sysid: u8, compid: u8, msg: &dyn Encode, log: &mut Log) {
        let Some(conn) = &mut self.conn else {
            return;
        };
        if let Err(e) = conn.send_auto(sysid, compid, msg) {
            self.send_errors.log(log, "send errors", || {
                format!("send of {} failed: {e}", msg.meta().name)
            });
            if breaks_link(&self.opts.endpoint, &e) {
                self.drop_connection();
            }
        }
    }

    /// Drops a failed connection, keeping its signing state for the next.
    fn drop_connection(&mut self) {
        if let Some(conn) = self.conn.take() {
            self.carried = SigningState::capture(conn.signer(), conn.parser().verifier());
        }
        self.reopen_at = WallInstant::now() + REOPEN_INTERVAL;
    }

    /// Saves the signing state when due (cheap: call every iteration), or
    /// now with `force` (at exit). Failures are logged, never fatal.
    pub fn save_signing_state(&mut self, force: bool, log: &mut Log) {
        let (Some(file), Some(conn)) = (&mut self.state_file, &self.conn) else {
            return;
        };
        if !force && !file.due(conn.signer()) {
            return;
        }
        match file.save(conn.signer(), conn.parser().verifier()) {
            Ok(_) if force => {
                log.line(&format!("signing state saved to {}", file.path().display()))
            }
            Ok(_) => {}
            Err(e) => self.send_errors.log(log, "state file errors", || {
                format!(
                    "cannot save the signing state to {}: {e}",
                    file.path().display()
                )
            }),
        }
    }

    /// The next frame, waiting up to `wait`; `None` when none came (or the
    /// link failed: logged, and reopened later).
    pub fn recv(&mut self, wait: Duration, log: &mut Log) -> Option<ReceivedFrame> {
        self.report_stats(log);
        let Some(conn) = &mut self.conn else {
            self.reopen(log);
            // Nothing to read from: wait as asked, without spinning.
            std::thread::sleep(wait.min(Duration::from_millis(50)));
            return None;
        };
        match conn.recv(Some(wait)) {
            Ok(frame) => frame,
            Err(e) => {
                self.recv_errors
                    .log(log, "receive errors", || format!("receive failed: {e}"));
                if breaks_link(&self.opts.endpoint, &e) {
                    self.drop_connection();
                } else {
                    // A transient error: do not spin on it.
                    std::thread::sleep(Duration::from_millis(10).min(wait));
                }
                None
            }
        }
    }

    /// What the engine made of `frame`: a trusted frame may pin a `udpin`
    /// link's peer (see the module docs); untrusted ones are logged,
    /// rate-limited.
    pub fn judged(&mut self, frame: &ReceivedFrame, verdict: Verdict, log: &mut Log) {
        let source = self.conn.as_ref().and_then(|c| c.transport().last_source());
        match verdict {
            Verdict::Trusted => {
                if let Some(source) = source {
                    self.trusted_source(source, frame.is_authenticated(), log);
                }
            }
            Verdict::Untrusted => self.untrusted.log(log, "untrusted frames", || {
                let h = frame.header();
                format!(
                    "ignored {} from {}/{}{}{}",
                    frame.meta().map_or("an unknown message", |m| m.name),
                    h.sysid,
                    h.compid,
                    if frame.is_authenticated() {
                        ", signed"
                    } else {
                        ", not authenticated"
                    },
                    source.map_or(String::new(), |s| format!(" ({s})")),
                )
            }),
        }
    }

    fn trusted_source(&mut self, source: SocketAddr, authenticated: bool, log: &mut Log) {
        let Some(AnyTransport::UdpIn(udp)) = self.conn.as_mut().map(|c| c.transport_mut()) else {
            return;
        };
        if udp.reply_to() != ReplyTo::Pinned {
            return;
        }
        if let Some(peer) = self.pin.trusted(source, authenticated) {
            udp.set_peer(peer);
            log.line(&format!("answering {peer} (trusted peer)"));
        }
    }

    /// Opens a failed link again, at most every [`REOPEN_INTERVAL`].
    fn reopen(&mut self, log: &mut Log) {
        if WallInstant::now() < self.reopen_at {
            return;
        }
        self.reopen_at = WallInstant::now() + REOPEN_INTERVAL;
        match connect(&self.opts, &self.carried) {
            Ok(conn) => {
                log.line(&format!("link {} open again", self.opts.endpoint));
                self.conn = Some(conn);
                self.pin.reset();
            }
            Err(e) => self.recv_errors.log(log, "receive errors", || {
                format!("cannot open {} again: {e}", self.opts.endpoint)
            }),
        }
    }

    /// Summarises what the parser refused since the last summary.
    fn report_stats(&mut self, log: &mut Log) {
        if self.stats_at.elapsed() < STATS_INTERVAL {
            return;
        }
        self.stats_at = WallInstant::now();
        let Some(conn) = &self.conn else {
            return;
        };
        let (now, was) = (*conn.stats(), self.stats_seen);
        self.stats_seen = now;
        let delta = [
            ("bad checksums", now.bad_crc - was.bad_crc),
            ("bad signatures", now.bad_signature - was.bad_signature),
            (
                "unsigned refused",
                now.unsigned_rejected - was.unsigned_rejected,
            ),
            ("bytes dropped", now.bytes_dropped - was.bytes_dropped),
        ];
        let parts: Vec<String> = delta
            .iter()
            .filter(|(_, n)| *n > 0)
            .map(|(what, n)| format!("{n} {what}"))
            .collect();
        if !parts.is_empty() {
            log.line(&format!(
                "link refused in the last {} s: {}",
                STATS_INTERVAL.as_secs(),
                parts.join(", ")
            ));
        }
    }
}

/// Opens the connection: with a key, it signs what it sends and verifies
/// what comes (unsigned frames still arrive, marked unauthenticated: whether
/// they count is the engine's trust rule). The verifier starts from the
/// clock, so a capture older than the signing window (one minute) replayed
/// into a freshly started daemon is refused, and from `state` (the state
/// file's, or a failed connection's), so a replay of anything it accepted
/// before is refused too; the signer resumes after anything it may have
/// sent.
fn connect(opts: &LinkOptions, state: &SigningState) -> io::Result<Connection> {
    let mut transport = fbwag_dialect::mavframe::conn::open(&opts.endpoint)?;
    if let AnyTransport::UdpIn(udp) = &mut transport {
        udp.set_reply_to(opts.peer.map_or(ReplyTo::Pinned, ReplyTo::Fixed));
    }
    let Some(key) = opts.key else {
        return Ok(Connection::new(transport));
    };
    let verifier: Verifier = state.verifier(key);
    let mut conn = Connection::with_parser(transport, Parser::with_signing(verifier, true));
    conn.set_signer(Some(state.signer(key, 0)));
    Ok(conn)
}

/// Whether an error means the link is gone (a TCP peer closed, a serial
/// port vanished) rather than one datagram failing.
fn breaks_link(endpoint: &Endpoint, e: &io::Error) -> bool {
    let stream = matches!(endpoint, Endpoint::Tcp(_) | Endpoint::Serial { .. });
    stream
        && matches!(
            e.kind(),
            io::ErrorKind::UnexpectedEof
                | io::ErrorKind::ConnectionReset
                | io::ErrorKind::ConnectionAborted
                | io::ErrorKind::BrokenPipe
                | io::ErrorKind::NotConnected
                | io::ErrorKind::NotFound
        )
}

/// The loop every daemon runs: timers when due, then frames until the next
/// deadline, at most [`RECV_BUDGET`] of them, then timers again. So neither
/// the receiver sampling nor the protocol's timers can be starved by a
/// flood, and the daemon never sleeps past a deadline.
pub trait Node {
    /// When [`Node::handle_timeout`] must next run.
    fn poll_timeout(&self) -> Option<fbwag_delegation::Instant>;
    /// Timers due at `now`.
    fn handle_timeout(&mut self, now: fbwag_delegation::Instant, link: &mut Link, log: &mut Log);
    /// One received frame.
    fn handle_frame(
        &mut self,
        now: fbwag_delegation::Instant,
        frame: &ReceivedFrame,
        link: &mut Link,
        log: &mut Log,
    ) -> Verdict;
    /// True when the daemon should stop.
    fn done(&self, clock: &Clock) -> bool;
}

/// Runs `node` on `link` until it is done.
pub fn run(node: &mut impl Node, link: &mut Link, clock: &Clock, log: &mut Log) {
    // The longest wait without looking at the clock: `done` is checked at
    // least this often.
    const MAX_WAIT: Duration = Duration::from_millis(100);
    while !node.done(clock) {
        link.save_signing_state(false, log);
        let now = clock.now();
        if node.poll_timeout().is_some_and(|t| t <= now) {
            node.handle_timeout(now, link, log);
        }
        let deadline = node
            .poll_timeout()
            .map_or(MAX_WAIT, |t| clock.until(t).min(MAX_WAIT));
        let until = WallInstant::now() + deadline;
        let mut wait = deadline;
        for _ in 0..RECV_BUDGET {
            let Some(frame) = link.recv(wait, log) else {
                break;
            };
            let verdict = node.handle_frame(clock.now(), &frame, link, log);
            link.judged(&frame, verdict, log);
            // The rest of this iteration's frames only if already there.
            wait = Duration::ZERO;
            if WallInstant::now() >= until {
                break;
            }
        }
    }
    link.save_signing_state(true, log);
}
