"""pymavlink as a GCS against the real rotorpilot binary, as a user script would
drive PX4 SITL: udpin on the GCS port, parameters, arming, takeoff, the
estimated disturbances against the injected truth, a controller switch in
flight, offboard, land, disarm. Every wait is bounded.

Run with the pymavlink venv: `python -m pytest tests/clients/test_pymavlink.py`.
"""

import math
import struct
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle, command, drain  # noqa: E402
from harness import wait_message as wait  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
SPEED = 5.0
# the flight also runs, unchanged, with the vehicle at 20x
FAST = 20.0


def int32_as_float(v):
    """PX4 carries INT32 parameters bytewise in the float field."""
    return struct.unpack("<f", struct.pack("<i", v))[0]


def float_as_int32(f):
    return struct.unpack("<i", struct.pack("<f", f))[0]


@pytest.fixture(params=[SPEED], ids=lambda s: f"x{s:g}")
def vehicle(request):
    """`request.param`: the speed, or (speed, preset parameters)."""
    speed, params = request.param if isinstance(request.param, tuple) else (request.param, None)
    with Vehicle(speed=speed, params=params) as v:
        yield v
        # shown by pytest only when the test failed
        print("rotorpilot log (tail):\n" + v.logs())


def connect(v):
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=255)
    hb = m.wait_heartbeat(timeout=5)
    assert hb is not None, "no heartbeat: the vehicle must speak first"
    return m


def param_get(m, name, timeout=3.0):
    drain(m)
    m.mav.param_request_read_send(m.target_system, m.target_component, name.encode(), -1)
    return wait(m, "PARAM_VALUE", lambda p: p.param_id == name, timeout)


def param_set(m, name, value, kind=mavlink.MAV_PARAM_TYPE_REAL32, timeout=3.0):
    if kind == mavlink.MAV_PARAM_TYPE_INT32:
        value = int32_as_float(int(value))
    drain(m)
    m.param_set_send(name, value, kind)
    return wait(m, "PARAM_VALUE", lambda p: p.param_id == name, timeout)


def param_answers(m, name, value, kind=mavlink.MAV_PARAM_TYPE_REAL32, window=0.5, first=3.0):
    """Send PARAM_SET and return this set's answers: the PARAM_ERROR and
    PARAM_VALUE messages for `name`, in order, the first within `first` s
    (a loaded machine may delay it), then any others within `window` s of
    it. Answers to an earlier set (an accepted set's rebroadcast follows its
    echo by ~5 ms) are waited out first (100 ms without one), so none can
    pass for this set's."""
    if kind == mavlink.MAV_PARAM_TYPE_INT32:
        value = int32_as_float(int(value))
    types = ["PARAM_VALUE", "PARAM_ERROR"]
    while wait(m, types, lambda p: p.param_id == name, 0.1) is not None:
        pass
    drain(m)
    m.param_set_send(name, value, kind)
    a = wait(m, types, lambda p: p.param_id == name, first)
    if a is None:
        return []
    out = [a]
    deadline = time.monotonic() + window
    while (a := wait(m, types, lambda p: p.param_id == name, deadline - time.monotonic())) is not None:
        out.append(a)
    return out


def kinds(answers):
    return [a.get_type() for a in answers]


def wait_armable(m, timeout=10.0):
    ok = wait(m, "SYS_STATUS", lambda s: s.onboard_control_sensors_health & 0x10000000, timeout)
    assert ok is not None, "never armable"


def rel_alt(m):
    drain(m)
    g = wait(m, "GLOBAL_POSITION_INT", timeout=2.0)
    assert g is not None
    return g.relative_alt / 1000.0


def sim_time_s(m):
    """Simulated time [s] from the vehicle's own clock (ATTITUDE.time_boot_ms)."""
    drain(m)
    a = wait(m, "ATTITUDE", timeout=2.0)
    assert a is not None, "no ATTITUDE"
    return a.time_boot_ms / 1000.0


def wait_sim(m, seconds, wall_timeout=60.0):
    """Let `seconds` of simulated time pass, however fast the vehicle runs on this machine."""
    start = sim_time_s(m)
    deadline = time.monotonic() + wall_timeout
    while time.monotonic() < deadline:
        if sim_time_s(m) - start >= seconds:
            return
        time.sleep(0.05)
    raise AssertionError(f"{seconds} s of simulated time did not pass in {wall_timeout} s")


def latest(m, name, kind, timeout=2.0):
    drain(m)
    return wait(m, kind, lambda d: d.name == name, timeout)


def test_identity_and_mode_names(vehicle):
    m = connect(vehicle)
    hb = wait(m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1)
    assert hb.autopilot == mavlink.MAV_AUTOPILOT_PX4
    assert hb.type == mavlink.MAV_TYPE_QUADROTOR
    assert m.target_system == vehicle.sysid
    assert m.flightmode == "LOITER"
    assert m.mode_mapping()["OFFBOARD"] == (29, 6, 0)


def test_param_fetch_set_and_refuse(vehicle):
    m = connect(vehicle)
    t0 = time.monotonic()
    m.param_fetch_all()
    seen = {}
    count = None
    while time.monotonic() - t0 < 5.0:
        p = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=1.0)
        if p is None:
            break
        count = p.param_count
        seen[p.param_index] = p.param_id
        if len(seen) == count:
            break
    took = time.monotonic() - t0
    assert count and len(seen) == count, f"{len(seen)} of {count}"
    assert sorted(seen) == list(range(count))
    print(f"full parameter list: {count} parameters in {took * 1000:.1f} ms")
    # Each set's own answers (param_answers): accepted, the echo and the
    # rebroadcast; refused, PARAM_ERROR then the unchanged value; and the
    # value read back afterwards by a fresh request.
    # REAL32 set: echoed exactly, then rebroadcast
    a = param_answers(m, "MIS_TAKEOFF_ALT", 3.0)
    assert kinds(a) == ["PARAM_VALUE", "PARAM_VALUE"], a
    assert all(v.param_value == 3.0 for v in a), a
    # out of range: refused, the unchanged value comes back
    a = param_answers(m, "MIS_TAKEOFF_ALT", -1.0)
    assert kinds(a) == ["PARAM_ERROR", "PARAM_VALUE"], a
    assert a[0].error == mavlink.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE
    assert a[1].param_value == 3.0
    assert param_get(m, "MIS_TAKEOFF_ALT").param_value == 3.0
    # INT32, bytewise
    a = param_answers(m, "SYS_FAILURE_EN", 1, mavlink.MAV_PARAM_TYPE_INT32)
    assert kinds(a) == ["PARAM_VALUE", "PARAM_VALUE"], a
    assert all(v.param_type == mavlink.MAV_PARAM_TYPE_INT32 for v in a)
    assert all(float_as_int32(v.param_value) == 1 for v in a), a
    # REAL32 for an INT32 parameter: refused (MAV_PARAM_ERROR_TYPE_MISMATCH,
    # 7, newer than pymavlink 2.4.50's enum), unchanged
    a = param_answers(m, "SYS_FAILURE_EN", 0.0)
    assert kinds(a) == ["PARAM_ERROR", "PARAM_VALUE"], a
    assert a[0].error == 7
    assert float_as_int32(a[1].param_value) == 1
    assert float_as_int32(param_get(m, "SYS_FAILURE_EN").param_value) == 1
    # unknown name: PARAM_ERROR, no PARAM_VALUE
    a = param_answers(m, "NO_SUCH_PARAM", 1.0)
    assert kinds(a) == ["PARAM_ERROR"], a
    assert a[0].error == mavlink.MAV_PARAM_ERROR_DOES_NOT_EXIST
    assert param_get(m, "MIS_TAKEOFF_ALT").param_value == 3.0


# PX4 parameters that PX4's own integration tests (test/mavsdk_tests) set:
# name -> (MAVLink type, PX4 SITL's boot default, a value to set)
PX4_TEST_PARAMS = {
    "MPC_Z_V_AUTO_DN": (mavlink.MAV_PARAM_TYPE_REAL32, 1.5, 2.5),
    "RTL_TYPE": (mavlink.MAV_PARAM_TYPE_INT32, 0, 1),
    "RTL_APPR_FORCE": (mavlink.MAV_PARAM_TYPE_INT32, 0, 1),
    "EKF2_HGT_REF": (mavlink.MAV_PARAM_TYPE_INT32, 1, 0),
}


def wire_value(p):
    return float_as_int32(p.param_value) if p.param_type == mavlink.MAV_PARAM_TYPE_INT32 else p.param_value


def test_px4_parameters_px4s_integration_tests_set(vehicle):
    """A script written for PX4 sets the parameters PX4's own tests set: each
    exists with PX4's type and boot default, a set is echoed and reads back
    by name and by index, and PX4's range is enforced."""
    m = connect(vehicle)
    for name, (kind, default, value) in PX4_TEST_PARAMS.items():
        p = param_get(m, name)
        assert p is not None, f"{name}: no PARAM_VALUE (DOES_NOT_EXIST?)"
        assert p.param_type == kind, name
        assert wire_value(p) == default, f"{name} boots at {wire_value(p)}"
        a = param_answers(m, name, value, kind)
        assert kinds(a) == ["PARAM_VALUE", "PARAM_VALUE"], f"{name}: {a}"
        assert all(wire_value(v) == value for v in a), a
        assert wire_value(param_get(m, name)) == value, f"{name} read back by name"
        drain(m)
        m.mav.param_request_read_send(m.target_system, m.target_component, b"", p.param_index)
        by_index = wait(m, "PARAM_VALUE", lambda q: q.param_index == p.param_index, 3.0)
        assert by_index is not None and by_index.param_id == name, f"{name} by index {p.param_index}"
        assert wire_value(by_index) == value
    # PX4's range for MPC_Z_V_AUTO_DN is 0.5 .. 4 m/s
    a = param_answers(m, "MPC_Z_V_AUTO_DN", 9.0)
    assert kinds(a) == ["PARAM_ERROR", "PARAM_VALUE"], a
    assert a[0].error == mavlink.MAV_PARAM_ERROR_VALUE_OUT_OF_RANGE
    assert a[1].param_value == 2.5


def test_bounds_px4_declares_are_accepted(vehicle):
    """QGroundControl offers a parameter's range as PX4 declares it: a value
    at PX4's bound is stored here too (each of these was refused before,
    PARAM_ERROR, out of range)."""
    m = connect(vehicle)
    for name, value in [("RTL_DESCEND_ALT", 0.0), ("BAT_LOW_THR", 0.5), ("BAT_CRIT_THR", 0.5),
                        ("BAT_EMERGEN_THR", 0.5), ("GF_MAX_VER_DIST", 10000.0)]:
        a = param_answers(m, name, value)
        assert kinds(a) == ["PARAM_VALUE", "PARAM_VALUE"], f"{name}: {a}"
        assert all(v.param_value == value for v in a), f"{name}: {a}"


def test_available_modes_list_the_modes_the_vehicle_flies(vehicle):
    """QGroundControl builds its mode menu for PX4 from AVAILABLE_MODES (the
    standard modes protocol): MAV_CMD_REQUEST_MESSAGE with param2 0 gives
    every mode, k the k-th, one past the last is denied. Each mode carries
    PX4's custom mode, so the HEARTBEAT's mode is among them."""
    m = connect(vehicle)
    hb = m.wait_heartbeat(timeout=5)
    # MAVLink 2 only: the ids and enums of pymavlink's v20 dialect
    available_modes, standard_mode_mission = 435, 6
    assert command(m, mavlink.MAV_CMD_REQUEST_MESSAGE, available_modes, 0) == 0
    first = wait(m, "AVAILABLE_MODES", lambda _: True, 3.0)
    assert first is not None, "no AVAILABLE_MODES"
    modes = [first]
    while len(modes) < first.number_modes:
        nxt = wait(m, "AVAILABLE_MODES", lambda _: True, 3.0)
        assert nxt is not None, f"{len(modes)} of {first.number_modes} modes"
        modes.append(nxt)
    assert sorted(x.mode_index for x in modes) == list(range(1, first.number_modes + 1))
    by_mode = {x.custom_mode: x for x in modes}
    assert hb.custom_mode in by_mode, f"the current mode {hb.custom_mode} is listed"
    mission = by_mode[4 << 16 | 4 << 24]  # AUTO.MISSION
    assert mission.standard_mode == standard_mode_mission and mission.mode_name == ""
    assert by_mode[4 << 16 | 3 << 24].mode_name == "Hold"  # AUTO.LOITER, not a standard mode
    assert command(m, mavlink.MAV_CMD_REQUEST_MESSAGE, available_modes, 3) == 0
    third = wait(m, "AVAILABLE_MODES", lambda _: True, 3.0)
    assert third is not None and third.mode_index == 3 and third.custom_mode == modes[2].custom_mode
    past = command(m, mavlink.MAV_CMD_REQUEST_MESSAGE, available_modes, first.number_modes + 1)
    assert past == mavlink.MAV_RESULT_DENIED


def test_full_parameter_list_at_1x():
    """MAVROS and QGroundControl load the whole list at connect: all of it,
    in index order, quickly, at 1x."""
    with Vehicle(speed=1.0) as v:
        m = connect(v)
        drain(m)
        t0 = time.monotonic()
        m.mav.param_request_list_send(m.target_system, m.target_component)
        seen = []
        count = None
        while time.monotonic() - t0 < 10.0:
            p = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=1.0)
            if p is None:
                break
            count = p.param_count
            seen.append(p.param_index)
            if len(seen) == count:
                break
        took = time.monotonic() - t0
        assert count is not None and count > 1000, count
        assert seen == list(range(count)), "every parameter once, in index order"
        print(f"full parameter list at 1x: {count} parameters in {took * 1000:.0f} ms")
        assert took < 3.0, f"{took:.2f} s"


@pytest.mark.parametrize("speed", [1.0, FAST], ids=["x1", "x20"])
def test_mavros_connect_sequence(speed):
    """What MAVROS does on connect, as its plugins do it: `sys_status` asks
    for AUTOPILOT_VERSION (MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES), `param`
    loads the whole list, and `sys_time` sends TIMESYNC (tc1 = 0, ts1 its
    clock in ns) at 10 Hz, warning when a round trip takes over 10 ms.
    Every step answered; the round trips well under 10 ms (the median and
    nine in ten: one slow one on a loaded machine is a warning in MAVROS,
    not a failure); the figures printed."""
    with Vehicle(speed=speed) as v:
        m = connect(v)
        drain(m)
        t0 = time.monotonic()
        m.mav.command_long_send(m.target_system, m.target_component, 520, 0, 1, 0, 0, 0, 0, 0, 0)
        version = wait(m, "AUTOPILOT_VERSION", timeout=3.0)
        version_ms = (time.monotonic() - t0) * 1000
        assert version is not None, "no AUTOPILOT_VERSION"
        assert version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2, version
        drain(m)
        t0 = time.monotonic()
        m.mav.param_request_list_send(m.target_system, m.target_component)
        seen = set()
        count = None
        while time.monotonic() - t0 < 10.0 and (count is None or len(seen) < count):
            p = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=1.0)
            if p is None:
                break
            count = p.param_count
            seen.add(p.param_index)
        params_ms = (time.monotonic() - t0) * 1000
        assert count is not None and len(seen) == count > 1000, (count, len(seen))
        drain(m)
        rtts = []
        for _ in range(30):
            ts1 = time.monotonic_ns()
            m.mav.timesync_send(0, ts1)
            answer = wait(m, "TIMESYNC", lambda t, ts1=ts1: t.ts1 == ts1 and t.tc1 != 0, timeout=1.0)
            assert answer is not None, "TIMESYNC not answered"
            rtts.append((time.monotonic_ns() - ts1) / 1e6)
            time.sleep(0.1)  # MAVROS's timesync_rate, 10 Hz
        rtts.sort()
        median, p90, worst = rtts[len(rtts) // 2], rtts[int(len(rtts) * 0.9) - 1], rtts[-1]
        print(f"MAVROS connect at x{speed:g}: AUTOPILOT_VERSION in {version_ms:.1f} ms, {count} parameters in "
              f"{params_ms:.0f} ms, TIMESYNC round trip median {median:.2f} ms, 90 % {p90:.2f} ms, "
              f"worst {worst:.2f} ms (30)")
        assert median < 10.0 and p90 < 10.0, rtts


def test_current_mode_and_standard_modes(vehicle):
    """CURRENT_MODE streams at PX4's 0.5 Hz with the heartbeat's custom mode
    and its MAV_STANDARD_MODE; MAV_CMD_DO_SET_STANDARD_MODE switches to a
    standard mode a multicopter flies (SAFE_RECOVERY: Return) and FAILS one
    it does not (CRUISE, a fixed-wing mode), as PX4 answers."""
    m = connect(vehicle)
    drain(m)
    c = wait(m, "CURRENT_MODE", timeout=5.0)
    assert c is not None, "no CURRENT_MODE"
    hb = wait(m, "HEARTBEAT", timeout=3.0)
    assert (c.custom_mode, c.intended_custom_mode) == (hb.custom_mode, hb.custom_mode), (c, hb)
    assert c.standard_mode == mavlink.MAV_STANDARD_MODE_NON_STANDARD  # Hold has none
    assert param_set(m, "MIS_TAKEOFF_ALT", 3.0).param_value == pytest.approx(3.0)
    wait_armable(m)
    m.arducopter_arm()
    assert command(m, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, float("nan")) == 0
    assert wait(m, "HEARTBEAT", lambda h: mavutil.interpret_px4_mode(h.base_mode, h.custom_mode) == "LOITER", 20)
    assert command(m, mavlink.MAV_CMD_DO_SET_STANDARD_MODE, mavlink.MAV_STANDARD_MODE_CRUISE) == \
        mavlink.MAV_RESULT_FAILED
    assert command(m, mavlink.MAV_CMD_DO_SET_STANDARD_MODE, mavlink.MAV_STANDARD_MODE_SAFE_RECOVERY) == \
        mavlink.MAV_RESULT_ACCEPTED
    c = wait(m, "CURRENT_MODE", lambda c: c.standard_mode == mavlink.MAV_STANDARD_MODE_SAFE_RECOVERY, 5.0)
    assert c is not None, "CURRENT_MODE never said Return"
    hb = wait(m, "HEARTBEAT", timeout=3.0)
    assert mavutil.interpret_px4_mode(hb.base_mode, hb.custom_mode) == "RTL"
    assert c.custom_mode == hb.custom_mode


IDEAL = {"RP_NAV_SRC": 0}
FILTER = {"RP_NAV_SRC": 1}


@pytest.mark.parametrize("vehicle", [(SPEED, IDEAL), (FAST, IDEAL), (SPEED, FILTER)],
                         ids=["x5-ideal", "x20-ideal", "x5-filter"], indirect=True)
def test_flight_with_disturbance_estimation_offboard_and_landing(vehicle):
    """The seed report's experiment over MAVLink: a wrench and a lighter
    vehicle injected in a hover, estimated. On the ideal navigation solution
    (the setting kept for the report's experiments) within the report's
    tolerances; on the navigation filter (the daemon's default) within what
    its errors allow, measured: its attitude error (0.1 to 1.6 deg in this
    hover) tilts the thrust the estimator subtracts by m g sin(error), and
    its vertical accelerometer bias and GNSS height move the vertical force
    and so the mass (measured: horizontal force within 0.13 N,
    vertical within 0.59 N, mass within 3 %, torque as on the ideal
    solution)."""
    filtered = vehicle.params.get("RP_NAV_SRC") == 1
    m = connect(vehicle)
    # the injected truth: 0.5 N east and north, 0.2 N m yaw torque, a lighter vehicle
    nominal = param_get(m, "SIM_MASS").param_value
    true_mass = round(nominal * 0.9, 3)
    assert param_set(m, "MIS_TAKEOFF_ALT", 3.0).param_value == pytest.approx(3.0)

    wait_armable(m)
    m.arducopter_arm()
    assert wait(m, "HEARTBEAT", lambda h: h.base_mode & 128, 3.0) is not None, "armed"
    # pymavlink habit: p7 = 10 meaning "relative"; PX4 reads AMSL and raises it to home + MIS_TAKEOFF_ALT
    assert command(m, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == 0
    assert wait(m, "EXTENDED_SYS_STATE", lambda e: e.landed_state == 2, 15.0) is not None, "in air"
    assert wait(m, "HEARTBEAT", lambda h: mavutil.interpret_px4_mode(h.base_mode, h.custom_mode) == "LOITER", 15)
    assert abs(rel_alt(m) - 3.0) < 0.4

    for name, value in [("SIM_FEXT_X", 0.5), ("SIM_FEXT_Y", 0.5), ("SIM_TEXT_Z", 0.2), ("SIM_MASS", true_mass)]:
        p = param_set(m, name, value)
        assert p is not None and p.param_value == pytest.approx(value), name
    # let the estimator converge and the vehicle settle at its new hover: while it
    # still accelerates the estimate rightly carries (m_nom - m_true) a as well
    wait_sim(m, 15.0)
    f = latest(m, "EST_FORCE", "DEBUG_VECT")
    tq = latest(m, "EST_TORQUE", "DEBUG_VECT")
    mass = latest(m, "EST_MASS", "NAMED_VALUE_FLOAT")
    truth_f = latest(m, "SIM_FORCE", "DEBUG_VECT")
    truth_m = latest(m, "SIM_MASS", "NAMED_VALUE_FLOAT")
    print(f"EST_FORCE {f.x:.3f} {f.y:.3f} {f.z:.3f} N, EST_TORQUE {tq.x:.3f} {tq.y:.3f} {tq.z:.3f} N m, "
          f"EST_MASS {mass.value:.3f} kg (true {true_mass}, nominal {nominal})")
    assert (truth_f.x, truth_f.y) == pytest.approx((0.5, 0.5), abs=1e-3)
    assert truth_m.value == pytest.approx(true_mass, abs=1e-3)
    force_tol, vertical_tol, mass_rel = (0.25, 0.15, 0.01) if filtered else (0.01, 0.05, 0.005)
    assert f.x == pytest.approx(0.5, abs=force_tol) and f.y == pytest.approx(0.5, abs=force_tol)
    assert tq.z == pytest.approx(0.2, abs=0.004)
    # ideal: within 0.5 %, what is left is ground effect at 3 m (about 0.05 % of the thrust)
    assert mass.value == pytest.approx(true_mass, rel=mass_rel)
    # the lighter vehicle shows as an upward (negative NED z) force of (m_true - m_nom) g
    assert f.z == pytest.approx((true_mass - nominal) * 9.81, abs=vertical_tol)

    # switch the controller in flight: it keeps holding
    ctrl = float_as_int32(param_get(m, "CTRL_TYPE").param_value)
    other = (ctrl + 1) % 3
    p = param_set(m, "CTRL_TYPE", other, mavlink.MAV_PARAM_TYPE_INT32)
    assert float_as_int32(p.param_value) == other
    wait_sim(m, 4.0)
    assert abs(rel_alt(m) - 3.0) < 0.5

    # offboard: stream a position setpoint, then switch (pymavlink's set_mode)
    target = (2.0, 1.0, -4.0)

    def setpoint():
        m.mav.set_position_target_local_ned_send(
            0, m.target_system, m.target_component, mavlink.MAV_FRAME_LOCAL_NED, 2552,
            *target, 0, 0, 0, 0, 0, 0, 0, 0)

    for _ in range(5):
        setpoint()
        time.sleep(0.05)
    drain(m)
    m.set_mode("OFFBOARD")
    ack = wait(m, "COMMAND_ACK", lambda a: a.command == mavlink.MAV_CMD_DO_SET_MODE, 3.0)
    assert ack is not None and ack.result == 0
    deadline = time.monotonic() + 20.0
    reached = shown = False
    while time.monotonic() < deadline and not (reached and shown):
        setpoint()
        p = wait(m, ["LOCAL_POSITION_NED", "HEARTBEAT"], timeout=0.05)
        if p is None:
            continue
        if p.get_type() == "HEARTBEAT":
            shown = shown or m.flightmode == "OFFBOARD"
        elif math.dist((p.x, p.y, p.z), target) < 0.3:
            reached = True
    assert shown, "OFFBOARD in the heartbeat"
    assert reached, "offboard position reached"

    # land and disarm
    drain(m)
    m.set_mode("LAND")
    assert wait(m, "EXTENDED_SYS_STATE", lambda e: e.landed_state == 1, 30.0) is not None, "landed"
    assert wait(m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1 and not h.base_mode & 128, 15.0), "disarmed"


def test_the_vehicle_decides_and_names_its_airframe():
    """The octocopter says so in its HEARTBEAT; failure injection, mission start
    and reboot are answered by the autopilot (with a STATUSTEXT saying why),
    and a reboot keeps the vehicle's clock running."""
    with Vehicle(speed=SPEED, extra=["--airframe", "octo"]) as v:
        m = connect(v)
        hb = wait(m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1)
        assert hb.type == mavlink.MAV_TYPE_OCTOROTOR

        def refused(cmd, *params):
            """The ACK's result and the STATUSTEXT that came with it."""
            result = command(m, cmd, *params)
            text = wait(m, "STATUSTEXT", timeout=2.0)
            return result, text.text if text is not None else None

        result, text = refused(mavlink.MAV_CMD_INJECT_FAILURE, 0, 1, 1)
        assert result == mavlink.MAV_RESULT_DENIED and "SYS_FAILURE_EN" in text
        p = param_set(m, "SYS_FAILURE_EN", 1, mavlink.MAV_PARAM_TYPE_INT32)
        assert float_as_int32(p.param_value) == 1
        assert command(m, mavlink.MAV_CMD_INJECT_FAILURE, 0, 4, 1) == mavlink.MAV_RESULT_UNSUPPORTED
        result, text = refused(mavlink.MAV_CMD_MISSION_START, 0, 0)
        assert result == mavlink.MAV_RESULT_DENIED and "No valid mission" in text

        wait_armable(m)
        m.arducopter_arm()
        assert wait(m, "HEARTBEAT", lambda h: h.base_mode & 128, 3.0) is not None, "armed"
        result, text = refused(mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1)
        assert result == mavlink.MAV_RESULT_DENIED and "Reboot denied" in text
        m.arducopter_disarm()
        assert wait(m, "HEARTBEAT", lambda h: not h.base_mode & 128, 3.0) is not None, "disarmed"
        before = sim_time_s(m)
        assert command(m, mavlink.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1) == mavlink.MAV_RESULT_ACCEPTED
        assert wait(m, "STATUSTEXT", lambda t: "Rebooted" in t.text, 3.0) is not None
        assert sim_time_s(m) >= before, "time_boot_ms runs on through a reboot"
        assert wait(m, "HEARTBEAT", lambda h: h.type == mavlink.MAV_TYPE_OCTOROTOR, 3.0) is not None


def test_param_pck_opens_as_px4_serves_it(vehicle):
    """MAVProxy's and QGroundControl's first FTP request: OpenFileRO of
    @PARAM/param.pck is ACKed with the file's size (4 bytes, little endian)
    in a session, as PX4 answers it."""
    m = connect(vehicle)
    payload = bytearray(251)
    payload[3] = 4  # OpenFileRO
    name = b"@PARAM/param.pck"
    payload[4] = len(name)
    payload[12:12 + len(name)] = name
    m.mav.file_transfer_protocol_send(0, m.target_system, m.target_component, payload)
    r = wait(m, "FILE_TRANSFER_PROTOCOL", timeout=2.0)
    assert r is not None
    data = bytes(r.payload)
    assert data[3] == 128, f"ACK, not opcode {data[3]} (error {data[12]})"
    assert data[5] == 4 and data[4] == 4  # req_opcode OpenFileRO, size 4
    assert int.from_bytes(data[12:16], "little") > 0, "param.pck has a size"


def test_clean_shutdown_saves_parameters():
    v = Vehicle(speed=SPEED).start()
    try:
        m = connect(v)
        assert param_set(m, "MPC_XY_CRUISE", 6.5).param_value == pytest.approx(6.5)
        took = v.stop()
        assert took < 1.0, f"stopped in {took:.2f} s"
        assert v.returncode == 0
        text = (Path(v.state_dir) / "params.toml").read_text()
        assert "MPC_XY_CRUISE = 6.5" in text
    finally:
        v.stop()
        v.cleanup()
