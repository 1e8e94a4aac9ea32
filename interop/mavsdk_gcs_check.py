#!/usr/bin/env python3
"""What a MAVSDK ground station sees of a flight controller, as JSON lines,
for fbwag-cli/tests/ground_station.rs (and by hand).

Connects to a running mavsdk_server (gRPC), waits for the vehicle, makes the
requests a ground station typically makes, then for --seconds prints:

  {"t": s, "what": "call", "call": NAME, "ok": bool, "value": ...}   each request
  {"t": s, "what": "mode", "mode": MAVSDK FlightMode name}           at each change
  {"t": s, "what": "custom_mode", "value": N}     HEARTBEAT custom_mode of 1/1, at each
                                                  change (MAVSDK's mavlink_direct plugin)
  {"t": s, "what": "rc", "available": bool}       rc_status.is_available, at each change
  {"t": s, "what": "armable", "value": bool}      health.is_armable, at each change
  {"t": s, "what": "home", "lat": .., "lon": .., "alt": ..}          first home
  {"t": s, "what": "sample", "lat": .., "lon": .., "rel_alt": .., "heading": ..,
   "custom_mode": N, "mode": NAME}                every 0.5 s once a position came
  {"t": s, "what": "done"}

    target/peerenv/lib/python3.11/site-packages/mavsdk/bin/mavsdk_server -p 50051 udpin://127.0.0.1:14540 &
    target/peerenv/bin/python interop/mavsdk_gcs_check.py --grpc-port 50051 --seconds 30

The calls: info.get_version, param.get_param_int(FS_SHORT_ACTN),
param.set_param_float(AIRSPEED_CRUISE, 22.0) then its read-back,
param.set_param_float(FS_LONG_TIMEOUT, 6.0) (refused: it decides who flies,
and fc-sim is armed),
telemetry.set_rate_position(2), mission_raw.download_mission(),
action.return_to_launch() (denied by fc-sim: the delegation engine decides
modes). Each is bounded to 8 s.
"""
import argparse
import asyncio
import json
import time
import warnings

warnings.filterwarnings("ignore", category=FutureWarning)
from mavsdk import System  # noqa: E402

START = time.monotonic()


def out(what, **fields):
    fields.update({"t": round(time.monotonic() - START, 3), "what": what})
    print(json.dumps(fields), flush=True)


class State:
    """The latest values, for the sampler."""

    def __init__(self):
        self.position = None
        self.heading = None
        self.mode = None
        self.custom_mode = None


async def on_change(stream, what, key, state=None, attr=None):
    last = object()
    async for value in stream:
        k = key(value)
        if state is not None:
            setattr(state, attr, k)
        if k != last:
            last = k
            out(what, **({"value": k} if not isinstance(k, dict) else k))


async def latest(stream, state, attr):
    async for value in stream:
        setattr(state, attr, value)


async def heartbeats(drone, state):
    """HEARTBEAT custom_mode of the autopilot (1/1), through MAVSDK."""
    last = None
    async for m in drone.mavlink_direct.message("HEARTBEAT"):
        if (m.system_id, m.component_id) != (1, 1):
            continue
        mode = json.loads(m.fields_json).get("custom_mode")
        state.custom_mode = mode
        if mode != last:
            last = mode
            out("custom_mode", value=mode)


async def sampler(state):
    while True:
        await asyncio.sleep(0.5)
        p = state.position
        if p is None:
            continue
        out("sample", lat=p.latitude_deg, lon=p.longitude_deg, rel_alt=p.relative_altitude_m,
            heading=state.heading.heading_deg if state.heading else None,
            custom_mode=state.custom_mode, mode=state.mode)


async def call(name, coro, value=lambda v: v):
    try:
        v = await asyncio.wait_for(coro, 8)
        out("call", call=name, ok=True, value=value(v))
    except Exception as e:  # the request failed: say how
        out("call", call=name, ok=False, value=type(e).__name__ + ": " + str(e))


async def requests(drone):
    await call("get_version", drone.info.get_version(),
               lambda v: [v.flight_sw_major, v.flight_sw_minor, v.flight_sw_patch])
    await call("get_param_int FS_SHORT_ACTN", drone.param.get_param_int("FS_SHORT_ACTN"))
    await call("set_param_float AIRSPEED_CRUISE 22",
               drone.param.set_param_float("AIRSPEED_CRUISE", 22.0), lambda v: None)
    await call("get_param_float AIRSPEED_CRUISE", drone.param.get_param_float("AIRSPEED_CRUISE"))
    await call("set_param_float FS_LONG_TIMEOUT 6",
               drone.param.set_param_float("FS_LONG_TIMEOUT", 6.0), lambda v: None)
    await call("set_rate_position 2", drone.telemetry.set_rate_position(2.0), lambda v: None)
    await call("download_mission", drone.mission_raw.download_mission(), lambda v: len(v))
    await call("return_to_launch", drone.action.return_to_launch(), lambda v: None)


async def sweep(drone):
    """--sweep: more of MAVSDK's plugins, to see which requests an FC is
    asked and which fc-sim leaves unanswered (fc-sim logs them as "not
    served"). Commands that would change who flies are denied by fc-sim."""
    from mavsdk.mission_raw import MissionItem
    item = MissionItem(0, 6, 16, 1, 1, 0, 10, 0, float("nan"), 504501000, 305234000, 100, 0)
    a, m, t, i = drone.action, drone.mission_raw, drone.telemetry, drone.info
    calls = [
        ("param.get_all_params", drone.param.get_all_params(), lambda v: len(v.int_params) + len(v.float_params)),
        ("info.get_identification", i.get_identification(), str),
        ("info.get_product", i.get_product(), str),
        ("info.get_flight_information", i.get_flight_information(), str),
        ("telemetry.get_gps_global_origin", t.get_gps_global_origin(), str),
        ("telemetry.set_rate_attitude_euler 5", t.set_rate_attitude_euler(5.0), str),
        ("telemetry.set_rate_gps_info 1", t.set_rate_gps_info(1.0), str),
        ("telemetry.set_rate_home 1", t.set_rate_home(1.0), str),
        ("telemetry.set_rate_in_air 1", t.set_rate_in_air(1.0), str),
        ("telemetry.set_rate_battery 1", t.set_rate_battery(1.0), str),
        ("telemetry.set_rate_rc_status 1", t.set_rate_rc_status(1.0), str),
        ("telemetry.set_rate_fixedwing_metrics 2", t.set_rate_fixedwing_metrics(2.0), str),
        ("telemetry.set_rate_velocity_ned 2", t.set_rate_velocity_ned(2.0), str),
        ("action.get_return_to_launch_altitude", a.get_return_to_launch_altitude(), str),
        ("action.set_current_speed 20", a.set_current_speed(20.0), str),
        ("action.arm", a.arm(), str),
        ("action.hold", a.hold(), str),
        ("action.land", a.land(), str),
        ("action.reboot", a.reboot(), str),
        ("mission_raw.upload_mission", m.upload_mission([item]), str),
        ("mission_raw.download_geofence", m.download_geofence(), len),
        ("mission_raw.download_rallypoints", m.download_rallypoints(), len),
        ("mission_raw.clear_mission", m.clear_mission(), str),
        ("mission_raw.start_mission", m.start_mission(), str),
    ]
    for name, coro, value in calls:
        await call(name, coro, value)


async def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--server", default="localhost", help="mavsdk_server host")
    ap.add_argument("--grpc-port", type=int, default=50051)
    ap.add_argument("--seconds", type=float, default=30.0, help="watch this long after connecting")
    ap.add_argument("--sweep", action="store_true",
                    help="also call more plugins (see sweep()) after the usual requests")
    args = ap.parse_args()
    drone = System(mavsdk_server_address=args.server, port=args.grpc_port)
    await drone.connect()
    async for s in drone.core.connection_state():
        if s.is_connected:
            out("connected")
            break
    state = State()
    t = drone.telemetry
    tasks = [
        on_change(t.flight_mode(), "mode", lambda m: m.name, state, "mode"),
        on_change(t.rc_status(), "rc", lambda r: {"available": r.is_available}),
        on_change(t.health(), "armable", lambda h: h.is_armable),
        latest(t.position(), state, "position"),
        latest(t.heading(), state, "heading"),
        heartbeats(drone, state),
        sampler(state),
    ]
    tasks = [asyncio.ensure_future(x) for x in tasks]

    async def first_home():
        async for h in t.home():
            out("home", lat=h.latitude_deg, lon=h.longitude_deg, alt=h.absolute_altitude_m)
            return

    tasks.append(asyncio.ensure_future(first_home()))
    await requests(drone)
    if args.sweep:
        await sweep(drone)
    await asyncio.sleep(max(0.0, args.seconds - (time.monotonic() - START)))
    out("done")
    for x in tasks:
        x.cancel()
    await asyncio.gather(*tasks, return_exceptions=True)


if __name__ == "__main__":
    asyncio.run(main())
