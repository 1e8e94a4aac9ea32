//! The fuzz corpus and every input a fuzz run ever crashed on, replayed
//! under `cargo test` through the same harness functions libFuzzer runs
//! (fuzz/src/lib.rs, compiled here as a module): fuzz/corpus/<target>/ (seeds
//! and inputs kept from fuzz runs) and fuzz/regressions/<target>/ (crashes,
//! copied there by conformance/scripts/fuzz.sh; each stays as a test).

mod support;

#[path = "../../fuzz/src/lib.rs"]
#[allow(dead_code)]
mod fuzz_targets;

fn replay(target: &str, run: fn(&[u8])) {
    let root = support::repo().join("fuzz");
    let mut count = 0;
    let mut failures = Vec::new();
    for dir in ["corpus", "regressions"] {
        let Ok(entries) = std::fs::read_dir(root.join(dir).join(target)) else {
            continue;
        };
        let mut files: Vec<_> = entries.map(|e| e.unwrap().path()).collect();
        files.sort();
        for f in files {
            let bytes = std::fs::read(&f).unwrap();
            count += 1;
            if std::panic::catch_unwind(|| run(&bytes)).is_err() {
                failures.push(f.display().to_string());
            }
        }
    }
    assert!(
        failures.is_empty(),
        "{target}: inputs that fail: {failures:#?}"
    );
    assert!(count > 0, "no corpus for {target}");
    eprintln!("fuzz_regressions: {target}: {count} inputs replayed");
}

#[test]
fn parser_corpus_and_regressions() {
    replay("parser", fuzz_targets::parser);
}

#[test]
fn frame_corpus_and_regressions() {
    replay("frame", fuzz_targets::frame);
}

#[test]
fn view_corpus_and_regressions() {
    replay("view", fuzz_targets::view);
}

#[test]
fn xml_corpus_and_regressions() {
    replay("xml", fuzz_targets::xml);
}
