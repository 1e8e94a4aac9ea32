//! Every merged enum entry has the value pymavlink 2.4.50 gives it, for every
//! shipped dialect and for a fixture that makes pymavlink renumber
//! auto-valued entries during the merge.

mod support;

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::Command;

fn pymavlink_enums(files: &[PathBuf]) -> BTreeMap<String, BTreeSet<String>> {
    let out = Command::new(support::python())
        .arg(support::repo().join("conformance/pymavlink/enums.py"))
        .args(files)
        .output()
        .expect("run enums.py");
    assert!(
        out.status.success(),
        "enums.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut by_file = BTreeMap::new();
    let mut current = String::new();
    for line in String::from_utf8(out.stdout).expect("utf-8").lines() {
        match line.strip_prefix("# ") {
            Some(name) => current = name.to_string(),
            None => {
                by_file
                    .entry(current.clone())
                    .or_insert_with(BTreeSet::new)
                    .insert(line.to_string());
            }
        }
    }
    by_file
}

fn our_enums(xml: &Path) -> BTreeSet<String> {
    let schema = mavgen_rs::Schema::load(&[xml])
        .unwrap_or_else(|d| panic!("{} rejected: {d:?}", xml.display()));
    schema
        .enums()
        .flat_map(|e| {
            e.entries()
                .map(move |entry| format!("{} {} {}", e.name(), entry.name(), entry.value()))
        })
        .collect()
}

#[test]
fn merged_enum_values_equal_pymavlink() {
    let mut files = support::xml_files();
    files.push(support::repo().join("conformance/fixtures/merge_root.xml"));
    let theirs = pymavlink_enums(&files);
    let mut entries = 0;
    for xml in &files {
        let name = xml.file_name().unwrap().to_string_lossy().into_owned();
        let ours = our_enums(xml);
        let expected = theirs.get(&name).cloned().unwrap_or_default();
        let missing: Vec<_> = expected.difference(&ours).take(5).collect();
        let extra: Vec<_> = ours.difference(&expected).take(5).collect();
        assert!(
            missing.is_empty() && extra.is_empty(),
            "{name}: pymavlink only {missing:?}; ours only {extra:?}"
        );
        entries += ours.len();
    }
    assert!(
        entries > 20_000,
        "suspiciously few enum entries compared: {entries}"
    );
}

#[test]
fn auto_values_are_renumbered_like_pymavlink() {
    let ours = our_enums(&support::repo().join("conformance/fixtures/merge_root.xml"));
    assert!(ours.contains("MERGE_E MERGE_E_AUTO_A 4"), "{ours:?}");
    assert!(ours.contains("MERGE_E MERGE_E_AUTO_B 5"), "{ours:?}");
}
