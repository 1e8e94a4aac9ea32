//! A digest of a node's state, for a model checker: what tells two states
//! apart, with times and event ids told apart from other values.
//!
//! The nodes ([`FcNode::digest`](crate::node::FcNode::digest),
//! [`CompanionNode::digest`](crate::node::CompanionNode::digest)), their
//! engines and machines feed a [`Digest`] every value that can change what
//! they do next, and nothing else: counters, which decide nothing, are left
//! out. A point in time goes through [`Digest::instant`], an FC event id
//! (the FC's milliseconds since boot) through [`Digest::event`], and a
//! sequence number of the peer's frames through [`Digest::sequence`], so a
//! checker can count each from its own now; a time that stops mattering
//! after a while (a lease, a time-out) goes through
//! [`Digest::instant_within`] with that while, and a deadline that no
//! longer fires is not fed: every rule compares times,
//! events and sequence numbers only with each other and with the present,
//! so two nodes whose states differ only by when they happened behave
//! alike, and digest alike. `fbwag-model` identifies its states this way.
//!
//! Take a digest with the node's outputs drained (see the crate's call
//! order): outputs still queued count by number, not by content.

use crate::Moment;
use core::hash::{Hash, Hasher};
use core::time::Duration;

/// A [`Hasher`] told apart what is a time, an FC event id and a sequence
/// number of the peer's frames.
pub trait Digest: Hasher {
    /// A point in time of the node's clock: a deadline, or when something
    /// was last heard.
    fn instant(&mut self, t: Moment);
    /// A point in time that matters only until `lapse` after it (a
    /// time-out, a lease): from then on every rule reading it decides as
    /// for any older time. By default, an [`instant`](Digest::instant).
    fn instant_within(&mut self, t: Moment, lapse: Duration) {
        let _ = lapse;
        self.instant(t);
    }
    /// An FC event id (`FBWAG_NOTICE.timestamp`: the FC's milliseconds
    /// since boot).
    fn event(&mut self, event: u32);
    /// The MAVLink sequence number of one of the peer's frames.
    fn sequence(&mut self, seq: u8);
}

/// Feeds `value` with `each` when present, after whether it is.
pub(crate) fn option<D: Digest, T>(d: &mut D, value: Option<T>, each: impl FnOnce(&mut D, T)) {
    value.is_some().hash(d);
    if let Some(v) = value {
        each(d, v);
    }
}
