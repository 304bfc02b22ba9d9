"""Exact replay of a MAVSDK 3 flight: a flight at --speed 10 with
--log-dir and --log-csv (parameter changes, takeoff, offboard velocity and
position setpoints, a mission upload and start, a failure injection, land),
stopped with SIGTERM; then `rotorpilot replay flight.record --csv` twice.
Both replays must be byte-identical to each other and to the live flight's
own flight.csv, whatever the machine's load was during the live flight.

Run with the mavsdk<4 venv: `python -m pytest tests/clients/test_mavsdk3_replay.py`.
"""

import asyncio
import glob
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "mavsdk_examples"))
from harness import Vehicle, binary  # noqa: E402
from test_mavsdk3_failure import collect, fly  # noqa: E402
from test_mavsdk3_mission import at, item, until  # noqa: E402

import common  # noqa: E402
from mavsdk.failure import FailureType, FailureUnit  # noqa: E402
from mavsdk.mission import MissionPlan  # noqa: E402
from mavsdk.offboard import PositionNedYaw, VelocityNedYaw  # noqa: E402


def test_a_mavsdk_flight_replays_byte_for_byte():
    logs = tempfile.mkdtemp(prefix="rotorpilot-replay-")
    with Vehicle(speed=10.0, extra=["--log-dir", logs, "--log-csv"]) as v:
        seen = {}

        async def scenario(uav):
            texts = []
            tasks = [collect(uav.telemetry.status_text(), texts, lambda t: t.text)]
            try:
                await uav.param.set_param_int("SYS_FAILURE_EN", 1)
                await uav.param.set_param_float("MPC_XY_CRUISE", 4.0)
                await uav.param.set_param_float("MIS_TAKEOFF_ALT", 6.0)
                home = await common.sample(uav.telemetry.home(), "home", 10)
                await uav.action.arm()
                await uav.action.takeoff()
                await common.next_matching(uav.telemetry.position(), lambda p: p.relative_altitude_m > 5.0, 30,
                                           "takeoff to 6 m")
                # offboard: a few velocity setpoints, then a position, over several seconds
                await uav.offboard.set_velocity_ned(VelocityNedYaw(0.0, 0.0, 0.0, 0.0))
                await uav.offboard.start()
                for k in range(10):
                    await uav.offboard.set_velocity_ned(VelocityNedYaw(2.0, 0.5 * (k % 3), 0.0, 10.0 * k))
                    await asyncio.sleep(0.05)
                await uav.offboard.set_position_ned(PositionNedYaw(5.0, 5.0, -8.0, 45.0))
                for _ in range(10):
                    await uav.offboard.set_position_ned(PositionNedYaw(5.0, 5.0, -8.0, 45.0))
                    await asyncio.sleep(0.05)
                await uav.offboard.stop()
                # a mission
                items = [item(*at(home, n, e), 8.0, 4.0) for n, e in [(15.0, 0.0), (15.0, 10.0)]]
                await uav.mission.set_return_to_launch_after_mission(False)
                await uav.mission.upload_mission(MissionPlan(items))
                await uav.mission.start_mission()
                await common.next_matching(uav.mission.mission_progress(), lambda p: p.current == p.total, 60,
                                           "mission finished")
                # a failure: one battery cell off, then back
                await uav.failure.inject(FailureUnit.SYSTEM_BATTERY, FailureType.OFF, 0)
                await until(lambda: any("battery cell off" in t for t in texts), 10, "the injection's text")
                await uav.param.set_param_float("MPC_LAND_SPEED", 1.2)
                await uav.action.land()
                await common.next_matching(uav.telemetry.armed(), lambda a: not a, 60, "landed and disarmed")
                seen["texts"] = list(texts)
            finally:
                for t in tasks:
                    t.cancel()

        fly(v, scenario, 180)
    assert v.returncode == 0, v.returncode
    runs = glob.glob(os.path.join(logs, "*"))
    assert len(runs) == 1, runs
    record, live = os.path.join(runs[0], "flight.record"), os.path.join(runs[0], "flight.csv")
    with open(record) as f:
        lines = [json.loads(line) for line in f]
    kinds = {k for line in lines for k in line if k not in ("step", "outcome")}
    # everything the flight did reached the record
    for kind in ("header", "command", "set_param", "change_plans", "gcs_heartbeat", "end"):
        assert kind in kinds, (kind, kinds)
    commands = json.dumps([line["command"] for line in lines if "command" in line])
    for what in ("Arm", "Takeoff", "Offboard", "\"Mission\"", "InjectFailure", "Land"):
        assert what in commands, what
    replays = []
    for k in (1, 2):
        out = os.path.join(runs[0], f"r{k}.csv")
        r = subprocess.run([binary(), "replay", record, "--csv", out, "--json"], capture_output=True, text=True,
                           timeout=120)
        assert r.returncode == 0, r.stderr
        summary = json.loads(r.stdout)
        assert summary["complete"] and not summary["armed"], summary
        replays.append(out)
        print(f"replay {k}: {summary['steps']} steps in {summary['wall_time_s']:.3f} s "
              f"({summary['steps_per_s']:.0f} steps/s)")
    live_bytes = Path(live).read_bytes()
    assert live_bytes.count(b"\n") > 10_000, "the live CSV is too short to prove anything"
    assert Path(replays[0]).read_bytes() == Path(replays[1]).read_bytes(), "two replays differ"
    assert Path(replays[0]).read_bytes() == live_bytes, "the replay differs from the live flight's CSV"
    subprocess.run(["rm", "-rf", logs])
