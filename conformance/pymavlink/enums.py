#!/usr/bin/env python3
"""Print pymavlink's merged enums of a dialect, one entry per line:

    ENUM_NAME ENTRY_NAME VALUE

usage: enums.py XML...   a "# FILE" header before each file's entries

Runs pymavlink's own mavgen front end (as table.py does) so includes are
expanded and enums merged exactly as pymavlink merges them, including the
renumbering of auto-valued entries. The *_ENUM_END markers pymavlink appends
are left out: they are not part of the XML.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from table import load  # noqa: E402


def main(paths):
    out = []
    for path in paths:
        out.append("# %s" % os.path.basename(path))
        rows = set()
        for x in load(path):
            for e in x.enum:
                for entry in e.entry:
                    if not entry.end_marker:
                        rows.add((e.name, entry.name, int(entry.value)))
        out.extend("%s %s %d" % r for r in sorted(rows))
    print("\n".join(out))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: enums.py XML...")
    main(sys.argv[1:])
