"""The raw sensors on the wire, read by pymavlink against the real rotorpilot
binary as a ground station reads PX4 SITL's: HIGHRES_IMU, SCALED_IMU and
SCALED_PRESSURE asked for with SET_MESSAGE_INTERVAL on the GCS link (PX4's
normal mode does not stream them), GPS_RAW_INT with the receiver's own
accuracies; then MAV_CMD_INJECT_FAILURE with PX4's sensor units: a STUCK
barometer repeats one pressure, an OFF barometer sends nothing, an OFF
magnetometer leaves HIGHRES_IMU's magnetometer fields unflagged, and OK
brings each back; a WRONG barometer (PX4 has none) is UNSUPPORTED and a
second barometer DENIED.

Run with the pymavlink venv: `python -m pytest tests/clients/test_pymavlink_sensors.py`.
"""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle, command, drain  # noqa: E402
from harness import wait_message as wait  # noqa: E402
from test_pymavlink import connect, param_set  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
INJECT = mavlink.MAV_CMD_INJECT_FAILURE
MAG, BARO = 2, 3
OK, OFF, STUCK, WRONG = 0, 1, 2, 4
# HIGHRES_IMU.fields_updated bits
ACC_GYRO = 0x3F
MAG_BITS = 0x1C0
PRESSURE = 0x200


@pytest.fixture
def vehicle():
    with Vehicle(speed=2.0) as v:
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
