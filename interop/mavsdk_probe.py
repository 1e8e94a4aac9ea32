#!/usr/bin/env python3
"""Connect MAVSDK (the pip package `mavsdk` 3.17.4 and the mavsdk_server it
ships) to a flight controller and print what it reports, for a bounded time:
connection, autopilot identity (AUTOPILOT_VERSION), flight mode, health,
RC status, armed/in-air/landed state and status texts at every change, and
the first value of position, home, GPS, battery, attitude, velocity and
fixed-wing metrics (or that none came).

    target/peerenv/bin/python interop/mavsdk_probe.py udpin://127.0.0.1:14540 --seconds 15
    # FC, e.g.: fbwag fc-sim --link udpout:127.0.0.1:14540 --rc-loss-at 5 --rc-back-at 10

By default the Python package starts its own bundled mavsdk_server on the
given connection URL (gRPC on --grpc-port, default 50051) and kills it on
exit. With --server HOST it uses an already running mavsdk_server instead,
e.g. one started as:
    target/peerenv/lib/python3.11/site-packages/mavsdk/bin/mavsdk_server -p 50051 udpin://127.0.0.1:14540
Each line printed is "<seconds> <what>: <value>".
"""
import argparse
import asyncio
import time

from mavsdk import System

START = time.monotonic()


def out(what, value):
    print("%7.3f %s: %s" % (time.monotonic() - START, what, value), flush=True)


async def watch(stream, what, key=lambda v: v, once=False):
    """Print a telemetry stream's value each time it changes."""
    last = object()
    async for value in stream:
        if key(value) != last:
            last = key(value)
            out(what, value)
            if once:
                return


# Streams printed at every change; the rest only once, at their first value.
CHANGES = ("flight_mode", "health", "rc_status", "armed", "in_air", "landed_state",
           "status_text")
ONCE = ("position", "home", "gps_info", "raw_gps", "battery", "attitude_euler", "velocity_ned",
        "fixedwing_metrics", "heading")


async def typical_requests(drone):
    """What a ground station or companion typically asks, each bounded to
    5 s: a telemetry rate, a failsafe parameter, the mission."""
    calls = [
        ("telemetry.set_rate_position(2)", drone.telemetry.set_rate_position(2.0)),
        ("param.get_param_int(FS_SHORT_ACTN)", drone.param.get_param_int("FS_SHORT_ACTN")),
        ("mission_raw.download_mission()", drone.mission_raw.download_mission()),
    ]
    for what, call in calls:
        try:
            out(what, await asyncio.wait_for(call, 5))
        except Exception as e:  # an FC that does not answer: a timeout or an error result
            out(what + " failed", repr(e))


async def probe(drone, seconds, requests):
    async for state in drone.core.connection_state():
        if state.is_connected:
            out("connected", state)
            break
    try:
        version = await asyncio.wait_for(drone.info.get_version(), 5)
        out("info.get_version", version)
    except Exception as e:  # the FC may not answer AUTOPILOT_VERSION
        out("info.get_version failed", repr(e))
    if requests:
        await typical_requests(drone)
    tasks = {}
    for name in CHANGES + ONCE:
        stream = getattr(drone.telemetry, name)()
        tasks[name] = asyncio.ensure_future(
            watch(stream, "telemetry." + name, key=str, once=name in ONCE))
    await asyncio.sleep(seconds)
    silent = [n for n in ONCE if not tasks[n].done()]
    out("streams with no value in %.0f s" % seconds, ", ".join(silent) or "none")
    for t in tasks.values():
        t.cancel()
    await asyncio.gather(*tasks.values(), return_exceptions=True)


async def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("url", nargs="?", default="udpin://127.0.0.1:14540",
                    help="MAVSDK connection URL (default %(default)s)")
    ap.add_argument("--seconds", type=float, default=15.0, help="watch this long after connecting")
    ap.add_argument("--requests", action="store_true",
                    help="also set a telemetry rate, read a parameter, download the mission")
    ap.add_argument("--server", help="use a running mavsdk_server at this host")
    ap.add_argument("--grpc-port", type=int, default=50051)
    args = ap.parse_args()
    drone = System(mavsdk_server_address=args.server, port=args.grpc_port)
    await drone.connect(system_address=args.url)
    out("mavsdk_server", "external at %s" % args.server if args.server else "bundled, started")
    try:
        await asyncio.wait_for(probe(drone, args.seconds, args.requests), args.seconds + 60)
    finally:
        drone._stop_mavsdk_server()  # the bundled server; no-op for --server


if __name__ == "__main__":
    asyncio.run(main())
