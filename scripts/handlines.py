"""Hand-written lines of Rust outside tests, per directory: the .rs files
under each DIR at git revision REV (or in the work tree: WORKTREE), without
blank lines, comment lines, `#[cfg(test)]` items (brace-matched) and files
named tests.rs or test_dialect.rs.

Usage: python3 scripts/handlines.py REV|WORKTREE DIR...
  e.g. python3 scripts/handlines.py HEAD mavframe/src fbwag-cli/src"""
import subprocess, sys, re
rev, dirs = sys.argv[1], sys.argv[2:]
def files():
    if rev == "WORKTREE":
        out = subprocess.check_output(["git", "ls-files", "--others", "--cached", "--exclude-standard", *dirs], text=True)
    else:
        out = subprocess.check_output(["git", "ls-tree", "-r", "--name-only", rev, *dirs], text=True)
    return [f for f in out.split() if f.endswith(".rs") and not f.endswith(("/tests.rs", "test_dialect.rs"))]
def text(f):
    if rev == "WORKTREE":
        try: return open(f).read()
        except FileNotFoundError: return ""
    return subprocess.check_output(["git", "show", f"{rev}:{f}"], text=True)
def count(src):
    lines = src.split("\n"); n = 0; i = 0
    while i < len(lines):
        l = lines[i].strip()
        if l.startswith("#[cfg(test)]"):
            # skip the item: until braces balance after the first '{' (or a ';' line)
            depth = 0; started = False; i += 1
            while i < len(lines):
                s = lines[i]; depth += s.count("{") - s.count("}")
                if "{" in s: started = True
                i += 1
                if (started and depth <= 0) or (not started and s.strip().endswith(";")): break
            continue
        if l and not l.startswith("//"): n += 1
        i += 1
    return n
total = 0
for d in dirs:
    t = sum(count(text(f)) for f in files() if f.startswith(d))
    print(f"{d}: {t}"); total += t
