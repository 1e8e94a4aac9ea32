//! `--config PATH`: a daemon's options from files, fbwag's TOML or
//! mavlink-router's own configuration.
//!
//! A TOML file holds the options of the command line, one key per long
//! option (`sign_key` or `sign-key` for `--sign-key`), and `links` for
//! `fbwag router`'s links. A mavlink-router file (`main.conf`: a `.conf`
//! name, or a first section `[General]` or `[…Endpoint NAME]`) is read as
//! it is ([`ini`]) and its keys turned into the same options
//! ([`mavlink_router`]). Either way the words go through clap: the `Args`
//! structs stay the one definition of every option, so an option is
//! configurable the day it exists, with the same checks and the same
//! `--help`. PATH may also be a directory: its `*.toml` files, or its
//! `*.conf` files (mavlink-router's `config.d`), in name order, so a
//! package can add a link in a file of its own; a directory holding both
//! is refused (the two formats are read apart: give each its directory).
//! `--config` may be given more than once. Every mavlink-router file adds
//! to one configuration, as mavlink-router merges `main.conf` and
//! `config.d` (a section met again takes more keys; a later value of a
//! key wins), whose options come first on the command line built; then
//! the TOML files', in order; then the command line's: a single-valued
//! option given later wins, and list options (`out`, `links`) add up.
//!
//! A file that is not UTF-8, TOML or mavlink-router's format, a key that
//! is no option, a value of the wrong kind, or a value the option refuses
//! is reported with the file's line and column. `--print-config` prints
//! what the files gave as one TOML file ([`FileArgs::toml`]).

mod ini;
mod mavlink_router;

use clap::{Arg, ArgAction, Command};
use std::ffi::OsString;
use std::fmt;
use std::io::Read;
use std::path::{Path, PathBuf};
use toml::de::{DeTable, DeValue};
use toml::Spanned;

/// The largest file read: a daemon's options fit in far less.
const MAX_BYTES: u64 = 1 << 20;

/// A place in a file: 1-based line and column.
#[derive(Debug, Clone)]
pub struct Location {
    pub path: PathBuf,
    pub line: usize,
    pub column: usize,
}

impl Location {
    fn at(path: &Path, text: &str, offset: usize) -> Self {
        let mut offset = offset.min(text.len());
        while !text.is_char_boundary(offset) {
            offset -= 1;
        }
        let before = &text[..offset];
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        Location {
            path: path.to_owned(),
            line: before.matches('\n').count() + 1,
            column: before[line_start..].chars().count() + 1,
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}", self.path.display(), self.line, self.column)
    }
}

/// Why a configuration file was refused.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read {}: {source}", path.display())]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{} is over {MAX_BYTES} bytes: not a configuration file", path.display())]
    TooLarge { path: PathBuf },
    #[error("{} holds both *.conf (mavlink-router's) and *.toml files: the two are read apart; give each its directory and --config each", path.display())]
    Mixed { path: PathBuf },
    #[error("{at}: {message}")]
    Syntax { at: Location, message: String },
    #[error("{at}: `{key}`: {why}")]
    Key {
        at: Location,
        key: String,
        why: String,
    },
}

/// One option a file gives: by its name (a long option, `-` or `_`
/// between words, or a positional's), with the file's key and where the
/// file gives it.
#[derive(Debug, Clone)]
pub struct Given {
    pub option: String,
    /// The file's key, for errors.
    pub key: String,
    pub at: Location,
    pub value: Value,
}

/// What a file gives an option.
#[derive(Debug, Clone)]
pub enum Value {
    /// A switch, on or off.
    Switch(bool),
    /// Values as the command line writes them, each with where the file
    /// gives it.
    Words(Vec<(String, Location)>),
}

/// How an option takes values, for printing it back.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Takes {
    Switch,
    One,
    Many,
}

/// The options a file gave, as command-line words, and where each came
/// from (to name the file's line when the option refuses its value).
#[derive(Debug, Default)]
pub struct FileArgs {
    /// The links, every file's together: clap takes a positional's
    /// values only as one run.
    positionals: Vec<OsString>,
    options: Vec<OsString>,
    /// Switches (`--require-signed`) and their value, the last file's:
    /// a later file's `false` turns one off.
    switches: Vec<(OsString, bool)>,
    origins: Vec<Origin>,
    /// The files read, in the order read.
    files: Vec<PathBuf>,
}

/// Where the file gave an option.
#[derive(Debug)]
struct Origin {
    /// As clap names it in an error: `--sign-key`, a positional's `<CONN>`.
    name: String,
    /// Its key in a TOML file (`sign_key`, `links`).
    toml_key: String,
    takes: Takes,
    key: String,
    at: Location,
    /// Each value as clap sees it, and where the file gives it (an
    /// array's element on its own line, say); a switch's `true`/`false`.
    values: Vec<(String, Location)>,
}

impl Origin {
    /// Where the file gives the first value `wanted` accepts.
    fn value_at(&self, wanted: impl Fn(&String) -> bool) -> Option<&Location> {
        self.values
            .iter()
            .find(|(v, _)| wanted(v))
            .map(|(_, at)| at)
    }
}

/// Inserts the options of every `--config PATH` (when the subcommand has
/// that option and it is given) after the subcommand's name in `argv`, so
/// the command line's own come after them.
pub fn expand(
    command: &Command,
    mut argv: Vec<OsString>,
) -> Result<(Vec<OsString>, Option<FileArgs>), ConfigError> {
    let Some(sub) = argv
        .get(1)
        .and_then(|s| s.to_str())
        .and_then(|s| command.find_subcommand(s))
    else {
        return Ok((argv, None));
    };
    if !sub.get_arguments().any(|a| a.get_id() == "config") {
        return Ok((argv, None));
    }
    let paths = config_paths(command, &argv);
    if paths.is_empty() {
        return Ok((argv, None));
    }
    let mut mavlink_router = ini::Document::default();
    let mut toml_files = Vec::new();
    for path in &paths {
        for file in files(path)? {
            let text = read(&file)?;
            let by_name = file.extension().and_then(|e| e.to_str());
            let is_ini = match by_name {
                Some("conf") => true,
                Some("toml") => false,
                _ => ini::looks_like(&text),
            };
            if is_ini {
                mavlink_router.read(&file, &text)?;
            } else {
                toml_files.push((file, text));
            }
        }
    }
    let mut all = FileArgs::default();
    if !mavlink_router.files.is_empty() {
        all.append(load_mavlink_router(sub, &mavlink_router)?);
    }
    for (file, text) in &toml_files {
        all.append(load_toml(sub, file, text)?);
    }
    argv.splice(2..2, all.words().cloned().collect::<Vec<_>>());
    Ok((argv, Some(all)))
}

/// The values of every `--config` in `argv`, as clap reads them: the very
/// ones the parse proper sees, whatever their spelling (`--config=PATH`)
/// or encoding (a path that is not UTF-8). The rest of the command line
/// may still be incomplete (links only in the files): errors are ignored
/// here, and reported by the parse proper.
fn config_paths(command: &Command, argv: &[OsString]) -> Vec<PathBuf> {
    let Ok(matches) = command
        .clone()
        .ignore_errors(true)
        .try_get_matches_from(argv)
    else {
        return Vec::new();
    };
    matches
        .subcommand()
        .and_then(|(_, m)| m.try_get_many::<PathBuf>("config").ok().flatten())
        .map(|paths| paths.cloned().collect())
        .unwrap_or_default()
}

/// The files `path` names: itself, or a directory's `*.toml` or `*.conf`
/// files (not hidden ones, regular files or links to them) in name
/// order; anything else there is left alone (an editor's backup, a
/// package manager's `.dpkg-old`, a pipe). A path given itself is read
/// whatever it is (`--config <(…)`).
fn files(path: &Path) -> Result<Vec<PathBuf>, ConfigError> {
    if !path.is_dir() {
        return Ok(vec![path.to_owned()]);
    }
    let read = |source| ConfigError::Read {
        path: path.to_owned(),
        source,
    };
    let mut found = Vec::new();
    let mut kinds = [false; 2];
    for entry in std::fs::read_dir(path).map_err(read)? {
        let file = entry.map_err(read)?.path();
        let hidden = file
            .file_name()
            .is_some_and(|n| n.as_encoded_bytes().starts_with(b"."));
        let kind = match file.extension().and_then(|e| e.to_str()) {
            Some("toml") => 0,
            Some("conf") => 1,
            _ => continue,
        };
        if hidden {
            continue;
        }
        // A link whose target is gone is a lost drop-in: refused, not
        // skipped (its keys, or its links, would vanish unnoticed).
        let meta = std::fs::metadata(&file).map_err(|source| ConfigError::Read {
            path: file.clone(),
            source,
        })?;
        if meta.is_file() {
            kinds[kind] = true;
            found.push(file);
        }
    }
    if kinds == [true, true] {
        return Err(ConfigError::Mixed {
            path: path.to_owned(),
        });
    }
    found.sort();
    Ok(found)
}

/// The text of `path`: at most [`MAX_BYTES`], UTF-8 (a byte that is not
/// is refused at its place).
fn read(path: &Path) -> Result<String, ConfigError> {
    // Read at most one byte past the bound: a device or a pipe given as
    // the file has no size to check first.
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .and_then(|f| f.take(MAX_BYTES + 1).read_to_end(&mut bytes))
        .map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
    if bytes.len() as u64 > MAX_BYTES {
        return Err(ConfigError::TooLarge {
            path: path.to_owned(),
        });
    }
    String::from_utf8(bytes).map_err(|e| {
        let good = e.utf8_error().valid_up_to();
        let bad = e.as_bytes()[good];
        let text = String::from_utf8_lossy(&e.as_bytes()[..good]).into_owned();
        ConfigError::Syntax {
            at: Location::at(path, &text, good),
            message: format!("byte 0x{bad:02x} is not UTF-8: a configuration file is text"),
        }
    })
}

impl FileArgs {
    /// The command-line words, the links first.
    pub fn words(&self) -> impl Iterator<Item = &OsString> {
        let on = self.switches.iter().filter(|(_, on)| *on);
        self.positionals
            .iter()
            .chain(&self.options)
            .chain(on.map(|(flag, _)| flag))
    }

    /// `other`'s options after these.
    fn append(&mut self, other: FileArgs) {
        self.positionals.extend(other.positionals);
        self.options.extend(other.options);
        for (flag, on) in other.switches {
            self.set_switch(flag, on);
        }
        self.origins.extend(other.origins);
        self.files.extend(other.files);
    }

    fn set_switch(&mut self, flag: OsString, on: bool) {
        match self.switches.iter_mut().find(|(f, _)| *f == flag) {
            Some(switch) => switch.1 = on,
            None => self.switches.push((flag, on)),
        }
    }

    /// Adds what `g` gives option `arg`.
    fn add(&mut self, arg: &Arg, g: Given) -> Result<(), ConfigError> {
        let name = match (arg.get_long(), arg.get_value_names()) {
            (Some(long), _) => format!("--{long}"),
            (None, Some([first, ..])) => format!("<{first}>"),
            (None, _) => format!("<{}>", arg.get_id().as_str().to_uppercase()),
        };
        let takes = takes(arg);
        let values = match g.value {
            Value::Switch(on) if takes == Takes::Switch => {
                self.set_switch(name.clone().into(), on);
                vec![(on.to_string(), g.at.clone())]
            }
            Value::Switch(_) => {
                return Err(ConfigError::Key {
                    at: g.at,
                    key: g.key,
                    why: "takes a value, not true or false".into(),
                })
            }
            Value::Words(_) if takes == Takes::Switch => {
                return Err(ConfigError::Key {
                    at: g.at,
                    key: g.key,
                    why: "a switch: true or false".into(),
                })
            }
            Value::Words(words) => {
                // `--flag=VALUE`: a value that starts with `-` stays a value.
                let flag = arg.get_long().map(|l| format!("--{l}"));
                let out = if arg.is_positional() {
                    &mut self.positionals
                } else {
                    &mut self.options
                };
                out.extend(words.iter().map(|(v, _)| match &flag {
                    Some(f) => OsString::from(format!("{f}={v}")),
                    None => OsString::from(v),
                }));
                words
            }
        };
        let toml_key = match arg.get_long() {
            Some(long) => long.replace('-', "_"),
            None => arg.get_id().to_string(),
        };
        self.origins.push(Origin {
            name,
            toml_key,
            takes,
            key: g.key,
            at: g.at,
            values,
        });
        Ok(())
    }

    /// `e` as the file's error, when the value it refuses is one the file
    /// gave.
    pub fn blame(&self, e: &clap::Error) -> Option<ConfigError> {
        use clap::error::{ContextKind, ContextValue};
        let text = |kind| match e.get(kind) {
            Some(ContextValue::String(s)) => Some(s.as_str()),
            _ => None,
        };
        let flag = text(ContextKind::InvalidArg)?;
        let value = text(ContextKind::InvalidValue);
        let (origin, at) = self.origins.iter().find_map(|o| {
            // A list positional is `<CONN>...` in clap's errors.
            let named = flag
                .split_whitespace()
                .next()
                .map(|f| f.trim_end_matches("..."))
                == Some(o.name.as_str());
            let at = match value {
                Some(v) => o.value_at(|w| w == v)?,
                None => &o.at,
            };
            named.then_some((o, at))
        })?;
        let rendered = e.to_string();
        let first = rendered.lines().next().unwrap_or_default();
        Some(ConfigError::Key {
            at: at.clone(),
            key: origin.key.clone(),
            why: first.trim_start_matches("error: ").to_owned(),
        })
    }

    /// The file's place of a per-link option a daemon refused after the
    /// parse (`--filter-in 9:RULE`, `--peer 2`, `--sniffer 5`: the flag,
    /// then the link's place), when a file gave that link a value of that
    /// option: the refusal (`why`) as the file's error.
    pub fn blame_link(&self, arg: &str, why: impl fmt::Display) -> Option<ConfigError> {
        let (flag, value) = arg.split_once(' ')?;
        // `LINK` or `LINK:RULE` (a filter's rule, which must be the file's
        // too: the command line may give the same link another).
        let (link, rule) = link_and_rule(value);
        link.as_ref()?;
        let same = |v: &String| {
            let (l, r) = link_and_rule(v);
            l == link && rule.is_none_or(|rule| r == Some(rule))
        };
        let (origin, at) = self
            .origins
            .iter()
            .rev()
            .filter(|o| o.name == flag)
            .find_map(|o| Some((o, o.value_at(same)?)))?;
        Some(ConfigError::Key {
            at: at.clone(),
            key: origin.key.clone(),
            why: format!("{value}: {why}"),
        })
    }

    /// The files' options as one TOML file of fbwag's (`--print-config`
    /// of `fbwag PROGRAM`): each option once, as the daemon takes it (a
    /// later file's single-valued option, a list option's values
    /// together), after a comment naming the files.
    pub fn toml(&self, program: &str) -> String {
        let mut table = toml::Table::new();
        for o in &self.origins {
            let key = o.toml_key.clone();
            match o.takes {
                Takes::Switch => {
                    let on = o.values.first().is_some_and(|(v, _)| v == "true");
                    table.insert(key, toml::Value::Boolean(on));
                }
                Takes::One => {
                    if let Some((v, _)) = o.values.last() {
                        table.insert(key, toml_value(v));
                    }
                }
                Takes::Many => {
                    let list = table
                        .entry(key)
                        .or_insert_with(|| toml::Value::Array(Vec::new()));
                    if let toml::Value::Array(list) = list {
                        list.extend(o.values.iter().map(|(v, _)| toml_value(v)));
                    }
                }
            }
        }
        let files: Vec<String> = self.files.iter().map(|f| f.display().to_string()).collect();
        let mut out = format!("# fbwag {program}: the options of {}\n", files.join(", "));
        for (key, value) in &table {
            match value {
                // A list of more than one value: one a line.
                toml::Value::Array(list) if list.len() > 1 => {
                    out.push_str(&format!("{key} = [\n"));
                    for v in list {
                        out.push_str(&format!("    {v},\n"));
                    }
                    out.push_str("]\n");
                }
                value => out.push_str(&format!("{key} = {value}\n")),
            }
        }
        out
    }
}

/// A per-link value's link (its place or name) and what follows its
/// colon, if any.
fn link_and_rule(v: &str) -> (Option<crate::args::LinkRef>, Option<&str>) {
    let (link, rule) = v.split_once(':').map_or((v, None), |(l, r)| (l, Some(r)));
    (crate::args::link(link).ok(), rule.map(str::trim))
}

/// A value as TOML writes it: a number where the command line's word is
/// one (written back the same), else a string.
fn toml_value(v: &str) -> toml::Value {
    match v.parse::<i64>() {
        Ok(n) if n.to_string() == v => toml::Value::Integer(n),
        _ => toml::Value::String(v.to_string()),
    }
}

/// How `arg` takes values.
fn takes(arg: &Arg) -> Takes {
    if matches!(arg.get_action(), ArgAction::SetTrue) {
        Takes::Switch
    } else if matches!(arg.get_action(), ArgAction::Append)
        || arg.get_num_args().is_some_and(|n| n.max_values() > 1)
    {
        Takes::Many
    } else {
        Takes::One
    }
}

/// Reads the TOML file `path` as the options of subcommand `command`.
#[cfg(test)]
fn load(command: &Command, path: &Path) -> Result<FileArgs, ConfigError> {
    let text = read(path)?;
    load_toml(command, path, &text)
}

/// The options of subcommand `command` in the TOML file `path`, whose
/// text is `text`.
fn load_toml(command: &Command, path: &Path, text: &str) -> Result<FileArgs, ConfigError> {
    let table = DeTable::parse(text).map_err(|e| ConfigError::Syntax {
        at: Location::at(path, text, e.span().map_or(0, |s| s.start)),
        message: e.message().trim().to_owned(),
    })?;
    let mut out = FileArgs {
        files: vec![path.to_owned()],
        ..FileArgs::default()
    };
    for (key, value) in table.get_ref() {
        let at = |offset| Location::at(path, text, offset);
        let key_text = key.get_ref().to_string();
        let arg = option(command, key.get_ref()).ok_or_else(|| ConfigError::Key {
            at: at(key.span().start),
            key: key_text.clone(),
            why: format!("no such option; the options: {}", names(command).join(", ")),
        })?;
        let fault = |(why, offset)| ConfigError::Key {
            at: at(offset),
            key: key_text.clone(),
            why,
        };
        let value_span = value.span().start;
        let value = if takes(arg) == Takes::Switch {
            Value::Switch(switch(value).map_err(|why| fault((why, value.span().start)))?)
        } else {
            let given = words(takes(arg), value).map_err(fault)?;
            Value::Words(given.into_iter().map(|(v, o)| (v, at(o))).collect())
        };
        let given = Given {
            option: key_text.clone(),
            key: key_text.clone(),
            at: at(value_span),
            value,
        };
        out.add(arg, given)?;
    }
    Ok(out)
}

/// The options of subcommand `command` in mavlink-router's configuration
/// `doc`; the links go to its positional `links` (`fbwag router`) or,
/// without one, to `--out` (`fbwag cc`, whose FC link is `--link`).
fn load_mavlink_router(command: &Command, doc: &ini::Document) -> Result<FileArgs, ConfigError> {
    let mut out = FileArgs {
        files: doc.files.clone(),
        ..FileArgs::default()
    };
    let mut missing: Vec<Given> = Vec::new();
    for g in mavlink_router::settings(doc)? {
        let links = g.option == mavlink_router::LINKS && option(command, "links").is_none();
        let name = if links { "out" } else { g.option.as_str() };
        match option(command, name) {
            Some(arg) => out.add(arg, g)?,
            None => missing.push(g),
        }
    }
    // The first in the files' order.
    let place = |g: &Given| {
        let file = doc.files.iter().position(|f| *f == g.at.path);
        (file, g.at.line, g.at.column)
    };
    match missing.into_iter().min_by_key(place) {
        Some(g) => Err(ConfigError::Key {
            why: format!(
                "no equivalent in fbwag {}: it is fbwag router's --{}",
                command.get_name(),
                g.option
            ),
            at: g.at,
            key: g.key,
        }),
        None => Ok(out),
    }
}

/// The option a key names: its long name, `-` or `_` between words, or a
/// positional's name; never `config` itself, `print-config`, `help` or
/// `version`.
fn option<'c>(command: &'c Command, key: &str) -> Option<&'c Arg> {
    let key = key.replace('_', "-");
    command
        .get_arguments()
        .filter(|a| !not_in_files(a))
        .find(|a| match a.get_long() {
            Some(long) => long == key,
            None => a.is_positional() && a.get_id().as_str().replace('_', "-") == key,
        })
}

/// Options a file cannot give.
fn not_in_files(a: &Arg) -> bool {
    matches!(
        a.get_id().as_str(),
        "config" | "print_config" | "help" | "version"
    )
}

/// The keys a file may hold.
fn names(command: &Command) -> Vec<String> {
    command
        .get_arguments()
        .filter(|a| !not_in_files(a))
        .filter_map(|a| match a.get_long() {
            Some(long) => Some(long.replace('-', "_")),
            None => a.is_positional().then(|| a.get_id().to_string()),
        })
        .collect()
}

/// A switch's value: `true` or `false`.
fn switch(value: &Spanned<DeValue>) -> Result<bool, String> {
    match value.get_ref() {
        DeValue::Boolean(on) => Ok(*on),
        other => Err(format!("a switch: true or false, not {}", other.type_str())),
    }
}

/// The values of `value` for an option that `takes` them (not a switch):
/// a list option takes a list or one value; any other one value (a
/// string, a number). Each value as clap will see it, with the byte
/// offset of where the file gives it; an error with where the value at
/// fault is.
fn words(takes: Takes, value: &Spanned<DeValue>) -> Result<Vec<(String, usize)>, (String, usize)> {
    let one = |v: &Spanned<DeValue>| {
        let at = v.span().start;
        scalar(v.get_ref())
            .map(|s| (s, at))
            .map_err(|why| (why, at))
    };
    match value.get_ref() {
        DeValue::Array(items) if takes == Takes::Many => items.iter().map(one).collect(),
        DeValue::Array(_) => Err(("takes one value, not a list".into(), value.span().start)),
        _ => Ok(vec![one(value)?]),
    }
}

/// One value as the command line writes it.
fn scalar(value: &DeValue) -> Result<String, String> {
    match value {
        DeValue::String(s) => Ok(s.to_string()),
        DeValue::Integer(i) => {
            let digits = i.as_str().replace('_', "");
            i128::from_str_radix(&digits, i.radix())
                .map(|n| n.to_string())
                .map_err(|e| e.to_string())
        }
        DeValue::Float(f) => Ok(f.as_str().replace('_', "")),
        other => Err(format!("a string or a number, not {}", other.type_str())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::{CommandFactory, Parser};

    #[derive(Parser)]
    struct Demo {
        #[arg(value_name = "CONN", num_args = 2.., required = true)]
        links: Vec<String>,
        #[arg(long)]
        sign_key: Option<String>,
        #[arg(long)]
        require_signed: bool,
        #[arg(long = "out")]
        outs: Vec<String>,
        #[arg(long)]
        report: Option<f64>,
        #[arg(long)]
        config: Option<PathBuf>,
    }

    fn load_text(text: &str) -> Result<FileArgs, ConfigError> {
        let dir = std::env::temp_dir().join(format!("fbwag-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join(format!(
            "{:x}.toml",
            text.len() * 31 + text.as_bytes()[0] as usize
        ));
        std::fs::write(&path, text).unwrap();
        let r = load(&Demo::command(), &path);
        std::fs::remove_file(&path).unwrap();
        r
    }

    fn words(f: &FileArgs) -> Vec<String> {
        f.words()
            .map(|w| w.to_string_lossy().into_owned())
            .collect()
    }

    /// A fresh directory of the test's own.
    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("fbwag-config-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    /// The words `expand` adds to `fbwag demo ARGS`.
    fn expanded(args: Vec<OsString>) -> Result<Vec<String>, ConfigError> {
        let cli = Command::new("fbwag").subcommand(Demo::command().name("demo"));
        let argv = ["fbwag", "demo"]
            .map(OsString::from)
            .into_iter()
            .chain(args);
        let (_, file) = expand(&cli, argv.collect())?;
        Ok(file.map(|f| words(&f)).unwrap_or_default())
    }

    #[test]
    fn a_later_file_turns_a_switch_off() {
        let dir = scratch("switch");
        std::fs::write(dir.join("10-base.toml"), "require_signed = true\n").unwrap();
        let on = expanded(vec!["--config".into(), dir.clone().into()]).unwrap();
        assert!(on.iter().any(|w| w == "--require-signed"), "{on:?}");
        std::fs::write(dir.join("20-off.toml"), "require_signed = false\n").unwrap();
        let off = expanded(vec!["--config".into(), dir.clone().into()]).unwrap();
        assert!(!off.iter().any(|w| w == "--require-signed"), "{off:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A drop-in whose target is gone would take its keys with it unseen.
    #[cfg(unix)]
    #[test]
    fn a_dangling_link_in_a_directory_is_refused() {
        let dir = scratch("dangling");
        std::fs::write(dir.join("10-base.toml"), "report = 1\n").unwrap();
        std::os::unix::fs::symlink(dir.join("gone"), dir.join("40-key.toml")).unwrap();
        let e = expanded(vec!["--config".into(), dir.clone().into()]).unwrap_err();
        assert!(
            matches!(&e, ConfigError::Read { path, .. } if path.ends_with("40-key.toml")),
            "{e}"
        );
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// `--config=PATH` is read whatever PATH's encoding, as clap takes it.
    #[cfg(unix)]
    #[test]
    fn a_path_that_is_not_utf8_is_read() {
        use std::os::unix::ffi::{OsStrExt, OsStringExt};
        let dir = scratch("utf8");
        let name = std::ffi::OsStr::from_bytes(b"sec\xff.toml");
        std::fs::write(dir.join(name), "require_signed = true\n").unwrap();
        let mut arg = b"--config=".to_vec();
        arg.extend_from_slice(dir.join(name).as_os_str().as_bytes());
        let got = expanded(vec![OsString::from_vec(arg)]).unwrap();
        assert!(got.iter().any(|w| w == "--require-signed"), "{got:?}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn keys_become_the_options_of_the_command_line() {
        let f = load_text(
            "links = [\"udpin:0.0.0.0:1\", \"udpout:127.0.0.1:2\"]\n\
             sign-key = \"@/etc/key\"\nrequire_signed = true\nout = \"udpout:1.2.3.4:5\"\n\
             report = 0x10\n",
        )
        .unwrap();
        let mut got = words(&f);
        got.sort();
        assert_eq!(
            got,
            [
                "--out=udpout:1.2.3.4:5",
                "--report=16",
                "--require-signed",
                "--sign-key=@/etc/key",
                "udpin:0.0.0.0:1",
                "udpout:127.0.0.1:2",
            ]
        );
        let parsed =
            Demo::try_parse_from(std::iter::once(OsString::from("demo")).chain(f.words().cloned()))
                .unwrap();
        assert_eq!(parsed.links.len(), 2);
        assert_eq!(parsed.report, Some(16.0));
    }

    #[test]
    fn a_bad_file_is_refused_at_its_line_and_column() {
        let e = load_text("report = 1\nsign_kye = \"x\"\n").unwrap_err();
        assert!(
            matches!(&e, ConfigError::Key { at, key, .. } if at.line == 2 && at.column == 1 && key == "sign_kye"),
            "{e}"
        );
        assert!(e.to_string().contains("sign_key"), "lists the options: {e}");
        let e = load_text("report = 1\nrequire_signed = \"yes\"\n").unwrap_err();
        assert!(
            matches!(&e, ConfigError::Key { at, .. } if at.line == 2 && at.column == 18),
            "{e}"
        );
        let e = load_text("report = 1\n\nreport = [1, 2\n").unwrap_err();
        assert!(
            matches!(&e, ConfigError::Syntax { at, .. } if at.line == 3),
            "{e}"
        );
        for bad in ["report = [1, 2]\n", "config = \"x\"\n", "[table]\nx = 1\n"] {
            assert!(load_text(bad).is_err(), "{bad}");
        }
    }
}
