//! Little-endian field codecs over payload bytes.
//!
//! MAVLink 2 drops trailing zero bytes from payloads, so a received payload
//! may be shorter than its message's wire length. Every read here treats the
//! missing bytes as zero (as the C library's zero-filled buffer does) and
//! never panics, whatever the slice length; the fast path is one bounds check.

use core::fmt;
use core::marker::PhantomData;

/// A MAVLink scalar wire type (`uint8_t` … `double`, `char` as `u8`).
pub trait Scalar: Copy + Default + PartialEq + fmt::Debug + 'static {
    /// Bytes on the wire.
    const SIZE: usize;
    /// Reads the value at `offset`, zero-filling bytes past the end of `buf`.
    #[doc(hidden)]
    fn read(buf: &[u8], offset: usize) -> Self;
    /// Writes the value at `offset`; bytes that do not fit are not written.
    #[doc(hidden)]
    fn write(self, buf: &mut [u8], offset: usize);
}

macro_rules! scalar {
    ($($t:ty),*) => {$(
        impl Scalar for $t {
            const SIZE: usize = core::mem::size_of::<$t>();

            #[inline(always)]
            fn read(buf: &[u8], offset: usize) -> Self {
                const N: usize = core::mem::size_of::<$t>();
                let mut bytes = [0u8; N];
                match buf.get(offset..offset + N) {
                    Some(src) => bytes.copy_from_slice(src),
                    None => bytes = read_partial::<N>(buf, offset),
                }
                <$t>::from_le_bytes(bytes)
            }

            #[inline(always)]
            fn write(self, buf: &mut [u8], offset: usize) {
                const N: usize = core::mem::size_of::<$t>();
                if let Some(dst) = buf.get_mut(offset..offset + N) {
                    dst.copy_from_slice(&self.to_le_bytes());
                }
            }
        }
    )*};
}

/// The bytes of a field that does not lie whole in `buf` (a truncated
/// payload): the present prefix, zeros after. Out of line and cold, so the
/// inlined read of every generated accessor stays a bounds check and a load
/// (one copy of this per field size instead of one per field, which cost the
/// full dialect about a tenth of its compile time).
#[cold]
#[inline(never)]
fn read_partial<const N: usize>(buf: &[u8], offset: usize) -> [u8; N] {
    let mut bytes = [0u8; N];
    let tail = buf.get(offset..).unwrap_or(&[]);
    // Byte by byte (N ≤ 8): a variable-length copy would call `memcpy`.
    for (i, dst) in bytes.iter_mut().enumerate() {
        if let Some(&b) = tail.get(i) {
            *dst = b;
        }
    }
    bytes
}

scalar!(u8, i8, u16, i16, u32, i32, u64, i64, f32, f64);

/// The first `N` bytes of `payload` as an array, zero-filled past the end
/// of a truncated MAVLink 2 payload (as the C library's buffer is). A copy
/// of at most 255 bytes, by value: reads at constant offsets from it need no
/// bounds checks, and a full-length payload costs only the copy.
// Generated code only: not part of the API.
#[doc(hidden)]
#[inline(always)]
pub fn padded<const N: usize>(payload: &[u8]) -> [u8; N] {
    match payload.first_chunk::<N>() {
        Some(whole) => *whole,
        None => zero_filled(payload),
    }
}

/// `payload` (shorter than `N`) followed by zeros.
#[inline(never)]
fn zero_filled<const N: usize>(payload: &[u8]) -> [u8; N] {
    let mut out = [0u8; N];
    let n = payload.len().min(N);
    out[..n].copy_from_slice(&payload[..n]);
    out
}

/// The first `N` bytes of `payload` as an array to write a whole payload
/// into, or the error saying how many bytes were needed.
// Generated code only: not part of the API.
#[doc(hidden)]
#[inline(always)]
pub fn prefix_mut<const N: usize>(
    payload: &mut [u8],
) -> Result<&mut [u8; N], crate::message::BufferTooSmall> {
    let got = payload.len();
    payload
        .first_chunk_mut::<N>()
        .ok_or(crate::message::BufferTooSmall { needed: N, got })
}

/// Reads a scalar at `offset` (zero-filled past the end of `buf`).
// Generated code only: not part of the API.
#[doc(hidden)]
#[inline(always)]
pub fn read<T: Scalar>(buf: &[u8], offset: usize) -> T {
    T::read(buf, offset)
}

/// An array field read in place: `N` elements of `T` starting at an offset of
/// the payload. Elements past the end of a truncated payload read as zero.
#[derive(Clone, Copy)]
pub struct ArrayView<'a, T: Scalar, const N: usize> {
    bytes: &'a [u8],
    _elem: PhantomData<T>,
}

impl<'a, T: Scalar, const N: usize> ArrayView<'a, T, N> {
    /// The array at `offset` of `payload` (any length).
    #[inline(always)]
    pub fn new(payload: &'a [u8], offset: usize) -> Self {
        let bytes = payload.get(offset..).unwrap_or(&[]);
        let bytes = bytes.get(..N * T::SIZE).unwrap_or(bytes);
        ArrayView {
            bytes,
            _elem: PhantomData,
        }
    }

    /// Number of elements, always `N`.
    #[inline(always)]
    pub const fn len(&self) -> usize {
        N
    }

    /// True when `N` is zero (never, for arrays the generator accepts).
    #[inline(always)]
    pub const fn is_empty(&self) -> bool {
        N == 0
    }

    /// Element `index`, or `None` when `index >= N`.
    #[inline(always)]
    pub fn get(&self, index: usize) -> Option<T> {
        (index < N).then(|| T::read(self.bytes, index * T::SIZE))
    }

    /// The elements in order, zero-filled.
    pub fn iter(&self) -> impl ExactSizeIterator<Item = T> + 'a {
        let bytes = self.bytes;
        (0..N).map(move |i| T::read(bytes, i * T::SIZE))
    }

    /// The bytes of the array present in the payload (shorter than
    /// `N * size` when the payload was truncated).
    #[inline(always)]
    pub fn present_bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// Copies the elements out.
    pub fn to_array(&self) -> [T; N] {
        let mut out = [T::default(); N];
        for (i, slot) in out.iter_mut().enumerate() {
            *slot = T::read(self.bytes, i * T::SIZE);
        }
        out
    }
}

impl<T: Scalar, const N: usize> fmt::Debug for ArrayView<'_, T, N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl<T: Scalar, const N: usize> PartialEq<[T; N]> for ArrayView<'_, T, N> {
    fn eq(&self, other: &[T; N]) -> bool {
        self.iter().eq(other.iter().copied())
    }
}

/// Writes an array field at `offset` (elements that do not fit are dropped).
// Generated code only: not part of the API.
#[doc(hidden)]
#[inline]
pub fn write_array<T: Scalar, const N: usize>(buf: &mut [u8], offset: usize, value: &[T; N]) {
    for (i, v) in value.iter().enumerate() {
        v.write(buf, offset + i * T::SIZE);
    }
}

/// A `char[N]` field read in place: a NUL-terminated (or `N`-byte) string.
#[derive(Clone, Copy, PartialEq, Eq)]
pub struct CharArray<'a, const N: usize> {
    bytes: &'a [u8],
}

impl<'a, const N: usize> CharArray<'a, N> {
    /// The string at `offset` of `payload` (any length).
    #[inline(always)]
    pub fn new(payload: &'a [u8], offset: usize) -> Self {
        let bytes = payload.get(offset..).unwrap_or(&[]);
        // All N bytes (fewer in a truncated payload), even after a NUL: the
        // wire carries them, and re-encoding must not change them.
        CharArray {
            bytes: bytes.get(..N).unwrap_or(bytes),
        }
    }

    /// The string's bytes, up to (not including) the first NUL: what
    /// pymavlink and the C library's users see as the text.
    #[inline(always)]
    pub fn as_bytes(&self) -> &'a [u8] {
        let end = self
            .bytes
            .iter()
            .position(|&b| b == 0)
            .unwrap_or(self.bytes.len());
        &self.bytes[..end]
    }

    /// Every byte of the field present in the payload, NULs and what
    /// follows them included.
    #[inline(always)]
    pub fn raw(&self) -> &'a [u8] {
        self.bytes
    }

    /// The string as UTF-8, if it is (up to the first NUL).
    pub fn to_str(&self) -> Result<&'a str, core::str::Utf8Error> {
        core::str::from_utf8(self.as_bytes())
    }

    /// Copies every byte of the field (zero-padded past a truncated
    /// payload), so parse → emit reproduces the payload exactly.
    #[inline]
    pub fn to_array(&self) -> [u8; N] {
        let mut out = [0u8; N];
        // Not `copy_from_slice`: its variable length makes it a `memcpy`
        // call, whose result is then read back through a store-forwarding
        // stall; strings are short, and this loop is unrolled or vectorised.
        for (i, slot) in out.iter_mut().enumerate() {
            if let Some(&b) = self.bytes.get(i) {
                *slot = b;
            }
        }
        out
    }
}

impl<const N: usize> fmt::Debug for CharArray<'_, N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.to_str() {
            Ok(s) => fmt::Debug::fmt(s, f),
            Err(_) => fmt::Debug::fmt(self.as_bytes(), f),
        }
    }
}

/// Builds a zero-padded `char[N]` value from a string, cutting it at `N` bytes.
///
/// ```
/// let text: [u8; 5] = mavframe::field::chars("FBWAG");
/// assert_eq!(&text, b"FBWAG");
/// ```
pub fn chars<const N: usize>(s: &str) -> [u8; N] {
    let mut out = [0u8; N];
    let n = s.len().min(N);
    out[..n].copy_from_slice(&s.as_bytes()[..n]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_reads_zero_fill_truncated_payloads() {
        let buf = [0x40, 0xe2, 0x01];
        assert_eq!(read::<u32>(&buf, 0), 123_456);
        assert_eq!(read::<u32>(&buf, 2), 1);
        assert_eq!(read::<u64>(&buf, 200), 0);
        assert_eq!(read::<f32>(&[], 0), 0.0);
        assert_eq!(read::<i16>(&[0xff, 0xff], 0), -1);
    }

    #[test]
    fn scalar_write_round_trips_and_ignores_out_of_range() {
        let mut buf = [0u8; 8];
        (-2.5f64).write(&mut buf, 0);
        assert_eq!(read::<f64>(&buf, 0), -2.5);
        0xdead_u16.write(&mut buf, 7); // does not fit: not written
        assert_eq!(buf[7], read::<f64>(&buf, 0).to_le_bytes()[7]);
    }

    #[test]
    fn padded_zero_fills_and_prefix_mut_checks_the_length() {
        assert_eq!(padded::<4>(&[1, 2]), [1, 2, 0, 0]);
        assert_eq!(padded::<4>(&[]), [0; 4]);
        assert_eq!(padded::<2>(&[1, 2, 3]), [1, 2]);
        let mut buf = [0u8; 5];
        assert_eq!(prefix_mut::<4>(&mut buf).map(|a| a.len()), Ok(4));
        assert_eq!(
            prefix_mut::<6>(&mut buf).map(|a| a.len()),
            Err(crate::message::BufferTooSmall { needed: 6, got: 5 })
        );
    }

    #[test]
    fn arrays_read_in_place_and_zero_fill() {
        let buf = [1, 0, 2, 0, 3];
        let a = ArrayView::<u16, 4>::new(&buf, 0);
        assert_eq!(a.to_array(), [1, 2, 3, 0]);
        assert_eq!(a.get(3), Some(0));
        assert_eq!(a.get(4), None);
        assert_eq!(a.present_bytes(), &buf);
        let beyond = ArrayView::<u16, 4>::new(&buf, 99);
        assert_eq!(beyond.to_array(), [0; 4]);
    }

    #[test]
    fn char_arrays_stop_at_nul_or_length() {
        let buf = *b"ABCDE\0\0";
        assert_eq!(CharArray::<5>::new(&buf, 0).as_bytes(), b"ABCDE");
        assert_eq!(CharArray::<3>::new(&buf, 3).as_bytes(), b"DE");
        assert_eq!(CharArray::<5>::new(&buf, 2).to_array(), *b"CDE\0\0");
        // Bytes after a NUL are kept by to_array and raw (not as_bytes).
        let odd = *b"AB\0CD";
        assert_eq!(CharArray::<5>::new(&odd, 0).as_bytes(), b"AB");
        assert_eq!(CharArray::<5>::new(&odd, 0).raw(), &odd);
        assert_eq!(CharArray::<5>::new(&odd, 0).to_array(), odd);
        assert_eq!(CharArray::<5>::new(b"AB", 0).to_str(), Ok("AB"));
        assert_eq!(chars::<3>("FBWAG"), *b"FBW");
    }
}
