//! The flight controller's node: its companion link (which also carries
//! the ground stations' traffic the companion routes) around the FC
//! engine.

use super::{sender, Arrival, Core, DropReason, Drops, Fate, LinkId, LinkSpec, NodeError, Output};
use crate::digest::Digest;
use crate::engine::{FcEngine, FcEngineStats, FcOutput, Verdict};
use crate::fc::FcConfig;
use crate::outbox::Outbox;
use crate::{wire, Moment, Peer};
use core::hash::Hash;
use fbwag_dialect::Message;

/// The flight controller's node: the [`FcEngine`] and the policy of its
/// links (see the [module docs](super)).
///
/// Driven as [`CompanionNode`](super::CompanionNode)'s example shows: each
/// frame a link's parser accepted goes to `handle_frame` as an
/// [`Arrival`](super::Arrival), and its [`Fate`](super::Fate) says where it goes.
#[derive(Debug, Clone)]
pub struct FcNode {
    engine: FcEngine,
    core: Core,
    cfg: FcConfig,
    /// Counters of engines replaced by [`FcNode::reconfigure`].
    stats_before: FcEngineStats,
    out: Outbox<Output<FcOutput>, 24>,
}

impl FcNode {
    /// A node whose engine starts at `now`, with no links yet.
    pub fn new(cfg: FcConfig, now: Moment) -> Result<Self, NodeError> {
        Ok(FcNode {
            engine: FcEngine::new(cfg, now)?,
            core: Core::new(cfg.require_signed),
            cfg,
            stats_before: FcEngineStats::default(),
            out: Outbox::new(),
        })
    }

    /// Adds link `link`.
    pub fn add_link(&mut self, link: LinkId, spec: LinkSpec) -> Result<(), NodeError> {
        self.core.add(link, spec)
    }

    /// The engine (read only).
    pub fn engine(&self) -> &FcEngine {
        &self.engine
    }

    /// The settings in force.
    pub fn config(&self) -> &FcConfig {
        &self.cfg
    }

    /// The engine's counters, over every engine a reconfiguration replaced.
    pub fn stats(&self) -> FcEngineStats {
        self.stats_before.plus(self.engine.stats())
    }

    /// Frames dropped, by reason.
    pub fn drops(&self) -> &Drops {
        &self.core.drops
    }

    /// Feeds `d` everything that decides what the node does next: the
    /// engine's and the links' (see [`crate::digest`]); counters are left
    /// out.
    pub fn digest(&self, d: &mut impl Digest) {
        let FcNode {
            engine,
            core,
            cfg,
            stats_before: _,
            out,
        } = self;
        engine.digest(d);
        core.digest(d);
        cfg.hash(d);
        out.len().hash(d);
    }

    /// New settings, from `now`: a new engine (call it only while nothing
    /// of a handover is under way; the receiver state carries over).
    pub fn reconfigure(&mut self, cfg: FcConfig, now: Moment) -> Result<(), NodeError> {
        let mut engine = FcEngine::new(cfg, now)?;
        engine.set_receiver_ok(self.engine.machine().receiver_ok());
        self.stats_before = self.stats();
        self.engine = engine;
        self.cfg = cfg;
        self.core.require_signed = cfg.require_signed;
        Ok(())
    }

    /// A link was opened again: whom it answered is forgotten.
    pub fn link_reopened(&mut self, link: LinkId) {
        self.core.reopened(link);
    }

    /// The receiver's state, sampled by the engine's RC check.
    pub fn set_receiver_ok(&mut self, ok: bool) {
        self.engine.set_receiver_ok(ok);
    }

    /// When [`handle_timeout`](Self::handle_timeout) must next run.
    pub fn poll_timeout(&self) -> Option<Moment> {
        self.engine.poll_timeout()
    }

    /// Timers due at `now`.
    pub fn handle_timeout(&mut self, now: Moment) {
        self.engine.handle_timeout(now);
        self.drain_engine();
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<Output<FcOutput>> {
        self.out.pop()
    }

    /// A frame link `a.link` delivered at `now`: its fate. The FC routes
    /// nothing; a ground station's request is served only when its
    /// signature verified, where signing is required (as ArduPilot serves
    /// a signed link).
    pub fn handle_frame(&mut self, now: Moment, a: Arrival) -> Fate {
        if self.core.spec(a.link).is_none() {
            return Fate::default();
        }
        let from = sender(&a.frame);
        if from == self.cfg.own {
            return self.core.drop(DropReason::OwnIds);
        }
        let authority = self.engine.authority();
        let heartbeat = || Message::Heartbeat(wire::fc_heartbeat(authority));
        let peer = self.cfg.companion;
        if let Err(dropped) = self
            .core
            .peer_source(&a, now, peer, &mut self.out, heartbeat)
        {
            return dropped;
        }
        // The engine sees every frame of the peer's address: it acts on the
        // companion's trusted ones and counts the rest.
        let verdict = self.engine.handle_frame(now, &a.frame, a.authenticated);
        self.drain_engine();
        if from == self.cfg.companion && verdict == Verdict::Untrusted {
            return self.core.drop(DropReason::Unauthenticated);
        }
        Fate {
            input: verdict == Verdict::Trusted,
            serve: a.authenticated || !self.cfg.require_signed,
            ..Fate::default()
        }
    }

    /// Link `link`'s parser refused a frame of `sender` from `source` for
    /// its signature: on the listening companion link, while it answers
    /// no companion, a source claiming the companion's ids gets the FC's
    /// signed heartbeat, once a second at most, so that a companion with
    /// another key sees the mismatch too.
    pub fn handle_bad_signature(
        &mut self,
        now: Moment,
        link: LinkId,
        source: core::net::SocketAddr,
        sender: Peer,
    ) {
        if sender == self.cfg.companion && self.core.signature_beacon(link, source, now) {
            let authority = self.engine.authority();
            let message = Message::Heartbeat(wire::fc_heartbeat(authority));
            self.out.push(Output::TransmitTo {
                link,
                to: source,
                message,
            });
        }
    }

    fn drain_engine(&mut self) {
        while let Some(output) = self.engine.poll_output() {
            self.out.push(match output {
                FcOutput::Transmit(message) => Output::Transmit {
                    links: self.core.all(),
                    message,
                },
                event => Output::Event(event),
            });
        }
    }
}
