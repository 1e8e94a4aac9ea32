//! The senders the parser tracks for sequence gaps ([`LinkStats`]), found
//! in constant time whatever they are.
//!
//! A frame's sender is looked up among up to [`MAX_TRACKED_LINKS`] tracked
//! ones; one not found takes the next free slot, or the last once all are
//! taken. A search slot by slot cost up to 32 compares per frame, and
//! garbage (or a flood) whose frames each come from a new (system,
//! component) pair paid all of them: on a stream of 8-byte frames of
//! unknown ids, 92 instructions per byte instead of 62 from one sender.
//! Instead, a bit per slot is kept by system id and by component id, each
//! folded to 7 bits: the slots whose sender's ids both fold as the frame's
//! are at most four (two system ids times two component ids fold alike),
//! and most often one, compared in full. Two loads and an AND, 1 KiB.
//! (Unfolded, the tables took 2 KiB, and random bytes, which never touch
//! them, parsed a third slower: the parser's layout matters.)

use super::{LinkStats, MAX_TRACKED_LINKS};

/// The tracked senders: what [`Parser::links`](super::Parser::links)
/// returns, and the tables that find a sender's slot.
pub(super) struct Senders {
    links: [LinkStats; MAX_TRACKED_LINKS],
    /// Bit `i` of `by_sysid[fold(s)]`: slot `i` is taken by a sender whose
    /// system id folds to `fold(s)`...
    by_sysid: [u32; FOLDED],
    /// ...and of `by_compid[fold(c)]`, whose component id does.
    by_compid: [u32; FOLDED],
    tracked: usize,
}

impl Senders {
    pub(super) fn new() -> Self {
        Senders {
            links: [LinkStats::default(); MAX_TRACKED_LINKS],
            by_sysid: [0; FOLDED],
            by_compid: [0; FOLDED],
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

    /// The slot of sender `(sysid, compid)`, among the (at most four)
    /// whose sender's ids fold alike: the first of them, most often.
    #[inline(always)]
    fn find(&self, sysid: u8, compid: u8) -> Option<usize> {
        let alike = self.by_sysid[fold(sysid)] & self.by_compid[fold(compid)];
        let slot = alike.trailing_zeros() as usize % MAX_TRACKED_LINKS;
        let link = &self.links[slot];
        if alike != 0 && (link.sysid, link.compid) == (sysid, compid) {
            return Some(slot);
        }
        self.find_among(alike & alike.wrapping_sub(1), sysid, compid)
    }

    /// [`find`](Self::find) among the other slots `alike`.
    #[cold]
    fn find_among(&self, mut alike: u32, sysid: u8, compid: u8) -> Option<usize> {
        while alike != 0 {
            let slot = alike.trailing_zeros() as usize % MAX_TRACKED_LINKS;
            let link = &self.links[slot];
            if (link.sysid, link.compid) == (sysid, compid) {
                return Some(slot);
            }
            alike &= alike - 1;
        }
        None
    }

    /// A slot for a new sender: the next free one, else the last (whose
    /// sender is forgotten).
    #[cold]
    #[inline(never)]
    fn take_slot(&mut self, sysid: u8, compid: u8, seq: u8) -> usize {
        let slot = self.tracked.min(MAX_TRACKED_LINKS - 1);
        if slot < self.tracked {
            let old = self.links[slot];
            self.by_sysid[fold(old.sysid)] &= !(1 << slot);
            self.by_compid[fold(old.compid)] &= !(1 << slot);
        }
        self.links[slot] = LinkStats {
            sysid,
            compid,
            received: 0,
            lost: 0,
            gaps: 0,
            last_seq: seq.wrapping_sub(1),
        };
        self.by_sysid[fold(sysid)] |= 1 << slot;
        self.by_compid[fold(compid)] |= 1 << slot;
        self.tracked = (self.tracked + 1).min(MAX_TRACKED_LINKS);
        slot
    }
}

const _: () = assert!(MAX_TRACKED_LINKS <= 32, "one bit per slot in a u32");

/// Entries of the tables by id: ids folded to their low 7 bits.
const FOLDED: usize = 128;

#[inline(always)]
fn fold(id: u8) -> usize {
    usize::from(id) % FOLDED
}

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
            let (sysid, compid) = match n % 3 {
                // Ids that fold alike: the most candidates per look-up.
                0 => ((x & 0x80) as u8 | 5, (x >> 8 & 0x80) as u8 | 9),
                _ => ((x % spread) as u8, (x >> 8 & 3) as u8),
            };
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
