#!/usr/bin/env python3
"""The table of benches/scripts/router_compare.sh from router_load's lines.

    router_compare.py RAW [FIRST_ROUTER SECOND_ROUTER]

Ratios are FIRST ÷ SECOND (default fbwag ÷ mavlink-routerd), each from the
same run; every row says which way is better. CPU per frame divides the
router's CPU by the frames it read (sent minus those the kernel dropped at
its input socket), so work on frames it never saw is not counted.
"""
import sys


def load(path):
    with open(path) as f:
        lines = [l.split() for l in f if l.strip()]
    head, rows = lines[0], lines[1:]
    out = {}
    for r in rows:
        d = dict(zip(head, r))
        for k in head[2:]:
            d[k] = float(d[k])
        out[(d["router"], d["phase"])] = d
    return out


def fmt(v, unit=""):
    if v is None:
        return "n/a"
    if v >= 100000:
        return f"{v:,.0f}{unit}"
    if v >= 100:
        return f"{v:,.0f}{unit}"
    if v >= 10:
        return f"{v:.1f}{unit}"
    return f"{v:.2f}{unit}"


def throughput(d):
    return d["delivered"] / d["wall_s"] if d["wall_s"] > 0 else None


def loss(d):
    """Loss in %, and where: router input socket / router / sink socket."""
    if not d["sent"]:
        return "n/a"
    k = d["per_dgram"]
    at_in = d["in_drops"] * k
    at_sink = d["out_drops"]
    inside = max(d["read"] - d["delivered"] - at_sink, 0)
    total = 100 * (d["sent"] - d["delivered"]) / d["sent"]
    return (f"{total:.1f} % (input {100 * at_in / d['sent']:.1f}, "
            f"router {100 * inside / d['sent']:.1f}, sink {100 * at_sink / d['sent']:.1f})")


def cpu_us(d, field):
    if not d["read"]:
        return None
    secs = d["cpu_stat_s"] if field == "stat" else d["cpu_sched_ns"] / 1e9
    return secs / d["read"] * 1e6


def busy(d):
    return 100 * d["cpu_sched_ns"] / 1e9 / (d["wall_s"] + 0.3)


def main():
    raw = load(sys.argv[1])
    a, b = (sys.argv[2], sys.argv[3]) if len(sys.argv) > 3 else ("fbwag", "mavlink-routerd")
    rows = []

    def row(name, fn, better, unit=""):
        va = fn(raw[(a, phase)]) if (a, phase) in raw else None
        vb = fn(raw[(b, phase)]) if (b, phase) in raw else None
        ratio = f"{va / vb:.2f}" if isinstance(va, float) and isinstance(vb, float) and vb else "n/a"
        show = (lambda v: v if isinstance(v, str) else fmt(v, unit))
        rows.append((name, show(va), show(vb), ratio, better))

    for phase, label in (("sat1", "1 frame/datagram"), ("sat10", "10 frames/datagram")):
        row(f"saturation, {label}: frames/s delivered", throughput, "higher")
        row(f"… loss", loss, "")
        row(f"… router CPU busy", busy, "", " %")
        row(f"… CPU µs/frame (stat)", lambda d: cpu_us(d, "stat"), "lower")
        row(f"… CPU µs/frame (schedstat)", lambda d: cpu_us(d, "sched"), "lower")
        row(f"… CPU µs per frame delivered (schedstat)",
            lambda d: d["cpu_sched_ns"] / 1e3 / d["delivered"] if d["delivered"] else None, "lower")
        row(f"… frames per CPU-second (a whole core's capacity)",
            lambda d: 1e6 / cpu_us(d, "sched") if cpu_us(d, "sched") else None, "higher")
    for phase, label in (("r2000", "2,000"), ("r20000", "20,000")):
        row(f"{label} frames/s: frames/s delivered", throughput, "")
        row(f"… loss", loss, "")
        row(f"… CPU µs/frame (stat)", lambda d: cpu_us(d, "stat"), "lower")
        row(f"… CPU µs/frame (schedstat)", lambda d: cpu_us(d, "sched"), "lower")
    phase = "lat1000"
    row("1,000 frames/s: latency median µs", lambda d: d["p50_us"] if d["p50_us"] >= 0 else None, "lower")
    row("… latency p99 µs", lambda d: d["p99_us"] if d["p99_us"] >= 0 else None, "lower")
    row("… loss", loss, "")

    print(f"| | {a} | {b} | {a} ÷ {b} | better |")
    print("|---|---:|---:|---:|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")
    bad = [(k, d) for k, d in raw.items() if d["bad"] or d["stale"] or d["disorder"]]
    print()
    if bad:
        for (r, p), d in bad:
            print(f"CHECK: {r} {p}: {d['bad']:.0f} bad, {d['stale']:.0f} stale, "
                  f"{d['disorder']:.0f} out of order frames at the sink")
    else:
        print("Sink checks: every frame delivered had a good CRC, its type's length, "
              "the current phase's counter and its system's order.")


if __name__ == "__main__":
    main()
