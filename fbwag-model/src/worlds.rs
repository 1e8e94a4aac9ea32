//! The bounded worlds the default check explores, each to its fixpoint.
//!
//! One world with every disturbance at once (receiver flaps, restarts of
//! either side, a stranger, duplicates, the autonomy falling silent) has
//! more states than ten minutes can visit: each disturbance multiplies
//! them. So the default check is a set of worlds, each with the pilot's
//! receiver and the lossy, reordering link, and a few disturbances; every
//! timer of both nodes fires in at least one of them (see [`crate::Reach`]).

use crate::setup::{self, ModelConfig};
use crate::DelegationModel;
use core::time::Duration;
use fbwag_delegation::cc::CcConfig;
use fbwag_delegation::fc::FcConfig;

/// The virtual time past which a world's search is cut: every world's
/// fixpoint lies within 50 s, so only a bug that keeps time going with
/// ever new states reaches it (and the report then says no fixpoint).
pub const HORIZON: Duration = Duration::from_secs(90);

/// A bounded world: its bounds and the nodes' settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct World {
    /// Its name (`fbwag sim --model-check --world NAME`).
    pub name: &'static str,
    /// What it is for, in a few words.
    pub purpose: &'static str,
    /// The world's bounds.
    pub bounds: ModelConfig,
    /// The FC's settings.
    pub fc: FcConfig,
    /// The companion's settings.
    pub cc: CcConfig,
}

impl World {
    /// The model of this world.
    pub fn model(&self) -> DelegationModel {
        let mut m = DelegationModel::new(self.bounds);
        m.fc = self.fc;
        m.cc = self.cc;
        m
    }
}

/// A world with only the receiver and the lossy link; `f` adds to it.
fn world(
    name: &'static str,
    purpose: &'static str,
    rc_flips: u8,
    f: impl FnOnce(&mut ModelConfig),
) -> World {
    let mut bounds = ModelConfig {
        rc_flips,
        fc_reboots: 0,
        cc_reboots: 0,
        dups: 0,
        autonomy_flips: 0,
        stranger: false,
        horizon: Some(HORIZON),
        ..ModelConfig::default()
    };
    f(&mut bounds);
    World {
        name,
        purpose,
        bounds,
        fc: setup::fc_config(),
        cc: setup::cc_config(),
    }
}

/// The worlds of the default check (`fbwag sim --model-check`).
pub fn default_worlds() -> Vec<World> {
    vec![
        world(
            "two-cycles",
            "the receiver lost, back once the FC flies RTL, and lost again: two whole RC-loss \
             cycles, each through its retries to the RTL after the last",
            3,
            |b| b.rc_back_in_rtl = true,
        ),
        world(
            "rc-back",
            "the receiver lost and back at any step: in the handshake, in companion control, \
             in RTL",
            2,
            |_| {},
        ),
        world(
            "fc-restart",
            "the FC restarts (in its first second), keeping its signing state or not",
            1,
            |b| {
                b.fc_reboots = 1;
                b.fc_reboot_window = Duration::from_secs(1);
            },
        ),
        world(
            "cc-restart",
            "the companion restarts, keeping its signing state or not",
            1,
            |b| b.cc_reboots = 1,
        ),
        world(
            "stranger",
            "a stranger without the key forges and replays at every step; the link also \
             duplicates a frame",
            1,
            |b| {
                b.stranger = true;
                b.dups = 1;
            },
        ),
        world(
            "autonomy",
            "the autonomy falls silent, at any step",
            1,
            |b| b.autonomy_flips = 1,
        ),
        {
            let mut w = world(
                "companion-silence",
                "the FC's override time-out (4 s) above its companion-silence time-out (3 s), \
                 so the latter fires",
                1,
                |_| {},
            );
            w.fc.override_timeout = Duration::from_secs(4);
            w
        },
    ]
}

/// The quick world of the test command: one receiver loss and a
/// stranger who forges and replays.
pub fn quick() -> World {
    world(
        "quick",
        "one RC loss and a stranger who forges and replays: every state, in under a minute",
        1,
        |b| b.stranger = true,
    )
}

/// Every disturbance at once ([`ModelConfig::default`]): too many states
/// for a fixpoint, for a search bounded in depth.
pub fn all() -> World {
    World {
        name: "all",
        purpose: "every disturbance at once, for a search bounded in depth",
        bounds: ModelConfig::default(),
        fc: setup::fc_config(),
        cc: setup::cc_config(),
    }
}

/// Every world by name: the default ones, the quick one and `all`.
pub fn by_name(name: &str) -> Option<World> {
    default_worlds()
        .into_iter()
        .chain([quick(), all()])
        .find(|w| w.name == name)
}

/// The names [`by_name`] knows.
pub fn names() -> Vec<&'static str> {
    default_worlds()
        .iter()
        .chain(&[quick(), all()])
        .map(|w| w.name)
        .collect()
}
