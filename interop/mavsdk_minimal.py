#!/usr/bin/env python3
"""Minimal MAVSDK client (pip package mavsdk 3.17.4): start the bundled
mavsdk_server on udpin://127.0.0.1:14540, wait for the FC, print its first
position, flight mode and health, then stop (the server with it).
For more (every change, requests, a bound on time): mavsdk_probe.py."""
import asyncio

from mavsdk import System


async def first(stream):
    async for value in stream:
        return value


async def main():
    drone = System()  # no address: starts the bundled mavsdk_server (gRPC port 50051)
    await drone.connect(system_address="udpin://127.0.0.1:14540")
    async for state in drone.core.connection_state():
        if state.is_connected:
            break
    print("flight mode:", await first(drone.telemetry.flight_mode()))
    print("health:", await first(drone.telemetry.health()))
    print("position:", await asyncio.wait_for(first(drone.telemetry.position()), 10))


asyncio.run(main())
