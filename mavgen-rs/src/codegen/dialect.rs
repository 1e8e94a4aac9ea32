//! The dialect items of a root file: `Message`, `MessageView`, `MESSAGES`
//! and `Dialect`.

use super::{lit, serde_attr, Gen};
use crate::names::camel;
use crate::schema::MessageRef;
use proc_macro2::{Ident, Literal, TokenStream};
use quote::{format_ident, quote};
use std::collections::BTreeSet;

/// The dialect's messages sorted by id, as the pieces its items repeat.
struct Messages {
    /// The variant of `Message` and `MessageView`.
    variants: Vec<Ident>,
    /// The owned struct's path from the root module.
    paths: Vec<TokenStream>,
    /// The view's path from the root module.
    views: Vec<TokenStream>,
    ids: Vec<Literal>,
    /// The XML names.
    names: Vec<String>,
    /// The variants' docs.
    docs: Vec<String>,
}

impl Gen<'_> {
    pub(super) fn dialect(&self, root: usize) -> TokenStream {
        let msgs = self.dialect_messages(root);
        let enums = self.dialect_enums(root, &msgs);
        let table = self.dialect_table(&msgs);
        let message_impl = self.message_enum_impl(&msgs);
        let view_impl = self.view_enum_impl(&msgs);
        let (paths, variants) = (&msgs.paths, &msgs.variants);
        quote! {
            #enums
            #table
            #message_impl
            #view_impl

            #(
                impl From<#paths> for Message {
                    fn from(m: #paths) -> Self {
                        Self::#variants(m)
                    }
                }
            )*
        }
    }

    /// The selected messages of `root` and the files it includes.
    fn dialect_messages(&self, root: usize) -> Messages {
        let reach: BTreeSet<usize> = self.schema.reachable(root).into_iter().collect();
        let mut refs: Vec<MessageRef> = self
            .selected
            .iter()
            .copied()
            .filter(|r| reach.contains(&r.file))
            .collect();
        refs.sort_by_key(|&r| self.schema.message(r).id);
        let mut msgs = Messages {
            variants: Vec::new(),
            paths: Vec::new(),
            views: Vec::new(),
            ids: Vec::new(),
            names: Vec::new(),
            docs: Vec::new(),
        };
        for r in refs {
            let m = self.schema.message(r);
            let name = camel(&m.name);
            msgs.variants.push(format_ident!("{}", name));
            msgs.paths.push(self.path(root, r.file, &name));
            msgs.views
                .push(self.path(root, r.file, &format!("{name}View")));
            msgs.ids.push(lit(m.id));
            msgs.docs.push(format!(" `{}` (id {}).", m.name, m.id));
            msgs.names.push(m.name.clone());
        }
        msgs
    }

    /// The `Message` and `MessageView` enums.
    fn dialect_enums(&self, root: usize, msgs: &Messages) -> TokenStream {
        let fname = self.schema.files[root]
            .path
            .file_name()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        let enum_doc = format!(
            " Every message of the `{fname}` dialect ({} messages, its includes' too).",
            msgs.ids.len()
        );
        let view_doc = format!(" A zero-copy view of any message of the `{fname}` dialect.");
        // Externally tagged by XML name: `{"HEARTBEAT": {…}}`.
        let serde = self.serde_derive(quote!());
        let Messages {
            variants,
            paths,
            views,
            docs: vdocs,
            ..
        } = msgs;
        let renames = msgs
            .names
            .iter()
            .map(|name| serde_attr(&[quote!(rename = #name)]));
        quote! {
            #[doc = #enum_doc]
            #[derive(Debug, Clone, Copy, PartialEq)]
            #serde
            pub enum Message {
                #( #[doc = #vdocs] #renames #variants(#paths), )*
            }

            #[doc = #view_doc]
            #[derive(Debug, Clone, Copy)]
            pub enum MessageView<'a> {
                #( #[doc = #vdocs] #variants(#views<'a>), )*
            }
        }
    }

    /// `MESSAGES` and `Dialect`.
    fn dialect_table(&self, msgs: &Messages) -> TokenStream {
        let rt = &self.rt();
        let (paths, ids) = (&msgs.paths, &msgs.ids);
        let idx = (0..ids.len()).map(Literal::usize_unsuffixed);
        quote! {
            /// The dialect's table: id, name, CRC_EXTRA and lengths of every
            /// message, sorted by id.
            pub const MESSAGES: &[#rt::MessageMeta] = &[ #( #paths::META, )* ];

            /// This dialect, for code generic over dialects.
            #[derive(Debug, Clone, Copy, Default)]
            pub struct Dialect;

            impl #rt::MessageSet for Dialect {
                type Message = Message;
                type View<'a> = MessageView<'a>;
                const MESSAGES: &'static [#rt::MessageMeta] = MESSAGES;

                /// The table row of `id`, by a `match` (jump tables over the
                /// dense id ranges): the parser looks up every frame, and this
                /// is several times faster than the default binary search.
                #[inline]
                fn meta(id: u32) -> Option<&'static #rt::MessageMeta> {
                    Some(match id {
                        #( #ids => &MESSAGES[#idx], )*
                        _ => return None,
                    })
                }

                fn parse(id: u32, payload: &[u8]) -> Option<Message> {
                    Message::parse(id, payload)
                }

                fn view(id: u32, payload: &[u8]) -> Option<MessageView<'_>> {
                    MessageView::new(id, payload)
                }
            }
        }
    }

    /// The methods of `Message`, and `impl Encode` for it.
    fn message_enum_impl(&self, msgs: &Messages) -> TokenStream {
        let rt = &self.rt();
        let (variants, paths, ids) = (&msgs.variants, &msgs.paths, &msgs.ids);
        quote! {
            // `parse` picks a constructor and calls it, rather than building
            // the variant in each arm: LLVM merges the arms of a `match` that
            // all return the enum into one tail storing the whole enum (the
            // largest variant, 264 bytes in fbwag.xml) from a stack copy,
            // whatever the variant. Each constructor writes its variant's
            // fields straight into the caller's return slot instead: owned
            // decode of the benchmark capture ran 1.25x faster.
            impl Message {
                /// Reads the payload of message `id`; `None` when the dialect
                /// does not know `id`.
                pub fn parse(id: u32, payload: &[u8]) -> Option<Self> {
                    let parse: fn(&[u8]) -> Self = match id {
                        #( #ids => |p| Self::#variants(#paths::parse(p)), )*
                        _ => return None,
                    };
                    Some(parse(payload))
                }

                /// The message's table row.
                pub fn meta(&self) -> &'static #rt::MessageMeta {
                    match self {
                        #( Self::#variants(_) => &#paths::META, )*
                    }
                }

                /// The message id.
                pub fn id(&self) -> u32 {
                    self.meta().id
                }

                /// The message name in the XML.
                pub fn name(&self) -> &'static str {
                    self.meta().name
                }

                /// Writes the full payload; returns its length.
                pub fn emit(&self, payload: &mut [u8]) -> Result<usize, #rt::BufferTooSmall> {
                    match self {
                        #( Self::#variants(m) => m.emit(payload), )*
                    }
                }
            }

            /// The enum frames like any single message: `encode` and
            /// `Connection::send` take either.
            impl #rt::Encode for Message {
                #[inline]
                fn meta(&self) -> &'static #rt::MessageMeta {
                    Message::meta(self)
                }

                #[inline]
                fn emit_payload(&self, payload: &mut [u8]) -> Result<usize, #rt::BufferTooSmall> {
                    self.emit(payload)
                }
            }
        }
    }

    /// The methods of `MessageView`.
    fn view_enum_impl(&self, msgs: &Messages) -> TokenStream {
        let rt = &self.rt();
        let Messages {
            variants,
            paths,
            views,
            ids,
            ..
        } = msgs;
        quote! {
            impl<'a> MessageView<'a> {
                /// Views the payload of message `id`; `None` when the dialect
                /// does not know `id`.
                pub fn new(id: u32, payload: &'a [u8]) -> Option<Self> {
                    Some(match id {
                        #( #ids => Self::#variants(#views::new(payload)), )*
                        _ => return None,
                    })
                }

                /// The message's table row.
                pub fn meta(&self) -> &'static #rt::MessageMeta {
                    match self {
                        #( Self::#variants(_) => &#paths::META, )*
                    }
                }

                /// Copies the message out.
                pub fn to_message(&self) -> Message {
                    // A constructor called once, as in `Message::parse`: arms
                    // building the enum each would share one tail copying
                    // the largest variant.
                    type Parse = fn(&[u8]) -> Message;
                    let (parse, payload): (Parse, &[u8]) = match self {
                        #( Self::#variants(v) => (|p| Message::#variants(#paths::parse(p)), v.as_bytes()), )*
                    };
                    parse(payload)
                }
            }
        }
    }
}
