//! The public view of a loaded dialect: `Schema::from_text` (a text named
//! as a file, its includes read from disk), the message, field and enum
//! views, and `Config::generate_from` on a schema already loaded.

use mavgen_rs::{Config, Schema, Severity, MAX_FILE_BYTES};
use std::path::{Path, PathBuf};

fn fixtures_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

fn minimal() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../message_definitions/minimal.xml")
}

const ONE_MESSAGE: &str = r#"<mavlink>
  <include>dup_id_included.xml</include>
  <messages>
    <message id="6" name="FROM_TEXT">
      <field type="uint8_t" name="a">A.</field>
      <field type="uint32_t" name="b">B.</field>
      <extensions/>
      <field type="int16_t" name="c">C.</field>
    </message>
  </messages>
</mavlink>"#;

#[test]
fn a_text_reads_its_includes_next_to_the_path_it_is_named() {
    let named = fixtures_dir().join("unsaved.xml");
    let schema = Schema::from_text(&named, ONE_MESSAGE).unwrap_or_else(|d| panic!("{d:?}"));
    let names: Vec<_> = schema.messages().map(|m| (m.id(), m.name())).collect();
    assert_eq!(
        names,
        [(6, "FROM_TEXT"), (4, "OTHER_MSG"), (5, "INC_MSG")],
        "the text first, then its include"
    );
    let files: Vec<_> = schema.paths().map(|p| p.file_name().unwrap()).collect();
    assert_eq!(files, ["unsaved.xml", "dup_id_included.xml"]);
}

#[test]
fn field_views_show_the_wire_layout() {
    let named = fixtures_dir().join("unsaved.xml");
    let schema = Schema::from_text(&named, ONE_MESSAGE).unwrap();
    let m = schema.messages().next().unwrap();
    // Base fields largest first (b, then a), the extension after them.
    let fields: Vec<_> = m
        .fields()
        .map(|f| {
            (
                f.name(),
                f.c_type(),
                f.offset(),
                f.wire_len(),
                f.is_extension(),
            )
        })
        .collect();
    assert_eq!(
        fields,
        [
            ("a", "uint8_t", 4, 1, false),
            ("b", "uint32_t", 0, 4, false),
            ("c", "int16_t", 5, 2, true),
        ]
    );
    assert_eq!((m.min_len(), m.max_len()), (5, 7));
}

#[test]
fn a_text_named_as_a_file_it_is_included_by_is_that_file() {
    // cycle_b.xml includes cycle_a.xml: the text, named cycle_a.xml, must be
    // recognised as the file on disk (a cycle), not read a second time.
    let text = std::fs::read_to_string(fixtures_dir().join("cycle_a.xml")).unwrap();
    let diags = Schema::from_text(fixtures_dir().join("cycle_a.xml"), &text).unwrap_err();
    assert!(
        diags.iter().any(|d| d
            .message
            .contains("include cycle: cycle_a.xml -> cycle_b.xml")),
        "{diags:?}"
    );
}

#[test]
fn a_text_over_the_file_limit_is_refused_with_a_diagnostic() {
    let text = " ".repeat(MAX_FILE_BYTES as usize + 1);
    let diags = Schema::from_text("big.xml", &text).unwrap_err();
    assert_eq!(diags.len(), 1, "{diags:?}");
    assert_eq!(diags[0].severity, Severity::Error);
    assert!(diags[0].to_string().contains("big.xml"), "{}", diags[0]);
    assert!(diags[0].to_string().contains("8 MiB"), "{}", diags[0]);
}

#[test]
fn heartbeat_and_its_enum_as_pymavlink_sees_them() {
    let schema = Schema::load(&[minimal()]).unwrap();
    let hb = schema.messages().find(|m| m.name() == "HEARTBEAT").unwrap();
    assert_eq!(
        (hb.id(), hb.crc_extra(), hb.min_len(), hb.max_len()),
        (0, 50, 9, 9)
    );
    let custom_mode = hb.fields().find(|f| f.name() == "custom_mode").unwrap();
    assert_eq!(
        (custom_mode.offset(), custom_mode.c_type()),
        (0, "uint32_t")
    );
    let autopilot = hb.fields().find(|f| f.name() == "autopilot").unwrap();
    assert_eq!(autopilot.enum_name(), Some("MAV_AUTOPILOT"));

    let e = schema
        .enums()
        .find(|e| e.name() == "MAV_AUTOPILOT")
        .unwrap();
    assert!(!e.is_bitmask());
    let values: Vec<u64> = e.entries().map(|x| x.value()).collect();
    assert!(values.windows(2).all(|w| w[0] < w[1]), "{values:?}");
    assert_eq!(
        e.entries().next().map(|x| x.name()),
        Some("MAV_AUTOPILOT_GENERIC")
    );
}

#[test]
fn generating_from_a_loaded_schema_equals_generating_from_files() {
    let schema = Schema::load(&[minimal()]).unwrap();
    let from_schema = Config::new().generate_from(&schema).unwrap();
    let from_files = Config::new().generate(&[minimal()]).unwrap();
    assert!(from_schema.output == from_files.output);
    assert_eq!(from_schema.inputs, from_files.inputs);
}
