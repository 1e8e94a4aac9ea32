//! mavlink-router's configuration files, read as mavlink-router reads
//! them: `[General]`, `[UartEndpoint NAME]`, `[UdpEndpoint NAME]` and
//! `[TcpEndpoint NAME]` sections of `Key = Value` lines; section kinds,
//! names and keys compared without regard to case; `#` or `;` first on a
//! line for a comment (none after a value); surrounding blanks ignored.
//! Every file of a configuration adds to one document: a section met
//! again (in the same file or a later one) takes more keys, and a key met
//! again replaces the earlier value, as mavlink-router's `config.d`
//! overrides its `main.conf`.
//!
//! Stricter than mavlink-router where it would go on silently: a line
//! before any section, a section of an unknown kind, a `[General]` with a
//! name, an endpoint without one, a header with stray characters and a
//! line without `=` or without a value are refused, at the file's line and
//! column; so is a file that is not UTF-8 (at its first bad byte). Which
//! keys a section takes is the mapping's (`super::mavlink_router`).

use super::{ConfigError, Location};
use std::path::Path;

/// The kinds of section.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    General,
    Uart,
    Udp,
    Tcp,
}

impl Kind {
    /// The kind's word, as mavlink-router's documentation spells it.
    pub fn word(self) -> &'static str {
        match self {
            Kind::General => "General",
            Kind::Uart => "UartEndpoint",
            Kind::Udp => "UdpEndpoint",
            Kind::Tcp => "TcpEndpoint",
        }
    }

    fn parse(word: &str) -> Option<Kind> {
        [Kind::General, Kind::Uart, Kind::Udp, Kind::Tcp]
            .into_iter()
            .find(|k| k.word().eq_ignore_ascii_case(word))
    }
}

/// `Key = Value`, as the last file to give it wrote it.
#[derive(Debug, Clone)]
pub struct Entry {
    /// The key as written.
    pub key: String,
    /// Where the key starts.
    pub at: Location,
    pub value: String,
    /// Where the value starts.
    pub value_at: Location,
}

/// A section, every file's keys of it together.
#[derive(Debug, Clone)]
pub struct Section {
    pub kind: Kind,
    /// The endpoint's name, as first written (`None` for `[General]`).
    pub name: Option<String>,
    /// Where it was first opened.
    pub at: Location,
    /// Its keys in the order first given.
    pub entries: Vec<Entry>,
}

impl Section {
    /// The value of `key` (any case), if given.
    pub fn get(&self, key: &str) -> Option<&Entry> {
        self.entries
            .iter()
            .find(|e| e.key.eq_ignore_ascii_case(key))
    }

    /// `[UdpEndpoint gcs]`, for messages.
    pub fn title(&self) -> String {
        match &self.name {
            Some(name) => format!("[{} {name}]", self.kind.word()),
            None => format!("[{}]", self.kind.word()),
        }
    }
}

/// Every file's sections, in the order first opened.
#[derive(Debug, Default)]
pub struct Document {
    pub sections: Vec<Section>,
    /// The files read, in order.
    pub files: Vec<std::path::PathBuf>,
}

impl Document {
    /// Adds the file `path`, whose text is `text`, to the document.
    pub fn read(&mut self, path: &Path, text: &str) -> Result<(), ConfigError> {
        self.files.push(path.to_owned());
        let mut current: Option<usize> = None;
        // A byte-order mark (an editor's on Windows) is no content.
        let mut offset = if text.starts_with('\u{feff}') { 3 } else { 0 };
        for line in text[offset..].split_inclusive('\n') {
            let start = offset;
            offset += line.len();
            let trimmed = line.trim_start();
            let first = start + (line.len() - trimmed.len());
            let content = trimmed.trim_end();
            let at = |o: usize| Location::at(path, text, o);
            if content.is_empty() || content.starts_with('#') || content.starts_with(';') {
                continue;
            }
            if content.starts_with('[') {
                current = Some(self.open(path, text, first, content)?);
                continue;
            }
            let Some(index) = current else {
                return Err(syntax(
                    at(first),
                    "a key before any section: begin with [General], [UartEndpoint NAME], [UdpEndpoint NAME] or [TcpEndpoint NAME]",
                ));
            };
            let entry = entry(content, first, &at)?;
            let entries = &mut self.sections[index].entries;
            match entries
                .iter_mut()
                .find(|e| e.key.eq_ignore_ascii_case(&entry.key))
            {
                Some(earlier) => *earlier = entry,
                None => entries.push(entry),
            }
        }
        Ok(())
    }

    /// Opens the section of header `content` (at byte `first` of `text`):
    /// its index, a new one or the one of the same kind and name.
    fn open(
        &mut self,
        path: &Path,
        text: &str,
        first: usize,
        content: &str,
    ) -> Result<usize, ConfigError> {
        let at = |o: usize| Location::at(path, text, o);
        let Some(close) = content.find(']') else {
            return Err(syntax(at(first), "a section header without `]`"));
        };
        if close + 1 != content.len() {
            return Err(syntax(
                at(first + close + 1),
                "characters after the section header's `]`",
            ));
        }
        let inner = &content[1..close];
        if inner.starts_with(char::is_whitespace) || inner.ends_with(char::is_whitespace) {
            return Err(syntax(
                at(first),
                "blanks inside the brackets: write [UdpEndpoint NAME]",
            ));
        }
        let (word, name) = match inner.split_once(' ') {
            Some((word, name)) => (word, Some(name)),
            None => (inner, None),
        };
        if inner.chars().any(|c| c.is_whitespace() && c != ' ')
            || name.is_some_and(|n| n.contains(' '))
        {
            return Err(syntax(
                at(first),
                "a section is a kind and a name without blanks, one space between: [UdpEndpoint NAME]",
            ));
        }
        let kind = Kind::parse(word).ok_or_else(|| {
            syntax(
                at(first + 1),
                &format!(
                    "unknown section `{word}`: the sections are [General], [UartEndpoint NAME], [UdpEndpoint NAME] and [TcpEndpoint NAME]"
                ),
            )
        })?;
        match (kind, name) {
            (Kind::General, Some(_)) => {
                return Err(syntax(at(first), "[General] takes no name"));
            }
            (Kind::General, None) => {}
            (_, None) => {
                return Err(syntax(
                    at(first),
                    &format!("[{} NAME]: an endpoint needs a name", kind.word()),
                ));
            }
            (_, Some(_)) => {}
        }
        let same = |s: &Section| {
            s.kind == kind
                && match (&s.name, name) {
                    (Some(a), Some(b)) => a.eq_ignore_ascii_case(b),
                    (None, None) => true,
                    _ => false,
                }
        };
        if let Some(index) = self.sections.iter().position(same) {
            return Ok(index);
        }
        self.sections.push(Section {
            kind,
            name: name.map(str::to_string),
            at: at(first),
            entries: Vec::new(),
        });
        Ok(self.sections.len() - 1)
    }
}

/// `Key = Value` of a line whose content (trimmed) starts at byte `first`.
fn entry(
    content: &str,
    first: usize,
    at: &impl Fn(usize) -> Location,
) -> Result<Entry, ConfigError> {
    let Some(equals) = content.find('=') else {
        return Err(syntax(at(first), "expected `Key = Value`: no `=`"));
    };
    let key = content[..equals].trim_end();
    if key.is_empty() {
        return Err(syntax(at(first), "a key is missing before `=`"));
    }
    let after = &content[equals + 1..];
    let value = after.trim_start();
    if value.is_empty() {
        return Err(syntax(
            at(first + equals),
            &format!("`{key}` has no value after `=`"),
        ));
    }
    let value_start = first + equals + 1 + (after.len() - value.len());
    Ok(Entry {
        key: key.to_string(),
        at: at(first),
        value: value.to_string(),
        value_at: at(value_start),
    })
}

fn syntax(at: Location, message: &str) -> ConfigError {
    ConfigError::Syntax {
        at,
        message: message.to_string(),
    }
}

/// Whether `text` reads as mavlink-router's format: its first line that
/// is neither blank nor a comment opens a section of one of its kinds.
pub fn looks_like(text: &str) -> bool {
    text.trim_start_matches('\u{feff}')
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && !l.starts_with('#') && !l.starts_with(';'))
        .and_then(|l| l.strip_prefix('['))
        .map(|l| l.split([' ', ']']).next().unwrap_or_default())
        .is_some_and(|word| Kind::parse(word).is_some())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read(text: &str) -> Result<Document, ConfigError> {
        let mut doc = Document::default();
        doc.read(Path::new("main.conf"), text)?;
        Ok(doc)
    }

    fn refused(text: &str) -> (usize, usize, String) {
        match read(text).unwrap_err() {
            ConfigError::Syntax { at, message } => (at.line, at.column, message),
            other => panic!("{other}"),
        }
    }

    #[test]
    fn sections_merge_and_a_later_key_wins_whatever_its_case() {
        let doc = read(
            "# comment\n; another\n[General]\nTcpServerPort=5760\n\n\
             [UdpEndpoint gcs]\r\n  Mode = Server \r\nPort=1\n[udpendpoint GCS]\nport = 2\n\
             [general]\nREPORTSTATS = true",
        )
        .unwrap();
        assert_eq!(doc.sections.len(), 2);
        let general = &doc.sections[0];
        assert_eq!(general.entries.len(), 2, "{general:?}");
        let gcs = &doc.sections[1];
        assert_eq!(gcs.name.as_deref(), Some("gcs"));
        assert_eq!(gcs.get("mode").unwrap().value, "Server");
        let port = gcs.get("PORT").unwrap();
        assert_eq!(
            (port.value.as_str(), port.at.line, port.at.column),
            ("2", 10, 1)
        );
        assert_eq!(port.value_at.column, 8);
        assert_eq!(gcs.get("Mode").unwrap().value_at.column, 10);
    }

    #[test]
    fn malformed_lines_are_refused_at_their_line_and_column() {
        let cases: &[(&str, usize, usize, &str)] = &[
            ("Port = 1\n", 1, 1, "before any section"),
            ("[General]\n  Port\n", 2, 3, "no `=`"),
            ("[General]\n = 3\n", 2, 2, "key is missing"),
            ("[General]\nLog =\n", 2, 5, "no value"),
            ("[General\n", 1, 1, "without `]`"),
            ("[General] x\n", 1, 10, "after the section"),
            ("[ General]\n", 1, 1, "blanks inside"),
            ("[Foo bar]\n", 1, 2, "unknown section `Foo`"),
            ("[General x]\n", 1, 1, "takes no name"),
            ("[UdpEndpoint]\n", 1, 1, "needs a name"),
            ("[UdpEndpoint a b]\n", 1, 1, "without blanks"),
            ("[UdpEndpoint\ta]\n", 1, 1, "without blanks"),
            (
                "\n\n   [TcpEndpoint a]\nx=1\n[[General]]\n",
                5,
                11,
                "after the section",
            ),
        ];
        for (text, line, column, says) in cases {
            let (l, c, message) = refused(text);
            assert_eq!((l, c), (*line, *column), "{text:?}: {message}");
            assert!(message.contains(says), "{text:?}: {message}");
        }
    }

    #[test]
    fn the_format_is_told_by_its_first_section() {
        assert!(looks_like("# x\n\n[General]\nA=1\n"));
        assert!(looks_like("\u{feff}[General]\r\nA=1\r\n"));
        let doc = read("\u{feff}[General]\r\nA = 1\r\n").unwrap();
        assert_eq!(doc.sections[0].get("a").unwrap().value, "1");
        assert!(looks_like("[uartendpoint fc]\n"));
        assert!(looks_like("[TcpEndpoint]"));
        assert!(!looks_like("links = [\"udpin:0.0.0.0:1\"]\n"));
        assert!(!looks_like("[table]\nx = 1\n"));
        assert!(!looks_like(""));
    }
}
