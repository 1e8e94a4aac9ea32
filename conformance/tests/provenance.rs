//! The upstream XML files are protocol data copied unchanged from pymavlink
//! 2.4.50: byte-identical to the pinned package, and to the hashes in
//! message_definitions/PROVENANCE.md.

mod support;

use sha2::{Digest, Sha256};
use std::process::Command;

fn listed_hashes() -> Vec<(String, String)> {
    let text = std::fs::read_to_string(support::repo().join("message_definitions/PROVENANCE.md"))
        .expect("PROVENANCE.md");
    text.lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            (cells.len() == 4 && cells[1].ends_with(".xml"))
                .then(|| (cells[1].to_string(), cells[2].to_string()))
        })
        .collect()
}

fn sha256(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

#[test]
fn upstream_xml_matches_provenance_hashes() {
    let listed = listed_hashes();
    let upstream: Vec<_> = support::xml_files()
        .into_iter()
        .filter(|p| !p.ends_with("fbwag.xml"))
        .collect();
    assert_eq!(
        listed.len(),
        upstream.len(),
        "PROVENANCE.md must list every upstream file"
    );
    for (name, hash) in &listed {
        let bytes =
            std::fs::read(support::repo().join("message_definitions").join(name)).expect(name);
        assert_eq!(
            &sha256(&bytes),
            hash,
            "{name} differs from its recorded hash"
        );
    }
}

#[test]
fn upstream_xml_matches_pinned_pymavlink() {
    let out = Command::new(support::python())
        .args(["-c", "import os, pymavlink; print(os.path.join(os.path.dirname(pymavlink.__file__), 'dialects', 'v20'))"])
        .output()
        .expect("python");
    assert!(out.status.success());
    let dir = std::path::PathBuf::from(String::from_utf8(out.stdout).unwrap().trim());
    for (name, _) in listed_hashes() {
        let ours = std::fs::read(support::repo().join("message_definitions").join(&name)).unwrap();
        let theirs = std::fs::read(dir.join(&name))
            .unwrap_or_else(|e| panic!("{name} not in pymavlink: {e}"));
        assert!(
            ours == theirs,
            "{name} is not byte-identical to pymavlink 2.4.50's copy"
        );
    }
}
