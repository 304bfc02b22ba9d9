"""Failure injection with MAVSDK-Python 3.x's Failure plugin (a real MAVSDK 3
core in mavsdk_server) against the rotorpilot binary: a motor of the octo
switched off in the middle of a mission (the flight stack notices it from its
ESC speeds, reallocates and finishes the mission on the path), and the GPS
switched off in Hold (the vehicle descends without position, and holds again
when the fix comes back). Every wait is bounded.

Run with the mavsdk<4 venv: `python -m pytest tests/clients/test_mavsdk3_failure.py`.
"""

import asyncio
import math
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "mavsdk_examples"))
from harness import Vehicle  # noqa: E402
from test_mavsdk3 import free_tcp_port  # noqa: E402
from test_mavsdk3_mission import at, item, until  # noqa: E402

import common  # noqa: E402
from mavsdk import System  # noqa: E402
from mavsdk.failure import FailureType, FailureUnit  # noqa: E402
from mavsdk.mission import MissionPlan  # noqa: E402
from mavsdk.telemetry import FixType, FlightMode  # noqa: E402

M_PER_DEG = common.M_PER_DEG_LAT
ENABLED = {"SYS_FAILURE_EN": 1}


def north_east_m(home, lat, lon):
    n = (lat - home.latitude_deg) * M_PER_DEG
    e = (lon - home.longitude_deg) * M_PER_DEG * math.cos(math.radians(home.latitude_deg))
    return n, e


def off_segment_m(p, a, b, margin):
    """Distance of `p` from segment a-b, or None when p projects within
    `margin` metres of either end (corners are cut on purpose)."""
    ab = (b[0] - a[0], b[1] - a[1])
    length = math.hypot(*ab)
    s = ((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / length
    if s < margin or s > length - margin:
        return None
    return abs((p[0] - a[0]) * ab[1] - (p[1] - a[1]) * ab[0]) / length


def fly(vehicle, scenario, wall_limit):
    async def main():
        uav = System(port=free_tcp_port())
        await uav.connect(system_address=f"udpin://0.0.0.0:{vehicle.api_port}")
        try:
            await common.next_matching(uav.core.connection_state(), lambda c: c.is_connected, 20, "heartbeat")
            await common.next_matching(
                uav.telemetry.health(), lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable,
                20, "health")
            await asyncio.wait_for(scenario(uav), wall_limit)
        finally:
            uav._stop_mavsdk_server()

    asyncio.run(main())


def collect(stream, out, f):
    async def run():
        async for x in stream:
            out.append(f(x))

    return asyncio.ensure_future(run())


def test_octo_loses_a_motor_mid_mission_and_finishes_it_on_the_path():
    """failure.inject(MOTOR, OFF, 1) on the octo while it flies a square
    mission: the vehicle says so, keeps flying (COM_ACT_FAIL_ACT 0, PX4's
    default: warn and go on), completes the mission, and the legs flown with
    seven rotors stay within 1 m of the straight lines."""
    with Vehicle(speed=10.0, extra=["--airframe", "octo"], params=ENABLED) as v:
        result = {}

        async def scenario(uav):
            home = await common.sample(uav.telemetry.home(), "home", 10)
            corners = [(30.0, 0.0), (30.0, 30.0), (0.0, 30.0), (0.0, 0.0)]
            items = [item(*at(home, n, e), 15.0, 5.0) for n, e in corners]
            await uav.mission.set_return_to_launch_after_mission(False)
            await uav.mission.upload_mission(MissionPlan(items))
            texts, progress, samples = [], [], []
            tasks = [
                collect(uav.telemetry.status_text(), texts, lambda t: t.text),
                collect(uav.mission.mission_progress(), progress, lambda p: (p.current, p.total)),
                collect(uav.telemetry.position(), samples,
                        lambda p: (progress[-1][0] if progress else -1,
                                   north_east_m(home, p.latitude_deg, p.longitude_deg))),
            ]
            try:
                await uav.action.arm()
                await uav.mission.start_mission()
                await until(lambda: progress and progress[-1][0] >= 1, 60, "leg to the second corner")
                await uav.failure.inject(FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 1)
                await until(lambda: any("Motor 1 failed" in t for t in texts), 10, "motor failure detected")
                await common.next_matching(uav.mission.mission_progress(), lambda p: p.current == p.total, 90,
                                           "mission finished")
                mode = await common.sample(uav.telemetry.flight_mode(), "mode", 5)
                result.update(texts=list(texts), samples=list(samples), mode=mode, corners=corners)
            finally:
                for t in tasks:
                    t.cancel()

        fly(v, scenario, 240)
        assert any("CMD_INJECT_FAILURE" in t and "motor 1 off" in t for t in result["texts"]), result["texts"]
        # the mission goes on: still in Mission (or Hold after its last item), never Land
        assert result["mode"] in (FlightMode.MISSION, FlightMode.HOLD), result["mode"]
        corners = result["corners"]
        errors = []
        for current, p in result["samples"]:
            if 2 <= current <= 3:  # legs 2 and 3, flown after the failure
                d = off_segment_m(p, corners[current - 1], corners[current], margin=8.0)
                if d is not None:
                    errors.append(d)
        assert len(errors) > 10, f"too few samples on the legs: {len(errors)}"
        print(f"octo, motor 1 off mid-mission: largest distance from the legs {max(errors):.3f} m "
              f"over {len(errors)} samples")
        assert max(errors) < 1.0, max(errors)


def test_gps_off_descends_without_position_and_gps_back_holds():
    """failure.inject(GPS, OFF, 0) in Hold at 20 m: GPS_RAW_INT says no fix,
    the vehicle descends (AUTO.LAND in the heartbeat, a STATUSTEXT saying
    why); GPS OK before touchdown: it holds again where it is."""
    with Vehicle(speed=5.0, params=ENABLED) as v:
        result = {}

        async def scenario(uav):
            texts = []
            task = collect(uav.telemetry.status_text(), texts, lambda t: t.text)
            try:
                await uav.action.set_takeoff_altitude(20.0)
                await uav.action.arm()
                await uav.action.takeoff()
                await common.next_matching(uav.telemetry.position(), lambda p: p.relative_altitude_m > 19.5, 60,
                                           "20 m")
                await common.next_matching(uav.telemetry.flight_mode(), lambda m: m == FlightMode.HOLD, 30, "Hold")
                await uav.failure.inject(FailureUnit.SENSOR_GPS, FailureType.OFF, 0)
                # PX4's silent receiver: NO_GPS, satellites unknown (255)
                gps = await common.next_matching(uav.telemetry.gps_info(), lambda g: g.fix_type == FixType.NO_GPS,
                                                 10, "no GPS")
                result["fix"] = gps.fix_type
                await common.next_matching(uav.telemetry.flight_mode(), lambda m: m == FlightMode.LAND, 10,
                                           "descent")
                await until(lambda: any("No GPS fix" in t for t in texts), 5, "the reason")
                start = await common.sample(uav.telemetry.position(), "position", 5)
                await common.next_matching(uav.telemetry.position(),
                                           lambda p: p.relative_altitude_m < start.relative_altitude_m - 3.0, 30,
                                           "3 m lower")
                await uav.failure.inject(FailureUnit.SENSOR_GPS, FailureType.OK, 0)
                await common.next_matching(uav.telemetry.flight_mode(), lambda m: m == FlightMode.HOLD, 10,
                                           "Hold again")
                await until(lambda: any("GPS fix regained" in t for t in texts), 5, "the regained text")
                result["held_at"] = (await common.sample(uav.telemetry.position(), "position", 5)).relative_altitude_m
                result["texts"] = list(texts)
                await uav.action.land()
                await common.next_matching(uav.telemetry.armed(), lambda a: not a, 60, "disarmed after landing")
            finally:
                task.cancel()

        fly(v, scenario, 180)
        assert result["fix"] == FixType.NO_GPS, result["fix"]
        assert any("CMD_INJECT_FAILURE" in t and "GPS off" in t for t in result["texts"]), result["texts"]
        assert 5.0 < result["held_at"] < 17.5, result["held_at"]
