//! Rust names for XML names, and rustdoc text for XML descriptions.

use proc_macro2::{Ident, Span};

/// Words Rust reserves; an XML name equal to one gets a raw identifier
/// (`r#type`), or a trailing `_` where raw identifiers are not allowed.
const KEYWORDS: &[&str] = &[
    "as", "break", "const", "continue", "crate", "else", "enum", "extern", "false", "fn", "for",
    "if", "impl", "in", "let", "loop", "match", "mod", "move", "mut", "pub", "ref", "return",
    "self", "Self", "static", "struct", "super", "trait", "true", "type", "unsafe", "use", "where",
    "while", "async", "await", "dyn", "abstract", "become", "box", "do", "final", "macro",
    "override", "priv", "typeof", "unsized", "virtual", "yield", "try", "gen",
];

/// Keywords that cannot be raw identifiers.
const NOT_RAW: &[&str] = &["crate", "self", "Self", "super", "_"];

/// An identifier for `name`, escaped if it is a keyword.
pub fn ident(name: &str) -> Ident {
    if NOT_RAW.contains(&name) {
        Ident::new(&format!("{name}_"), Span::call_site())
    } else if KEYWORDS.contains(&name) {
        Ident::new_raw(name, Span::call_site())
    } else {
        Ident::new(name, Span::call_site())
    }
}

/// `GLOBAL_POSITION_INT` → `GlobalPositionInt`, `GPS2_RAW` → `Gps2Raw`.
pub fn camel(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    for part in name.split('_').filter(|p| !p.is_empty()) {
        let mut chars = part.chars();
        if let Some(c) = chars.next() {
            out.push(c.to_ascii_uppercase());
            out.extend(chars.map(|c| c.to_ascii_lowercase()));
        }
    }
    if out.is_empty() || out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert(0, 'M');
    }
    out
}

/// A field name as a Rust method/field name: `omegaIx` → `omega_ix`,
/// `Vcc` → `vcc`; snake_case names are unchanged.
pub fn field(name: &str) -> String {
    let mut out = String::with_capacity(name.len() + 4);
    let mut prev_lower = false;
    for c in name.chars() {
        if c.is_ascii_uppercase() {
            if prev_lower {
                out.push('_');
            }
            out.push(c.to_ascii_lowercase());
            prev_lower = false;
        } else {
            out.push(c);
            prev_lower = c.is_ascii_lowercase() || c.is_ascii_digit();
        }
    }
    out
}

/// `uAvionix` → `uavionix`, `python_array_test` unchanged: module names.
pub fn snake(name: &str) -> String {
    let mut out = String::with_capacity(name.len() + 4);
    for c in name.chars() {
        if c.is_ascii_alphanumeric() {
            out.push(c.to_ascii_lowercase());
        } else if !out.ends_with('_') {
            out.push('_');
        }
    }
    if out.is_empty() || out.starts_with(|c: char| c.is_ascii_digit()) {
        out.insert_str(0, "m_");
    }
    out
}

/// The module for an XML file named `stem`: [`snake`] case, and a trailing
/// `_` for a Rust keyword (`fn.xml` → `fn_`, `mod.xml` → `mod_`, `self.xml`
/// → `self_`). The module's file is `<module>.rs`, so a keyword cannot be a
/// raw identifier (`r#fn.rs`), and `mod.rs` stays the root of the output.
pub fn module(stem: &str) -> String {
    let mut name = snake(stem);
    if KEYWORDS.contains(&name.as_str()) || name == "_" {
        name.push('_');
    }
    name
}

/// The name of an enum entry inside its enum: the enum's name is stripped
/// (`MAV_TYPE_FIXED_WING` in `MAV_TYPE` → `FIXED_WING`) unless what remains
/// would start with a digit, where the enum's last word stays
/// (`GPS_FIX_TYPE_2D_FIX` → `TYPE_2D_FIX`).
pub fn entry_suffix<'a>(enum_name: &str, entry: &'a str) -> &'a str {
    let Some(rest) = entry
        .strip_prefix(enum_name)
        .and_then(|r| r.strip_prefix('_'))
    else {
        return entry;
    };
    if rest.is_empty() {
        return entry;
    }
    if rest.starts_with(|c: char| c.is_ascii_digit()) {
        let word_start = enum_name.rfind('_').map_or(0, |i| i + 1);
        return &entry[word_start..];
    }
    rest
}

/// Turns XML description text into rustdoc lines: whitespace folded (so no
/// accidental code blocks or doctests), brackets and HTML escaped (rustdoc
/// would take them for links and tags), bare URLs wrapped so rustdoc links
/// them, and a line that would start a list or heading escaped.
pub fn doc_lines(text: &str, width: usize) -> Vec<String> {
    wrap(&escape(text), width)
        .into_iter()
        .map(|l| escape_line_start(&l))
        .collect()
}

/// Like [`doc_lines`], as one Markdown list item (`- ` then indented lines).
pub fn doc_list_item(text: &str, width: usize) -> Vec<String> {
    wrap(&escape(text), width.saturating_sub(2))
        .into_iter()
        .enumerate()
        .map(|(i, l)| {
            if i == 0 {
                format!("- {l}")
            } else {
                format!("  {}", escape_line_start(&l))
            }
        })
        .collect()
}

fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for word in text.split_whitespace() {
        if !out.is_empty() {
            out.push(' ');
        }
        let (word, url) = match word.find("http://").or_else(|| word.find("https://")) {
            Some(at) => (&word[..at], Some(&word[at..])),
            None => (word, None),
        };
        for c in word.chars() {
            match c {
                '[' => out.push_str("\\["),
                ']' => out.push_str("\\]"),
                '<' => out.push_str("&lt;"),
                '>' => out.push_str("&gt;"),
                '\\' => out.push_str("\\\\"),
                _ => out.push(c),
            }
        }
        if let Some(url) = url {
            let link = url.trim_end_matches(['.', ',', ')', ';', ':', ']', '\'']);
            out.push('<');
            out.push_str(link);
            out.push('>');
            out.push_str(&url[link.len()..]);
        }
    }
    out
}

/// Markdown reads `- x`, `+ x`, `* x`, `# x` and `1. x` at a line start as
/// structure; in the middle of a wrapped sentence they are text.
fn escape_line_start(line: &str) -> String {
    let mut chars = line.chars();
    let first = chars.next();
    let second = chars.next();
    let digits = line.chars().take_while(char::is_ascii_digit).count();
    let after_digits = line[digits..].chars().collect::<Vec<_>>();
    let structural = match first {
        Some('-' | '+' | '*') => {
            second.is_none_or(|c| c == ' ') || line.chars().all(|c| c == first.unwrap())
        }
        Some('#') => second.is_none_or(|c| c == ' ' || c == '#'),
        Some('=') => line.chars().all(|c| c == '='),
        _ => digits > 0 && matches!(after_digits.as_slice(), ['.' | ')'] | ['.' | ')', ' ', ..]),
    };
    if structural {
        format!("\\{line}")
    } else {
        line.to_string()
    }
}

/// Greedy word wrap.
pub fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for word in text.split(' ').filter(|w| !w.is_empty()) {
        if !line.is_empty() && line.len() + 1 + word.len() > width {
            lines.push(std::mem::take(&mut line));
        }
        if !line.is_empty() {
            line.push(' ');
        }
        line.push_str(word);
    }
    if !line.is_empty() {
        lines.push(line);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camel_case_names() {
        assert_eq!(camel("FBWAG_NOTICE"), "FbwagNotice");
        assert_eq!(camel("GPS2_RAW"), "Gps2Raw");
        assert_eq!(camel("MAV_CMD"), "MavCmd");
        assert_eq!(camel("2D"), "M2d");
    }

    #[test]
    fn field_names_become_snake_case() {
        assert_eq!(field("omegaIx"), "omega_ix");
        assert_eq!(field("Vcc"), "vcc");
        assert_eq!(field("time_boot_ms"), "time_boot_ms");
        assert_eq!(field("xacc2"), "xacc2");
    }

    #[test]
    fn keywords_are_escaped() {
        assert_eq!(ident("type").to_string(), "r#type");
        assert_eq!(ident("self").to_string(), "self_");
        assert_eq!(ident("yaw").to_string(), "yaw");
    }

    #[test]
    fn entry_names_lose_their_enum_prefix() {
        assert_eq!(
            entry_suffix("MAV_TYPE", "MAV_TYPE_FIXED_WING"),
            "FIXED_WING"
        );
        assert_eq!(
            entry_suffix("GPS_FIX_TYPE", "GPS_FIX_TYPE_2D_FIX"),
            "TYPE_2D_FIX"
        );
        assert_eq!(entry_suffix("MAV_FRAME", "MAV_FRAME"), "MAV_FRAME");
        assert_eq!(entry_suffix("A", "B_C"), "B_C");
    }

    #[test]
    fn docs_are_escaped_and_wrapped() {
        let lines = doc_lines(
            "Angle  [rad] <b>x</b>\n    code? see https://mavlink.io/x.",
            200,
        );
        assert_eq!(
            lines,
            vec!["Angle \\[rad\\] &lt;b&gt;x&lt;/b&gt; code? see <https://mavlink.io/x>."]
        );
        assert_eq!(wrap("aa bb cc", 5), vec!["aa bb", "cc"]);
    }
}
