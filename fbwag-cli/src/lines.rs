//! Input read line by line, each line on its own: a line that is not UTF-8
//! or is too long is reported as such and the next line is read, where
//! `BufRead::lines` would end the whole input at the first bad byte (and
//! buffer a line of any length).

use std::io::{self, BufRead, Read};

/// Longest line kept: 1 MiB. The longest line `fbwag decode` writes (a
/// 255-byte payload of `double`s or char arrays as numbers) is under 8 KiB.
pub const MAX_LINE: usize = 1 << 20;

/// One line of input, without its line ending.
#[derive(Debug, PartialEq, Eq)]
pub enum Line {
    /// The line's text.
    Text(String),
    /// The line is not UTF-8 from this byte on.
    NotUtf8 {
        /// Length of the valid prefix.
        valid_up_to: usize,
    },
    /// The line holds more than [`MAX_LINE`] bytes (the rest was skipped).
    TooLong,
}

/// Numbered lines of a reader.
pub struct Lines<R> {
    reader: R,
    number: u64,
}

impl<R: BufRead> Lines<R> {
    /// Lines of `reader`, numbered from 1.
    pub fn new(reader: R) -> Self {
        Lines { reader, number: 0 }
    }

    /// The next line and its number; `None` at the end of the input.
    pub fn next_line(&mut self) -> io::Result<Option<(u64, Line)>> {
        let mut buf = Vec::new();
        let limit = MAX_LINE as u64 + 1;
        if (&mut self.reader).take(limit).read_until(b'\n', &mut buf)? == 0 {
            return Ok(None);
        }
        self.number += 1;
        if buf.last() == Some(&b'\n') {
            buf.pop();
            if buf.last() == Some(&b'\r') {
                buf.pop();
            }
        } else if buf.len() > MAX_LINE {
            self.skip_line()?;
            return Ok(Some((self.number, Line::TooLong)));
        }
        let line = String::from_utf8(buf).map_or_else(
            |e| Line::NotUtf8 {
                valid_up_to: e.utf8_error().valid_up_to(),
            },
            Line::Text,
        );
        Ok(Some((self.number, line)))
    }

    /// Discards input up to and including the next newline (or to the end).
    fn skip_line(&mut self) -> io::Result<()> {
        loop {
            let buf = match self.reader.fill_buf() {
                Ok(b) => b,
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            };
            if buf.is_empty() {
                return Ok(());
            }
            match buf.iter().position(|&b| b == b'\n') {
                Some(i) => {
                    self.reader.consume(i + 1);
                    return Ok(());
                }
                None => {
                    let n = buf.len();
                    self.reader.consume(n);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all(input: &[u8]) -> Vec<(u64, Line)> {
        let mut lines = Lines::new(input);
        let mut out = Vec::new();
        while let Some(l) = lines.next_line().unwrap() {
            out.push(l);
        }
        out
    }

    #[test]
    fn a_bad_line_is_reported_and_the_next_one_read() {
        let got = all(b"a\r\n\xff\xfe\nb");
        assert_eq!(
            got,
            vec![
                (1, Line::Text("a".into())),
                (2, Line::NotUtf8 { valid_up_to: 0 }),
                (3, Line::Text("b".into())),
            ]
        );
    }

    #[test]
    fn a_line_over_the_limit_is_skipped_whole() {
        let mut input = vec![b'x'; MAX_LINE + 10];
        input.extend_from_slice(b"\nok\n");
        let got = all(&input);
        assert_eq!(got, vec![(1, Line::TooLong), (2, Line::Text("ok".into()))]);
        let mut input = vec![b'x'; MAX_LINE];
        input.push(b'\n');
        assert!(matches!(all(&input)[..], [(1, Line::Text(ref t))] if t.len() == MAX_LINE));
    }
}
