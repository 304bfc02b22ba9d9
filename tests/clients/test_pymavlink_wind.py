"""The wind the vehicle feels, over MAVLink, as PX4 sends it: pymavlink as a
GCS against the rotorpilot binary sets the world's wind in flight
(SIM_WIND_SPD = 5 m/s, SIM_WIND_DIR = 270: from the west, ArduPilot's
convention; no turbulence) and reads WIND_COV, the flight stack's estimate
from the momentum-based estimator's force and the quad's nominal drag. Every
wait is bounded.

Run with the pymavlink venv: `python -m pytest tests/clients/test_pymavlink_wind.py`.
"""

import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

import pytest


sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle, command, drain  # noqa: E402
from harness import wait_message as wait  # noqa: E402
from test_pymavlink import connect, param_set, rel_alt, sim_time_s, wait_armable, wait_sim  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
WIND_COV = 231


@pytest.fixture
def vehicle():
    logs = tempfile.mkdtemp(prefix="rotorpilot-wind-logs-")
    with Vehicle(speed=5.0, extra=["--log-dir", logs]) as v:
        yield v
        print("rotorpilot log (tail):\n" + v.logs())
    shutil.rmtree(logs, ignore_errors=True)


def from_deg(w):
    """The direction the wind comes from [deg, 0..360), from WIND_COV's north and east."""
    return math.degrees(math.atan2(-w.wind_y, -w.wind_x)) % 360.0


def test_wind_cov_reports_the_wind_set_in_flight(vehicle):
    m = connect(vehicle)
    # SET_MESSAGE_INTERVAL as for any stream: 10 Hz on this link (0.5 Hz by default, as PX4's normal mode)
    assert command(m, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, WIND_COV, 100_000) == 0
    # on the ground there is no estimate: nothing is sent, and a request is denied as PX4 denies it
    drain(m)
    assert wait(m, "WIND_COV", timeout=1.0) is None
    assert command(m, mavlink.MAV_CMD_REQUEST_MESSAGE, WIND_COV) == mavlink.MAV_RESULT_DENIED

    assert param_set(m, "MIS_TAKEOFF_ALT", 5.0).param_value == pytest.approx(5.0)
    wait_armable(m)
    m.arducopter_arm()
    assert wait(m, "HEARTBEAT", lambda h: h.base_mode & 128, 3.0) is not None, "armed"
    assert command(m, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == 0
    assert wait(m, "HEARTBEAT", lambda h: mavutil.interpret_px4_mode(h.base_mode, h.custom_mode) == "LOITER", 20)
    assert abs(rel_alt(m) - 5.0) < 0.4
    # still air: the estimate is there and calm
    w = wait(m, "WIND_COV", timeout=5.0)
    assert w is not None, "no WIND_COV in the air"
    assert math.hypot(w.wind_x, w.wind_y) < 0.3, w

    for name, value in [("SIM_WIND_TURB", 0.0), ("SIM_WIND_DIR", 270.0), ("SIM_WIND_SPD", 5.0)]:
        p = param_set(m, name, value)
        assert p is not None and p.param_value == pytest.approx(value), name
    t0 = sim_time_s(m)
    wait_sim(m, 10.0)
    drain(m)
    w = wait(m, "WIND_COV", timeout=2.0)
    assert w is not None
    speed = math.hypot(w.wind_x, w.wind_y)
    print(f"{w.time_usec / 1e6 - t0:.1f} s after the wind was set: WIND_COV north {w.wind_x:.3f} east "
          f"{w.wind_y:.3f} m/s ({speed:.3f} m/s from {from_deg(w):.1f} deg), var_horiz {w.var_horiz:.4f}, "
          f"wind_alt {w.wind_alt:.1f} m")
    # from the west: it blows east
    assert speed == pytest.approx(5.0, abs=0.5)
    assert abs((from_deg(w) - 270.0 + 180.0) % 360.0 - 180.0) < 10.0
    assert (w.wind_z, w.var_vert, w.horiz_accuracy, w.vert_accuracy) == (0.0, 0.0, 0.0, 0.0)
    assert 0.0 <= w.var_horiz < 0.05
    g = wait(m, "GLOBAL_POSITION_INT", timeout=2.0)
    assert w.wind_alt == pytest.approx(g.alt / 1000.0, abs=0.5), "wind_alt is the altitude AMSL"
    # the vehicle holds its position against it
    assert abs(rel_alt(m) - 5.0) < 0.5

    # land: the estimate is forgotten on the ground
    drain(m)
    m.set_mode("LAND")
    assert wait(m, "EXTENDED_SYS_STATE", lambda e: e.landed_state == 1, 40.0) is not None, "landed"
    time.sleep(0.5)
    drain(m)
    assert wait(m, "WIND_COV", timeout=1.0) is None

    # the flight's ULog has PX4's `wind` topic, 1 Hz while the estimate exists
    from pyulog import ULog

    run_dir = Path(next(line.split("logs:", 1)[1].strip() for line in vehicle.banner if "logs:" in line))
    vehicle.stop()
    ulog = ULog(str(run_dir / "flight.ulg"))
    wind = next(d for d in ulog.data_list if d.name == "wind").data
    late = [i for i, t in enumerate(wind["timestamp"]) if t / 1e6 > w.time_usec / 1e6 - 3.0]
    assert late, "wind logged up to the end of the hover"
    i = late[0]
    print(f"ULog wind: {len(wind['timestamp'])} samples; at {wind['timestamp'][i] / 1e6:.1f} s north "
          f"{wind['windspeed_north'][i]:.3f} east {wind['windspeed_east'][i]:.3f} m/s")
    assert wind["windspeed_north"][i] == pytest.approx(0.0, abs=0.5)
    assert wind["windspeed_east"][i] == pytest.approx(5.0, abs=0.5)
    assert wind["variance_north"][i] >= 0.0 and wind["tas_innov"][i] == 0.0
