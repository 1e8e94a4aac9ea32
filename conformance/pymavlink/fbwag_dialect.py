#!/usr/bin/env python3
"""pymavlink's own Python bindings for the FBWAG dialect, generated on demand.

pymavlink 2.4.50 does not ship message_definitions/fbwag.xml, so this helper
runs pymavlink's generator (``pymavlink.generator.mavgen``, language Python3)
on it and imports the result:

    import fbwag_dialect
    mav = fbwag_dialect.load()          # wire protocol 2.0 (the default)
    assert mav.MAVLink_fbwag_notice_message.crc_extra == 30

The generated module is cached as
``target/pymavlink-fbwag/pymavlink-<version>-wire<wire>/fbwag.py`` and is only
regenerated when it is missing or older than fbwag.xml or any XML file it
includes (transitively). It is written to a temporary name and renamed into
place, so concurrent callers never import a half-written file. Everything
mavgen prints goes to stderr.

Running this file directly generates (if needed) and prints the path of the
generated module.
"""
import contextlib
import importlib.util
import os
import re
import shutil
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.normpath(os.path.join(HERE, "..", ".."))
DEFAULT_XML = os.path.join(REPO, "message_definitions", "fbwag.xml")
CACHE = os.path.join(REPO, "target", "pymavlink-fbwag")

_INCLUDE = re.compile(r"<include>\s*([^<]+?)\s*</include>")
_loaded = {}


def xml_closure(xml):
    """fbwag.xml and every file it includes, transitively (absolute paths).

    Includes resolve relative to the including file, as in mavgen."""
    seen = []
    todo = [os.path.abspath(xml)]
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.append(path)
        with open(path, encoding="utf-8") as f:
            text = f.read()
        # Drop comments so a commented-out <include> does not count.
        text = re.sub(r"<!--.*?-->", "", text, flags=re.S)
        for inc in _INCLUDE.findall(text):
            todo.append(os.path.abspath(os.path.join(os.path.dirname(path), inc)))
    return seen


def generated_path(wire="2.0"):
    import pymavlink
    tag = "pymavlink-%s-wire%s" % (pymavlink.__version__, wire)
    return os.path.join(CACHE, tag, "fbwag.py")


def _stale(py, xml):
    if not os.path.exists(py):
        return True
    built = os.path.getmtime(py)
    return any(os.path.getmtime(x) > built for x in xml_closure(xml))


def generate(wire="2.0", xml=DEFAULT_XML, force=False):
    """Generate the bindings if needed; return the path of the .py file."""
    from pymavlink.generator import mavgen, mavparse

    protocols = {"1.0": mavparse.PROTOCOL_1_0, "2.0": mavparse.PROTOCOL_2_0}
    if wire not in protocols:
        raise ValueError("wire must be '1.0' or '2.0', not %r" % (wire,))
    py = generated_path(wire)
    if not force and not _stale(py, xml):
        return py
    os.makedirs(os.path.dirname(py), exist_ok=True)
    # The file name becomes the module's DIALECT constant, so generate
    # "fbwag.py" inside a private temporary directory, then rename it.
    tmpdir = tempfile.mkdtemp(prefix=".gen-", dir=os.path.dirname(py))
    tmp = os.path.join(tmpdir, "fbwag.py")
    opts = mavgen.Opts(output=tmp, wire_protocol=protocols[wire], language="Python3")
    try:
        with contextlib.redirect_stdout(sys.stderr):
            ok = mavgen.mavgen(opts, [xml])
        if not ok or not os.path.exists(tmp):
            raise RuntimeError("pymavlink mavgen failed on %s (wire %s)" % (xml, wire))
        os.replace(tmp, py)
    finally:
        shutil.rmtree(tmpdir, ignore_errors=True)
    return py


def load(wire="2.0", xml=DEFAULT_XML):
    """Import (generating first if needed) pymavlink's bindings for fbwag.xml.

    Returns the module: it has pymavlink's usual API (``MAVLink``,
    ``MAVLink_<name>_message`` classes, ``mavlink_map``, ``enums``...)."""
    key = (wire, os.path.abspath(xml))
    if key in _loaded:
        return _loaded[key]
    py = generate(wire, xml)
    name = "pymavlink_fbwag_wire%s" % wire.replace(".", "")
    spec = importlib.util.spec_from_file_location(name, py)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    spec.loader.exec_module(mod)
    _loaded[key] = mod
    return mod


def wire_min_lengths(xml=DEFAULT_XML):
    """{msgid: wire_min_length} as pymavlink's parser (mavparse) computes it:
    the payload length without extension fields, which is what a MAVLink 1
    frame carries when sent by the C library (ArduPilot). The generated
    Python module does not record it."""
    from pymavlink.generator import mavparse

    out = {}
    # mavparse's chatter (enum warnings) is dropped: this is a query, and a
    # malformed file raises anyway.
    with open(os.devnull, "w") as null, contextlib.redirect_stdout(null):
        for path in xml_closure(xml):
            for m in mavparse.MAVXML(path, mavparse.PROTOCOL_2_0).message:
                out[m.id] = m.wire_min_length
    return out


if __name__ == "__main__":
    w = sys.argv[1] if len(sys.argv) > 1 else "2.0"
    m = load(w)
    if w == "2.0":  # wire 1.0 drops ids > 255, FBWAG_NOTICE included
        assert m.MAVLink_fbwag_notice_message.crc_extra == 30
    print(generated_path(w))
