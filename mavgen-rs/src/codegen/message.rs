//! The items of one message: the owned struct with its constants, `parse`
//! and `emit`, the zero-copy view and the in-place writer.

use super::field::FieldKind;
use super::{docs, lit, Gen, DOC_WIDTH};
use crate::layout::Layout;
use crate::model::{Field, Message};
use crate::names::{self, camel, doc_lines, ident};
use proc_macro2::{Ident, TokenStream};
use quote::{format_ident, quote};

/// The names of a message's generated types, and the runtime's path
/// (parsed once per message, not per field).
struct Names {
    rt: TokenStream,
    /// `FooBar`, as text for docs.
    base: String,
    owned: Ident,
    view: Ident,
    writer: Ident,
}

/// What one field contributes to each of the message's items.
#[derive(Default)]
struct FieldParts {
    struct_fields: Vec<TokenStream>,
    getters: Vec<TokenStream>,
    setters: Vec<TokenStream>,
    from_view: Vec<TokenStream>,
    emit: Vec<TokenStream>,
    defaults: Vec<TokenStream>,
}

impl Gen<'_> {
    pub(super) fn message(&self, module: usize, m: &Message, layout: &Layout) -> TokenStream {
        let base = camel(&m.name);
        let names = Names {
            rt: self.rt(),
            owned: format_ident!("{}", base),
            view: format_ident!("{}View", base),
            writer: format_ident!("{}Mut", base),
            base,
        };
        let mut parts = FieldParts::default();
        for (fi, f) in m.fields.iter().enumerate() {
            self.field_parts(module, m, f, layout.offsets[fi], &names, &mut parts);
        }
        let owned = self.owned_items(m, layout, &names, &parts);
        let view = self.view_items(&names, &parts.getters);
        let writer = self.writer_items(&names, &parts.setters);
        quote!(#owned #view #writer)
    }

    /// Adds field `f` (at payload offset `offset`) to every item.
    fn field_parts(
        &self,
        module: usize,
        m: &Message,
        f: &Field,
        offset: usize,
        names: &Names,
        parts: &mut FieldParts,
    ) {
        let rt = &names.rt;
        let rust_name = names::field(&f.name);
        let fid = ident(&rust_name);
        let off = lit(offset as u64);
        let kind = self.kind(module, f);

        let fdoc = docs(&self.field_docs(module, f, offset));
        let serde = self.serde_field(f, &fid, &kind);
        let user = self.field_attrs(&m.name, &f.name);
        let owned_ty = kind.owned_type();
        parts
            .struct_fields
            .push(quote!(#fdoc #serde #user pub #fid: #owned_ty,));

        let base = &names.base;
        // rustdoc cannot resolve raw identifiers: link the struct instead.
        let target = if fid.to_string().starts_with("r#") {
            format!("struct@{base}")
        } else {
            format!("{base}::{fid}")
        };
        let get_doc = format!(
            " Reads [`{base}::{rust_name}`]({target}) (`{}` at offset {offset}).",
            f.name
        );
        let (get_ty, get_body) = (
            kind.view_type(rt),
            kind.read(rt, &quote!(self.payload), &off),
        );
        parts.getters.push(quote! {
            #[doc = #get_doc]
            #[inline]
            pub fn #fid(&self) -> #get_ty {
                #get_body
            }
        });

        let setter = format_ident!("set_{}", rust_name);
        let set_doc = format!(" Sets the `{}` field.", f.name);
        let set_ty = kind.setter_type();
        let set_body = kind.write(rt, &quote!(self.payload), &quote!(value), &off);
        parts.setters.push(quote! {
            #[doc = #set_doc]
            #[inline]
            pub fn #setter(&mut self, value: #set_ty) {
                #set_body
            }
        });

        let read = kind.read_owned(rt, &quote!(p), &off);
        parts.from_view.push(quote!(#fid: #read,));
        let value = if kind.by_ref() {
            quote!(&self.#fid)
        } else {
            quote!(self.#fid)
        };
        let write = kind.write(rt, &quote!(out), &value, &off);
        parts.emit.push(quote!(#write;));
        let default = kind.default_value();
        parts.defaults.push(quote!(#fid: #default,));
    }

    /// The serde arguments of a message field: its XML name, and the form
    /// of its values.
    fn serde_field(&self, f: &Field, fid: &Ident, kind: &FieldKind) -> TokenStream {
        let mut args = Vec::new();
        let rust = fid.to_string();
        // serde names a raw identifier without its `r#` itself.
        if rust.strip_prefix("r#").unwrap_or(&rust) != f.name {
            let name = &f.name;
            args.push(quote!(rename = #name));
        }
        args.extend(kind.serde_with(|item| self.rt_path(item)));
        super::serde_attr(&args)
    }

    fn message_docs(m: &Message, layout: &Layout) -> TokenStream {
        let mut mdoc = doc_lines(&m.description, DOC_WIDTH);
        if mdoc.is_empty() {
            mdoc.push(format!("`{}`", m.name));
        }
        mdoc.push(String::new());
        mdoc.push(format!(
            "MAVLink message `{}`: id {}, CRC_EXTRA {}, payload {} bytes ({} without extensions).",
            m.name, m.id, layout.crc_extra, layout.max_len, layout.min_len
        ));
        if m.wip {
            mdoc.push("**Work in progress**: may change.".into());
        }
        if let Some(d) = &m.deprecated {
            mdoc.extend(doc_lines(&super::deprecated_note(d), DOC_WIDTH));
        }
        docs(&mdoc)
    }

    /// The owned struct, its `Default` and `impl Message`.
    fn owned_items(
        &self,
        m: &Message,
        layout: &Layout,
        names: &Names,
        parts: &FieldParts,
    ) -> TokenStream {
        let owned = &names.owned;
        let mdoc = Self::message_docs(m, layout);
        // Messages are plain wire data, so `Copy` (which also makes the
        // derived `Clone` a plain copy instead of a clone per field: 5 % of
        // the full dialect's compile time). `Default` derives for arrays up
        // to 32 elements only; the version field defaults to the dialect
        // version, not 0.
        let derive_default = m
            .fields
            .iter()
            .all(|f| !f.mavlink_version && f.array_len.is_none_or(|n| n <= 32));
        let (derives, default_impl) = if derive_default {
            (
                quote!(#[derive(Debug, Clone, Copy, PartialEq, Default)]),
                quote!(),
            )
        } else {
            let defaults = &parts.defaults;
            (
                quote!(#[derive(Debug, Clone, Copy, PartialEq)]),
                quote! {
                    impl Default for #owned {
                        fn default() -> Self {
                            Self { #(#defaults)* }
                        }
                    }
                },
            )
        };
        // Fields left out read as the Default (as extension fields do on
        // the wire); unknown ones are refused, so a misspelt key cannot
        // silently send a zero.
        let serde = self.serde_derive(quote!(, default, deny_unknown_fields));
        let user = self.type_attrs(&m.name);
        let struct_fields = &parts.struct_fields;
        let inherent = self.owned_impl(m, layout, names, parts);
        let message_impl = self.message_impl(names);
        quote! {
            #mdoc
            #derives
            #serde
            #user
            pub struct #owned {
                #(#struct_fields)*
            }

            #inherent

            #default_impl

            #message_impl
        }
    }

    /// The table row of the message (`META`).
    fn message_meta(&self, m: &Message, layout: &Layout) -> TokenStream {
        let rt = &self.rt();
        let opt = |o: Option<usize>| match o {
            Some(v) => {
                let v = lit(v as u64);
                quote!(Some(#v))
            }
            None => quote!(None),
        };
        let (ts, tc) = (opt(layout.target_system), opt(layout.target_component));
        let field_metas = layout.order.iter().map(|&i| {
            let f = &m.fields[i];
            let (fname, ty) = (
                f.name.as_str(),
                format_ident!("{}", f.primitive.field_type()),
            );
            let (n, off, ext) = (
                lit(f.array_len.unwrap_or(0) as u64),
                lit(layout.offsets[i] as u64),
                f.extension,
            );
            quote!(#rt::FieldMeta::new(#fname, #rt::FieldType::#ty, #n, #off, #ext))
        });
        // The runtime's constructors: its rows may gain fields.
        let targets = if layout.target_system.is_some() || layout.target_component.is_some() {
            quote!(.with_target_offsets(#ts, #tc))
        } else {
            quote!()
        };
        quote! {
            /// This message's row of the dialect table.
            pub const META: #rt::MessageMeta = #rt::MessageMeta::new(
                Self::ID,
                Self::NAME,
                Self::CRC_EXTRA,
                Self::MIN_LEN as u8,
                Self::MAX_LEN as u8,
                &[ #(#field_metas),* ],
            )#targets;
        }
    }

    /// The owned struct's constants, `parse`, `from_view` and `emit`.
    fn owned_impl(
        &self,
        m: &Message,
        layout: &Layout,
        names: &Names,
        parts: &FieldParts,
    ) -> TokenStream {
        let rt = &names.rt;
        let (owned, view) = (&names.owned, &names.view);
        let (id, name, crc, min, max) = (
            lit(m.id),
            m.name.as_str(),
            lit(layout.crc_extra),
            lit(layout.min_len as u64),
            lit(layout.max_len as u64),
        );
        let meta = self.message_meta(m, layout);
        let (from_view, emit) = (&parts.from_view, &parts.emit);
        quote! {
            impl #owned {
                /// Message id.
                pub const ID: u32 = #id;
                /// Message name in the XML.
                pub const NAME: &'static str = #name;
                /// CRC_EXTRA seed of the frame checksum.
                pub const CRC_EXTRA: u8 = #crc;
                /// Payload length without extension fields.
                pub const MIN_LEN: usize = #min;
                /// Payload length with all extension fields.
                pub const MAX_LEN: usize = #max;
                #meta

                /// Reads a payload of any length (missing bytes read as zero).
                pub fn parse(payload: &[u8]) -> Self {
                    // Fields are read from one fixed-size copy (zero-filled if
                    // the payload was truncated): constant offsets, no
                    // per-field bounds checks or truncation paths to compile.
                    let p: &[u8; Self::MAX_LEN] = &#rt::field::padded(payload);
                    Self { #(#from_view)* }
                }

                /// Copies every field out of a view.
                #[inline]
                pub fn from_view(view: &#view<'_>) -> Self {
                    Self::parse(view.as_bytes())
                }

                /// Writes all [`Self::MAX_LEN`] payload bytes at the start of
                /// `payload`; returns that length.
                pub fn emit(&self, payload: &mut [u8]) -> Result<usize, #rt::BufferTooSmall> {
                    let out = #rt::field::prefix_mut::<{ Self::MAX_LEN }>(payload)?;
                    #(#emit)*
                    Ok(Self::MAX_LEN)
                }
            }
        }
    }

    /// `impl mavframe::MessageData` for the owned struct.
    fn message_impl(&self, names: &Names) -> TokenStream {
        let rt = &names.rt;
        let (owned, view) = (&names.owned, &names.view);
        quote! {
            impl #rt::MessageData for #owned {
                const META: #rt::MessageMeta = #owned::META;
                type View<'a> = #view<'a>;

                #[inline]
                fn parse(payload: &[u8]) -> Self {
                    #owned::parse(payload)
                }

                #[inline]
                fn emit(&self, payload: &mut [u8]) -> Result<usize, #rt::BufferTooSmall> {
                    #owned::emit(self, payload)
                }

                #[inline]
                fn view(payload: &[u8]) -> #view<'_> {
                    #view::new(payload)
                }
            }
        }
    }

    /// The zero-copy view and its accessors.
    fn view_items(&self, names: &Names, getters: &[TokenStream]) -> TokenStream {
        let (base, owned, view) = (&names.base, &names.owned, &names.view);
        // `struct@`: a message may be named like a prelude item (DEBUG).
        let view_doc = format!(" A zero-copy view over a [`{base}`](struct@{base}) payload: fields are read in place at their wire offsets.");
        quote! {
            #[doc = #view_doc]
            ///
            /// Any slice length is accepted and no accessor panics: bytes past
            /// the end of a truncated payload read as zero.
            #[derive(Debug, Clone, Copy)]
            pub struct #view<'a> {
                payload: &'a [u8],
            }

            impl<'a> #view<'a> {
                /// Views `payload` (any length).
                #[inline]
                pub const fn new(payload: &'a [u8]) -> Self {
                    Self { payload }
                }

                /// The payload bytes this view reads.
                #[inline]
                pub const fn as_bytes(&self) -> &'a [u8] {
                    self.payload
                }

                /// Copies every field out.
                #[inline]
                pub fn to_message(&self) -> #owned {
                    #owned::from_view(self)
                }

                #(#getters)*
            }
        }
    }

    /// The in-place writer and its setters.
    fn writer_items(&self, names: &Names, setters: &[TokenStream]) -> TokenStream {
        let rt = &names.rt;
        let (base, owned, view, writer) = (&names.base, &names.owned, &names.view, &names.writer);
        let mut_doc =
            format!(" Writes the fields of a [`{base}`](struct@{base}) payload in place.");
        let new_doc = format!(" A writer over `payload`, which must hold at least [`{base}::MAX_LEN`](struct@{base}) bytes.");
        quote! {
            #[doc = #mut_doc]
            #[derive(Debug)]
            pub struct #writer<'a> {
                payload: &'a mut [u8],
            }

            impl<'a> #writer<'a> {
                #[doc = #new_doc]
                pub fn new(payload: &'a mut [u8]) -> Result<Self, #rt::BufferTooSmall> {
                    if payload.len() < #owned::MAX_LEN {
                        return Err(#rt::BufferTooSmall { needed: #owned::MAX_LEN, got: payload.len() });
                    }
                    Ok(Self { payload })
                }

                /// A view of the fields written so far.
                pub fn view(&self) -> #view<'_> {
                    #view::new(self.payload)
                }

                #(#setters)*
            }
        }
    }

    fn field_docs(&self, module: usize, f: &Field, layout_offset: usize) -> Vec<String> {
        let mut lines = doc_lines(&f.description, DOC_WIDTH);
        if lines.is_empty() {
            lines.push(format!("`{}`", f.name));
        }
        let mut facts = Vec::new();
        if names::field(&f.name) != f.name {
            facts.push(format!("XML name: `{}`.", f.name));
        }
        if let Some(u) = &f.units {
            facts.push(format!("Units: `{u}`."));
        }
        if let Some(m) = &f.multiplier {
            facts.push(format!("Multiplier: `{m}`."));
        }
        if let Some(e) = &f.enum_name {
            match self.enums.get(e) {
                Some(info) => {
                    let path = self.doc_path(module, info.module, &info.rust_name);
                    facts.push(format!("Values: [`{}`](struct@{path}).", info.rust_name));
                }
                None => facts.push(format!("Values: `{e}`.")),
            }
        }
        if let Some(v) = &f.invalid {
            facts.push(format!("Invalid / unknown: `{v}`."));
        }
        if let Some(v) = &f.default {
            facts.push(format!("Default: `{v}`."));
        }
        if f.instance {
            facts.push("Instance field: tells apart several sources of this message.".into());
        }
        if f.mavlink_version {
            facts.push("Set to the dialect's MAVLink version by `Default`.".into());
        }
        if f.extension {
            facts.push(
                "Extension field: absent from MAVLink 1 frames, reads 0 when not sent.".into(),
            );
        }
        facts.push(format!(
            "Wire: `{}{}` at payload offset {layout_offset}.",
            f.primitive.c_name(),
            f.array_len.map_or(String::new(), |n| format!("[{n}]"))
        ));
        lines.push(String::new());
        lines.extend(doc_lines(&facts.join(" "), DOC_WIDTH).into_iter().map(|l| {
            l.replace("\\`", "`")
                .replace("\\[", "[")
                .replace("\\]", "]")
                .replace("\\_", "_")
        }));
        lines
    }
}
