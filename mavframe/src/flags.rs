//! The flag-set API of generated bitmask enums.
//!
//! A bitmask enum is generated as a newtype over its wire value with one
//! associated constant per flag, like a value enum; a macro then adds
//! the set operations, `Debug`, and an implementation of [`bitflags::Flags`]
//! (so bitflags' generic API — `iter_names`, its text parser — works on it).
//!
//! Why not a `bitflags!` invocation per enum: that macro expands to some
//! eighty functions and trait impls per type. With the 52 bitmask enums of
//! ardupilotmega it was a quarter of the dialect's compile time; this
//! expansion is small, and its `Debug` shares one non-generic function.

use core::fmt;

/// Writes `Name(FLAG_A | FLAG_B | 0x40)`: the named flags set in `bits`, in
/// table order, then any bits no flag names, in hex (`Name(0x0)` when
/// empty). The format of bitflags' own `Debug`. Generated code only: not
/// part of the API.
#[doc(hidden)]
pub fn fmt(
    f: &mut fmt::Formatter<'_>,
    type_name: &str,
    bits: u64,
    flags: &[(&str, u64)],
) -> fmt::Result {
    f.write_str(type_name)?;
    f.write_str("(")?;
    let mut rest = bits;
    let mut first = true;
    for &(name, value) in flags {
        // A flag is shown when all its bits are set and some are still
        // unnamed (multi-bit flags overlap single-bit ones).
        if value != 0 && bits & value == value && rest & value != 0 {
            if !first {
                f.write_str(" | ")?;
            }
            f.write_str(name)?;
            rest &= !value;
            first = false;
        }
    }
    if rest != 0 || first {
        if !first {
            f.write_str(" | ")?;
        }
        write!(f, "{rest:#x}")?;
    }
    f.write_str(")")
}

/// Implements the flag-set API for a generated bitmask newtype
/// `struct Name(pub Repr)` whose flags are associated constants:
/// `mavframe::flag_set!(Name, u8, [FLAG_A, FLAG_B]);`.
///
/// Adds `empty`, `all`, `bits`, `from_bits_retain`, `from_bits_truncate`,
/// `from_bits`, `is_empty`, `contains`, `intersects`, `union`,
/// `intersection`, `difference`, `insert`, `remove`, `set`, the operators
/// `| & - !` (and `|=`, `&=`), `Debug`, `From` to and from `Repr`, and
/// [`bitflags::Flags`]. Bits no flag names are kept everywhere except by
/// `from_bits_truncate` and `from_bits`. The rest of bitflags' API
/// (`iter_names`, `from_name`, `toggle`, `complement`, text parsing…) comes
/// with the trait: `use mavframe::bitflags::Flags;`.
// Generated code only: not part of the API.
#[doc(hidden)]
#[macro_export]
macro_rules! flag_set {
    ($name:ident, $repr:ty, [$($flag:ident),* $(,)?]) => {
        impl $name {
            /// The empty set.
            #[inline]
            pub const fn empty() -> Self {
                Self(0)
            }

            /// Every flag the XML defines.
            #[inline]
            pub const fn all() -> Self {
                Self(0 $(| Self::$flag.0)*)
            }

            /// The raw wire value.
            #[inline]
            pub const fn bits(&self) -> $repr {
                self.0
            }

            /// The set of a raw wire value, unknown bits kept.
            #[inline]
            pub const fn from_bits_retain(bits: $repr) -> Self {
                Self(bits)
            }

            /// The set of a raw wire value, unknown bits dropped.
            #[inline]
            pub const fn from_bits_truncate(bits: $repr) -> Self {
                Self(bits & Self::all().0)
            }

            /// The set of a raw wire value; `None` if it has unknown bits.
            #[inline]
            pub const fn from_bits(bits: $repr) -> Option<Self> {
                if bits & !Self::all().0 == 0 {
                    Some(Self(bits))
                } else {
                    None
                }
            }

            /// No bit is set.
            #[inline]
            pub const fn is_empty(&self) -> bool {
                self.0 == 0
            }

            /// Every bit of `other` is set in `self`.
            #[inline]
            pub const fn contains(&self, other: Self) -> bool {
                self.0 & other.0 == other.0
            }

            /// Some bit of `other` is set in `self`.
            #[inline]
            pub const fn intersects(&self, other: Self) -> bool {
                self.0 & other.0 != 0
            }

            /// The bits set in either.
            #[must_use]
            #[inline]
            pub const fn union(self, other: Self) -> Self {
                Self(self.0 | other.0)
            }

            /// The bits set in both.
            #[must_use]
            #[inline]
            pub const fn intersection(self, other: Self) -> Self {
                Self(self.0 & other.0)
            }

            /// The bits of `self` not set in `other`.
            #[must_use]
            #[inline]
            pub const fn difference(self, other: Self) -> Self {
                Self(self.0 & !other.0)
            }

            /// Sets the bits of `other`.
            #[inline]
            pub fn insert(&mut self, other: Self) {
                self.0 |= other.0;
            }

            /// Clears the bits of `other`.
            #[inline]
            pub fn remove(&mut self, other: Self) {
                self.0 &= !other.0;
            }

            /// Sets (`value`) or clears the bits of `other`.
            #[inline]
            pub fn set(&mut self, other: Self, value: bool) {
                if value {
                    self.insert(other)
                } else {
                    self.remove(other)
                }
            }
        }

        impl ::core::ops::BitOr for $name {
            type Output = Self;
            #[inline]
            fn bitor(self, other: Self) -> Self {
                Self(self.0 | other.0)
            }
        }

        impl ::core::ops::BitOrAssign for $name {
            #[inline]
            fn bitor_assign(&mut self, other: Self) {
                self.0 |= other.0;
            }
        }

        impl ::core::ops::BitAnd for $name {
            type Output = Self;
            #[inline]
            fn bitand(self, other: Self) -> Self {
                Self(self.0 & other.0)
            }
        }

        impl ::core::ops::BitAndAssign for $name {
            #[inline]
            fn bitand_assign(&mut self, other: Self) {
                self.0 &= other.0;
            }
        }

        impl ::core::ops::Sub for $name {
            type Output = Self;
            #[inline]
            fn sub(self, other: Self) -> Self {
                Self(self.0 & !other.0)
            }
        }

        impl ::core::ops::Not for $name {
            type Output = Self;
            /// Complements every bit of the wire value, unknown ones included.
            #[inline]
            fn not(self) -> Self {
                Self(!self.0)
            }
        }

        impl ::core::fmt::Debug for $name {
            fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
                // A plain table, not an iterator over `Flags::FLAGS`: a
                // `dyn Iterator` would instantiate every iterator method
                // for every flag type.
                const NAMES: &[(&str, u64)] = &[$((stringify!($flag), $name::$flag.0 as u64),)*];
                $crate::flags::fmt(f, stringify!($name), self.0 as u64, NAMES)
            }
        }

        impl ::core::convert::From<$repr> for $name {
            #[inline]
            fn from(bits: $repr) -> Self {
                Self(bits)
            }
        }

        impl ::core::convert::From<$name> for $repr {
            #[inline]
            fn from(set: $name) -> Self {
                set.0
            }
        }

        impl $crate::bitflags::Flags for $name {
            const FLAGS: &'static [$crate::bitflags::Flag<Self>] = &[
                $($crate::bitflags::Flag::new(stringify!($flag), Self::$flag),)*
            ];
            type Bits = $repr;

            #[inline]
            fn bits(&self) -> $repr {
                self.0
            }

            #[inline]
            fn from_bits_retain(bits: $repr) -> Self {
                Self(bits)
            }
        }
    };
}

#[cfg(test)]
mod tests {
    extern crate std;
    use std::format;

    /// Two single-bit flags and one two-bit flag overlapping them.
    #[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
    pub struct Modes(pub u8);
    impl Modes {
        pub const A: Self = Self(1);
        pub const B: Self = Self(2);
        pub const AB: Self = Self(3);
        pub const HIGH: Self = Self(0x80);
    }
    crate::flag_set!(Modes, u8, [A, B, AB, HIGH]);

    #[test]
    fn set_operations_keep_unknown_bits() {
        let mut m = Modes::A | Modes::from_bits_retain(0x10);
        assert_eq!(m.bits(), 0x11);
        assert!(m.contains(Modes::A) && !m.contains(Modes::AB));
        assert!(m.intersects(Modes::AB));
        m.insert(Modes::B);
        assert!(m.contains(Modes::AB));
        m.set(Modes::A, false);
        assert_eq!(m, Modes(0x12));
        assert_eq!((m - Modes::B).bits(), 0x10);
        assert_eq!((!Modes::empty()).bits(), 0xff);
        assert_eq!(Modes::all().bits(), 0x83);
        assert_eq!(Modes::from_bits_truncate(0xff), Modes::all());
        assert_eq!(Modes::from_bits(0x10), None);
        assert_eq!(Modes::from_bits(0x81), Some(Modes::A | Modes::HIGH));
        assert_eq!(u8::from(Modes::from(7)), 7);
    }

    #[test]
    fn debug_names_flags_then_unknown_bits_like_bitflags() {
        assert_eq!(format!("{:?}", Modes::empty()), "Modes(0x0)");
        assert_eq!(format!("{:?}", Modes::A), "Modes(A)");
        // Both single bits name the two-bit flag's bits first.
        assert_eq!(format!("{:?}", Modes::AB), "Modes(A | B)");
        assert_eq!(format!("{:?}", Modes(0x91)), "Modes(A | HIGH | 0x10)");
        assert_eq!(format!("{:?}", Modes(0x40)), "Modes(0x40)");
    }

    #[test]
    fn bitflags_generic_api_works() {
        use bitflags::Flags;
        let names: std::vec::Vec<_> = Modes(0x83).iter_names().map(|(n, _)| n).collect();
        assert_eq!(names, ["A", "B", "HIGH"]);
        let mut text = std::string::String::new();
        bitflags::parser::to_writer(&Modes(0x81), &mut text).unwrap();
        assert_eq!(text, "A | HIGH");
        let parsed: Modes = bitflags::parser::from_str("B | 0x10").unwrap();
        assert_eq!(parsed, Modes(0x12));
    }
}
