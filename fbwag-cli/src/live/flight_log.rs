//! The flight stack's own log over MAVLink (`fbwag router --flight-log
//! DIR`), as mavlink-router's `Log =` takes ArduPilot's: the DataFlash log
//! the FC streams in REMOTE_LOG_DATA_BLOCK messages (200 bytes each,
//! numbered from 0) once asked with a REMOTE_LOG_BLOCK_STATUS whose
//! `seqno` is MAV_REMOTE_LOG_DATA_BLOCK_START, each block acknowledged
//! (status ACK) or asked again (NACK) by number, and ended with
//! MAV_REMOTE_LOG_DATA_BLOCK_STOP. The FC sends a block again until it is
//! acknowledged (ArduPilot: after 100 ms; a NACK moves it ahead) and
//! stops after 10 s without an answer. The blocks are written at their
//! place (`seqno × 200`) in a `.bin` file under the same rules as the
//! telemetry log ([`super::logfiles`]): the free-space floor, the number
//! of files kept; one file per log of the FC.
//!
//! Trust: the vehicle ([`super::vehicle::Vehicle`]) is the system `--log-sysid` names, or
//! else the first autopilot (component 1, an autopilot type) whose
//! HEARTBEAT is heard, on the link it was heard on; on a link with a key
//! only verified frames count. Only that system's blocks, on that link,
//! addressed to the router's own ids ([`OWN_COMPID`] of the vehicle's
//! system), are written: a stranger's are counted and dropped. Blocks are
//! taken in a window of [`WINDOW`] numbers past the lowest one missing
//! (a bit each: 128 bytes), so neither a block numbered far ahead nor a
//! flood makes a sparse file of any size or holds memory; an answer goes
//! for each block taken, and NACKs for at most [`NACKS_MAX`] missing
//! numbers before it.
//!
//! Sans-IO: [`FlightLog::block`] and [`FlightLog::poll`] say what to send
//! ([`Reply`]); the router sends it.

use super::logfiles::{Counts, Files, Item, Kind, BLOCK_LEN};
use super::tlog::{LogMode, LogOptions};
use super::Log;
use fbwag_delegation::Moment;
use fbwag_dialect::dialects::ardupilotmega::{
    MavRemoteLogDataBlockCommands as Seqno, MavRemoteLogDataBlockStatuses as Status,
};
use fbwag_dialect::Message;
use std::io;

/// The router's component id when it asks for the log (of the vehicle's
/// system): MAV_COMP_ID_ONBOARD_COMPUTER2, a companion's program.
pub const OWN_COMPID: u8 = 192;

/// Block numbers taken past the lowest one missing.
pub const WINDOW: u32 = 1024;

/// NACKs sent for the missing numbers before a block, at most.
pub const NACKS_MAX: u32 = 16;

/// START is sent again this often until blocks come (µs).
const ASK_EVERY: u64 = 1_000_000;

/// Without a block for this long (µs), the FC stopped (ArduPilot gives
/// up after 10 s without an answer): the file ends, and the log is asked
/// for again.
const SILENT: u64 = 5_000_000;

/// A REMOTE_LOG_BLOCK_STATUS to send the vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reply {
    pub seqno: u32,
    pub ack: bool,
}

impl Reply {
    const START: Reply = Reply {
        seqno: Seqno::MAV_REMOTE_LOG_DATA_BLOCK_START.0,
        ack: true,
    };
    const STOP: Reply = Reply {
        seqno: Seqno::MAV_REMOTE_LOG_DATA_BLOCK_STOP.0,
        ack: true,
    };

    /// The message, to the vehicle's system `sysid` (every component).
    pub fn message(self, sysid: u8) -> Message {
        use fbwag_dialect::dialects::ardupilotmega::RemoteLogBlockStatus;
        Message::RemoteLogBlockStatus(RemoteLogBlockStatus {
            target_system: sysid,
            target_component: 0,
            seqno: self.seqno,
            status: if self.ack {
                Status::MAV_REMOTE_LOG_DATA_BLOCK_ACK
            } else {
                Status::MAV_REMOTE_LOG_DATA_BLOCK_NACK
            },
        })
    }
}

/// Where the log stands.
#[derive(Debug)]
enum State {
    /// Not wanted now (disarmed, under `while-armed`; no vehicle yet).
    Idle,
    /// START sent; again at `again`.
    Asking { again: u64 },
    /// Blocks coming: `base` is the lowest number not received, `taken`
    /// the numbers received from `base` on (bit i: `base + i`).
    Receiving {
        base: u32,
        taken: Box<[u64; WINDOW as usize / 64]>,
        last: u64,
    },
}

/// What the flight log did, beyond its files.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Tally {
    /// Blocks acknowledged (copies of received ones included).
    pub acked: u64,
    /// Missing blocks asked again.
    pub nacked: u64,
    /// Blocks past the window, not taken.
    pub ahead: u64,
    /// Blocks from anyone but the vehicle on its link, verified where it
    /// has a key: dropped.
    pub strangers: u64,
    /// Logs begun (a START answered with block 0).
    pub logs: u64,
}

/// The flight log: the FC's blocks in, answers out, files written.
pub struct FlightLog {
    files: Files,
    mode: LogMode,
    state: State,
    /// When a STOP was last sent for unwanted blocks (at most one a
    /// second: a flood is never answered in kind).
    stopped_at: Option<u64>,
    pub tally: Tally,
}

impl FlightLog {
    /// Starts the writer of `.bin` files in `o`'s directory.
    pub fn start(o: &LogOptions, program: &str) -> io::Result<FlightLog> {
        let files = Files::start(&o.files, program, Kind::FlightLog, "--flight-log")?;
        Ok(FlightLog::with(files, o.mode))
    }

    fn with(files: Files, mode: LogMode) -> FlightLog {
        FlightLog {
            files,
            mode,
            state: State::Idle,
            stopped_at: None,
            tally: Tally::default(),
        }
    }

    /// Whether the log is wanted now, for a vehicle heard armed or not.
    fn wanted(&self, armed: Option<bool>) -> bool {
        match self.mode {
            LogMode::Always => armed.is_some(),
            LogMode::WhileArmed => armed == Some(true),
        }
    }

    /// What to send at `now`, the vehicle armed or not (`None`: not heard
    /// yet): START until blocks come, STOP when no longer wanted; the file
    /// ends when the log stops or the FC falls silent.
    pub fn poll(&mut self, now: Moment, armed: Option<bool>) -> Option<Reply> {
        let now = now.0;
        let wanted = self.wanted(armed);
        match &mut self.state {
            State::Idle if wanted => {
                self.state = State::Asking {
                    again: now + ASK_EVERY,
                };
                Some(Reply::START)
            }
            State::Asking { .. } if !wanted => {
                self.state = State::Idle;
                Some(Reply::STOP)
            }
            State::Asking { again } if now >= *again => {
                *again = now + ASK_EVERY;
                Some(Reply::START)
            }
            State::Receiving { .. } if !wanted => {
                self.end();
                self.state = State::Idle;
                Some(Reply::STOP)
            }
            State::Receiving { last, .. } if now >= *last + SILENT => {
                self.end();
                self.state = State::Idle;
                None
            }
            _ => None,
        }
    }

    /// The next time [`poll`](Self::poll) has something to do.
    pub fn poll_timeout(&self) -> Option<Moment> {
        match &self.state {
            State::Idle => None,
            State::Asking { again } => Some(Moment(*again)),
            State::Receiving { last, .. } => Some(Moment(last + SILENT)),
        }
    }

    /// Ends the file of the log being received.
    fn end(&mut self) {
        // A full queue keeps the file open: the next log's blocks then
        // land in it at their places, whole.
        self.files.push(Item::Close);
    }

    /// A block of the vehicle's, numbered `seqno`: written (when taken)
    /// and answered.
    pub fn block(
        &mut self,
        now: Moment,
        seqno: u32,
        data: &[u8; BLOCK_LEN],
        replies: &mut Vec<Reply>,
    ) {
        let now = now.0;
        if let State::Asking { .. } = self.state {
            if seqno == 0 {
                self.tally.logs += 1;
                self.state = State::Receiving {
                    base: 0,
                    taken: Box::new([0; WINDOW as usize / 64]),
                    last: now,
                };
            }
        }
        let State::Receiving { base, taken, last } = &mut self.state else {
            // Another log (sent to someone before, or not wanted): stopped,
            // and asked for from its start (poll).
            if self.stopped_at.is_none_or(|t| now >= t + ASK_EVERY) {
                self.stopped_at = Some(now);
                replies.push(Reply::STOP);
            }
            return;
        };
        *last = now;
        if seqno < *base {
            // Written already: its acknowledgement was lost.
            self.tally.acked += 1;
            replies.push(Reply { seqno, ack: true });
            return;
        }
        let offset = seqno - *base;
        if offset >= WINDOW {
            self.tally.ahead += 1;
            return;
        }
        let is_taken = |t: &[u64], i: u32| t[i as usize / 64] & (1 << (i % 64)) != 0;
        if !is_taken(&taken[..], offset) && !self.files.push(Item::Block { seqno, data: *data }) {
            // The disk is slow: not acknowledged, so the FC sends it again.
            return;
        }
        taken[offset as usize / 64] |= 1 << (offset % 64);
        // NACKs for the numbers missing just before it.
        let from = offset.saturating_sub(NACKS_MAX);
        for i in (from..offset).filter(|&i| !is_taken(&taken[..], i)) {
            self.tally.nacked += 1;
            replies.push(Reply {
                seqno: *base + i,
                ack: false,
            });
        }
        self.tally.acked += 1;
        replies.push(Reply { seqno, ack: true });
        // Move the window past what is whole.
        let whole = (0..WINDOW)
            .find(|&i| !is_taken(&taken[..], i))
            .unwrap_or(WINDOW);
        if whole > 0 {
            shift(taken, whole);
            *base += whole;
        }
    }

    /// The writer's notes, into the daemon's log.
    pub fn notes(&mut self, log: &mut Log) {
        self.files.notes(log);
    }

    /// The files' counts so far.
    pub fn counts(&self) -> Counts {
        self.files.counts()
    }

    /// Ends the log ([`Files::finish`]): STOP, to send the vehicle when a
    /// log was coming.
    pub fn finish(&mut self, log: &mut Log) -> (Counts, Option<Reply>) {
        let stop = matches!(self.state, State::Receiving { .. } | State::Asking { .. })
            .then_some(Reply::STOP);
        (self.files.finish(log), stop)
    }

    /// The counts in the log's words.
    pub fn line(&self) -> String {
        let t = self.tally;
        format!(
            "{}; {} logs begun, {} blocks acknowledged, {} asked again, {} past the window, {} from strangers dropped",
            self.counts().line("flight log", "blocks"),
            t.logs,
            t.acked,
            t.nacked,
            t.ahead,
            t.strangers
        )
    }

    /// The counts as a JSON object, for `--events`.
    pub fn json(&self) -> serde_json::Value {
        let mut v = self.counts().json();
        let t = self.tally;
        v["logs"] = t.logs.into();
        v["acked"] = t.acked.into();
        v["nacked"] = t.nacked.into();
        v["ahead"] = t.ahead.into();
        v["strangers"] = t.strangers.into();
        v
    }
}

/// `bits` moved down by `n` (bit n becomes bit 0).
fn shift(bits: &mut [u64; WINDOW as usize / 64], n: u32) {
    let (words, rest) = ((n / 64) as usize, n % 64);
    let len = bits.len();
    for i in 0..len {
        let lo = bits.get(i + words).copied().unwrap_or(0);
        let hi = bits.get(i + words + 1).copied().unwrap_or(0);
        bits[i] = if rest == 0 {
            lo
        } else {
            (lo >> rest) | (hi << (64 - rest))
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(ms: u64) -> Moment {
        Moment(ms * 1000)
    }

    fn blocks(log: &mut FlightLog, ms: u64, seqnos: &[u32]) -> Vec<Reply> {
        let mut replies = Vec::new();
        for &s in seqnos {
            log.block(at(ms), s, &[s as u8; BLOCK_LEN], &mut replies);
        }
        replies
    }

    fn ack(seqno: u32) -> Reply {
        Reply { seqno, ack: true }
    }

    fn nack(seqno: u32) -> Reply {
        Reply { seqno, ack: false }
    }

    /// The blocks queued, by number (`None`: a file's end).
    fn written(items: &std::sync::mpsc::Receiver<Item>) -> Vec<Option<u32>> {
        items
            .try_iter()
            .map(|i| match i {
                Item::Block { seqno, data } => {
                    assert_eq!(data[0], seqno as u8);
                    Some(seqno)
                }
                _ => None,
            })
            .collect()
    }

    #[test]
    fn a_log_is_asked_for_then_acknowledged_gaps_asked_again() {
        let (files, items) = Files::stalled(64);
        let mut log = FlightLog::with(files, LogMode::Always);
        assert_eq!(log.poll(at(0), None), None, "no vehicle yet");
        assert_eq!(log.poll(at(0), Some(false)), Some(Reply::START));
        assert_eq!(log.poll(at(500), Some(false)), None);
        assert_eq!(log.poll(at(1000), Some(false)), Some(Reply::START));
        // Blocks of a log sent before: stopped, at most once a second.
        assert_eq!(blocks(&mut log, 1100, &[40, 41]), [Reply::STOP]);
        assert_eq!(
            blocks(&mut log, 1200, &[0, 1, 3]),
            [ack(0), ack(1), nack(2), ack(3)]
        );
        assert_eq!(blocks(&mut log, 1300, &[2, 1]), [ack(2), ack(1)]);
        assert_eq!(written(&items), [Some(0), Some(1), Some(3), Some(2)]);
        // Far ahead: not taken, not answered.
        assert_eq!(blocks(&mut log, 1400, &[4 + WINDOW]), []);
        assert_eq!(
            blocks(&mut log, 1400, &[4 + WINDOW - 1]).len(),
            1 + NACKS_MAX as usize
        );
        assert_eq!(log.tally.ahead, 1);
        // Silent: the file ends, and the log is asked for again.
        assert_eq!(log.poll(at(1400 + 5000), Some(false)), None);
        let _ = written(&items);
        assert_eq!(log.poll(at(6500), Some(false)), Some(Reply::START));
        assert_eq!(blocks(&mut log, 6600, &[0]), [ack(0)]);
        assert_eq!(written(&items), [Some(0)]);
        assert_eq!(log.tally.logs, 2);
    }

    #[test]
    fn while_armed_the_log_starts_at_arming_and_stops_at_disarming() {
        let (files, items) = Files::stalled(64);
        let mut log = FlightLog::with(files, LogMode::WhileArmed);
        assert_eq!(log.poll(at(0), Some(false)), None);
        assert_eq!(log.poll(at(10), Some(true)), Some(Reply::START));
        assert_eq!(blocks(&mut log, 20, &[0, 1]), [ack(0), ack(1)]);
        assert_eq!(log.poll(at(30), Some(false)), Some(Reply::STOP));
        assert_eq!(written(&items), [Some(0), Some(1), None]);
        assert_eq!(log.poll(at(40), Some(false)), None);
    }

    #[test]
    fn a_full_queue_leaves_a_block_unacknowledged() {
        let (files, items) = Files::stalled(1);
        let mut log = FlightLog::with(files, LogMode::Always);
        log.poll(at(0), Some(true));
        assert_eq!(blocks(&mut log, 1, &[0, 1]), [ack(0)]);
        assert_eq!(written(&items), [Some(0)]);
        assert_eq!(blocks(&mut log, 2, &[1]), [ack(1)]);
    }

    #[test]
    fn the_window_moves_past_whole_runs() {
        let mut bits = [0u64; WINDOW as usize / 64];
        bits[0] = 0b1011;
        bits[1] = 1;
        shift(&mut bits, 2);
        assert_eq!(bits[0], 0b10 | (1 << 62));
        shift(&mut bits, 64);
        assert_eq!(bits[0], 0);
        bits[15] = 1 << 63;
        shift(&mut bits, 63 + 64 * 15);
        assert_eq!(bits[0], 1);
    }
}
