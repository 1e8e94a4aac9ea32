//! Writes the seed inputs of the fuzz targets into fuzz/corpus/<target>/
//! (checked in; run once, or after the harness input formats change):
//!
//!     cargo run -p conformance --example fuzz_seeds
//!
//! parser: byte 0 = policy/chunking, then streams of valid MAVLink 1/2,
//! signed (with fuzz/src/lib.rs's key) and unsigned frames, some with garbage
//! between them; frame: single frames; view: message index + payload; xml:
//! the small upstream dialects and mavgen-rs's test fixtures without includes.

use fbwag_dialect::mavframe::frame::{finish, Header, Version, HEADER_LEN_V1, HEADER_LEN_V2};
use fbwag_dialect::mavframe::Signer;
use fbwag_dialect::MESSAGES;
use std::path::PathBuf;

const KEY: [u8; 32] = [0x42; 32];

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

fn frame(rng: &mut Rng, idx: usize, mode: u64, ts: u64) -> Vec<u8> {
    let meta = &MESSAGES[idx % MESSAGES.len()];
    let v1 = mode == 2 && meta.id <= 255;
    let start = if v1 { HEADER_LEN_V1 } else { HEADER_LEN_V2 };
    let mut out = [0u8; 300];
    for b in &mut out[start..start + meta.max_len as usize] {
        *b = match rng.next() % 4 {
            0 => 0,
            _ => rng.next() as u8,
        };
    }
    let mut signer = (mode == 1 && !v1).then(|| Signer::new(KEY, (ts % 3) as u8, ts));
    let h = Header {
        seq: rng.next() as u8,
        sysid: 1,
        compid: 1 + (rng.next() % 2) as u8 * 190,
    };
    let version = if v1 { Version::V1 } else { Version::V2 };
    let n = finish(
        version,
        h,
        meta,
        meta.max_len as usize,
        signer.as_mut(),
        &mut out,
    )
    .unwrap();
    out[..n].to_vec()
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let corpus = root.join("fuzz/corpus");
    let mut rng = Rng(0x5eed);
    let write = |t: &str, name: String, bytes: &[u8]| {
        let d = corpus.join(t);
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join(name), bytes).unwrap();
    };
    for s in 0..24u64 {
        let mut stream = vec![(s % 9) as u8];
        for k in 0..(4 + s as usize % 12) {
            let idx = (rng.next() % MESSAGES.len() as u64) as usize;
            stream.extend(frame(
                &mut rng,
                idx,
                (s + k as u64) % 3,
                1000 + s * 100 + k as u64,
            ));
            if s % 4 == 3 {
                stream.extend([0xFD, 0x40, 0x00, 0x55, 0xFE, 0x07]);
            }
        }
        write("parser", format!("seed-{s:02}"), &stream);
    }
    for (i, m) in MESSAGES.iter().enumerate() {
        let f = frame(&mut rng, i, i as u64 % 3, 5000 + i as u64);
        if i % 6 == 0 {
            write("frame", format!("seed-{}", m.name.to_lowercase()), &f);
        }
        // Every message for `view`: each has its own accessors.
        let mut v = (i as u16).to_le_bytes().to_vec();
        let start = if f[0] == 0xFD {
            HEADER_LEN_V2
        } else {
            HEADER_LEN_V1
        };
        v.extend_from_slice(&f[start..start + f[1] as usize]);
        write("view", format!("seed-{}", m.name.to_lowercase()), &v);
    }
    let defs = root.join("message_definitions");
    for x in ["minimal.xml", "test.xml", "python_array_test.xml"] {
        write(
            "xml",
            format!("seed-{x}"),
            &std::fs::read(defs.join(x)).unwrap(),
        );
    }
    let fixtures = root.join("mavgen-rs/tests/fixtures");
    let mut names: Vec<_> = std::fs::read_dir(&fixtures)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    for p in names {
        let text = std::fs::read(&p).unwrap();
        if !String::from_utf8_lossy(&text).contains("<include>") {
            write(
                "xml",
                format!("seed-{}", p.file_name().unwrap().to_string_lossy()),
                &text,
            );
        }
    }
    println!("seeds written to {}", corpus.display());
}
