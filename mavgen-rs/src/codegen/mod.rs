//! Turns a checked [`Schema`] into Rust source: one module per XML file and a
//! `mod.rs` that includes them.
//!
//! Items are built as token streams with `quote` and printed with
//! `prettyplease`, so the output is deterministic and reads like hand-written
//! code. Each top-level item is printed alone and the items are joined with
//! a blank line (prettyplease packs a file's items together).
//!
//! Where each part is built: `message` (a message's owned struct, view and
//! writer), `field` (per kind of field, its part of each of those), `enums`
//! (value enums and flag sets), `dialect` (the root file's `Message`,
//! `MessageView`, `MESSAGES`, `Dialect`), `check` (Rust name collisions,
//! found before anything is built); this file chooses what to generate,
//! names the modules and assembles the files.

mod check;
mod dialect;
mod enums;
mod field;
mod message;

use crate::diag::{Diagnostic, Position, Severity};
use crate::model::{Field, Primitive};
use crate::names::{self, ident};
use crate::schema::{MessageRef, Schema};
use enums::EnumInfo;
use field::{EnumField, FieldKind};
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

/// The version of the runtime's interface to generated code
/// (`mavframe::GENERATED_CODE_INTERFACE`) this generator writes code for.
/// Generated code asserts at compile time that the runtime it builds
/// against has the same: raise both together when generated code needs
/// another runtime.
pub const RUNTIME_INTERFACE: u32 = 1;

/// Generated files: `(file name, contents)`, `mod.rs` first.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Output {
    /// The files, in a stable order.
    pub files: Vec<(String, String)>,
    /// Enums generated (all of the schema's, or those the selected
    /// messages use).
    pub enums: usize,
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
    let rt = runtime_path(&opts.runtime).map_err(|d| vec![d])?;
    let mut errors = Vec::new();
    let modules = module_names(schema, &mut errors);
    let selected = select_messages(schema, opts.messages.as_ref(), &mut errors);
    let enums = select_enums(schema, opts.messages.is_some(), &selected);
    for (pattern, attrs) in opts.type_attributes.iter().chain(&opts.field_attributes) {
        if let Err(e) = parse_attributes(attrs) {
            errors.push(error(
                None,
                format!("attribute `{attrs}` for `{pattern}` does not parse: {e}"),
            ));
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
    let bodies = gen.render_modules()?;
    let files = gen.files(opts.regenerate_hint.as_deref(), bodies);
    check_unique(&files)?;
    Ok(Output {
        files,
        enums: gen.enums.len(),
    })
}

fn error(position: Option<Position>, message: String) -> Diagnostic {
    Diagnostic {
        severity: Severity::Error,
        position,
        message,
    }
}

/// The runtime crate path, checked to parse, as compact text.
fn runtime_path(runtime: &str) -> Result<String, Diagnostic> {
    match syn::parse_str::<syn::Path>(runtime) {
        Ok(p) => Ok(quote!(#p).to_string().replace(' ', "")),
        Err(e) => Err(error(
            None,
            format!("runtime crate path `{runtime}` is not a Rust path: {e}"),
        )),
    }
}

/// The module of each XML file, named after the file (see
/// [`names::module`]; the module's file is `<module>.rs`). Files that would
/// share a module, and so an output file, are refused.
fn module_names(schema: &Schema, errors: &mut Vec<Diagnostic>) -> Vec<String> {
    let mut modules = Vec::new();
    let mut owner: HashMap<String, usize> = HashMap::new();
    for (i, f) in schema.files.iter().enumerate() {
        let stem = f
            .path
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        let name = names::module(&stem);
        if let Some(&other) = owner.get(&name) {
            let at = Position {
                file: f.path.clone(),
                line: 1,
                column: 1,
            };
            errors.push(error(
                Some(at),
                format!(
                    "{} and {} would both become module `{name}` (file `{name}.rs`); rename one",
                    schema.files[other].path.display(),
                    f.path.display()
                ),
            ));
        } else {
            owner.insert(name.clone(), i);
        }
        modules.push(name);
    }
    modules
}

/// The messages to generate: all, or those `filter` names.
fn select_messages(
    schema: &Schema,
    filter: Option<&BTreeSet<String>>,
    errors: &mut Vec<Diagnostic>,
) -> BTreeSet<MessageRef> {
    let Some(names) = filter else {
        return schema.message_refs().collect();
    };
    let by_name: HashMap<&str, MessageRef> = schema
        .message_refs()
        .map(|r| (schema.message(r).name.as_str(), r))
        .collect();
    let mut selected = BTreeSet::new();
    for n in names {
        match by_name.get(n.as_str()) {
            Some(&r) => {
                selected.insert(r);
            }
            None => errors.push(error(
                None,
                format!("message filter names {n}, which the dialect does not define"),
            )),
        }
    }
    selected
}

/// Enums to generate: all of them, or (`filtered`) those the selected
/// messages use.
fn select_enums(
    schema: &Schema,
    filtered: bool,
    selected: &BTreeSet<MessageRef>,
) -> BTreeMap<String, EnumInfo> {
    let used: BTreeSet<&str> = selected
        .iter()
        .flat_map(|&r| schema.message(r).fields.iter())
        .filter_map(|f| f.enum_name.as_deref())
        .collect();
    schema
        .enums
        .iter()
        .filter(|(name, _)| !filtered || used.contains(name.as_str()))
        .map(|(name, m)| (name.clone(), enums::enum_info(schema, name, m)))
        .collect()
}

/// Refuses output where two files share a name, one of which would
/// overwrite the other. [`module_names`] already refuses the inputs that
/// lead there; this holds whatever the naming rule becomes.
fn check_unique(files: &[(String, String)]) -> Result<(), Vec<Diagnostic>> {
    let mut seen = BTreeSet::new();
    let clashes: Vec<Diagnostic> = files
        .iter()
        .filter(|(name, _)| !seen.insert(name.as_str()))
        .map(|(name, _)| error(None, format!("two generated files would be named `{name}`")))
        .collect();
    if clashes.is_empty() {
        Ok(())
    } else {
        Err(clashes)
    }
}

/// The comment every generated file starts with.
fn header(file: &str, hint: Option<&str>) -> String {
    let mut h = String::new();
    let _ = writeln!(
        h,
        "// @generated by mavgen-rs {} from {file}. Do not edit.",
        env!("CARGO_PKG_VERSION")
    );
    if let Some(hint) = hint {
        let _ = writeln!(h, "// Regenerate with: {hint}");
    }
    h.push('\n');
    h
}

impl Gen<'_> {
    /// Each module's formatted items. Work units of a few items each are
    /// rendered on every core (syn's parse and prettyplease dominate the
    /// run time) and joined in order.
    fn render_modules(&self) -> Result<Vec<String>, Vec<Diagnostic>> {
        let mut jobs: Vec<(usize, Vec<Item>)> = Vec::new();
        for i in 0..self.schema.files.len() {
            let items = self.module_items(i);
            if items.is_empty() {
                jobs.push((i, Vec::new()));
            }
            for chunk in items.chunks(CHUNK_ITEMS) {
                jobs.push((i, chunk.to_vec()));
            }
        }
        let rendered = parallel_map(&jobs, |(i, items)| self.render(*i, items));
        let mut bodies = vec![String::new(); self.schema.files.len()];
        for ((i, _), text) in jobs.iter().zip(rendered) {
            let text = text.map_err(|e| {
                vec![error(
                    None,
                    format!("internal error: generated code does not parse: {e}"),
                )]
            })?;
            if !bodies[*i].is_empty() {
                bodies[*i].push('\n');
            }
            bodies[*i].push_str(&text);
        }
        Ok(bodies)
    }

    /// `mod.rs` and one file per module, from the modules' `bodies`.
    fn files(&self, hint: Option<&str>, bodies: Vec<String>) -> Vec<(String, String)> {
        let mut mod_rs = header("the files below", hint);
        // A crate including these files declares the feature the serde impls
        // are under; rustc's check-cfg warns at every use otherwise (item-level
        // `allow(unexpected_cfgs)` does not reach `cfg_attr`).
        let _ = writeln!(
            mod_rs,
            "// Serialize and Deserialize are implemented under `#[cfg(feature = \"{SERDE_FEATURE}\")]`:\n\
             // the crate including these files declares a `{SERDE_FEATURE}` feature that enables the\n\
             // runtime's (`{SERDE_FEATURE} = [\"mavframe/serde\"]`), even if it never turns it on.\n"
        );
        let _ = writeln!(
            mod_rs,
            "// Built only against the runtime this code was generated for.\n\
             const _: () = assert!(\n    \
             {rt}::GENERATED_CODE_INTERFACE == {RUNTIME_INTERFACE},\n    \
             \"generated by mavgen-rs {version} for another version of {name}: regenerate it \
             with the mavgen-rs that matches this {name}\"\n);\n",
            rt = self.rt,
            name = self.rt.trim_start_matches("::"),
            version = env!("CARGO_PKG_VERSION"),
        );
        let mut files = Vec::new();
        for ((i, f), body) in self.schema.files.iter().enumerate().zip(bodies) {
            let fname = f
                .path
                .file_name()
                .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
            let module = &self.modules[i];
            let mut doc = format!("Definitions of `{fname}`");
            if self.schema.roots.contains(&i) {
                doc.push_str(&format!(" (a dialect: see [`{module}::Message`])"));
            }
            let _ = writeln!(mod_rs, "#[doc = {:?}]", doc + ".");
            // dead_code, wrong_self_convention: a crate including these files
            // in a private module uses a few of their items and is not told
            // of the rest, nor linted on names only exported items escape.
            mod_rs.push_str("#[allow(dead_code, clippy::enum_variant_names, clippy::large_enum_variant, clippy::len_without_is_empty, clippy::wrong_self_convention)]\n");
            let _ = writeln!(
                mod_rs,
                "pub mod {module} {{\n    include!(\"{module}.rs\");\n}}"
            );
            files.push((format!("{module}.rs"), header(&fname, hint) + &body));
        }
        files.insert(0, ("mod.rs".to_string(), mod_rs));
        files
    }
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

    /// How field `f` of a message in `module` is represented.
    fn kind(&self, module: usize, f: &Field) -> FieldKind {
        match (f.array_len, f.primitive) {
            (Some(n), Primitive::Char) => FieldKind::Chars(n),
            (Some(n), p) => FieldKind::Array(p, n),
            (None, p) => match f.enum_name.as_deref().and_then(|e| self.enums.get(e)) {
                Some(info) if p.is_unsigned_int() && !f.mavlink_version => {
                    let e = EnumField {
                        prim: p,
                        path: self.path(module, info.module, &info.rust_name),
                        repr: info.repr,
                    };
                    if info.bitmask {
                        FieldKind::Bitmask(e)
                    } else {
                        FieldKind::Enum(e)
                    }
                }
                _ => FieldKind::Scalar {
                    prim: p,
                    version: f
                        .mavlink_version
                        .then_some(self.schema.files[module].version),
                },
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
        // prettyplease prints a file's items back to back: printing each
        // alone and joining them puts a blank line between items.
        let items: Vec<String> = file
            .items
            .into_iter()
            .map(|item| {
                prettyplease::unparse(&syn::File {
                    shebang: None,
                    attrs: Vec::new(),
                    items: vec![item],
                })
            })
            .collect();
        Ok(items.join("\n"))
    }
}
