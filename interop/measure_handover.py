#!/usr/bin/env python3
"""Handover time (receiver failure -> companion control, as `fbwag fc-sim`
reports it: "handover N ms after the receiver failed"), measured in one
invocation over several runs of each set-up, all on 127.0.0.1 UDP:

  direct            fc-sim --udpout--> fbwag cc
  router            fc-sim --> fbwag router --> fbwag cc
  cc-routing        fc-sim --> fbwag cc --out--> a ground-station port (the
                    companion routing while it delegates)
  mavproxy          fc-sim --> MAVProxy (default dialect, no key) --> fbwag cc
  mavproxy-signed   fc-sim (signed, --require-signed) --> MAVProxy
                    (--dialect=fbwag, signing key) --> fbwag cc (signed)

Every run starts fresh processes and ends them (only those). Prints each
run and, per set-up, the median, min and max. Needs the peer venv
(scripts/peer-env.sh): run it with that python.

usage: target/peerenv/bin/python interop/measure_handover.py \\
           --fbwag target/release/fbwag [--runs 7] [--setups direct,mavproxy]
"""
import argparse
import datetime
import os
import re
import socket
import statistics
import subprocess
import sys
import tempfile
import time

PASSPHRASE = "fbwag-bench"
KEY_HEX = "1eeb12caa5637aa80caed04c6ac2783bdae83ca2c99c9f8a4cb9fe3861365094"  # sha256(PASSPHRASE)
MAVPROXY = os.path.join(os.path.dirname(sys.executable), "mavproxy.py")
HANDOVER = re.compile(r"handover (\d+) ms")
# fc-sim's log stamps (UTC, RFC 3339, µs) of its first status-1 notice and
# of the companion's status-2 answer: the handshake's round trip, which is
# what a router in the path adds to. The handover figure also holds the
# FC's own failsafe detection delay (about 100-160 ms here, by the
# receiver's phase).
SENT = re.compile(r"^(\S+) \w+ +fc: -> FBWAG_NOTICE status 1 ", re.M)
ANSWER = re.compile(r"^(\S+) \w+ +fc: <- FBWAG_NOTICE status 2 ", re.M)


def stamp(match):
    """A log line's time, in seconds."""
    return datetime.datetime.fromisoformat(match.group(1)).timestamp()


def free_port():
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_mavproxy(master, out, extra, home):
    env = dict(os.environ, HOME=home, PYTHONUNBUFFERED="1")
    env.pop("DISPLAY", None)
    p = subprocess.Popen([MAVPROXY, "--master=udpin:127.0.0.1:%d" % master,
                          "--out=udpout:127.0.0.1:%d" % out, "--non-interactive", "--no-state"]
                         + extra, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, env=env, text=True)
    end = time.time() + 40
    for line in p.stdout:  # ready once its master socket is bound
        if "Waiting for heartbeat" in line or time.time() > end:
            break
    return p


def one_run(fbwag, setup, home):
    """(handover, handshake round trip) in ms of one fresh run, or None
    (with the FC's log on stderr)."""
    p_fc, p_cc = free_port(), free_port()
    fc_sign, cc_sign, mp = [], [], None
    procs = []
    try:
        if setup == "mavproxy-signed":
            fc_sign = ["--sign-key", KEY_HEX, "--require-signed"]
            cc_sign = ["--sign-key", KEY_HEX]
        cc_out = []
        if setup == "cc-routing":
            # A ground station's port: nobody listens, the companion routes
            # everything the FC says to it.
            cc_out = ["--out", "udpout:127.0.0.1:%d" % free_port()]
        cc = subprocess.Popen([fbwag, "cc", "--link", "udpin:127.0.0.1:%d" % p_cc,
                               "--duration", "30"] + cc_sign + cc_out,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(cc)
        if setup in ("direct", "cc-routing"):
            time.sleep(0.3)
            fc_port = p_cc
        elif setup == "router":
            # The router's FC side listens on p_fc; its companion side
            # sends to the companion's udpin.
            router = subprocess.Popen([fbwag, "router", "udpin:127.0.0.1:%d" % p_fc,
                                       "udpout:127.0.0.1:%d" % p_cc, "--duration", "30"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            procs.append(router)
            time.sleep(0.3)
            fc_port = p_fc
        else:
            extra = [] if setup == "mavproxy" else [
                "--dialect=fbwag", "--cmd=signing key %s" % PASSPHRASE]
            mp = start_mavproxy(p_fc, p_cc, extra, home)
            procs.append(mp)
            fc_port = p_fc
        fc = subprocess.run([fbwag, "fc-sim", "--link", "udpout:127.0.0.1:%d" % fc_port,
                             "--rc-loss-at", "2", "--rc-back-at", "3", "--duration", "3.3"]
                            + fc_sign, capture_output=True, text=True, timeout=30)
        m, sent, answer = (r.search(fc.stdout) for r in (HANDOVER, SENT, ANSWER))
        if m is None or sent is None or answer is None:
            sys.stderr.write(fc.stdout)
            return None
        return int(m.group(1)), round((stamp(answer) - stamp(sent)) * 1000)
    finally:
        for p in procs:
            p.kill()
            p.wait()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--fbwag", required=True, help="path of the fbwag binary")
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--setups", default="direct,router,cc-routing,mavproxy,mavproxy-signed")
    args = ap.parse_args()
    setups = args.setups.split(",")
    results = {s: [] for s in setups}
    with tempfile.TemporaryDirectory(prefix="mavproxy-home-") as home:
        # Interleaved, so a slow moment of the machine hits every set-up.
        for i in range(args.runs):
            for s in setups:
                r = one_run(os.path.abspath(args.fbwag), s, home)
                results[s].append(r)
                print("run %d %-16s %s" % (i + 1, s, "no handover" if r is None else
                                           "handover %d ms, round trip %d ms" % r), flush=True)
    for s in setups:
        ok = [r for r in results[s] if r is not None]
        if not ok:
            print("%-16s no handover in %d runs" % (s, len(results[s])))
            continue
        for k, what in ((0, "handover"), (1, "round trip")):
            v = [r[k] for r in ok]
            print("%-16s %-10s median %.0f ms  min %d  max %d  (%d/%d runs handed over)" % (
                s, what, statistics.median(v), min(v), max(v), len(ok), len(results[s])))


if __name__ == "__main__":
    main()
