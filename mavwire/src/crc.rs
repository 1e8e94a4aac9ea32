//! CRC-16/MCRF4XX, the MAVLink frame checksum ("X.25" in MAVLink sources).
//!
//! The byte-at-a-time update of the MAVLink specification: no table, four
//! shifts and xors per byte. crc-any's CRC-16/MCRF4XX is the test oracle.

/// A running MAVLink checksum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Crc(u16);

impl Crc {
    /// A checksum with MAVLink's initial value.
    #[inline]
    pub const fn new() -> Self {
        Crc(0xFFFF)
    }

    /// Adds bytes.
    #[inline]
    pub fn update(&mut self, bytes: &[u8]) {
        let mut crc = self.0;
        for &b in bytes {
            let tmp = b ^ (crc as u8);
            let tmp = tmp ^ (tmp << 4);
            crc = (crc >> 8) ^ ((tmp as u16) << 8) ^ ((tmp as u16) << 3) ^ ((tmp as u16) >> 4);
        }
        self.0 = crc;
    }

    /// The checksum so far.
    #[inline]
    pub const fn get(&self) -> u16 {
        self.0
    }
}

impl Default for Crc {
    fn default() -> Self {
        Self::new()
    }
}

/// The checksum of a frame: `bytes` from after the start byte to the end of
/// the payload, then the message's CRC_EXTRA seed.
#[inline]
pub fn frame_crc(bytes: &[u8], crc_extra: u8) -> u16 {
    let mut crc = Crc::new();
    crc.update(bytes);
    crc.update(&[crc_extra]);
    crc.get()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn oracle(bytes: &[u8]) -> u16 {
        let mut c = crc_any::CRCu16::crc16mcrf4cc();
        c.digest(bytes);
        c.get_crc()
    }

    #[test]
    fn check_value_of_crc16_mcrf4xx() {
        // The catalogue check value for CRC-16/MCRF4XX over "123456789".
        let mut c = Crc::new();
        c.update(b"123456789");
        assert_eq!(c.get(), 0x6F91);
    }

    #[test]
    fn equals_crc_any_on_every_length_and_pattern() {
        let mut data = [0u8; 300];
        let mut x: u32 = 0x1234_5678;
        for b in data.iter_mut() {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            *b = x as u8;
        }
        for len in 0..data.len() {
            let mut c = Crc::new();
            c.update(&data[..len]);
            assert_eq!(c.get(), oracle(&data[..len]), "length {len}");
        }
    }
}
