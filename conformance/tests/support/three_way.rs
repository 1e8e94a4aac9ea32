//! One frame through all three implementations, for the focused tests of
//! documented differences and fixed bugs (the bulk comparison is
//! tests/wire.rs).

use super::frames::{build_frame, Mode, KEY};
use super::peers;
use super::values::{hex, hex_decode, values_text};
use mavframe::{Header, MessageMeta};
use std::sync::atomic::{AtomicUsize, Ordering};

/// What pymavlink and the C library make of one case.
#[derive(Debug)]
pub struct ThreeWay {
    /// Rust's frame (mavframe).
    pub rust: Vec<u8>,
    /// pymavlink's frame, packed from the same values.
    pub py: Vec<u8>,
    /// pymavlink's decoding of Rust's frame (`ok:…` token).
    pub py_decodes_rust: String,
    /// The C library's frame, packed from the same values.
    pub c: Vec<u8>,
    pub c_decodes_rust: String,
    pub c_decodes_py: String,
}

static RUN: AtomicUsize = AtomicUsize::new(0);

/// Packs `payload` (max_len bytes) of `meta` in `mode` with all three.
pub fn three_way(dialect: &str, meta: &MessageMeta, mode: Mode, payload: &[u8]) -> ThreeWay {
    let header = Header {
        seq: 7,
        sysid: 1,
        compid: 191,
    };
    let (link, ts) = (3, 0x0000_1000_0000_0000);
    let rust = build_frame(meta, mode, header, payload, link, ts, &KEY);
    let values = values_text(meta, payload);
    let line = format!(
        "0 {} {} {} {} {} {link} {ts} {values} {}",
        mode.token(),
        meta.id,
        header.seq,
        header.sysid,
        header.compid,
        hex(&rust)
    );
    let n = RUN.fetch_add(1, Ordering::Relaxed);
    let dir = peers::scratch(dialect, &format!("three-way-{}-{n}", std::process::id()));
    let py_in = dir.join("case.txt");
    std::fs::write(&py_in, format!("{line}\n")).unwrap();
    let key = hex(&KEY);
    let py_out = peers::pymavlink(&["frames", "--dialect", dialect, "--key", &key], &py_in);
    let mut it = py_out[0].split(' ').skip(1);
    let py_hex = it.next().unwrap().to_string();
    let py_decodes_rust = it.next().unwrap().to_string();
    let c_in = dir.join("c-case.txt");
    std::fs::write(&c_in, format!("{line} {py_hex}\n")).unwrap();
    let harness = peers::c_harness(dialect);
    let c_out = peers::c_lib(&harness, &["frames", &key], &c_in);
    let mut it = c_out[0].split(' ').skip(1);
    let c = hex_decode(it.next().unwrap()).unwrap();
    let c_decodes_rust = it.next().unwrap().to_string();
    let c_decodes_py = it.next().unwrap().to_string();
    let _ = std::fs::remove_dir_all(&dir);
    ThreeWay {
        rust,
        py: hex_decode(&py_hex).unwrap(),
        py_decodes_rust,
        c,
        c_decodes_rust,
        c_decodes_py,
    }
}

/// The field `name` of a `name=value;…` value text (or of an `ok:…` token).
pub fn field<'a>(text: &'a str, name: &str) -> &'a str {
    let values = text.rsplit(':').next().unwrap();
    values
        .split(';')
        .find_map(|kv| kv.strip_prefix(name).and_then(|r| r.strip_prefix('=')))
        .unwrap_or_else(|| panic!("no field {name} in {text}"))
}

/// Runs a Python snippet with pymavlink importable (and conformance/pymavlink
/// on the path); returns stdout.
pub fn python(snippet: &str) -> String {
    let out = std::process::Command::new(super::python())
        .arg("-c")
        .arg(format!(
            "import sys; sys.path.insert(0, {:?})\n{snippet}",
            super::repo()
                .join("conformance/pymavlink")
                .display()
                .to_string()
        ))
        .output()
        .expect("python");
    assert!(
        out.status.success(),
        "python snippet failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}
