//! `fbwag decode` reads every input form (binary, `--hex`, `--tlog`) in
//! chunks: the result does not depend on where chunks end, and an endless
//! input is decoded in bounded memory instead of being read whole first.

mod common;
use common::fbwag;

use std::process::{Command, Stdio};

/// 6,000 frames (about 100 KB: more than one 64 KiB read).
fn frames() -> Vec<u8> {
    let lines: String = (0..6000)
        .map(|i| {
            format!(
                "{{\"name\":\"STATUSTEXT\",\"seq\":{},\"sysid\":1,\"compid\":1,\"fields\":{{\"severity\":{},\"text\":\"frame {i}\"}}}}\n",
                i % 256,
                i % 8
            )
        })
        .collect();
    let (bytes, err, code) = fbwag(&["encode"], lines.as_bytes());
    assert_eq!(code, Some(0), "{err}");
    bytes
}

#[test]
fn hex_input_decodes_like_binary_wherever_reads_split_it() {
    let bytes = frames();
    let (expected, err, code) = fbwag(&["decode"], &bytes);
    assert_eq!(code, Some(0), "{err}");
    // Odd line lengths put digit pairs across every kind of boundary.
    let hex: String = bytes.iter().map(|b| format!("{b:02x}")).collect();
    let wrapped: String = hex
        .as_bytes()
        .chunks(61)
        .map(|c| format!("{}\n", std::str::from_utf8(c).unwrap()))
        .collect();
    let (got, err, code) = fbwag(&["decode", "--hex"], wrapped.as_bytes());
    assert_eq!(code, Some(0), "{err}");
    assert!(got == expected, "--hex decoded differently from binary");
    let (_, err, code) = fbwag(&["decode", "--hex"], b"fd0\n");
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("odd number of hex digits"), "{err}");
}

#[test]
fn tlog_records_are_found_across_reads_and_garbage_is_counted() {
    let bytes = frames();
    let (json, _, _) = fbwag(&["decode"], &bytes);
    let count = json
        .split(|&b| b == b'\n')
        .filter(|l| !l.is_empty())
        .count();
    // Each frame becomes a record; three garbage bytes after twelve of them.
    let mut tlog = Vec::new();
    let mut at = 0;
    let mut i = 0u64;
    while at < bytes.len() {
        let len = if bytes[at] == 0xFD {
            bytes[at + 1] as usize + 12
        } else {
            unreachable!()
        };
        tlog.extend_from_slice(&(1_000 + i).to_be_bytes());
        tlog.extend_from_slice(&bytes[at..at + len]);
        if i % 500 == 250 {
            tlog.extend_from_slice(&[0x00, 0x17, 0x42]);
        }
        at += len;
        i += 1;
    }
    let (out, err, code) = fbwag(&["decode", "--tlog"], &tlog);
    assert_eq!(code, Some(1), "garbage makes the status 1: {err}");
    let lines: Vec<&str> = std::str::from_utf8(&out).unwrap().lines().collect();
    assert_eq!(lines.len(), count, "{err}");
    for (k, line) in lines.iter().enumerate() {
        let ts = format!("{{\"tlog_us\":{},", 1_000 + k);
        assert!(line.starts_with(&ts), "record {k}: {line}");
    }
    assert!(
        err.contains(&format!("tlog: {count} records, 36 unreadable")),
        "{err}"
    );
}

/// An endless input (`/dev/zero`) was read whole before decoding, for
/// `--tlog` and `--hex`: memory grew until the process died. Now it is
/// decoded as it comes: after a few seconds the process is still running
/// with a small resident set.
#[cfg(target_os = "linux")]
#[test]
fn an_endless_tlog_input_is_decoded_in_bounded_memory() {
    // The cap only protects the machine should this regress.
    let mut child = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "ulimit -v 2097152; exec '{}' decode --tlog /dev/zero",
            env!("CARGO_BIN_EXE_fbwag")
        ))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("run fbwag");
    std::thread::sleep(std::time::Duration::from_secs(3));
    let status = std::fs::read_to_string(format!("/proc/{}/status", child.id()));
    let alive = child.try_wait().unwrap().is_none();
    let _ = child.kill();
    let _ = child.wait();
    assert!(alive, "decode --tlog /dev/zero died");
    let rss_kb: u64 = status
        .unwrap()
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .expect("VmRSS");
    assert!(rss_kb < 64 * 1024, "resident set {rss_kb} kB");
}
