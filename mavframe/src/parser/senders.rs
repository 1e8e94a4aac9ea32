//! The senders the parser tracks for sequence gaps ([`LinkStats`]), found
//! in constant time whatever they are.
//!
//! A frame's sender is looked up among up to [`MAX_TRACKED_LINKS`] tracked
//! ones; one not found takes the next free slot, or the last once all are
//! taken. A search slot by slot cost up to 32 compares per frame, and
//! garbage (or a flood) whose frames each come from a new (system,
//! component) pair paid all of them: on a stream of 8-byte frames of
//! unknown ids, 92 instructions per byte instead of 62 from one sender.
//! Instead, a bit per slot is kept by system id and by component id: the
//! slot of a sender is the one bit both of its ids have, two loads and an
//! AND (2 KiB).

use super::{LinkStats, MAX_TRACKED_LINKS};

/// The tracked senders: what [`Parser::links`](super::Parser::links)
/// returns, and their ids side by side.
pub(super) struct Senders {
    links: [LinkStats; MAX_TRACKED_LINKS],
    /// Bit `i` of `by_sysid[s]`: slot `i` is taken by a sender of system
    /// id `s`...
    by_sysid: [u32; 256],
    /// ...and of `by_compid[c]`, of component id `c`.
    by_compid: [u32; 256],
    tracked: usize,
}

impl Senders {
    pub(super) const fn new() -> Self {
        const NONE: LinkStats = LinkStats {
            sysid: 0,
            compid: 0,
            received: 0,
            lost: 0,
            gaps: 0,
            last_seq: 0,
        };
        Senders {
            links: [NONE; MAX_TRACKED_LINKS],
            by_sysid: [0; 256],
            by_compid: [0; 256],
            tracked: 0,
        }
    }

    /// The senders tracked, in the order first seen (the last slot holds
    /// the newest of those that came after the others were taken).
    pub(super) fn links(&self) -> &[LinkStats] {
        &self.links[..self.tracked]
    }

    /// The sender `(sysid, compid)`, its sequence counters started at `seq`
    /// when it is new.
    #[inline(always)]
    pub(super) fn get(&mut self, sysid: u8, compid: u8, seq: u8) -> &mut LinkStats {
        let slot = match self.find(sysid, compid) {
            Some(slot) => slot,
            None => self.take_slot(sysid, compid, seq),
        };
        &mut self.links[slot]
    }

    /// The slot of sender `(sysid, compid)`: the only slot whose sender has
    /// both ids (two senders never share a slot, nor a sender two slots).
    #[inline(always)]
    fn find(&self, sysid: u8, compid: u8) -> Option<usize> {
        let both = self.by_sysid[usize::from(sysid)] & self.by_compid[usize::from(compid)];
        (both != 0).then(|| both.trailing_zeros() as usize % MAX_TRACKED_LINKS)
    }

    /// A slot for a new sender: the next free one, else the last (whose
    /// sender is forgotten).
    #[cold]
    #[inline(never)]
    fn take_slot(&mut self, sysid: u8, compid: u8, seq: u8) -> usize {
        let slot = self.tracked.min(MAX_TRACKED_LINKS - 1);
        if slot < self.tracked {
            let old = self.links[slot];
            self.by_sysid[usize::from(old.sysid)] &= !(1 << slot);
            self.by_compid[usize::from(old.compid)] &= !(1 << slot);
        }
        self.links[slot] = LinkStats {
            sysid,
            compid,
            received: 0,
            lost: 0,
            gaps: 0,
            last_seq: seq.wrapping_sub(1),
        };
        self.by_sysid[usize::from(sysid)] |= 1 << slot;
        self.by_compid[usize::from(compid)] |= 1 << slot;
        self.tracked = (self.tracked + 1).min(MAX_TRACKED_LINKS);
        slot
    }
}

const _: () = assert!(MAX_TRACKED_LINKS <= 32, "one bit per slot in a u32");

#[cfg(test)]
mod tests {
    use super::*;

    /// The slot-by-slot search this replaces: the reference.
    fn slow(s: &Senders, sysid: u8, compid: u8) -> Option<usize> {
        s.links()
            .iter()
            .position(|l| (l.sysid, l.compid) == (sysid, compid))
    }

    #[test]
    fn finds_what_a_search_slot_by_slot_finds() {
        let mut s = Senders::new();
        let mut x = 0x1234_5678u32;
        for n in 0..2000u32 {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            // Few senders at first (every slot hit again), many later (the
            // last slot taken over again and again), id 0/0 among them.
            let spread = if n < 500 { 8 } else { 256 };
            let (sysid, compid) = ((x % spread) as u8, (x >> 8 & 3) as u8);
            let before = slow(&s, sysid, compid);
            assert_eq!(s.find(sysid, compid), before);
            let tracked = s.tracked;
            let link = *s.get(sysid, compid, n as u8);
            assert_eq!((link.sysid, link.compid), (sysid, compid));
            let expect = before.unwrap_or(tracked.min(MAX_TRACKED_LINKS - 1));
            assert_eq!(slow(&s, sysid, compid), Some(expect));
        }
        assert_eq!(s.links().len(), MAX_TRACKED_LINKS);
    }

    #[test]
    fn an_empty_table_finds_nobody_not_even_0_0() {
        let s = Senders::new();
        assert_eq!(s.find(0, 0), None);
    }
}
