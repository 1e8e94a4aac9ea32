//! A plain router's node: every link a ground link, no engine.

use super::{
    Answers, Arrival, Core, Direction, DropReason, Drops, Fate, Filter, LinkId, LinkSpec, Links,
    NodeError, Output, Role,
};
use crate::outbox::Outbox;
use crate::Moment;
use core::convert::Infallible;
use core::time::Duration;

/// A router's node: routes every frame by the routing rules, answers on
/// each listening link only the sources it admits (on a link with a key,
/// only sources of authenticated frames), and with signing required routes
/// only authenticated frames (see the [module docs](super)). Each link's
/// filters ([`RouterNode::set_filter`]) and the de-duplication window
/// ([`RouterNode::set_dedup`]) narrow what is routed. Its only outputs are
/// [`Output::Peers`].
///
/// Driven as [`CompanionNode`](super::CompanionNode)'s example shows: each
/// frame a link's parser accepted goes to `handle_frame` as an
/// [`Arrival`](super::Arrival), and its [`Fate`](super::Fate) says where it goes.
#[derive(Debug, Clone)]
pub struct RouterNode {
    core: Core,
    /// Links with a key.
    keyed: Links,
    out: Outbox<Output<Infallible>, 8>,
}

impl RouterNode {
    /// A router; `require_signed`: only authenticated frames are routed.
    pub fn new(require_signed: bool) -> Self {
        RouterNode {
            core: Core::new(require_signed),
            keyed: Links::NONE,
            out: Outbox::new(),
        }
    }

    /// Adds link `link`; `keyed`: the link verifies signatures.
    pub fn add_link(
        &mut self,
        link: LinkId,
        answers: Answers,
        keyed: bool,
    ) -> Result<(), NodeError> {
        self.core.add(link, LinkSpec::new(Role::Ground, answers))?;
        if keyed {
            self.keyed = self.keyed.union(Links::only(link));
        }
        Ok(())
    }

    /// Sets the filter of link `link` in `direction` (every link starts
    /// with [`Filter::ALL`] both ways).
    pub fn set_filter(
        &mut self,
        link: LinkId,
        direction: Direction,
        filter: Filter,
    ) -> Result<(), NodeError> {
        self.core.set_filter(link, direction, filter)
    }

    /// Makes `link` a sniffer: it gets every frame routed, those
    /// addressed to systems on other links as well as the broadcasts (a
    /// logger, a tool watching the whole network), through its
    /// out-filter. What arrives on it is routed as from any link.
    pub fn set_sniffer(&mut self, link: LinkId) -> Result<(), NodeError> {
        self.core.set_sniffer(link)
    }

    /// Drops a copy of a frame that went on less than `window` before,
    /// from any link (`None` or zero: off, the default).
    pub fn set_dedup(&mut self, window: Option<Duration>) {
        self.core.set_dedup(window);
    }

    /// Frames dropped, by reason.
    pub fn drops(&self) -> &Drops {
        &self.core.drops
    }

    /// A link was opened again: whom it answered is forgotten.
    pub fn link_reopened(&mut self, link: LinkId) {
        self.core.reopened(link);
    }

    /// The next output, if any.
    pub fn poll_output(&mut self) -> Option<Output<Infallible>> {
        self.out.pop()
    }

    /// A frame link `a.link` delivered at `now`: where it goes.
    pub fn handle_frame(&mut self, now: Moment, a: Arrival) -> Fate {
        let Some(spec) = self.core.spec(a.link) else {
            return Fate::default();
        };
        if self.core.require_signed && !a.authenticated {
            return self.core.drop(DropReason::Unauthenticated);
        }
        // On a keyed link only a verified frame earns answers.
        let joins = a.authenticated || !self.keyed.contains(a.link);
        let out = &mut self.out;
        let known = self
            .core
            .admits_source(&a, now, joins, a.authenticated, &mut |link, peers| {
                out.push(Output::Peers { link, peers })
            });
        if !known && matches!(spec.answers, Answers::Fixed(_)) {
            return self.core.drop(DropReason::NotPeer);
        }
        if let Some(reason) = self.core.screen(&a, now) {
            return self.core.drop(reason);
        }
        let all = self.core.all();
        Fate {
            route: self.core.route(&a, a.authenticated, all),
            ..Fate::default()
        }
    }
}
