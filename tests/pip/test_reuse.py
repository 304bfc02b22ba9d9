"""One vehicle for many tests (`@pytest.mark.rotorpilot(reuse=True)`): the
reset between two tests leaves nothing of the first for the second, and a
flight after a reset is the flight a fresh vehicle flies.

- A MAVSDK 3 test changes parameters, uploads a mission and a geofence,
  injects a motor failure in flight; the next test, on the same vehicle
  (same daemon), sees over pymavlink the start parameters, no plan, a
  disarmed vehicle at home, and flies on all four motors.
- Under `-n 2` each worker has its own shared vehicle; a failing test on one
  names its record and the step its flight starts at, and the run leaves no
  process behind.
- The proof: a flight flown on a vehicle after another flight and a reset,
  against the same vehicle started fresh: the record's inputs after the
  reset are the fresh flight's (steps aside, which the wall clock sets), and
  replaying them on a fresh vehicle (`rotorpilot replay`, the fresh record's
  header) writes the live flight's CSV in every column but `time_s`, which
  is offset by the reset's step (the simulated clock keeps counting across a
  reboot).

Needs `pip install .` (or the plugin on the path), mavsdk==3.17.4 and
pymavlink==2.4.50. Every wait is bounded.
"""

import json
import os
import struct
import subprocess

import pytest
from pymavlink import mavutil

from rotorpilot import Vehicle, binary, wait_message
from rotorpilot.shared import reset
from test_no_hang import run_inner

MAVLINK = mavutil.mavlink

STATE = '''
import asyncio, math, os, struct

import pytest
from mavsdk import System
from mavsdk.failure import FailureType, FailureUnit
from mavsdk.geofence import FenceType, GeofenceData, Point, Polygon
from mavsdk.mission import MissionItem, MissionPlan
from pymavlink import mavutil

from rotorpilot import wait_message

pytestmark = pytest.mark.rotorpilot(speed=10, reuse=True)
M_PER_DEG = 111_195.0


async def first(stream, cond, timeout, what):
    async def scan():
        async for x in stream:
            if cond(x):
                return x
    try:
        return await asyncio.wait_for(scan(), timeout)
    except asyncio.TimeoutError:
        raise AssertionError(f"no {what} within {timeout} s") from None


def item(home, north_m, alt_m):
    nan = float("nan")
    return MissionItem(home.latitude_deg + north_m / M_PER_DEG, home.longitude_deg, alt_m, 5.0, True, nan, nan,
                       MissionItem.CameraAction.NONE, nan, 1.0, 2.0, nan, nan, MissionItem.VehicleAction.NONE)


def test_1_changes_everything(rotorpilot_mavsdk, rotorpilot_vehicle):
    with open("pid", "w") as f:
        f.write(str(rotorpilot_vehicle.proc.pid))

    async def fly():
        drone = rotorpilot_mavsdk
        await drone.connect()
        await first(drone.telemetry.health(), lambda h: h.is_armable and h.is_home_position_ok, 10, "health")
        home = await first(drone.telemetry.home(), lambda h: True, 10, "home")
        await drone.param.set_param_float("MIS_TAKEOFF_ALT", 7.5)
        await drone.param.set_param_float("MPC_XY_CRUISE", 3.0)
        await drone.param.set_param_int("SYS_FAILURE_EN", 1)
        await drone.mission.upload_mission(MissionPlan([item(home, 10, 8), item(home, 20, 8)]))
        d = 100 / M_PER_DEG
        fence = [Point(home.latitude_deg + a * d, home.longitude_deg + b * d) for a, b in ((1, 1), (1, -1), (-1, -1), (-1, 1))]
        await drone.geofence.upload_geofence(GeofenceData([Polygon(fence, FenceType.INCLUSION)], []))
        assert len((await drone.mission.download_mission()).mission_items) == 2
        await drone.action.arm()
        await drone.action.takeoff()
        await first(drone.telemetry.position(), lambda p: p.relative_altitude_m > 5.0, 30, "takeoff")
        await drone.failure.inject(FailureUnit.SYSTEM_MOTOR, FailureType.OFF, 1)
        await asyncio.sleep(0.3)  # falling, armed, with a dead motor: the test ends here

    asyncio.run(asyncio.wait_for(fly(), 120))


def recv(m, kind, cond=None, timeout=10.0):
    msg = wait_message(m, kind, cond, timeout)
    assert msg is not None, f"no {kind} meeting the condition within {timeout} s"
    return msg


def param(m, name):
    m.mav.param_request_read_send(m.target_system, 1, name.encode(), -1)
    p = recv(m, "PARAM_VALUE", lambda p: p.param_id == name, 5)
    if p.param_type == mavutil.mavlink.MAV_PARAM_TYPE_INT32:
        return struct.unpack("<i", struct.pack("<f", p.param_value))[0]
    return p.param_value


def test_2_sees_a_fresh_vehicle(rotorpilot_mavlink, rotorpilot_vehicle):
    m = rotorpilot_mavlink
    with open("pid") as f:
        assert int(f.read()) == rotorpilot_vehicle.proc.pid, "the same vehicle (daemon) as the first test"
    # parameters at their start values
    assert param(m, "MIS_TAKEOFF_ALT") == 2.5
    assert param(m, "MPC_XY_CRUISE") == 5.0
    assert param(m, "SYS_FAILURE_EN") == 0
    # no plan of any type
    for kind in (0, 1, 2):
        m.mav.mission_request_list_send(m.target_system, 1, kind)
        assert recv(m, "MISSION_COUNT", lambda c: c.mission_type == kind, 5).count == 0, f"plan type {kind}"
    # disarmed, on the ground at home, ready to arm
    assert not recv(m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1).base_mode & 128, "disarmed"
    m.mav.command_long_send(m.target_system, 1, mavutil.mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 242, 0, 0, 0, 0, 0, 0)
    home = recv(m, "HOME_POSITION", timeout=5)
    pos = recv(m, "GLOBAL_POSITION_INT")
    # at home within the navigation filter's horizontal error on the ground (0.3 m: 27e-7 deg of latitude)
    assert abs(pos.lat - home.latitude) <= 27 and abs(pos.lon - home.longitude) <= 40, (pos, home)
    assert abs(pos.relative_alt) < 300 and abs(pos.vz) < 5, pos
    # no failure left: it climbs to the default takeoff altitude on all four motors and holds level
    m.arducopter_arm()
    recv(m, "HEARTBEAT", lambda h: h.base_mode & 128, 5)
    m.mav.command_long_send(m.target_system, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 0)
    recv(m, "GLOBAL_POSITION_INT", lambda g: g.relative_alt > 2300, 30)
    att = recv(m, "ATTITUDE")
    assert abs(att.roll) < 0.1 and abs(att.pitch) < 0.1, att
'''


def test_the_next_test_sees_defaults_no_plan_no_failure_disarmed_at_home(tmp_path):
    rc, out, left = run_inner(tmp_path, STATE)
    assert rc == 0, out[-4000:]
    assert "2 passed" in out, out[-4000:]
    assert not left, left


WORKERS = '''
import os
import pytest

pytestmark = pytest.mark.rotorpilot(speed=10, reuse=True)

@pytest.mark.parametrize("i", range(6))
def test_takes_a_shared_vehicle(rotorpilot_mavlink, rotorpilot_vehicle, i):
    assert rotorpilot_mavlink.target_system == 1
    with open(f"seen-{i}", "w") as f:
        f.write(f"{os.environ.get('PYTEST_XDIST_WORKER', 'main')} {rotorpilot_vehicle.proc.pid}")

def test_z_fails(rotorpilot_mavlink):
    rotorpilot_mavlink.arducopter_arm()
    assert False, "on purpose"
'''


def test_each_xdist_worker_has_its_own_shared_vehicle(tmp_path):
    rc, out, left = run_inner(tmp_path, WORKERS, "-n", "2")
    assert rc == 1 and "1 failed, 6 passed" in out, out[-4000:]
    assert not left, left
    seen = [(tmp_path / f"seen-{i}").read_text().split() for i in range(6)]
    pids = {}
    for worker, pid in seen:
        pids.setdefault(worker, set()).add(pid)
    assert len(pids) == 2, seen  # both workers served tests
    assert all(len(p) == 1 for p in pids.values()), pids  # one vehicle per worker
    assert len(set.union(*pids.values())) == 2, pids  # not the same one
    # the failed test's record is kept and named, with the step its flight starts at
    assert "rotorpilot: flight record kept in" in out, out[-4000:]
    assert "a shared vehicle: this test's flight starts at step" in out, out[-4000:]


# --- the proof: a flight after a reset is a fresh vehicle's flight ----------------

def connect(v):
    m = mavutil.mavlink_connection(v.pymavlink_url, source_system=255)
    assert m.wait_heartbeat(timeout=10) is not None
    return m


def command(m, cmd, *p):
    m.mav.command_long_send(m.target_system, 1, cmd, 0, *(list(p) + [0] * (7 - len(p))))
    ack = wait_message(m, "COMMAND_ACK", lambda a: a.command == cmd, 5)
    assert ack is not None and ack.result == 0, (cmd, ack)


def upload_mission(m, n):
    m.mav.mission_count_send(m.target_system, 1, n, 0)
    for _ in range(n):
        req = wait_message(m, ["MISSION_REQUEST_INT", "MISSION_REQUEST"], None, 5)
        assert req is not None
        m.mav.mission_item_int_send(m.target_system, 1, req.seq, MAVLINK.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                    MAVLINK.MAV_CMD_NAV_WAYPOINT, 0, 1, 0, 0, 0, float("nan"),
                                    473977420 + 1000 * (req.seq + 1), 85455940, 10.0, 0)
    ack = wait_message(m, "MISSION_ACK", None, 5)
    assert ack is not None and ack.type == 0, ack


def messy_flight(v):
    """What a first test leaves behind: parameters, a mission, a failure, in the air."""
    m = connect(v)
    for name, value, kind in (("MIS_TAKEOFF_ALT", 7.5, 9), ("MPC_XY_CRUISE", 3.0, 9),
                              ("SYS_FAILURE_EN", struct.unpack("<f", struct.pack("<i", 1))[0], 6)):
        m.mav.param_set_send(m.target_system, 1, name.encode(), value, kind)
        assert wait_message(m, "PARAM_VALUE", lambda p, n=name: p.param_id == n, 5) is not None
    upload_mission(m, 2)
    m.arducopter_arm()
    assert wait_message(m, "HEARTBEAT", lambda h: h.base_mode & 128, 5)
    command(m, MAVLINK.MAV_CMD_NAV_TAKEOFF)
    assert wait_message(m, "GLOBAL_POSITION_INT", lambda g: g.relative_alt > 5000, 30)
    command(m, MAVLINK.MAV_CMD_INJECT_FAILURE, 101, 1, 1)  # motor 1 off
    m.close()


def short_flight(v):
    """The test under comparison: arm, take off, land, disarmed."""
    m = connect(v)
    m.arducopter_arm()
    assert wait_message(m, "HEARTBEAT", lambda h: h.base_mode & 128, 5)
    command(m, MAVLINK.MAV_CMD_NAV_TAKEOFF)
    assert wait_message(m, "GLOBAL_POSITION_INT", lambda g: g.relative_alt > 2000, 30)
    command(m, MAVLINK.MAV_CMD_NAV_LAND)
    assert wait_message(m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1 and not h.base_mode & 128, 60)
    m.close()


def read_record(path):
    with open(path) as f:
        lines = [json.loads(line) for line in f]
    return lines[0]["header"], [x for x in lines[1:] if "end" not in x], lines[-1].get("end", {}).get("step")


def without_step(inputs):
    return [{k: v for k, v in x.items() if k != "step"} for x in inputs]


def test_a_flight_after_a_reset_is_a_fresh_vehicles_flight(tmp_path):
    # on the ideal navigation solution: to the bit (on the daemon's default,
    # the navigation filter, within its time stamps' rounding: docs/testing.md)
    opts = dict(speed=10, params={"RP_NAV_SRC": 0}, extra_args=["--log-csv"], root=str(tmp_path))
    fresh = Vehicle(**opts).start()
    try:
        short_flight(fresh)
    finally:
        assert fresh.stop() == 0
    shared = Vehicle(**opts).start()
    try:
        messy_flight(shared)
        step0 = reset(shared)
        short_flight(shared)
    finally:
        assert shared.stop() == 0
    f_header, f_inputs, _ = read_record(fresh.record)
    s_header, s_inputs, s_end = read_record(shared.record)
    assert s_header == f_header, "both started as the same fresh vehicle"

    # the inputs: the reset's reboot line, then exactly the fresh flight's inputs (their steps are the wall clock's)
    reboot = max(i for i, x in enumerate(s_inputs) if "reboot" in x)
    assert s_inputs[reboot]["step"] == step0
    after = s_inputs[reboot + 1:]
    assert without_step(after) == without_step(f_inputs)

    # the CSV: those inputs on a fresh vehicle (the fresh record's header, steps counted from the reset)
    # replay to the live flight after the reset, every column but time_s
    rebased = tmp_path / "after-reset.record"
    with open(rebased, "w") as f:
        f.write(json.dumps({"header": f_header}) + "\n")
        for x in after:
            f.write(json.dumps(dict(x, step=x["step"] - step0)) + "\n")
        f.write(json.dumps({"end": {"step": s_end - step0}}) + "\n")
    out = tmp_path / "after-reset.csv"
    r = subprocess.run([binary(), "replay", str(rebased), "--csv", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    with open(os.path.join(shared.log_dir, "flight.csv")) as f:
        live = f.read().splitlines()
    with open(out) as f:
        replayed = f.read().splitlines()
    assert live[0] == replayed[0]  # the header row
    live_rows = live[1 + step0:]
    assert len(live_rows) == len(replayed) - 1 == s_end - step0
    dt = f_header["step_s"]
    for k, (a, b) in enumerate(zip(live_rows, replayed[1:])):
        ta, rest_a = a.split(",", 1)
        tb, rest_b = b.split(",", 1)
        assert rest_a == rest_b, f"row {k} after the reset differs from a fresh vehicle's:\n{a}\n{b}"
        assert abs(float(ta) - float(tb) - step0 * dt) < 1e-6, (k, ta, tb)
