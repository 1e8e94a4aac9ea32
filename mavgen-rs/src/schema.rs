//! Loads a set of dialect files with everything they include, merges enums
//! across files and checks the result, the way pymavlink's mavgen does, but
//! reporting every problem with its position instead of stopping at one.

use crate::diag::{Diagnostic, Diagnostics, Loc, Source};
use crate::input::{self, ReadError, MAX_FILE_BYTES, MAX_TOTAL_BYTES};
use crate::layout::Layout;
use crate::model::{Enum, Message, XmlFile};
use crate::xml;
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

/// Highest message id MAVLink 2 can carry (24 bits).
pub(crate) const MAX_MESSAGE_ID: u64 = 0xFF_FFFF;
/// Longest payload a frame can carry.
pub(crate) const MAX_PAYLOAD: usize = 255;
/// Most fields pymavlink (and the C library's field bitmaps) allow.
pub(crate) const MAX_FIELDS: usize = 64;

/// Field names that make the official C generator's output wrong: its
/// `mavlink_msg_*_pack`/`_pack_chan`/`_send` functions have parameters (and
/// locals) with these names, so a field of the same name shadows them. See
/// `docs/c-generator-name-clash.md`.
pub(crate) const C_CLASHING_FIELD_NAMES: &[&str] =
    &["system_id", "component_id", "msg", "chan", "packet", "buf"];

/// An enum after merging every file's declaration of it.
#[derive(Debug, Clone)]
pub(crate) struct MergedEnum {
    /// The merged definition: entries sorted by value, as pymavlink sorts them.
    pub(crate) def: Enum,
    /// The file whose module holds the enum: of the files declaring it, the
    /// one the others include (so `common.xml`'s `MAV_CMD` stays in `common`,
    /// with the entries ArduPilot and vendors merge into it).
    pub(crate) home: usize,
    /// Every file declaring the enum, in load order.
    pub(crate) declared_in: Vec<usize>,
}

/// A loaded, checked set of dialect files.
#[derive(Debug)]
pub struct Schema {
    /// File texts, for positions.
    pub(crate) sources: Vec<Source>,
    /// Files in pymavlink's order: the roots, then includes breadth first.
    pub(crate) files: Vec<XmlFile>,
    /// Indices of the files asked for (the dialects).
    pub(crate) roots: Vec<usize>,
    /// For each file, the file each of its `<include>`s names (`None` where
    /// it could not be read), aligned with [`XmlFile::includes`].
    pub(crate) includes: Vec<Vec<Option<usize>>>,
    /// Layout of each message: `layouts[file][message]`.
    pub(crate) layouts: Vec<Vec<Layout>>,
    /// Merged enums by name.
    pub(crate) enums: BTreeMap<String, MergedEnum>,
    /// Warnings found while loading.
    pub(crate) warnings: Vec<Diagnostic>,
}

/// A message of the schema: file index and message index.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) struct MessageRef {
    /// Index into [`Schema::files`].
    pub(crate) file: usize,
    /// Index into that file's messages.
    pub(crate) index: usize,
}

impl Schema {
    /// Loads `roots` and all they include, and checks them. On failure, the
    /// diagnostics (errors first found, warnings too) are returned.
    ///
    /// Every file must be a regular file of at most [`MAX_FILE_BYTES`], all
    /// of them together at most [`MAX_TOTAL_BYTES`]; anything else (a FIFO,
    /// a device, a directory) is an error at the `<include>` naming it.
    /// Include chains of any depth are handled without recursion.
    pub fn load<P: AsRef<Path>>(roots: &[P]) -> Result<Schema, Vec<Diagnostic>> {
        let mut diags = Diagnostics::default();
        let mut loader = Loader::default();
        let mut root_ids = Vec::new();
        for root in roots {
            let root = root.as_ref();
            match loader.read(root, None, &mut diags) {
                Some(id) if !root_ids.contains(&id) => root_ids.push(id),
                _ => {}
            }
        }
        Self::resolve(loader, root_ids, diags)
    }

    /// Checks one dialect given as text, as if it were the file at `path`
    /// (an editor's unsaved buffer, a test's literal): diagnostics name
    /// `path`, and its `<include>`s are read from disk relative to `path`'s
    /// directory with the bounds of [`Schema::load`]. The text itself may
    /// hold at most [`MAX_FILE_BYTES`]; `path` need not exist.
    ///
    /// ```
    /// let xml = r#"<mavlink><messages>
    ///   <message id="42" name="PING_ME"><field type="uint32_t" name="seq">n</field></message>
    /// </messages></mavlink>"#;
    /// let schema = mavgen_rs::Schema::from_text("ping.xml", xml).unwrap();
    /// let ping = schema.messages().next().unwrap();
    /// assert_eq!((ping.id(), ping.name(), ping.max_len()), (42, "PING_ME", 4));
    ///
    /// let bad = xml.replace("uint32_t", "uint33_t");
    /// let errors = mavgen_rs::Schema::from_text("ping.xml", &bad).unwrap_err();
    /// assert!(errors[0].to_string().starts_with("ping.xml:2:"), "{}", errors[0]);
    /// ```
    pub fn from_text(path: impl AsRef<Path>, text: &str) -> Result<Schema, Vec<Diagnostic>> {
        let path = path.as_ref();
        let mut diags = Diagnostics::default();
        let mut loader = Loader::default();
        let root = match loader.count(text.len()) {
            Ok(()) => vec![loader.add(path, lexical_canonical(path), text.into(), &mut diags)],
            Err(e) => {
                loader.refuse(path, &None, &e, &mut diags);
                Vec::new()
            }
        };
        Self::resolve(loader, root, diags)
    }

    /// Follows the includes of the roots `loader` has read, then checks
    /// the whole.
    fn resolve(
        mut loader: Loader,
        root_ids: Vec<usize>,
        mut diags: Diagnostics,
    ) -> Result<Schema, Vec<Diagnostic>> {
        if diags.has_errors() {
            return Err(diags.into_vec());
        }
        // Breadth first, one level per pass, as mavgen's expand_includes.
        let mut includes: Vec<Vec<Option<usize>>> = Vec::new();
        let mut next = 0;
        while next < loader.files.len() {
            let level_end = loader.files.len();
            for f in next..level_end {
                let mut targets = Vec::new();
                for inc in loader.files[f].includes.clone() {
                    let base = loader.files[f].path.parent().unwrap_or(Path::new("."));
                    let shown = loader.sources[f]
                        .path
                        .parent()
                        .map_or_else(|| PathBuf::from(&inc.name), |p| p.join(&inc.name));
                    targets.push(loader.read(
                        &base.join(&inc.name),
                        Some((inc.loc, shown)),
                        &mut diags,
                    ));
                }
                includes.push(targets);
            }
            next = level_end;
        }
        // A file that did not parse has holes (messages without ids or
        // fields): checking it further would only report follow-up errors.
        if diags.has_errors() {
            return Err(diags.into_vec());
        }
        let Loader { sources, files, .. } = loader;
        let mut schema = Schema {
            sources,
            files,
            roots: root_ids,
            includes,
            layouts: Vec::new(),
            enums: BTreeMap::new(),
            warnings: Vec::new(),
        };
        schema.check_cycles(&mut diags);
        schema.merge_enums(&mut diags);
        schema.check_messages(&mut diags);
        if diags.has_errors() {
            return Err(diags.into_vec());
        }
        schema.warnings = diags.into_vec();
        Ok(schema)
    }

    /// Every message, in load order.
    pub(crate) fn message_refs(&self) -> impl Iterator<Item = MessageRef> + '_ {
        self.files.iter().enumerate().flat_map(|(file, f)| {
            (0..f.messages.len()).map(move |index| MessageRef { file, index })
        })
    }

    /// The message behind `r`.
    pub(crate) fn message(&self, r: MessageRef) -> &crate::model::Message {
        &self.files[r.file].messages[r.index]
    }

    /// The layout of `r`.
    pub(crate) fn layout(&self, r: MessageRef) -> &Layout {
        &self.layouts[r.file][r.index]
    }

    /// Files reachable from `root` (itself included), in load order.
    pub(crate) fn reachable(&self, root: usize) -> Vec<usize> {
        let mut seen = vec![false; self.files.len()];
        let mut stack = vec![root];
        while let Some(f) = stack.pop() {
            if !std::mem::replace(&mut seen[f], true) {
                stack.extend(self.includes[f].iter().flatten());
            }
        }
        (0..self.files.len()).filter(|&f| seen[f]).collect()
    }

    /// [`Schema::reachable`] as a bit set over file indices.
    fn reachable_bits(&self, root: usize) -> Vec<u64> {
        let mut bits = vec![0u64; self.files.len().div_ceil(64)];
        for f in self.reachable(root) {
            bits[f / 64] |= 1 << (f % 64);
        }
        bits
    }

    /// Every file read, for `cargo:rerun-if-changed`.
    pub fn paths(&self) -> impl Iterator<Item = &Path> {
        self.files.iter().map(|f| f.path.as_path())
    }

    /// Reports every include that closes a cycle. Depth-first search with
    /// an explicit stack (an include chain may be as long as there are
    /// files): an edge back to a file on the stack closes a cycle.
    fn check_cycles(&self, diags: &mut Diagnostics) {
        const NEW: usize = usize::MAX;
        const DONE: usize = usize::MAX - 1;
        // For each file: NEW, DONE, or its index in `stack` while on it.
        let mut state = vec![NEW; self.files.len()];
        // (file, index of the next include to follow)
        let mut stack: Vec<(usize, usize)> = Vec::new();
        for root in 0..self.files.len() {
            if state[root] != NEW {
                continue;
            }
            state[root] = 0;
            stack.push((root, 0));
            while let Some(top) = stack.last_mut() {
                let (f, inc) = *top;
                top.1 += 1;
                let Some(&target) = self.includes[f].get(inc) else {
                    state[f] = DONE;
                    stack.pop();
                    continue;
                };
                let Some(t) = target else { continue };
                match state[t] {
                    NEW => {
                        state[t] = stack.len();
                        stack.push((t, 0));
                    }
                    DONE => {}
                    on_stack => {
                        let cycle: Vec<usize> = stack[on_stack..].iter().map(|&(x, _)| x).collect();
                        diags.error(
                            &self.sources,
                            self.files[f].includes[inc].loc,
                            format!("include cycle: {}", self.cycle_names(&cycle)),
                        );
                    }
                }
            }
        }
    }

    /// `a.xml -> b.xml -> a.xml` for the cycle through `files`; a long cycle
    /// is shortened to its first and last files, so a cycle through
    /// thousands of files stays one readable line.
    fn cycle_names(&self, files: &[usize]) -> String {
        const SHOWN: usize = 8;
        let name = |&x: &usize| file_name(&self.files[x].path);
        let closing = std::iter::once(name(&files[0]));
        let names: Vec<String> = if files.len() <= SHOWN {
            files.iter().map(name).chain(closing).collect()
        } else {
            let head = files[..SHOWN / 2].iter().map(name);
            let skipped = format!("({} more)", files.len() - SHOWN);
            let tail = files[files.len() - SHOWN / 2..].iter().map(name);
            head.chain(std::iter::once(skipped))
                .chain(tail)
                .chain(closing)
                .collect()
        };
        names.join(" -> ")
    }

    /// pymavlink's `merge_enums`, step for step: a later declaration of an
    /// enum appends its entries to the first one; auto-numbered entries of
    /// the first that overlap the later range are renumbered above it.
    fn merge_enums(&mut self, diags: &mut Diagnostics) {
        let mut merged = self.merged_declarations();
        // Reachability of the files declaring a merged enum only, computed
        // when first needed: one bit per file each, so a long include chain
        // costs no more than it must.
        let mut reach: HashMap<usize, Vec<u64>> = HashMap::new();
        for m in merged.values_mut() {
            m.home = self.enum_home(m, &mut reach);
            self.check_entries(m, diags);
            // After the checks, so "first declared" means first in the files.
            m.def.entries.sort_by_key(|e| e.value); // stable, as Python's sorted
        }
        self.enums = merged;
    }

    /// Every enum with its later declarations appended to the first.
    fn merged_declarations(&self) -> BTreeMap<String, MergedEnum> {
        let mut merged: BTreeMap<String, MergedEnum> = BTreeMap::new();
        for (f, file) in self.files.iter().enumerate() {
            for e in &file.enums {
                let mut incoming = e.clone();
                match merged.get_mut(&e.name) {
                    None => {
                        merged.insert(
                            e.name.clone(),
                            MergedEnum {
                                def: incoming,
                                home: f,
                                declared_in: vec![f],
                            },
                        );
                    }
                    Some(m) => {
                        let first = &mut m.def;
                        let start = first.start_value.unwrap_or(0);
                        if start <= incoming.highest_value
                            && first.highest_value >= incoming.start_value.unwrap_or(0)
                        {
                            for entry in &mut first.entries {
                                if entry.value <= incoming.highest_value && entry.autovalue {
                                    entry.value = incoming.highest_value + 1;
                                    incoming.highest_value = entry.value;
                                }
                            }
                        }
                        first.entries.extend(incoming.entries);
                        if first.description.trim().is_empty() {
                            first.description = incoming.description;
                        }
                        first.bitmask |= incoming.bitmask;
                        if !m.declared_in.contains(&f) {
                            m.declared_in.push(f);
                        }
                    }
                }
            }
        }
        merged
    }

    /// The file an enum is generated in: included by the most other
    /// declaring files; ties go to the file loaded first (common.xml before
    /// a vendor file that extends MAV_CMD without including common.xml).
    fn enum_home(&self, m: &MergedEnum, reach: &mut HashMap<usize, Vec<u64>>) -> usize {
        if m.declared_in.len() > 1 {
            for &e in &m.declared_in {
                reach.entry(e).or_insert_with(|| self.reachable_bits(e));
            }
        }
        let reaches = |e: usize, d: usize| reach.get(&e).map_or(e == d, |b| bit(b, d));
        *m.declared_in
            .iter()
            .max_by_key(|&&d| {
                (
                    m.declared_in.iter().filter(|&&e| reaches(e, d)).count(),
                    std::cmp::Reverse(d),
                )
            })
            .expect("declared at least once")
    }

    /// Entry names and values unique within a merged enum.
    fn check_entries(&self, m: &MergedEnum, diags: &mut Diagnostics) {
        let mut names: HashMap<&str, Loc> = HashMap::new();
        let mut values: HashMap<u64, (&str, Loc)> = HashMap::new();
        for entry in &m.def.entries {
            if let Some(prev) = names.insert(&entry.name, entry.loc) {
                let at = self.sources[prev.file].position(prev.offset);
                diags.error(
                    &self.sources,
                    entry.loc,
                    format!(
                        "duplicate enum entry name {}.{} (first declared at {}:{})",
                        m.def.name,
                        entry.name,
                        at.file.display(),
                        at.line
                    ),
                );
            } else if let Some((prev_name, prev)) =
                values.insert(entry.value, (&entry.name, entry.loc))
            {
                let at = self.sources[prev.file].position(prev.offset);
                diags.error(
                    &self.sources,
                    entry.loc,
                    format!(
                        "duplicate enum value {} = {} in {} (already used by {} at {}:{})",
                        entry.name,
                        entry.value,
                        m.def.name,
                        prev_name,
                        at.file.display(),
                        at.line
                    ),
                );
            }
        }
    }

    /// `FILE:LINE` of `l`, for messages pointing at an earlier declaration.
    fn here(&self, l: Loc) -> String {
        let p = self.sources[l.file].position(l.offset);
        format!("{}:{}", p.file.display(), p.line)
    }

    /// Every message's checks, ids and names unique across all files, and
    /// the wire layouts.
    fn check_messages(&mut self, diags: &mut Diagnostics) {
        let mut by_id: HashMap<u64, (String, Loc)> = HashMap::new();
        let mut by_name: HashMap<String, Loc> = HashMap::new();
        let mut layouts = Vec::with_capacity(self.files.len());
        for file in &self.files {
            let mut file_layouts = Vec::with_capacity(file.messages.len());
            for m in &file.messages {
                self.check_name_and_id(m, diags);
                if let Some((other, l)) = by_id.get(&m.id) {
                    diags.error(
                        &self.sources,
                        m.id_loc,
                        format!(
                            "duplicate message id {} for {} (also used by {other} at {})",
                            m.id,
                            m.name,
                            self.here(*l)
                        ),
                    );
                } else {
                    by_id.insert(m.id, (m.name.clone(), m.loc));
                }
                if let Some(l) = by_name.get(&m.name) {
                    diags.error(
                        &self.sources,
                        m.loc,
                        format!(
                            "duplicate message name {} (first declared at {})",
                            m.name,
                            self.here(*l)
                        ),
                    );
                } else {
                    by_name.insert(m.name.clone(), m.loc);
                }
                file_layouts.push(self.check_message(m, diags));
            }
            layouts.push(file_layouts);
        }
        self.layouts = layouts;
    }

    /// A message's name is an identifier and its id fits a frame.
    fn check_name_and_id(&self, m: &Message, diags: &mut Diagnostics) {
        if !is_identifier(&m.name) {
            diags.error(
                &self.sources,
                m.loc,
                format!(
                    "message name `{}` is not an identifier ([A-Za-z_][A-Za-z0-9_]*)",
                    m.name
                ),
            );
        }
        if m.id > MAX_MESSAGE_ID {
            diags.error(&self.sources, m.id_loc, format!("message {}: id {} is above {MAX_MESSAGE_ID}, the largest a MAVLink 2 frame carries", m.name, m.id));
        }
    }

    /// One message's fields and payload size; returns its layout.
    fn check_message(&self, m: &Message, diags: &mut Diagnostics) -> Layout {
        if m.fields.is_empty() {
            diags.error(
                &self.sources,
                m.loc,
                format!("message {} has no fields", m.name),
            );
        }
        if m.fields.len() > MAX_FIELDS {
            diags.error(
                &self.sources,
                m.loc,
                format!(
                    "message {} has {} fields; at most {MAX_FIELDS} are allowed",
                    m.name,
                    m.fields.len()
                ),
            );
        }
        self.check_fields(m, diags);
        let layout = Layout::of(m);
        if layout.max_len > MAX_PAYLOAD {
            diags.error(
                &self.sources,
                m.loc,
                format!(
                    "message {} has a {}-byte payload; a frame carries at most {MAX_PAYLOAD}",
                    m.name, layout.max_len
                ),
            );
        }
        layout
    }

    /// The fields of message `m`: names, duplicates, enum references.
    fn check_fields(&self, m: &Message, diags: &mut Diagnostics) {
        let mut seen: HashMap<&str, Loc> = HashMap::new();
        for f in &m.fields {
            if !is_identifier(&f.name) {
                diags.error(
                    &self.sources,
                    f.loc,
                    format!("field name `{}` in {} is not an identifier", f.name, m.name),
                );
            }
            if let Some(l) = seen.insert(&f.name, f.loc) {
                diags.error(
                    &self.sources,
                    f.loc,
                    format!(
                        "duplicate field {} in message {} (first at {})",
                        f.name,
                        m.name,
                        self.here(l)
                    ),
                );
            }
            if let Some(e) = &f.enum_name {
                if !self.enums.contains_key(e) {
                    diags.error(
                        &self.sources,
                        f.enum_loc,
                        format!("field {}.{} refers to unknown enum {e}", m.name, f.name),
                    );
                }
            }
            if C_CLASHING_FIELD_NAMES.contains(&f.name.as_str()) {
                diags.warning(
                    &self.sources,
                    f.loc,
                    format!(
                        "field {}.{} has the name of a parameter of the official C generator's mavlink_msg_{}_pack/_send functions: the C header pymavlink generates for it does not compile (see docs/c-generator-name-clash.md)",
                        m.name,
                        f.name,
                        m.name.to_lowercase()
                    ),
                );
            }
        }
    }
}

/// Reads files once each, by canonical path.
#[derive(Default)]
struct Loader {
    sources: Vec<Source>,
    files: Vec<XmlFile>,
    by_path: HashMap<PathBuf, usize>,
    /// Bytes read so far, against [`MAX_TOTAL_BYTES`].
    total: u64,
}

impl Loader {
    /// Reads and parses `path` unless already read; `from` is the include
    /// that names it (its position, and the path to show).
    fn read(
        &mut self,
        path: &Path,
        from: Option<(Loc, PathBuf)>,
        diags: &mut Diagnostics,
    ) -> Option<usize> {
        let canonical = match path.canonicalize() {
            Ok(p) => p,
            Err(e) => {
                self.refuse(path, &from, &ReadError::Io(e), diags);
                return None;
            }
        };
        if let Some(&id) = self.by_path.get(&canonical) {
            return Some(id);
        }
        let text = match self.read_text(&canonical) {
            Ok(t) => t,
            Err(e) => {
                self.refuse(path, &from, &e, diags);
                return None;
            }
        };
        let shown = from.map_or_else(|| path.to_path_buf(), |(_, p)| p);
        Some(self.add(&shown, canonical, text, diags))
    }

    /// Parses `text`, the file at `canonical` shown as `shown`, as the next
    /// file.
    fn add(
        &mut self,
        shown: &Path,
        canonical: PathBuf,
        text: String,
        diags: &mut Diagnostics,
    ) -> usize {
        let id = self.files.len();
        self.sources.push(Source::new(shown, text));
        let file = xml::parse(&self.sources, id, canonical.clone(), diags);
        self.files.push(file);
        self.by_path.insert(canonical, id);
        id
    }

    /// One file's text, within both the per-file and the total limit.
    fn read_text(&mut self, path: &Path) -> Result<String, ReadError> {
        let text = input::read_regular_text(path, MAX_FILE_BYTES)?;
        self.count(text.len())?;
        Ok(text)
    }

    /// Counts a file of `len` bytes against both limits.
    fn count(&mut self, len: usize) -> Result<(), ReadError> {
        let len = len as u64;
        if len > MAX_FILE_BYTES {
            return Err(ReadError::TooLarge {
                limit: MAX_FILE_BYTES,
            });
        }
        self.total += len;
        if self.total > MAX_TOTAL_BYTES {
            return Err(ReadError::TooLarge {
                limit: MAX_TOTAL_BYTES,
            });
        }
        Ok(())
    }

    /// Reports why `path` was not read: at the `<include>` naming it, or
    /// without a position for a file given by the caller.
    fn refuse(
        &self,
        path: &Path,
        from: &Option<(Loc, PathBuf)>,
        e: &ReadError,
        diags: &mut Diagnostics,
    ) {
        let why = match e {
            ReadError::TooLarge { limit } if *limit == MAX_TOTAL_BYTES => format!(
                "the files read would exceed {limit} bytes ({} MiB) in all, the most mavgen-rs reads in one run",
                limit >> 20
            ),
            e => e.to_string(),
        };
        match from {
            Some((loc, shown)) => diags.error(
                &self.sources,
                *loc,
                format!("cannot read included file {}: {why}", shown.display()),
            ),
            None => diags.push(
                crate::diag::Severity::Error,
                None,
                format!("cannot read {}: {why}", path.display()),
            ),
        }
    }
}

/// Bit `i` of a bit set made by [`Schema::reachable_bits`].
fn bit(bits: &[u64], i: usize) -> bool {
    bits[i / 64] & (1 << (i % 64)) != 0
}

/// The canonical form of a path that may not exist (a text given with a
/// name): its directory canonicalized when that exists, so an include of
/// the same file from disk is recognised as this text; else as given.
fn lexical_canonical(path: &Path) -> PathBuf {
    if let Ok(p) = path.canonicalize() {
        return p;
    }
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match (dir.canonicalize(), path.file_name()) {
        (Ok(d), Some(name)) => d.join(name),
        _ => path.to_path_buf(),
    }
}

fn file_name(p: &Path) -> String {
    p.file_name().map_or_else(
        || p.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    )
}

/// `[A-Za-z_][A-Za-z0-9_]*`
pub(crate) fn is_identifier(s: &str) -> bool {
    let mut chars = s.chars();
    chars
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}
