//! fc-sim's log over MAVLink, as ArduPilot's MAVLink logging backend
//! sends its DataFlash log (LOG_BACKEND_TYPE's MAVLink bit): a
//! REMOTE_LOG_BLOCK_STATUS whose `seqno` is
//! MAV_REMOTE_LOG_DATA_BLOCK_START makes its sender the log's client (if
//! no log is being sent) and starts a log from block 0: the formats
//! ([`super::dataflash::start`]), then the records as they come, cut into
//! 200-byte REMOTE_LOG_DATA_BLOCKs from component MAV_COMP_ID_LOG. A block
//! is kept until the client acknowledges it (status ACK) and sent again
//! 100 ms after it was last sent, or at once when the client NACKs it;
//! MAV_REMOTE_LOG_DATA_BLOCK_STOP, or 10 s without an answer, ends the
//! log. At most [`UNACKED_MAX`] blocks wait for their acknowledgement and
//! [`PENDING_MAX`] bytes for a block: beyond, records are dropped and
//! counted, as ArduPilot drops what its buffer cannot take.
//!
//! Sans-IO: [`RemoteLog::poll`] says which blocks to send now.

use super::dataflash;
use fbwag_delegation::Peer;
use std::collections::VecDeque;

/// The log's component id (MAV_COMP_ID_LOG), as ArduPilot sends from.
pub const LOG_COMPID: u8 = 110;

/// A block's bytes.
pub const BLOCK_LEN: usize = 200;

/// START and STOP, as REMOTE_LOG_BLOCK_STATUS's `seqno`.
pub const START: u32 = 2_147_483_646;
pub const STOP: u32 = 2_147_483_645;

/// Blocks sent and not acknowledged, at most.
pub const UNACKED_MAX: usize = 32;

/// Bytes waiting to fill a block, at most.
pub const PENDING_MAX: usize = 8 * 1024;

/// A block is sent again this long after it was last sent (µs).
const RESEND_AFTER: u64 = 100_000;

/// Blocks sent per poll, at most (new and again together).
const SENT_PER_POLL: usize = 8;

/// Without an answer for this long (µs), the client is gone.
const CLIENT_GONE: u64 = 10_000_000;

/// A block waiting for its acknowledgement.
#[derive(Debug, Clone)]
struct Block {
    seqno: u32,
    data: [u8; BLOCK_LEN],
    /// When last sent (`None`: not yet, or NACKed).
    sent_at: Option<u64>,
}

/// The log being sent, if any.
#[derive(Debug, Default)]
pub struct RemoteLog {
    /// The client (who sent START); `None`: no log being sent.
    to: Option<Peer>,
    next_seqno: u32,
    pending: Vec<u8>,
    unacked: VecDeque<Block>,
    /// The client's last answer (µs).
    answered: u64,
    /// Records dropped: the client too slow, or gone.
    pub dropped: u64,
    /// Blocks sent again.
    pub resent: u64,
}

impl RemoteLog {
    /// The client, while a log is being sent.
    pub fn client(&self) -> Option<Peer> {
        self.to
    }

    /// A REMOTE_LOG_BLOCK_STATUS from `from` at `now` (µs): START begins
    /// a log (its first bytes `start`) unless one is being sent, STOP ends
    /// it; otherwise an ACK or NACK of block `seqno`. True when a log
    /// began.
    pub fn status(&mut self, now: u64, from: Peer, seqno: u32, ack: bool, start: &[u8]) -> bool {
        match (seqno, ack) {
            (START, true) if self.to.is_none() => {
                *self = RemoteLog {
                    to: Some(from),
                    answered: now,
                    pending: start.to_vec(),
                    dropped: self.dropped,
                    resent: self.resent,
                    ..RemoteLog::default()
                };
                return true;
            }
            (START, _) => {}
            (STOP, _) if self.to == Some(from) => self.to = None,
            _ if self.to != Some(from) => {}
            (seqno, true) => {
                self.answered = now;
                self.unacked.retain(|b| b.seqno != seqno);
            }
            (seqno, false) => {
                self.answered = now;
                if let Some(b) = self.unacked.iter_mut().find(|b| b.seqno == seqno) {
                    b.sent_at = None;
                }
            }
        }
        false
    }

    /// Appends a record, while a log is being sent and there is room.
    pub fn record(&mut self, bytes: &[u8]) {
        if self.to.is_none() {
            return;
        }
        if self.pending.len() + bytes.len() > PENDING_MAX {
            self.dropped += 1;
            return;
        }
        self.pending.extend_from_slice(bytes);
    }

    /// The blocks to send at `now` (µs), each with its number: blocks
    /// NACKed or unacknowledged for 100 ms first, then new full ones while
    /// fewer than [`UNACKED_MAX`] wait. A client silent for 10 s ends the
    /// log.
    pub fn poll(&mut self, now: u64) -> Vec<(u32, [u8; BLOCK_LEN])> {
        if self.to.is_none() {
            return Vec::new();
        }
        if now >= self.answered + CLIENT_GONE {
            self.to = None;
            self.unacked.clear();
            return Vec::new();
        }
        let mut out = Vec::new();
        for b in &mut self.unacked {
            if out.len() == SENT_PER_POLL {
                return out;
            }
            if b.sent_at.is_none_or(|t| now >= t + RESEND_AFTER) {
                if b.sent_at.is_some() {
                    self.resent += 1;
                }
                b.sent_at = Some(now);
                out.push((b.seqno, b.data));
            }
        }
        while out.len() < SENT_PER_POLL
            && self.unacked.len() < UNACKED_MAX
            && self.pending.len() >= BLOCK_LEN
        {
            let mut data = [0; BLOCK_LEN];
            data.copy_from_slice(&self.pending[..BLOCK_LEN]);
            self.pending.drain(..BLOCK_LEN);
            let seqno = self.next_seqno;
            self.next_seqno += 1;
            self.unacked.push_back(Block {
                seqno,
                data,
                sent_at: Some(now),
            });
            out.push((seqno, data));
        }
        out
    }

    /// When [`poll`](Self::poll) next has something to do (µs).
    pub fn poll_timeout(&self) -> Option<u64> {
        self.to?;
        let resend = self.unacked.iter().map(|b| match b.sent_at {
            Some(t) => t + RESEND_AFTER,
            None => 0,
        });
        let full =
            (self.pending.len() >= BLOCK_LEN && self.unacked.len() < UNACKED_MAX).then_some(0);
        resend
            .chain(full)
            .chain([self.answered + CLIENT_GONE])
            .min()
    }
}

/// fc-sim's firmware, as its log's MSG names it.
pub fn firmware() -> String {
    format!(
        "ArduPlane V4.6.0 (fbwag fc-sim {})",
        env!("CARGO_PKG_VERSION")
    )
}

/// What a log begins with at `time_us`: the formats, the firmware, and
/// the mode (`mode`) flown.
pub fn start_bytes(time_us: u64, mode: u8) -> Vec<u8> {
    let mut bytes = dataflash::start(time_us, &firmware());
    bytes.extend(dataflash::mode(time_us, mode, 0));
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROUTER: Peer = Peer {
        sysid: 1,
        compid: 192,
    };

    fn started() -> RemoteLog {
        let mut log = RemoteLog::default();
        assert!(log.status(0, ROUTER, START, true, &[7; 450]));
        log
    }

    fn numbers(blocks: &[(u32, [u8; BLOCK_LEN])]) -> Vec<u32> {
        blocks.iter().map(|(s, _)| *s).collect()
    }

    #[test]
    fn blocks_go_until_acknowledged_nacks_go_at_once() {
        let mut log = started();
        assert_eq!(numbers(&log.poll(0)), [0, 1], "50 bytes wait for more");
        assert!(log.poll(50_000).is_empty());
        log.status(60_000, ROUTER, 0, true, &[]);
        assert_eq!(numbers(&log.poll(100_000)), [1], "sent again");
        log.status(110_000, ROUTER, 1, false, &[]);
        assert_eq!(numbers(&log.poll(110_000)), [1], "NACKed: at once");
        assert_eq!(log.resent, 1);
        log.record(&[8; 150]);
        assert_eq!(numbers(&log.poll(110_000)), [2]);
        // A stranger's STOP, ACK or START changes nothing.
        let other = Peer::new(255, 190);
        log.status(120_000, other, STOP, true, &[]);
        log.status(120_000, other, 2, true, &[]);
        assert!(!log.status(120_000, other, START, true, &[]));
        assert_eq!(log.client(), Some(ROUTER));
        log.status(130_000, ROUTER, STOP, true, &[]);
        assert!(log.poll(1_000_000).is_empty());
        log.record(&[1; 10]);
        assert_eq!(log.client(), None);
    }

    #[test]
    fn a_slow_client_bounds_what_waits_and_a_silent_one_ends_the_log() {
        let mut log = started();
        for _ in 0..100 {
            log.record(&[1; 200]);
        }
        assert!(log.dropped > 0);
        let mut sent = 0;
        for ms in 0..10 {
            sent += log.poll(ms * 1000).len();
        }
        assert_eq!(sent, UNACKED_MAX);
        assert!(log.poll(10_000_000).is_empty());
        assert_eq!(log.client(), None);
        assert!(
            log.status(10_000_001, ROUTER, START, true, &[]),
            "a new log"
        );
    }
}
