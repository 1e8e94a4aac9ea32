#!/usr/bin/env bash
# MAVSDK (which cannot sign) reading and commanding an FC that requires
# signatures, through the companion's --trusted-out link.
# Needs: fbwag on PATH; python3 with `mavsdk` 3.x (pip install mavsdk==3.17.4:
# its wheel ships mavsdk_server).
set -euo pipefail
P_FC=${P_FC:-14550}                  # the companion's port for the FC
P_MAVSDK=${P_MAVSDK:-14540}          # mavsdk_server's port, the companion's --trusted-out
P_GRPC=${P_GRPC:-50051}              # mavsdk_server's gRPC port
PYTHON=${PYTHON:-python3}
KEY=$(printf %s fbwag-bench | sha256sum | cut -c1-64)
RUN=$(mktemp -d)
# On exit, stop what is still running and wait for it: its ports are free
# for the next run.
trap 'kill $(jobs -p) 2>/dev/null || true; wait' EXIT
fail() { echo "FAILED: $1"; for f in "$RUN"/*.log "$RUN"/*.jsonl; do
    [ -f "$f" ] && { echo "--- $f"; cat "$f"; }; done; exit 1; }
expect() { grep -q -- "$2" "$RUN/$1" && echo "ok: $1: $2" || fail "no '$2' in $1"; }
wait_for() { for _ in $(seq 150); do grep -q -- "$2" "$RUN/$1" && return; sleep 0.2; done; expect "$1" "$2"; }

# 1. The FC (fc-sim here), signed.
fbwag fc-sim --link udpin:127.0.0.1:$P_FC --sign-key $KEY --require-signed \
    --duration 120 >$RUN/fc.log 2>&1 &
# 2. mavsdk_server, before the companion (as a service would run it): it
#    takes the first component it hears for the vehicle, and the companion
#    speaks on its links only once it hears the FC. (System() can start
#    the server itself, but then a failing program never exits: mavsdk 3.x
#    joins the server's log thread before it stops the server.)
SERVER=$($PYTHON -W ignore -c 'import mavsdk, os; print(os.path.dirname(mavsdk.__file__) + "/bin/mavsdk_server")')
$SERVER -p $P_GRPC udpin://127.0.0.1:$P_MAVSDK >$RUN/mavsdk_server.log 2>&1 &
wait_for mavsdk_server.log "Waiting to discover"
# 3. The companion: what MAVSDK sends on the trusted link goes on to the FC
#    signed with the key, but for what decides who flies (the delegation's
#    and the failsafe's parameters, signing, control): never signed on.
#    Loopback only: whoever can send into that port commands the aircraft.
fbwag cc --link udpout:127.0.0.1:$P_FC --sign-key $KEY --require-signed \
    --trusted-out udpout:127.0.0.1:$P_MAVSDK --duration 120 >$RUN/cc.log 2>&1 &
# 4. A MAVSDK program.
cat >$RUN/gcs.py <<PY
import asyncio
from mavsdk import System

async def main():
    drone = System(mavsdk_server_address="127.0.0.1", port=$P_GRPC)
    await drone.connect()
    async for state in drone.core.connection_state():
        if state.is_connected:
            break
    print("connected", flush=True)
    for _ in range(20):  # the version comes with the first AUTOPILOT_VERSION
        try:
            v = await drone.info.get_version()
            break
        except Exception:
            await asyncio.sleep(0.5)
    print("version", v.flight_sw_major, v.flight_sw_minor, v.flight_sw_patch)
    print("FS_SHORT_ACTN", await drone.param.get_param_int("FS_SHORT_ACTN"))
    await drone.param.set_param_float("AIRSPEED_CRUISE", 22.0)
    print("AIRSPEED_CRUISE", await drone.param.get_param_float("AIRSPEED_CRUISE"))
    try:
        await drone.param.set_param_float("FS_LONG_TIMEOUT", 6.0)
        print("FS_LONG_TIMEOUT set")
    except Exception as e:
        print("FS_LONG_TIMEOUT refused", e)
    try:
        await drone.action.return_to_launch()
        print("RTL accepted")
    except Exception as e:
        print("RTL", e)

asyncio.run(asyncio.wait_for(main(), 90))
PY
$PYTHON -W ignore::FutureWarning $RUN/gcs.py >$RUN/gcs.log 2>&1 || true

# What to expect: the version and parameters of the signed FC, the
# ordinary parameter set, the failsafe's refused (the companion drops it:
# `protected` in its log), and RTL answered (denied: fc-sim's engine
# decides modes).
expect gcs.log "version 4 6 0"
expect gcs.log "FS_SHORT_ACTN 5"
expect gcs.log "AIRSPEED_CRUISE 22.0"
expect gcs.log "FS_LONG_TIMEOUT refused"
expect cc.log "protected"
expect gcs.log "RTL .*COMMAND_DENIED"
echo "runbook passed (logs in $RUN)"
