//! A plain router's node: every link a ground link, no engine.

use super::{
    Answers, Arrival, Core, DropReason, Drops, Fate, LinkId, LinkSpec, Links, NodeError, Output,
    Role,
};
use crate::outbox::Outbox;
use crate::Instant;
use core::convert::Infallible;

/// A router's node: routes every frame by the routing rules, answers on
/// each listening link only the sources it admits (on a link with a key,
/// only sources of authenticated frames), and with signing required routes
/// only authenticated frames (see the [module docs](super)). Its only
/// outputs are [`Output::Peers`].
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
    pub fn handle_frame(&mut self, now: Instant, a: Arrival) -> Fate {
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
        let all = self.core.all();
        Fate {
            route: self.core.route(&a, a.authenticated, all),
            ..Fate::default()
        }
    }
}
