//! The attacker's tools: what to send (floods, forged and signed frames),
//! a paced sender thread, a capturing relay (a tap on the link), and raw
//! datagrams from source port 0.
#![allow(dead_code)]

use fbwag_delegation::{wire, Peer, Status};
use fbwag_dialect::dialects::common::{ManualControl, RcChannelsOverride, SetAttitudeTarget};
use fbwag_dialect::mavframe::signing::timestamp_now;
use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Frame, Header, Signer, Version};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::net::{SocketAddr, UdpSocket};
use std::path::Path;
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

pub const FC: Peer = Peer::new(1, 1);
pub const CC: Peer = Peer::new(1, 191);
/// A ground station's ids (ArduPilot's default `SYSID_MYGCS` 255, and
/// MAV_COMP_ID_MISSIONPLANNER 190): ArduPlane would apply its overrides.
pub const GCS: Peer = Peer::new(255, 190);

/// The worst parser input the issue names: every start byte opens a
/// candidate that only fails at its checksum.
pub const WORST: [u8; 10] = [0xfe, 0xfe, 0xfe, 0xfd, 0xfd, 0x00, 0x00, 0xfe, 0x00, 0xfe];

/// The parser's worst input known (`found_k` of benches/src/worst.rs, stop
/// 24): an unsigned MAVLink 1 frame of unknown id 10, confirmed, after
/// eleven long 0xFE candidates and a 0xFD, every 20 bytes. Worst in small
/// reads, where each candidate's frame is cut by the datagram.
pub const FOUND_K: [u8; 20] = [
    0xfe, 0x00, 0xfe, 0xfe, 0xfd, 0x0a, 0x00, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe, 0xfe,
    0xfe, 0xfe, 0xfe, 0xfd,
];

/// Channel values no real controller in these tests sends: a control
/// applied with them came from the attacker.
pub const MARK: [u16; 8] = [1111, 1999, 1111, 1999, 1111, 1999, 1111, 1999];

/// The key the attacker signs with (not the daemons' key).
pub const WRONG_KEY: [u8; 32] = [0x42; 32];

/// `key` (64 hex digits) as bytes.
pub fn key_bytes(hex: &str) -> [u8; 32] {
    let mut k = [0u8; 32];
    for (i, b) in k.iter_mut().enumerate() {
        *b = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).expect("hex key");
    }
    k
}

/// One MAVLink 2 frame of `msg` from `from`, signed when `signer` is given.
pub fn frame(from: Peer, seq: u8, msg: &dyn Encode, signer: Option<&mut Signer>) -> Vec<u8> {
    let mut buf = [0u8; 300];
    let header = Header {
        seq,
        sysid: from.sysid,
        compid: from.compid,
    };
    let n = encode(Version::V2, header, msg, signer, &mut buf).expect("encode");
    buf[..n].to_vec()
}

/// The three kinds of control, addressed to the FC, with [`MARK`].
pub fn controls() -> [Box<dyn Encode + Send>; 3] {
    let [c1, c2, c3, c4, c5, c6, c7, c8] = MARK;
    [
        Box::new(RcChannelsOverride {
            target_system: FC.sysid,
            target_component: FC.compid,
            chan1_raw: c1,
            chan2_raw: c2,
            chan3_raw: c3,
            chan4_raw: c4,
            chan5_raw: c5,
            chan6_raw: c6,
            chan7_raw: c7,
            chan8_raw: c8,
            ..Default::default()
        }),
        Box::new(SetAttitudeTarget {
            target_system: FC.sysid,
            target_component: FC.compid,
            // A hard bank: roll ~ -0.78 rad, full thrust.
            q: [0.92, -0.38, 0.0, 0.0],
            thrust: 1.0,
            ..Default::default()
        }),
        Box::new(ManualControl {
            target: FC.sysid,
            x: -1000,
            y: 1000,
            z: 1000,
            r: -1000,
            ..Default::default()
        }),
    ]
}

/// True when a `control_applied` event carries the attacker's control: the
/// [`MARK`] channels, or what the attitude / manual forgeries map to (full
/// deflection of channel 1 at full throttle, which no test controller
/// sends).
pub fn is_attackers(channels: &[u64]) -> bool {
    let mark: Vec<u64> = MARK.iter().map(|&c| c as u64).collect();
    channels == mark.as_slice()
        || (channels.len() >= 3
            && (channels[0] <= 1010 || channels[0] >= 1990)
            && channels[2] >= 1990)
}

/// Garbage generators for a flood, each datagram `len` bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Garbage {
    /// Uniform random bytes.
    Random,
    /// Random bytes, half of them MAVLink start bytes (0xFD, 0xFE).
    StartDense,
    /// [`WORST`] repeated.
    Worst,
    /// [`FOUND_K`] repeated.
    FoundK,
    /// 10-byte MAVLink 2 headers announcing a long payload that never
    /// comes (one per datagram).
    FalseHeader,
}

impl Garbage {
    pub fn datagram(self, rng: &mut Pcg64, len: usize) -> Vec<u8> {
        match self {
            Garbage::Random => (0..len).map(|_| rng.gen()).collect(),
            Garbage::StartDense => (0..len)
                .map(|_| match rng.gen_range(0..4) {
                    0 => 0xfd,
                    1 => 0xfe,
                    _ => rng.gen(),
                })
                .collect(),
            Garbage::Worst => WORST.iter().copied().cycle().take(len).collect(),
            Garbage::FoundK => FOUND_K.iter().copied().cycle().take(len).collect(),
            Garbage::FalseHeader => {
                // Known ids, so the parser waits for the whole payload.
                let id: u32 = [15001, 70, 0, 253][rng.gen_range(0..4)];
                let from = [FC, CC][rng.gen_range(0..2)];
                let [a, b, c, _] = id.to_le_bytes();
                vec![
                    0xfd,
                    rng.gen_range(200..=255),
                    0,
                    0,
                    rng.gen(),
                    from.sysid,
                    from.compid,
                    a,
                    b,
                    c,
                ]
            }
        }
    }
}

/// Valid frames (good checksums) from strangers: other ids, or the right
/// ids signed with a wrong key. Protocol messages and control, all of which
/// a daemon must ignore.
pub fn stranger_frame(rng: &mut Pcg64, n: u64) -> Vec<u8> {
    let stranger = Peer::new(rng.gen_range(2..=250), rng.gen());
    let seq = n as u8;
    match n % 6 {
        0 => frame(
            stranger,
            seq,
            &wire::notice(FC, Status::RC_LOST, rng.gen()),
            None,
        ),
        1 => frame(
            stranger,
            seq,
            &wire::notice(FC, Status::CC_TAKEOVER_CONFIRMED, rng.gen()),
            None,
        ),
        2 => {
            let c = &controls()[rng.gen_range(0..3)];
            frame(stranger, seq, c.as_ref(), None)
        }
        3 => frame(
            stranger,
            seq,
            &wire::fc_heartbeat(fbwag_delegation::fc::Authority::Companion),
            None,
        ),
        // The right ids, signed with the wrong key: each costs the receiver
        // a SHA-256.
        4 => {
            let mut s = Signer::new(WRONG_KEY, 0, timestamp_now());
            frame(CC, seq, controls()[0].as_ref(), Some(&mut s))
        }
        _ => {
            let mut s = Signer::new(WRONG_KEY, 0, timestamp_now());
            frame(
                FC,
                seq,
                &wire::notice(FC, Status::RC_LOST, rng.gen()),
                Some(&mut s),
            )
        }
    }
}

/// What an attacker thread sent.
#[derive(Debug, Default, Clone, Copy)]
pub struct Sent {
    pub datagrams: u64,
    pub bytes: u64,
    /// Datagrams the daemons sent to the attacker: with a daemon that
    /// answers only its authenticated peer, none.
    pub received: u64,
    /// Of those, datagrams of one HEARTBEAT frame: a listening daemon's
    /// answer to a frame of its peer's ids signed with another key, while
    /// it has no peer.
    pub heartbeats: u64,
}

/// A thread sending datagrams from its own socket (127.0.0.1, a port of its
/// own) to some targets at a steady rate until stopped (also on drop).
pub struct Attacker {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Sent>>,
    /// The attacker's address: the daemons must never answer it.
    pub addr: SocketAddr,
    targets: Arc<Mutex<Vec<SocketAddr>>>,
}

impl Attacker {
    /// Sends `per_sec` datagrams a second to each target, each made by
    /// `gen(rng, n)` (n counts datagrams).
    pub fn start(
        targets: &[SocketAddr],
        per_sec: f64,
        seed: u64,
        mut gen: impl FnMut(&mut Pcg64, u64) -> Vec<u8> + Send + 'static,
    ) -> Attacker {
        let socket = UdpSocket::bind("127.0.0.1:0").expect("attacker socket");
        socket.set_nonblocking(true).expect("non-blocking");
        let addr = socket.local_addr().expect("attacker address");
        let stop = Arc::new(AtomicBool::new(false));
        let targets = Arc::new(Mutex::new(targets.to_vec()));
        let (stop2, targets2) = (stop.clone(), targets.clone());
        let thread = std::thread::spawn(move || {
            let mut rng = Pcg64::seed_from_u64(seed);
            let mut sent = Sent::default();
            let start = Instant::now();
            let mut n = 0u64;
            while !stop2.load(Ordering::Relaxed) {
                let due = (start.elapsed().as_secs_f64() * per_sec) as u64;
                // Behind schedule (a busy machine): skip ahead rather than
                // burst more than 20 ms worth.
                n = n.max(due.saturating_sub((per_sec * 0.02) as u64 + 1));
                let to: Vec<SocketAddr> = targets2.lock().unwrap().clone();
                while n < due {
                    let d = gen(&mut rng, n);
                    for t in &to {
                        // A daemon not up yet or gone (an ICMP error), or a
                        // full socket buffer: not sent.
                        if socket.send_to(&d, t).is_ok() {
                            sent.datagrams += 1;
                            sent.bytes += d.len() as u64;
                        }
                    }
                    n += 1;
                }
                let mut buf = [0u8; 2048];
                while let Ok((len, _)) = socket.recv_from(&mut buf) {
                    sent.received += 1;
                    let frame = Frame::new_checked(&buf[..len]);
                    if frame.is_ok_and(|f| f.msg_id() == 0 && f.frame_len() == len) {
                        sent.heartbeats += 1;
                    }
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            sent
        });
        Attacker {
            stop,
            thread: Some(thread),
            addr,
            targets,
        }
    }

    /// Also attacks `target` from now on.
    pub fn add_target(&self, target: SocketAddr) {
        self.targets.lock().unwrap().push(target);
    }

    /// Stops and says what was sent.
    pub fn stop(mut self) -> Sent {
        self.stop.store(true, Ordering::Relaxed);
        self.thread
            .take()
            .map(|t| t.join().expect("attacker thread"))
            .unwrap_or_default()
    }
}

impl Drop for Attacker {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Which way a captured datagram went.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dir {
    FcToCc,
    CcToFc,
}

/// Datagrams seen by a [`Tap`], in order.
pub type Capture = Vec<(Dir, Vec<u8>)>;

/// A tap: a relay between an `udpout` FC (which sends to
/// [`Tap::fc_side`]) and an `udpin` CC, forwarding everything both ways and
/// keeping a copy of every datagram.
pub struct Tap {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Capture>>,
    pub fc_side: SocketAddr,
}

impl Tap {
    pub fn start(cc: SocketAddr) -> Tap {
        let fc_socket = UdpSocket::bind("127.0.0.1:0").expect("tap");
        let cc_socket = UdpSocket::bind("127.0.0.1:0").expect("tap");
        let fc_side = fc_socket.local_addr().expect("tap address");
        for s in [&fc_socket, &cc_socket] {
            s.set_read_timeout(Some(Duration::from_millis(2)))
                .expect("timeout");
        }
        let stop = Arc::new(AtomicBool::new(false));
        let stop2 = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut seen = Vec::new();
            let mut fc = None;
            let mut buf = [0u8; 65536];
            while !stop2.load(Ordering::Relaxed) {
                if let Ok((n, from)) = fc_socket.recv_from(&mut buf) {
                    fc = Some(from);
                    seen.push((Dir::FcToCc, buf[..n].to_vec()));
                    let _ = cc_socket.send_to(&buf[..n], cc);
                }
                if let (Ok((n, _)), Some(fc)) = (cc_socket.recv_from(&mut buf), fc) {
                    seen.push((Dir::CcToFc, buf[..n].to_vec()));
                    let _ = fc_socket.send_to(&buf[..n], fc);
                }
            }
            seen
        });
        Tap {
            stop,
            thread: Some(thread),
            fc_side,
        }
    }

    /// Stops and returns the capture.
    pub fn stop(mut self) -> Capture {
        self.stop.store(true, Ordering::Relaxed);
        self.thread
            .take()
            .map(|t| t.join().expect("tap thread"))
            .unwrap_or_default()
    }
}

impl Drop for Tap {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// How fast the `fbwag` binary under test parses `sample` (bytes/s),
/// through `fbwag decode` on a file in `dir`, growing the input until one
/// run takes 150 ms. Sets a flood's rate relative to what the daemon can
/// take (the test build is unoptimised, and the parser's speed on its worst
/// input is being changed on another branch), so a flood loads the daemon
/// the same share whatever the build. Never asserted.
pub fn parse_rate(dir: &Path, sample: &[u8]) -> f64 {
    let file = dir.join("calibration.bin");
    let mut len = 4096;
    loop {
        let data: Vec<u8> = sample.iter().copied().cycle().take(len).collect();
        std::fs::write(&file, &data).expect("calibration file");
        let t = Instant::now();
        let out = Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .arg("decode")
            .arg(&file)
            .output()
            .expect("fbwag decode");
        let took = t.elapsed();
        // 1: no frame decoded (garbage); anything else is a failure.
        assert!(
            matches!(out.status.code(), Some(0 | 1)),
            "fbwag decode failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        if took >= Duration::from_millis(150) || len >= 64 << 20 {
            return len as f64 / took.as_secs_f64();
        }
        len *= 4;
    }
}

/// Sends `payload` to `to` as one UDP datagram whose source port is 0,
/// through a raw socket (root only). `Err` says why it could not.
pub fn send_from_port_zero(to: SocketAddr, payload: &[u8]) -> std::io::Result<()> {
    use socket2::{Domain, Protocol, SockAddr, Socket, Type};
    let socket = Socket::new(Domain::IPV4, Type::RAW, Some(Protocol::UDP))?;
    // The UDP header: source port 0, destination, length; checksum 0 means
    // "none" in IPv4. The kernel adds the IP header.
    let len = (8 + payload.len()) as u16;
    let mut d = Vec::with_capacity(len as usize);
    d.extend_from_slice(&0u16.to_be_bytes());
    d.extend_from_slice(&to.port().to_be_bytes());
    d.extend_from_slice(&len.to_be_bytes());
    d.extend_from_slice(&0u16.to_be_bytes());
    d.extend_from_slice(payload);
    socket.send_to(&d, &SockAddr::from(to))?;
    Ok(())
}

/// An attacker on the path: a relay between an `udpout` FC (which sends to
/// [`OnPath::fc_side`]) and an `udpin` CC that forwards everything both
/// ways and also sends datagrams of its own to both daemons at a steady
/// rate. They come from the address each daemon hears its peer from (what
/// a radio on the link, or a switch between the daemons, can do), so its
/// frames reach the engines, and only signing tells them from the peer's.
pub struct OnPath {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Sent>>,
    pub fc_side: SocketAddr,
}

impl OnPath {
    /// Relays between the FC and the CC at `cc`, sending `per_sec` datagrams
    /// a second to each daemon, each made by `gen(rng, n)` (to the FC only
    /// once it has spoken: its address is not known before).
    pub fn start(
        cc: SocketAddr,
        per_sec: f64,
        seed: u64,
        mut gen: impl FnMut(&mut Pcg64, u64) -> Vec<u8> + Send + 'static,
    ) -> OnPath {
        let fc_socket = UdpSocket::bind("127.0.0.1:0").expect("relay");
        let cc_socket = UdpSocket::bind("127.0.0.1:0").expect("relay");
        let fc_side = fc_socket.local_addr().expect("relay address");
        for s in [&fc_socket, &cc_socket] {
            s.set_nonblocking(true).expect("non-blocking");
        }
        let stop = Arc::new(AtomicBool::new(false));
        let stop2 = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut rng = Pcg64::seed_from_u64(seed);
            let mut sent = Sent::default();
            let (start, mut n, mut fc) = (Instant::now(), 0u64, None);
            let mut buf = [0u8; 65536];
            while !stop2.load(Ordering::Relaxed) {
                while let Ok((len, from)) = fc_socket.recv_from(&mut buf) {
                    fc = Some(from);
                    sent.received += 1;
                    let _ = cc_socket.send_to(&buf[..len], cc);
                }
                while let Ok(len) = cc_socket.recv(&mut buf) {
                    sent.received += 1;
                    if let Some(fc) = fc {
                        let _ = fc_socket.send_to(&buf[..len], fc);
                    }
                }
                let due = (start.elapsed().as_secs_f64() * per_sec) as u64;
                // Behind schedule: skip ahead rather than burst (as Attacker).
                n = n.max(due.saturating_sub((per_sec * 0.02) as u64 + 1));
                while n < due {
                    let d = gen(&mut rng, n);
                    let to_fc = fc.map(|fc| (&fc_socket, fc));
                    for (socket, to) in [Some((&cc_socket, cc)), to_fc].into_iter().flatten() {
                        if socket.send_to(&d, to).is_ok() {
                            sent.datagrams += 1;
                            sent.bytes += d.len() as u64;
                        }
                    }
                    n += 1;
                }
                std::thread::sleep(Duration::from_millis(1));
            }
            sent
        });
        OnPath {
            stop,
            thread: Some(thread),
            fc_side,
        }
    }

    /// Stops and says what it sent of its own (`received`: the datagrams it
    /// relayed).
    pub fn stop(mut self) -> Sent {
        self.stop.store(true, Ordering::Relaxed);
        self.thread
            .take()
            .map(|t| t.join().expect("relay thread"))
            .unwrap_or_default()
    }
}

impl Drop for OnPath {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
