//! The nodes as the daemons set them up, the settings the model runs, and
//! the bounds of the world around them.

use core::net::{IpAddr, Ipv4Addr, SocketAddr};
use core::time::Duration;
use fbwag_delegation::cc::CcConfig;
use fbwag_delegation::fc::FcConfig;
use fbwag_delegation::node::{
    Answers, AutonomyFallback, CompanionNode, ControlSource, FcNode, LinkId, LinkSpec, Role,
    PEER_SILENCE,
};
use fbwag_delegation::{Moment, Peer};

/// The peer link of both nodes (the FC's companion link, the companion's
/// FC link): a listening link (`udpin`) that answers whom the node admits.
pub const FC_LINK: LinkId = 0;
/// The companion's ground link, trusted like the key (`--trusted-out`,
/// deploy/cc.toml's MAVSDK link): its unsigned frames go on signed.
pub const GROUND_LINK: LinkId = 1;
/// The companion's autonomy link.
pub const AUTONOMY_LINK: LinkId = 2;
/// The autonomy program's ids.
pub const AUTONOMY: Peer = Peer::new(1, 158);
/// A ground station's ids (the stranger's requests to the FC).
pub const STATION: Peer = Peer::new(255, 190);

const fn local(port: u16) -> SocketAddr {
    SocketAddr::new(IpAddr::V4(Ipv4Addr::LOCALHOST), port)
}
/// Where the FC's frames come from, as the companion sees them.
pub const FC_ADDR: SocketAddr = local(14_550);
/// Where the companion's frames come from, as the FC sees them.
pub const CC_ADDR: SocketAddr = local(14_551);
/// The autonomy program's address on the companion's autonomy link.
pub const AUTONOMY_ADDR: SocketAddr = local(14_600);
/// The stranger's own address (it may also forge a peer's).
pub const STRANGER_ADDR: SocketAddr = local(40_000);

/// The period of every periodic stream in the model: the virtual clock
/// moves on a grid of this step.
pub const GRID: Duration = Duration::from_millis(500);

/// How long the autonomy must be silent to count as silent: two steps of
/// the grid. The autonomy's control reaches the companion at every step
/// of the clock (a stream far faster than the grid); with the default
/// 500 ms, one step, its own next frame would land on its silence.
pub const SILENCE: Duration = Duration::from_millis(1000);

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

/// How far back a time can still matter to either node with these
/// settings: past it, an instant, an event id or a signing time compares
/// with every later one alike (see [`crate::state`]).
pub fn memory(fc: &FcConfig, cc: &CcConfig) -> Duration {
    let longest = [
        fc.retry_interval,
        fc.handshake_timeout,
        fc.override_timeout,
        fc.heartbeat_timeout,
        fc.heartbeat_period,
        cc.ack_retry_interval,
        cc.control_lease,
        cc.confirm_timeout,
        cc.fc_timeout,
        cc.control_fc_timeout,
        cc.fc_event_lifetime + fc.handshake_timeout,
        cc.heartbeat_period,
        PEER_SILENCE,
        SILENCE,
        // The time beacon's rate.
        Duration::from_secs(1),
    ]
    .into_iter()
    .max()
    .unwrap_or_default();
    longest + GRID
}

/// The FC's node as `fbwag fc-sim` sets it up: one listening link, to the
/// companion.
pub fn fc_node(cfg: FcConfig, now: Moment) -> FcNode {
    let mut node = FcNode::new(cfg, now).expect("the model's FC settings are valid");
    let spec = LinkSpec::new(Role::Peer, Answers::Chosen);
    node.add_link(FC_LINK, spec).expect("one link");
    node
}

/// The companion's node as `fbwag cc --fc udpin:... --trusted-out ...
/// --autonomy udpin:...` sets it up; the autonomy flies, a silent one declines.
pub fn cc_node(cfg: CcConfig, now: Moment) -> CompanionNode {
    let source = ControlSource::Autonomy {
        link: AUTONOMY_LINK,
        fallback: AutonomyFallback::Decline,
        silence: SILENCE,
    };
    let mut node = CompanionNode::new(cfg, source, now).expect("valid companion settings");
    let links = [
        (FC_LINK, Role::Peer, Answers::Chosen),
        (GROUND_LINK, Role::Ground, Answers::Target),
        (AUTONOMY_LINK, Role::Autonomy, Answers::Chosen),
    ];
    for (link, role, answers) in links {
        let trusted = link == GROUND_LINK;
        node.add_link(
            link,
            LinkSpec {
                trusted,
                ..LinkSpec::new(role, answers)
            },
        )
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
    /// The receiver comes back only while the FC flies RTL (a whole RC-loss
    /// cycle ends in the fallback before the next begins).
    pub rc_back_in_rtl: bool,
    /// FC restarts.
    pub fc_reboots: u8,
    /// The FC restarts only while it has been up at most this long: its
    /// uptime stamps its event ids and its sequence numbers restart, so
    /// until it can no longer restart, states at other uptimes stay apart
    /// (see [`crate::state`]).
    pub fc_reboot_window: Duration,
    /// Companion restarts.
    pub cc_reboots: u8,
    /// Duplicated frames.
    pub dups: u8,
    /// Changes of the autonomy (silent, speaking again).
    pub autonomy_flips: u8,
    /// A stranger without the key forges frames and replays what it
    /// captured, at any step, as often as it likes.
    pub stranger: bool,
    /// Virtual time explored, if bounded: a guard, for a fixpoint needs
    /// none, against a bug that keeps time going with ever new states (a
    /// retry counter without end); a search cut by it is no fixpoint.
    pub horizon: Option<Duration>,
    /// A planted fault, or none (the product as it is).
    pub fault: Option<Fault>,
}

impl ModelConfig {
    /// The world for showing a planted fault: the receiver fails once and
    /// the FC may restart; no duplicates, stranger, companion restarts or
    /// autonomy silences, so the search reaches the fault quickly.
    pub fn for_fault(fault: Fault) -> Self {
        ModelConfig {
            rc_flips: 1,
            fc_reboots: 1,
            cc_reboots: 0,
            dups: 0,
            stranger: false,
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
            rc_flips: 4,
            rc_back_in_rtl: false,
            fc_reboots: 1,
            fc_reboot_window: Duration::from_secs(8),
            cc_reboots: 1,
            dups: 1,
            autonomy_flips: 2,
            stranger: true,
            horizon: None,
            fault: None,
        }
    }
}
