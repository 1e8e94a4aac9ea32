//! Value enums (newtypes with associated constants) and flag sets.

use super::{docs, lit, Gen, DOC_WIDTH, SERDE_FEATURE};
use crate::model::{Entry, Primitive};
use crate::names::{camel, doc_lines, doc_list_item, entry_suffix};
use crate::schema::{MergedEnum, Schema};
use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};
use std::collections::BTreeSet;

/// The tokens of one enum's type and entries (see `Gen::enum_tokens`).
struct EnumTokens {
    name: proc_macro2::Ident,
    repr: proc_macro2::Ident,
    doc: TokenStream,
    consts: Vec<proc_macro2::Ident>,
    entry_docs: Vec<TokenStream>,
    values: Vec<Literal>,
}

/// Rust-side facts about one merged enum.
pub(super) struct EnumInfo {
    pub module: usize,
    pub rust_name: String,
    pub repr: Primitive,
    pub bitmask: bool,
}

/// Chooses an enum's Rust representation: wide enough for its values and for
/// every unsigned field that carries it, so conversions never lose bits.
pub(super) fn enum_info(schema: &Schema, name: &str, m: &MergedEnum) -> EnumInfo {
    let max = m.def.entries.iter().map(|e| e.value).max().unwrap_or(0);
    let mut repr = if max <= u8::MAX as u64 {
        Primitive::U8
    } else if max <= u16::MAX as u64 {
        Primitive::U16
    } else if max <= u32::MAX as u64 {
        Primitive::U32
    } else {
        Primitive::U64
    };
    let mut bitmask = m.def.bitmask;
    for r in schema.message_refs() {
        for f in &schema.message(r).fields {
            if f.enum_name.as_deref() == Some(name)
                && f.array_len.is_none()
                && f.primitive.is_unsigned_int()
                && !f.mavlink_version
            {
                if f.primitive.size() > repr.size() {
                    repr = f.primitive;
                }
                bitmask |= f.display.as_deref() == Some("bitmask");
            }
        }
    }
    EnumInfo {
        module: m.home,
        rust_name: camel(name),
        repr,
        bitmask,
    }
}

impl Gen<'_> {
    fn entry_docs(&self, e: &Entry) -> Vec<String> {
        let mut lines = doc_lines(&e.description, DOC_WIDTH);
        if lines.is_empty() {
            lines.push(format!("`{}`", e.name));
        }
        if e.wip {
            lines.push(String::new());
            lines.push("**Work in progress**: may change.".into());
        }
        if let Some(d) = &e.deprecated {
            lines.push(String::new());
            lines.extend(doc_lines(&super::deprecated_note(d), DOC_WIDTH));
        }
        let params: Vec<_> = e
            .params
            .iter()
            .filter(|p| !p.description.trim().is_empty() || p.label.is_some())
            .collect();
        if !params.is_empty() {
            lines.push(String::new());
            for p in params {
                let mut head = format!("Param {}", p.index);
                match (&p.label, &p.units) {
                    (Some(l), Some(u)) => head.push_str(&format!(" ({l}, {u})")),
                    (Some(l), None) => head.push_str(&format!(" ({l})")),
                    (None, Some(u)) => head.push_str(&format!(" ({u})")),
                    (None, None) => {}
                }
                lines.extend(doc_list_item(
                    &format!("{head}: {}", p.description),
                    DOC_WIDTH,
                ));
            }
        }
        lines
    }

    fn enum_docs(&self, def: &MergedEnum) -> Vec<String> {
        let mut lines = doc_lines(&def.def.description, DOC_WIDTH);
        if lines.is_empty() {
            lines.push(format!("`{}`", def.def.name));
        }
        lines.push(String::new());
        lines.push(format!("MAVLink enum `{}`.", def.def.name));
        if let Some(d) = &def.def.deprecated {
            lines.extend(doc_lines(&super::deprecated_note(d), DOC_WIDTH));
        }
        lines
    }

    /// Variant or constant names for the entries, unique within the enum.
    fn entry_names(def: &MergedEnum, convert: fn(&str) -> String, reserved: &str) -> Vec<String> {
        let mut seen = BTreeSet::new();
        seen.insert(reserved.to_string());
        def.def
            .entries
            .iter()
            .map(|e| {
                let mut n = convert(entry_suffix(&def.def.name, &e.name));
                if !seen.insert(n.clone()) {
                    n = format!("{n}{}", e.value);
                    seen.insert(n.clone());
                }
                n
            })
            .collect()
    }

    /// What value enums and flag sets have in common: the type, its
    /// representation and docs, and per entry its constant, docs and value.
    fn enum_tokens(&self, def: &MergedEnum, info: &EnumInfo) -> EnumTokens {
        let names = Self::entry_names(def, |s| s.to_ascii_uppercase(), "_");
        EnumTokens {
            name: format_ident!("{}", info.rust_name),
            repr: format_ident!("{}", info.repr.rust_name()),
            doc: docs(&self.enum_docs(def)),
            consts: names.iter().map(|n| format_ident!("{}", n)).collect(),
            entry_docs: def
                .def
                .entries
                .iter()
                .map(|e| docs(&self.entry_docs(e)))
                .collect(),
            values: def.def.entries.iter().map(|e| lit(e.value)).collect(),
        }
    }

    /// A value enum as a newtype over its wire value with one associated
    /// constant per entry: any value is representable (an unlisted one is
    /// kept, never rejected), conversions are free, and constants match in
    /// patterns like enum variants.
    pub(super) fn value_enum(&self, def: &MergedEnum, info: &EnumInfo) -> TokenStream {
        let EnumTokens {
            name,
            repr,
            doc,
            consts,
            entry_docs,
            values,
        } = self.enum_tokens(def, info);
        let xml_names: Vec<_> = def.def.entries.iter().map(|e| e.name.as_str()).collect();
        let serde = self.enum_serde(def, &name, &repr, false);
        let user = self.type_attrs(&def.def.name);
        quote! {
            #doc
            ///
            /// The wire value itself: values the XML does not list are kept, so
            /// a message is never rejected for carrying one.
            #[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
            #user
            pub struct #name(pub #repr);

            impl #name {
                #( #entry_docs pub const #consts: Self = Self(#values); )*

                /// The enum for a raw wire value.
                pub const fn from_raw(value: #repr) -> Self {
                    Self(value)
                }

                /// The raw wire value.
                pub const fn to_raw(self) -> #repr {
                    self.0
                }

                /// The entry's name in the XML, `None` for a value it does not list.
                pub const fn name(self) -> Option<&'static str> {
                    Some(match self.0 {
                        #( #values => #xml_names, )*
                        _ => return None,
                    })
                }
            }

            impl ::core::fmt::Debug for #name {
                fn fmt(&self, f: &mut ::core::fmt::Formatter<'_>) -> ::core::fmt::Result {
                    match self.name() {
                        Some(name) => f.write_str(name),
                        None => write!(f, "{}({})", stringify!(#name), self.0),
                    }
                }
            }

            impl From<#repr> for #name {
                fn from(value: #repr) -> Self {
                    Self(value)
                }
            }

            impl From<#name> for #repr {
                fn from(value: #name) -> Self {
                    value.0
                }
            }

            #serde
        }
    }

    /// Serialize and Deserialize for a value enum or flag set: names in
    /// human-readable formats, numbers in compact ones (see
    /// `mavframe::serde::value_enum` and `mavframe::serde::flags`).
    fn enum_serde(
        &self,
        def: &MergedEnum,
        name: &proc_macro2::Ident,
        repr: &proc_macro2::Ident,
        bitmask: bool,
    ) -> TokenStream {
        let rt = self.rt();
        let xml = def.def.name.as_str();
        let names = def.def.entries.iter().map(|e| e.name.as_str());
        let values = def.def.entries.iter().map(|e| lit(e.value));
        // Not `FLAGS`, which would hide bitflags' `Flags::FLAGS`.
        let table = quote!(SERDE_TABLE);
        let (module, name_arg) = if bitmask {
            (quote!(flags), quote!(, Self::#table))
        } else {
            (quote!(value_enum), quote!(, self.name()))
        };
        let table_doc = format!(
            " The XML name and value of every {}.",
            if bitmask { "flag" } else { "entry" }
        );
        quote! {
            #[cfg(feature = #SERDE_FEATURE)]
            impl #name {
                #[doc = #table_doc]
                const #table: &'static [(&'static str, #repr)] = &[ #( (#names, #values), )* ];
            }

            #[cfg(feature = #SERDE_FEATURE)]
            impl #rt::serde::Serialize for #name {
                fn serialize<S: #rt::serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                    #rt::serde::#module::serialize(serializer, self.0 #name_arg)
                }
            }

            #[cfg(feature = #SERDE_FEATURE)]
            impl<'de> #rt::serde::Deserialize<'de> for #name {
                fn deserialize<D: #rt::serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                    #rt::serde::#module::deserialize(deserializer, #xml, Self::#table).map(Self)
                }
            }
        }
    }

    /// A bitmask enum: a newtype over its wire value with one associated
    /// constant per flag, as a value enum, and the set operations from the
    /// runtime's `flag_set!` (see `mavframe::flags` for why not `bitflags!`).
    pub(super) fn flag_set(&self, def: &MergedEnum, info: &EnumInfo) -> TokenStream {
        let rt = self.rt();
        let EnumTokens {
            name,
            repr,
            doc,
            consts,
            entry_docs,
            values,
        } = self.enum_tokens(def, info);
        let serde = self.enum_serde(def, &name, &repr, true);
        let user = self.type_attrs(&def.def.name);
        quote! {
            #doc
            ///
            /// A flag set: bits the XML does not list are kept, not dropped.
            #[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
            #user
            pub struct #name(pub #repr);

            impl #name {
                #( #entry_docs pub const #consts: Self = Self(#values); )*
            }

            #rt::flag_set!(#name, #repr, [#(#consts),*]);

            #serde
        }
    }
}
