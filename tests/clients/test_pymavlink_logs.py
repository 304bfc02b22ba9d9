"""The logs of a run (`--log-dir`) read back by the tools PX4 users read them
with: each link's `.tlog` by pymavlink's `mavutil.mavlink_connection(file)`
(what MAVProxy and MAVExplorer use), `flight.ulg` by pyulog (and its
`ulog_info` / `ulog_messages` commands).

A vehicle at 10x with a log directory; pymavlink arms, takes off, hovers,
lands on the GCS link and asks for AUTOPILOT_VERSION on the API link; then
SIGTERM, and every file is read back and checked against what the client
did and saw. Run with the pymavlink venv (pymavlink, pytest, pyulog).
"""

import collections
import struct
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import FILTER_HEIGHT_DRIFT_M, Vehicle  # noqa: E402
from harness import wait_message as wait  # noqa: E402

from pymavlink import mavutil  # noqa: E402
from pyulog import ULog  # noqa: E402

mavlink = mavutil.mavlink
SPEED = 10.0
TAKEOFF_ALT = 3.0
# EST_ORDER set in flight (the default is 3)
NEW_ORDER = 5
# topic -> rate [Hz] (PX4's default logger intervals; docs/logs.md)
RATES = {
    "vehicle_attitude": 20,
    "vehicle_angular_velocity": 50,
    "vehicle_local_position": 10,
    "vehicle_global_position": 5,
    "vehicle_attitude_setpoint": 20,
    "actuator_motors": 10,
    "battery_status": 5,
    "rotorpilot_wrench_estimate": 50,
    "rotorpilot_control_wrench": 50,
    "rotorpilot_sim_truth": 50,
}
# logged once a second and on every change
ON_CHANGE = ["vehicle_status", "vehicle_land_detected"]




def read_tlog(path):
    m = mavutil.mavlink_connection(str(path))
    msgs = []
    while True:
        msg = m.recv_match()
        if msg is None:
            break
        msgs.append(msg)
    m.close()
    return msgs


@pytest.fixture(scope="module")
def flight():
    """Fly once; hand the tests the run directory and what the client did."""
    logs = tempfile.mkdtemp(prefix="rotorpilot-logs-")
    v = Vehicle(speed=SPEED, extra=["--log-dir", logs], params={"MIS_TAKEOFF_ALT": TAKEOFF_ALT})
    v.start()
    try:
        run_dir = Path(next(line.split("logs:", 1)[1].strip() for line in v.banner if "logs:" in line))
        sent = collections.Counter()
        seen = []
        def command(m, cmd, *p, timeout=3.0):
            p = list(p) + [0.0] * (7 - len(p))
            m.mav.command_long_send(m.target_system, m.target_component, cmd, 0, *p)
            sent[(m.source_system, cmd)] += 1
            ack = wait(m, "COMMAND_ACK", lambda a: a.command == cmd, timeout, seen if m.source_system == 255 else None)
            assert ack is not None, f"no COMMAND_ACK for {cmd}"
            return ack.result

        # the API link first, on its own: one COMMAND_LONG (REQUEST_MESSAGE
        # AUTOPILOT_VERSION). (pymavlink: a second connection opened in the
        # process while the first is in use stops the first one's replies.)
        api = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.api_port}", source_system=254)
        assert api.wait_heartbeat(timeout=5) is not None
        assert command(api, mavlink.MAV_CMD_REQUEST_MESSAGE, 148) == 0
        api.close()

        gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=255)
        assert gcs.wait_heartbeat(timeout=5) is not None
        # the parameter count (asked again if a datagram went missing)
        for _ in range(3):
            gcs.mav.param_request_read_send(gcs.target_system, 1, b"", 0)
            count = wait(gcs, "PARAM_VALUE", timeout=2, seen=seen)
            if count is not None:
                break
        assert count is not None, "no PARAM_VALUE"
        assert wait(gcs, "SYS_STATUS", lambda s: s.onboard_control_sensors_health & 0x10000000, 10, seen)
        wall_start = time.time()
        assert command(gcs, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
        assert command(gcs, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == 0
        assert wait(gcs, "EXTENDED_SYS_STATE", lambda e: e.landed_state == 2, 15, seen), "in air"
        assert wait(gcs, "GLOBAL_POSITION_INT", lambda g: g.relative_alt > (TAKEOFF_ALT - 0.2) * 1000, 15, seen)
        # a parameter changed in flight: the estimator's order (INT32, bytewise in the float)
        as_float = struct.unpack("<f", struct.pack("<i", NEW_ORDER))[0]
        gcs.param_set_send("EST_ORDER", as_float, mavlink.MAV_PARAM_TYPE_INT32)
        assert wait(gcs, "PARAM_VALUE", lambda p: p.param_id == "EST_ORDER", 3, seen), "EST_ORDER set"
        # hover a little (simulated seconds from the vehicle's clock)
        a0 = wait(gcs, "ATTITUDE", timeout=2)
        assert wait(gcs, "ATTITUDE", lambda a: a.time_boot_ms - a0.time_boot_ms > 5000, 10, seen)
        assert command(gcs, mavlink.MAV_CMD_NAV_LAND) == 0
        assert wait(gcs, "EXTENDED_SYS_STATE", lambda e: e.landed_state == 1, 30, seen), "landed"
        assert wait(gcs, "HEARTBEAT", lambda h: h.get_srcComponent() == 1 and not h.base_mode & 128, 15, seen)
        # read what is still queued (the last texts)
        wait(gcs, "NONE", timeout=0.5, seen=seen)
        wall_end = time.time()
    except BaseException:
        print("rotorpilot log (tail):\n" + v.logs())
        raise
    finally:
        v.stop()
    assert v.returncode == 0, v.logs()
    yield {
        "dir": run_dir,
        "sent": sent,
        "seen": seen,
        "sysid": v.sysid,
        "param_count": count.param_count,
        "wall": (wall_start, wall_end),
    }
    v.cleanup()


def test_the_run_directory_holds_a_tlog_per_link_and_the_ulog(flight):
    names = sorted(p.name for p in flight["dir"].iterdir())
    assert names == ["api.tlog", "flight.record", "flight.ulg", "gcs.tlog"]


@pytest.mark.parametrize("link,client", [("gcs", 255), ("api", 254)])
def test_tlogs_read_back_with_pymavlink(flight, link, client):
    msgs = read_tlog(flight["dir"] / f"{link}.tlog")
    assert not [m for m in msgs if m.get_type() == "BAD_DATA"]
    stamps = [m._timestamp for m in msgs]
    assert all(b >= a for a, b in zip(stamps, stamps[1:])), "timestamps increase"
    t0, t1 = flight["wall"]
    assert stamps[0] <= t0 and stamps[-1] >= t1 - 1.0, "Unix time, covering the flight"

    # sent: the vehicle's heartbeats at 1 Hz of wall time, all through the log
    ours = [m for m in msgs if m.get_srcSystem() == flight["sysid"]]
    hb = [m._timestamp for m in ours if m.get_type() == "HEARTBEAT"]
    span = stamps[-1] - stamps[0]
    assert abs(len(hb) - span) <= 2, (len(hb), span)
    assert all(0.5 < b - a < 1.5 for a, b in zip(hb, hb[1:])), "one heartbeat a second"
    # received: exactly the client's COMMAND_LONGs, and each one's ACK sent
    theirs = [m for m in msgs if m.get_srcSystem() == client]
    got = collections.Counter((client, m.command) for m in theirs if m.get_type() == "COMMAND_LONG")
    want = collections.Counter({k: n for k, n in flight["sent"].items() if k[0] == client})
    assert got == want and sum(want.values()) > 0
    acks = collections.Counter(m.command for m in ours if m.get_type() == "COMMAND_ACK")
    for (_, cmd), n in want.items():
        assert acks[cmd] >= n, cmd
    types = {m.get_type() for m in ours}
    assert {"ATTITUDE", "GLOBAL_POSITION_INT", "SYS_STATUS"} <= types
    if link == "gcs":
        # the status texts the client saw went through this link
        texts = {m.text for m in ours if m.get_type() == "STATUSTEXT"}
        assert {t for _, t in flight["seen"]} <= texts


@pytest.fixture(scope="module")
def ulog(flight):
    return ULog(str(flight["dir"] / "flight.ulg"))


def topic(ulog, name):
    d = [x for x in ulog.data_list if x.name == name]
    assert len(d) == 1, name
    return d[0].data


def test_ulog_has_the_px4_topics_at_their_rates(ulog):
    start = ulog.start_timestamp
    end = max(topic(ulog, n)["timestamp"][-1] for n in RATES)
    duration = (end - start) / 1e6
    assert duration > 10, duration
    for name, hz in RATES.items():
        t = topic(ulog, name)["timestamp"]
        assert np.all(np.diff(t.astype(np.int64)) > 0), f"{name}: timestamps increase"
        # one sample per interval of simulated time, from start to end
        assert abs(len(t) - duration * hz) <= 2, (name, len(t), duration * hz)
        assert np.allclose(np.diff(t.astype(np.int64)), 1e6 / hz), name
    for name in ON_CHANGE:
        t = topic(ulog, name)["timestamp"]
        assert len(t) >= duration - 1, name
    # a trajectory setpoint only while a reference is tracked
    traj = topic(ulog, "trajectory_setpoint")["timestamp"]
    assert 0 < len(traj) <= duration * 5 + 1


def test_ulog_values_follow_the_flight(ulog):
    lp = topic(ulog, "vehicle_local_position")
    top = lp["z"][0] - lp["z"].min()
    assert abs(top - TAKEOFF_ALT) < 0.4, top
    assert abs(lp["z"][-1] - lp["z"][0]) < FILTER_HEIGHT_DRIFT_M, "landed at the end"
    assert lp["xy_valid"].all() and lp["z_valid"].all()
    assert lp["ref_lat"][0] == pytest.approx(47.397742, abs=1e-5)
    gp = topic(ulog, "vehicle_global_position")
    assert gp["alt"].max() - gp["alt"][0] == pytest.approx(top, abs=0.3)

    att = topic(ulog, "vehicle_attitude")
    norms = np.sqrt(sum(att[f"q[{i}]"] ** 2 for i in range(4)))
    assert np.allclose(norms, 1.0, atol=1e-5)

    st = topic(ulog, "vehicle_status")
    arming = list(st["arming_state"])
    assert arming[0] == 1 and 2 in arming and arming[-1] == 1, "disarmed, armed, disarmed"
    navs = set(st["nav_state"])
    assert {17, 18} <= navs, navs  # AUTO_TAKEOFF, AUTO_LAND
    ld = topic(ulog, "vehicle_land_detected")
    assert ld["landed"][0] == 1 and 0 in set(ld["landed"]) and ld["landed"][-1] == 1

    mot = topic(ulog, "actuator_motors")
    rotors = np.stack([mot[f"control[{i}]"] for i in range(4)])
    assert np.all((rotors >= 0) & (rotors <= 1))
    assert rotors.max() > 0.2, "spinning in flight"
    assert np.isnan(mot["control[4]"]).all(), "unused motors are NaN, as PX4"
    # hover: the four rotors share the weight, so each is near the hover thrust
    armed_flying = rotors[:, rotors.min(axis=0) > 0.05]
    assert armed_flying.size > 0

    truth = topic(ulog, "rotorpilot_sim_truth")
    est = topic(ulog, "rotorpilot_wrench_estimate")
    tz = truth["position_ned[2]"]
    assert tz[0] - tz.min() == pytest.approx(top, abs=FILTER_HEIGHT_DRIFT_M)
    assert truth["mass_kg"][0] > 0
    # no disturbance injected: the estimated mass is the true one in hover
    flying = np.nonzero(tz[0] - tz > TAKEOFF_ALT - 0.3)[0]
    assert est["mass_kg"][flying[len(flying) // 2]] == pytest.approx(truth["mass_kg"][0], rel=0.02)
    bat = topic(ulog, "battery_status")
    assert bat["remaining"][-1] < bat["remaining"][0] <= 1.0
    assert bat["discharged_mah"][-1] > 0


def test_ulog_parameters_info_and_status_texts(ulog, flight):
    assert ulog.msg_info_dict["sys_name"] == "rotorpilot"
    assert "ver_sw" in ulog.msg_info_dict
    p = ulog.initial_parameters
    assert p["MIS_TAKEOFF_ALT"] == pytest.approx(TAKEOFF_ALT)
    assert p["MAV_SYS_ID"] == flight["sysid"]
    assert isinstance(p["MAV_SYS_ID"], int) and isinstance(p["MIS_TAKEOFF_ALT"], float)
    assert len(p) == flight["param_count"], "every parameter"
    # the change in flight, as PX4 logs one, and the order the estimate reports
    assert p["EST_ORDER"] == 3
    assert [(n, v) for _, n, v in ulog.changed_parameters] == [("EST_ORDER", NEW_ORDER)]
    changed_at = ulog.changed_parameters[0][0]
    est = topic(ulog, "rotorpilot_wrench_estimate")
    assert est["order"][0] == 3 and est["order"][-1] == NEW_ORDER
    first_new = est["timestamp"][np.argmax(est["order"] == NEW_ORDER)]
    assert abs(int(first_new) - int(changed_at)) <= 120_000, "within 0.1 s of simulated time"
    logged = [(m.log_level, m.message) for m in ulog.logged_messages]
    # every STATUSTEXT the client saw, with its severity (syslog numbers in both)
    assert flight["seen"], "the flight announced something"
    for severity, text in flight["seen"]:
        assert (ord("0") + severity, text) in logged, text
    stamps = [m.timestamp for m in ulog.logged_messages]
    assert stamps == sorted(stamps)


@pytest.mark.parametrize("tool", ["ulog_info", "ulog_messages", "ulog_params"])
def test_pyulog_commands_read_the_ulog(flight, tool):
    exe = Path(sys.executable).parent / tool
    out = subprocess.run([str(exe), str(flight["dir"] / "flight.ulg")], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    if tool == "ulog_info":
        assert "vehicle_local_position" in out.stdout and "sys_name: rotorpilot" in out.stdout
    elif tool == "ulog_messages":
        assert flight["seen"][0][1] in out.stdout
    else:
        assert "MIS_TAKEOFF_ALT" in out.stdout



# the raw sensor topics: rate [Hz] (docs/logs.md)
RAW_RATES = {"sensor_combined": 50, "vehicle_air_data": 5, "vehicle_magnetometer": 5, "sensor_gps": 8}


def test_ulog_has_the_raw_sensor_topics_with_px4_fields(ulog):
    start = ulog.start_timestamp
    end = topic(ulog, "vehicle_attitude")["timestamp"][-1]
    duration = (end - start) / 1e6
    for name, hz in RAW_RATES.items():
        t = topic(ulog, name)["timestamp"].astype(np.int64)
        assert np.all(np.diff(t) > 0), f"{name}: timestamps increase"
        assert abs(len(t) - duration * hz) <= 3, (name, len(t), duration * hz)
    sc = topic(ulog, "sensor_combined")
    # at rest on the ground before takeoff: -g on z (FRD), no rotation
    assert sc["accelerometer_m_s2[2]"][0] == pytest.approx(-9.81, abs=0.5)
    assert abs(sc["gyro_rad[0]"][0]) < 0.05
    air = topic(ulog, "vehicle_air_data")
    # ISA at PX4's home, 488 m AMSL: about 95.6 kPa; the barometric altitude follows the climb
    assert air["baro_pressure_pa"][0] == pytest.approx(95_595, abs=60)
    assert air["baro_alt_meter"].max() - air["baro_alt_meter"][0] == pytest.approx(TAKEOFF_ALT, abs=0.5)
    mag = topic(ulog, "vehicle_magnetometer")
    norm = np.sqrt(sum(mag[f"magnetometer_ga[{i}]"] ** 2 for i in range(3)))
    assert np.median(norm) == pytest.approx(0.486, abs=0.02)
    gps = topic(ulog, "sensor_gps")
    assert gps["latitude_deg"][0] == pytest.approx(47.397742, abs=1e-5)
    assert set(gps["fix_type"]) == {3} and gps["eph"][0] == pytest.approx(0.9)
    # each fix is delivered one 125 ms epoch after it was taken
    assert np.all(gps["timestamp"].astype(np.int64) - gps["timestamp_sample"].astype(np.int64) == 125_000)
