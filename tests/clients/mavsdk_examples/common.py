"""What the example scripts read from the environment: where to connect
(default as in MAVSDK-Python's examples, udpin://0.0.0.0:14540), the
mavsdk_server gRPC port (default 50051), and how much faster than real time
the vehicle runs (so the examples' sleeps cover the same simulated time)."""

import asyncio
import os

URL = os.environ.get("ROTORPILOT_MAVSDK_URL", "udpin://0.0.0.0:14540")
GRPC_PORT = int(os.environ.get("MAVSDK_SERVER_PORT", "50051"))
SPEED = float(os.environ.get("ROTORPILOT_SPEED", "1"))


async def sleep(seconds):
    """The examples' asyncio.sleep, in simulated seconds."""
    await asyncio.sleep(seconds / SPEED)


async def wait_until(agen, cond, timeout, what):
    """First item of an async generator that satisfies cond, or fail."""

    async def first():
        async for x in agen:
            if cond(x):
                return x

    try:
        return await asyncio.wait_for(first(), timeout)
    except asyncio.TimeoutError:
        raise SystemExit(f"timed out waiting for {what}")
