//! mavgen-rs's id/name/CRC_EXTRA/min/max table equals pymavlink 2.4.50's own
//! mavgen front end, message for message, for every shipped XML and ours.

mod support;

use std::collections::BTreeMap;
use std::process::Command;

fn pymavlink_tables() -> BTreeMap<String, String> {
    let dir = support::repo().join("message_definitions");
    let out = Command::new(support::python())
        .arg(support::repo().join("conformance/pymavlink/table.py"))
        .arg("--all-shipped")
        .arg(&dir)
        .output()
        .expect("run table.py");
    assert!(
        out.status.success(),
        "table.py failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut tables = BTreeMap::new();
    let mut current: Option<String> = None;
    for line in String::from_utf8(out.stdout).expect("utf-8").lines() {
        if let Some(name) = line.strip_prefix("# ") {
            current = Some(name.to_string());
            tables.insert(name.to_string(), String::new());
        } else {
            let t = tables
                .get_mut(current.as_ref().expect("header first"))
                .expect("table");
            t.push_str(line);
            t.push('\n');
        }
    }
    tables
}

fn our_table(xml: &std::path::Path) -> String {
    let schema = mavgen_rs::Schema::load(&[xml])
        .unwrap_or_else(|d| panic!("{} rejected: {d:?}", xml.display()));
    let mut rows: Vec<_> = schema.messages().collect();
    rows.sort_by_key(|m| m.id());
    rows.iter()
        .map(|m| {
            format!(
                "{} {} {} {} {}\n",
                m.id(),
                m.name(),
                m.crc_extra(),
                m.min_len(),
                m.max_len()
            )
        })
        .collect()
}

#[test]
fn every_dialect_table_equals_pymavlink() {
    let theirs = pymavlink_tables();
    let files = support::xml_files();
    assert_eq!(
        theirs.len(),
        files.len(),
        "pymavlink saw a different set of files"
    );
    let (mut messages, mut mismatches) = (0, Vec::new());
    for xml in &files {
        let name = xml.file_name().unwrap().to_string_lossy().into_owned();
        let ours = our_table(xml);
        let expected = &theirs[&name];
        messages += ours.lines().count();
        if &ours != expected {
            let diff: Vec<_> = ours
                .lines()
                .zip(expected.lines())
                .filter(|(a, b)| a != b)
                .take(5)
                .collect();
            mismatches.push(format!(
                "{name}: {} vs {} lines; first differences (ours, pymavlink): {diff:?}",
                ours.lines().count(),
                expected.lines().count()
            ));
        }
    }
    assert!(mismatches.is_empty(), "{}", mismatches.join("\n"));
    eprintln!(
        "tables: {} dialects, {messages} message rows, 0 mismatches",
        files.len()
    );
    assert!(messages > 2500, "suspiciously few rows: {messages}");
}

#[test]
fn pinned_values() {
    let t = our_table(&support::repo().join("message_definitions/fbwag.xml"));
    assert!(t.lines().any(|l| l == "15001 FBWAG_NOTICE 30 12 12"));
    assert!(t.lines().any(|l| l == "0 HEARTBEAT 50 9 9"));
}
