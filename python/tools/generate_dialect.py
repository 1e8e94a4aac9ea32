#!/usr/bin/env python3
"""Generate the FBWAG dialect modules of this package with pymavlink's own
generator (pymavlink 2.4.50's mavgen, language Python3) from
message_definitions/fbwag.xml:

    python/dialects/v10/fbwag.py   wire protocol 1.0 (no FBWAG_NOTICE: ids
                                   above 255 do not exist in MAVLink 1)
    python/dialects/v20/fbwag.py   wire protocol 2.0

The wheel installs them as pymavlink.dialects.v10.fbwag and
pymavlink.dialects.v20.fbwag (python/pyproject.toml).

    python3 python/tools/generate_dialect.py           rewrite both files
    python3 python/tools/generate_dialect.py --check   exit 1 if either differs

Run it with a Python that has pymavlink==2.4.50 (e.g. target/pyenv/bin/python
from scripts/python-env.sh): another version's mavgen writes other code.
"""
import argparse
import contextlib
import io
import os
import sys
import tempfile

PYMAVLINK_VERSION = "2.4.50"
HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE_ROOT = os.path.dirname(HERE)
REPO = os.path.dirname(PACKAGE_ROOT)
XML = os.path.join(REPO, "message_definitions", "fbwag.xml")
WIRES = {"v10": "1.0", "v20": "2.0"}


def checked_in(sub):
    """Path of the checked-in module for one wire protocol ("v10", "v20")."""
    return os.path.join(PACKAGE_ROOT, "dialects", sub, "fbwag.py")


def require_pinned_pymavlink():
    import pymavlink

    if pymavlink.__version__ != PYMAVLINK_VERSION:
        raise RuntimeError("pymavlink %s is pinned, this Python has %s (%s)"
                           % (PYMAVLINK_VERSION, pymavlink.__version__, sys.executable))


def generate(sub, xml=XML):
    """The module mavgen writes for one wire protocol, as bytes."""
    from pymavlink.generator import mavgen, mavparse

    protocol = {"1.0": mavparse.PROTOCOL_1_0, "2.0": mavparse.PROTOCOL_2_0}[WIRES[sub]]
    # The output's file name becomes the module's DIALECT constant.
    with tempfile.TemporaryDirectory(prefix="fbwag-mavgen-") as tmp:
        out = os.path.join(tmp, "fbwag.py")
        opts = mavgen.Opts(output=out, wire_protocol=protocol, language="Python3")
        # mavgen reports its progress (and XML warnings) on stdout: shown
        # only when it fails.
        chatter = io.StringIO()
        with contextlib.redirect_stdout(chatter):
            ok = mavgen.mavgen(opts, [xml])
        if not ok or not os.path.exists(out):
            sys.stderr.write(chatter.getvalue())
            raise RuntimeError("pymavlink mavgen failed on %s (wire %s)" % (xml, WIRES[sub]))
        with open(out, "rb") as f:
            return f.read()


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0].replace("\n", " "))
    p.add_argument("--check", action="store_true",
                   help="write nothing; exit 1 if a checked-in module differs")
    args = p.parse_args()
    require_pinned_pymavlink()
    stale = []
    for sub in WIRES:
        fresh = generate(sub)
        path = checked_in(sub)
        with open(path, "rb") as f:
            current = f.read() if os.path.exists(path) else b""
        if current == fresh:
            print("up to date %s" % os.path.relpath(path, REPO))
            continue
        stale.append(os.path.relpath(path, REPO))
        if not args.check:
            with open(path, "wb") as f:
                f.write(fresh)
            print("written %s" % os.path.relpath(path, REPO))
    if args.check and stale:
        print("stale (run python/tools/generate_dialect.py): %s" % ", ".join(stale),
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
