#!/usr/bin/env python3
"""The table of benches/scripts/router_compare.sh from router_load's lines.

    router_compare.py RAW [FIRST_ROUTER SECOND_ROUTER [REFERENCE]]

One column per router, in the order given (default fbwag, mavlink-routerd,
bare-forward when present). With a reference, a second table: FIRST's
bounds, each a ratio from this run (latency and saturation against SECOND,
CPU per frame at 2,000 frames/s against REFERENCE), met or missed. Each figure adds up the router's slices of the
phase (latency: the median of the slices' medians and p99s). The ratio is
FIRST ÷ SECOND over the whole phase, and REFERENCE ÷ SECOND: how far
below SECOND a program that only forwards gets on this machine. Beside
each, in brackets, the lowest and highest ratio of a slice against the
slice that ran next to it, which shows how much of a difference the
machine's noise can make. Every row says
which way is better. CPU per frame divides the router's CPU by the frames it
read (sent minus those the kernel dropped at its input socket), so work on
frames it never saw is not counted.
"""
import statistics
import sys

COUNTS = ("sent", "read", "delivered", "bad", "stale", "disorder", "in_drops",
          "out_drops", "cpu_stat_s", "cpu_sched_ns", "load_s", "wall_s")


def load(path):
    """{(router, phase): [slice, ...]}, each slice a dict of its fields."""
    with open(path) as f:
        lines = [l.split() for l in f if l.strip()]
    head, rows = lines[0], lines[1:]
    out = {}
    for r in rows:
        d = dict(zip(head, r))
        for k in head[2:]:
            d[k] = float(d[k])
        out.setdefault((d["router"], d["phase"]), []).append(d)
    return out


def total(slices):
    """The phase as one: counts added up, latency the median over slices."""
    d = {k: sum(s[k] for s in slices) for k in COUNTS}
    d["per_dgram"] = slices[0]["per_dgram"]
    for k in ("p50_us", "p99_us"):
        seen = [s[k] for s in slices if s[k] >= 0]
        d[k] = statistics.median(seen) if seen else -1
    return d


def fmt(v, unit=""):
    if v is None:
        return "n/a"
    if v >= 100:
        return f"{v:,.0f}{unit}"
    if v >= 10:
        return f"{v:.1f}{unit}"
    return f"{v:.2f}{unit}"


def throughput(d):
    return d["delivered"] / d["load_s"] if d["load_s"] > 0 else None


def loss(d):
    """Loss in %, and where: router input socket / router / sink socket."""
    if not d["sent"]:
        return "n/a"
    k = d["per_dgram"]
    at_in = d["in_drops"] * k
    at_sink = d["out_drops"]
    inside = max(d["read"] - d["delivered"] - at_sink, 0)
    pct = lambda n: 100 * n / d["sent"]
    return (f"{pct(d['sent'] - d['delivered']):.1f} % (input {pct(at_in):.1f}, "
            f"router {pct(inside):.1f}, sink {pct(at_sink):.1f})")


def cpu_us(d, field="sched"):
    if not d["read"]:
        return None
    secs = d["cpu_stat_s"] if field == "stat" else d["cpu_sched_ns"] / 1e9
    return secs / d["read"] * 1e6


def busy(d):
    """CPU over the time it was measured (the load and the drain)."""
    return 100 * d["cpu_sched_ns"] / 1e9 / d["wall_s"] if d["wall_s"] > 0 else None


def latency(key):
    return lambda d: d[key] if d[key] >= 0 else None


def ratio(fn, a, b):
    """a ÷ b over the phase, and the range of the paired slices' ratios."""
    def quotient(x, y):
        vx, vy = fn(x), fn(y)
        ok = isinstance(vx, float) and isinstance(vy, float) and vy
        return vx / vy if ok else None

    whole = quotient(total(a), total(b))
    if whole is None:
        return "n/a"
    pairs = [q for q in map(quotient, a, b) if q is not None]
    spread = f" [{min(pairs):.2f}–{max(pairs):.2f}]" if len(pairs) > 1 else ""
    return f"**{whole:.2f}**{spread}"


def table(raw, routers):
    a, b = routers[0], routers[1]
    rows = []

    def row(phase, name, fn, better, unit="", paired=True):
        def show(r):
            if (r, phase) not in raw:
                return "n/a"
            v = fn(total(raw[(r, phase)]))
            return v if isinstance(v, str) else fmt(v, unit)
        def against_b(x):
            both = (x, phase) in raw and (b, phase) in raw
            return ratio(fn, raw[(x, phase)], raw[(b, phase)]) if both and paired else ""
        rows.append([name] + [show(x) for x in routers] + [against_b(a)]
                    + [against_b(x) for x in routers[2:]] + [better])

    for phase, label in (("sat1", "1 frame/datagram"), ("sat10", "10 frames/datagram")):
        row(phase, f"saturation, {label}: frames/s delivered", throughput, "higher")
        row(phase, "… loss", loss, "", paired=False)
        row(phase, "… router CPU busy", busy, "", " %", paired=False)
        row(phase, "… CPU µs/frame (stat)", lambda d: cpu_us(d, "stat"), "lower", paired=False)
        row(phase, "… CPU µs/frame (schedstat)", cpu_us, "lower")
    for phase, label in (("r2000", "2,000"), ("r20000", "20,000")):
        row(phase, f"{label} frames/s: frames/s delivered", throughput, "", paired=False)
        row(phase, "… loss", loss, "", paired=False)
        row(phase, "… CPU µs/frame (schedstat)", cpu_us, "lower")
    row("lat1000", "1,000 frames/s: latency median µs", latency("p50_us"), "lower")
    row("lat1000", "… latency p99 µs", latency("p99_us"), "lower")
    row("lat1000", "… loss", loss, "", paired=False)

    # A reference (the bare forwarder) against the second router shows how
    # far below the second any program can go on this machine.
    references = "".join(f" {x} ÷ {b} |" for x in routers[2:])
    print("| | " + " | ".join(routers) + f" | {a} ÷ {b} [slices] |{references} better |")
    print("|---|" + "---:|" * (len(routers) + 1 + len(routers[2:])) + "---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")


def quotient(fn, a, b):
    """a ÷ b over the phase, and the paired slices' lowest and highest."""
    va, vb = fn(total(a)), fn(total(b))
    if not (isinstance(va, float) and isinstance(vb, float) and vb):
        return None, None
    pairs = [fn(x) / fn(y) for x, y in zip(a, b)
             if isinstance(fn(x), float) and isinstance(fn(y), float) and fn(y)]
    return va / vb, (min(pairs), max(pairs)) if pairs else None


def bounds(raw, first, second, reference):
    """The targets of FIRST, each a ratio against SECOND or REFERENCE from
    this run, met or not."""
    rows = [
        ("lat1000", "1,000 frames/s: latency median", latency("p50_us"), second, "≤", 1.0, " µs"),
        ("r2000", "2,000 frames/s: CPU per frame", cpu_us, reference, "≤", 1.1, " µs"),
        ("sat1", "saturation, 1 frame/datagram: frames/s delivered", throughput, second, "≥", 1.5, ""),
        ("sat1", "… CPU per frame", cpu_us, second, "≤", 0.6, " µs"),
        ("sat10", "saturation, 10 frames/datagram: frames/s delivered", throughput, second, "≥", 1.5, ""),
        ("sat10", "… CPU per frame", cpu_us, second, "≤", 0.6, " µs"),
    ]
    print(f"| {first}'s bounds | {first} | against | ratio [slices] | target | |")
    print("|---|---:|---:|---:|---:|---|")
    for phase, name, fn, other, way, target, unit in rows:
        if (first, phase) not in raw or (other, phase) not in raw:
            continue
        a, b = raw[(first, phase)], raw[(other, phase)]
        q, spread = quotient(fn, a, b)
        if q is None:
            continue
        met = q <= target if way == "≤" else q >= target
        pairs = f" [{spread[0]:.2f}–{spread[1]:.2f}]" if spread else ""
        print(f"| {name} | {fmt(fn(total(a)), unit)} | {other} {fmt(fn(total(b)), unit)} "
              f"| **{q:.2f}**{pairs} | {way} {target:.2f}× | {'met' if met else 'missed'} |")


def main():
    raw = load(sys.argv[1])
    present = {r for r, _ in raw}
    routers = sys.argv[2:] or ["fbwag", "mavlink-routerd"]
    if len(routers) < 2:
        sys.exit("router_compare.py RAW [FIRST SECOND [REFERENCE]]: two routers to compare")
    if len(sys.argv) <= 2 and "bare-forward" in present:
        routers.append("bare-forward")
    table(raw, routers)
    print()
    if len(routers) > 2:
        bounds(raw, routers[0], routers[1], routers[2])
        print()
    bad = [(k, total(s)) for k, s in raw.items()]
    bad = [(k, d) for k, d in bad if d["bad"] or d["stale"] or d["disorder"]]
    for (r, p), d in bad:
        print(f"CHECK: {r} {p}: {d['bad']:.0f} bad, {d['stale']:.0f} stale, "
              f"{d['disorder']:.0f} out of order frames at the sink")
    if not bad:
        print("Sink checks: every frame delivered had a good CRC, its type's length, "
              "the current slice's counter and its system's order.")


if __name__ == "__main__":
    main()
