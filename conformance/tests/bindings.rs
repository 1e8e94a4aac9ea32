//! `bindings/fbwag/` (written by the README's main command) is exactly what
//! mavgen-rs generates now: a stale check-in, or output that depends on the
//! machine or the run, fails here.

mod support;

#[test]
fn checked_in_bindings_are_current() {
    let generated = mavgen::Config::new()
        .generate(&[support::repo().join("message_definitions/fbwag.xml")])
        .unwrap_or_else(|e| panic!("{e}"));
    let dir = support::repo().join("bindings/fbwag");
    let mut on_disk: Vec<String> = std::fs::read_dir(&dir)
        .expect("bindings/fbwag")
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
        "file set differs: regenerate with the README's main command"
    );
    for (name, text) in &generated.output.files {
        let disk = std::fs::read_to_string(dir.join(name)).unwrap();
        assert!(
            disk == *text,
            "bindings/fbwag/{name} is stale: regenerate with the README's main command"
        );
    }
}
