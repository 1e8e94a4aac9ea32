//! Test programs on the daemons' side links: a UDP socket playing a ground
//! station or an autonomy program (it sends its own frames on a schedule
//! and keeps everything it receives), a crowd of TCP clients, and the
//! frames of a datagram read byte by byte (what a receiver sees on the
//! wire: the ids, the signed flag, the signature's length).
#![allow(dead_code)]

use std::io::Write;
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// MAVLink 2's start byte.
const STX_V2: u8 = 0xfd;
/// MAVLink 1's start byte.
const STX_V1: u8 = 0xfe;
/// MAVLink 2's incompatibility flag of a signed frame.
const IFLAG_SIGNED: u8 = 0x01;
/// A MAVLink 2 signature: link id, 6-byte timestamp, 6-byte hash.
pub const SIGNATURE_LEN: usize = 13;

/// One frame as it is on the wire.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawFrame {
    pub v2: bool,
    pub sysid: u8,
    pub compid: u8,
    pub msgid: u32,
    pub incompat: u8,
    pub payload: Vec<u8>,
    /// The signature block (empty when unsigned).
    pub signature: Vec<u8>,
}

impl RawFrame {
    /// MAVLink 2, the signed flag set, and a whole signature after it.
    pub fn is_signed(&self) -> bool {
        self.v2 && self.incompat & IFLAG_SIGNED != 0 && self.signature.len() == SIGNATURE_LEN
    }

    pub fn from(&self, sysid: u8, compid: u8) -> bool {
        (self.sysid, self.compid) == (sysid, compid)
    }

    /// The payload bytes at `at..at + N`, MAVLink 2's trailing zeros put
    /// back.
    fn bytes<const N: usize>(&self, at: usize) -> [u8; N] {
        let mut out = [0u8; N];
        for (i, b) in out.iter_mut().enumerate() {
            *b = self.payload.get(at + i).copied().unwrap_or(0);
        }
        out
    }

    pub fn u32_at(&self, at: usize) -> u32 {
        u32::from_le_bytes(self.bytes(at))
    }

    pub fn i32_at(&self, at: usize) -> i32 {
        i32::from_le_bytes(self.bytes(at))
    }

    /// A NUL-terminated char array of `len` bytes at `at`.
    pub fn text_at(&self, at: usize, len: usize) -> String {
        let raw: Vec<u8> = (0..len)
            .map(|i| self.payload.get(at + i).copied().unwrap_or(0))
            .take_while(|&b| b != 0)
            .collect();
        String::from_utf8_lossy(&raw).into_owned()
    }
}

/// The frames of a datagram, in order. Bytes that start no frame are
/// skipped (no checksum is checked: these are the daemons' own frames).
pub fn frames_in(mut d: &[u8]) -> Vec<RawFrame> {
    let mut out = Vec::new();
    while let Some(&stx) = d.first() {
        let parsed = match stx {
            STX_V2 if d.len() >= 12 => {
                let len = usize::from(d[1]);
                let incompat = d[2];
                let sig = if incompat & IFLAG_SIGNED != 0 {
                    SIGNATURE_LEN
                } else {
                    0
                };
                let end = (10 + len + 2 + sig).min(d.len());
                let frame = RawFrame {
                    v2: true,
                    sysid: d[5],
                    compid: d[6],
                    msgid: u32::from_le_bytes([d[7], d[8], d[9], 0]),
                    incompat,
                    payload: d[10..(10 + len).min(d.len())].to_vec(),
                    signature: d[(10 + len + 2).min(end)..end].to_vec(),
                };
                Some((frame, end))
            }
            STX_V1 if d.len() >= 8 => {
                let len = usize::from(d[1]);
                let end = (6 + len + 2).min(d.len());
                let frame = RawFrame {
                    v2: false,
                    sysid: d[3],
                    compid: d[4],
                    msgid: u32::from(d[5]),
                    incompat: 0,
                    payload: d[6..(6 + len).min(d.len())].to_vec(),
                    signature: Vec::new(),
                };
                Some((frame, end))
            }
            _ => None,
        };
        match parsed {
            Some((frame, end)) => {
                out.push(frame);
                d = &d[end..];
            }
            None => d = &d[1..],
        }
    }
    out
}

/// A datagram a [`Station`] received.
#[derive(Debug, Clone)]
pub struct Got {
    /// Since the station started.
    pub at: Duration,
    pub from: SocketAddr,
    pub bytes: Vec<u8>,
}

impl Got {
    pub fn frames(&self) -> Vec<RawFrame> {
        frames_in(&self.bytes)
    }
}

/// What a station sends every period (frames, each its own datagram),
/// given how many periods went before.
pub type Beat = Box<dyn FnMut(u64) -> Vec<Vec<u8>> + Send>;

/// A UDP socket on 127.0.0.1 playing a ground station or an autonomy
/// program: every `period` it sends what its [`Beat`] makes, to its target
/// (or, without one, to the last address it heard from), and it keeps
/// every datagram it receives. Stops when dropped.
pub struct Station {
    pub addr: SocketAddr,
    started: Instant,
    socket: UdpSocket,
    target: Arc<Mutex<Option<SocketAddr>>>,
    got: Arc<Mutex<Vec<Got>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Station {
    /// Bound to 127.0.0.1:`port` (0: any free port).
    pub fn start(port: u16, to: Option<SocketAddr>, period: Duration, mut beat: Beat) -> Station {
        let socket = UdpSocket::bind(("127.0.0.1", port)).expect("station socket");
        socket
            .set_read_timeout(Some(Duration::from_millis(5)))
            .expect("read timeout");
        let addr = socket.local_addr().expect("station address");
        let target = Arc::new(Mutex::new(to));
        let got = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let (socket2, target2, got2, stop2) = (
            socket.try_clone().expect("clone"),
            target.clone(),
            got.clone(),
            stop.clone(),
        );
        let started = Instant::now();
        let thread = std::thread::spawn(move || {
            let start = started;
            let (mut next, mut n) = (start, 0u64);
            let mut buf = [0u8; 65536];
            while !stop2.load(Ordering::Relaxed) {
                if Instant::now() >= next {
                    let to = *target2.lock().unwrap();
                    let frames = beat(n);
                    if let Some(to) = to {
                        for f in frames {
                            // A daemon not up yet: not sent.
                            let _ = socket2.send_to(&f, to);
                        }
                    }
                    n += 1;
                    next += period;
                }
                if let Ok((len, from)) = socket2.recv_from(&mut buf) {
                    target2.lock().unwrap().get_or_insert(from);
                    got2.lock().unwrap().push(Got {
                        at: start.elapsed(),
                        from,
                        bytes: buf[..len].to_vec(),
                    });
                }
            }
        });
        Station {
            addr,
            started,
            socket,
            target,
            got,
            stop,
            thread: Some(thread),
        }
    }

    /// A station that only listens (and answers nothing).
    pub fn listen(port: u16) -> Station {
        Station::start(
            port,
            None,
            Duration::from_secs(3600),
            Box::new(|_| Vec::new()),
        )
    }

    /// Sends `bytes` now, to the target or the last address heard; false
    /// when there is none yet.
    pub fn send(&self, bytes: &[u8]) -> bool {
        let to = *self.target.lock().unwrap();
        to.is_some_and(|to| self.socket.send_to(bytes, to).is_ok())
    }

    /// Time since it started (the clock of [`Got::at`]).
    pub fn elapsed(&self) -> Duration {
        self.started.elapsed()
    }

    /// Everything received so far.
    pub fn received(&self) -> Vec<Got> {
        self.got.lock().unwrap().clone()
    }

    /// Every frame received so far, with when.
    pub fn frames(&self) -> Vec<(Duration, RawFrame)> {
        self.received()
            .iter()
            .flat_map(|g| g.frames().into_iter().map(move |f| (g.at, f)))
            .collect()
    }
}

impl Drop for Station {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// TCP clients arriving at `to` one every `every`, each sending `hello`
/// once and then holding its connection; at most `keep` open (the oldest
/// closed first). Stops when dropped.
pub struct TcpCrowd {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<u64>>,
}

impl TcpCrowd {
    pub fn start(to: SocketAddr, every: Duration, keep: usize, hello: Vec<u8>) -> TcpCrowd {
        let stop = Arc::new(AtomicBool::new(false));
        let stop2 = stop.clone();
        let thread = std::thread::spawn(move || {
            let mut open: std::collections::VecDeque<TcpStream> = Default::default();
            let mut connected = 0u64;
            while !stop2.load(Ordering::Relaxed) {
                if let Ok(mut c) = TcpStream::connect_timeout(&to, Duration::from_millis(200)) {
                    let _ = c.write_all(&hello);
                    connected += 1;
                    open.push_back(c);
                    if open.len() > keep {
                        open.pop_front();
                    }
                }
                std::thread::sleep(every);
            }
            connected
        });
        TcpCrowd {
            stop,
            thread: Some(thread),
        }
    }

    /// Stops; how many connections were made.
    pub fn stop(mut self) -> u64 {
        self.stop.store(true, Ordering::Relaxed);
        self.thread
            .take()
            .map(|t| t.join().expect("crowd thread"))
            .unwrap_or(0)
    }
}

impl Drop for TcpCrowd {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
