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

/// `fieldName`/`FIELD_NAME` → `field_name` for module names.
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
/// accidental code blocks or doctests), Markdown-significant brackets and
/// HTML escaped, bare URLs wrapped so rustdoc links them without warnings.
pub fn doc_lines(text: &str, width: usize) -> Vec<String> {
    let folded = text.split_whitespace().collect::<Vec<_>>().join(" ");
    let mut escaped = String::with_capacity(folded.len());
    for word in folded.split(' ') {
        if !escaped.is_empty() {
            escaped.push(' ');
        }
        if word.starts_with("http://") || word.starts_with("https://") {
            let trimmed = word.trim_end_matches(['.', ',', ')', ';']);
            escaped.push('<');
            escaped.push_str(trimmed);
            escaped.push('>');
            escaped.push_str(&word[trimmed.len()..]);
            continue;
        }
        for c in word.chars() {
            match c {
                '[' => escaped.push_str("\\["),
                ']' => escaped.push_str("\\]"),
                '<' => escaped.push_str("&lt;"),
                '>' => escaped.push_str("&gt;"),
                '*' => escaped.push_str("\\*"),
                '_' => escaped.push_str("\\_"),
                '`' => escaped.push_str("\\`"),
                '#' => escaped.push_str("\\#"),
                '|' => escaped.push_str("\\|"),
                '\\' => escaped.push_str("\\\\"),
                _ => escaped.push(c),
            }
        }
    }
    wrap(&escaped, width)
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
