#!/usr/bin/env bash
# Builds the API docs of the published crates as docs.rs does (the features
# of each crate's [package.metadata.docs.rs]; warnings are errors), then
# reads the rendered pages under target/doc and fails on any link rustdoc
# left as text: `[name]` or `[path::to::item]` in a doc block, outside code.
# rustdoc's own lint misses those in docs inlined from another crate (a
# re-export) and in links to a crate whose pages are not there.
#
# Stable rustdoc: `--cfg docsrs` (the feature labels, nightly `doc_cfg`) is
# docs.rs's business; what is checked here is the text and its links.
# Needs cargo and python3.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
target="${CARGO_TARGET_DIR:-target}"

doc() {
    echo "==> cargo doc $*"
    RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --locked "$@"
}

# One crate after the crates it links to: rustdoc links into another crate's
# pages only if that crate's directory exists when it starts rendering, and
# cargo documents crates in parallel. bitflags and stateright: their trait
# docs are inlined on our pages (every flag set's `Flags` impl, fbwag-model's
# `Model` impl), and resolve into their own pages.
doc -p bitflags@2 -p stateright
doc -p mavframe --all-features
# fbwag-dialect: docs.rs's list, every feature but `codegen` (which generates
# the code the checked-in bindings hold). The crates after it ask for the
# same features of it and of mavframe, so neither is compiled again.
dialect="fbwag-dialect/serial,fbwag-dialect/tokio,fbwag-dialect/serde,fbwag-dialect/embedded-io-async"
doc -p fbwag-dialect --features serial,tokio,serde,embedded-io-async
doc -p fbwag-dialect-cc --all-features --features mavframe/embedded-io-async
doc -p fbwag-delegation --all-features --features "$dialect"
doc -p fbwag-model --features "$dialect"

echo "==> links left as text in target/doc"
python3 - "$target/doc" mavframe fbwag_dialect fbwag_dialect_cc fbwag_delegation fbwag_model <<'EOF'
import os, re, sys
from html.parser import HTMLParser

# `[`code`]` or `[a::path]` not followed by `(`: what rustdoc prints for an
# intra-doc link it could not resolve. A bare `[word]` is left alone: the
# MAVLink XML's own text has `[NaN]`, `char[N]`, and rustdoc's lint already
# reports those in our crates.
LINK = re.compile(
    r"\[(`[^`\]]+`|[A-Za-z_]\w*(?:::[A-Za-z_]\w*)+(?:\(\))?!?)\](?![(\[])"
)
OPEN, CLOSE = "\u2039", "\u203a"  # brackets inside code, kept out of the match


class Page(HTMLParser):
    """Collects the text of every doc block, code spans marked with `."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.divs, self.doc, self.pre, self.code = [], 0, 0, 0
        self.text, self.found = [], []

    def handle_starttag(self, tag, attrs):
        if tag == "div":
            is_doc = "docblock" in (dict(attrs).get("class") or "").split()
            self.divs.append(is_doc)
            self.doc += is_doc
        elif tag == "pre":
            self.pre += 1
        elif tag == "code":
            self.code += 1
            self.mark()

    def handle_endtag(self, tag):
        if tag == "div" and self.divs:
            if self.divs.pop():
                self.doc -= 1
                if not self.doc:
                    self.flush()
        elif tag == "pre":
            self.pre -= 1
        elif tag == "code":
            self.code -= 1
            self.mark()

    def mark(self):
        if self.doc and not self.pre:
            self.text.append("`")

    def handle_data(self, data):
        if self.doc and not self.pre:
            if self.code:
                data = data.replace("[", OPEN).replace("]", CLOSE).replace("`", "'")
            self.text.append(data)

    def flush(self):
        text, self.text = "".join(self.text), []
        for m in LINK.finditer(text):
            around = " ".join(text[max(0, m.start() - 40) : m.end() + 20].split())
            self.found.append((m.group(0).replace("`", ""), around))


root, crates = sys.argv[1], sys.argv[2:]
bad = 0
for crate in crates:
    pages = 0
    for d, _, files in os.walk(os.path.join(root, crate)):
        for f in sorted(files):
            if not f.endswith(".html"):
                continue
            pages += 1
            path = os.path.join(d, f)
            page = Page()
            with open(path, encoding="utf-8") as html:
                page.feed(html.read())
            page.close()
            for link, around in page.found:
                print(f"{os.path.relpath(path, root)}: {link} in \"{around}\"")
                bad += 1
    if not pages:
        sys.exit(f"{root}/{crate}: no pages")
print(f"{bad} link(s) left as text" if bad else "none")
sys.exit(1 if bad else 0)
EOF
