//! One test per diagnostic class: each asserts the file, line and column
//! (1-based, columns in characters), the severity and the gist of the
//! message, against small hand-written fixtures in `tests/fixtures/`.

use mavgen_rs::{Config, Diagnostic, Error, Schema, Severity};
use std::path::{Path, PathBuf};

/// A diagnostic flattened for comparison: (file name, line, column,
/// severity, message).
type Diag = (String, usize, usize, Severity, String);

fn fixtures_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

fn fixture(name: &str) -> PathBuf {
    fixtures_dir().join(name)
}

/// Flattens `d`, checking that it points into a fixture file (the root as
/// given to `Schema::load`, or an include resolved next to it).
fn flatten(d: &Diagnostic) -> Diag {
    let p = d
        .position
        .as_ref()
        .unwrap_or_else(|| panic!("diagnostic without a position: {d}"));
    assert_eq!(
        p.file.parent(),
        Some(fixtures_dir().as_path()),
        "diagnostic points outside the fixtures: {d}"
    );
    let name = p.file.file_name().unwrap().to_string_lossy().into_owned();
    (name, p.line, p.column, d.severity, d.message.clone())
}

/// The diagnostics of loading `name`, which must fail.
fn errors(name: &str) -> Vec<Diag> {
    match Schema::load(&[fixture(name)]) {
        Ok(_) => panic!("{name} loaded without errors"),
        Err(diags) => diags.iter().map(flatten).collect(),
    }
}

/// The warnings of loading `name`, which must succeed.
fn warnings(name: &str) -> Vec<Diag> {
    match Schema::load(&[fixture(name)]) {
        Ok(schema) => schema.warnings().iter().map(flatten).collect(),
        Err(diags) => panic!(
            "{name} failed to load:\n{}",
            diags.iter().map(|d| format!("{d}\n")).collect::<String>()
        ),
    }
}

/// Asserts `d` is at `file:line:col` with `severity` and a message
/// containing `needle`.
#[track_caller]
fn assert_diag(d: &Diag, file: &str, line: usize, col: usize, severity: Severity, needle: &str) {
    let (f, l, c, s, m) = d;
    assert_eq!(
        (f.as_str(), *l, *c, *s),
        (file, line, col, severity),
        "wrong place or severity for: {m}"
    );
    assert!(m.contains(needle), "message {m:?} lacks {needle:?}");
}

/// Asserts `diags` is exactly one error, at `file:line:col`, containing `needle`.
#[track_caller]
fn assert_one_error(diags: &[Diag], file: &str, line: usize, col: usize, needle: &str) {
    assert_eq!(
        diags.len(),
        1,
        "expected exactly one diagnostic: {diags:#?}"
    );
    assert_diag(&diags[0], file, line, col, Severity::Error, needle);
}

#[test]
fn malformed_xml_mismatched_end_tag_points_at_the_end_tag() {
    // `      <field type="uint8_t" name="x">x</fild>`: `</fild>` is column 39.
    let e = errors("malformed_end_tag.xml");
    assert_one_error(
        &e,
        "malformed_end_tag.xml",
        5,
        39,
        "malformed XML: ill-formed document: expected `</field>`, but `</fild>` was found",
    );
}

#[test]
fn malformed_xml_unclosed_attribute_quote_points_at_the_element() {
    // `name="x>…` never closes: the `<field` it belongs to is reported.
    let e = errors("malformed_quote.xml");
    assert_one_error(&e, "malformed_quote.xml", 5, 7, "malformed XML");
    assert!(e[0].4.contains("not closed"), "{e:?}");
}

#[test]
fn malformed_xml_in_an_included_file_is_reported_in_that_file() {
    let e = errors("malformed_included_root.xml");
    assert_diag(
        &e[0],
        "malformed_included.xml",
        5,
        26,
        Severity::Error,
        "expected `</description>`, but `</descripton>` was found",
    );
}

#[test]
fn malformed_xml_in_an_included_file_causes_no_follow_up_errors() {
    // Message B's <field> comes after the broken end tag, so it was never
    // read: claiming B "has no fields" is a follow-up error, not a finding.
    let e = errors("malformed_included_root.xml");
    assert_one_error(
        &e,
        "malformed_included.xml",
        5,
        26,
        "expected `</description>`",
    );
}

#[test]
fn unknown_field_type_points_at_the_type_attribute() {
    let e = errors("unknown_type.xml");
    assert_one_error(
        &e,
        "unknown_type.xml",
        6,
        14,
        "field bad: unknown type `float_t`",
    );
}

#[test]
fn a_byte_order_mark_does_not_shift_positions() {
    // quick-xml does not count a BOM in its offsets (found by the xml fuzz
    // target): the element's offset fell inside the 4-byte character before
    // it, and slicing there panicked.
    let e = errors("bom_unknown_type.xml");
    assert_one_error(
        &e,
        "bom_unknown_type.xml",
        6,
        15,
        "field bad: unknown type `float_t`",
    );
}

#[test]
fn display_is_file_line_col_severity_message() {
    let path = fixture("unknown_type.xml");
    let diags = Schema::load(&[&path]).unwrap_err();
    assert_eq!(diags.len(), 1);
    let shown = diags[0].to_string();
    let prefix = format!(
        "{}:6:14: error: field bad: unknown type `float_t`",
        path.display()
    );
    assert!(shown.starts_with(&prefix), "{shown}");
}

#[test]
fn columns_count_characters_not_bytes() {
    // `°` and `ü` take two bytes each before `type=`, which is character 37.
    let e = errors("columns_in_chars.xml");
    assert_one_error(&e, "columns_in_chars.xml", 5, 37, "unknown type `float_t`");
}

#[test]
fn zero_array_length_points_at_the_type_attribute() {
    let e = errors("bad_array_len.xml");
    assert_one_error(
        &e,
        "bad_array_len.xml",
        6,
        14,
        "field text: type `char[0]`: array length must be 1 to 255",
    );
}

#[test]
fn missing_include_points_at_the_include_element() {
    let e = errors("missing_include.xml");
    assert_one_error(&e, "missing_include.xml", 3, 3, "cannot read included file");
    assert!(e[0].4.contains("does_not_exist.xml"), "{e:?}");
}

#[test]
fn include_cycle_is_reported_at_the_include_closing_it() {
    // cycle_a.xml includes cycle_b.xml (line 3), which includes cycle_a.xml
    // (line 4): the second include closes the cycle.
    let e = errors("cycle_a.xml");
    assert_one_error(
        &e,
        "cycle_b.xml",
        4,
        3,
        "include cycle: cycle_a.xml -> cycle_b.xml -> cycle_a.xml",
    );
}

#[test]
fn duplicate_message_id_across_an_include() {
    // The root's ROOT_MSG (id 5) is read first; the included INC_MSG's `id=`
    // is reported, naming the root's message and line.
    let e = errors("dup_id_root.xml");
    assert_one_error(
        &e,
        "dup_id_included.xml",
        7,
        31,
        "duplicate message id 5 for INC_MSG (also used by ROOT_MSG at ",
    );
    assert!(e[0].4.ends_with("dup_id_root.xml:5)"), "{e:?}");
}

#[test]
fn duplicate_message_name() {
    let e = errors("dup_message_name.xml");
    assert_one_error(
        &e,
        "dup_message_name.xml",
        7,
        5,
        "duplicate message name A (first declared at ",
    );
    assert!(e[0].4.ends_with("dup_message_name.xml:4)"), "{e:?}");
}

#[test]
fn duplicate_field_in_a_message() {
    let e = errors("dup_field.xml");
    assert_one_error(
        &e,
        "dup_field.xml",
        7,
        9,
        "duplicate field x in message A (first at ",
    );
    assert!(e[0].4.ends_with("dup_field.xml:5)"), "{e:?}");
}

#[test]
fn duplicate_enum_value() {
    // E_C's `0x1` is the value of E_A.
    let e = errors("dup_enum_value.xml");
    assert_one_error(
        &e,
        "dup_enum_value.xml",
        7,
        7,
        "duplicate enum value E_C = 1 in E (already used by E_A at ",
    );
    assert!(e[0].4.ends_with("dup_enum_value.xml:5)"), "{e:?}");
}

#[test]
fn duplicate_enum_value_across_a_merge() {
    // Both files declare enum E; the merged entries clash on value 1.
    let e = errors("dup_enum_value_merge_root.xml");
    assert_one_error(
        &e,
        "dup_enum_value_merge_included.xml",
        6,
        7,
        "duplicate enum value E_INCLUDED = 1 in E (already used by E_ROOT at ",
    );
    assert!(
        e[0].4.ends_with("dup_enum_value_merge_root.xml:6)"),
        "{e:?}"
    );
}

#[test]
fn duplicate_enum_entry_name() {
    let e = errors("dup_enum_name.xml");
    assert_one_error(
        &e,
        "dup_enum_name.xml",
        7,
        7,
        "duplicate enum entry name E.E_A (first declared at ",
    );
    assert!(e[0].4.ends_with("dup_enum_name.xml:5)"), "{e:?}");
}

#[test]
fn duplicate_enum_entry_name_with_a_smaller_value_is_reported_at_the_later_entry() {
    // E_A = 2 on line 5, E_A = 1 on line 6: the duplicate is line 6.
    let e = errors("dup_enum_name_descending.xml");
    assert_one_error(
        &e,
        "dup_enum_name_descending.xml",
        6,
        7,
        "duplicate enum entry name E.E_A (first declared at ",
    );
    assert!(e[0].4.ends_with("dup_enum_name_descending.xml:5)"), "{e:?}");
}

#[test]
fn unknown_enum_points_at_the_enum_attribute() {
    let e = errors("unknown_enum.xml");
    assert_one_error(
        &e,
        "unknown_enum.xml",
        11,
        41,
        "field A.mode refers to unknown enum NO_SUCH_ENUM",
    );
}

#[test]
fn message_id_above_24_bits_points_at_the_id_attribute() {
    // 16777215 (LARGEST, line 4) is allowed; 16777216 (line 7) is not.
    let e = errors("big_id.xml");
    assert_one_error(
        &e,
        "big_id.xml",
        7,
        14,
        "message TOO_LARGE: id 16777216 is above 16777215",
    );
}

#[test]
fn payload_above_255_bytes_points_at_the_message() {
    // FULL (uint8_t[255], line 4) is allowed; 200 + 100 bytes is not.
    let e = errors("big_payload.xml");
    assert_one_error(
        &e,
        "big_payload.xml",
        7,
        5,
        "message OVERFULL has a 300-byte payload; a frame carries at most 255",
    );
}

#[test]
fn more_than_64_fields_points_at_the_message() {
    // SIXTY_FOUR (line 4) is allowed; SIXTY_FIVE (line 70) is not.
    let e = errors("too_many_fields.xml");
    assert_one_error(
        &e,
        "too_many_fields.xml",
        70,
        5,
        "message SIXTY_FIVE has 65 fields; at most 64 are allowed",
    );
}

#[test]
fn message_without_id_points_at_the_message() {
    let e = errors("missing_id.xml");
    assert_one_error(
        &e,
        "missing_id.xml",
        4,
        5,
        "message is missing its `id` attribute",
    );
}

#[test]
fn enum_entry_value_not_an_integer_points_at_the_value_attribute() {
    // `      <entry name="E_ONE" value="one"/>`: `value=` is column 27.
    let e = errors("bad_enum_value.xml");
    assert_one_error(
        &e,
        "bad_enum_value.xml",
        6,
        27,
        "enum entry E_ONE: value `one` is not a non-negative integer",
    );
}

#[test]
fn system_id_field_is_a_warning_and_the_schema_loads() {
    let w = warnings("system_id_warning.xml");
    assert_eq!(w.len(), 1, "{w:#?}");
    assert_diag(
        &w[0],
        "system_id_warning.xml",
        6,
        7,
        Severity::Warning,
        "field NOTICE.system_id has the name of a parameter of the official C generator",
    );
}

#[test]
fn rust_keywords_are_accepted_as_field_names() {
    assert_eq!(warnings("keywords.xml"), Vec::<Diag>::new());
    let generated = Config::new()
        .generate(&[fixture("keywords.xml")])
        .unwrap_or_else(|e| panic!("{e}"));
    let code: String = generated
        .output
        .files
        .iter()
        .map(|(_, text)| text.as_str())
        .collect();
    for field in [
        "pub r#type: u8",
        "pub r#match: u8",
        "pub self_: u8",
        "pub r#fn: u16",
        "pub r#async: u32",
    ] {
        assert!(code.contains(field), "generated code lacks `{field}`");
    }
}

#[test]
fn keyword_escape_that_collides_with_another_field_is_an_error() {
    // keyword_collision.xml: fields `self` (line 5) and `self_` (line 6).
    match Config::new().generate(&[fixture("keyword_collision.xml")]) {
        Ok(_) => panic!("two fields named `self_` in Rust were generated"),
        Err(Error::Invalid(diags)) => {
            let e: Vec<Diag> = diags.iter().map(flatten).collect();
            assert_one_error(&e, "keyword_collision.xml", 6, 7, "self_");
        }
        Err(e) => panic!("unexpected error: {e}"),
    }
}

#[test]
fn independent_parse_errors_are_all_reported() {
    let e = errors("two_errors.xml");
    assert_eq!(e.len(), 2, "{e:#?}");
    assert_diag(
        &e[0],
        "two_errors.xml",
        5,
        14,
        Severity::Error,
        "enum entry E_ZERO: value `zero` is not a non-negative integer",
    );
    assert_diag(
        &e[1],
        "two_errors.xml",
        10,
        14,
        Severity::Error,
        "field x: unknown type `uint128_t`",
    );
}

#[test]
fn independent_check_errors_are_all_reported() {
    let e = errors("two_check_errors.xml");
    assert_eq!(e.len(), 2, "{e:#?}");
    assert_diag(
        &e[0],
        "two_check_errors.xml",
        5,
        38,
        Severity::Error,
        "field A.x refers to unknown enum MISSING",
    );
    assert_diag(
        &e[1],
        "two_check_errors.xml",
        7,
        5,
        Severity::Error,
        "duplicate message name A",
    );
}

#[test]
fn valid_fixture_loads_without_diagnostics() {
    // The fixture the CLI tests generate from must stay clean.
    assert_eq!(warnings("valid_root.xml"), Vec::<Diag>::new());
}

// Files that are not whole XML documents: truncated, or with something
// outside the root element. Each comment says what pymavlink 2.4.50 does
// with the same file (`mavparse.MAVXML(path, '2.0')`, which parses with
// expat); expat's columns are 0-based, ours 1-based, so "expat 1:94" is our
// 1:95.

/// A whole one-message dialect on one line: `</messages>` starts at byte
/// 94, `</mavlink>` at 105, and it is 115 bytes long.
const WHOLE: &str = r#"<mavlink><messages><message id="1" name="X"><field type="uint8_t" name="a">a</field></message></messages></mavlink>"#;

/// The diagnostics of `Schema::from_text("x.xml", text)`, which must fail,
/// as `line:col: message` (the file is always x.xml).
fn text_errors(text: &str) -> Vec<String> {
    match Schema::from_text("x.xml", text) {
        Ok(_) => panic!("accepted without errors: {text:?}"),
        Err(diags) => diags
            .iter()
            .map(|d| {
                let p = d.position.as_ref().expect("a position");
                assert_eq!(p.file, Path::new("x.xml"));
                assert_eq!(d.severity, Severity::Error, "{d}");
                format!("{}:{}: {}", p.line, p.column, d.message)
            })
            .collect(),
    }
}

/// Asserts `text` fails with exactly one error, `line:col: message`.
#[track_caller]
fn assert_text_error(text: &str, expected: &str) {
    assert_eq!(text_errors(text), [expected], "for {text:?}");
}

#[test]
fn whole_file_and_what_may_surround_its_root_are_accepted() {
    // The control for the tests below; pymavlink agrees on all four.
    for text in [
        WHOLE.to_string(),
        format!("{WHOLE}\n"),
        format!("<?xml version=\"1.0\"?>\n<!DOCTYPE mavlink>\n<!-- c -->\n{WHOLE}\n"),
        format!("{WHOLE}\n<!-- trailing comment -->\n<?pi x?>\n"),
    ] {
        assert!(Schema::from_text("x.xml", &text).is_ok(), "{text:?}");
    }
}

#[test]
fn a_file_truncated_inside_an_element_names_the_element_and_where_it_opened() {
    // The file as an interrupted copy leaves it, cut before `</messages>`.
    // Was accepted as one message. pymavlink: "no element found: line 1,
    // column 94", the same place.
    assert_text_error(
        &WHOLE[..94],
        "1:95: the file ends inside <messages> (opened at 1:10)",
    );
}

#[test]
fn a_file_truncated_before_the_root_end_tag_points_at_the_end_of_the_file() {
    // Cut after `</messages>` and a newline. Was accepted. pymavlink: "no
    // element found: line 2, column 0", the same place.
    assert_text_error(
        &format!("{}\n", &WHOLE[..105]),
        "2:1: the file ends inside <mavlink> (opened at 1:1)",
    );
}

#[test]
fn a_file_truncated_inside_element_text_names_the_innermost_element() {
    // Cut inside a field's description, on the third line. Was accepted.
    // pymavlink: "no element found: line 3, column 68", the same place.
    let text = "<mavlink>\n<messages>\n<message id=\"1\" name=\"X\"><field type=\"uint8_t\" name=\"a\">half a descr";
    assert_text_error(text, "3:69: the file ends inside <field> (opened at 3:26)");
}

#[test]
fn a_file_holding_only_an_open_root_is_truncated_not_empty() {
    // Was accepted as a dialect without messages. pymavlink: "no element
    // found: line 1, column 9", the same place.
    assert_text_error(
        "<mavlink>",
        "1:10: the file ends inside <mavlink> (opened at 1:1)",
    );
}

#[test]
fn a_file_truncated_inside_a_tag_or_an_end_tag_points_at_the_tag() {
    // quick-xml reported these before the fix too; pinned here. pymavlink:
    // "unclosed token: line 1, column 105" for both, the same place.
    let tag = format!("{}<ver", &WHOLE[..105]);
    let end_tag = &WHOLE[..WHOLE.len() - 1];
    for text in [tag.as_str(), end_tag] {
        assert_text_error(
            text,
            "1:106: malformed XML: syntax error: tag not closed: `>` not found before end of input",
        );
    }
}

#[test]
fn a_file_truncated_inside_an_attribute_value_points_at_its_element() {
    // Cut in `name="a`. quick-xml reported this before the fix too.
    // pymavlink: "unclosed token: line 1, column 44", the same place.
    assert_text_error(
        &WHOLE[..72],
        "1:45: malformed XML: syntax error: tag not closed: `>` not found before end of input",
    );
}

#[test]
fn a_file_truncated_inside_a_comment_points_at_the_comment() {
    // quick-xml reported this before the fix too. pymavlink: "unclosed
    // token: line 1, column 105", the same place.
    assert_text_error(
        &format!("{}<!-- half a comm", &WHOLE[..105]),
        "1:106: malformed XML: syntax error: comment not closed: `-->` not found before end of input",
    );
}

#[test]
fn a_file_truncated_inside_cdata_or_a_declaration_points_at_its_start() {
    // quick-xml reported these before the fix too. pymavlink: "unclosed
    // CDATA section: line 1, column 116" (the end of the file, where we
    // point at the section's start) and "unclosed token: line 1, column 0"
    // (the same place).
    assert_text_error(
        &format!("{}<![CDATA[ x", &WHOLE[..105]),
        "1:106: malformed XML: syntax error: CDATA not closed: `]]>` not found before end of input",
    );
    assert_text_error(
        "<?xml version=\"1.0\"",
        "1:1: malformed XML: syntax error: processing instruction or xml declaration not closed: `?>` not found before end of input",
    );
}

#[test]
fn a_mismatched_or_extra_end_tag_points_at_the_end_tag() {
    // quick-xml reported these before the fix too. pymavlink: "mismatched
    // tag: line 1, column 107" and "not well-formed (invalid token): line
    // 1, column 116": the same end tags, at its name and at its `/` where
    // we point at its `<`.
    assert_text_error(
        &format!("{}</wrong>", &WHOLE[..105]),
        "1:106: malformed XML: ill-formed document: expected `</mavlink>`, but `</wrong>` was found",
    );
    assert_text_error(
        &format!("{WHOLE}</extra>"),
        "1:116: malformed XML: ill-formed document: close tag `</extra>` does not match any open tag",
    );
}

#[test]
fn text_outside_the_root_element_is_an_error_where_it_starts() {
    // Both were accepted. pymavlink: "junk after document element: line 2,
    // column 2" and "syntax error: line 1, column 0", the same places. An
    // entity is text too (pymavlink: "not well-formed (invalid token): line
    // 2, column 0").
    assert_text_error(
        &format!("{WHOLE}\n  trailing text\n"),
        "2:3: text after the root element <mavlink>, which closed at 1:106 (only comments may follow it)",
    );
    assert_text_error(
        &format!("{WHOLE}\n&amp;"),
        "2:1: text after the root element <mavlink>, which closed at 1:106 (only comments may follow it)",
    );
    assert_text_error(
        &format!("text before{WHOLE}"),
        "1:1: text before the root element (only the XML declaration, a DOCTYPE and comments may precede it)",
    );
}

#[test]
fn a_second_element_after_the_root_is_an_error_at_that_element() {
    // Was accepted (a second <mavlink> with messages would even have been
    // merged in). pymavlink: "junk after document element" at line 2,
    // column 0 and line 1, column 10: the same places.
    assert_text_error(
        &format!("{WHOLE}\n{WHOLE}\n"),
        "2:1: an element <mavlink> after the root element <mavlink>, which closed at 1:106 (only comments may follow it)",
    );
    assert_text_error(
        "<mavlink/><x/>",
        "1:11: an element <x> after the root element <mavlink>, which closed at 1:1 (only comments may follow it)",
    );
}

#[test]
fn cdata_doctype_or_a_declaration_out_of_place_is_an_error() {
    // All were accepted. pymavlink: "junk after document element: line 2,
    // column 0" for the first two, "syntax error: line 1, column 0" for the
    // third, "XML or text declaration not at start of entity: line 2,
    // column 0" for the last: the same places.
    let after =
        "after the root element <mavlink>, which closed at 1:106 (only comments may follow it)";
    assert_text_error(
        &format!("{WHOLE}\n<![CDATA[x]]>"),
        &format!("2:1: a CDATA section {after}"),
    );
    assert_text_error(
        &format!("{WHOLE}\n<!DOCTYPE x>"),
        &format!("2:1: a DOCTYPE {after}"),
    );
    assert_text_error(
        &format!("<![CDATA[x]]>{WHOLE}"),
        "1:1: a CDATA section before the root element (only the XML declaration, a DOCTYPE and comments may precede it)",
    );
    assert_text_error(
        &format!("<!-- c -->\n<?xml version=\"1.0\"?>\n{WHOLE}"),
        "2:1: an XML declaration (<?xml …?>) may only open the file",
    );
    // pymavlink: "not well-formed (invalid token): line 2, column 2", at the
    // DOCTYPE's name where we point at its `<`.
    assert_text_error(
        "<mavlink>\n<!DOCTYPE x>\n</mavlink>",
        "2:1: a DOCTYPE inside the root element",
    );
}

#[test]
fn a_file_without_an_element_is_an_error_at_its_end() {
    // pymavlink: "no element found" at line 1 column 0, line 3 column 0 and
    // line 2 column 0: the same places. The empty and blank files were
    // refused before too (at 1:1); the one whose comment mentions <mavlink>
    // was accepted, as the old check searched the text for "<mavlink".
    assert_text_error(
        "",
        "1:1: not a MAVLink definition: the file is empty, no <mavlink> root element",
    );
    assert_text_error(
        "  \n\n",
        "3:1: not a MAVLink definition: the file is empty, no <mavlink> root element",
    );
    assert_text_error(
        "<!-- <mavlink> -->\n",
        "2:1: not a MAVLink definition: the file holds no element, no <mavlink> root element",
    );
}

#[test]
fn a_root_other_than_mavlink_is_an_error_at_the_root() {
    // pymavlink accepts all three as a dialect without messages (it only
    // looks at paths under `mavlink`); we refuse them, as `<foo/>` was
    // already. `<mavlinkx/>` and `<foo><mavlink/></foo>` were accepted, as
    // the old check searched the text for "<mavlink".
    for (text, root) in [
        ("<foo/>", "foo"),
        ("<mavlinkx/>", "mavlinkx"),
        ("<foo><mavlink/></foo>", "foo"),
    ] {
        assert_text_error(
            text,
            &format!("1:1: not a MAVLink definition: the root element is <{root}>, not <mavlink>"),
        );
    }
}
