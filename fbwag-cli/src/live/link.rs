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
//!
//! Each UDP datagram is parsed on its own: whatever partial frame it ends
//! with is flushed, never completed by the next datagram. MAVLink over UDP
//! sends whole frames per datagram, and carrying a partial frame over (what
//! a `Connection` does) let anyone who sends a datagram steer the link: a
//! false header (10 bytes) or a few start bytes held the peer's next frame
//! back until the attacker's next datagram was read, and that frame was
//! then taken as coming from the attacker's address (with signing on, the
//! peer's signed frame moved the answers to the attacker at once). Stream
//! links (TCP, serial) keep partial frames across reads, as they must.

use super::{Clock, Limiter, Log, PeerPin};
use fbwag_delegation::engine::Verdict;
use fbwag_dialect::mavframe::conn::{AnyTransport, Endpoint, ReplyTo, Transport};
use fbwag_dialect::mavframe::frame::MAX_FRAME_LEN;
use fbwag_dialect::mavframe::parser::Stats;
use fbwag_dialect::mavframe::signing::state::{Loaded, SigningState, StateFile};
use fbwag_dialect::mavframe::signing::timestamp_now;
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Header, Parser, ReceivedFrame, Signer, Verifier, Version};
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

/// A daemon's link: the transport, its parser and the sending state. Not a
/// `Connection`, which keeps a partial frame across datagrams (see the
/// module docs).
pub struct Link {
    opts: LinkOptions,
    transport: Option<AnyTransport>,
    rx: Rx,
    tx: Tx,
    reopen_at: WallInstant,
    pin: PeerPin,
    state_file: Option<StateFile>,
    send_errors: Limiter,
    recv_errors: Limiter,
    untrusted: Limiter,
    stats_seen: Stats,
    stats_at: WallInstant,
}

/// The receive side: the parser, and the bytes of the last read not parsed
/// yet.
struct Rx {
    parser: Parser,
    buf: Box<[u8]>,
    start: usize,
    end: usize,
    /// The last read was a datagram whose end the parser has not been told
    /// about yet.
    datagram_open: bool,
    /// The sender of the bytes being parsed (UDP), hence of every frame
    /// found in them.
    source: Option<SocketAddr>,
}

/// The send side: sequence number, signer, one frame's buffer.
struct Tx {
    seq: u8,
    signer: Option<Signer>,
    buf: [u8; MAX_FRAME_LEN],
}

/// A whole UDP datagram fits (65,507 bytes at most).
const RECV_BUFFER_LEN: usize = 64 * 1024;

/// Bytes parsed per [`Link::recv`] call before the daemon services its
/// timers again: however long the parser takes per byte (its worst input
/// cost ~4 µs a byte before issue 10 item 2, 100 µs unoptimised), one
/// large datagram cannot hold the receiver sampling and the protocol's
/// timers back for more than this many bytes' work. Four of the longest
/// frames.
const PARSE_CHUNK: usize = 1024;

impl Link {
    /// Opens the link now: errors here (address in use, no such device)
    /// end the program before it starts; later errors never do.
    pub fn open(opts: LinkOptions, log: &mut Log) -> io::Result<Link> {
        let state_file = open_state_file(&opts, log)?;
        let transport = connect(&opts)
            .map_err(|e| io::Error::new(e.kind(), format!("cannot open {}: {e}", opts.endpoint)))?;
        // The verifier starts from the clock, so a capture older than the
        // signing window (one minute) replayed into a freshly started
        // daemon is refused, and from the state file, so a replay of
        // anything accepted before a restart is refused too; the signer
        // resumes after anything it may have sent. Unsigned frames still
        // arrive, marked unauthenticated: whether they count is the
        // engine's trust rule.
        let state = state_file
            .as_ref()
            .map_or_else(SigningState::default, |f| f.state().clone());
        let (parser, signer) = match opts.key {
            Some(key) => {
                let verifier: Verifier = state.verifier(key);
                (
                    Parser::with_signing(verifier, true),
                    Some(state.signer(key, 0)),
                )
            }
            None => (Parser::new(), None),
        };
        Ok(Link {
            opts,
            transport: Some(transport),
            rx: Rx {
                parser,
                buf: vec![0u8; RECV_BUFFER_LEN].into_boxed_slice(),
                start: 0,
                end: 0,
                datagram_open: false,
                source: None,
            },
            tx: Tx {
                seq: 0,
                signer,
                buf: [0; MAX_FRAME_LEN],
            },
            reopen_at: WallInstant::now(),
            pin: PeerPin::default(),
            state_file,
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
        let Some(transport) = &mut self.transport else {
            return;
        };
        let result = self
            .tx
            .frame(sysid, compid, msg)
            .and_then(|f| transport.send(f));
        if let Err(e) = result {
            self.send_errors.log(log, "send errors", || {
                format!("send of {} failed: {e}", msg.meta().name)
            });
            if breaks_link(&self.opts.endpoint, &e) {
                self.transport = None;
            }
        }
    }

    /// The next frame, waiting up to `wait`; `None` when none came (or the
    /// link failed: logged, and reopened later). At most one datagram (or
    /// one read of a stream) is taken from the transport per call, so a
    /// flood of datagrams without frames returns to the caller's timers
    /// after each.
    pub fn recv(&mut self, wait: Duration, log: &mut Log) -> Option<ReceivedFrame> {
        self.report_stats(log);
        if let Some(frame) = self.rx.next() {
            return Some(frame);
        }
        if self.rx.pending() {
            // The rest of the last read waits for the next call: timers
            // first.
            return None;
        }
        let Some(transport) = &mut self.transport else {
            self.reopen(log);
            // Nothing to read from: wait as asked, without spinning.
            std::thread::sleep(wait.min(Duration::from_millis(50)));
            return None;
        };
        match transport.recv(&mut self.rx.buf, Some(wait)) {
            Ok(0) => None,
            Ok(n) => {
                let datagram =
                    matches!(transport, AnyTransport::UdpIn(_) | AnyTransport::UdpOut(_));
                self.rx.filled(n, datagram, transport.last_source());
                self.rx.next()
            }
            Err(e) => {
                self.recv_errors
                    .log(log, "receive errors", || format!("receive failed: {e}"));
                if breaks_link(&self.opts.endpoint, &e) {
                    self.transport = None;
                    self.reopen_at = WallInstant::now() + REOPEN_INTERVAL;
                } else {
                    // A transient error: do not spin on it.
                    std::thread::sleep(Duration::from_millis(10).min(wait));
                }
                None
            }
        }
    }

    /// What the engine made of `frame` (the one [`Link::recv`] returned
    /// last): a trusted frame may pin a `udpin` link's peer (see the module
    /// docs); untrusted ones are logged, rate-limited.
    pub fn judged(&mut self, frame: &ReceivedFrame, verdict: Verdict, log: &mut Log) {
        let source = self.rx.source;
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
        let Some(AnyTransport::UdpIn(udp)) = self.transport.as_mut() else {
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

    /// Saves the signing state when due (cheap: call every iteration), or
    /// now with `force` (at exit). Failures are logged, never fatal.
    pub fn save_signing_state(&mut self, force: bool, log: &mut Log) {
        let Some(file) = &mut self.state_file else {
            return;
        };
        let signer = self.tx.signer.as_ref();
        if !force && !file.due(signer) {
            return;
        }
        match file.save(signer, self.rx.parser.verifier()) {
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

    /// Opens a failed link again, at most every [`REOPEN_INTERVAL`]. The
    /// parser (and its signing streams) is kept; a partial frame of the
    /// old stream is dropped.
    fn reopen(&mut self, log: &mut Log) {
        if WallInstant::now() < self.reopen_at {
            return;
        }
        self.reopen_at = WallInstant::now() + REOPEN_INTERVAL;
        match connect(&self.opts) {
            Ok(transport) => {
                log.line(&format!("link {} open again", self.opts.endpoint));
                self.transport = Some(transport);
                self.rx.restart();
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
        let (now, was) = (*self.rx.parser.stats(), self.stats_seen);
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

impl Rx {
    /// `n` bytes were read into `buf` from `source`; `datagram`: they are
    /// one whole datagram.
    fn filled(&mut self, n: usize, datagram: bool, source: Option<SocketAddr>) {
        self.start = 0;
        self.end = n.min(self.buf.len());
        self.datagram_open = datagram;
        self.source = source;
    }

    /// The next frame in the next [`PARSE_CHUNK`] bytes read; at the end
    /// of a datagram, the frames the parser can still complete from what it
    /// holds, then nothing is held over. `None` with [`Rx::pending`] true:
    /// no frame in this chunk, more bytes to parse.
    fn next(&mut self) -> Option<ReceivedFrame> {
        if self.start < self.end {
            let stop = self.end.min(self.start + PARSE_CHUNK);
            let mut input = &self.buf[self.start..stop];
            let got = self
                .parser
                .next(&mut input)
                .map(|r| ReceivedFrame::from(&r));
            self.start = stop - input.len();
            if got.is_some() {
                return got;
            }
            // The parser consumes its whole input before it says None.
            self.start = stop;
            if self.start < self.end {
                return None;
            }
        }
        if self.datagram_open {
            if let Some(r) = self.parser.flush() {
                return Some(ReceivedFrame::from(&r));
            }
            self.datagram_open = false;
        }
        None
    }

    /// Bytes read and not parsed yet, or a datagram not flushed yet: the
    /// transport must not be read (it would overwrite them).
    fn pending(&self) -> bool {
        self.start < self.end || self.datagram_open
    }

    /// A new stream: nothing read before belongs to it.
    fn restart(&mut self) {
        self.start = 0;
        self.end = 0;
        self.datagram_open = false;
        self.source = None;
        while self.parser.flush().is_some() {}
    }
}

impl Tx {
    /// `msg` framed with the next sequence number (which advances whether
    /// or not the send succeeds: a receiver counts a failed send as lost),
    /// signed when a key is set.
    fn frame(&mut self, sysid: u8, compid: u8, msg: &dyn Encode) -> io::Result<&[u8]> {
        let header = Header {
            seq: self.seq,
            sysid,
            compid,
        };
        self.seq = self.seq.wrapping_add(1);
        if let Some(signer) = &mut self.signer {
            // Keep up with the clock (receivers drop a stream that falls
            // more than a minute behind the newest timestamp they saw).
            signer.advance_to(timestamp_now());
        }
        let n = encode(
            Version::V2,
            header,
            msg,
            self.signer.as_mut(),
            &mut self.buf,
        )
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidInput, e))?;
        Ok(&self.buf[..n])
    }
}

/// The link's signing state file, loaded (or a fresh one); a damaged file
/// stops the program (it could mean tampering: dropping it silently would
/// reopen replays).
fn open_state_file(opts: &LinkOptions, log: &mut Log) -> io::Result<Option<StateFile>> {
    let (Some(path), Some(_)) = (&opts.signing_state, opts.key) else {
        return match opts.signing_state {
            Some(_) => Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "a signing state file needs a signing key",
            )),
            None => Ok(None),
        };
    };
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
    Ok(Some(file))
}

/// Opens the transport; a `udpin` one answers `--peer`, or else only the
/// peer this link pins.
fn connect(opts: &LinkOptions) -> io::Result<AnyTransport> {
    let mut transport = fbwag_dialect::mavframe::conn::open(&opts.endpoint)?;
    if let AnyTransport::UdpIn(udp) = &mut transport {
        udp.set_reply_to(opts.peer.map_or(ReplyTo::Pinned, ReplyTo::Fixed));
    }
    Ok(transport)
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
