#!/usr/bin/env python3
"""Markdown tables, with ratios, from the criterion results of the last
`cargo bench -p benches` (target/criterion/*/…/new/).

    cargo bench -p benches && python3 benches/scripts/report.py

Times are criterion's median estimates. A ratio "ours / theirs" above 1 means
fbwag-dialect is faster. Results of benchmarks run at different times mix
machine states: run the whole suite in one go before reporting.
"""
import glob
import json
import math
import os
import sys

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
ROOT = os.path.join(os.environ.get("CARGO_TARGET_DIR", os.path.join(REPO, "target")), "criterion")


def load():
    out = {}
    for bench in glob.glob(os.path.join(ROOT, "**", "new", "benchmark.json"), recursive=True):
        with open(bench) as f:
            b = json.load(f)
        with open(os.path.join(os.path.dirname(bench), "estimates.json")) as f:
            e = json.load(f)
        key = (b["group_id"], b["function_id"], b["value_str"])
        out[key] = {"ns": e["median"]["point_estimate"], "throughput": b.get("throughput")}
    return out


R = load()
if not R:
    sys.exit("no criterion results under %s: run `cargo bench -p benches` first" % ROOT)


def get(group, function, value=None):
    """A result by group, function and value; `BenchmarkId::new("a", "b")`
    and a plain "a/b" name are the same benchmark here."""
    if value is None and "/" in function:
        f, v = function.split("/", 1)
        return R.get((group, function, None)) or R.get((group, f, v))
    return R.get((group, function, value)) or R.get((group, "%s/%s" % (function, value), None))


def fmt_ns(ns):
    return "%.0f" % ns if ns >= 100 else "%.1f" % ns


def mibs(r):
    return r["throughput"]["Bytes"] / (r["ns"] * 1e-9) / 2**20


def geomean(xs):
    return math.exp(sum(math.log(x) for x in xs) / len(xs)) if xs else float("nan")


def stream_decode():
    rows = {k[1]: (v, k[2]) for k, v in R.items() if k[0] == "stream_decode"}
    if not rows:
        return
    frames = int(next(iter(rows.values()))[1] or 0)
    print("### Stream decode (criterion)\n")
    print("| decoder | MiB/s | M frames/s | ns/frame |")
    print("|---|---:|---:|---:|")
    for name in ["fbwag/views", "mavlink/raw", "fbwag/owned", "mavlink/owned",
                 "fbwag/views_all", "fbwag/owned_all", "mavlink/owned_all"]:
        if name in rows:
            r = rows[name][0]
            print("| %s | %.0f | %.2f | %.1f |" % (name, mibs(r), frames / (r["ns"] * 1e-9) / 1e6, r["ns"] / frames))
    print()
    for ours, theirs in [("fbwag/views", "mavlink/raw"), ("fbwag/views", "mavlink/owned"),
                         ("fbwag/owned", "mavlink/owned"),
                         ("fbwag/views_all", "mavlink/owned_all"),
                         ("fbwag/owned_all", "mavlink/owned_all")]:
        if ours in rows and theirs in rows:
            print("- %s vs %s: **%.2f×**" % (ours, theirs, rows[theirs][0]["ns"] / rows[ours][0]["ns"]))
    print()


def encode():
    for group, title in [("encode", "unsigned"), ("encode_signed", "signed")]:
        names = sorted({k[2] for k in R if k[0] == group and k[1] == "fbwag"} |
                       {k[1].split("/", 1)[1] for k in R if k[0] == group and "/" in k[1]})
        rows = []
        for n in names:
            o = get(group, "fbwag", n) or get(group, "fbwag/" + n)
            t = get(group, "mavlink", n) or get(group, "mavlink/" + n)
            if o and t:
                rows.append((n, o["ns"], t["ns"]))
        if not rows:
            continue
        print("### Encode, one frame, MAVLink 2 %s (criterion)\n" % title)
        print("| message | fbwag (ns) | mavlink (ns) | mavlink / fbwag |")
        print("|---|---:|---:|---:|")
        for n, o, t in rows:
            print("| %s | %s | %s | %.2f |" % (n, fmt_ns(o), fmt_ns(t), t / o))
        ratios = [t / o for _, o, t in rows]
        print("| **geometric mean** (%d types) | | | **%.2f** (min %.2f, max %.2f) |" % (
            len(rows), geomean(ratios), min(ratios), max(ratios)))
        print()
    if any(k[0] == "encode_mix" for k in R):
        print("### Encode the capture's mix of types, in its order (criterion)\n")
        print("| | fbwag (ns/frame) | mavlink (ns/frame) | mavlink / fbwag |")
        print("|---|---:|---:|---:|")
        for kind in ["unsigned", "signed"]:
            o, t = get("encode_mix", "fbwag", kind), get("encode_mix", "mavlink", kind)
            if o and t:
                n = o["throughput"]["Elements"]
                print("| %s | %.1f | %.1f | %.2f |" % (kind, o["ns"] / n, t["ns"] / n, t["ns"] / o["ns"]))
        print()


def notice():
    if not any(k[0] in ("notice_encode", "notice_decode") for k in R):
        return
    print("### FBWAG_NOTICE per frame (criterion)\n")
    print("| | fbwag (ns/frame) | mavlink (ns/frame) | mavlink / fbwag |")
    print("|---|---:|---:|---:|")
    for kind in ["unsigned", "signed"]:
        o, t = get("notice_encode", "fbwag", kind), get("notice_encode", "mavlink", kind)
        if o and t:
            print("| encode, %s | %s | %s | %.2f |" % (kind, fmt_ns(o["ns"]), fmt_ns(t["ns"]), t["ns"] / o["ns"]))
    t = get("notice_decode", "mavlink/owned")
    for kind in ["views", "owned"]:
        o = get("notice_decode", "fbwag/" + kind)
        if o and t:
            n = o["throughput"]["Elements"]
            print("| decode to %s (mavlink: owned), stream of %d | %s | %s | %.2f |" % (
                kind, n, fmt_ns(o["ns"] / n), fmt_ns(t["ns"] / n), t["ns"] / o["ns"]))
    print()


def crc():
    rows = {k[1]: v for k, v in R.items() if k[0] == "crc"}
    if not rows:
        return
    print("### Frame checksum alone (criterion)\n")
    print("| implementation | MiB/s | / crc-any |")
    print("|---|---:|---:|")
    base = rows.get("crc_any")
    for name in ["mavframe_slice16", "spec_bytewise", "crc_any"]:
        if name in rows:
            print("| %s | %.0f | %s |" % (name, mibs(rows[name]), "%.2f" % (base["ns"] / rows[name]["ns"]) if base else ""))
    print()


stream_decode()
encode()
notice()
crc()
