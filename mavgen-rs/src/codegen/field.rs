//! One place per kind of message field: each method of [`FieldKind`]
//! produces one part of the generated code (the owned field's type, the
//! view's accessor, the writer's setter, `parse`, `emit`, `Default`, serde).

use super::{lit, zero};
use crate::model::Primitive;
use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};

/// How a field is represented in Rust.
pub(super) enum FieldKind {
    /// A number; `version` is the dialect version a `mavlink_version`
    /// field defaults to.
    Scalar {
        prim: Primitive,
        version: Option<u8>,
    },
    /// An unsigned scalar carrying a value enum's value.
    Enum(EnumField),
    /// An unsigned scalar carrying a bitmask enum's flags.
    Bitmask(EnumField),
    /// A fixed-length array of numbers.
    Array(Primitive, usize),
    /// A `char[N]` string.
    Chars(usize),
}

/// A scalar field typed as a generated enum.
pub(super) struct EnumField {
    /// The field's wire type.
    pub prim: Primitive,
    /// The enum's path from the field's module.
    pub path: TokenStream,
    /// The enum's representation, at least as wide as `prim`.
    pub repr: Primitive,
}

impl EnumField {
    /// The raw wire value read from `src`, widened to the representation.
    fn read_raw(&self, rt: &TokenStream, src: &TokenStream, off: &Literal) -> TokenStream {
        let t = rust_type(self.prim);
        let raw = quote!(#rt::field::read::<#t>(#src, #off));
        if self.prim == self.repr {
            raw
        } else {
            let r = rust_type(self.repr);
            quote!(#r::from(#raw))
        }
    }

    /// `to_raw`, narrowed to the field's wire type. The representation is
    /// at least as wide as the field; the narrowing keeps the low bits,
    /// which is all the field holds.
    fn narrow(&self, to_raw: TokenStream) -> TokenStream {
        if self.prim == self.repr {
            to_raw
        } else {
            let t = rust_type(self.prim);
            quote!(#to_raw as #t)
        }
    }
}

fn rust_type(p: Primitive) -> Ident {
    format_ident!("{}", p.rust_name())
}

impl FieldKind {
    /// The type of the owned struct's field.
    pub fn owned_type(&self) -> TokenStream {
        match self {
            FieldKind::Scalar { prim, .. } => {
                let t = rust_type(*prim);
                quote!(#t)
            }
            FieldKind::Enum(e) | FieldKind::Bitmask(e) => e.path.clone(),
            FieldKind::Array(p, n) => {
                let (t, n) = (rust_type(*p), lit(*n as u64));
                quote!([#t; #n])
            }
            FieldKind::Chars(n) => {
                let n = lit(*n as u64);
                quote!([u8; #n])
            }
        }
    }

    /// The type the view's accessor returns (borrowing the payload `'a`).
    pub fn view_type(&self, rt: &TokenStream) -> TokenStream {
        match self {
            FieldKind::Array(p, n) => {
                let (t, n) = (rust_type(*p), lit(*n as u64));
                quote!(#rt::field::ArrayView<'a, #t, #n>)
            }
            FieldKind::Chars(n) => {
                let n = lit(*n as u64);
                quote!(#rt::field::CharArray<'a, #n>)
            }
            _ => self.owned_type(),
        }
    }

    /// The type the setter takes.
    pub fn setter_type(&self) -> TokenStream {
        let owned = self.owned_type();
        if self.by_ref() {
            quote!(&#owned)
        } else {
            owned
        }
    }

    /// Whether `emit` and the setter take the value by reference.
    pub fn by_ref(&self) -> bool {
        matches!(self, FieldKind::Array(..) | FieldKind::Chars(_))
    }

    /// Reads the field at `off` of the bytes `src`, as the view type.
    pub fn read(&self, rt: &TokenStream, src: &TokenStream, off: &Literal) -> TokenStream {
        match self {
            FieldKind::Scalar { prim, .. } => {
                let t = rust_type(*prim);
                quote!(#rt::field::read::<#t>(#src, #off))
            }
            FieldKind::Enum(e) => {
                let (path, raw) = (&e.path, e.read_raw(rt, src, off));
                quote!(#path::from_raw(#raw))
            }
            FieldKind::Bitmask(e) => {
                let (path, raw) = (&e.path, e.read_raw(rt, src, off));
                quote!(#path::from_bits_retain(#raw))
            }
            FieldKind::Array(..) => quote!(#rt::field::ArrayView::new(#src, #off)),
            FieldKind::Chars(_) => quote!(#rt::field::CharArray::new(#src, #off)),
        }
    }

    /// Reads the field at `off` of the bytes `src`, as the owned type.
    pub fn read_owned(&self, rt: &TokenStream, src: &TokenStream, off: &Literal) -> TokenStream {
        let read = self.read(rt, src, off);
        if self.by_ref() {
            quote!(#read.to_array())
        } else {
            read
        }
    }

    /// Writes `value` (the setter's type) at `off` of the bytes `dst`.
    pub fn write(
        &self,
        rt: &TokenStream,
        dst: &TokenStream,
        value: &TokenStream,
        off: &Literal,
    ) -> TokenStream {
        let scalar = match self {
            FieldKind::Scalar { .. } => value.clone(),
            FieldKind::Enum(e) => e.narrow(quote!(#value.to_raw())),
            FieldKind::Bitmask(e) => e.narrow(quote!(#value.bits())),
            FieldKind::Array(..) | FieldKind::Chars(_) => {
                return quote!(#rt::field::write_array(#dst, #off, #value));
            }
        };
        quote!(#rt::field::Scalar::write(#scalar, #dst, #off))
    }

    /// The owned field's value in `Default`.
    pub fn default_value(&self) -> TokenStream {
        match self {
            FieldKind::Scalar {
                version: Some(v), ..
            } => {
                let v = lit(*v);
                quote!(#v)
            }
            FieldKind::Scalar { prim, .. } => zero(*prim),
            FieldKind::Enum(e) | FieldKind::Bitmask(e) => {
                let path = &e.path;
                quote!(#path::default())
            }
            FieldKind::Array(p, n) => {
                let (z, n) = (zero(*p), lit(*n as u64));
                quote!([#z; #n])
            }
            FieldKind::Chars(n) => {
                let n = lit(*n as u64);
                quote!([0; #n])
            }
        }
    }

    /// The serde argument giving the form of the field's values (see
    /// `mavframe::serde`), `None` where serde's own fits; `rt_path` names
    /// a runtime item as a string.
    pub fn serde_with(&self, rt_path: impl Fn(&str) -> String) -> Option<TokenStream> {
        let with = |module: &str| {
            let path = rt_path(&format!("serde::{module}"));
            quote!(with = #path)
        };
        match self {
            FieldKind::Scalar {
                prim: Primitive::F32 | Primitive::F64,
                ..
            } => Some(with("float")),
            FieldKind::Scalar { .. } => None,
            FieldKind::Array(..) => Some(with("array")),
            FieldKind::Chars(_) => Some(with("chars")),
            FieldKind::Enum(e) | FieldKind::Bitmask(e) if e.prim != e.repr => {
                let path = format!(
                    "{}::<_, _, {}, {}>",
                    rt_path("serde::narrow"),
                    e.repr.rust_name(),
                    e.prim.rust_name()
                );
                Some(quote!(deserialize_with = #path))
            }
            FieldKind::Enum(_) | FieldKind::Bitmask(_) => None,
        }
    }
}
