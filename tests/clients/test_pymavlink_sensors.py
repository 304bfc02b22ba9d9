"""The raw sensors on the wire, read by pymavlink against the real rotorpilot
binary as a ground station reads PX4 SITL's: HIGHRES_IMU, SCALED_IMU and
SCALED_PRESSURE asked for with SET_MESSAGE_INTERVAL on the GCS link (PX4's
normal mode does not stream them), GPS_RAW_INT with the receiver's own
accuracies; then MAV_CMD_INJECT_FAILURE with PX4's sensor units: a STUCK
barometer repeats one pressure, an OFF barometer sends nothing, an OFF
magnetometer leaves HIGHRES_IMU's magnetometer fields unflagged, and OK
brings each back; a WRONG barometer (PX4 has none) is UNSUPPORTED and a
second barometer DENIED. Then the navigation messages as PX4 SITL streams
them (`mavlink_main.cpp`, `configure_streams_to_default`): ESTIMATOR_STATUS
at 0.5 Hz on the GCS link (normal mode) and 1 Hz on the API link (onboard),
VIBRATION at 0.1 and 0.5 Hz, ODOMETRY at 30 Hz on the API link only; their
values against the vehicle's own LOCAL_POSITION_NED in a hover, on the
ideal solution and on the navigation filter.

Run with the pymavlink venv: `python -m pytest tests/clients/test_pymavlink_sensors.py`.
"""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle, command, drain  # noqa: E402
from harness import wait_message as wait  # noqa: E402
from test_pymavlink import connect, param_set, wait_armable  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
INJECT = mavlink.MAV_CMD_INJECT_FAILURE
MAG, BARO = 2, 3
OK, OFF, STUCK, WRONG = 0, 1, 2, 4
# ESTIMATOR_STATUS.flags of a good GNSS-aided solution, as PX4 SITL reports it:
# attitude, horizontal and vertical velocity, relative and absolute horizontal
# position, absolute vertical position, predicted relative and absolute position
GOOD_SOLUTION = 1 | 2 | 4 | 8 | 16 | 32 | 256 | 512
ODOMETRY_ID = 331  # a MAVLink 2 id: pymavlink's default (v1.0) module names no constant for it
# HIGHRES_IMU.fields_updated bits
ACC_GYRO = 0x3F
MAG_BITS = 0x1C0
PRESSURE = 0x200


@pytest.fixture
def vehicle(request):
    with Vehicle(speed=2.0, params=getattr(request, "param", None)) as v:
        yield v
        print("rotorpilot log (tail):\n" + v.logs())


def stream(m, msg_id, hz):
    r = command(m, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz)
    assert r == mavlink.MAV_RESULT_ACCEPTED, (msg_id, r)


def collect(m, kind, seconds):
    """Every `kind` message within `seconds` wall seconds."""
    out = []
    wait(m, kind, lambda msg: out.append(msg) and False, timeout=seconds)
    return out


def inject(m, unit, kind, instance=0):
    nan = float("nan")
    return command(m, INJECT, unit, kind, instance, nan, nan, nan, nan)


def raw_streams(v):
    m = connect(v)
    stream(m, mavlink.MAVLINK_MSG_ID_HIGHRES_IMU, 50)
    stream(m, mavlink.MAVLINK_MSG_ID_SCALED_IMU, 25)
    stream(m, mavlink.MAVLINK_MSG_ID_SCALED_PRESSURE, 20)
    return m


def test_raw_sensor_messages_are_sane_at_rest(vehicle):
    m = raw_streams(vehicle)
    h = collect(m, "HIGHRES_IMU", 1.0)
    assert len(h) >= 20, len(h)
    zacc = sum(x.zacc for x in h) / len(h)
    # at rest: specific force -g on the FRD z axis (plus a turn-on bias of ~0.2 m/s^2)
    assert zacc == pytest.approx(-9.81, abs=0.6), zacc
    assert all(abs(x.xgyro) < 0.05 and abs(x.zgyro) < 0.05 for x in h)
    assert all(x.fields_updated & (ACC_GYRO | MAG_BITS | PRESSURE) == ACC_GYRO | MAG_BITS | PRESSURE for x in h)
    # ISA at PX4's home (488 m AMSL): ~955.9 hPa, and the pressure altitude near it
    assert h[-1].abs_pressure == pytest.approx(955.9, abs=0.6)
    assert h[-1].pressure_alt == pytest.approx(488.0, abs=5.0)
    # the Earth's field at home: ~0.49 gauss, mostly down
    b = h[-1]
    assert (b.xmag**2 + b.ymag**2 + b.zmag**2) ** 0.5 == pytest.approx(0.486, abs=0.05)
    assert b.zmag > 0.3
    # the noise is there: the accelerometer does not repeat itself
    assert len({x.zacc for x in h}) > len(h) // 2
    s = wait(m, "SCALED_IMU", timeout=2.0)
    assert s is not None and s.zacc == pytest.approx(-1000, abs=70), s
    p = wait(m, "SCALED_PRESSURE", timeout=2.0)
    assert p is not None and p.press_abs == pytest.approx(955.9, abs=0.6), p
    g = wait(m, "GPS_RAW_INT", timeout=3.0)
    assert g is not None and g.fix_type == 3
    assert (g.h_acc, g.v_acc, g.vel_acc, g.eph, g.epv) == (900, 1780, 400, 70, 110)
    assert g.lat == pytest.approx(473977420, abs=50)


def test_baro_stuck_and_off_and_mag_off_show_on_the_wire(vehicle):
    m = raw_streams(vehicle)
    assert param_set(m, "SYS_FAILURE_EN", 1, mavlink.MAV_PARAM_TYPE_INT32) is not None
    # PX4 has no WRONG barometer, and there is one barometer
    assert inject(m, BARO, WRONG) == mavlink.MAV_RESULT_UNSUPPORTED
    assert inject(m, BARO, OFF, 2) == mavlink.MAV_RESULT_DENIED
    live = collect(m, "SCALED_PRESSURE", 1.0)
    assert len({p.press_abs for p in live}) > 3, "a live barometer is noisy"

    assert inject(m, BARO, STUCK) == mavlink.MAV_RESULT_ACCEPTED
    wait(m, "STATUSTEXT", lambda s: "baro stuck" in s.text, timeout=2.0)
    drain(m)
    collect(m, "SCALED_PRESSURE", 0.2)
    stuck = collect(m, "SCALED_PRESSURE", 1.0)
    assert len(stuck) >= 10, len(stuck)
    assert len({p.press_abs for p in stuck}) == 1, "a stuck barometer repeats its value"
    assert stuck[-1].time_boot_ms > stuck[0].time_boot_ms, "with new times"

    assert inject(m, BARO, OFF) == mavlink.MAV_RESULT_ACCEPTED
    drain(m)
    collect(m, "SCALED_PRESSURE", 0.2)
    assert collect(m, "SCALED_PRESSURE", 1.0) == [], "an off barometer sends nothing"
    h = wait(m, "HIGHRES_IMU", timeout=2.0)
    assert h is not None and not h.fields_updated & PRESSURE and h.abs_pressure == 0.0

    assert inject(m, MAG, OFF) == mavlink.MAV_RESULT_ACCEPTED
    drain(m)
    collect(m, "HIGHRES_IMU", 0.2)
    h = collect(m, "HIGHRES_IMU", 0.5)
    assert h and all(not x.fields_updated & MAG_BITS and x.xmag == 0.0 for x in h)
    assert all(x.fields_updated & ACC_GYRO == ACC_GYRO for x in h), "the IMU still works"

    for unit in (BARO, MAG):
        assert inject(m, unit, OK) == mavlink.MAV_RESULT_ACCEPTED
    drain(m)
    collect(m, "HIGHRES_IMU", 0.2)
    h = collect(m, "HIGHRES_IMU", 0.5)
    assert h and all(x.fields_updated & (MAG_BITS | PRESSURE) == MAG_BITS | PRESSURE for x in h)
    back = collect(m, "SCALED_PRESSURE", 1.0)
    assert len({p.press_abs for p in back}) > 3, "fresh values again"


def api_link(v):
    """The API link (PX4's onboard mode), where PX4 SITL's API clients listen."""
    a = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.api_port}", source_system=254)
    assert a.wait_heartbeat(timeout=5) is not None, "the API link speaks first"
    return a


def counts(m, kinds, seconds):
    """How many of each of `kinds` arrive within `seconds` wall seconds, and the last of each."""
    n = {k: 0 for k in kinds}
    last = {}

    def see(msg):
        n[msg.get_type()] += 1
        last[msg.get_type()] = msg
        return False

    wait(m, list(kinds), see, timeout=seconds)
    return n, last


def hover(m, alt=3.0):
    assert param_set(m, "MIS_TAKEOFF_ALT", alt).param_value == pytest.approx(alt)
    wait_armable(m)
    m.arducopter_arm()
    assert wait(m, "HEARTBEAT", lambda h: h.base_mode & 128, 3.0) is not None, "armed"
    assert command(m, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == 0
    assert wait(m, "HEARTBEAT", lambda h: mavutil.interpret_px4_mode(h.base_mode, h.custom_mode) == "LOITER", 20)


def paired(m, seconds=1.0):
    """ODOMETRY and LOCAL_POSITION_NED of the same instant (same ms) on one link."""
    local = {}
    out = []

    def see(msg):
        if msg.get_type() == "LOCAL_POSITION_NED":
            local[msg.time_boot_ms] = msg
        elif msg.time_usec // 1000 in local:
            out.append((msg, local[msg.time_usec // 1000]))
        return False

    wait(m, ["ODOMETRY", "LOCAL_POSITION_NED"], see, timeout=seconds)
    return out


def check_odometry_against_local_position(a):
    pairs = paired(a)
    assert len(pairs) >= 5, len(pairs)
    for o, lp in pairs:
        assert (o.frame_id, o.child_frame_id) == (mavlink.MAV_FRAME_LOCAL_NED,) * 2, "PX4's EKF2 odometry is NED"
        assert o.estimator_type == mavlink.MAV_ESTIMATOR_TYPE_AUTOPILOT
        assert (o.x, o.y, o.z) == pytest.approx((lp.x, lp.y, lp.z), abs=1e-3)
        assert (o.vx, o.vy, o.vz) == pytest.approx((lp.vx, lp.vy, lp.vz), abs=1e-3)
        assert sum(c * c for c in o.q) == pytest.approx(1.0, abs=1e-4)
    return pairs[-1][0]


@pytest.mark.parametrize("vehicle", [{"RP_NAV_SRC": 0}], ids=["ideal"], indirect=True)
def test_navigation_messages_at_px4_rates_and_true_to_the_hover(vehicle):
    m = connect(vehicle)
    a = api_link(vehicle)
    hover(m)
    # the API link (onboard mode): ODOMETRY 30 Hz, ESTIMATOR_STATUS 1 Hz, VIBRATION 0.5 Hz
    drain(a)
    n, last = counts(a, ["ODOMETRY", "ESTIMATOR_STATUS", "VIBRATION"], 8.0)
    print("API link in 8 s:", n)
    assert 30 * 8 * 0.8 <= n["ODOMETRY"] <= 30 * 8 * 1.1, n
    assert 7 <= n["ESTIMATOR_STATUS"] <= 9, n
    assert 3 <= n["VIBRATION"] <= 5, n
    # the ideal solution reports what a healthy EKF does
    e = last["ESTIMATOR_STATUS"]
    assert e.flags == GOOD_SOLUTION, e
    assert (e.vel_ratio, e.pos_horiz_ratio, e.pos_vert_ratio, e.mag_ratio) == (0, 0, 0, 0)
    assert e.hagl_ratio != e.hagl_ratio and e.tas_ratio != e.tas_ratio, "NaN: no range finder, no airspeed"
    # vibration in a hover: the accelerometer's noise and the rotors' ripple, small and positive
    v = last["VIBRATION"]
    print("VIBRATION in a hover:", v)
    assert 0.0 < v.vibration_z < 0.5, v
    assert 0.0 < v.vibration_y < 0.1 and v.vibration_x >= 0.0, v
    assert (v.clipping_0, v.clipping_1, v.clipping_2) == (0, 0, 0)
    # ODOMETRY is the solution LOCAL_POSITION_NED carries, 3 m up
    o = check_odometry_against_local_position(a)
    assert o.z == pytest.approx(-3.0, abs=0.3)
    assert o.pose_covariance[0] != o.pose_covariance[0], "the ideal solution has no covariance: unknown"

    # the GCS link (normal mode): ESTIMATOR_STATUS 0.5 Hz, no ODOMETRY until asked
    drain(m)
    n, _ = counts(m, ["ODOMETRY", "ESTIMATOR_STATUS"], 6.0)
    print("GCS link in 6 s:", n)
    assert n["ODOMETRY"] == 0 and 2 <= n["ESTIMATOR_STATUS"] <= 4, n
    stream(m, ODOMETRY_ID, 10)
    drain(m)
    n, _ = counts(m, ["ODOMETRY"], 2.0)
    assert 15 <= n["ODOMETRY"] <= 22, n
    # VIBRATION's 0.1 Hz is slow to count: asked for once, it comes at once
    drain(m)
    m.mav.command_long_send(m.target_system, m.target_component, mavlink.MAV_CMD_REQUEST_MESSAGE, 0,
                            mavlink.MAVLINK_MSG_ID_VIBRATION, 0, 0, 0, 0, 0, 0)
    got = []
    wait(m, ["VIBRATION", "COMMAND_ACK"], lambda x: got.append(x) and False, timeout=1.0)
    assert [x.result for x in got if x.get_type() == "COMMAND_ACK"] == [mavlink.MAV_RESULT_ACCEPTED]
    assert any(x.get_type() == "VIBRATION" for x in got), got


def test_estimator_status_and_odometry_from_the_navigation_filter(vehicle):
    """On the daemon's default navigation source, the filter."""
    m = connect(vehicle)
    a = api_link(vehicle)
    hover(m)
    drain(a)
    n, last = counts(a, ["ESTIMATOR_STATUS"], 3.0)
    e = last["ESTIMATOR_STATUS"]
    print("ESTIMATOR_STATUS on the filter:", e)
    assert e.flags == GOOD_SOLUTION, e
    ratios = (e.vel_ratio, e.pos_horiz_ratio, e.pos_vert_ratio, e.mag_ratio)
    assert all(0.0 <= r < 1.0 for r in ratios), "every innovation within its gate"
    assert any(r > 0.0 for r in ratios), "the filter's own innovations"
    assert 0.0 < e.pos_horiz_accuracy < 2.0 and 0.0 < e.pos_vert_accuracy < 3.0, e
    o = check_odometry_against_local_position(a)
    pose = [o.pose_covariance[i] for i in (0, 6, 11, 15, 18, 20)]
    vel = [o.velocity_covariance[i] for i in (0, 6, 11)]
    assert all(0.0 < c < 10.0 for c in pose + vel), (pose, vel)
    assert o.pose_covariance[1] != o.pose_covariance[1], "off-diagonal terms unknown (NaN)"
    # its horizontal accuracy is the covariance's: sqrt(P_nn + P_ee)
    assert e.pos_horiz_accuracy == pytest.approx((pose[0] + pose[1]) ** 0.5, rel=0.3)
