//! The digest of what every node has (see [`crate::digest`]): its links,
//! whom they answer, the routing table, the de-duplication window.

use super::peers::Answered;
use super::{Core, LinkState, PEER_SILENCE};
use crate::digest::{self, Digest};
use crate::Moment;
use core::hash::Hash;
use core::time::Duration;
use fbwag_dialect::mavframe::peers::PeerSet;

impl Core {
    /// Feeds `d` everything that decides the node's policy from now on;
    /// the drop counters are left out.
    pub(super) fn digest(&self, d: &mut impl Digest) {
        let Core {
            links,
            table,
            drops: _,
            require_signed,
            beacons,
            filtered_out,
            roles,
            dedup,
            sniffers,
        } = self;
        for link in links {
            digest::option(d, link.as_ref(), |d, l| l.digest(d));
        }
        (table, require_signed, filtered_out, roles, sniffers).hash(d);
        for beacon in &beacons.0 {
            digest::option(d, *beacon, |d, (to, at)| {
                to.hash(d);
                d.instant(at);
            });
        }
        digest::option(d, dedup.as_ref(), |d, dedup| dedup.digest(d));
    }
}

impl LinkState {
    fn digest(&self, d: &mut impl Digest) {
        let LinkState {
            spec,
            peers,
            filter_in,
            filter_out,
        } = self;
        (spec, filter_in, filter_out).hash(d);
        match peers {
            // One peer: the peer rule reads how long it has been silent,
            // against PEER_SILENCE only.
            Answered::One(set) => {
                d.write_u8(0);
                peer_set(d, set, Some(PEER_SILENCE));
            }
            // Several: which was heard last also decides which goes first.
            Answered::Stations { verified, others } => {
                d.write_u8(1);
                peer_set(d, verified, None);
                peer_set(d, others, None);
            }
        }
    }
}

/// The addresses of `set`, each with when it was last heard (mattering
/// for `lapse`, if bounded).
fn peer_set<const N: usize>(d: &mut impl Digest, set: &PeerSet<N>, lapse: Option<Duration>) {
    set.len().hash(d);
    for addr in set.iter() {
        addr.hash(d);
        let heard = set.last_heard(addr).unwrap_or_default();
        let heard = Moment(heard.as_micros() as u64);
        match lapse {
            Some(lapse) => d.instant_within(heard, lapse),
            None => d.instant(heard),
        }
    }
}
