#!/usr/bin/env python3
"""Handover time of the live programs under floods, and parser MB/s on each
flood pattern. Timings live here, not in tests (the safety outcomes of the
same floods are fbwag-cli/tests/adversarial.rs).

For every flood (none, random bytes, start-byte-dense garbage, the worst
parser pattern, 10-byte false headers, valid frames from strangers) at each
rate, RUNS times: `fbwag cc` (udpin, signed) and `fbwag fc-sim` (udpout,
signed) over 127.0.0.1, both ports flooded from a third socket, the receiver
lost at 0.6 s; the handover is the FC's own `handover` event (receiver
failure -> companion control). A run ends at the handover, at RTL, or after
6.5 s (the FC falls back 5 s after its first notice), and counts as failed
without a handover. Then `fbwag decode` MB/s on 1 MB of each pattern (best of
3). Last, the handover over a TCP FC link of 46 or 20 kB/s (about 460,800
and 230,400 baud, through a pacing relay) while a ground station's flood into
the CC's `--out` link, up to 6 times what that link carries, is routed to
the FC: with the CC's default pace of routed traffic (`--routed-rate`) and
without it (`off`).

Usage: handover_under_flood.py FBWAG_BINARY [RUNS] [slow]
(`slow`: the slow-link table alone.)
Stdlib only. Prints markdown.
"""

import json
import os
import random
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time

KEY = "5a1f0c3d9e8b7a6f5e4d3c2b1a0f9e8d7c6b5a49382716051f2e3d4c5b6a7988"
WORST = bytes.fromhex("fefefefdfd0000fe00fe")
# `found_k` of benches/src/worst.rs, among the parser's costliest inputs
# (BENCHMARKS.md, "Parser worst case"), sent in 300-byte datagrams.
FOUND_K = bytes.fromhex("fe00fefefd0a00fe" + "fe" * 11 + "fd")
RC_LOSS_AT = 0.6
RUN_LIMIT = 6.5


def garbage(kind, rng, n):
    """n bytes of one flood pattern."""
    if kind == "random":
        return bytes(rng.getrandbits(8) for _ in range(n))
    if kind == "start-dense":
        return bytes(
            rng.choice((0xFD, 0xFE, rng.getrandbits(8), rng.getrandbits(8)))
            for _ in range(n)
        )
    if kind == "worst":
        return (WORST * (n // len(WORST) + 1))[:n]
    if kind == "found-k":
        return (FOUND_K * (n // len(FOUND_K) + 1))[:n]
    raise ValueError(kind)


def false_header(rng):
    """A MAVLink 2 header announcing 200-255 payload bytes of a known id."""
    msg_id = rng.choice((15001, 70, 0, 253))
    sys_id, comp_id = rng.choice(((1, 1), (1, 191)))
    return bytes(
        [0xFD, rng.randint(200, 255), 0, 0, rng.getrandbits(8), sys_id, comp_id]
    ) + msg_id.to_bytes(3, "little")


def stranger_frames(fbwag, tmp):
    """Valid frames from strangers, made by `fbwag encode`: notices, acks,
    overrides and heartbeats from other ids, and the companion's and FC's
    ids signed with a wrong key."""
    lines = []
    for i in range(64):
        sysid, compid = 2 + i % 200, (i * 37) % 256
        notice = (
            '{"name":"FBWAG_NOTICE","sysid":%d,"compid":%d,"seq":%d,'
            '"fields":{"system_id":1,"component_id":1,"failsafe_status":%d,'
            '"text":"FBWAG","timestamp":%d}}'
        )
        lines.append(notice % (sysid, compid, i, 1 + i % 2, 500 + i * 13))
        lines.append(
            '{"name":"RC_CHANNELS_OVERRIDE","sysid":%d,"compid":%d,"seq":%d,'
            '"fields":{"target_system":1,"target_component":1,"chan1_raw":1111,'
            '"chan3_raw":1999}}' % (sysid, compid, i)
        )
        lines.append(
            '{"name":"HEARTBEAT","sysid":%d,"compid":%d,"seq":%d,'
            '"fields":{"custom_mode":30}}' % (sysid, compid, i)
        )
    plain = encode(fbwag, lines, [])
    signed_lines = [
        l.replace('"sysid":%d,"compid":%d' % (2 + i % 200, (i * 37) % 256),
                  '"sysid":1,"compid":%d' % (191 if i % 2 else 1))
        for i, l in enumerate(lines)
    ]
    signed = encode(
        fbwag,
        signed_lines,
        ["--sign-key", "42" * 32, "--link-id", "0"],
    )
    return plain + signed


def encode(fbwag, lines, extra):
    """Frames of `fbwag encode` for JSON lines, split into frames."""
    out = subprocess.run(
        [fbwag, "encode", *extra],
        input="\n".join(lines).encode(),
        capture_output=True,
        check=False,
    )
    if out.returncode != 0:
        sys.exit("fbwag encode failed: " + out.stderr.decode())
    frames, data = [], out.stdout
    while data:
        # MAVLink 2: 10-byte header, payload, 2-byte CRC, 13-byte signature.
        size = 12 + data[1] + (13 if data[2] & 1 else 0)
        frames.append(data[:size])
        data = data[size:]
    return frames


def datagrams(kind, fbwag, tmp):
    """A pool of datagrams of one flood, cycled by the flooder."""
    rng = random.Random(7)
    if kind == "false-header":
        return [false_header(rng) for _ in range(256)]
    if kind == "strangers":
        return stranger_frames(fbwag, tmp)
    if kind == "worst-64k":
        return [garbage("worst", rng, 65000)]
    if kind == "found-k":
        return [garbage(kind, rng, 300)]
    return [garbage(kind, rng, 1024) for _ in range(16)]


class Flooder(threading.Thread):
    """Sends `per_sec` datagrams a second to each target until stopped."""

    def __init__(self, pool, per_sec, targets):
        super().__init__(daemon=True)
        self.pool, self.per_sec, self.targets = pool, per_sec, targets
        self.stop = threading.Event()
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind(("127.0.0.1", 0))

    def run(self):
        start, n = time.monotonic(), 0
        while not self.stop.is_set():
            due = int((time.monotonic() - start) * self.per_sec)
            n = max(n, due - int(self.per_sec * 0.02) - 1)
            while n < due:
                d = self.pool[n % len(self.pool)]
                for t in self.targets:
                    try:
                        self.sock.sendto(d, t)
                    except OSError:
                        pass
                n += 1
            time.sleep(0.001)


def free_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def udp_port_of(pid):
    """The UDP port a process bound (its socket inode in /proc/net/udp)."""
    deadline = time.monotonic() + 5
    while time.monotonic() < deadline:
        inodes = set()
        try:
            for fd in os.listdir("/proc/%d/fd" % pid):
                link = os.readlink("/proc/%d/fd/%s" % (pid, fd))
                if link.startswith("socket:["):
                    inodes.add(link[8:-1])
        except OSError:
            pass
        with open("/proc/net/udp") as f:
            for line in f.readlines()[1:]:
                cols = line.split()
                if cols[9] in inodes:
                    return int(cols[1].split(":")[1], 16)
        time.sleep(0.01)
    raise RuntimeError("fc-sim bound no UDP port")


def events(path):
    try:
        with open(path) as f:
            return f.read()
    except OSError:
        return ""


def one_run(fbwag, tmp, pool, per_sec):
    """The handover in ms, or None when it did not happen."""
    cc_port = free_port()
    cc_events, fc_events = os.path.join(tmp, "cc.ev"), os.path.join(tmp, "fc.ev")
    for p in (cc_events, fc_events):
        if os.path.exists(p):
            os.remove(p)
    sign = ["--sign-key", KEY, "--require-signed"]
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    cc = subprocess.Popen(
        [fbwag, "cc", "--link", "udpin:127.0.0.1:%d" % cc_port,
         "--duration", "10", "--events", cc_events, *sign], **quiet)
    fc = subprocess.Popen(
        [fbwag, "fc-sim", "--link", "udpout:127.0.0.1:%d" % cc_port,
         "--rc-loss-at", str(RC_LOSS_AT), "--duration", "10",
         "--events", fc_events, *sign], **quiet)
    flooder = None
    try:
        if pool:
            targets = [("127.0.0.1", cc_port), ("127.0.0.1", udp_port_of(fc.pid))]
            flooder = Flooder(pool, per_sec, targets)
            flooder.start()
        deadline = time.monotonic() + RUN_LIMIT
        while time.monotonic() < deadline:
            text = events(fc_events)
            if '"handover"' in text or '"RTL"' in text:
                break
            time.sleep(0.01)
        for line in events(fc_events).splitlines():
            try:
                event = json.loads(line)
            except ValueError:
                continue  # a line being written
            if event.get("event") == "handover":
                return event["ms"]
        return None
    finally:
        if flooder:
            flooder.stop.set()
            flooder.join()
        for p in (fc, cc):
            p.kill()
            p.wait()


def slow_relay(to_port, bytes_per_sec, far_buffer):
    """A TCP relay on 127.0.0.1 that accepts one connection and carries it
    to `to_port` at about `bytes_per_sec` each way (a serial-speed link).
    `far_buffer`: the receive buffer of the accepted side in bytes (what
    the far end of the link holds: a UART's few KiB), or None for the
    system's (it grows to 100 KiB and more: a modem's). Returns its port."""
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    if far_buffer:
        listener.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, far_buffer)
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    port = listener.getsockname()[1]

    def pump(src, dst):
        try:
            while True:
                data = src.recv(512)
                if not data:
                    break
                dst.sendall(data)
                time.sleep(len(data) / bytes_per_sec)
        except OSError:
            pass
        for s in (src, dst):
            try:
                s.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def serve():
        near, _ = listener.accept()
        listener.close()
        far = socket.create_connection(("127.0.0.1", to_port))
        # A serial link sends each byte as it comes: without this, Nagle's
        # algorithm holds the relay's small writes until the peer's delayed
        # ACK (40 ms on Linux), a delay of the harness, not of the link.
        for s in (near, far):
            s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        threading.Thread(target=pump, args=(near, far), daemon=True).start()
        threading.Thread(target=pump, args=(far, near), daemon=True).start()

    threading.Thread(target=serve, daemon=True).start()
    return port


def ground_station_flood(fbwag, tmp):
    """One 58.8 KB datagram of a ground station's broadcast heartbeats."""
    hb = encode(fbwag, ['{"name":"HEARTBEAT","sysid":255,"compid":190,"seq":0,'
                        '"fields":{"type":6}}'], [])[0]
    return [hb * 2800]


def one_slow_run(fbwag, tmp, pool, per_sec, link_rate, far_buffer, cc_args):
    """The handover in ms over a TCP FC link carrying `link_rate` B/s,
    with `pool` sent into the CC's --out link (routed to the FC), the CC
    run with `cc_args` too: None when it did not happen."""
    fc_port, out_port = free_port(), free_port()
    cc_events, fc_events = os.path.join(tmp, "cc.ev"), os.path.join(tmp, "fc.ev")
    for p in (cc_events, fc_events):
        if os.path.exists(p):
            os.remove(p)
    sign = ["--sign-key", KEY, "--require-signed"]
    quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rc_loss_at = 3.0
    fc = subprocess.Popen(
        [fbwag, "fc-sim", "--link", "tcpin:127.0.0.1:%d" % fc_port,
         "--rc-loss-at", str(rc_loss_at), "--duration", "12",
         "--events", fc_events, *sign], **quiet)
    time.sleep(0.3)
    relay = slow_relay(fc_port, link_rate, far_buffer)
    cc = subprocess.Popen(
        [fbwag, "cc", "--link", "tcp:127.0.0.1:%d" % relay,
         "--out", "udpin:127.0.0.1:%d" % out_port,
         "--duration", "12", "--events", cc_events, *sign, *cc_args], **quiet)
    flooder = None
    try:
        time.sleep(0.5)
        if pool:
            flooder = Flooder(pool, per_sec, [("127.0.0.1", out_port)])
            flooder.start()
        deadline = time.monotonic() + rc_loss_at + RUN_LIMIT
        while time.monotonic() < deadline:
            text = events(fc_events)
            if '"handover"' in text or '"RTL"' in text:
                break
            time.sleep(0.01)
        for line in events(fc_events).splitlines():
            try:
                event = json.loads(line)
            except ValueError:
                continue
            if event.get("event") == "handover":
                return event["ms"]
        return None
    finally:
        if flooder:
            flooder.stop.set()
            flooder.join()
        for p in (fc, cc):
            p.kill()
            p.wait()


def percentile(values, q):
    values = sorted(values)
    k = (len(values) - 1) * q
    lo = int(k)
    hi = min(lo + 1, len(values) - 1)
    return values[lo] + (values[hi] - values[lo]) * (k - lo)


def decode_rate(fbwag, tmp, kind, pool):
    """`fbwag decode` MB/s on 1 MB of the pattern (best of 3)."""
    data = b"".join(pool)
    data = (data * (2**20 // len(data) + 1))[: 2**20]
    path = os.path.join(tmp, "pattern.bin")
    with open(path, "wb") as f:
        f.write(data)
    best = None
    for _ in range(3):
        t = time.perf_counter()
        subprocess.run([fbwag, "decode", path], stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, check=False)
        took = time.perf_counter() - t
        best = took if best is None else min(best, took)
    return len(data) / best / 1e6


def main():
    fbwag = sys.argv[1]
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 10
    # (flood, datagrams/s per port): bytes/s = rate x datagram size (1 KiB
    # for garbage, 10 B for false headers, ~20-60 B for frames).
    plan = [
        ("none", 0),
        ("random", 1000),
        ("start-dense", 100),
        ("start-dense", 1000),
        ("worst", 10),
        ("worst", 100),
        ("worst", 1000),
        ("worst-64k", 5),
        ("found-k", 1000),
        ("found-k", 10000),
        ("false-header", 2000),
        ("false-header", 20000),
        ("strangers", 2000),
        ("strangers", 20000),
    ]
    with tempfile.TemporaryDirectory() as tmp:
        if sys.argv[3:] == ["slow"]:
            slow_link_table(fbwag, tmp, runs)
            return
        pools = {k: datagrams(k, fbwag, tmp) for k, _ in plan if k != "none"}
        print("| flood into both ports | per port | handovers | p50 ms | p95 ms | max ms |")
        print("|---|---|---|---|---|---|")
        for kind, rate in plan:
            pool = pools.get(kind)
            got = [one_run(fbwag, tmp, pool, rate) for _ in range(runs)]
            ok = [g for g in got if g is not None]
            size = len(pool[0]) if pool else 0
            per_port = "-" if not pool else "%d/s x %d B = %s" % (
                rate, size, human(rate * size))
            if kind == "strangers":
                per_port = "%d frames/s" % rate
            stats = ("%.0f | %.0f | %d" % (percentile(ok, 0.5), percentile(ok, 0.95), max(ok))
                     if ok else "- | - | -")
            print("| %s | %s | %d/%d | %s |" % (kind, per_port, len(ok), runs, stats))
            sys.stdout.flush()
        print()
        slow_link_table(fbwag, tmp, runs)
        print("| `fbwag decode`, 1 MB of | MB/s |")
        print("|---|---|")
        rng = random.Random(1)
        for kind in ("random", "start-dense", "worst", "found-k", "false-header", "strangers"):
            # A list of datagrams: 1 MB of them back to back.
            pool = pools.get(kind) or [garbage(kind, rng, 1 << 16)]
            print("| %s | %.2f |" % (kind, decode_rate(fbwag, tmp, kind, pool)))


def slow_link_table(fbwag, tmp, runs):
    """A ground station's flood into the CC's --out link, routed to the FC
    over a TCP link of about 460,800 or 230,400 baud, whose far end holds a
    UART's 4 KiB or what the system's buffer grows to (a modem's)."""
    gcs = ground_station_flood(fbwag, tmp)
    print("| FC link (TCP) | its far end's buffer | flood into the CC's `--out`, "
          "routed to the FC | CC's `--routed-rate` | handovers | p50 ms | p95 ms | max ms |")
    print("|---|---|---|---|---|---|---|---|")
    rows = [(46_000, 4096, 0, "default"), (46_000, 4096, 1, "default"),
            (46_000, 4096, 2, "default"), (46_000, None, 2, "default"),
            (46_000, None, 2, "off"), (20_000, None, 2, "default"),
            (20_000, None, 2, "off")]
    for link_rate, far_buffer, per_sec, routed in rows:
        pool = gcs if per_sec else None
        cc_args = ["--routed-rate", "off"] if routed == "off" else []
        got = [one_slow_run(fbwag, tmp, pool, per_sec, link_rate, far_buffer, cc_args)
               for _ in range(runs)]
        ok = [g for g in got if g is not None]
        what = "none" if not per_sec else "%d/s x %d B = %.1fx the link" % (
            per_sec, len(gcs[0]), per_sec * len(gcs[0]) / link_rate)
        far = "4 KiB (a UART)" if far_buffer else "the system's (a modem's)"
        rate = "8000 B/s (default)" if routed == "default" else "off"
        stats = ("%.0f | %.0f | %d" % (percentile(ok, 0.5), percentile(ok, 0.95), max(ok))
                 if ok else "- | - | -")
        print("| %d kB/s | %s | %s | %s | %d/%d | %s |" % (
            link_rate // 1000, far, what, rate, len(ok), runs, stats))
        sys.stdout.flush()
    print()


def human(bps):
    return "%.0f kB/s" % (bps / 1e3) if bps < 1e6 else "%.1f MB/s" % (bps / 1e6)


if __name__ == "__main__":
    main()
