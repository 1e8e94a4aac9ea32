//! Frames over UDP for the router's tests: making them, and finding them
//! among the datagrams a socket receives (the router may put several
//! frames in one).

use fbwag_dialect::mavframe::Encode;
use fbwag_dialect::{encode, Header, Signer, Version};
use std::net::UdpSocket;
use std::time::{Duration, Instant};

/// `msg` framed as MAVLink 2 from `sysid`/1, signed with `signer` if given.
pub fn frame(
    sysid: u8,
    seq: u8,
    msg: &(impl Encode + ?Sized),
    signer: Option<&mut Signer>,
) -> Vec<u8> {
    let mut buf = [0u8; fbwag_dialect::mavframe::frame::MAX_FRAME_LEN];
    let h = Header {
        seq,
        sysid,
        compid: 1,
    };
    let n = encode(Version::V2, h, msg, signer, &mut buf).unwrap();
    buf[..n].to_vec()
}

/// Every datagram `s` receives for `time`.
pub fn receive(s: &UdpSocket, time: Duration) -> Vec<Vec<u8>> {
    let end = Instant::now() + time;
    let mut got = Vec::new();
    let mut buf = [0u8; 2048];
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        s.set_read_timeout(Some(left.max(Duration::from_millis(1))))
            .unwrap();
        if let Ok(n) = s.recv(&mut buf) {
            got.push(buf[..n].to_vec());
        }
    }
    got
}

/// Every datagram `s` receives for `time`, then on until `done` holds of
/// them or `limit` (from the call) has passed: a loaded machine may
/// deliver what is waited for late.
pub fn receive_until(
    s: &UdpSocket,
    time: Duration,
    limit: Duration,
    done: impl Fn(&[Vec<u8>]) -> bool,
) -> Vec<Vec<u8>> {
    let end = Instant::now() + limit;
    let mut got = receive(s, time);
    let mut buf = [0u8; 2048];
    while !done(&got) {
        let Some(left) = end.checked_duration_since(Instant::now()) else {
            break;
        };
        s.set_read_timeout(Some(left.max(Duration::from_millis(1))))
            .unwrap();
        if let Ok(n) = s.recv(&mut buf) {
            got.push(buf[..n].to_vec());
        }
    }
    got
}

/// How often `frame` is among `datagrams`.
pub fn count(datagrams: &[Vec<u8>], frame: &[u8]) -> usize {
    datagrams
        .iter()
        .map(|d| d.windows(frame.len()).filter(|w| *w == frame).count())
        .sum()
}
