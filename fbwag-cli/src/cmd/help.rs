//! The long help texts: examples, and what the daemons' `--help` says
//! about links, peers, events and ground stations.

pub const EXAMPLES: &str = "\
Examples:
  echo fd0c0000000101993a0040e201000101014642574147d933 | fbwag decode --hex
  fbwag decode capture.bin > frames.jsonl
  fbwag decode --tlog flight.tlog | grep FBWAG_NOTICE
  fbwag decode capture.bin | fbwag encode > same.bin        # byte-exact
  fbwag encode --hex --sign-key $(printf '%064x' 0) --link-id 0 --sign-timestamp 1000 < frames.jsonl
  fbwag sim --table1                                        # the paper's Table I, 10,000 trials per row
  fbwag sim --scenario message-loss --loss 0.5 --trials 10000 --seed 7 --json
  fbwag sim --sweep --svg sweep.svg
  fbwag demo                                                # FC + companion over a lossy loopback relay
  fbwag cc --link serial:/dev/serial0:460800                # the companion daemon
  fbwag fc-sim --link udpout:127.0.0.1:14550 --rc-loss-at 3 --rc-back-at 12";

/// `--log-level` of the daemons.
pub const LOG_LEVEL: &str = "Log lines at this level and above: error, warn, notice, info, debug. \
Each line starts with the time (UTC, RFC 3339) and its level; under systemd (JOURNAL_STREAM \
names the output) with its syslog priority instead, <3> (error) to <7> (debug), which the \
journal files it by";

/// `--report` of the daemons.
pub const REPORT: &str = "Say in the log every this many seconds (0.1 or more) what each link \
took in, sent, refused (bad checksums, bad signatures, stale signing timestamps, unsigned \
frames) and lost, and what the node dropped; and write a status event then (--events). \
`off` or 0: no such lines, status events every 10 s";

/// The health events every daemon writes (`--events`).
macro_rules! health_events {
    () => {
        "
  {\"event\":\"link\",\"link\":NAME,\"state\":\"open\"|\"failed\"|\"retrying\"|\"recovered\",
   \"error\":TEXT (failed),\"down_s\":N (retrying, recovered)}   NAME: the link's NAME=,
                                          else its connection string; a failed
                                          link is opened again every second
  {\"event\":\"status\",\"links\":{NAME:{\"up\":B,\"frames_in\":N,\"frames_out\":N,
   \"refused\":{\"bad_checksum\":N,\"bad_signature\":N,\"stale_timestamp\":N,
   \"unsigned\":N,\"bad_flags\":N,\"bytes_dropped\":N},\"lost\":{\"queue_full\":N,
   \"routed\":N,\"send_errors\":N,\"state_saves\":N}},...},\"dropped\":{REASON:N,...}}
                                          every --report period (10 s; with
                                          --report off, 10 s) and at exit;
                                          totals since start. A wrong key shows
                                          as bad_signature; a clock or replays
                                          as stale_timestamp"
    };
}

/// What both daemons' `--help` says about links and peers.
macro_rules! link_rules {
    () => {
        "
Links and peers:
  Every send and receive error is logged (at most 5 lines per 10 s) and never
  ends the program. With udpin or tcpin, frames go to --peer if given;
  otherwise nothing is sent until a trusted frame arrives (the configured
  peer's ids, and a verified signature with --require-signed), then to that
  frame's source (for tcpin: that client; other clients get nothing); frames
  from any other address are dropped (counted as not_peer). A trusted frame
  from another address moves the peer only when its signature verified, or
  when the current peer has been silent for 3 s. A datagram without a valid
  frame changes nothing. udpout sockets are connected to their target: the
  system drops datagrams from anyone else. tcpin serves 32 clients at once:
  another evicts the one that has shown the least (nothing, then unsigned
  frames only), never the peer nor a client that sent a verified frame;
  --peer IP:0 matches a tcpin client from IP on any port. With a signing
  key, frames older than one minute (by their signing timestamp) are
  refused, and a frame accepted once is refused again on any
  connection."
    };
}

pub const CC_EVENTS: &str = concat!(
    "\
Events (--events), one JSON object per line, all with \"t_ms\" (ms since start)
and \"event\":",
    health_events!(),
    "
                                          and the companion's \"fc\": \"never
                                          heard\"|\"found\"|\"controlling\"|\"lost\",
                                          \"autonomy\", \"takeovers\"
  {\"event\":\"fc\",\"state\":\"found\"|\"lost\"|\"rebooted\"}   (never heard in a
                                          whole run: exit status 1)
  {\"event\":\"fc_mode\",\"mode\":\"FBWA\"|\"CIRCLE\"|\"FBWAG\"|\"RTL\"|...}
  {\"event\":\"control\",\"state\":\"start\",\"fc_event\":N}   the companion took over
  {\"event\":\"control\",\"state\":\"stop\"}
  {\"event\":\"takeover\",\"decision\":\"declined\",\"reason\":\"autonomy silent\",
   \"fc_event\":N}                           the autonomy was silent: the FC falls back
  {\"event\":\"takeover\",\"decision\":\"superseded\",\"by\":\"S/C\",\"fc_event\":N}
                                          the FC accepted another companion:
                                          this one stopped
  {\"event\":\"autonomy\",\"state\":\"silent\"|\"speaking\"}
  {\"event\":\"drops\",\"dropped\":{\"REASON\":N,...}}   frames dropped so far, by reason
                                          (own_ids, impersonation, unauthenticated,
                                          not_peer, gated, filtered, duplicate,
                                          protected), every --report period
                                          while they change
  {\"event\":\"summary\",\"takeovers\":N,\"handbacks\":N,\"trusted_frames\":N,
   \"untrusted_frames\":N,\"untrusted_notices\":N,\"controls_forwarded\":N,
   \"controls_dropped\":N,\"dropped\":{\"REASON\":N,...}}   at exit
                                          (with --tlog, also \"tlog\":{...} as below)
  {\"event\":\"tlog\",\"written\":N,\"dropped_queue_full\":N,\"not_written\":N,
   \"files\":N,\"deleted\":N}            --tlog: when log frames were lost (a disk
                                          too slow, or space below --tlog-min-free)
  {\"event\":\"dropped\",\"events\":N}   N events were dropped before this one:
                                          the reader had stopped reading (the
                                          daemon never waits for it; nor for
                                          its log, which says the same)
",
    link_rules!()
);

pub const ROUTER_EVENTS: &str = concat!(
    "\
Events (--events), one JSON object per line, all with \"t_ms\" (ms since start)
and \"event\":",
    health_events!(),
    "
  {\"event\":\"drops\",\"dropped\":{REASON:N,...},\"queue_dropped\":N}   every report
  {\"event\":\"tlog\",\"written\":N,...}   every report, with --tlog (see --tlog)
  {\"event\":\"flight_log\",\"written\":N,\"dropped_queue_full\":N,\"not_written\":N,
   \"files\":N,\"deleted\":N,\"logs\":N,\"acked\":N,\"nacked\":N,\"ahead\":N,
   \"strangers\":N}   every report, with --flight-log: blocks written, logs
                                          begun, blocks acknowledged and asked again,
                                          past the window, forged (not the vehicle's)
  {\"event\":\"summary\",\"frames\":N,\"forwarded\":N,\"dropped\":{...}}   at exit,
                                          with \"tlog\" and \"flight_log\" as above
"
);

pub const FC_EVENTS: &str = concat!(
    "\
Events (--events), one JSON object per line, all with \"t_ms\" (ms since start)
and \"event\":",
    health_events!(),
    "
                                          and fc-sim's \"mode\", \"armed\", \"receiver\"
  {\"event\":\"armed\",\"armed\":true}     at --arm-at
  {\"event\":\"mode\",\"mode\":\"FBWA\"|\"CIRCLE\"|\"FBWAG\"|\"RTL\"|...}   at start and every
                                          change (the pilot's: --pilot-mode)
  {\"event\":\"receiver\",\"state\":\"ok\"|\"lost\"}
  {\"event\":\"handover\",\"ms\":N}          receiver failure -> companion control
  {\"event\":\"control_applied\",\"sysid\":N,\"compid\":N,\"authenticated\":B,
   \"message\":\"RC_CHANNELS_OVERRIDE\"|..., \"channels\":[8 values]}   each control applied
  {\"event\":\"param\",\"name\":S,\"value\":X,\"sysid\":N,\"compid\":N}   a parameter set
  {\"event\":\"signing\",\"state\":\"on\"|\"off\",\"sysid\":N,\"compid\":N}   a key set
                                          by SETUP_SIGNING (refused while armed)
  {\"event\":\"summary\",\"trusted_frames\":N,\"untrusted_frames\":N,
   \"untrusted_notices\":N,\"controls_applied\":N,\"controls_untrusted\":N,
   \"controls_misaddressed\":N,\"controls_outside_companion\":N,
   \"gcs_unsigned_refused\":N, \"not_served\":{\"NAME\":N,...},
   \"dropped\":{\"REASON\":N,...}}   at exit
  {\"event\":\"dropped\",\"events\":N}   N events were dropped before this one:
                                          the reader had stopped reading (the
                                          daemon never waits for it; nor for
                                          its log, which says the same)

Ground stations:
  Served for any sender (with --require-signed: only frames whose signature
  verified, as ArduPilot on a signed link): every COMMAND_LONG/COMMAND_INT to
  this FC gets a COMMAND_ACK (ACCEPTED when done; UNSUPPORTED otherwise;
  DENIED, with a STATUSTEXT saying why, for mode changes, arming, RTL,
  landing, reboot and the like: the delegation engine decides who flies);
  AUTOPILOT_VERSION (MAV_CMD_REQUEST_MESSAGE, ..._AUTOPILOT_CAPABILITIES);
  MAV_CMD_REQUEST_MESSAGE/SET_MESSAGE_INTERVAL/GET_MESSAGE_INTERVAL and
  REQUEST_DATA_STREAM for the telemetry above (ATTITUDE at most 50 Hz, the
  rest at most 10 Hz: the protocol shares the link); HOME_POSITION (every 5 s
  and on request), GPS_GLOBAL_ORIGIN on request; the parameter protocol:
  FS_SHORT_ACTN (always 5, FBWAG), FS_SHORT_TIMEOUT, FS_LONG_ACTN (always 1,
  RTL), FS_LONG_TIMEOUT (the handshake timeout), SYSID_THISMAV,
  FBWAG_CC_SYSID, FBWAG_CC_COMPID, FBWAG_RETRY_TIME, FBWAG_RETRY_MAX,
  FBWAG_OVRD_TIME, FBWAG_CC_TIMEOUT, FBWAG_SIGNED (they decide who flies:
  writes take effect only while disarmed, see --arm-at, and the pilot flies,
  else are refused with a STATUSTEXT), AIRSPEED_CRUISE (the model's speed at
  trim throttle, 12-30 m/s, writable at any time); missions: a
  download is empty, an upload refused (but for an empty one); TIMESYNC.
  What is received and not served is logged (\"not served: ...\") and counted
  in the summary. On udpin and tcpin, answers go where every frame goes
  (--peer, or the companion's address): put a router (e.g. MAVProxy) between
  fc-sim and several ground stations.
",
    link_rules!()
);

/// `--signing-state` of both daemons.
pub const SIGNING_STATE: &str = "Keep the signing timestamps (this signer's, and each peer \
stream's) in this file across restarts, so a restart neither replays old timestamps nor \
accepts replays of frames accepted before (saved every second and at exit: SIGTERM, SIGINT, \
and SIGHUP from a terminal, stop the program as its end does; a damaged file, or one that cannot be written, stops the program: remove \
it to start from the clock). Without it, a restarted daemon accepts once, per stream, \
frames captured up to a minute before: use it whenever signing";

/// `--events` of both daemons.
pub const EVENTS: &str = "Write machine-readable events to this file (`-`: stdout), one JSON \
object per line (keys below). A FIFO is written once a reader opens it (events queue \
meanwhile, up to 4,096, then are counted as dropped); it never holds the daemon";
