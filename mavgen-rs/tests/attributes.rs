//! `Config::type_attribute` and `Config::field_attribute` (prost-build's
//! hooks): where the attributes land, which items each pattern reaches,
//! and the typed errors for attributes that do not parse or patterns that
//! name nothing; and the command line's `--type-attribute` and
//! `--field-attribute`.

use mavgen_rs::{AttributeProblem, Config, Error};
use std::path::{Path, PathBuf};
use std::process::Command;

fn snapshot_xml() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/snapshot/snapshot.xml")
}

/// The generated module (not mod.rs) for `config`.
fn module(config: &Config) -> String {
    let generated = config
        .generate(&[snapshot_xml()])
        .unwrap_or_else(|e| panic!("{e}"));
    generated.output.files[1].1.clone()
}

/// The lines of `code` from the one containing `start` to the next `{`
/// or `;` that ends an item head: the attributes and head of one item.
fn item_head<'a>(code: &'a str, item: &str) -> &'a str {
    let at = code
        .find(item)
        .unwrap_or_else(|| panic!("no `{item}` in the output"));
    // Back to the end of the doc comment before the item's attributes.
    let head_start = code[..at]
        .rfind("///")
        .map_or(0, |i| i + code[i..].find('\n').unwrap() + 1);
    &code[head_start..at + item.len()]
}

#[test]
fn type_attributes_land_on_the_named_message_or_enum_after_the_derives() {
    let mut config = Config::new();
    config
        .type_attribute("SNAP_ALL_TYPES", "#[must_use]")
        .type_attribute("SNAP_MODE", "#[derive(PartialOrd)] #[repr(transparent)]")
        .type_attribute("SNAP_FLAGS", r#"#[doc(alias = "flags")]"#);
    let code = module(&config);
    let head = item_head(&code, "pub struct SnapAllTypes {");
    assert!(
        head.ends_with("#[must_use]\npub struct SnapAllTypes {"),
        "{head}"
    );
    assert!(
        head.starts_with("#[derive(Debug, Clone, Copy, PartialEq)]"),
        "{head}"
    );
    assert!(
        code.contains("#[derive(PartialOrd)]\n#[repr(transparent)]\npub struct SnapMode(pub u16);"),
        "{code}"
    );
    assert!(code.contains("#[doc(alias = \"flags\")]\npub struct SnapFlags(pub u32);"));
    // Nothing else got them.
    assert_eq!(code.matches("#[must_use]").count(), 1);
    assert_eq!(code.matches("#[repr(transparent)]").count(), 1);
}

#[test]
fn the_dot_pattern_reaches_every_message_and_enum_but_not_the_dialect_enum() {
    let mut config = Config::new();
    config.type_attribute(".", "#[doc(alias = \"every\")]");
    let code = module(&config);
    // Two messages, three enums.
    assert_eq!(
        code.matches("#[doc(alias = \"every\")]").count(),
        5,
        "{code}"
    );
    assert!(!code.contains("#[doc(alias = \"every\")]\npub enum Message"));
}

#[test]
fn field_attributes_reach_one_field_a_message_s_fields_or_all() {
    let mut config = Config::new();
    config
        .field_attribute("SNAP_ALL_TYPES.type", "#[doc(alias = \"kind\")]")
        .field_attribute("SNAP_MAX_ID", "#[doc(alias = \"max\")]")
        .field_attribute(".", "#[doc(alias = \"any\")]");
    let code = module(&config);
    // After the serde attribute, before the field.
    assert!(
        code.contains(
            "    #[cfg_attr(feature = \"serde\", serde(with = \"::mavframe::serde::float\"))]\n    \
             #[doc(alias = \"kind\")]\n    #[doc(alias = \"any\")]\n    pub r#type: f32,"
        ),
        "{code}"
    );
    assert_eq!(code.matches("#[doc(alias = \"kind\")]").count(), 1);
    // SNAP_MAX_ID has 3 fields; SNAP_ALL_TYPES 15.
    assert_eq!(code.matches("#[doc(alias = \"max\")]").count(), 3);
    assert_eq!(code.matches("#[doc(alias = \"any\")]").count(), 18);
}

#[test]
fn an_attribute_that_does_not_parse_is_a_typed_error_naming_it() {
    for bad in ["#[derive(Hash)", "derive(Hash)", "#![no_std]", "", "#[a] b"] {
        let mut config = Config::new();
        config.type_attribute("SNAP_MODE", bad);
        // Refused before any file is read.
        match config.generate(&[Path::new("no-such-file.xml")]) {
            Err(Error::Attribute(e)) => {
                assert_eq!(e.attribute, bad);
                assert_eq!(e.pattern, "SNAP_MODE");
                assert!(matches!(e.problem, AttributeProblem::Syntax(_)), "{e:?}");
                assert!(e.to_string().contains(&format!("`{bad}`")), "{e}");
            }
            other => panic!("{bad:?}: {other:?}"),
        }
    }
    let mut config = Config::new();
    config.field_attribute("SNAP_MAX_ID.data", "#[serde(");
    assert!(matches!(
        config.generate(&[snapshot_xml()]),
        Err(Error::Attribute(_))
    ));
}

#[test]
fn a_pattern_naming_nothing_is_an_error_and_filtered_out_items_are_not() {
    let no_match = |config: &Config| match config.generate(&[snapshot_xml()]) {
        Err(Error::Attribute(e)) => e.problem == AttributeProblem::NoMatch,
        _ => false,
    };
    let mut config = Config::new();
    config.type_attribute("SNAP_TYPO", "#[must_use]");
    assert!(no_match(&config));
    let mut config = Config::new();
    config.field_attribute("SNAP_ALL_TYPES.tipe", "#[doc(alias = \"x\")]");
    assert!(no_match(&config));
    let mut config = Config::new();
    // A field pattern for a type name that is an enum, not a message.
    config.field_attribute("SNAP_MODE", "#[doc(alias = \"x\")]");
    assert!(no_match(&config));
    // Patterns are XML names, not Rust ones.
    let mut config = Config::new();
    config.type_attribute("SnapMode", "#[must_use]");
    assert!(no_match(&config));
    // A message the filter leaves out is still a name of the dialect.
    let mut config = Config::new();
    config
        .messages(["SNAP_MAX_ID"])
        .type_attribute("SNAP_ALL_TYPES", "#[must_use]");
    let code = module(&config);
    assert!(!code.contains("#[must_use]"));
}

#[test]
fn the_command_line_takes_pattern_equals_attributes() {
    let dir = std::env::temp_dir().join(format!("mavgen-rs-attrs-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_mavgen-rs"))
            .arg("generate")
            .arg(snapshot_xml())
            .arg("-o")
            .arg(&dir)
            .args(args)
            .output()
            .expect("run mavgen-rs")
    };
    let out = run(&[
        "--type-attribute",
        "SNAP_MODE=#[derive(PartialOrd)]",
        "--field-attribute",
        r#"SNAP_MAX_ID.data=#[doc(alias = "payload")]"#,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let code = std::fs::read_to_string(dir.join("snapshot.rs")).unwrap();
    assert!(code.contains("#[derive(PartialOrd)]\npub struct SnapMode(pub u16);"));
    assert!(code.contains("#[doc(alias = \"payload\")]\n    pub data: [u8; 40],"));
    let bad = run(&["--type-attribute", "SNAP_MODE=#[derive("]);
    assert_eq!(bad.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("#[derive("));
    let no_equals = run(&["--type-attribute", "SNAP_MODE"]);
    assert_eq!(no_equals.status.code(), Some(2), "clap's usage error");
    let _ = std::fs::remove_dir_all(&dir);
}
