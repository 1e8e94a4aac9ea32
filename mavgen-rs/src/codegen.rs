//! Turns a checked [`Schema`] into Rust source: one module per XML file and a
//! `mod.rs` that includes them.
//!
//! Items are built as token streams with `quote` and printed with
//! `prettyplease`, so the output is deterministic and reads like hand-written
//! code.

use crate::diag::{Diagnostic, Severity};
use crate::layout::Layout;
use crate::model::{Entry, Field, Message, Primitive};
use crate::names::{self, camel, doc_lines, doc_list_item, entry_suffix, ident, snake};
use crate::schema::{MergedEnum, MessageRef, Schema};
use proc_macro2::{Literal, TokenStream};
use quote::{format_ident, quote};
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt::Write as _;

const DOC_WIDTH: usize = 90;

/// Methods every message view has besides its field accessors.
const VIEW_METHODS: &[&str] = &["new", "as_bytes", "to_message"];

/// Code generation settings (see [`crate::Config`] for the builder).
#[derive(Debug, Clone)]
pub struct Options {
    /// Path of the runtime crate in the generated code, e.g. `::mavframe`.
    pub runtime: String,
    /// Generate only these messages (and the enums they use).
    pub messages: Option<BTreeSet<String>>,
    /// Shown in each file's header as the command that regenerates it.
    pub regenerate_hint: Option<String>,
    /// `(pattern, attributes)` added to messages and enums: pattern `.` for
    /// every one, or an XML message or enum name (see
    /// [`crate::Config::type_attribute`]).
    pub type_attributes: Vec<(String, String)>,
    /// `(pattern, attributes)` added to message fields: `.`, an XML message
    /// name (its every field) or `MESSAGE.field` (see
    /// [`crate::Config::field_attribute`]).
    pub field_attributes: Vec<(String, String)>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            runtime: "::mavframe".into(),
            messages: None,
            regenerate_hint: None,
            type_attributes: Vec::new(),
            field_attributes: Vec::new(),
        }
    }
}

/// The feature of the including crate that turns the serde impls on.
const SERDE_FEATURE: &str = "serde";

/// Generated files: `(file name, contents)`, `mod.rs` first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Output {
    /// The files, in a stable order.
    pub files: Vec<(String, String)>,
    /// Enums generated (all of the schema's, or those the selected
    /// messages use).
    pub enums: usize,
}

/// How a field is represented in Rust.
enum Kind {
    Scalar(Primitive),
    /// An unsigned scalar carrying an enum's value.
    Enum {
        prim: Primitive,
        path: TokenStream,
        repr: Primitive,
        bitmask: bool,
    },
    Array(Primitive, usize),
    Chars(usize),
}

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
struct EnumInfo {
    module: usize,
    rust_name: String,
    repr: Primitive,
    bitmask: bool,
}

struct Gen<'s> {
    schema: &'s Schema,
    /// The runtime crate path; a string because token types are not
    /// `Send`, and workers build their own tokens.
    rt: String,
    modules: Vec<String>,
    selected: BTreeSet<MessageRef>,
    enums: BTreeMap<String, EnumInfo>,
    /// The user's attributes, as in [`Options`] (checked to parse).
    type_attributes: &'s [(String, String)],
    field_attributes: &'s [(String, String)],
}

/// Generates the Rust modules for `schema`.
pub fn generate(schema: &Schema, opts: &Options) -> Result<Output, Vec<Diagnostic>> {
    let mut errors = Vec::new();
    let err = |errors: &mut Vec<Diagnostic>, position, message: String| {
        errors.push(Diagnostic {
            severity: Severity::Error,
            position,
            message,
        })
    };
    let rt = match syn::parse_str::<syn::Path>(&opts.runtime) {
        Ok(p) => quote!(#p).to_string().replace(' ', ""),
        Err(e) => {
            err(
                &mut errors,
                None,
                format!(
                    "runtime crate path `{}` is not a Rust path: {e}",
                    opts.runtime
                ),
            );
            return Err(errors);
        }
    };

    // One module per file, named after the file.
    let mut modules = Vec::new();
    let mut module_files: HashMap<String, usize> = HashMap::new();
    for (i, f) in schema.files.iter().enumerate() {
        let stem = f
            .path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        let name = snake(&stem);
        if let Some(&other) = module_files.get(&name) {
            err(
                &mut errors,
                None,
                format!(
                    "{} and {} would both become module `{name}`",
                    schema.files[other].path.display(),
                    f.path.display()
                ),
            );
        }
        module_files.insert(name.clone(), i);
        modules.push(name);
    }

    // The messages to generate.
    let all: Vec<MessageRef> = schema.message_refs().collect();
    let selected: BTreeSet<MessageRef> = match &opts.messages {
        None => all.iter().copied().collect(),
        Some(names) => {
            let by_name: HashMap<&str, MessageRef> = all
                .iter()
                .map(|&r| (schema.message(r).name.as_str(), r))
                .collect();
            let mut sel = BTreeSet::new();
            for n in names {
                match by_name.get(n.as_str()) {
                    Some(&r) => {
                        sel.insert(r);
                    }
                    None => err(
                        &mut errors,
                        None,
                        format!("message filter names {n}, which the dialect does not define"),
                    ),
                }
            }
            sel
        }
    };

    // Enums: all of them, or those the selected messages use.
    let used: BTreeSet<&str> = selected
        .iter()
        .flat_map(|&r| schema.message(r).fields.iter())
        .filter_map(|f| f.enum_name.as_deref())
        .collect();
    let mut enums = BTreeMap::new();
    for (name, m) in &schema.enums {
        if opts.messages.is_some() && !used.contains(name.as_str()) {
            continue;
        }
        enums.insert(name.clone(), enum_info(schema, name, m));
    }

    for (pattern, attrs) in opts.type_attributes.iter().chain(&opts.field_attributes) {
        if let Err(e) = parse_attributes(attrs) {
            err(
                &mut errors,
                None,
                format!("attribute `{attrs}` for `{pattern}` does not parse: {e}"),
            );
        }
    }
    let gen = Gen {
        schema,
        rt,
        modules,
        selected,
        enums,
        type_attributes: &opts.type_attributes,
        field_attributes: &opts.field_attributes,
    };
    errors.extend(gen.check_names());
    if !errors.is_empty() {
        return Err(errors);
    }

    let header = |file: &str| {
        let mut h = String::new();
        let _ = writeln!(
            h,
            "// @generated by mavgen-rs {} from {file}. Do not edit.",
            env!("CARGO_PKG_VERSION")
        );
        if let Some(hint) = &opts.regenerate_hint {
            let _ = writeln!(h, "// Regenerate with: {hint}");
        }
        h.push('\n');
        h
    };
    // Work units of a few items each, rendered on every core (syn's
    // parse and prettyplease dominate the run time) and joined in order.
    let mut jobs: Vec<(usize, Vec<Item>)> = Vec::new();
    for i in 0..schema.files.len() {
        let items = gen.module_items(i);
        if items.is_empty() {
            jobs.push((i, Vec::new()));
        }
        for chunk in items.chunks(CHUNK_ITEMS) {
            jobs.push((i, chunk.to_vec()));
        }
    }
    let rendered = parallel_map(&jobs, |(i, items)| gen.render(*i, items));
    let mut bodies = vec![String::new(); schema.files.len()];
    for ((i, _), r) in jobs.iter().zip(rendered) {
        match r {
            Ok(text) => {
                if !bodies[*i].is_empty() {
                    bodies[*i].push('\n');
                }
                bodies[*i].push_str(&text);
            }
            Err(e) => {
                err(
                    &mut errors,
                    None,
                    format!("internal error: generated code does not parse: {e}"),
                );
                return Err(errors);
            }
        }
    }

    let mut files = Vec::new();
    let mut mod_rs = header("the files below");
    // A crate including these files declares the feature the serde impls
    // are under; rustc's check-cfg warns at every use otherwise (item-level
    // `allow(unexpected_cfgs)` does not reach `cfg_attr`).
    let _ = writeln!(
        mod_rs,
        "// Serialize and Deserialize are implemented under `#[cfg(feature = \"{SERDE_FEATURE}\")]`:\n\
         // the crate including these files declares a `{SERDE_FEATURE}` feature that enables the\n\
         // runtime's (`{SERDE_FEATURE} = [\"mavframe/serde\"]`), even if it never turns it on.\n"
    );
    for (i, f) in schema.files.iter().enumerate() {
        let fname = f
            .path
            .file_name()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        let mut text = header(&fname);
        text.push_str(&bodies[i]);
        let module = &gen.modules[i];
        let mut doc = format!("Definitions of `{fname}`");
        if schema.roots.contains(&i) {
            doc.push_str(" (a dialect: see [`");
            doc.push_str(module);
            doc.push_str("::Message`])");
        }
        let _ = writeln!(mod_rs, "#[doc = {:?}]", doc + ".");
        mod_rs.push_str("#[allow(clippy::enum_variant_names, clippy::large_enum_variant, clippy::len_without_is_empty)]\n");
        let _ = writeln!(
            mod_rs,
            "pub mod {module} {{\n    include!(\"{module}.rs\");\n}}"
        );
        files.push((format!("{module}.rs"), text));
    }
    files.insert(0, ("mod.rs".to_string(), mod_rs));
    Ok(Output {
        files,
        enums: gen.enums.len(),
    })
}

/// Items per rendering job. Small jobs balance the cores, and keep syn's
/// token buffer and prettyplease's buffers (megabytes for 48 messages) in
/// cache and their memory reused: all.xml takes 15 % less CPU time than with
/// 48 items per job; below 8, the per-job overhead shows.
const CHUNK_ITEMS: usize = 8;

/// One top-level item to render.
#[derive(Debug, Clone)]
enum Item {
    Enum(String),
    Message(MessageRef),
    Dialect,
}

/// `f` over `jobs` on all cores, results in job order.
fn parallel_map<J: Sync, R: Send>(jobs: &[J], f: impl Fn(&J) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(jobs.len().max(1));
    let next = std::sync::atomic::AtomicUsize::new(0);
    let mut results: Vec<(usize, R)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let k = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(job) = jobs.get(k) else { break };
                        done.push((k, f(job)));
                    }
                    done
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("render worker panicked"))
            .collect()
    });
    results.sort_by_key(|(k, _)| *k);
    results.into_iter().map(|(_, r)| r).collect()
}

/// `tokens` with every identifier `name` replaced by `with`.
fn substitute(tokens: &TokenStream, name: &str, with: &TokenStream) -> TokenStream {
    use proc_macro2::{Group, TokenTree};
    tokens
        .clone()
        .into_iter()
        .flat_map(|tt| match tt {
            TokenTree::Ident(ref i) if i == name => with.clone(),
            TokenTree::Group(g) => {
                let mut inner = Group::new(g.delimiter(), substitute(&g.stream(), name, with));
                inner.set_span(g.span());
                TokenTree::Group(inner).into()
            }
            other => other.into(),
        })
        .collect()
}

/// Puts a blank line after every item that ends at the top level or at the
/// first indentation level (methods), which prettyplease leaves packed.
fn space_items(code: &str) -> String {
    let mut out = String::with_capacity(code.len() + code.len() / 20);
    let mut prev = "";
    for line in code.lines() {
        // A top-level macro call (`flag_set!(…);`) ends an item too.
        let closes_item = prev == "}"
            || prev == "    }"
            || prev == "};"
            || prev == "    };"
            || prev == ");"
            || (!prev.starts_with(' ') && prev.contains("!(") && prev.ends_with(");"));
        let same_level = if prev == "    }" || prev == "    };" {
            line.starts_with("    ") && !line.starts_with("    }")
        } else {
            !line.is_empty()
        };
        if closes_item && same_level && !line.starts_with('}') {
            out.push('\n');
        }
        out.push_str(line);
        out.push('\n');
        prev = line;
    }
    out
}

/// Chooses an enum's Rust representation: wide enough for its values and for
/// every unsigned field that carries it, so conversions never lose bits.
fn enum_info(schema: &Schema, name: &str, m: &MergedEnum) -> EnumInfo {
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

/// Parses attribute text such as `#[derive(Hash)] #[serde(rename_all = "lowercase")]`:
/// one or more outer attributes.
pub(crate) fn parse_attributes(text: &str) -> Result<Vec<syn::Attribute>, String> {
    use syn::parse::Parser as _;
    let attrs = syn::Attribute::parse_outer
        .parse_str(text)
        .map_err(|e| e.to_string())?;
    if attrs.is_empty() {
        return Err("expected one or more attributes such as `#[derive(Hash)]`".into());
    }
    Ok(attrs)
}

/// The attributes of `list` whose pattern `matches`, as tokens.
fn user_attributes(list: &[(String, String)], matches: impl Fn(&str) -> bool) -> TokenStream {
    list.iter()
        .filter(|(pattern, _)| matches(pattern))
        .filter_map(|(_, attrs)| parse_attributes(attrs).ok())
        .flatten()
        .map(|a| quote!(#a))
        .collect()
}

/// `#[cfg_attr(feature = "serde", serde(…))]` for `args`, nothing for none.
fn serde_attr(args: &[TokenStream]) -> TokenStream {
    if args.is_empty() {
        return quote!();
    }
    quote!(#[cfg_attr(feature = #SERDE_FEATURE, serde(#(#args),*))])
}

/// An integer literal without a type suffix (the context gives the type).
fn lit(value: impl Into<u64>) -> Literal {
    Literal::u64_unsuffixed(value.into())
}

/// `0` or `0.0`, as the type needs.
fn zero(p: Primitive) -> TokenStream {
    if matches!(p, Primitive::F32 | Primitive::F64) {
        quote!(0.0)
    } else {
        quote!(0)
    }
}

fn docs(lines: &[String]) -> TokenStream {
    let attrs = lines.iter().map(|l| {
        let l = format!(" {l}");
        quote!(#[doc = #l])
    });
    quote!(#(#attrs)*)
}

fn deprecated_note(d: &crate::model::Deprecated) -> String {
    let mut s = format!("**Deprecated** since {}", d.since);
    if !d.replaced_by.is_empty() {
        s.push_str(&format!(", replaced by `{}`", d.replaced_by));
    }
    s.push('.');
    let t = d.text.split_whitespace().collect::<Vec<_>>().join(" ");
    if !t.is_empty() {
        s.push(' ');
        s.push_str(&t);
    }
    s
}

impl Gen<'_> {
    fn check_names(&self) -> Vec<Diagnostic> {
        let mut out = Vec::new();
        for (i, _) in self.schema.files.iter().enumerate() {
            let mut taken: HashMap<String, String> = HashMap::new();
            if self.schema.roots.contains(&i) {
                for n in ["Message", "MessageView", "Dialect", "MESSAGES"] {
                    taken.insert(n.into(), "the dialect's own items".into());
                }
            }
            for r in self.selected.iter().filter(|r| r.file == i) {
                let m = self.schema.message(*r);
                let mut seen: HashMap<String, &str> = HashMap::new();
                for f in &m.fields {
                    // Compare escaped identifiers: `self` becomes `self_`.
                    let rust = ident(&names::field(&f.name)).to_string();
                    if let Some(prev) = seen.insert(rust.clone(), &f.name) {
                        out.push(Diagnostic {
                            severity: Severity::Error,
                            position: Some(self.schema.sources[f.loc.file].position(f.loc.offset)),
                            message: format!(
                                "fields {}.{prev} and {} would both be `{rust}` in Rust",
                                m.name, f.name
                            ),
                        });
                    }
                    if VIEW_METHODS.contains(&rust.as_str()) {
                        out.push(Diagnostic {
                            severity: Severity::Error,
                            position: Some(self.schema.sources[f.loc.file].position(f.loc.offset)),
                            message: format!(
                                "field {}.{} would clash with the view method `{}`",
                                m.name, f.name, f.name
                            ),
                        });
                    }
                }
            }
            let mut claim = |rust: String, what: String, loc: crate::diag::Loc| {
                if let Some(prev) = taken.get(&rust) {
                    out.push(Diagnostic {
                        severity: Severity::Error,
                        position: Some(self.schema.sources[loc.file].position(loc.offset)),
                        message: format!(
                            "{what} would be named `{rust}` in Rust, which {prev} already uses"
                        ),
                    });
                } else {
                    taken.insert(rust, what);
                }
            };
            for r in self.selected.iter().filter(|r| r.file == i) {
                let m = self.schema.message(*r);
                let base = camel(&m.name);
                for suffix in ["", "View", "Mut"] {
                    claim(
                        format!("{base}{suffix}"),
                        format!("message {}", m.name),
                        m.loc,
                    );
                }
            }
            for (name, info) in self.enums.iter().filter(|(_, e)| e.module == i) {
                let loc = self.schema.enums[name].def.loc;
                claim(info.rust_name.clone(), format!("enum {name}"), loc);
            }
        }
        out
    }

    /// Path from module `from` to item `name` of module `to`.
    fn path(&self, from: usize, to: usize, name: &str) -> TokenStream {
        let item = format_ident!("{}", name);
        if from == to {
            quote!(#item)
        } else {
            let m = ident(&self.modules[to]);
            quote!(super::#m::#item)
        }
    }

    fn doc_path(&self, from: usize, to: usize, name: &str) -> String {
        if from == to {
            name.to_string()
        } else {
            format!("super::{}::{name}", self.modules[to])
        }
    }

    fn kind(&self, module: usize, f: &Field) -> Kind {
        match (f.array_len, f.primitive) {
            (Some(n), Primitive::Char) => Kind::Chars(n),
            (Some(n), p) => Kind::Array(p, n),
            (None, p) => match f.enum_name.as_deref().and_then(|e| self.enums.get(e)) {
                Some(info) if p.is_unsigned_int() && !f.mavlink_version => Kind::Enum {
                    prim: p,
                    path: self.path(module, info.module, &info.rust_name),
                    repr: info.repr,
                    bitmask: info.bitmask,
                },
                _ => Kind::Scalar(p),
            },
        }
    }

    fn rt(&self) -> TokenStream {
        self.rt.parse().expect("runtime path checked in generate()")
    }

    /// The path of a runtime item as a string, for serde's attributes.
    fn rt_path(&self, item: &str) -> String {
        format!("{}::{item}", self.rt)
    }

    /// Derives serde's traits for a message or the dialect enum; `extra`
    /// are further `serde(…)` container arguments.
    fn serde_derive(&self, extra: TokenStream) -> TokenStream {
        let rt = self.rt();
        let krate = self.rt_path("serde");
        quote! {
            #[cfg_attr(
                feature = #SERDE_FEATURE,
                derive(#rt::serde::Serialize, #rt::serde::Deserialize),
                serde(crate = #krate #extra)
            )]
        }
    }

    /// The user's attributes for the message or enum `xml_name`.
    fn type_attrs(&self, xml_name: &str) -> TokenStream {
        user_attributes(self.type_attributes, |p| p == "." || p == xml_name)
    }

    /// The user's attributes for field `field` of message `message`.
    fn field_attrs(&self, message: &str, field: &str) -> TokenStream {
        user_attributes(self.field_attributes, |p| {
            p == "."
                || p == message
                || p.split_once('.')
                    .is_some_and(|(m, f)| m == message && f == field)
        })
    }

    /// The serde arguments of a message field: its XML name, and the form
    /// of its values (see `mavframe::serde`).
    fn serde_field(&self, f: &Field, fid: &proc_macro2::Ident, kind: &Kind) -> TokenStream {
        let mut args = Vec::new();
        let rust = fid.to_string();
        // serde names a raw identifier without its `r#` itself.
        if rust.strip_prefix("r#").unwrap_or(&rust) != f.name {
            let name = &f.name;
            args.push(quote!(rename = #name));
        }
        let with = |module: &str| {
            let path = self.rt_path(&format!("serde::{module}"));
            quote!(with = #path)
        };
        match kind {
            Kind::Scalar(Primitive::F32 | Primitive::F64) => args.push(with("float")),
            Kind::Scalar(_) => {}
            Kind::Array(..) => args.push(with("array")),
            Kind::Chars(_) => args.push(with("chars")),
            Kind::Enum { prim, repr, .. } if prim != repr => {
                let path = format!(
                    "{}::<_, _, {}, {}>",
                    self.rt_path("serde::narrow"),
                    repr.rust_name(),
                    prim.rust_name()
                );
                args.push(quote!(deserialize_with = #path));
            }
            Kind::Enum { .. } => {}
        }
        serde_attr(&args)
    }

    /// The module's items, in output order.
    fn module_items(&self, i: usize) -> Vec<Item> {
        let mut items = Vec::new();
        for (name, _) in self.enums.iter().filter(|(_, e)| e.module == i) {
            items.push(Item::Enum(name.clone()));
        }
        items.extend(
            self.selected
                .iter()
                .filter(|r| r.file == i)
                .map(|&r| Item::Message(r)),
        );
        if self.schema.roots.contains(&i) {
            items.push(Item::Dialect);
        }
        items
    }

    /// Renders items of module `i` to formatted Rust.
    fn render(&self, i: usize, items: &[Item]) -> Result<String, String> {
        let tokens: Vec<TokenStream> = items
            .iter()
            .map(|item| match item {
                Item::Enum(name) => {
                    let (def, info) = (&self.schema.enums[name], &self.enums[name]);
                    if info.bitmask {
                        self.flag_set(def, info)
                    } else {
                        self.value_enum(def, info)
                    }
                }
                Item::Message(r) => {
                    self.message(i, self.schema.message(*r), self.schema.layout(*r))
                }
                Item::Dialect => self.dialect(i),
            })
            .collect();
        let file: syn::File = syn::parse2(quote!(#(#tokens)*)).map_err(|e| e.to_string())?;
        Ok(space_items(&prettyplease::unparse(&file)))
    }

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
            lines.extend(doc_lines(&deprecated_note(d), DOC_WIDTH));
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
            lines.extend(doc_lines(&deprecated_note(d), DOC_WIDTH));
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
    fn value_enum(&self, def: &MergedEnum, info: &EnumInfo) -> TokenStream {
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
    fn flag_set(&self, def: &MergedEnum, info: &EnumInfo) -> TokenStream {
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

    fn message(&self, module: usize, m: &Message, layout: &Layout) -> TokenStream {
        let rt = self.rt();
        let rt = &rt;
        let base = camel(&m.name);
        let owned = format_ident!("{}", base);
        let view = format_ident!("{}View", base);
        let writer = format_ident!("{}Mut", base);
        let (id, name, crc, min, max) = (
            lit(m.id),
            m.name.as_str(),
            lit(layout.crc_extra),
            lit(layout.min_len as u64),
            lit(layout.max_len as u64),
        );
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
            let (fname, ty) = (f.name.as_str(), format_ident!("{}", f.primitive.field_type()));
            let (n, off, ext) = (lit(f.array_len.unwrap_or(0) as u64), lit(layout.offsets[i] as u64), f.extension);
            quote!(#rt::FieldMeta { name: #fname, ty: #rt::FieldType::#ty, array_len: #n, offset: #off, extension: #ext })
        });

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
            mdoc.extend(doc_lines(&deprecated_note(d), DOC_WIDTH));
        }
        let mdoc = docs(&mdoc);
        // `struct@`: a message may be named like a prelude item (DEBUG).
        let view_doc = format!(" A zero-copy view over a [`{base}`](struct@{base}) payload: fields are read in place at their wire offsets.");
        let mut_doc =
            format!(" Writes the fields of a [`{base}`](struct@{base}) payload in place.");
        let new_doc = format!(" A writer over `payload`, which must hold at least [`{base}::MAX_LEN`](struct@{base}) bytes.");

        let mut struct_fields = Vec::new();
        let mut getters = Vec::new();
        let mut setters = Vec::new();
        let mut from_view = Vec::new();
        let mut emit = Vec::new();
        let mut defaults = Vec::new();
        for (fi, f) in m.fields.iter().enumerate() {
            let rust_name = names::field(&f.name);
            let fid = ident(&rust_name);
            let setter = format_ident!("set_{}", rust_name);
            let fdoc = docs(&self.field_docs(module, f, layout.offsets[fi]));
            let off = lit(layout.offsets[fi] as u64);
            let kind = self.kind(module, f);
            // Templates over `__src` (the bytes read), `__dst` (the bytes
            // written) and `__value`: the accessors use them on the view's
            // slice, `parse` and `emit` on a fixed-size array.
            let (owned_ty, get_ty, get_tpl, set_ty, set_tpl, default, to_owned, by_ref) =
                match &kind {
                    Kind::Scalar(p) => {
                        let t = format_ident!("{}", p.rust_name());
                        let default = if f.mavlink_version {
                            let v = lit(self.schema.files[module].version);
                            quote!(#v)
                        } else {
                            zero(*p)
                        };
                        (
                            quote!(#t),
                            quote!(#t),
                            quote!(#rt::field::read::<#t>(__src, #off)),
                            quote!(#t),
                            quote!(#rt::field::Scalar::write(__value, __dst, #off)),
                            default,
                            quote!(),
                            false,
                        )
                    }
                    Kind::Enum {
                        prim,
                        path,
                        repr,
                        bitmask,
                    } => {
                        let t = format_ident!("{}", prim.rust_name());
                        let r = format_ident!("{}", repr.rust_name());
                        let raw = quote!(#rt::field::read::<#t>(__src, #off));
                        let widened = if prim == repr {
                            raw
                        } else {
                            quote!(#r::from(#raw))
                        };
                        let (get_body, to_raw) = if *bitmask {
                            (
                                quote!(#path::from_bits_retain(#widened)),
                                quote!(__value.bits()),
                            )
                        } else {
                            (quote!(#path::from_raw(#widened)), quote!(__value.to_raw()))
                        };
                        // The representation is at least as wide as the field; the
                        // narrowing keeps the low bits, which is all the field holds.
                        let narrowed = if prim == repr {
                            to_raw
                        } else {
                            quote!(#to_raw as #t)
                        };
                        (
                            path.clone(),
                            path.clone(),
                            get_body,
                            path.clone(),
                            quote!(#rt::field::Scalar::write(#narrowed, __dst, #off)),
                            quote!(#path::default()),
                            quote!(),
                            false,
                        )
                    }
                    Kind::Array(p, n) => {
                        let t = format_ident!("{}", p.rust_name());
                        let z = zero(*p);
                        let n = lit(*n as u64);
                        (
                            quote!([#t; #n]),
                            quote!(#rt::field::ArrayView<'a, #t, #n>),
                            quote!(#rt::field::ArrayView::new(__src, #off)),
                            quote!(&[#t; #n]),
                            quote!(#rt::field::write_array(__dst, #off, __value)),
                            quote!([#z; #n]),
                            quote!(.to_array()),
                            true,
                        )
                    }
                    Kind::Chars(n) => {
                        let n = lit(*n as u64);
                        (
                            quote!([u8; #n]),
                            quote!(#rt::field::CharArray<'a, #n>),
                            quote!(#rt::field::CharArray::new(__src, #off)),
                            quote!(&[u8; #n]),
                            quote!(#rt::field::write_array(__dst, #off, __value)),
                            quote!([0; #n]),
                            quote!(.to_array()),
                            true,
                        )
                    }
                };
            let serde = self.serde_field(f, &fid, &kind);
            let user = self.field_attrs(&m.name, &f.name);
            struct_fields.push(quote!(#fdoc #serde #user pub #fid: #owned_ty,));
            // rustdoc cannot resolve raw identifiers: link the struct instead.
            let target = if fid.to_string().starts_with("r#") {
                format!("struct@{base}")
            } else {
                format!("{base}::{fid}")
            };
            let get_doc = format!(
                " Reads [`{base}::{rust_name}`]({target}) (`{}` at offset {}).",
                f.name, layout.offsets[fi]
            );
            let get_body = substitute(&get_tpl, "__src", &quote!(self.payload));
            getters.push(quote! {
                #[doc = #get_doc]
                #[inline]
                pub fn #fid(&self) -> #get_ty {
                    #get_body
                }
            });
            let set_doc = format!(" Sets the `{}` field.", f.name);
            let set_body = substitute(&set_tpl, "__dst", &quote!(self.payload));
            let set_body = substitute(&set_body, "__value", &quote!(value));
            setters.push(quote! {
                #[doc = #set_doc]
                #[inline]
                pub fn #setter(&mut self, value: #set_ty) {
                    #set_body
                }
            });
            let read = substitute(&get_tpl, "__src", &quote!(p));
            from_view.push(quote!(#fid: #read #to_owned,));
            let value = if by_ref {
                quote!(&self.#fid)
            } else {
                quote!(self.#fid)
            };
            let write = substitute(&set_tpl, "__dst", &quote!(out));
            let write = substitute(&write, "__value", &value);
            emit.push(quote!(#write;));
            defaults.push(quote!(#fid: #default,));
        }

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
        quote! {
            #mdoc
            #derives
            #serde
            #user
            pub struct #owned {
                #(#struct_fields)*
            }

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
                /// This message's row of the dialect table.
                pub const META: #rt::MessageMeta = #rt::MessageMeta {
                    id: Self::ID,
                    name: Self::NAME,
                    crc_extra: Self::CRC_EXTRA,
                    min_len: Self::MIN_LEN as u8,
                    max_len: Self::MAX_LEN as u8,
                    target_system_offset: #ts,
                    target_component_offset: #tc,
                    fields: &[ #(#field_metas),* ],
                };

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

            #default_impl

            impl #rt::Message for #owned {
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

    fn dialect(&self, root: usize) -> TokenStream {
        let rt = self.rt();
        let rt = &rt;
        let reach: BTreeSet<usize> = self.schema.reachable(root).into_iter().collect();
        let mut msgs: Vec<MessageRef> = self
            .selected
            .iter()
            .copied()
            .filter(|r| reach.contains(&r.file))
            .collect();
        msgs.sort_by_key(|&r| self.schema.message(r).id);
        let variants: Vec<_> = msgs
            .iter()
            .map(|&r| format_ident!("{}", camel(&self.schema.message(r).name)))
            .collect();
        let paths: Vec<_> = msgs
            .iter()
            .map(|&r| self.path(root, r.file, &camel(&self.schema.message(r).name)))
            .collect();
        let views: Vec<_> = msgs
            .iter()
            .map(|&r| {
                self.path(
                    root,
                    r.file,
                    &format!("{}View", camel(&self.schema.message(r).name)),
                )
            })
            .collect();
        let ids: Vec<_> = msgs
            .iter()
            .map(|&r| lit(self.schema.message(r).id))
            .collect();
        let idx = (0..msgs.len()).map(Literal::usize_unsuffixed);
        let vdocs: Vec<_> = msgs
            .iter()
            .map(|&r| {
                format!(
                    " `{}` (id {}).",
                    self.schema.message(r).name,
                    self.schema.message(r).id
                )
            })
            .collect();
        let fname = self.schema.files[root]
            .path
            .file_name()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        let enum_doc = format!(
            " Every message of the `{fname}` dialect ({} messages, its includes' too).",
            msgs.len()
        );
        let view_doc = format!(" A zero-copy view of any message of the `{fname}` dialect.");
        // Externally tagged by XML name: `{"HEARTBEAT": {…}}`.
        let serde = self.serde_derive(quote!());
        let renames: Vec<_> = msgs
            .iter()
            .map(|&r| {
                let name = &self.schema.message(r).name;
                serde_attr(&[quote!(rename = #name)])
            })
            .collect();
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

            /// The dialect's table: id, name, CRC_EXTRA and lengths of every
            /// message, sorted by id.
            pub const MESSAGES: &[#rt::MessageMeta] = &[ #( #paths::META, )* ];

            /// This dialect, for code generic over dialects.
            #[derive(Debug, Clone, Copy, Default)]
            pub struct Dialect;

            impl #rt::Dialect for Dialect {
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

            #(
                impl From<#paths> for Message {
                    fn from(m: #paths) -> Self {
                        Self::#variants(m)
                    }
                }
            )*
        }
    }
}
