//! The nodes as the daemons set them up, the settings the model runs, and
//! the bounds of the world around them.

use core::net::SocketAddr;
use core::time::Duration;
use fbwag_delegation::cc::CcConfig;
use fbwag_delegation::fc::FcConfig;
use fbwag_delegation::node::{
    Answers, AutonomyFallback, CompanionNode, ControlSource, FcNode, LinkId, LinkSpec, Role,
    AUTONOMY_SILENCE,
};
use fbwag_delegation::{Moment, Peer};

/// The peer link of both nodes (the FC's companion link, the companion's
/// FC link).
pub const FC_LINK: LinkId = 0;
/// The companion's autonomy link.
pub const AUTONOMY_LINK: LinkId = 2;
/// The autonomy program's ids and address.
pub const AUTONOMY: Peer = Peer::new(1, 158);
/// The autonomy program's address on the companion's autonomy link.
pub const AUTONOMY_ADDR: SocketAddr = SocketAddr::new(
    core::net::IpAddr::V4(core::net::Ipv4Addr::LOCALHOST),
    14_600,
);

/// The period of every periodic stream in the model: the virtual clock
/// moves on a grid of this step.
pub const GRID: Duration = Duration::from_millis(500);

/// The FC's settings: the defaults (the paper's retry interval, retries,
/// handshake, override and companion-silence time-outs), signing required,
/// and the receiver sampling and the confirmation heartbeats at
/// [`GRID`] (10 Hz and 5 Hz by default) so the clock moves in steps of
/// 500 ms and a handshake spans ten of them.
pub fn fc_config() -> FcConfig {
    FcConfig {
        require_signed: true,
        rc_sample_period: GRID,
        companion_heartbeat_period: GRID,
        ..FcConfig::default()
    }
}

/// The companion's settings: the defaults, signing required, and the
/// control period (a timer the autonomy's companion ignores) at [`GRID`].
pub fn cc_config() -> CcConfig {
    CcConfig {
        require_signed: true,
        control_period: GRID,
        ..CcConfig::default()
    }
}

/// The FC's node as `fbwag fc-sim` sets it up: one link, to the companion.
pub fn fc_node(cfg: FcConfig, now: Moment) -> FcNode {
    let mut node = FcNode::new(cfg, now).expect("the model's FC settings are valid");
    let spec = LinkSpec::new(Role::Peer, Answers::Target);
    node.add_link(FC_LINK, spec).expect("one link");
    node
}

/// The companion's node as `fbwag cc --autonomy` sets it up: the FC line
/// and the autonomy's port; the autonomy flies, a silent one declines.
pub fn cc_node(cfg: CcConfig, now: Moment) -> CompanionNode {
    let source = ControlSource::Autonomy {
        link: AUTONOMY_LINK,
        fallback: AutonomyFallback::Decline,
        silence: AUTONOMY_SILENCE,
    };
    let mut node = CompanionNode::new(cfg, source, now).expect("valid companion settings");
    let links = [
        (FC_LINK, Role::Peer, Answers::Target),
        (AUTONOMY_LINK, Role::Autonomy, Answers::Chosen),
    ];
    for (link, role, answers) in links {
        node.add_link(link, LinkSpec::new(role, answers))
            .expect("distinct links");
    }
    node
}

/// A fault planted in the model's harness (never in the product), to show
/// the checker finds what each invariant forbids.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Fault {
    /// The harness applies the companion's control while the FC is still
    /// in its handshake (before the acknowledgement).
    ControlInHandshake,
    /// The harness re-sends the FC's notice at every FC tick of a
    /// handshake: a retry counter that never ends.
    EndlessRetries,
    /// The harness replays the companion's acknowledgement of an earlier
    /// FC boot, signed afresh, as if it were new.
    StaleAckAfterReboot,
}

impl Fault {
    /// Every planted fault.
    pub const ALL: [Fault; 3] = [
        Fault::ControlInHandshake,
        Fault::EndlessRetries,
        Fault::StaleAckAfterReboot,
    ];

    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Fault::ControlInHandshake => "control-in-handshake",
            Fault::EndlessRetries => "endless-retries",
            Fault::StaleAckAfterReboot => "stale-ack-after-reboot",
        }
    }

    /// The fault called `name`.
    pub fn from_name(name: &str) -> Option<Fault> {
        Fault::ALL.into_iter().find(|f| f.name() == name)
    }
}

/// Bounds of the world around the nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ModelConfig {
    /// Frames in flight per direction; more are lost.
    pub max_in_flight: usize,
    /// Changes of the pilot's receiver (lost, back, ...).
    pub rc_flips: u8,
    /// FC restarts.
    pub fc_reboots: u8,
    /// Companion restarts.
    pub cc_reboots: u8,
    /// Duplicated frames.
    pub dups: u8,
    /// Frames a stranger forges.
    pub forgeries: u8,
    /// Changes of the autonomy (silent, speaking again).
    pub autonomy_flips: u8,
    /// Virtual time explored.
    pub horizon: Duration,
    /// A planted fault, or none (the product as it is).
    pub fault: Option<Fault>,
}

impl ModelConfig {
    /// The world for showing a planted fault: the receiver fails once and
    /// the FC may restart; no duplicates, forgeries, companion restarts or
    /// autonomy silences, so the breadth-first search reaches the fault's
    /// depth quickly.
    pub fn for_fault(fault: Fault) -> Self {
        ModelConfig {
            rc_flips: 1,
            fc_reboots: 1,
            cc_reboots: 0,
            dups: 0,
            forgeries: 0,
            autonomy_flips: 0,
            fault: Some(fault),
            ..ModelConfig::default()
        }
    }
}

impl Default for ModelConfig {
    fn default() -> Self {
        ModelConfig {
            max_in_flight: 3,
            rc_flips: 3,
            fc_reboots: 1,
            cc_reboots: 1,
            dups: 1,
            forgeries: 1,
            autonomy_flips: 2,
            horizon: Duration::from_secs(12),
            fault: None,
        }
    }
}
