"""MAV_CMD_INJECT_FAILURE from pymavlink against the real rotorpilot binary, as
a test script would inject failures into PX4 SITL: DENIED while SYS_FAILURE_EN
is 0; once set, each supported unit/type ACCEPTED with its effect on the wire
(GPS_RAW_INT and the SYS_STATUS GPS health bit, the battery voltage, the
motor's STATUSTEXT, a silent radio) and undone with FAILURE_TYPE_OK;
unsupported pairs UNSUPPORTED, a motor that does not exist DENIED. A motor
switched off in flight reads stopped in ACTUATOR_OUTPUT_STATUS, as PX4's
control-allocation test checks it.

Run with the pymavlink venv: `python -m pytest tests/clients/test_pymavlink_failure.py`.
"""

import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle, command, drain  # noqa: E402
from harness import wait_message as wait  # noqa: E402
from test_pymavlink import connect, param_set, rel_alt, wait_armable  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
INJECT = mavlink.MAV_CMD_INJECT_FAILURE
GPS, BATTERY, MOTOR, MAVLINK_SIGNAL = 4, 100, 101, 105
OK, OFF, STUCK, WRONG = 0, 1, 2, 4
GPS_HEALTH = 0x20  # MAV_SYS_STATUS_SENSOR_GPS
ACTUATOR_OUTPUT_STATUS = 375


@pytest.fixture
def vehicle():
    with Vehicle(speed=5.0) as v:
        yield v
        print("rotorpilot log (tail):\n" + v.logs())


def enabled(v):
    m = connect(v)
    pv = param_set(m, "SYS_FAILURE_EN", 1, mavlink.MAV_PARAM_TYPE_INT32)
    assert pv is not None, "no PARAM_VALUE for SYS_FAILURE_EN"
    return m


def inject(m, unit, kind, instance=0):
    return command(m, INJECT, unit, kind, instance, float("nan"), float("nan"), float("nan"), float("nan"))


def status_text(m, part, timeout=3.0):
    st = wait(m, "STATUSTEXT", lambda s: part in s.text, timeout)
    assert st is not None, f"no STATUSTEXT with {part!r}"
    return st


def test_denied_while_disabled_unsupported_and_missing_motor(vehicle):
    m = connect(vehicle)
    assert inject(m, GPS, OFF) == mavlink.MAV_RESULT_DENIED
    status_text(m, "SYS_FAILURE_EN")
    # nothing happened: the receiver still has its fix
    g = wait(m, "GPS_RAW_INT", timeout=3.0)
    assert g is not None and g.fix_type == 3 and g.satellites_visible > 0
    pv = param_set(m, "SYS_FAILURE_EN", 1, mavlink.MAV_PARAM_TYPE_INT32)
    assert pv is not None
    for unit, kind in [(0, WRONG), (3, WRONG), (GPS, 3), (BATTERY, WRONG), (MAVLINK_SIGNAL, WRONG), (104, OFF)]:
        assert inject(m, unit, kind) == mavlink.MAV_RESULT_UNSUPPORTED, (unit, kind)
    # the default airframe is a quad: motor 9 does not exist
    assert inject(m, MOTOR, OFF, 9) == mavlink.MAV_RESULT_DENIED
    drain(m)
    s = wait(m, "SYS_STATUS", timeout=3.0)
    assert s is not None and s.onboard_control_sensors_health & GPS_HEALTH


def test_gps_off_shows_on_the_wire_and_ok_restores_it(vehicle):
    m = enabled(vehicle)
    assert inject(m, GPS, OFF) == mavlink.MAV_RESULT_ACCEPTED
    status_text(m, "CMD_INJECT_FAILURE, GPS off")
    g = wait(m, "GPS_RAW_INT", lambda g: g.fix_type <= 1, timeout=3.0)
    assert g is not None, "GPS_RAW_INT never lost its fix"
    # PX4's silent receiver (GPS_RAW_INT.hpp): NO_GPS, nothing known
    assert (g.fix_type, g.satellites_visible, g.lat, g.lon) == (0, 255, 0, 0)
    assert (g.eph, g.epv, g.vel, g.cog) == (65535, 65535, 65535, 65535)
    s = wait(m, "SYS_STATUS", timeout=3.0)
    assert s is not None and not s.onboard_control_sensors_health & GPS_HEALTH
    assert inject(m, GPS, OK) == mavlink.MAV_RESULT_ACCEPTED
    g = wait(m, "GPS_RAW_INT", lambda g: g.fix_type == 3, timeout=3.0)
    assert g is not None and g.satellites_visible > 0
    s = wait(m, "SYS_STATUS", timeout=3.0)
    assert s is not None and s.onboard_control_sensors_health & GPS_HEALTH


def test_battery_cell_and_motors(vehicle):
    m = enabled(vehicle)
    drain(m)
    full = wait(m, "SYS_STATUS", timeout=3.0).voltage_battery
    assert full > 15000, full
    assert inject(m, BATTERY, OFF) == mavlink.MAV_RESULT_ACCEPTED
    status_text(m, "battery cell off")
    low = wait(m, "SYS_STATUS", lambda s: s.voltage_battery < 0.8 * full, timeout=3.0)
    assert low is not None, "the voltage did not drop"
    assert low.battery_remaining < 10, low.battery_remaining
    assert inject(m, BATTERY, OK) == mavlink.MAV_RESULT_ACCEPTED
    back = wait(m, "SYS_STATUS", lambda s: s.voltage_battery > 0.95 * full, timeout=3.0)
    assert back is not None, "the voltage did not come back"

    assert inject(m, MOTOR, OFF, 3) == mavlink.MAV_RESULT_ACCEPTED
    status_text(m, "CMD_INJECT_FAILURE, motor 3 off")
    assert inject(m, MOTOR, WRONG, 3) == mavlink.MAV_RESULT_ACCEPTED
    status_text(m, "motor 3 wrong (50% thrust)")
    assert inject(m, MOTOR, OK, 0) == mavlink.MAV_RESULT_ACCEPTED
    status_text(m, "CMD_INJECT_FAILURE, motors ok")


def test_run_prearm_checks_says_the_failing_check(vehicle):
    """MAV_CMD_RUN_PREARM_CHECKS is ACCEPTED and, as PX4's forced health
    report, says the first check that fails ("Preflight Fail: ..."): with a
    battery cell off, "battery critical"; once it is back, nothing fails and
    nothing is said."""
    m = enabled(vehicle)
    wait_armable(m)
    assert inject(m, BATTERY, OFF) == mavlink.MAV_RESULT_ACCEPTED
    assert wait(m, "SYS_STATUS", lambda s: s.battery_remaining < 10, timeout=3.0) is not None
    drain(m)
    assert command(m, mavlink.MAV_CMD_RUN_PREARM_CHECKS) == mavlink.MAV_RESULT_ACCEPTED
    status_text(m, "Preflight Fail: battery critical")
    assert inject(m, BATTERY, OK) == mavlink.MAV_RESULT_ACCEPTED
    wait_armable(m)
    drain(m)
    assert command(m, mavlink.MAV_CMD_RUN_PREARM_CHECKS) == mavlink.MAV_RESULT_ACCEPTED
    said = wait(m, "STATUSTEXT", lambda s: "Preflight Fail" in s.text, timeout=1.0)
    assert said is None, said.text


def test_mavlink_signal_off_silences_the_vehicle_until_ok(vehicle):
    m = enabled(vehicle)
    assert wait(m, "HEARTBEAT", timeout=3.0) is not None
    # the ACK of the command that silences the radio still comes
    assert inject(m, MAVLINK_SIGNAL, OFF) == mavlink.MAV_RESULT_ACCEPTED
    time.sleep(0.3)
    drain(m)
    silent = m.recv_match(blocking=True, timeout=2.0)
    assert silent is None, f"the vehicle still sends: {silent}"
    # it still listens: OK is answered and the heartbeats come back
    assert inject(m, MAVLINK_SIGNAL, OK) == mavlink.MAV_RESULT_ACCEPTED
    assert wait(m, "HEARTBEAT", timeout=3.0) is not None, "no heartbeat after OK"


def test_a_motor_off_in_flight_reads_stopped_in_actuator_output_status():
    """ACTUATOR_OUTPUT_STATUS as PX4 SITL's PWM outputs read (PX4's
    control-allocation test: a stopped motor at most 901, a running one at
    least 999): off until asked; once SET_MESSAGE_INTERVAL asks, 16 active
    channels, all at the disarmed 900 us on the ground; the six motors of
    hexa-ppnnpn (it flies on without motor 1) between 1000 and 2000 in a
    hover; motor 1 switched off reads 900 while the five others run."""
    with Vehicle(speed=5.0, extra=["--airframe", "hexa-ppnnpn"]) as v:
        try:
            m = enabled(v)
            drain(m)
            assert wait(m, "ACTUATOR_OUTPUT_STATUS", timeout=1.0) is None, "sent unasked (PX4: off by default)"
            assert command(m, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, ACTUATOR_OUTPUT_STATUS, 50_000) == 0
            a = wait(m, "ACTUATOR_OUTPUT_STATUS", timeout=2.0)
            assert a is not None, "no ACTUATOR_OUTPUT_STATUS once asked"
            assert a.active == 16 and list(a.actuator[:16]) == [900.0] * 16, (a.active, a.actuator)

            assert param_set(m, "MIS_TAKEOFF_ALT", 5.0).param_value == pytest.approx(5.0)
            wait_armable(m)
            m.arducopter_arm()
            assert wait(m, "HEARTBEAT", lambda h: h.base_mode & 128, 3.0) is not None, "armed"
            assert command(m, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == 0
            loiter = wait(m, "HEARTBEAT",
                          lambda h: mavutil.interpret_px4_mode(h.base_mode, h.custom_mode) == "LOITER", 20)
            assert loiter is not None, "takeoff complete"
            assert abs(rel_alt(m) - 5.0) < 0.5
            drain(m)
            a = wait(m, "ACTUATOR_OUTPUT_STATUS", timeout=2.0)
            print(f"hovering: {list(a.actuator[:6])}")
            assert all(1000.0 <= x <= 2000.0 for x in a.actuator[:6]), a.actuator
            assert list(a.actuator[6:16]) == [900.0] * 10, "unused channels at their disarmed value"

            assert inject(m, MOTOR, OFF, 1) == mavlink.MAV_RESULT_ACCEPTED
            stopped = wait(m, "ACTUATOR_OUTPUT_STATUS", lambda a: a.actuator[0] <= 901.0, timeout=5.0)
            assert stopped is not None, "motor 1 never read stopped"
            drain(m)
            a = wait(m, "ACTUATOR_OUTPUT_STATUS", timeout=2.0)
            print(f"motor 1 off: {list(a.actuator[:6])}")
            assert a.actuator[0] == 900.0, a.actuator
            assert all(x >= 999.0 for x in a.actuator[1:6]), a.actuator
            # a single one on request, as any stream's message
            drain(m)
            assert command(m, mavlink.MAV_CMD_REQUEST_MESSAGE, ACTUATOR_OUTPUT_STATUS) == 0
            assert wait(m, "ACTUATOR_OUTPUT_STATUS", timeout=1.0) is not None
        except BaseException:
            print("rotorpilot log (tail):\n" + v.logs())
            raise
