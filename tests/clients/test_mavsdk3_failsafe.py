"""PX4's failsafes with MAVSDK-Python 3.x (a real MAVSDK 3 core in
mavsdk_server) against the rotorpilot binary at 20x: a geofence uploaded with
the Geofence plugin and left by offboard velocity (GF_ACTION Hold; a goto
outside it refused), the ground station going silent (MAVSDK's GCS heartbeats
stop with its server: NAV_DLL_ACT Return after PX4's 5 s in Hold, watched by
a pymavlink listener on the GCS link that sends no heartbeat) and the battery drained to critical
(COM_LOW_BAT_ACT Land, BATTERY_STATUS charge_state; the failsafe also read as
an event by MAVSDK's Events plugin), and the pilot taking over in the failsafe's
5 s of Hold (MAVSDK's hold() during the battery's delay: the landing never
comes). Every wait is bounded.

Run with the mavsdk<4 venv: `python -m pytest tests/clients/test_mavsdk3_failsafe.py`.
"""

import asyncio
import math
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "mavsdk_examples"))
from harness import Vehicle, drain, wait_message  # noqa: E402
from test_mavsdk3 import free_tcp_port  # noqa: E402

import common  # noqa: E402
from mavsdk import System  # noqa: E402
from mavsdk.geofence import FenceType, GeofenceData, Point, Polygon  # noqa: E402
from mavsdk.offboard import VelocityNedYaw  # noqa: E402
from mavsdk.telemetry import FlightMode  # noqa: E402
from pymavlink import mavutil  # noqa: E402

FAST = 20.0
M_PER_DEG = common.M_PER_DEG_LAT
SHORT_RTL = {"RTL_RETURN_ALT": 10.0, "RTL_DESCEND_ALT": 10.0}


def at(home, north, east):
    lat = home.latitude_deg + north / M_PER_DEG
    return lat, home.longitude_deg + east / (M_PER_DEG * math.cos(math.radians(home.latitude_deg)))


def north_east_m(home, p):
    n = (p.latitude_deg - home.latitude_deg) * M_PER_DEG
    e = (p.longitude_deg - home.longitude_deg) * M_PER_DEG * math.cos(math.radians(home.latitude_deg))
    return n, e


async def connect(vehicle):
    uav = System(port=free_tcp_port())
    await uav.connect(system_address=f"udpin://0.0.0.0:{vehicle.api_port}")
    await common.next_matching(uav.core.connection_state(), lambda c: c.is_connected, 20, "heartbeat")
    await common.next_matching(
        uav.telemetry.health(), lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable, 20,
        "health")
    return uav


async def take_off(uav, alt):
    await uav.action.set_takeoff_altitude(alt)
    await uav.action.arm()
    await uav.action.takeoff()
    await common.next_matching(uav.telemetry.flight_mode(), lambda m: m == FlightMode.HOLD, 30, "hold after takeoff")
    await common.next_matching(uav.telemetry.position(), lambda p: p.relative_altitude_m > alt - 0.3, 30, "altitude")


def collect_texts(uav, out):
    """Append every STATUSTEXT MAVSDK reports to `out`, in the background (at
    20x a failsafe's mode may last less than a heartbeat period)."""

    async def run():
        async for t in uav.telemetry.status_text():
            out.append(t.text)

    return asyncio.ensure_future(run())


async def until_said(texts, fragment, wall_limit):
    for _ in range(int(wall_limit / 0.02)):
        if any(fragment in t for t in texts):
            return
        await asyncio.sleep(0.02)
    raise AssertionError(f"no status text with {fragment!r} within {wall_limit} s: {texts}")


def listener(vehicle):
    """A pymavlink connection on the vehicle's GCS link that never sends (no GCS heartbeat)."""
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{vehicle.gcs_port}", source_system=250)
    assert m.wait_heartbeat(timeout=10), "no vehicle heartbeat on the GCS link"
    return m


def px4_mode(hb):
    return mavutil.interpret_px4_mode(hb.base_mode, hb.custom_mode)


def wait_msg(m, kind, cond, wall_limit, seen=None):
    """The first `kind` message satisfying `cond` within `wall_limit` s; every
    STATUSTEXT read on the way is appended to `seen`."""
    msg = wait_message(m, kind, cond, wall_limit, seen)
    if msg is None:
        raise AssertionError(f"no {kind} as wanted within {wall_limit} s")
    return msg


def test_geofence_breach_holds_and_a_goto_outside_is_ignored():
    async def scenario(v):
        uav = await connect(v)
        try:
            home = await common.sample(uav.telemetry.home(), "home")
            corners = [at(home, n, e) for n, e in ((-20, -20), (-20, 20), (20, 20), (20, -20))]
            await uav.geofence.upload_geofence(
                GeofenceData([Polygon([Point(lat, lon) for lat, lon in corners], FenceType.INCLUSION)], []))
            await take_off(uav, 5.0)
            # a target outside the fence: as on PX4, goto succeeds (DO_REPOSITION
            # ACCEPTED), the vehicle says why it ignores it and stays
            texts = []
            collector = collect_texts(uav, texts)
            before = north_east_m(home, await common.sample(uav.telemetry.position(), "position"))
            lat, lon = at(home, 40, 0)
            await uav.action.goto_location(lat, lon, home.absolute_altitude_m + 5.0, 0.0)
            await until_said(texts, "Reposition is outside geofence", 10)
            await common.pause(uav, 3.0)
            after = north_east_m(home, await common.sample(uav.telemetry.position(), "position"))
            print(f"goto outside the fence: stayed at {after} (was {before})")
            assert math.dist(before, after) < 1.0, (before, after)
            # out of the fence by offboard velocity: Hold at its border
            await uav.offboard.set_velocity_ned(VelocityNedYaw(3.0, 0.0, 0.0, 0.0))
            await uav.offboard.start()
            await until_said(texts, "Failsafe: geofence breach, triggering Hold", 20)
            await common.pause(uav, 5.0)
            await common.expect_mode(uav, FlightMode.HOLD, 5)
            collector.cancel()
            assert any("Geofence breached: outside geofence" in t for t in texts), texts
            p = await common.sample(uav.telemetry.position(), "position")
            n, e = north_east_m(home, p)
            print(f"geofence breach: holding {n:.2f} m north (fence at 20 m)")
            assert 20.0 <= n < 24.0 and abs(e) < 1.0
            await uav.action.return_to_launch()
            await common.touchdown(uav, 60)
        finally:
            uav._stop_mavsdk_server()

    with Vehicle(speed=FAST, params=SHORT_RTL) as v:
        asyncio.run(asyncio.wait_for(scenario(v), 120))


def test_data_link_loss_returns_when_mavsdk_goes_silent():
    params = dict(SHORT_RTL, NAV_DLL_ACT=2, COM_DL_LOSS_T=5)
    with Vehicle(speed=FAST, params=params) as v:
        m = listener(v)

        async def fly():
            uav = await connect(v)
            try:
                await take_off(uav, 5.0)
                lat, lon = at(await common.sample(uav.telemetry.home(), "home"), 15, 0)
                home = await common.sample(uav.telemetry.home(), "home")
                await uav.action.goto_location(lat, lon, home.absolute_altitude_m + 5.0, 0.0)
                await common.pause(uav, 8.0)
            finally:
                # MAVSDK's GCS heartbeats stop with its server
                uav._stop_mavsdk_server()

        asyncio.run(asyncio.wait_for(fly(), 90))
        silent = time.monotonic()
        seen = []
        drain(m, seen)
        hb = wait_msg(m, "HEARTBEAT", lambda h: px4_mode(h) == "LOITER", 5, seen)
        assert hb.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        # as PX4 (COM_FAIL_ACT_T 5 s): the failsafe holds 5 s before it
        # returns, on the wall clock above real time (a window for the pilot
        # to take over, as the loss timer itself)
        wait_msg(m, "STATUSTEXT", lambda t: t.text == "Failsafe: GCS connection lost, Return in 5 s", 15, seen)
        held = time.monotonic()
        wait_msg(m, "STATUSTEXT", lambda t: t.text == "Failsafe: GCS connection lost, triggering Return", 10, seen)
        waited = time.monotonic() - held
        print(f"data link: Hold, then Return {waited:.2f} s of wall time later")
        assert 4.5 < waited < 7.0
        wait_msg(m, "HEARTBEAT", lambda h: px4_mode(h) == "RTL", 5, seen)
        took = time.monotonic() - silent
        print(f"data link: RTL {took:.2f} s of wall time after MAVSDK stopped (COM_DL_LOSS_T 5 s, then "
              f"COM_FAIL_ACT_T 5 s, on the wall clock at {FAST:.0f}x)")
        assert 9.0 < took < 14.0
        wait_msg(m, "HEARTBEAT", lambda h: not h.base_mode & mavutil.mavlink.MAV_MODE_FLAG_SAFETY_ARMED, 30, seen)
        texts = [t for _, t in seen]
        print(f"status texts: {texts}")
        assert any("Connection to ground station lost" in t for t in texts)
        assert any("triggering Return" in t for t in texts)
        pos = wait_msg(m, "LOCAL_POSITION_NED", lambda p: True, 5)
        assert math.hypot(pos.x, pos.y) < 1.5, f"landed at home: {pos.x:.2f}, {pos.y:.2f}"


def test_battery_critical_lands():
    params = {"BAT1_CAPACITY": 100.0, "SIM_BAT_MIN_PCT": 0.0, "COM_LOW_BAT_ACT": 2}
    with Vehicle(speed=FAST, params=params) as v:
        m = listener(v)

        async def fly():
            uav = await connect(v)
            try:
                texts = []
                collector = collect_texts(uav, texts)
                events = []

                async def collect_events():
                    async for e in uav.events.events():
                        events.append(e)

                event_collector = asyncio.ensure_future(collect_events())
                await take_off(uav, 5.0)
                await until_said(texts, "Failsafe: battery critical, triggering Land", 30)
                # the same words as an event (MAVSDK's Events plugin, decoded by the vehicle's metadata)
                for _ in range(100):
                    if any(e.message == "Failsafe: battery critical, triggering Land" for e in events):
                        break
                    await asyncio.sleep(0.05)
                event_collector.cancel()
                said = [(e.message, e.log_level.name) for e in events]
                print(f"events: {said}")
                assert ("Failsafe: battery critical, triggering Land", "CRITICAL") in said
                b = await common.sample(uav.telemetry.battery(), "battery")
                print(f"battery: landing with {b.remaining_percent:.1f} % left")
                assert b.remaining_percent < 8.0
                await common.touchdown(uav, 60)
                collector.cancel()
                print(f"status texts: {texts}")
                assert any("Critical battery level, land now" in t for t in texts)
            finally:
                uav._stop_mavsdk_server()

        asyncio.run(asyncio.wait_for(fly(), 120))
        seen = []
        drain(m, seen)
        bs = wait_msg(m, "BATTERY_STATUS", lambda b: True, 5, seen)
        st = wait_msg(m, "SYS_STATUS", lambda s: True, 5, seen)
        print(f"BATTERY_STATUS charge_state {bs.charge_state}, remaining {bs.battery_remaining} %")
        assert bs.charge_state >= mavutil.mavlink.MAV_BATTERY_CHARGE_STATE_CRITICAL
        assert not st.onboard_control_sensors_health & mavutil.mavlink.MAV_SYS_STATUS_SENSOR_BATTERY


def test_taking_over_during_the_failsafe_hold_cancels_the_landing():
    # the battery drains to 6 %: below BAT_CRIT_THR (7 %), above BAT_EMERGEN_THR
    # (5 %), so only the critical failsafe comes, and no more severe one after it
    params = {"BAT1_CAPACITY": 100.0, "SIM_BAT_MIN_PCT": 6.0, "COM_LOW_BAT_ACT": 2}
    with Vehicle(speed=FAST, params=params) as v:

        async def fly():
            uav = await connect(v)
            try:
                texts = []
                collector = collect_texts(uav, texts)
                await take_off(uav, 5.0)
                # as PX4 (COM_FAIL_ACT_T 5 s, on the wall clock at 20x): Hold first
                await until_said(texts, "Failsafe: battery critical, Land in 5 s", 30)
                await common.expect_mode(uav, FlightMode.HOLD, 5)
                # the pilot takes over by selecting a mode, Hold itself
                await uav.action.hold()
                taken = time.monotonic()
                # well past the delay: no landing, still holding where it was
                await asyncio.sleep(8.0)
                print(f"took over; {time.monotonic() - taken:.1f} s of wall time later: {texts}")
                assert not any("triggering Land" in t for t in texts), texts
                await common.expect_mode(uav, FlightMode.HOLD, 5)
                p = await common.sample(uav.telemetry.position(), "position")
                print(f"holding at {p.relative_altitude_m:.2f} m")
                assert await common.sample(uav.telemetry.armed(), "armed")
                assert p.relative_altitude_m > 4.0
                # the pilot lands when they choose
                await uav.action.land()
                await common.touchdown(uav, 60)
                collector.cancel()
            finally:
                uav._stop_mavsdk_server()

        asyncio.run(asyncio.wait_for(fly(), 120))
