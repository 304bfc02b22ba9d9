"""Issue 15 (hardening) with pymavlink against the real binary: nothing a
client is told is saved is lost without the client hearing of it, a damaged
parameter file is kept, and impossible targets are refused with their ACK.

- A parameter file that cannot be written (here a directory squats on the
  temporary file the atomic write goes through, `.params.toml.<pid>.tmp`:
  root ignores permissions) gives the setter its echo, then PARAM_ERROR and a
  critical STATUSTEXT naming the file; the saver retries, and once the way is
  clear the value is on disk and the success is announced.
- A params file with a bad line is renamed aside (`params.bad-<unix time>`),
  said at start (STATUSTEXT and the log), and its valid lines are in force.
- Takeoff and reposition to latitude 95 deg, or above RP_ALT_MAX_AMSL, are
  DENIED with a STATUSTEXT; MAV_SYS_ID cannot be changed (the instance sets it).

Run with the pymavlink venv:
`python -m pytest tests/clients/test_pymavlink_hardening.py`.
"""

import glob
import os
import shutil
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle, drain  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink


def listen(v):
    """The GCS end, bound before or after the vehicle starts."""
    return mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=255)


def connect(v):
    m = listen(v)
    assert m.wait_heartbeat(timeout=5) is not None, "no heartbeat"
    return m


def collect(m, types, window):
    """Every message of `types` within `window` seconds, in order."""
    out = []
    deadline = time.monotonic() + window
    while time.monotonic() < deadline:
        msg = m.recv_match(type=types, blocking=True, timeout=0.1)
        if msg is not None:
            out.append(msg)
    return out


def texts(msgs):
    return " | ".join(x.text for x in msgs if x.get_type() == "STATUSTEXT")


def test_an_unwritable_params_file_is_reported_to_the_setter_and_retried_until_saved():
    with Vehicle(speed=5.0) as v:
        path = os.path.join(v.state_dir, "params.toml")
        squat = os.path.join(v.state_dir, f".params.toml.{v.proc.pid}.tmp")
        m = connect(v)
        # after the start's save (which goes through that temporary file)
        for _ in range(50):
            try:
                os.makedirs(os.path.join(squat, "in-the-way"))
                break
            except OSError:
                time.sleep(0.05)
        assert os.path.isdir(squat)
        drain(m)
        m.param_set_send("MIS_TAKEOFF_ALT", 4.25, mavlink.MAV_PARAM_TYPE_REAL32)
        got = collect(m, ["PARAM_VALUE", "PARAM_ERROR", "STATUSTEXT"], 1.5)
        answers = [x for x in got if x.get_type() != "STATUSTEXT" and x.param_id == "MIS_TAKEOFF_ALT"]
        kinds = [x.get_type() for x in answers]
        # the echo (the value is in force, as PX4 keeps it in RAM), then the error
        assert kinds[:2] == ["PARAM_VALUE", "PARAM_ERROR"], kinds
        assert abs(answers[0].param_value - 4.25) < 1e-6
        assert answers[1].error == mavlink.MAV_PARAM_ERROR_PERMISSION_DENIED
        said = texts(got)
        assert "MIS_TAKEOFF_ALT not saved" in said and "params.toml" in said, said
        crit = [x for x in got if x.get_type() == "STATUSTEXT" and x.severity <= mavlink.MAV_SEVERITY_CRITICAL]
        assert crit, said
        assert "MIS_TAKEOFF_ALT = 4.25" not in open(path).read()
        # clear the way: the saver's retry (1 s, then 2 s, ...) writes it and says so
        shutil.rmtree(squat)
        got = collect(m, ["STATUSTEXT"], 6.0)
        assert "Parameters saved after" in texts(got), texts(got)
        assert "MIS_TAKEOFF_ALT = 4.25" in open(path).read()
        assert "cannot save; will retry" in v.logs()
        # with the way clear, the echo comes only once the value is on disk
        drain(m)
        m.param_set_send("MIS_TAKEOFF_ALT", 3.75, mavlink.MAV_PARAM_TYPE_REAL32)
        echo = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=2.0)
        on_disk = open(path).read()
        assert echo is not None and abs(echo.param_value - 3.75) < 1e-6
        assert "MIS_TAKEOFF_ALT = 3.75" in on_disk


def test_a_params_file_with_a_bad_line_is_kept_aside_and_said_at_start():
    v = Vehicle(speed=5.0, params={"MIS_TAKEOFF_ALT": "4.5", "NOT_A_PARAM": "1"})
    m = listen(v)  # bound before the start: the start's STATUSTEXT reaches it
    with v:
        got = collect(m, ["STATUSTEXT"], 2.0)
        aside = glob.glob(os.path.join(v.state_dir, "params.bad-*"))
        assert len(aside) == 1, os.listdir(v.state_dir)
        assert open(aside[0]).read() == "MIS_TAKEOFF_ALT = 4.5\nNOT_A_PARAM = 1\n"
        # the valid line is in force and in the new file
        assert "MIS_TAKEOFF_ALT = 4.5" in open(os.path.join(v.state_dir, "params.toml")).read()
        assert "Parameter file set aside" in texts(got), texts(got)
        assert os.path.basename(aside[0]) in v.logs()


def test_impossible_takeoff_and_reposition_are_denied_with_a_reason():
    with Vehicle(speed=5.0) as v:
        m = connect(v)

        def ask(send, cmd):
            drain(m)
            send()
            got = collect(m, ["COMMAND_ACK", "STATUSTEXT"], 1.0)
            acks = [x for x in got if x.get_type() == "COMMAND_ACK" and x.command == cmd]
            assert acks, f"no ACK for {cmd}"
            return acks[0].result, texts(got)

        sys_, comp = v.sysid, 1
        takeoff = mavlink.MAV_CMD_NAV_TAKEOFF
        r, said = ask(lambda: m.mav.command_long_send(sys_, comp, takeoff, 0, 0, 0, 0, 0, 95.0, 8.5, 500.0), takeoff)
        assert r == mavlink.MAV_RESULT_DENIED and "out of range" in said, (r, said)
        r, said = ask(lambda: m.mav.command_long_send(sys_, comp, takeoff, 0, 0, 0, 0, 0, 0, 0, 12000.0), takeoff)
        assert r == mavlink.MAV_RESULT_DENIED and "RP_ALT_MAX_AMSL" in said, (r, said)
        repo = mavlink.MAV_CMD_DO_REPOSITION
        r, said = ask(lambda: m.mav.command_int_send(sys_, comp, mavlink.MAV_FRAME_GLOBAL, repo, 0, 0, -1, 1, 0, 0,
                                                     950000000, 85000000, 500.0), repo)
        assert r == mavlink.MAV_RESULT_DENIED and "out of range" in said, (r, said)
        # the vehicle took none of it: still on the ground, disarmed
        hb = m.recv_match(type="HEARTBEAT", blocking=True, timeout=2)
        assert hb is not None and not hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED


def test_mav_sys_id_cannot_be_changed_the_instance_sets_it():
    with Vehicle(speed=5.0) as v:
        m = connect(v)
        drain(m)
        raw = int(42).to_bytes(4, "little")
        import struct
        m.param_set_send("MAV_SYS_ID", struct.unpack("<f", raw)[0], mavlink.MAV_PARAM_TYPE_INT32)
        got = collect(m, ["PARAM_VALUE", "PARAM_ERROR", "STATUSTEXT"], 1.0)
        answers = [x for x in got if x.get_type() != "STATUSTEXT" and x.param_id == "MAV_SYS_ID"]
        assert [x.get_type() for x in answers][:2] == ["PARAM_ERROR", "PARAM_VALUE"], answers
        value = struct.unpack("<i", struct.pack("<f", answers[1].param_value))[0]
        assert value == v.sysid
        assert "instance" in texts(got), texts(got)
        hb = m.recv_match(type="HEARTBEAT", blocking=True, timeout=2)
        assert hb.get_srcSystem() == v.sysid
