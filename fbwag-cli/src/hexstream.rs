//! Hex text to bytes in chunks (for `fbwag decode --hex`), so input of any
//! size is decoded in bounded memory; a digit pair may span two chunks.

/// Hex text that is not whole bytes of hex digits.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum HexError {
    /// A byte that is neither a hex digit nor whitespace, after `digit`
    /// digits.
    #[error("byte 0x{byte:02x} is not a hex digit (digit {digit})")]
    NotHex { byte: u8, digit: u64 },
    /// The text ended half way through a byte.
    #[error("odd number of hex digits ({0})")]
    OddDigits(u64),
}

/// Decodes hex digits, ignoring ASCII whitespace.
#[derive(Default)]
pub struct HexDecoder {
    /// The high nibble of a pair whose low digit is still to come.
    pending: Option<u8>,
    /// Digits seen so far, for error positions.
    digits: u64,
}

impl HexDecoder {
    /// Appends the bytes of `text`'s digit pairs to `out`.
    pub fn push(&mut self, text: &[u8], out: &mut Vec<u8>) -> Result<(), HexError> {
        for &c in text {
            if c.is_ascii_whitespace() {
                continue;
            }
            let v = (c as char).to_digit(16).ok_or(HexError::NotHex {
                byte: c,
                digit: self.digits,
            })? as u8;
            self.digits += 1;
            match self.pending.take() {
                Some(high) => out.push(high << 4 | v),
                None => self.pending = Some(v),
            }
        }
        Ok(())
    }

    /// Checks the text ended on a whole byte.
    pub fn finish(&self) -> Result<(), HexError> {
        match self.pending {
            Some(_) => Err(HexError::OddDigits(self.digits)),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pairs_may_span_chunks_and_whitespace_is_ignored() {
        let mut d = HexDecoder::default();
        let mut out = Vec::new();
        d.push(b"fd 0", &mut out).unwrap();
        d.push(b"1\nA", &mut out).unwrap();
        assert!(d.finish().is_err());
        d.push(b"b", &mut out).unwrap();
        d.finish().unwrap();
        assert_eq!(out, [0xfd, 0x01, 0xab]);
        assert!(d.push(b"zz", &mut out).is_err());
        assert!(HexDecoder::default()
            .push("é".as_bytes(), &mut out)
            .is_err());
    }
}
