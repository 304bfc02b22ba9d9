"""MAVProxy against the rotorpilot binary, headless: mavproxy.py on the GCS
port (udpin, the vehicle speaks first), no GUI module loaded, no state or
logs written, driven through its command line on a pipe as a script would
drive it, with every wait bounded. Checks its own printed answers: the
vehicle and mode it detects, `wp load` / `wp list` / `wp clear`, `param
fetch` / `show` / `set`, `arm throttle` / `disarm`, and mode changes by
DO_SET_MODE through `long` (MAVProxy's own `mode NAME` cannot work with PX4
and pymavlink 2.4.50: it hands the mode tuple to `set_mode`, which raises
"required argument is not a float" before anything is sent), and the
commands docs/flying.md gives a MAVProxy user for takeoff, return and landing
(`takeoff`, `long NAV_RETURN_TO_LAUNCH`, `long NAV_LAND`, `long DO_SET_MODE
1 4 N`), beside the ones that do not work (`mode LAND`, `rtl`, `land`).

Run with the mavproxy venv: `python -m pytest tests/clients/test_mavproxy.py`.
"""

import os
import queue
import re
import subprocess
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import mission_link as ml  # noqa: E402
from harness import FILTER_HEIGHT_DRIFT_M, Vehicle  # noqa: E402

from pymavlink import mavwp  # noqa: E402

WPL = HERE / "missions" / "loop-jump.waypoints"


class MavProxy:
    """mavproxy.py as a subprocess; `send` types a command, `expect` waits for
    a line of its output matching a regular expression."""

    def __init__(self, master):
        script = Path(sys.executable).parent / "mavproxy.py"
        args = [sys.executable, str(script), f"--master={master}", "--no-state",
                "--default-modules=wp,param,mode,arm,cmdlong,misc"]
        env = dict(os.environ, PYTHONUNBUFFERED="1", MAVLINK20="1")
        self.proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                     text=True, bufsize=1, env=env)
        self.lines = queue.Queue()
        self.log = []
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            line = line.rstrip()
            self.log.append(line)
            self.lines.put(line)

    def send(self, command):
        self.proc.stdin.write(command + "\n")
        self.proc.stdin.flush()

    def expect(self, pattern, timeout=10.0):
        """The match of the first new output line matching `pattern`."""
        deadline = time.monotonic() + timeout
        rx = re.compile(pattern)
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                raise AssertionError(f"MAVProxy printed no line matching {pattern!r} within {timeout} s; "
                                     "its output:\n" + "\n".join(self.log[-60:]))
            try:
                line = self.lines.get(timeout=left)
            except queue.Empty:
                continue
            found = rx.search(line)
            if found:
                return found

    def collect(self, pattern, count, timeout=10.0):
        """The matches of the next `count` output lines matching `pattern`."""
        return [self.expect(pattern, timeout) for _ in range(count)]

    def stop(self):
        """Killed: it keeps no state (--no-state), and SIGTERM does not stop it."""
        if self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait(5)


@pytest.fixture
def session():
    with Vehicle(speed=5.0) as v:
        mp = MavProxy(f"udpin:127.0.0.1:{v.gcs_port}")
        try:
            mp.expect(rf"Detected vehicle {v.sysid}:1")
            # MAVProxy fetches the parameters on connecting; commands wait for that
            mp.expect(r"Received (\d+) parameters", timeout=20)
            yield v, mp
        finally:
            mp.stop()
            print("MAVProxy output:\n" + "\n".join(mp.log))


def test_waypoints_load_list_and_clear(session):
    v, mp = session
    # answered with MISSION_ITEM_INT to the vehicle's requests
    mp.send(f"wp load {WPL}")
    assert int(mp.expect(r"Loaded (\d+) waypoints").group(1)) == 6
    mp.expect(r"Got MISSION_ACK: TYPE_MISSION: ACCEPTED")
    truth = ml.Client(f"udpout:127.0.0.1:{v.api_bind}", sysid=254)
    loader = mavwp.MAVWPLoader()
    loader.load(str(WPL))
    sent = [ml.from_message(loader.wp(i)) for i in range(loader.count())]
    # MAVProxy turns the file's degrees into degE7 itself, truncating
    as_sent = [replace(it, x=int(it.x * 1e7) / 1e7, y=int(it.y * 1e7) / 1e7) if it.is_global() else it for it in sent]
    assert ml.plan_difference(as_sent, truth.download()) is None

    mp.send("wp list")
    assert int(mp.expect(r"Requesting (\d+) waypoints").group(1)) == 6
    # one line per item: command, frame, latitude, longitude, altitude, p1..p4, current, autocontinue
    rows = mp.collect(r"^(\d+) (\d+) ([-\d.]+) ([-\d.]+) ([-\d.]+) p1=", 6)
    listed = [(int(r.group(1)), int(r.group(2)), float(r.group(3)), float(r.group(4)), float(r.group(5)))
              for r in rows]
    for (cmd, frame, lat, lon, alt), it in zip(listed, sent):
        assert (cmd, frame) == (it.command, it.frame)
        if it.is_global():
            assert (lat, lon, alt) == pytest.approx((it.x, it.y, it.z), abs=1e-7)

    mp.send("wp clear")
    mp.expect(r"Got MISSION_ACK: TYPE_MISSION: ACCEPTED")
    assert truth.download() == []
    mp.send("wp list")
    assert int(mp.expect(r"Requesting (\d+) waypoints").group(1)) == 0


def test_params_modes_arming_and_a_mission_flown(session):
    v, mp = session
    assert any("Mode LOITER" in line for line in mp.log), "Hold, as pymavlink names PX4's AUTO.LOITER"
    count = int(re.search(r"Received (\d+) parameters", "\n".join(mp.log)).group(1))
    assert count >= 30
    mp.send(f"wp load {WPL}")
    mp.expect(r"Got MISSION_ACK: TYPE_MISSION: ACCEPTED")

    mp.send("param fetch")
    assert int(mp.expect(r"Received (\d+) parameters", timeout=20).group(1)) == count
    mp.send("param show MIS_TAKEOFF_ALT")
    assert float(mp.expect(r"MIS_TAKEOFF_ALT\s+([-\d.]+)").group(1)) == pytest.approx(2.5)
    mp.send("param set MIS_TAKEOFF_ALT 4.5")
    time.sleep(0.5)
    mp.send("param show MIS_TAKEOFF_ALT")
    assert float(mp.expect(r"MIS_TAKEOFF_ALT\s+([-\d.]+)").group(1)) == pytest.approx(4.5)
    truth = ml.Client(f"udpout:127.0.0.1:{v.api_bind}", sysid=254)
    truth.mav.param_request_read_send(*truth.target, b"MIS_TAKEOFF_ALT", -1)
    p = truth.recv("PARAM_VALUE", 3)
    assert p is not None and p.param_value == pytest.approx(4.5), "the vehicle has it"

    mp.send("arm throttle")
    mp.expect(r"COMPONENT_ARM_DISARM: ACCEPTED")
    mp.expect(r"\bARMED$")
    mp.send("disarm")
    mp.expect(r"COMPONENT_ARM_DISARM: ACCEPTED")
    mp.expect(r"\bDISARMED$")

    # AUTO.MISSION by DO_SET_MODE (base 1, main 4, sub 4): arm, and the mission takes off first
    mp.send("arm throttle")
    mp.expect(r"\bARMED$")
    mp.send("long DO_SET_MODE 1 4 4")
    mp.expect(r"DO_SET_MODE: ACCEPTED")
    mp.expect(r"Mode MISSION")
    # the mission lands at its end (item 5, NAV_LAND) and the vehicle disarms
    mp.expect(r"\bDISARMED$", timeout=60)
    truth.drain()
    cur = truth.recv("MISSION_CURRENT", 3)
    assert cur is not None and cur.mission_state == 5 and cur.seq == 5

    # on the ground again: Position is refused without manual control (PX4);
    # Mission, then Hold, by DO_SET_MODE; the prompt follows
    mp.send("long DO_SET_MODE 1 3 0")
    mp.expect(r"DO_SET_MODE: TEMPORARILY_REJECTED")
    mp.send("long DO_SET_MODE 1 4 4")
    mp.expect(r"DO_SET_MODE: ACCEPTED")
    mp.expect(r"Mode MISSION")
    mp.send("long DO_SET_MODE 1 4 3")
    mp.expect(r"DO_SET_MODE: ACCEPTED")
    mp.expect(r"Mode LOITER")


def test_the_readme_commands_take_off_return_and_land(session):
    """The MAVProxy commands of docs/flying.md, in flight: each is answered and the
    vehicle enters the mode; the MAVProxy commands it warns about fail as it
    says (a client bug, the same against PX4: nothing reaches the vehicle)."""
    v, mp = session
    mp.send("mode LAND")
    mp.expect(r"ERROR in command \['LAND'\]: required argument is not a float")
    mp.send("rtl")
    mp.expect(r"Unknown command 'rtl'")
    # `land` is DO_LAND_START (a mission's landing sequence), which a multicopter does not run
    mp.send("land")
    mp.expect(r"DO_LAND_START: UNSUPPORTED")

    # `takeoff ALT` sends p7 = ALT, which PX4 reads as AMSL: below home it is
    # raised to MIS_TAKEOFF_ALT, so that parameter sets the height
    mp.send("param set MIS_TAKEOFF_ALT 5")
    time.sleep(0.5)
    mp.send("arm throttle")
    mp.expect(r"\bARMED$")
    mp.send("takeoff 5")
    mp.expect(r"NAV_TAKEOFF: ACCEPTED")
    mp.expect(r"Takeoff to 5.0 m above home")
    mp.expect(r"Mode TAKEOFF")
    mp.expect(r"Mode LOITER", timeout=30)
    truth = ml.Client(f"udpout:127.0.0.1:{v.api_bind}", sysid=254)
    truth.drain()
    pos = truth.recv("LOCAL_POSITION_NED", 3)
    assert pos is not None and pos.z == pytest.approx(-5.0, abs=0.5), "5 m above home (NED z up is negative)"

    mp.send("long DO_SET_MODE 1 4 5")
    mp.expect(r"DO_SET_MODE: ACCEPTED")
    mp.expect(r"Mode RTL")
    mp.send("long DO_SET_MODE 1 4 6")
    mp.expect(r"DO_SET_MODE: ACCEPTED")
    mp.expect(r"Mode LAND")
    mp.send("long NAV_RETURN_TO_LAUNCH")
    mp.expect(r"NAV_RETURN_TO_LAUNCH: ACCEPTED")
    mp.expect(r"Mode RTL")
    mp.send("long NAV_LAND")
    mp.expect(r"NAV_LAND: ACCEPTED")
    mp.expect(r"Mode LAND")
    mp.expect(r"\bDISARMED$", timeout=60)
    truth.mav.heartbeat_send(6, 8, 0, 0, 0)  # still a peer (the link forgets a silent one after 30 s)
    truth.drain()
    pos = truth.recv("LOCAL_POSITION_NED", 3)
    # the navigation filter's height after a flight: within its drift of the start's
    assert pos is not None and abs(pos.z) < FILTER_HEIGHT_DRIFT_M, "landed where it was"
