"""MAVSDK-Python 3.x (the gRPC API; its bundled mavsdk_server is a real
MAVSDK 3 core) against the rotorpilot binary. Each script in mavsdk_examples/
is a small flight or parameter session written against that public API and
exits non-zero when the vehicle misbehaves. The vehicle runs as PX4 SITL
instance N (API link 14580+N sending to 127.0.0.1:14540+N) and the scripts
connect with udpin://0.0.0.0:14540+N.

Run with the mavsdk<4 venv (which also holds pymavlink, for the two-client
test): `python -m pytest tests/clients/test_mavsdk3.py`.
"""

import contextlib
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from harness import Vehicle, free_tcp_port  # noqa: E402

SPEED = 5.0
# a script written for real time also runs unchanged with the vehicle at 20x
FAST = 20.0
REAL_TIME = 1.0
SCRIPTS = HERE / "mavsdk_examples"


def script_env(vehicle):
    """The environment a script of mavsdk_examples/ reads (common.py)."""
    env = dict(os.environ)
    env.update(
        ROTORPILOT_MAVSDK_URL=f"udpin://0.0.0.0:{vehicle.api_port}",
        MAVSDK_SERVER_PORT=str(free_tcp_port()),
        ROTORPILOT_SPEED=str(vehicle.speed),
        PYTHONWARNINGS="ignore::FutureWarning",
    )
    return env


@contextlib.contextmanager
def running_script(name, vehicle):
    """A script of mavsdk_examples/ running beside the test (its output on
    `.stdout`), killed on the way out if it has not ended."""
    script = subprocess.Popen(
        [sys.executable, str(SCRIPTS / name)],
        cwd=SCRIPTS,
        env=script_env(vehicle),
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        yield script
    finally:
        if script.poll() is None:
            script.kill()
            script.wait(5)


def run_script(name, vehicle, timeout=150):
    t0 = time.monotonic()
    try:
        p = subprocess.run(
            [sys.executable, str(SCRIPTS / name)],
            cwd=SCRIPTS,
            env=script_env(vehicle),
            capture_output=True,
            text=True,
            timeout=timeout,
        )
    except subprocess.TimeoutExpired as e:
        pytest.fail(f"{name} timed out after {timeout} s\n{e.stdout}\n{e.stderr}\n{vehicle.logs()}")
    took = time.monotonic() - t0
    print(f"{name}: exit {p.returncode} in {took:.1f} s\n{p.stdout[-3000:]}")
    if p.returncode != 0:
        pytest.fail(f"{name} failed ({p.returncode})\n{p.stdout}\n{p.stderr[-3000:]}\n{vehicle.logs()}")
    return p.stdout


FLIGHTS = ["takeoff_and_land.py", "goto.py", "offboard_position_ned.py", "offboard_velocity_ned.py"]


@pytest.mark.parametrize(
    "speed,script",
    [(SPEED, s) for s in FLIGHTS + ["all_params.py", "ground_truth.py", "orbit.py", "highres_imu.py", "follow_me.py", "arming_checks.py"]]
    + [(FAST, s) for s in FLIGHTS]
    # a timed path streamed at 10 Hz, as the example streams it: in real time
    # (sped up, the client's own latency stales every setpoint)
    + [(REAL_TIME, "offboard_from_csv.py")],
    ids=lambda x: f"x{x:g}" if isinstance(x, float) else x,
)
def test_script(speed, script):
    """The same script, unchanged, at 5x and at 20x (ROTORPILOT_SPEED only sizes
    its wall-clock limits; its pauses are on the vehicle's clock)."""
    with Vehicle(speed=speed) as v:
        run_script(script, v)


def test_gcs_and_mavsdk_at_once_and_a_reconnecting_gcs():
    """A pymavlink GCS on the GCS link while a MAVSDK script flies on the API
    link: both are served. Then the GCS restarts on a new port (udpout from an
    ephemeral port, as pymavlink udpout does) and is served again."""
    from pymavlink import mavutil

    with Vehicle(speed=SPEED) as v:
        gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=255)
        assert gcs.wait_heartbeat(timeout=5) is not None
        with running_script("takeoff_and_land.py", v) as script:
            # while MAVSDK flies, the GCS sees the flight
            in_air = gcs.recv_match(
                type="EXTENDED_SYS_STATE", condition="EXTENDED_SYS_STATE.landed_state==2", blocking=True, timeout=40
            )
            assert in_air is not None, "the GCS sees the MAVSDK flight"
            # the GCS also gets answers of its own
            gcs.mav.param_request_read_send(gcs.target_system, 0, b"MIS_TAKEOFF_ALT", -1)
            assert gcs.recv_match(type="PARAM_VALUE", blocking=True, timeout=3) is not None
            gcs.close()
            # the GCS comes back from a new ephemeral port, talking first
            again = mavutil.mavlink_connection(f"udpout:127.0.0.1:{v.gcs_bind}", source_system=255)
            again.mav.heartbeat_send(6, 8, 0, 0, 0)
            # MAVSDK's own heartbeats reach this link too (forwarded, as PX4's
            # -f does); pymavlink locks onto the first vehicle heartbeat
            deadline = time.monotonic() + 5
            while again.target_system == 0 and time.monotonic() < deadline:
                again.wait_heartbeat(timeout=1)
            assert again.target_system == v.sysid
            again.mav.param_request_read_send(again.target_system, 0, b"MIS_TAKEOFF_ALT", -1)
            assert again.recv_match(type="PARAM_VALUE", blocking=True, timeout=3) is not None
            out, _ = script.communicate(timeout=120)
            print(out[-2000:])
            assert script.returncode == 0, out


def test_a_status_text_mavsdk_sends_reaches_the_gcs():
    """ServerUtility.send_status_text on the API link, as MAVSDK-Python's
    send_status_message.py example sends it (as system 1): a pymavlink GCS on
    the GCS link reads the text, sent by MAVSDK's system and component. The
    GCS sends its heartbeat each second: PX4 forwards a message without a
    target only onto a link on which it has heard someone."""
    from pymavlink import mavutil

    with Vehicle(speed=SPEED) as v:
        gcs = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=255)
        assert gcs.wait_heartbeat(timeout=5) is not None
        with running_script("status_text.py", v) as script:
            texts = []
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and not any(t == "Hello world!" for t, _ in texts):
                gcs.mav.heartbeat_send(6, 8, 0, 0, 0)
                m = gcs.recv_match(type="STATUSTEXT", blocking=True, timeout=1)
                if m is not None:
                    texts.append((m.text, (m.get_srcSystem(), m.get_srcComponent())))
            out, _ = script.communicate(timeout=60)
            print(out[-2000:])
            assert script.returncode == 0, out
            sent = [src for t, src in texts if t == "Hello world!"]
            assert sent, f"the GCS got no 'Hello world!', only {texts}"
            # MAVSDK's system (1, as the example sets it) and its component,
            # not the autopilot's: forwarded as sent, not announced anew
            assert sent[0][0] == 1 and sent[0][1] != 1, sent
