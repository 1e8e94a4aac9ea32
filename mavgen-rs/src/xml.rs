//! Reads one MAVLink XML file into the [`model`](crate::model).
//!
//! Element paths follow pymavlink's `mavparse`: only `mavlink.messages.*`,
//! `mavlink.enums.*`, `mavlink.include`, `mavlink.version` and
//! `mavlink.dialect` carry meaning; anything else is ignored as it is there.

use crate::diag::{Diagnostics, Loc, Source};
use crate::model::{Deprecated, Entry, Enum, Field, Include, Message, Param, Primitive, XmlFile};
use quick_xml::events::{BytesStart, Event};
use quick_xml::Reader;
use std::path::PathBuf;

/// Parses `sources[file]`. Problems go to `diags`; the returned model holds
/// what could be read (callers stop when `diags` has errors).
pub fn parse(sources: &[Source], file: usize, path: PathBuf, diags: &mut Diagnostics) -> XmlFile {
    let mut p = Parser {
        sources,
        file,
        diags,
        out: XmlFile {
            path,
            version: 2,
            dialect: None,
            includes: Vec::new(),
            enums: Vec::new(),
            messages: Vec::new(),
        },
        stack: Vec::new(),
        opened: Vec::new(),
        root: Root::NotYet,
        in_extensions: false,
        text_target: None,
    };
    p.run();
    p.out
}

/// The deepest element with a meaning: `mavlink.enums.enum.entry.param`.
const MEANINGFUL_DEPTH: usize = 5;

/// Where the reader is with respect to the root element.
#[derive(Clone, Copy, PartialEq)]
enum Root {
    /// No element yet: only the XML declaration, a DOCTYPE, comments,
    /// processing instructions and whitespace may come.
    NotYet,
    /// Inside the root element.
    Open,
    /// The root element, opened at `opened`, closed at `closed` (its end
    /// tag, or the element itself when empty): only comments, processing
    /// instructions and whitespace may follow.
    Closed { opened: usize, closed: usize },
}

/// Where character data goes, by element path.
#[derive(Clone, Copy, PartialEq)]
enum Text {
    MessageDescription,
    MessageDeprecated,
    Field,
    EnumDescription,
    EnumDeprecated,
    EntryDescription,
    EntryDeprecated,
    Param,
    Version,
    Dialect,
    Include,
}

struct Parser<'s, 'd> {
    sources: &'s [Source],
    file: usize,
    diags: &'d mut Diagnostics,
    out: XmlFile,
    /// Names of the open elements, the outermost [`MEANINGFUL_DEPTH`] only:
    /// deeper elements carry no meaning, and keeping (and joining) all names
    /// would make deeply nested input cost memory and quadratic time.
    stack: Vec<String>,
    /// Where each open element starts, outermost first: its length is the
    /// nesting depth, and a file that ends early is reported at the element
    /// it leaves open. One offset per level (the reader keeps every open
    /// name for its own end-tag check anyway).
    opened: Vec<usize>,
    /// Whether the root element has been read, to refuse what XML allows
    /// only once per file (one root) or only inside the root (text).
    root: Root,
    in_extensions: bool,
    /// Where character data goes: the target, the text so far, where the
    /// element starts, and its nesting depth (its end closes the target).
    text_target: Option<(Text, String, Loc, usize)>,
}

impl Parser<'_, '_> {
    fn loc(&self, offset: usize) -> Loc {
        Loc {
            file: self.file,
            offset,
        }
    }

    fn error(&mut self, offset: usize, msg: impl Into<String>) {
        let loc = self.loc(offset);
        self.diags.error(self.sources, loc, msg);
    }

    fn run(&mut self) {
        let text = &self.sources[self.file].text;
        // quick-xml skips a byte-order mark without counting it in its
        // positions, which would put every offset 3 bytes early (wrong
        // columns, and slicing inside a character). Parse after it instead
        // and add it back.
        let bom = if text.starts_with('\u{feff}') {
            '\u{feff}'.len_utf8()
        } else {
            0
        };
        let mut reader = Reader::from_str(&text[bom..]);
        reader.config_mut().trim_text(false);
        loop {
            let start = bom + reader.buffer_position() as usize;
            let event = match reader.read_event() {
                Ok(Event::Eof) => break,
                Ok(event) => event,
                Err(e) => {
                    let at = bom + reader.error_position() as usize;
                    self.error(at, format!("malformed XML: {e}"));
                    return;
                }
            };
            if !self.placed(&event, start, bom) {
                return;
            }
            self.event(event, start);
        }
        self.at_eof(text.len());
    }

    /// Hands one event to the model.
    fn event(&mut self, event: Event, start: usize) {
        match event {
            Event::Start(e) => {
                self.open(&e, start);
                self.start(&e, start);
            }
            Event::Empty(e) => {
                self.open(&e, start);
                self.start(&e, start);
                self.end(start);
            }
            Event::End(_) => self.end(start),
            Event::Text(t) => match t.unescape() {
                Ok(s) => self.text(&s),
                Err(e) => self.error(start, format!("malformed XML: {e}")),
            },
            Event::CData(t) => self.text(&String::from_utf8_lossy(&t)),
            _ => {}
        }
    }

    /// Refuses what quick-xml reads without complaint but XML (and so
    /// pymavlink's expat) forbids at this place: text or a second element
    /// outside the root, a DOCTYPE after it, an XML declaration not opening
    /// the file. Reports the first and returns false, as expat stops there.
    fn placed(&mut self, event: &Event, start: usize, bom: usize) -> bool {
        let what = match (event, self.root) {
            (Event::Decl(_), _) if start != bom => {
                self.error(
                    start,
                    "an XML declaration (<?xml …?>) may only open the file",
                );
                return false;
            }
            (Event::Text(t), Root::NotYet | Root::Closed { .. }) => match non_blank(t) {
                None => return true,
                Some(skip) => return self.outside_root(start + skip, "text"),
            },
            (Event::CData(_), Root::NotYet | Root::Closed { .. }) => "a CDATA section".to_string(),
            (Event::DocType(_), Root::Open | Root::Closed { .. }) => "a DOCTYPE".to_string(),
            (Event::Start(e) | Event::Empty(e), Root::Closed { .. }) => format!(
                "an element <{}>",
                String::from_utf8_lossy(e.name().as_ref())
            ),
            _ => return true,
        };
        self.outside_root(start, &what)
    }

    /// Reports `what`, found at `at` where it may not be; returns false.
    fn outside_root(&mut self, at: usize, what: &str) -> bool {
        let msg = match self.root {
            Root::NotYet => format!(
                "{what} before the root element (only the XML declaration, a DOCTYPE and comments may precede it)"
            ),
            Root::Open => format!("{what} inside the root element"),
            Root::Closed { opened, closed } => {
                let p = self.sources[self.file].position(closed);
                format!(
                    "{what} after the root element <{}>, which closed at {}:{} (only comments may follow it)",
                    self.name_at(opened),
                    p.line,
                    p.column
                )
            }
        };
        self.error(at, msg);
        false
    }

    /// Refuses a file that ends inside an element (a truncated copy: expat
    /// says "no element found") or holds none, or whose root is not
    /// `<mavlink>`.
    fn at_eof(&mut self, len: usize) {
        if let Some(&innermost) = self.opened.last() {
            let name = self.name_at(innermost);
            let p = self.sources[self.file].position(innermost);
            let msg = format!(
                "the file ends inside <{name}> (opened at {}:{})",
                p.line, p.column
            );
            self.error(len, msg);
        } else if self.root == Root::NotYet {
            let blank = self.sources[self.file]
                .text
                .trim_start_matches('\u{feff}')
                .trim()
                .is_empty();
            let what = if blank {
                "the file is empty"
            } else {
                "the file holds no element"
            };
            self.error(
                len,
                format!("not a MAVLink definition: {what}, no <mavlink> root element"),
            );
        }
    }

    /// The name of the element whose tag starts at `offset`.
    fn name_at(&self, offset: usize) -> &str {
        let tag = self.sources[self.file].text.get(offset + 1..).unwrap_or("");
        let end = tag
            .find(|c: char| c.is_whitespace() || c == '/' || c == '>')
            .unwrap_or(tag.len());
        &tag[..end]
    }

    fn open(&mut self, e: &BytesStart, start: usize) {
        if self.root == Root::NotYet {
            self.root = Root::Open;
            if e.name().as_ref() != b"mavlink" {
                let name = String::from_utf8_lossy(e.name().as_ref()).into_owned();
                self.error(
                    start,
                    format!(
                        "not a MAVLink definition: the root element is <{name}>, not <mavlink>"
                    ),
                );
            }
        }
        self.opened.push(start);
        if self.depth() <= MEANINGFUL_DEPTH {
            let name = String::from_utf8_lossy(e.name().as_ref()).into_owned();
            self.stack.push(name);
        }
    }

    /// How many elements are open.
    fn depth(&self) -> usize {
        self.opened.len()
    }

    /// The dotted path of the open elements (`mavlink.messages.message`);
    /// empty below [`MEANINGFUL_DEPTH`], where no path has a meaning.
    fn path(&self) -> String {
        if self.depth() > MEANINGFUL_DEPTH {
            return String::new();
        }
        self.stack.join(".")
    }

    /// The offset of attribute `name` inside the element starting at `start`,
    /// so a bad value is pointed at precisely.
    fn attr_offset(&self, start: usize, name: &str) -> usize {
        let text = &self.sources[self.file].text[start..];
        let end = text.find('>').unwrap_or(text.len());
        let needle = format!("{name}=");
        text[..end]
            .match_indices(&needle)
            .find(|(i, _)| text[..*i].ends_with(char::is_whitespace))
            .map_or(start, |(i, _)| start + i)
    }

    fn attrs(&mut self, e: &BytesStart, start: usize) -> Vec<(String, String)> {
        let mut out = Vec::new();
        for a in e.attributes() {
            match a {
                Ok(a) => {
                    let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
                    match a.unescape_value() {
                        Ok(v) => out.push((key, v.into_owned())),
                        Err(err) => {
                            let at = self.attr_offset(start, &key);
                            self.error(at, format!("malformed XML: attribute `{key}`: {err}"));
                        }
                    }
                }
                Err(err) => self.error(start, format!("malformed XML: {err}")),
            }
        }
        out
    }

    fn required(
        &mut self,
        attrs: &[(String, String)],
        name: &str,
        what: &str,
        start: usize,
    ) -> Option<String> {
        let v = get(attrs, name);
        if v.is_none() {
            self.error(start, format!("{what} is missing its `{name}` attribute"));
        }
        v
    }

    fn start(&mut self, e: &BytesStart, start: usize) {
        let path = self.path();
        let loc = self.loc(start);
        match path.as_str() {
            "mavlink.messages.message" => self.start_message(e, start, loc),
            "mavlink.messages.message.wip" => {
                if let Some(m) = self.out.messages.last_mut() {
                    m.wip = true;
                }
            }
            "mavlink.messages.message.extensions" => self.in_extensions = true,
            "mavlink.messages.message.deprecated" => {
                let d = self.deprecated(e, start);
                if let Some(m) = self.out.messages.last_mut() {
                    m.deprecated = Some(d);
                }
                self.collect(Text::MessageDeprecated, loc);
            }
            "mavlink.messages.message.description" => {
                self.collect(Text::MessageDescription, loc);
            }
            "mavlink.messages.message.field" => self.start_field(e, start, loc),
            "mavlink.enums.enum" => self.start_enum(e, start, loc),
            "mavlink.enums.enum.description" => {
                self.collect(Text::EnumDescription, loc);
            }
            "mavlink.enums.enum.deprecated" => {
                let d = self.deprecated(e, start);
                if let Some(en) = self.out.enums.last_mut() {
                    en.deprecated = Some(d);
                }
                self.collect(Text::EnumDeprecated, loc);
            }
            "mavlink.enums.enum.entry" => self.start_entry(e, start, loc),
            "mavlink.enums.enum.entry.description" => {
                self.collect(Text::EntryDescription, loc);
            }
            "mavlink.enums.enum.entry.wip" => {
                if let Some(en) = self.out.enums.last_mut().and_then(|e| e.entries.last_mut()) {
                    en.wip = true;
                }
            }
            "mavlink.enums.enum.entry.deprecated" => {
                let d = self.deprecated(e, start);
                if let Some(en) = self.out.enums.last_mut().and_then(|e| e.entries.last_mut()) {
                    en.deprecated = Some(d);
                }
                self.collect(Text::EntryDeprecated, loc);
            }
            "mavlink.enums.enum.entry.param" => self.start_param(e, start, loc),
            "mavlink.include" => self.collect(Text::Include, loc),
            "mavlink.version" => self.collect(Text::Version, loc),
            "mavlink.dialect" => self.collect(Text::Dialect, loc),
            _ => {}
        }
    }

    /// A `<message>`: its name and id.
    fn start_message(&mut self, e: &BytesStart, start: usize, loc: Loc) {
        let attrs = self.attrs(e, start);
        let name = self
            .required(&attrs, "name", "message", start)
            .unwrap_or_default();
        let id_text = self.required(&attrs, "id", "message", start);
        let id_loc = self.loc(self.attr_offset(start, "id"));
        let id = match id_text.as_deref().map(parse_int) {
            Some(Some(v)) => v,
            Some(None) => {
                let msg = format!(
                    "message {name}: id `{}` is not a non-negative integer",
                    id_text.unwrap_or_default()
                );
                self.error(id_loc.offset, msg);
                0
            }
            None => 0,
        };
        self.in_extensions = false;
        self.out.messages.push(Message {
            id,
            name,
            description: String::new(),
            deprecated: None,
            wip: false,
            fields: Vec::new(),
            loc,
            id_loc,
        });
    }

    /// A message's `<field>`: its type, enum and the other attributes.
    fn start_field(&mut self, e: &BytesStart, start: usize, loc: Loc) {
        let attrs = self.attrs(e, start);
        let name = self
            .required(&attrs, "name", "field", start)
            .unwrap_or_default();
        let ty = self
            .required(&attrs, "type", "field", start)
            .unwrap_or_else(|| "uint8_t".into());
        let type_at = self.attr_offset(start, "type");
        let enum_loc = self.loc(self.attr_offset(start, "enum"));
        let (primitive, array_len, mavlink_version) = match parse_type(&ty) {
            Ok(t) => t,
            Err(msg) => {
                self.error(type_at, format!("field {name}: {msg}"));
                (Primitive::U8, None, false)
            }
        };
        let field = Field {
            name,
            primitive,
            array_len,
            mavlink_version,
            enum_name: get(&attrs, "enum").filter(|s| !s.is_empty()),
            display: get(&attrs, "display"),
            units: get(&attrs, "units").filter(|s| !s.is_empty()),
            multiplier: get(&attrs, "multiplier"),
            instance: get(&attrs, "instance").is_some_and(|v| v == "true"),
            invalid: get(&attrs, "invalid"),
            default: get(&attrs, "default"),
            description: String::new(),
            extension: self.in_extensions,
            loc,
            enum_loc,
        };
        if let Some(m) = self.out.messages.last_mut() {
            m.fields.push(field);
        }
        self.collect(Text::Field, loc);
    }

    /// An `<enum>`.
    fn start_enum(&mut self, e: &BytesStart, start: usize, loc: Loc) {
        let attrs = self.attrs(e, start);
        let name = self
            .required(&attrs, "name", "enum", start)
            .unwrap_or_default();
        self.out.enums.push(Enum {
            name,
            description: String::new(),
            bitmask: get(&attrs, "bitmask").is_some_and(|v| v == "true"),
            deprecated: None,
            entries: Vec::new(),
            start_value: None,
            highest_value: 0,
            loc,
        });
    }

    /// An enum `<entry>`, numbered as pymavlink does when it has no value.
    fn start_entry(&mut self, e: &BytesStart, start: usize, loc: Loc) {
        let attrs = self.attrs(e, start);
        let name = self
            .required(&attrs, "name", "enum entry", start)
            .unwrap_or_default();
        let value_text = get(&attrs, "value");
        let value_at = self.attr_offset(start, "value");
        let Some(en) = self.out.enums.last() else {
            return;
        };
        // pymavlink: an entry without a value is one above the highest
        // so far, and the highest starts at 0 (so the first is 1).
        let (value, autovalue) = match value_text.as_deref() {
            None => (en.highest_value + 1, true),
            Some(t) => match parse_value(t) {
                Some(v) => (v, false),
                None => {
                    self.error(value_at, format!("enum entry {name}: value `{t}` is not a non-negative integer (decimal, 0x…, 0b…, 0o… or A**B)"));
                    (0, false)
                }
            },
        };
        let en = self.out.enums.last_mut().expect("checked above");
        if en.start_value.is_none_or(|s| value < s) {
            en.start_value = Some(value);
        }
        en.highest_value = en.highest_value.max(value);
        en.entries.push(Entry {
            name,
            value,
            autovalue,
            description: String::new(),
            deprecated: None,
            wip: false,
            params: Vec::new(),
            loc,
        });
    }

    /// An entry's `<param>`.
    fn start_param(&mut self, e: &BytesStart, start: usize, loc: Loc) {
        let attrs = self.attrs(e, start);
        let index = self
            .required(&attrs, "index", "enum param", start)
            .unwrap_or_default();
        if let Some(en) = self.out.enums.last_mut().and_then(|e| e.entries.last_mut()) {
            en.params.push(Param {
                index,
                label: get(&attrs, "label").filter(|s| !s.is_empty()),
                units: get(&attrs, "units").filter(|s| !s.is_empty()),
                description: String::new(),
            });
        }
        self.collect(Text::Param, loc);
    }

    fn deprecated(&mut self, e: &BytesStart, start: usize) -> Deprecated {
        let attrs = self.attrs(e, start);
        Deprecated {
            since: self
                .required(&attrs, "since", "deprecated", start)
                .unwrap_or_default(),
            replaced_by: self
                .required(&attrs, "replaced_by", "deprecated", start)
                .unwrap_or_default(),
            text: String::new(),
        }
    }

    fn text(&mut self, s: &str) {
        if let Some((_, buf, _, _)) = &mut self.text_target {
            buf.push_str(s);
        }
    }

    /// Starts collecting the text of the element just opened.
    fn collect(&mut self, target: Text, loc: Loc) {
        self.text_target = Some((target, String::new(), loc, self.depth()));
    }

    /// Closes the innermost element; `at` is where its end tag (or the
    /// element, when empty) starts.
    fn end(&mut self, at: usize) {
        let depth = self.depth();
        if depth <= MEANINGFUL_DEPTH {
            self.stack.pop();
        }
        if let Some(opened) = self.opened.pop() {
            if self.opened.is_empty() {
                self.root = Root::Closed { opened, closed: at };
            }
        }
        // Only the element that opened the target closes it; text of nested
        // elements (`<b>` in a description) is kept in its parent's text.
        if !matches!(self.text_target, Some((_, _, _, d)) if d == depth) {
            return;
        }
        let Some((target, text, loc, _)) = self.text_target.take() else {
            return;
        };
        let msg = self.out.messages.last_mut();
        let en = self.out.enums.last_mut();
        let slot: Option<&mut String> = match target {
            Text::MessageDescription => msg.map(|m| &mut m.description),
            Text::MessageDeprecated => msg.and_then(|m| m.deprecated.as_mut()).map(|d| &mut d.text),
            Text::Field => msg
                .and_then(|m| m.fields.last_mut())
                .map(|f| &mut f.description),
            Text::EnumDescription => en.map(|e| &mut e.description),
            Text::EnumDeprecated => en.and_then(|e| e.deprecated.as_mut()).map(|d| &mut d.text),
            Text::EntryDescription => en
                .and_then(|e| e.entries.last_mut())
                .map(|e| &mut e.description),
            Text::EntryDeprecated => en
                .and_then(|e| e.entries.last_mut())
                .and_then(|e| e.deprecated.as_mut())
                .map(|d| &mut d.text),
            Text::Param => en
                .and_then(|e| e.entries.last_mut())
                .and_then(|e| e.params.last_mut())
                .map(|p| &mut p.description),
            Text::Include | Text::Version | Text::Dialect => None,
        };
        if let Some(slot) = slot {
            *slot = text;
            return;
        }
        match target {
            Text::Include => {
                let name = text.trim().to_string();
                if name.is_empty() {
                    self.error(loc.offset, "empty <include>");
                } else {
                    self.out.includes.push(Include { name, loc });
                }
            }
            Text::Version => match text.trim().parse::<u8>() {
                Ok(v) => self.out.version = v,
                Err(_) => self.error(
                    loc.offset,
                    format!(
                        "<version> `{}` is not an integer from 0 to 255",
                        text.trim()
                    ),
                ),
            },
            Text::Dialect => match text.trim().parse::<u32>() {
                Ok(v) => self.out.dialect = Some(v),
                Err(_) => self.error(
                    loc.offset,
                    format!("<dialect> `{}` is not a non-negative integer", text.trim()),
                ),
            },
            // Stored through `slot` above.
            _ => {}
        }
    }
}

/// The byte offset of the first character of `t` that is not XML
/// whitespace, if any: text that is only whitespace may stand outside the
/// root element, and other text is pointed at where it starts. The raw
/// (escaped) bytes count, so the offset is one into the source.
fn non_blank(t: &quick_xml::events::BytesText) -> Option<usize> {
    t.iter()
        .position(|b| !matches!(b, b' ' | b'\t' | b'\r' | b'\n'))
}

fn get(attrs: &[(String, String)], name: &str) -> Option<String> {
    attrs
        .iter()
        .find(|(k, _)| k == name)
        .map(|(_, v)| v.clone())
}

/// Parses a field type: `uint16_t`, `char[5]`, `uint8_t_mavlink_version`,
/// and pymavlink's legacy `array[N]` (an `int8_t` array).
fn parse_type(ty: &str) -> Result<(Primitive, Option<usize>, bool), String> {
    if ty == "uint8_t_mavlink_version" {
        return Ok((Primitive::U8, None, true));
    }
    let (base, len) = match ty.find('[') {
        None => (ty, None),
        Some(i) => {
            let inner = ty[i + 1..]
                .strip_suffix(']')
                .ok_or_else(|| format!("type `{ty}` has an unterminated array length"))?;
            let n: usize = inner.parse().map_err(|_| {
                format!("type `{ty}`: array length `{inner}` is not a positive integer")
            })?;
            if n == 0 || n > 255 {
                return Err(format!("type `{ty}`: array length must be 1 to 255"));
            }
            (&ty[..i], Some(n))
        }
    };
    let prim = if base == "array" && len.is_some() {
        Some(Primitive::I8)
    } else {
        Primitive::from_xml(base)
    };
    let prim = prim.ok_or_else(|| {
        format!("unknown type `{ty}` (expected char, [u]int8_t … [u]int64_t, float, double, optionally with [N], or uint8_t_mavlink_version)")
    })?;
    Ok((prim, len, false))
}

/// A plain integer: decimal or `0x`/`0o`/`0b` prefixed (Python literal rules,
/// underscores allowed).
fn parse_int(text: &str) -> Option<u64> {
    let t = text.trim().replace('_', "");
    let (digits, radix) = match t.get(..2) {
        Some("0x" | "0X") => (&t[2..], 16),
        Some("0o" | "0O") => (&t[2..], 8),
        Some("0b" | "0B") => (&t[2..], 2),
        _ => (t.as_str(), 10),
    };
    if digits.is_empty() || digits.starts_with(['+', '-']) {
        return None;
    }
    u64::from_str_radix(digits, radix).ok()
}

/// An enum entry value: an integer, or the `A**B` and `A<<B` forms used by
/// bitmask enums (pymavlink evaluates them with Python's `eval`).
fn parse_value(text: &str) -> Option<u64> {
    if let Some((a, b)) = text.split_once("**") {
        return parse_int(a)?.checked_pow(u32::try_from(parse_int(b)?).ok()?);
    }
    if let Some((a, b)) = text.split_once("<<") {
        return parse_int(a)?.checked_shl(u32::try_from(parse_int(b)?).ok()?);
    }
    parse_int(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn types_parse_as_pymavlink_reads_them() {
        assert_eq!(parse_type("uint8_t"), Ok((Primitive::U8, None, false)));
        assert_eq!(parse_type("uint8"), Ok((Primitive::U8, None, false)));
        assert_eq!(parse_type("char[5]"), Ok((Primitive::Char, Some(5), false)));
        assert_eq!(parse_type("array[3]"), Ok((Primitive::I8, Some(3), false)));
        assert_eq!(
            parse_type("uint8_t_mavlink_version"),
            Ok((Primitive::U8, None, true))
        );
        assert!(parse_type("float_t").is_err());
        assert!(parse_type("uint128_t").is_err());
        assert!(parse_type("char[0]").is_err());
        assert!(parse_type("char[5").is_err());
    }

    #[test]
    fn values_accept_python_integer_forms() {
        assert_eq!(parse_value("42"), Some(42));
        assert_eq!(parse_value("0x40"), Some(64));
        assert_eq!(parse_value("0b101"), Some(5));
        assert_eq!(parse_value("2**31"), Some(1 << 31));
        assert_eq!(parse_value("1<<3"), Some(8));
        assert_eq!(parse_value("1_000"), Some(1000));
        assert_eq!(parse_value("-1"), None);
        assert_eq!(parse_value("x"), None);
        assert_eq!(parse_value("2**99"), None);
    }
}
