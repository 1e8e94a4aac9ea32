//! fc-sim's own log in ArduPilot's DataFlash format (the `.bin` files
//! pymavlink's `DFReader`, `mavlogdump.py` and MAVExplorer read): records
//! of a header (0xA3 0x95), a type, then fields packed little-endian as
//! the type's FMT record says. The log begins with an FMT record for each
//! type (FMT's own first), then a MSG naming the firmware and the
//! records the simulator writes as it flies: MODE at each change, ATT and
//! POS periodically ([`super::remote_log`] sends them).

/// Each record's first two bytes.
const HEAD: [u8; 2] = [0xa3, 0x95];

/// A record type: its id, name, field formats and column names (the
/// format characters are DFReader's: `Q` u64, `c` i16 × 0.01, `C` u16 ×
/// 0.01, `L` i32 × 1e-7, `f` f32, `M` u8 mode, `B` u8, `n` `char[4]`,
/// `N` `char[16]`, `Z` `char[64]`).
#[derive(Debug, Clone, Copy)]
pub struct Type {
    pub id: u8,
    pub name: &'static str,
    pub format: &'static str,
    pub columns: &'static str,
}

/// FMT: the record that describes the others.
pub const FMT: Type = Type {
    id: 128,
    name: "FMT",
    format: "BBnNZ",
    columns: "Type,Length,Name,Format,Columns",
};

/// MSG: a text (the firmware's name).
pub const MSG: Type = Type {
    id: 130,
    name: "MSG",
    format: "QZ",
    columns: "TimeUS,Message",
};

/// MODE: a mode change (ArduPlane's number, twice, and the reason).
pub const MODE: Type = Type {
    id: 131,
    name: "MODE",
    format: "QMBB",
    columns: "TimeUS,Mode,ModeNum,Rsn",
};

/// ATT: the attitude (degrees, × 100 on the wire).
pub const ATT: Type = Type {
    id: 132,
    name: "ATT",
    format: "QccC",
    columns: "TimeUS,Roll,Pitch,Yaw",
};

/// POS: the position (degrees × 1e7, metres).
pub const POS: Type = Type {
    id: 133,
    name: "POS",
    format: "QLLff",
    columns: "TimeUS,Lat,Lng,Alt,RelHomeAlt",
};

/// Every type the simulator writes, FMT first.
pub const TYPES: [Type; 5] = [FMT, MSG, MODE, ATT, POS];

impl Type {
    /// A record's length, its header and type included.
    pub fn len(&self) -> usize {
        3 + self.format.chars().map(field_len).sum::<usize>()
    }
}

/// The bytes of a field of format `c`.
fn field_len(c: char) -> usize {
    match c {
        'b' | 'B' | 'M' => 1,
        'h' | 'H' | 'c' | 'C' => 2,
        'i' | 'I' | 'e' | 'E' | 'L' | 'f' | 'n' => 4,
        'q' | 'Q' | 'd' => 8,
        'N' => 16,
        'Z' | 'a' => 64,
        _ => 0,
    }
}

/// A record being built.
struct Record(Vec<u8>);

impl Record {
    fn new(t: &Type) -> Record {
        let mut bytes = Vec::with_capacity(t.len());
        bytes.extend(HEAD);
        bytes.push(t.id);
        Record(bytes)
    }

    fn put(mut self, bytes: &[u8]) -> Record {
        self.0.extend_from_slice(bytes);
        self
    }

    /// Text in a field of `n` bytes, zero-padded (cut if longer).
    fn text(self, s: &str, n: usize) -> Record {
        let mut field = vec![0; n];
        let len = s.len().min(n);
        field[..len].copy_from_slice(&s.as_bytes()[..len]);
        self.put(&field)
    }
}

/// The FMT record of `t`.
pub fn fmt(t: &Type) -> Vec<u8> {
    Record::new(&FMT)
        .put(&[t.id, t.len() as u8])
        .text(t.name, 4)
        .text(t.format, 16)
        .text(t.columns, 64)
        .0
}

/// What a log begins with: every type's FMT, then MSG `firmware`.
pub fn start(time_us: u64, firmware: &str) -> Vec<u8> {
    let mut bytes: Vec<u8> = TYPES.iter().flat_map(fmt).collect();
    bytes.extend(
        Record::new(&MSG)
            .put(&time_us.to_le_bytes())
            .text(firmware, 64)
            .0,
    );
    bytes
}

/// A MODE record: ArduPlane's mode number, and why (1: the radio, 2:
/// the GCS, 3: the radio failsafe, ArduPilot's ModeReason's first ones).
pub fn mode(time_us: u64, number: u8, reason: u8) -> Vec<u8> {
    Record::new(&MODE)
        .put(&time_us.to_le_bytes())
        .put(&[number, number, reason])
        .0
}

/// An ATT record: roll, pitch and yaw in radians.
pub fn att(time_us: u64, roll: f64, pitch: f64, yaw: f64) -> Vec<u8> {
    let centi = |rad: f64| (rad.to_degrees() * 100.0).round();
    let signed = |rad: f64| (centi(rad).clamp(-32768.0, 32767.0) as i16).to_le_bytes();
    let yaw = (centi(yaw).rem_euclid(36_000.0) as u16).to_le_bytes();
    Record::new(&ATT)
        .put(&time_us.to_le_bytes())
        .put(&signed(roll))
        .put(&signed(pitch))
        .put(&yaw)
        .0
}

/// A POS record: degrees, metres above sea level and above home.
pub fn pos(time_us: u64, lat: f64, lon: f64, alt: f64, height: f64) -> Vec<u8> {
    let e7 = |deg: f64| ((deg * 1e7).round() as i32).to_le_bytes();
    Record::new(&POS)
        .put(&time_us.to_le_bytes())
        .put(&e7(lat))
        .put(&e7(lon))
        .put(&(alt as f32).to_le_bytes())
        .put(&(height as f32).to_le_bytes())
        .0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_are_as_long_as_their_formats_say() {
        assert_eq!(FMT.len(), 89, "ArduPilot's FMT");
        assert_eq!(fmt(&ATT).len(), FMT.len());
        let start = start(1, "ArduPlane");
        assert_eq!(start.len(), TYPES.len() * FMT.len() + MSG.len());
        assert_eq!(mode(1, 5, 1).len(), MODE.len());
        let att = att(7, 0.1, -0.2, -0.5);
        assert_eq!(att.len(), ATT.len());
        assert_eq!(&att[..3], &[0xa3, 0x95, ATT.id]);
        assert_eq!(i16::from_le_bytes([att[11], att[12]]), 573);
        assert_eq!(u16::from_le_bytes([att[15], att[16]]), 36_000 - 2865);
        assert_eq!(pos(1, -35.3, 149.1, 600.0, 100.0).len(), POS.len());
        // FMT of FMT: type 128, 89 bytes, its name.
        assert_eq!(&start[3..8], &[128, 89, b'F', b'M', b'T']);
    }
}
