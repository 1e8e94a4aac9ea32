//! Field values over a message's field table (`META.fields`): seeded random
//! payloads and the value text the three implementations exchange.
//!
//! Value text, fields in wire order: `name=value;name=value;…`, integers in
//! decimal (a scalar `char` as its byte), `float`/`double` as the hex of
//! their IEEE bits (8 / 16 digits), `char[N]` as the hex of all N bytes,
//! other arrays as comma-separated elements. The Python (`wire.py`) and C
//! (`harness.c`) sides read and write exactly this.

use mavframe::field::{read, Scalar};
use mavframe::{FieldMeta, FieldType, MessageMeta};
use std::fmt::Write as _;

/// SplitMix64: tiny, seedable, the same sequence everywhere.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (n > 0).
    pub fn below(&mut self, n: u64) -> u64 {
        self.next_u64() % n
    }

    /// Uniform in `lo..=hi`.
    pub fn range(&mut self, lo: usize, hi: usize) -> usize {
        lo + self.below((hi - lo + 1) as u64) as usize
    }

    /// True with probability `num/den`.
    pub fn chance(&mut self, num: u64, den: u64) -> bool {
        self.below(den) < num
    }

    pub fn byte(&mut self) -> u8 {
        self.next_u64() as u8
    }

    /// A header byte: uniform, with the extremes 0 and 255 more often.
    pub fn header_byte(&mut self) -> u8 {
        match self.below(8) {
            0 => 0,
            1 => 255,
            _ => self.byte(),
        }
    }
}

/// How a payload is filled.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fill {
    /// Every byte zero: MAVLink 2 sends one payload byte.
    Zero,
    /// Every byte 0xFF: all-ones integers, quiet NaNs with full payloads.
    Ones,
    /// Every field at its maximum (full-length printable strings).
    Max,
    /// Every field at its minimum (full-length strings of bytes >= 0x80).
    Min,
    /// Random values over full ranges, extremes and non-finite floats
    /// favoured; trailing fields or extensions sometimes zero.
    Random,
}

/// The fill of variant `k` of a message: the four fixed fills, then random.
pub fn fill_of(k: usize) -> Fill {
    match k {
        0 => Fill::Zero,
        1 => Fill::Ones,
        2 => Fill::Max,
        3 => Fill::Min,
        _ => Fill::Random,
    }
}

/// Options for random fills.
#[derive(Debug, Clone, Copy, Default)]
pub struct Opts {
    /// float32 signalling NaNs allowed (pymavlink quiets them: documented
    /// difference, so the main corpus leaves them out).
    pub f32_snan: bool,
    /// Sprinkle start bytes (0xFD, 0xFE) over the payload: false starts.
    pub start_bytes: bool,
    /// `char[N]` values may hold bytes after their first NUL: pymavlink's
    /// decoded strings stop there, so the value corpus leaves them out; the
    /// byte-exact case is tests/fixed_bugs.rs (B1).
    pub bytes_after_nul: bool,
}

fn elem_count(f: &FieldMeta) -> usize {
    (f.array_len as usize).max(1)
}

fn is_signed(ty: FieldType) -> bool {
    matches!(
        ty,
        FieldType::I8 | FieldType::I16 | FieldType::I32 | FieldType::I64
    )
}

/// Little-endian bytes of one integer element of `size` bytes.
fn int_elem(rng: &mut Rng, size: usize, signed: bool) -> u64 {
    let bits = size as u32 * 8;
    let mask = if bits == 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    };
    let max = if signed { mask >> 1 } else { mask };
    let min = if signed { !(mask >> 1) & mask } else { 0 };
    match rng.below(20) {
        0..=7 => rng.next_u64() & mask,
        8 | 9 => 0,
        10 => 1,
        11 | 12 => mask, // -1 / all ones
        13 | 14 => max,
        15 | 16 => min,
        17 => max - 1,
        _ => rng.below(100) & mask, // small
    }
}

fn f32_elem(rng: &mut Rng, snan: bool) -> u32 {
    let sign = (rng.below(2) as u32) << 31;
    match rng.below(24) {
        0..=7 => {
            // Random finite: any exponent but the all-ones one.
            let e = rng.below(255) as u32;
            sign | e << 23 | (rng.next_u64() as u32 & 0x7F_FFFF)
        }
        8 => 0,
        9 => 0x8000_0000, // -0.0
        10 => 1.0f32.to_bits(),
        11 => (-1.5f32).to_bits(),
        12 => 0x7FC0_0000,                                              // NaN
        13 => 0xFFC0_0000,                                              // -NaN
        14 => sign | 0x7FC0_0000 | (rng.next_u64() as u32 & 0x3F_FFFF), // quiet NaN, payload
        15 => f32::INFINITY.to_bits(),
        16 => f32::NEG_INFINITY.to_bits(),
        17 => f32::MAX.to_bits(),
        18 => f32::MIN.to_bits(),
        19 => f32::MIN_POSITIVE.to_bits(),
        20 => sign | 1,                                   // smallest subnormal
        21 => sign | (rng.next_u64() as u32 & 0x7F_FFFF), // subnormal
        22 if snan => sign | 0x7F80_0000 | (1 + rng.below(0x3F_FFFF) as u32), // signalling NaN
        _ => (rng.below(2_000_001) as f32 / 1000.0 - 1000.0).to_bits(),
    }
}

fn f64_elem(rng: &mut Rng) -> u64 {
    let sign = rng.below(2) << 63;
    match rng.below(24) {
        0..=7 => sign | rng.below(2047) << 52 | (rng.next_u64() & 0xF_FFFF_FFFF_FFFF),
        8 => 0,
        9 => 1 << 63,
        10 => 1.0f64.to_bits(),
        11 => (-2.5f64).to_bits(),
        12 => 0x7FF8_0000_0000_0000,
        13 => sign | 0x7FF8_0000_0000_0000 | (rng.next_u64() & 0x7_FFFF_FFFF_FFFF),
        // Signalling NaN: doubles pass through Python unchanged.
        14 => sign | 0x7FF0_0000_0000_0000 | (1 + rng.below(0x7_FFFF_FFFF_FFFE)),
        15 => f64::INFINITY.to_bits(),
        16 => f64::NEG_INFINITY.to_bits(),
        17 => f64::MAX.to_bits(),
        18 => f64::MIN.to_bits(),
        19 => f64::MIN_POSITIVE.to_bits(),
        20 => sign | 1,
        21 => (f32::MAX as f64 * 4.0).to_bits(), // beyond float32
        _ => (rng.below(2_000_001) as f64 / 1000.0 - 1000.0).to_bits(),
    }
}

fn put(p: &mut [u8], at: usize, bytes: &[u8]) {
    p[at..at + bytes.len()].copy_from_slice(bytes);
}

fn fill_chars(rng: &mut Rng, out: &mut [u8], after_nul: bool) {
    let n = out.len();
    out.fill(0);
    match rng.below(7) {
        0 => {} // empty
        1 | 2 => {
            // short printable string, NUL padded
            let len = rng.range(1, n.max(1));
            for b in &mut out[..len] {
                *b = 0x20 + rng.below(95) as u8;
            }
        }
        3 | 4 => {
            // full length, no NUL
            for b in out.iter_mut() {
                *b = 0x20 + rng.below(95) as u8;
            }
        }
        5 => {
            // full length, any non-NUL byte (>= 0x80 included)
            for b in out.iter_mut() {
                *b = 1 + rng.below(255) as u8;
            }
        }
        _ => {
            // any bytes: high bytes, NULs (what follows the first NUL is
            // zeroed unless `after_nul`)
            for b in out.iter_mut() {
                *b = rng.byte();
            }
            if !after_nul {
                if let Some(p) = out.iter().position(|&b| b == 0) {
                    out[p..].fill(0);
                }
            }
        }
    }
}

fn fill_field(rng: &mut Rng, p: &mut [u8], f: &FieldMeta, fill: Fill, opts: Opts) {
    let at = f.offset as usize;
    let size = f.ty.size();
    let n = elem_count(f);
    let signed = is_signed(f.ty);
    if f.ty == FieldType::Char && f.array_len > 0 {
        let dst = &mut p[at..at + n];
        match fill {
            Fill::Max => dst.iter_mut().for_each(|b| *b = b'~'),
            Fill::Min => dst
                .iter_mut()
                .enumerate()
                .for_each(|(i, b)| *b = 0x80 + (i % 128) as u8),
            _ => fill_chars(rng, dst, opts.bytes_after_nul),
        }
        return;
    }
    for k in 0..n {
        let e = at + k * size;
        match (f.ty, fill) {
            (FieldType::F32, Fill::Max) => put(p, e, &f32::MAX.to_le_bytes()),
            (FieldType::F32, Fill::Min) => put(p, e, &f32::NEG_INFINITY.to_le_bytes()),
            (FieldType::F64, Fill::Max) => put(p, e, &f64::INFINITY.to_le_bytes()),
            (FieldType::F64, Fill::Min) => put(p, e, &f64::MIN.to_le_bytes()),
            (FieldType::F32, _) => put(p, e, &f32_elem(rng, opts.f32_snan).to_le_bytes()),
            (FieldType::F64, _) => put(p, e, &f64_elem(rng).to_le_bytes()),
            (_, Fill::Max) => {
                let v: u64 = if signed {
                    u64::MAX >> (65 - size * 8)
                } else {
                    u64::MAX
                };
                put(p, e, &v.to_le_bytes()[..size]);
            }
            (_, Fill::Min) => {
                let v: u64 = if signed { 1u64 << (size * 8 - 1) } else { 0 };
                put(p, e, &v.to_le_bytes()[..size]);
            }
            _ => {
                let v = int_elem(rng, size, signed);
                put(p, e, &v.to_le_bytes()[..size]);
            }
        }
    }
}

/// A payload of `meta.max_len` bytes for `fill`.
pub fn random_payload(meta: &MessageMeta, rng: &mut Rng, fill: Fill, opts: Opts) -> Vec<u8> {
    let mut p = vec![0u8; meta.max_len as usize];
    match fill {
        Fill::Zero => return p,
        Fill::Ones => {
            p.fill(0xFF);
            return p;
        }
        _ => {}
    }
    for f in meta.fields {
        fill_field(rng, &mut p, f, fill, opts);
    }
    if fill == Fill::Random {
        // Trailing zeros: MAVLink 2 truncation of more than the last byte.
        if rng.chance(1, 3) {
            let keep = rng.range(0, meta.fields.len() - 1);
            for f in &meta.fields[keep..] {
                let at = f.offset as usize;
                p[at..at + f.wire_len()].fill(0);
            }
        }
        // Extensions unset.
        if rng.chance(1, 4) {
            zero_extensions(meta, &mut p);
        }
        if opts.start_bytes {
            for _ in 0..rng.range(1, 4) {
                let at = rng.range(0, p.len() - 1);
                let in_chars = meta.fields.iter().any(|f| {
                    f.ty == FieldType::Char
                        && (f.offset as usize..f.offset as usize + f.wire_len()).contains(&at)
                });
                if !in_chars || opts.bytes_after_nul {
                    p[at] = if rng.chance(1, 2) { 0xFD } else { 0xFE };
                }
            }
        }
    }
    p
}

/// Zeroes the extension fields (what a MAVLink 1 frame of the C library
/// carries: base fields only).
pub fn zero_extensions(meta: &MessageMeta, payload: &mut [u8]) {
    for f in meta.fields.iter().filter(|f| f.extension) {
        let at = f.offset as usize;
        let end = (at + f.wire_len()).min(payload.len());
        if at < end {
            payload[at..end].fill(0);
        }
    }
}

fn elem_text(out: &mut String, payload: &[u8], ty: FieldType, at: usize) {
    let _ = match ty {
        FieldType::Char | FieldType::U8 => write!(out, "{}", read::<u8>(payload, at)),
        FieldType::I8 => write!(out, "{}", read::<i8>(payload, at)),
        FieldType::U16 => write!(out, "{}", read::<u16>(payload, at)),
        FieldType::I16 => write!(out, "{}", read::<i16>(payload, at)),
        FieldType::U32 => write!(out, "{}", read::<u32>(payload, at)),
        FieldType::I32 => write!(out, "{}", read::<i32>(payload, at)),
        FieldType::U64 => write!(out, "{}", read::<u64>(payload, at)),
        FieldType::I64 => write!(out, "{}", read::<i64>(payload, at)),
        FieldType::F32 => write!(out, "{:08x}", read::<f32>(payload, at).to_bits()),
        FieldType::F64 => write!(out, "{:016x}", read::<f64>(payload, at).to_bits()),
    };
}

/// The value text of a payload of any length (zero-filled past its end),
/// read through the field table and `mavframe::field`.
pub fn values_text(meta: &MessageMeta, payload: &[u8]) -> String {
    let mut out = String::with_capacity(16 * meta.fields.len());
    for (i, f) in meta.fields.iter().enumerate() {
        if i > 0 {
            out.push(';');
        }
        out.push_str(f.name);
        out.push('=');
        let at = f.offset as usize;
        if f.ty == FieldType::Char && f.array_len > 0 {
            for k in 0..f.array_len as usize {
                let _ = write!(out, "{:02x}", read::<u8>(payload, at + k));
            }
        } else if f.array_len == 0 {
            elem_text(&mut out, payload, f.ty, at);
        } else {
            for k in 0..f.array_len as usize {
                if k > 0 {
                    out.push(',');
                }
                elem_text(&mut out, payload, f.ty, at + k * f.ty.size());
            }
        }
    }
    out
}

/// Writes a value text back into a payload of `meta.max_len` bytes (the
/// inverse of [`values_text`]); `None` if the text does not fit the table.
pub fn payload_from_text(meta: &MessageMeta, text: &str) -> Option<Vec<u8>> {
    let mut p = vec![0u8; meta.max_len as usize];
    let mut items = text.split(';');
    for f in meta.fields {
        let (name, v) = items.next()?.split_once('=')?;
        if name != f.name {
            return None;
        }
        let at = f.offset as usize;
        if f.ty == FieldType::Char && f.array_len > 0 {
            let bytes = hex_decode(v)?;
            if bytes.len() != f.array_len as usize {
                return None;
            }
            put(&mut p, at, &bytes);
            continue;
        }
        let elems: Vec<&str> = v.split(',').collect();
        if elems.len() != elem_count(f) {
            return None;
        }
        for (k, e) in elems.iter().enumerate() {
            let a = at + k * f.ty.size();
            match f.ty {
                FieldType::F32 => u32::from_str_radix(e, 16).ok()?.write(&mut p, a),
                FieldType::F64 => u64::from_str_radix(e, 16).ok()?.write(&mut p, a),
                FieldType::Char | FieldType::U8 => e.parse::<u8>().ok()?.write(&mut p, a),
                FieldType::I8 => e.parse::<i8>().ok()?.write(&mut p, a),
                FieldType::U16 => e.parse::<u16>().ok()?.write(&mut p, a),
                FieldType::I16 => e.parse::<i16>().ok()?.write(&mut p, a),
                FieldType::U32 => e.parse::<u32>().ok()?.write(&mut p, a),
                FieldType::I32 => e.parse::<i32>().ok()?.write(&mut p, a),
                FieldType::U64 => e.parse::<u64>().ok()?.write(&mut p, a),
                FieldType::I64 => e.parse::<i64>().ok()?.write(&mut p, a),
            }
        }
    }
    items.next().is_none().then_some(p)
}

pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
}

pub fn hex_decode(s: &str) -> Option<Vec<u8>> {
    if s.len() % 2 != 0 {
        return None;
    }
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(s.get(i..i + 2)?, 16).ok())
        .collect()
}
