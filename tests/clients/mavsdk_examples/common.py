"""Shared plumbing for the MAVSDK 3 (gRPC) client scripts in this directory.

The pytest driver (../test_mavsdk3.py) passes three things through the
environment: the UDP endpoint on which this script's mavsdk_server listens for
the vehicle's API link, the TCP port that mavsdk_server serves gRPC on, and
how many times faster than real time the simulation is asked to run (used only
to size wall-clock limits). The defaults fit a single vehicle (instance 0)
running at real time.

Pauses are measured on the vehicle's own clock (the boot time stamped on its
attitude messages), so a loaded machine that runs the simulation slower than
asked does not shorten a climb or a hover. Every wait has a wall-clock limit;
a script that gives up exits non-zero with the reason, which the driver prints.
"""

import asyncio
import gc
import math
import os
import sys
import traceback
import weakref

from mavsdk import System

API_URL = os.environ.get("ROTORPILOT_MAVSDK_URL", "udpin://0.0.0.0:14540")
SERVER_PORT = int(os.environ.get("MAVSDK_SERVER_PORT", "50051"))
TIME_SCALE = float(os.environ.get("ROTORPILOT_SPEED", "1"))

# metres per degree of latitude (spherical earth, R = 6371 km)
M_PER_DEG_LAT = 111_195.0


# every System made by bring_up, so that a failed script can still stop its server
_SYSTEMS = weakref.WeakSet()


class Failure(Exception):
    """A check did not hold; the message says which."""


def bail(reason):
    """Fail the script (see launch)."""
    raise Failure(reason)


def launch(main):
    """Run the coroutine function `main` and exit: 0 if it returned, 1 if it
    raised, with the reason on stderr.

    MAVSDK stops a System's mavsdk_server, and the non-daemon thread that reads
    the server's output, only when the System is garbage collected. A traceback
    keeps the System alive, and the interpreter would then wait for that thread
    forever instead of exiting; so a failure is reported, the traceback dropped
    and any server still running stopped before exiting.
    """
    status = 0
    try:
        asyncio.run(main())
    except Failure as err:
        print(f"FAILED: {err}", file=sys.stderr)
        status = 1
    except BaseException:  # noqa: B036 - also SystemExit and Ctrl-C: never hang
        traceback.print_exc()
        status = 1
    gc.collect()
    for uav in list(_SYSTEMS):
        uav._stop_mavsdk_server()
    sys.stdout.flush()
    sys.exit(status)


async def next_matching(stream, wanted, wall_limit, label):
    """Read a MAVSDK subscription until an item satisfies `wanted` and return
    that item; bail out if none does within `wall_limit` real seconds."""

    async def scan():
        try:
            async for item in stream:
                if wanted(item):
                    return item
            return None
        finally:
            # end the gRPC subscription now rather than whenever it is collected
            await stream.aclose()

    try:
        found = await asyncio.wait_for(scan(), wall_limit)
    except asyncio.TimeoutError:
        found = None
    if found is None:
        bail(f"no {label} within {wall_limit} s")
    return found


async def sample(stream, label, wall_limit=5):
    """The next item of a subscription, whatever it is."""
    return await next_matching(stream, lambda _item: True, wall_limit, label)


async def vehicle_time_s(uav):
    """The vehicle's clock in seconds since boot (simulated time)."""
    att = await sample(uav.telemetry.attitude_euler(), "attitude")
    return att.timestamp_us / 1e6


async def pause(uav, sim_seconds):
    """Let `sim_seconds` of the vehicle's (simulated) time go by."""
    until = await vehicle_time_s(uav) + sim_seconds
    await next_matching(
        uav.telemetry.attitude_euler(),
        lambda a: a.timestamp_us / 1e6 >= until,
        20 + 10 * sim_seconds / TIME_SCALE,
        f"{sim_seconds} s of vehicle time",
    )


async def bring_up(need_position=True, sysid=245):
    """Start a mavsdk_server for the vehicle's API link (MAVSDK speaking as
    system `sysid`, 245 by default), wait until the vehicle is discovered and
    (unless told otherwise) until it reports a global position estimate and a
    home position, and return the System."""
    uav = System(port=SERVER_PORT, sysid=sysid)
    _SYSTEMS.add(uav)
    await uav.connect(system_address=API_URL)
    print(f"[link] gRPC on :{SERVER_PORT}, listening for the vehicle on {API_URL}")
    await next_matching(uav.core.connection_state(), lambda c: c.is_connected, 20, "vehicle heartbeat")
    print("[link] vehicle discovered")
    if need_position:
        await next_matching(
            uav.telemetry.health(),
            lambda h: h.is_global_position_ok and h.is_home_position_ok,
            20,
            "global position and home",
        )
        print("[link] position estimate and home are valid")
    return uav


def echo_status_text(uav):
    """Print the vehicle's STATUSTEXT messages as they come, in the background
    (so a refusal or a failsafe shows in the script's output); returns the task."""

    async def echo():
        try:
            async for note in uav.telemetry.status_text():
                print(f"[vehicle {note.type}] {note.text}")
        except asyncio.CancelledError:
            pass

    return asyncio.create_task(echo())


async def expect_mode(uav, mode, wall_limit=5):
    """Wait until the vehicle reports flight mode `mode` (a telemetry.FlightMode)."""
    await next_matching(uav.telemetry.flight_mode(), lambda m: m == mode, wall_limit, f"flight mode {mode}")
    print(f"[mode] {mode}")


async def touchdown(uav, wall_limit=60):
    """Wait until the vehicle says it is on the ground, then until it disarms."""
    await next_matching(uav.telemetry.in_air(), lambda flying: not flying, wall_limit, "touchdown")
    print("[land] on the ground")
    await next_matching(uav.telemetry.armed(), lambda armed: not armed, 20, "automatic disarm")
    print("[land] disarmed")


def ground_gap_m(lat_a, lon_a, lat_b, lon_b):
    """Horizontal distance between two nearby points, flat-earth approximation."""
    d_north = (lat_a - lat_b) * M_PER_DEG_LAT
    d_east = (lon_a - lon_b) * M_PER_DEG_LAT * math.cos(math.radians(0.5 * (lat_a + lat_b)))
    return math.hypot(d_north, d_east)


def heading_gap_deg(a, b):
    """Smallest angle between two headings in degrees (any wrapping)."""
    return abs((a - b + 180.0) % 360.0 - 180.0)
