//! The checked-in bindings the dialect crates compile are exactly what
//! mavgen-rs generates now: `fbwag-dialect/bindings/fbwag/` (every message)
//! and `fbwag-dialect-cc/bindings/` (the messages of
//! `fbwag-dialect-cc/messages.txt`), both written by the README's main
//! command (`scripts/regenerate.sh`). A stale check-in, or output that
//! depends on the machine or the run, fails here.

mod support;

/// Compares the directory `dir` (from the repository root) with a fresh
/// generation of fbwag.xml.
fn assert_current(dir: &str, messages: Option<Vec<String>>) {
    let mut config = mavgen_rs::Config::new();
    if let Some(m) = messages {
        config.messages(m);
    }
    let generated = config
        .generate(&[support::repo().join("message_definitions/fbwag.xml")])
        .unwrap_or_else(|e| panic!("{e}"));
    let path = support::repo().join(dir);
    let mut on_disk: Vec<String> = std::fs::read_dir(&path)
        .unwrap_or_else(|e| panic!("{dir}: {e}"))
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".rs"))
        .collect();
    on_disk.sort();
    let mut expected: Vec<String> = generated
        .output
        .files
        .iter()
        .map(|(n, _)| n.clone())
        .collect();
    expected.sort();
    assert_eq!(
        on_disk, expected,
        "{dir}: file set differs; regenerate with scripts/regenerate.sh"
    );
    for (name, text) in &generated.output.files {
        let disk = std::fs::read_to_string(path.join(name)).unwrap();
        assert!(
            disk == *text,
            "{dir}/{name} is stale: regenerate with scripts/regenerate.sh"
        );
    }
}

#[test]
fn full_bindings_are_current() {
    assert_current("fbwag-dialect/bindings/fbwag", None);
}

#[test]
fn companion_subset_bindings_are_current() {
    let list = std::fs::read_to_string(support::repo().join("fbwag-dialect-cc/messages.txt"))
        .expect("fbwag-dialect-cc/messages.txt");
    let names = mavgen_rs::Config::message_list(&list);
    // The crate re-exports these two, so every build must have them.
    for needed in ["HEARTBEAT", "FBWAG_NOTICE"] {
        assert!(
            names.iter().any(|n| n == needed),
            "messages.txt lacks {needed}"
        );
    }
    assert_current("fbwag-dialect-cc/bindings", Some(names));
}
