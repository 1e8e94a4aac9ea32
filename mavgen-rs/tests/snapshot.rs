//! The generated code for a small XML covering every construct, compared
//! byte for byte with the checked-in `tests/snapshot/expected/` (compiled by
//! the conformance crate under `deny(warnings)`). After an intended change:
//! `UPDATE_SNAPSHOTS=1 cargo test -p mavgen-rs --test snapshot`.

use std::path::PathBuf;

#[test]
fn generated_code_matches_snapshot() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/snapshot");
    let generated = mavgen_rs::Config::new()
        .generate(&[dir.join("snapshot.xml")])
        .unwrap_or_else(|e| panic!("{e}"));
    let expected_dir = dir.join("expected");
    if std::env::var_os("UPDATE_SNAPSHOTS").is_some() {
        std::fs::create_dir_all(&expected_dir).unwrap();
        for (name, text) in &generated.output.files {
            std::fs::write(expected_dir.join(name), text).unwrap();
        }
    }
    for (name, text) in &generated.output.files {
        let expected = std::fs::read_to_string(expected_dir.join(name))
            .unwrap_or_else(|e| panic!("{name}: {e} (run with UPDATE_SNAPSHOTS=1)"));
        assert!(
            *text == expected,
            "{name} differs from the snapshot; review `git diff` after UPDATE_SNAPSHOTS=1"
        );
    }
    assert_eq!(generated.output.files.len(), 2, "mod.rs and snapshot.rs");
}

#[test]
fn generation_is_deterministic() {
    let xml = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../message_definitions/fbwag.xml");
    let a = mavgen_rs::Config::new().generate(&[&xml]).unwrap();
    let b = mavgen_rs::Config::new().generate(&[&xml]).unwrap();
    assert!(a.output == b.output);
}
