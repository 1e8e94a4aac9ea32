//! Name collisions in the generated Rust, found before any code is built.

use super::{Gen, VIEW_METHODS};
use crate::diag::{Diagnostic, Severity};
use crate::names::{self, camel, ident};
use std::collections::HashMap;

impl Gen<'_> {
    pub(super) fn check_names(&self) -> Vec<Diagnostic> {
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
}
