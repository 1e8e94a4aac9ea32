//! Diagnostics in the `FILE:LINE:COL: error: …` form compilers use, so
//! editors and CI logs link straight to the offending XML.

use std::fmt;
use std::path::{Path, PathBuf};

/// How bad a diagnostic is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Severity {
    /// Accepted by pymavlink, but known to break some peer.
    Warning,
    /// The input is rejected; nothing is generated.
    Error,
}

/// A position in a source file: a byte offset, shown as line and column.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Position {
    /// The file as it was named (relative to the including file or the CLI).
    pub file: PathBuf,
    /// 1-based line.
    pub line: usize,
    /// 1-based column, in characters.
    pub column: usize,
}

/// One finding about the input.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Diagnostic {
    /// Error or warning.
    pub severity: Severity,
    /// Where, when the finding has a place in a file.
    pub position: Option<Position>,
    /// What is wrong, in one line.
    pub message: String,
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(p) = &self.position {
            write!(f, "{}:{}:{}: ", p.file.display(), p.line, p.column)?;
        }
        let kind = match self.severity {
            Severity::Warning => "warning",
            Severity::Error => "error",
        };
        write!(f, "{kind}: {}", self.message)
    }
}

/// The text of one XML file with its line table, to turn offsets into lines.
#[derive(Debug, Clone)]
pub struct Source {
    /// Path as given (kept for messages).
    pub path: PathBuf,
    /// File contents.
    pub text: String,
    line_starts: Vec<usize>,
}

impl Source {
    /// Wraps a file's text.
    pub fn new(path: &Path, text: String) -> Self {
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(i, _)| i + 1))
            .collect();
        Source {
            path: path.to_path_buf(),
            text,
            line_starts,
        }
    }

    /// Line and column (both 1-based, column in characters) of a byte offset.
    pub fn position(&self, offset: usize) -> Position {
        let offset = offset.min(self.text.len());
        let line = self.line_starts.partition_point(|&s| s <= offset);
        let start = self.line_starts[line - 1];
        let column = self
            .text
            .get(start..offset)
            .map_or(offset - start, |s| s.chars().count())
            + 1;
        Position {
            file: self.path.clone(),
            line,
            column,
        }
    }
}

/// A place in one of the loaded files.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Loc {
    /// Index of the file in the load order.
    pub file: usize,
    /// Byte offset in that file.
    pub offset: usize,
}

/// Collects diagnostics while a dialect is loaded and checked.
#[derive(Debug, Default)]
pub struct Diagnostics {
    items: Vec<Diagnostic>,
}

impl Diagnostics {
    /// Records an error at `loc` of `sources`.
    pub fn error(&mut self, sources: &[Source], loc: Loc, message: impl Into<String>) {
        self.push(
            Severity::Error,
            Some(sources[loc.file].position(loc.offset)),
            message,
        );
    }

    /// Records a warning at `loc` of `sources`.
    pub fn warning(&mut self, sources: &[Source], loc: Loc, message: impl Into<String>) {
        self.push(
            Severity::Warning,
            Some(sources[loc.file].position(loc.offset)),
            message,
        );
    }

    /// Records a diagnostic.
    pub fn push(
        &mut self,
        severity: Severity,
        position: Option<Position>,
        message: impl Into<String>,
    ) {
        self.items.push(Diagnostic {
            severity,
            position,
            message: message.into(),
        });
    }

    /// True when any error was recorded.
    pub fn has_errors(&self) -> bool {
        self.items.iter().any(|d| d.severity == Severity::Error)
    }

    /// All diagnostics, in the order found.
    pub fn into_vec(self) -> Vec<Diagnostic> {
        self.items
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positions_are_one_based_lines_and_character_columns() {
        let s = Source::new(Path::new("a.xml"), "ab\nçd<x\n".to_string());
        let p = s.position(0);
        assert_eq!((p.line, p.column), (1, 1));
        let lt = s.text.find('<').unwrap();
        let p = s.position(lt);
        assert_eq!((p.line, p.column), (2, 3));
        let p = s.position(s.text.len());
        assert_eq!((p.line, p.column), (3, 1));
    }
}
