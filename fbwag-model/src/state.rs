//! The model's state: both real nodes, the frames in flight, the pilot's
//! receiver, the virtual clock, and the facts the invariants need (which
//! the nodes keep private, so the harness records them from the nodes'
//! outputs as they happen).

use crate::wire::Endpoint;
use core::fmt::{self, Write as _};
use core::hash::{Hash, Hasher};
use fbwag_delegation::node::{CompanionNode, FcNode};
use fbwag_delegation::Moment;
use std::collections::hash_map::DefaultHasher;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

/// Who put a frame on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Party {
    /// The flight controller's node.
    Fc,
    /// The companion's node.
    Cc,
    /// Someone without the key.
    Stranger,
}

/// A frame in flight, with what the harness knows of its origin.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct InFlight {
    /// The frame's bytes, as encoded (and signed) by the sender.
    pub bytes: Vec<u8>,
    /// The sender.
    pub from: Party,
    /// How many times the FC had booted when it was sent: an
    /// acknowledgement sent to an earlier boot is stale.
    pub fc_boot: u8,
}

/// A node with a digest of its whole state, taken once per change.
///
/// The nodes keep their state private and implement neither `Hash` nor
/// `Eq`; their derived `Debug` prints every field, so hashing it identifies
/// the state exactly (two nodes with the same `Debug` text behave the
/// same). The digest is computed when the node changes, not per lookup.
/// Equal nodes are stored once ([`Interned`]): a node is 32 KB, and
/// millions of model states share a few hundred thousand node states.
#[derive(Clone)]
pub struct Held<N> {
    node: Arc<N>,
    digest: u64,
}

/// A node type with its table of distinct states.
pub trait Interned: fmt::Debug + Clone + Send + Sync + 'static {
    /// The table: digest to the one copy of that state.
    fn table() -> &'static Mutex<HashMap<u64, Arc<Self>>>;
}

impl Interned for FcNode {
    fn table() -> &'static Mutex<HashMap<u64, Arc<Self>>> {
        static TABLE: OnceLock<Mutex<HashMap<u64, Arc<FcNode>>>> = OnceLock::new();
        TABLE.get_or_init(Default::default)
    }
}

impl Interned for CompanionNode {
    fn table() -> &'static Mutex<HashMap<u64, Arc<Self>>> {
        static TABLE: OnceLock<Mutex<HashMap<u64, Arc<CompanionNode>>>> = OnceLock::new();
        TABLE.get_or_init(Default::default)
    }
}

impl<N: Interned> Held<N> {
    /// Holds `node`.
    pub fn new(node: N) -> Self {
        Self::intern(node)
    }

    fn intern(node: N) -> Self {
        let digest = digest(&node);
        let mut table = N::table().lock().unwrap_or_else(|e| e.into_inner());
        let node = table
            .entry(digest)
            .or_insert_with(|| Arc::new(node))
            .clone();
        Held { node, digest }
    }

    /// The node, read only.
    pub fn get(&self) -> &N {
        &self.node
    }

    /// Runs `f` on a copy of the node and keeps the result.
    pub fn update<R>(&mut self, f: impl FnOnce(&mut N) -> R) -> R {
        let mut node = (*self.node).clone();
        let r = f(&mut node);
        *self = Self::intern(node);
        r
    }
}

impl<N> Hash for Held<N> {
    fn hash<H: Hasher>(&self, h: &mut H) {
        self.digest.hash(h);
    }
}

impl<N> PartialEq for Held<N> {
    fn eq(&self, other: &Self) -> bool {
        self.digest == other.digest
    }
}

impl<N> Eq for Held<N> {}

impl<N: fmt::Debug> fmt::Debug for Held<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "#{:016x}", self.digest)
    }
}

/// Feeds formatted text into a hasher without allocating.
struct HashWriter<'a>(&'a mut DefaultHasher);

impl fmt::Write for HashWriter<'_> {
    fn write_str(&mut self, s: &str) -> fmt::Result {
        self.0.write(s.as_bytes());
        Ok(())
    }
}

/// A fixed-key hash of `node`'s `Debug` text.
fn digest(node: &impl fmt::Debug) -> u64 {
    let mut h = DefaultHasher::new();
    let _ = write!(HashWriter(&mut h), "{node:?}");
    h.finish()
}

/// One side: its node, its MAVLink endpoint, and its boot.
#[derive(Clone, Debug)]
pub struct Side<N> {
    /// The node.
    pub node: Held<N>,
    /// Framing and signing.
    pub link: Endpoint,
    /// When it last booted (its own clock reads `now - boot`).
    pub boot: Moment,
    /// Boots so far (0: the first run).
    pub boots: u8,
}

impl<N> PartialEq for Side<N> {
    fn eq(&self, o: &Self) -> bool {
        (self.node == o.node) && self.link == o.link && self.boot == o.boot && self.boots == o.boots
    }
}

impl<N> Eq for Side<N> {}

impl<N> Hash for Side<N> {
    fn hash<H: Hasher>(&self, h: &mut H) {
        self.node.hash(h);
        self.link.hash(h);
        self.boot.hash(h);
        self.boots.hash(h);
    }
}

impl PartialEq for Endpoint {
    fn eq(&self, other: &Self) -> bool {
        let h = |e: &Endpoint| {
            let mut s = DefaultHasher::new();
            e.hash(&mut s);
            s.finish()
        };
        h(self) == h(other)
    }
}

impl Eq for Endpoint {}

/// Notices sent, per sender, status and event (for the retry bound).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Sent {
    /// The sender.
    pub from: Party,
    /// `failsafe_status`.
    pub status: u8,
    /// `timestamp`: the event.
    pub event: u32,
    /// How many.
    pub count: u8,
}

/// What the invariants read besides the nodes, recorded by the harness.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash)]
pub struct Ghost {
    /// Invariants broken at a transition (bit = index in
    /// [`crate::props::INVARIANTS`]).
    pub broken: u16,
    /// When the pilot's receiver last changed (lost or back).
    pub rc_changed: Moment,
    /// When the FC entered its current handshake.
    pub handshake_since: Option<Moment>,
    /// When the FC last left companion control (mode change or reboot).
    pub left_companion: Option<Moment>,
    /// Notices sent in the current boot of each sender.
    pub sent: Vec<Sent>,
    /// Receiver flips, duplicates, forgeries, autonomy flips so far.
    pub rc_flips: u8,
    /// Duplicates so far.
    pub dups: u8,
    /// Forged frames so far.
    pub forgeries: u8,
    /// Autonomy silences and returns so far.
    pub autonomy_flips: u8,
    /// Planted fault (c): the last acknowledgement of the companion, kept
    /// for a replay after the FC reboots.
    pub recorded_ack: Option<InFlight>,
}

/// Steps from the initial state on the path that first reached a state:
/// not part of the state (equal states reached by longer paths are the
/// same state), so it neither hashes nor compares.
#[derive(Clone, Copy, Debug, Default)]
pub struct Steps(pub usize);

impl Hash for Steps {
    fn hash<H: Hasher>(&self, _: &mut H) {}
}

impl PartialEq for Steps {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl Eq for Steps {}

/// The whole model state.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct State {
    /// Steps from the start (see [`Steps`]).
    pub steps: Steps,
    /// Virtual time.
    pub now: Moment,
    /// The flight controller.
    pub fc: Side<FcNode>,
    /// The companion.
    pub cc: Side<CompanionNode>,
    /// Frames on their way to the companion.
    pub to_cc: Vec<InFlight>,
    /// Frames on their way to the FC.
    pub to_fc: Vec<InFlight>,
    /// The pilot's receiver works.
    pub rc_ok: bool,
    /// The autonomy streams its control.
    pub autonomy_speaks: bool,
    /// Facts for the invariants.
    pub ghost: Ghost,
}

impl State {
    /// The FC's own clock.
    pub fn fc_now(&self) -> Moment {
        Moment(self.now.0 - self.fc.boot.0)
    }

    /// The companion's own clock.
    pub fn cc_now(&self) -> Moment {
        Moment(self.now.0 - self.cc.boot.0)
    }

    /// The FC's next deadline, in model time.
    pub fn fc_deadline(&self) -> Option<Moment> {
        let t = self.fc.node.get().poll_timeout()?;
        Some(Moment(self.fc.boot.0 + t.0))
    }

    /// The companion's next deadline, in model time.
    pub fn cc_deadline(&self) -> Option<Moment> {
        let t = self.cc.node.get().poll_timeout()?;
        Some(Moment(self.cc.boot.0 + t.0))
    }

    /// The earliest deadline of either node.
    pub fn earliest(&self) -> Option<Moment> {
        [self.fc_deadline(), self.cc_deadline()]
            .into_iter()
            .flatten()
            .min()
    }
}
