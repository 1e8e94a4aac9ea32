#!/usr/bin/env python3
"""Print pymavlink's view of a MAVLink dialect, one message per line:

    ID NAME CRC_EXTRA MIN_LEN MAX_LEN

usage: table.py XML               the dialect XML plus everything it includes
       table.py --all-shipped DIR "# FILE" header + table for every DIR/*.xml

The reference for our Rust generator. Rather than re-implementing pymavlink's
include handling, we run pymavlink's own mavgen() front end (XSD validation,
include expansion relative to the including file, duplicate checks, enum
merging, CRC merging) for wire protocol 2.0 with a language that generates
nothing, and capture the list of parsed files it builds. That list is a local
of mavgen(), so we read it from its call to mavparse.total_msgs(). Everything
pymavlink prints goes to stderr; stdout carries only the table.
"""
import contextlib
import os
import sys

from pymavlink.generator import mavgen, mavparse


def load(path):
    """Return the MAVXML objects mavgen builds for `path` (root first)."""
    captured = []
    real_total_msgs = mavparse.total_msgs

    def spy(xml):
        captured.append(list(xml))
        return real_total_msgs(xml)

    # "none" is not a language: mavgen prints "Unsupported language" and
    # returns True after the front end has run, writing no files.
    opts = mavgen.Opts(output=os.devnull, wire_protocol=mavparse.PROTOCOL_2_0,
                       language="none")
    mavparse.total_msgs = spy
    try:
        with contextlib.redirect_stdout(sys.stderr):
            ok = mavgen.mavgen(opts, [path])
    finally:
        mavparse.total_msgs = real_total_msgs
    if not ok or not captured:
        sys.exit("table.py: pymavlink mavgen rejected %s" % path)
    return captured[-1]


def table(path):
    xml = load(path)
    # Python output uses every file's message objects; C output uses the root
    # file's merged dicts. Insist both views agree, so either can be trusted.
    root = xml[0]
    rows = []
    for x in xml:
        for m in x.message:
            row = (m.id, m.name, m.crc_extra, m.wire_min_length, m.wire_length)
            merged = (m.id, root.message_names.get(m.id),
                      root.message_crcs.get(m.id),
                      root.message_min_lengths.get(m.id),
                      root.message_lengths.get(m.id))
            if row != merged:
                sys.exit("table.py: %s: message %s from %s not merged into "
                         "root: %r != %r" % (path, m.name, x.filename, row, merged))
            rows.append(row)
    if len(rows) != len(root.message_crcs):
        sys.exit("table.py: %s: %u messages but %u merged CRCs"
                 % (path, len(rows), len(root.message_crcs)))
    return sorted(rows)


def main(argv):
    if len(argv) == 2 and not argv[1].startswith("-"):
        files = [(None, argv[1])]
    elif len(argv) == 3 and argv[1] == "--all-shipped":
        d = argv[2]
        files = [(f, os.path.join(d, f))
                 for f in sorted(os.listdir(d)) if f.endswith(".xml")]
    else:
        sys.exit("usage: table.py XML | table.py --all-shipped DIR")
    out = []
    for header, path in files:
        if header is not None:
            out.append("# %s" % header)
        out.extend("%u %s %u %u %u" % r for r in table(path))
    sys.stdout.write("".join(line + "\n" for line in out))


if __name__ == "__main__":
    main(sys.argv)
