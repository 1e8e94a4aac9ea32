//! What an operator monitors: each link's state as it changes (`link`
//! events) and, every report period, the daemon's status (`status`
//! events): per link whether it is open, the frames it took in and sent,
//! what its parser refused by reason and what it lost; the node's drops
//! by reason. Counts are totals since the start (a reopened link's parser
//! counts from zero again: its new counts are added), as monitoring
//! systems take counters.

use super::Events;
use fbwag_delegation::node::Drops;
use fbwag_dialect::mavframe::parser::Stats;
use fbwag_dialect::mavframe::route::LinkId;
use fbwag_dialect::mavframe::router::{LinkCounters, Out, RouterEvent};
use serde_json::{json, Map, Value};
use std::time::{Duration, Instant};

/// The status period when the text report is off.
pub const STATUS_EVERY: Duration = Duration::from_secs(10);

/// One link's totals since the start.
#[derive(Debug, Default, Clone, Copy)]
struct Totals {
    /// Its parser's counters: the sum of every parser it had.
    parser: Stats,
    /// The current parser's counters when last read.
    seen: Stats,
}

impl Totals {
    /// Takes in the link's parser counters `now`: what grew since last
    /// time, or all of them when they went back (a new parser).
    fn update(&mut self, now: &Stats) {
        let reset = now.frames < self.seen.frames;
        let grew = |n: u64, was: u64| if reset { n } else { n.saturating_sub(was) };
        let p = &mut self.parser;
        let was = self.seen;
        p.frames += grew(now.frames, was.frames);
        p.bad_crc += grew(now.bad_crc, was.bad_crc);
        p.bad_signature += grew(now.bad_signature, was.bad_signature);
        p.stale_timestamp += grew(now.stale_timestamp, was.stale_timestamp);
        p.unsigned_rejected += grew(now.unsigned_rejected, was.unsigned_rejected);
        p.bad_incompat_flags += grew(now.bad_incompat_flags, was.bad_incompat_flags);
        p.bytes_dropped += grew(now.bytes_dropped, was.bytes_dropped);
        self.seen = *now;
    }
}

/// The links' state and totals, and when the next status is due.
pub struct Health {
    every: Duration,
    next: Instant,
    /// Each link's: since when it is down (`None`: open), and its totals.
    links: Vec<(Option<Instant>, Totals)>,
}

impl Health {
    /// A status every `every`.
    pub fn new(every: Duration) -> Self {
        Health {
            every,
            next: Instant::now() + every,
            links: Vec::new(),
        }
    }

    fn link(&mut self, link: LinkId) -> &mut (Option<Instant>, Totals) {
        let i = usize::from(link);
        if self.links.len() <= i {
            self.links.resize(i + 1, (None, Totals::default()));
        }
        &mut self.links[i]
    }

    /// Each link open at start: a `link` event `open` (one that could not
    /// be opened says `failed` when its failure comes).
    pub fn started(&mut self, out: &Out<'_>, events: &mut Events) {
        for link in out.links().iter() {
            if out.is_up(link) {
                let name = out.name(link);
                events.emit("link", json!({"link": name, "state": "open"}));
            } else {
                self.link(link).0 = Some(Instant::now());
            }
        }
    }

    /// A link failed or is open again: its `link` event (`failed` with
    /// the error, `recovered` with how long it was down).
    pub fn changed(&mut self, out: &Out<'_>, event: &RouterEvent, events: &mut Events) {
        match event {
            RouterEvent::LinkDown { link, error } => {
                let name = out.name(*link);
                self.link(*link).0.get_or_insert_with(Instant::now);
                let error = error.to_string();
                events.emit(
                    "link",
                    json!({"link": name, "state": "failed", "error": error}),
                );
            }
            RouterEvent::LinkUp { link } => {
                let name = out.name(*link);
                let down = self.link(*link).0.take();
                let down_s = down.map_or(0.0, |t| t.elapsed().as_secs_f64());
                let down_s = (down_s * 10.0).round() / 10.0;
                events.emit(
                    "link",
                    json!({"link": name, "state": "recovered", "down_s": down_s}),
                );
            }
            // Signatures, and what later versions of the router report.
            _ => {}
        }
    }

    /// Whether the status is due.
    pub fn due(&self) -> bool {
        Instant::now() >= self.next
    }

    /// The status event: each link's state and totals, the node's `drops`,
    /// and `more` (the daemon's own: the FC found, the autonomy
    /// speaking…); a `link` event `retrying` for each link still down.
    pub fn status(
        &mut self,
        out: &Out<'_>,
        drops: &Drops,
        more: Map<String, Value>,
        events: &mut Events,
    ) {
        self.next = Instant::now() + self.every;
        let mut links = Map::new();
        for link in out.links().iter() {
            let name = out.name(link);
            let counters = out.counters(link);
            let (down, totals) = self.link(link);
            totals.update(&counters.parser);
            if let Some(since) = *down {
                let down_s = since.elapsed().as_secs();
                events.emit(
                    "link",
                    json!({"link": name, "state": "retrying", "down_s": down_s}),
                );
            }
            links.insert(
                name,
                link_status(out.is_up(link), &totals.parser, &counters),
            );
        }
        let mut status = Map::new();
        status.insert("links".into(), links.into());
        status.insert("dropped".into(), super::net::drop_counts(drops));
        status.extend(more);
        events.emit("status", status.into());
    }
}

/// One link in a status event.
fn link_status(up: bool, p: &Stats, c: &LinkCounters) -> Value {
    json!({
        "up": up,
        "frames_in": p.frames,
        "frames_out": c.frames_out,
        "refused": {
            "bad_checksum": p.bad_crc,
            "bad_signature": p.bad_signature,
            "stale_timestamp": p.stale_timestamp,
            "unsigned": p.unsigned_rejected,
            "bad_flags": p.bad_incompat_flags,
            "bytes_dropped": p.bytes_dropped,
        },
        "lost": {
            "queue_full": c.dropped_full,
            "routed": c.routed_dropped,
            "send_errors": c.send_errors,
            "state_saves": c.state_save_errors,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn totals_add_a_new_parsers_counts_to_the_old_ones() {
        let mut t = Totals::default();
        let stats = |frames, bad_signature| {
            let mut s = Stats::default();
            (s.frames, s.bad_signature) = (frames, bad_signature);
            s
        };
        t.update(&stats(10, 2));
        t.update(&stats(15, 3));
        assert_eq!((t.parser.frames, t.parser.bad_signature), (15, 3));
        // The link reopened: its parser counts from zero.
        t.update(&stats(4, 1));
        assert_eq!((t.parser.frames, t.parser.bad_signature), (19, 4));
    }
}
