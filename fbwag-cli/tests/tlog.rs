//! `--tlog DIR`: `fbwag router` writes every frame it routes to .tlog files
//! (8-byte big-endian µs timestamp, then the frame), in order; `fbwag
//! decode --tlog` and pymavlink's mavlogdump.py read them back; files
//! rotate at `--tlog-max-size`; below `--tlog-min-free` the router's own
//! old logs are deleted, no other file is, and writing stops while routing
//! goes on. Every link is on 127.0.0.1; each router runs a few seconds.

mod common;

use common::{fbwag, free_port, peer_python, udp_port_bound, Proc};
use fbwag_delegation::wire;
use fbwag_dialect::dialects::minimal::Heartbeat;
use fbwag_dialect::{encode, Header, Version};
use serde_json::Value;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// A HEARTBEAT from `sysid`/1 whose custom_mode is `n`, numbered `n`.
fn heartbeat(sysid: u8, n: u32) -> Vec<u8> {
    let hb = Heartbeat {
        custom_mode: n,
        ..wire::cc_heartbeat()
    };
    let header = Header {
        seq: n as u8,
        sysid,
        compid: 1,
    };
    let mut buf = [0u8; 300];
    let len = encode(Version::V2, header, &hb, None, &mut buf).expect("encode");
    buf[..len].to_vec()
}

/// A fresh directory for one test's files.
fn scratch(name: &str) -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("tlog-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The router's .tlog files in `dir`, by name.
fn own_logs(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let name = p.file_name().unwrap().to_str().unwrap();
            name.starts_with("fbwag-router-2") && name.ends_with("Z.tlog")
        })
        .collect();
    files.sort();
    files
}

/// The records of a tlog: (timestamp, frame), read by the format's rule
/// (a MAVLink 2 frame's length from its header); a record cut short fails.
fn records(bytes: &[u8]) -> Vec<(u64, Vec<u8>)> {
    let mut out = Vec::new();
    let mut at = 0;
    while at < bytes.len() {
        let ts = u64::from_be_bytes(bytes[at..at + 8].try_into().unwrap());
        let frame = &bytes[at + 8..];
        assert_eq!(frame[0], 0xFD, "record at {at} is not a MAVLink 2 frame");
        let signed = if frame[2] & 1 != 0 { 13 } else { 0 };
        let len = 12 + frame[1] as usize + signed;
        out.push((ts, frame[..len].to_vec()));
        at += 8 + len;
    }
    out
}

/// A router of two udpin links logging to `dir` for `seconds`; the
/// receiver on the second link speaks first, so it is answered; then
/// `count` heartbeats from sysid 1 go in on the first link, 2 ms apart.
/// The router's exit, its log, its events file and the frames the receiver
/// got.
struct Run {
    status: std::process::ExitStatus,
    log: String,
    events: Vec<Value>,
    sent: Vec<Vec<u8>>,
    received: usize,
}

fn route(dir: &Path, seconds: &str, count: u32, extra: &[&str]) -> Run {
    route_by(
        Command::new(env!("CARGO_BIN_EXE_fbwag")),
        dir,
        seconds,
        count,
        extra,
    )
}

/// [`route`], the router started by `fbwag` (the program, or a shell that
/// runs it).
fn route_by(mut fbwag: Command, dir: &Path, seconds: &str, count: u32, extra: &[&str]) -> Run {
    let (a, b) = (free_port(), free_port());
    let events = dir.join("events.jsonl");
    let router = Proc::spawn(
        fbwag
            .arg("router")
            .args([a, b].map(|p| format!("udpin:127.0.0.1:{p}")))
            .arg("--tlog")
            .arg(dir.join("logs"))
            .args(["--duration", seconds, "--report", "1", "--events"])
            .arg(&events)
            .args(extra),
    );
    // One registration heartbeat only (the log's first record): sent
    // once the router listens, not after a guess at its start-up time.
    assert!(
        udp_port_bound(a) && udp_port_bound(b),
        "the router never listened"
    );
    let receiver = UdpSocket::bind("127.0.0.1:0").unwrap();
    receiver
        .set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    receiver
        .send_to(&heartbeat(2, 1_000_000), ("127.0.0.1", b))
        .unwrap();
    std::thread::sleep(Duration::from_millis(200));
    let sender = UdpSocket::bind("127.0.0.1:0").unwrap();
    let sent: Vec<Vec<u8>> = (0..count).map(|n| heartbeat(1, n)).collect();
    let mut received = 0;
    let mut buf = [0u8; 2048];
    // The router puts frames queued together into one datagram: count
    // frames (all of one length), not datagrams.
    let frames = |len: usize| {
        assert_eq!(len % sent[0].len(), 0, "a datagram of whole frames");
        len / sent[0].len()
    };
    for frame in &sent {
        sender.send_to(frame, ("127.0.0.1", a)).unwrap();
        std::thread::sleep(Duration::from_millis(2));
        receiver.set_nonblocking(true).unwrap();
        while let Ok(len) = receiver.recv(&mut buf) {
            received += frames(len);
        }
        receiver.set_nonblocking(false).unwrap();
    }
    // The last frames may still be on their way on a loaded machine: wait
    // for them until the router's run is nearly over, not for one gap.
    let deadline = Instant::now() + Duration::from_secs(2);
    while received < sent.len() && Instant::now() < deadline {
        if let Ok(len) = receiver.recv(&mut buf) {
            received += frames(len);
        }
    }
    let out = router.finish(Duration::from_secs(10));
    let events = std::fs::read_to_string(&events)
        .unwrap_or_default()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    Run {
        status: out.status,
        log: String::from_utf8_lossy(&out.stdout).into_owned()
            + &String::from_utf8_lossy(&out.stderr),
        events,
        sent,
        received,
    }
}

impl Run {
    fn summary_tlog(&self) -> &Value {
        let s = self.events.iter().find(|e| e["event"] == "summary");
        &s.unwrap_or_else(|| panic!("no summary:\n{}", self.log))["tlog"]
    }
}

fn now_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap()
        .as_micros() as u64
}

#[test]
fn routed_frames_are_logged_in_order_and_read_back() {
    let dir = scratch("order");
    let start = now_us();
    let run = route(&dir, "3", 200, &[]);
    let end = now_us();
    assert!(run.status.success(), "{}", run.log);
    assert_eq!(run.received, 200, "every frame routed: {}", run.log);
    let files = own_logs(&dir.join("logs"));
    assert_eq!(files.len(), 1, "{files:?}\n{}", run.log);
    let bytes = std::fs::read(&files[0]).unwrap();
    let recs = records(&bytes);
    // The receiver's heartbeat (link 1), then the sender's 200 (link 0),
    // byte for byte, in order, stamped with the wall clock in order.
    assert_eq!(recs.len(), 201, "{}", run.log);
    assert_eq!(recs[0].1, heartbeat(2, 1_000_000));
    assert_eq!(recs[0].0 & 3, 1, "link 1 in the low bits");
    for (k, (ts, frame)) in recs[1..].iter().enumerate() {
        assert_eq!(frame, &run.sent[k], "record {}", k + 1);
        assert_eq!(ts & 3, 0, "link 0 in the low bits");
    }
    assert!(recs.windows(2).all(|w| w[0].0 & !3 <= w[1].0 & !3));
    assert!(recs[0].0 >= start & !3 && recs[200].0 <= end);
    assert_eq!(run.summary_tlog()["written"], 201, "{}", run.log);
    assert_eq!(run.summary_tlog()["dropped_queue_full"], 0);
    assert!(
        run.log.contains("tlog: 201 frames written (1 files begun)"),
        "{}",
        run.log
    );

    // `fbwag decode --tlog` reads the same records, timestamps included.
    let file = files[0].to_str().unwrap();
    let (out, err, code) = fbwag(&["decode", "--tlog", file], b"");
    assert_eq!(code, Some(0), "{err}");
    let lines: Vec<Value> = std::str::from_utf8(&out)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 201, "{err}");
    for (line, (ts, _)) in lines.iter().zip(&recs) {
        assert_eq!(line["tlog_us"], *ts);
        assert_eq!(line["name"], "HEARTBEAT");
    }
    let modes: Vec<u64> = lines[1..]
        .iter()
        .map(|l| l["fields"]["custom_mode"].as_u64().unwrap())
        .collect();
    assert_eq!(modes, (0..200).collect::<Vec<u64>>());

    // pymavlink's mavlogdump.py reads it as a tlog: every frame, in order,
    // on the link the low bits name.
    let Some(py) = peer_python() else {
        return;
    };
    let dump = py.parent().unwrap().join("mavlogdump.py");
    let mavlogdump = |link: &str| {
        let out = Command::new(&py)
            .arg(&dump)
            .args(["--format", "json", "--link", link, file])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8(out.stdout)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str::<Value>(l).unwrap())
            .collect::<Vec<_>>()
    };
    let link0 = mavlogdump("0");
    assert_eq!(link0.len(), 200);
    for (k, m) in link0.iter().enumerate() {
        assert_eq!(m["meta"]["type"], "HEARTBEAT");
        assert_eq!(m["data"]["custom_mode"], k as u64);
        let t = m["meta"]["timestamp"].as_f64().unwrap();
        assert!((t - recs[k + 1].0 as f64 * 1e-6).abs() < 1e-3, "{t}");
    }
    let link1 = mavlogdump("1");
    assert_eq!(link1.len(), 1);
    assert_eq!(link1[0]["data"]["custom_mode"], 1_000_000);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn files_rotate_before_they_pass_the_size() {
    let dir = scratch("rotate");
    let run = route(&dir, "3", 300, &["--tlog-max-size", "2K"]);
    assert!(run.status.success(), "{}", run.log);
    let files = own_logs(&dir.join("logs"));
    let sizes: Vec<u64> = files
        .iter()
        .map(|f| std::fs::metadata(f).unwrap().len())
        .collect();
    // 301 records of 29 bytes: 70 to a file of 2,048 bytes at most.
    let record = 8 + heartbeat(1, 0).len() as u64;
    assert_eq!(record, 29);
    assert_eq!(files.len(), 5, "{sizes:?}\n{}", run.log);
    for size in &sizes[..4] {
        assert!(*size <= 2048 && size + record > 2048, "{sizes:?}");
    }
    // The files in name order hold the frames in order.
    let mut all = Vec::new();
    for f in &files {
        all.extend(records(&std::fs::read(f).unwrap()));
    }
    assert_eq!(all.len(), 301);
    for (k, (_, frame)) in all[1..].iter().enumerate() {
        assert_eq!(frame, &run.sent[k], "record {}", k + 1);
    }
    assert_eq!(run.summary_tlog()["files"], 5, "{}", run.log);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A file that cannot grow (the process's file size limit, as a full
/// disk or an I/O error would do): the router goes on routing every frame
/// (the limit's SIGXFSZ would end it), keeps the file it wrote, cut back
/// to whole records, makes no new file per frame, says so once, and its
/// counts are what the file holds.
#[test]
fn a_file_that_cannot_grow_is_kept_whole_and_counted_true() {
    let dir = scratch("fsize");
    let mut shell = Command::new("sh");
    // 4 blocks of 512 or 1,024 bytes (the shell's unit): 70 or 141 records.
    shell.args(["-c", "ulimit -f 4 && exec \"$0\" \"$@\""]);
    shell.arg(env!("CARGO_BIN_EXE_fbwag"));
    // Frames for about 4 s: a new file a second after each failure, and
    // after 3 failed files in a row, none (before, one every second for
    // as long as frames came).
    let count = 1800;
    // Few events (the events file is under the same limit): no report.
    let run = route_by(
        shell,
        &dir,
        "6",
        count,
        &["--tlog-min-free", "0", "--report", "off"],
    );
    assert!(run.status.success(), "{:?}\n{}", run.status, run.log);
    assert_eq!(run.received, count as usize, "routing goes on: {}", run.log);
    let files = own_logs(&dir.join("logs"));
    assert!((1..=3).contains(&files.len()), "{files:?}\n{}", run.log);
    let mut kept = 0;
    for f in &files {
        let bytes = std::fs::read(f).unwrap();
        assert_eq!(bytes.len() % 29, 0, "whole records: {}", bytes.len());
        kept += records(&bytes).len() as u64;
    }
    assert!(kept >= 70, "{kept} records\n{}", run.log);
    let t = run.summary_tlog();
    assert_eq!(t["written"], kept, "{}", run.log);
    assert_eq!(t["not_written"], u64::from(count) + 1 - kept, "{}", run.log);
    assert_eq!(t["files"], files.len(), "{}", run.log);
    let said = run.log.matches("tlog: cannot write").count();
    assert!((1..=files.len()).contains(&said), "{}", run.log);
    assert_eq!(run.log.matches("tlog: given up").count(), 1, "{}", run.log);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A log directory that cannot be made (here its name is a file's; a
/// card mounted read-only does the same): said once, and routing goes on.
#[test]
fn a_log_directory_that_cannot_be_made_leaves_routing_alone() {
    let dir = scratch("nodir");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("logs"), b"a file").unwrap();
    let run = route(&dir, "2", 50, &[]);
    assert!(run.status.success(), "{}", run.log);
    assert_eq!(run.received, 50, "{}", run.log);
    assert_eq!(
        run.log.matches("tlog: cannot create").count(),
        1,
        "{}",
        run.log
    );
    let t = run.summary_tlog();
    assert_eq!(t["written"], 0, "{}", run.log);
    assert_eq!(t["not_written"], 51, "{}", run.log);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The free space of `dir`'s file system, from `df`.
fn free_space(dir: &Path) -> Option<u64> {
    let out = Command::new("df")
        .args(["-B1", "--output=avail"])
        .arg(dir)
        .output()
        .ok()?;
    String::from_utf8(out.stdout)
        .ok()?
        .lines()
        .nth(1)?
        .trim()
        .parse()
        .ok()
}

#[test]
fn at_the_floor_only_own_old_logs_go_and_writing_stops_while_routing_goes_on() {
    let dir = scratch("floor");
    let logs = dir.join("logs");
    std::fs::create_dir_all(&logs).unwrap();
    let own = [
        "fbwag-router-20200101T000000.000000Z.tlog",
        "fbwag-router-20200101T000001.000000Z.tlog",
    ];
    let foreign = [
        "fbwag-cc-20200101T000000.000000Z.tlog",
        "fbwag-router-notes.tlog",
        "flight.tlog",
        "fbwag-router-20200101T000002.000000Z.tlog.bak",
    ];
    for name in own.iter().chain(&foreign) {
        std::fs::write(logs.join(name), [0u8; 4096]).unwrap();
    }
    // A floor above what the file system has free: nothing can keep it.
    let free = free_space(&logs).expect("df");
    let floor = (free + (1 << 30)).to_string();
    let run = route(&dir, "3", 100, &["--tlog-min-free", &floor]);
    assert!(run.status.success(), "{}", run.log);
    assert_eq!(run.received, 100, "routing goes on: {}", run.log);
    for name in own {
        assert!(!logs.join(name).exists(), "{name} kept\n{}", run.log);
    }
    for name in foreign {
        assert!(logs.join(name).exists(), "{name} deleted\n{}", run.log);
    }
    assert!(own_logs(&logs).is_empty(), "{}", run.log);
    assert_eq!(
        run.log.matches("tlog: stopped writing").count(),
        1,
        "{}",
        run.log
    );
    let t = run.summary_tlog();
    assert_eq!(t["deleted"], 2, "{}", run.log);
    assert_eq!(t["written"], 0);
    assert_eq!(t["not_written"], 101);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_tlog_cut_short_is_an_error_naming_the_offset() {
    let mut tlog = Vec::new();
    for n in 0..3 {
        tlog.extend_from_slice(&(1_000 + u64::from(n)).to_be_bytes());
        tlog.extend_from_slice(&heartbeat(1, n));
    }
    let whole = tlog.len();
    for (cut, left, needed) in [(5, 24, 29), (25, 4, 9), (21, 8, 14), (18, 11, 18)] {
        let (out, err, code) = fbwag(&["decode", "--tlog"], &tlog[..whole - cut]);
        assert_eq!(code, Some(2), "{err}");
        let lines = std::str::from_utf8(&out).unwrap().lines().count();
        assert_eq!(lines, 2, "the records before are decoded: {err}");
        assert!(
            err.contains(&format!(
                "the record at byte offset 58 has {left} bytes, it needs at least {needed}"
            )),
            "cut {cut}: {err}"
        );
    }
}

/// Garbage between records costs only its own bytes: a start byte in it
/// that claims a long frame of an unknown id does not swallow the good
/// records behind it, and a record whose length byte was flipped costs
/// that record alone. The summary counts the frames printed.
#[test]
fn garbage_in_a_tlog_costs_only_its_own_bytes() {
    let record = |n: u32| {
        let mut r = (1_000 + u64::from(n)).to_be_bytes().to_vec();
        r.extend_from_slice(&heartbeat(1, n));
        r
    };
    let mut tlog = Vec::new();
    for n in 0..20 {
        if n == 5 {
            tlog.extend_from_slice(b"\x00garbage\xfd\xff");
        }
        let mut r = record(n);
        if n == 12 {
            r[9] = 200; // The frame's length byte.
        }
        tlog.extend_from_slice(&r);
    }
    let (out, err, code) = fbwag(&["decode", "--tlog"], &tlog);
    assert_eq!(code, Some(1), "bytes were skipped: {err}");
    let modes: Vec<u64> = std::str::from_utf8(&out)
        .unwrap()
        .lines()
        .map(|l| {
            serde_json::from_str::<Value>(l).unwrap()["fields"]["custom_mode"]
                .as_u64()
                .unwrap()
        })
        .collect();
    let want: Vec<u64> = (0..20).filter(|n| *n != 12).collect();
    assert_eq!(modes, want, "{err}");
    assert!(err.starts_with("decoded 19 frames"), "{err}");
    assert!(err.contains("tlog: 19 records"), "{err}");

    // Near the end, a start byte claiming more bytes than are left is
    // garbage too when whole records follow it, not a cut record.
    let mut tail = record(0);
    tail.extend_from_slice(b"\x00\x01\x02\x03\x04\x05\x06\x07\xfd\xff");
    for n in 1..4 {
        tail.extend_from_slice(&record(n));
    }
    let (out, err, code) = fbwag(&["decode", "--tlog"], &tail);
    assert_eq!(code, Some(1), "{err}");
    assert_eq!(
        std::str::from_utf8(&out).unwrap().lines().count(),
        4,
        "{err}"
    );
    assert!(err.contains("tlog: 4 records, 10 unreadable"), "{err}");
}

#[test]
fn the_companion_logs_the_fc_frames_it_takes_and_its_own() {
    let dir = scratch("cc");
    let fc = UdpSocket::bind("127.0.0.1:0").unwrap();
    fc.set_read_timeout(Some(Duration::from_millis(100)))
        .unwrap();
    let port = fc.local_addr().unwrap().port();
    let cc = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(["cc", "--link", &format!("udpout:127.0.0.1:{port}")])
            .arg("--tlog")
            .arg(&dir)
            .args(["--duration", "2.5"]),
    );
    // The FC answers each frame of the companion with a heartbeat.
    let mut sent = Vec::new();
    let mut buf = [0u8; 2048];
    let end = std::time::Instant::now() + Duration::from_secs(2);
    while std::time::Instant::now() < end {
        if let Ok((_, from)) = fc.recv_from(&mut buf) {
            let hb = heartbeat(1, sent.len() as u32);
            fc.send_to(&hb, from).unwrap();
            sent.push(hb);
        }
    }
    let out = cc.finish(Duration::from_secs(5));
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    let files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(files.len(), 1, "{files:?}\n{log}");
    let name = files[0].file_name().unwrap().to_str().unwrap();
    assert!(name.starts_with("fbwag-cc-"), "{name}");
    let recs = records(&std::fs::read(&files[0]).unwrap());
    let fc_frames: Vec<&Vec<u8>> = recs
        .iter()
        .filter(|(ts, _)| ts & 3 == 0)
        .map(|(_, f)| f)
        .collect();
    assert!(!sent.is_empty(), "{log}");
    assert_eq!(fc_frames, sent.iter().collect::<Vec<_>>(), "{log}");
    // The companion's own heartbeats: from 1/191, marked 3.
    let own = recs
        .iter()
        .filter(|(ts, f)| ts & 3 == 3 && f[5..7] == [1, 191] && f[7..10] == [0, 0, 0])
        .count();
    assert!(own >= 2, "{own} own heartbeats\n{log}");
    assert!(log.contains("tlog: "), "{log}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_limits_are_checked_and_need_a_directory() {
    let links = ["router", "udpin:127.0.0.1:9", "udpin:127.0.0.1:10"];
    let with = |extra: &[&str]| {
        let args: Vec<&str> = links.iter().chain(extra).copied().collect();
        fbwag(&args, b"")
    };
    let (_, err, code) = with(&["--tlog", "/nonexistent", "--tlog-max-size", "64X"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("size in bytes"), "{err}");
    // Smaller than one record of the largest frame: refused, not rounded.
    let (_, err, code) = with(&["--tlog", "/nonexistent", "--tlog-max-size", "100"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("from 288"), "{err}");
    let (_, err, code) = with(&["--tlog-min-free", "1G"]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--tlog <DIR>"), "{err}");
}

/// The router's own files of `suffix` (`Z.bin`, `Z.tlog`) in `dir`, by
/// name.
fn own_files(dir: &Path, suffix: &str) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let name = p.file_name().unwrap().to_str().unwrap();
            name.starts_with("fbwag-router-2") && name.ends_with(suffix)
        })
        .collect();
    files.sort();
    files
}

/// A REMOTE_LOG_DATA_BLOCK numbered `seqno`, claiming to be the FC's log
/// (1/110) for the router (1/192): a stranger's, on another link.
fn forged_block(seqno: u32) -> Vec<u8> {
    use fbwag_dialect::dialects::ardupilotmega::{
        MavRemoteLogDataBlockCommands, RemoteLogDataBlock,
    };
    let block = RemoteLogDataBlock {
        target_system: 1,
        target_component: 192,
        seqno: MavRemoteLogDataBlockCommands(seqno),
        data: [0xa3; 200],
    };
    let header = Header {
        seq: seqno as u8,
        sysid: 1,
        compid: 110,
    };
    let mut buf = [0u8; 300];
    let len = encode(Version::V2, header, &block, None, &mut buf).expect("encode");
    buf[..len].to_vec()
}

/// mavlink-router's `Log =` with `LogTelemetry`, `LogMode = while-armed`
/// and `MaxLogFiles`, read from its own file: fc-sim, armed at 1 s,
/// sends its DataFlash log over MAVLink once the router asks; the router
/// writes it to a .bin that pymavlink's DFReader (mavlogdump.py) reads
/// back, FMT to ATT, and logs telemetry only while armed; of its older
/// files of each kind it keeps one (two with the new one), others' files
/// untouched; blocks a stranger forges on another link are counted, not
/// written.
#[test]
fn the_flight_stacks_log_is_received_while_armed_and_read_back_by_dfreader() {
    let dir = scratch("flight-log");
    let logs = dir.join("logs");
    std::fs::create_dir_all(&logs).unwrap();
    let old = |n: u32, kind: &str| format!("fbwag-router-2020010{n}T000000.000000Z.{kind}");
    for n in 1..=3 {
        for kind in ["bin", "tlog"] {
            std::fs::write(logs.join(old(n, kind)), b"old").unwrap();
        }
    }
    std::fs::write(
        logs.join("00000-2020-01-01_00-00-00.bin"),
        b"mavlink-router's",
    )
    .unwrap();
    let (fc_port, gcs_port) = (free_port(), free_port());
    let gcs = UdpSocket::bind(("127.0.0.1", gcs_port)).unwrap();
    let conf = dir.join("main.conf");
    std::fs::write(
        &conf,
        format!(
            "[General]\nLog = {}\nLogTelemetry = true\nLogMode = while-armed\n\
             MaxLogFiles = 2\nMinFreeSpace = 0\nMavlinkDialect = ardupilotmega\n\
             [UdpEndpoint fc]\nMode = Server\nAddress = 127.0.0.1\nPort = {fc_port}\n\
             [UdpEndpoint gcs]\nMode = Normal\nAddress = 127.0.0.1\nPort = {gcs_port}\n",
            logs.display()
        ),
    )
    .unwrap();
    let events = dir.join("events.jsonl");
    let router = Proc::spawn(
        Command::new(env!("CARGO_BIN_EXE_fbwag"))
            .args(["router", "--duration", "4.5", "--report", "off", "--config"])
            .arg(&conf)
            .arg("--events")
            .arg(&events),
    );
    assert!(udp_port_bound(fc_port), "the router never listened");
    let fc = Proc::spawn(Command::new(env!("CARGO_BIN_EXE_fbwag")).args([
        "fc-sim",
        "--link",
        &format!("udpout:127.0.0.1:{fc_port}"),
        "--arm-at",
        "1",
        "--duration",
        "3.5",
    ]));
    // A stranger on the ground link forges the FC's log blocks once the
    // router sends there.
    gcs.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
    let mut buf = [0u8; 2048];
    let (_, router_at) = gcs
        .recv_from(&mut buf)
        .expect("the FC's frames on the ground link");
    std::thread::sleep(Duration::from_millis(1500));
    for seqno in 0..20 {
        gcs.send_to(&forged_block(seqno), router_at).unwrap();
    }
    let fc = fc.finish(Duration::from_secs(10));
    let out = router.finish(Duration::from_secs(10));
    let log = String::from_utf8_lossy(&out.stdout);
    let fc_log = String::from_utf8_lossy(&fc.stdout);
    assert!(out.status.success(), "{log}");
    assert!(log.contains("vehicle 1: armed"), "{log}");
    assert!(
        fc_log.contains("log: sending the DataFlash log to 1/192"),
        "{fc_log}\n{log}"
    );

    // Of each kind: the newest old file and the new one.
    let bins = own_files(&logs, "Z.bin");
    let tlogs = own_files(&logs, "Z.tlog");
    assert_eq!(bins.len(), 2, "{bins:?}\n{log}");
    assert_eq!(tlogs.len(), 2, "{tlogs:?}\n{log}");
    assert!(bins[0].ends_with(old(3, "bin")) && tlogs[0].ends_with(old(3, "tlog")));
    assert!(logs.join("00000-2020-01-01_00-00-00.bin").exists());

    // Telemetry only while armed: every FC HEARTBEAT logged says armed.
    let recs = records(&std::fs::read(&tlogs[1]).unwrap());
    let heartbeats: Vec<&Vec<u8>> = recs
        .iter()
        .map(|(_, f)| f)
        .filter(|f| f[7..10] == [0, 0, 0] && f[5] == 1 && f[6] == 1)
        .collect();
    assert!(heartbeats.len() >= 2, "{log}");
    for hb in &heartbeats {
        assert!(
            hb[1] > 6 && hb[10 + 6] & 0x80 != 0,
            "a disarmed HEARTBEAT logged"
        );
    }

    // The summary: a log begun, the forged blocks dropped, none written.
    let summary: Value = std::fs::read_to_string(&events)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<Value>(l).unwrap())
        .find(|e| e["event"] == "summary")
        .expect("a summary");
    let flight = &summary["flight_log"];
    assert_eq!(flight["logs"], 1, "{summary}");
    assert_eq!(flight["strangers"], 20, "{summary}");
    assert!(flight["written"].as_u64().unwrap() >= 4, "{summary}");

    // pymavlink's DFReader reads the log: its formats, the firmware, the
    // mode and the attitude, 25 a second, from arming on.
    let Some(py) = peer_python() else {
        return;
    };
    let dump = Command::new(&py)
        .arg(py.parent().unwrap().join("mavlogdump.py"))
        .args(["--format", "json"])
        .arg(&bins[1])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&dump.stdout);
    assert!(
        dump.status.success(),
        "{}",
        String::from_utf8_lossy(&dump.stderr)
    );
    let messages: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let of = |t: &'static str| messages.iter().filter(move |m| m["meta"]["type"] == t);
    assert_eq!(of("FMT").count(), 5, "{text}");
    let firmware = of("MSG").next().expect("MSG")["data"]["Message"].clone();
    assert!(
        firmware.as_str().unwrap().starts_with("ArduPlane"),
        "{firmware}"
    );
    assert_eq!(of("MODE").next().expect("MODE")["data"]["Mode"], 5);
    let att: Vec<u64> = of("ATT")
        .map(|m| m["data"]["TimeUS"].as_u64().unwrap())
        .collect();
    assert!(att.len() >= 20, "{} ATT records\n{text}", att.len());
    assert!(att[0] >= 900_000, "logged before arming: {}", att[0]);
    assert!(att.windows(2).all(|w| w[1] - w[0] == 40_000), "{att:?}");
    assert!(of("POS").count() >= 4, "{text}");
    let _ = std::fs::remove_dir_all(&dir);
}
