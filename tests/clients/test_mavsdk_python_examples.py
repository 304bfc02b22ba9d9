"""MAVSDK-Python's own example scripts, unmodified, against rotorpilot run as
PX4 SITL instance 0, as a PX4 SITL user runs them: `python example.py` in
the examples directory, the script connecting to udpin://0.0.0.0:14540 (or
udp://:14540) and its mavsdk_server on TCP 50051, both hard-coded.

The scripts are vendored, unmodified, with their licence, in
mavsdk_python_examples/examples/ (the tag mavsdk_python_examples/README.md
names); $MAVSDK_PYTHON_EXAMPLES may name another copy (the `examples/` of a
MAVSDK-Python checkout at that tag). Each script is checked byte for byte
against mavsdk_python_examples/SHA256SUMS and run from a scratch copy of
that directory (some write files beside themselves).

Each test has a network namespace of its own (`unshare --net --pid`, its
loopback up), so the fixed ports collide with nothing, and a PID namespace,
so that ending it ends every process the test started, mavsdk_server
included: nothing leaks. Without `unshare` (not root, no user namespaces)
the tests skip, saying why.

"Does what it says", per script (`EXAMPLES`): a script that ends exits 0
within its bound and printed its lines; one that loops (a telemetry printer)
printed its lines within its bound, then ends cleanly on SIGINT (Ctrl-C, as
its user stops it). Where cheap, a ground station on the GCS link
(gcs_probe.py) checks the vehicle: the modes it flew in, landed and disarmed
at the end, what a script sent reaching the GCS link. A script that fails
because rotorpilot lacks a feature is `xfail(strict=True)` naming it, so it
flips loudly when the feature lands.

Run in the mavsdk 3.17.4 venv (which holds pymavlink), as root (namespaces):
`python -m pytest -n 4 tests/clients/test_mavsdk_python_examples.py`.
"""

import hashlib
import json
import os
import queue
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from harness import Vehicle, wrapped_pid  # noqa: E402

PINNED = HERE / "mavsdk_python_examples"
SOURCE = os.environ.get("MAVSDK_PYTHON_EXAMPLES") or str(PINNED / "examples")

# Vehicle speed-up: the scripts sleep on the wall clock, so a faster vehicle
# only flies further within each pause; every script here stays correct at 5x.
SPEED = 5.0

# PX4 custom modes as (main mode, sub mode) in HEARTBEAT.custom_mode
POSCTL, ORBIT = (3, 0), (3, 1)
MISSION, RTL, LAND, FOLLOW = (4, 4), (4, 5), (4, 6), (4, 8)
OFFBOARD = (6, 0)


@dataclass(frozen=True)
class Example:
    """One example script and what "does what it says" means for it."""

    path: str
    # True: it ends by itself, exit 0 within `bound` s; False: it loops, and
    # its `lines` come within `bound` s, then SIGINT ends it
    ends: bool
    bound: float
    # regular expressions its output must match (each somewhere)
    lines: tuple = ()
    # command-line arguments (the script's own documented usage)
    args: tuple = ()
    speed: float = SPEED
    # the vehicle is landed and disarmed at the end (within 60 s)
    lands: bool = False
    # PX4 modes (main, sub) the vehicle must have been in
    modes: tuple = ()
    # (message name, source system) that must reach the GCS link
    gcs_msgs: tuple = ()
    # the vehicle within 1 m of this NED point (m) when this line is printed
    at: tuple = ()
    # what the GCS (gcs_probe.py) does once the script is connected: "arm",
    # "disarm", each a second after the last (the first a second after the
    # script says it is connected, so that it has subscribed)
    gcs_does: tuple = ()
    # a rotorpilot feature the script needs and that is missing: xfail(strict)
    missing: str = ""
    # parameters (name, value) the vehicle holds afterwards, as saved in its
    # state directory's params.toml
    saved: tuple = ()
    # the daemon writes ULogs (--log-dir), as PX4 SITL always does; the
    # script's download (`log-*.ulog` beside it) must be that ULog's bytes.
    # (Its "100 %" line comes only for a log of over 200 of MAVSDK's chunks:
    # MAVSDK-Python ends the stream at SUCCESS without yielding the 1.0, so
    # the last line is the chunk before; a short flight's log ends at 9x %.)
    logs: bool = False


# A parameter file in QGroundControl's format (upload_params.py's input):
# two parameters PX4 SITL has, set to values other than their defaults.
PARAM_FILE = (
    "# Onboard parameters for Vehicle 1\n"
    "#\n# Vehicle-Id Component-Id Name Value Type\n"
    "1\t1\tMIS_TAKEOFF_ALT\t3.5\t9\n"
    "1\t1\tCOM_DISARM_LAND\t3\t9\n"
)

EXAMPLES = [
    Example("all_params.py", True, 60, lines=(r"MIS_TAKEOFF_ALT", r"MPC_XY_CRUISE")),
    Example(
        "do_orbit.py", True, 120, lines=(r"Do orbit at 10m",), lands=True, modes=(ORBIT, RTL),
    ),
    Example(
        "failure_injection.py", True, 90, lines=(r"-- Injecting GPS failure",),
    ),
    Example("firmware_version.py", True, 30, lines=(r"flight_sw_major",)),
    Example(
        "follow_me_example.py", True, 120, lines=(r"-- Following Target",), lands=True, modes=(FOLLOW,),
    ),
    Example("geofence.py", True, 30, lines=(r"Geofence uploaded!",)),
    Example(
        "goto.py", False, 40, lines=(r"Staying connected, press Ctrl-C to exit",),
    ),
    Example(
        "highres_imu.py", False, 30, lines=(r"HIGHRES_IMU \(105\)", r"X Acceleration \(m/s\^2\): -?\d"),
    ),
    Example(
        "logfile_download.py", True, 60, lines=(r"Log \d+ from", r"Downloading: log \d+"), logs=True,
    ),
    Example(
        "manual_control.py", False, 40, lines=(r"-- Starting manual control",), modes=(POSCTL,),
    ),
    Example(
        "mavlink_direct_receive.py", False, 30, lines=(r"ATTITUDE from 1/1:", r'"rollspeed"'),
    ),
    Example(
        "mavlink_direct_send.py", True, 40, lines=(r"Sending airspeed 19",), gcs_msgs=(("AIRSPEED", 245),),
    ),
    Example("mission.py", True, 150, lines=(r"Mission progress: 3/3",), lands=True, modes=(MISSION, RTL)),
    Example("mission_import.py", True, 30, lines=(r"Mission uploaded",)),
    Example("mission_raw.py", True, 30, lines=(r"-- Done",)),
    Example("offboard_attitude.py", True, 60, lines=(r"-- Stopping offboard",), modes=(OFFBOARD,)),
    Example("offboard_position_ned.py", True, 90, lines=(r"-- Stopping offboard",), modes=(OFFBOARD,)),
    # it lands, then stops offboard, which (MAVSDK's Offboard.stop) switches
    # to Hold: the vehicle stays in the air, on PX4 too
    # it holds (50, 0, -10) with a constant 1 m/s north feed-forward: PX4's
    # position controller settles where v_sp + MPC_XY_P (p_sp - p) = 0,
    # 1 / 0.95 = 1.05 m past the point
    Example(
        "offboard_position_velocity_ned.py", True, 90, lines=(r"-- Stopping offboard",), modes=(OFFBOARD,),
        at=("-- Stopping offboard", (51.05, 0.0, -10.0)),
    ),
    Example("offboard_velocity_body.py", True, 90, lines=(r"-- Stopping offboard",), modes=(OFFBOARD,)),
    Example("offboard_velocity_ned.py", True, 90, lines=(r"-- Stopping offboard",), modes=(OFFBOARD,)),
    Example(
        "offboard_from_csv/offboard_from_csv.py", True, 240, lines=(r"-- Shape completed",), speed=1.0,
        lands=True, modes=(OFFBOARD,), at=("-- Shape completed", (0.0, 0.206, -15.0)),
    ),
    # Its text reaching the GCS is not checked here: the script returns as
    # soon as send_status_text is queued, and its exit stops mavsdk_server,
    # sometimes before the STATUSTEXT has left, against PX4 as here (a race in
    # the client, so a check would pass or fail by chance). The same text,
    # sent by the same plugin from a script that waits before it exits, is
    # checked at the GCS in test_mavsdk3.py.
    Example("send_status_message.py", True, 30, lines=(r"-- Connected to drone!",)),
    Example("takeoff_and_land.py", True, 60, lines=(r"-- Landing",), lands=True, modes=(LAND,)),
    Example(
        "telemetry.py", False, 30, lines=(r"Battery: \d", r"GPS info: GpsInfo: \[num_satellites: \d+, fix_type: FIX_3D\]",
                                          r"In air: False", r"Position: \[latitude_deg: 47\.39"),
    ),
    Example("telemetry_flight_mode.py", False, 30, lines=(r"FlightMode: HOLD",)),
    Example("telemetry_is_armed_is_in_air.py", False, 30, lines=(r"Is_armed: False", r"Is_in_air: False")),
    Example(
        "telemetry_status_text.py", False, 30, lines=(r"Statustext: StatusText: \[type: INFO, text: Armed by external command\]",),
        gcs_does=("arm", "disarm"),
    ),
    Example(
        "telemetry_takeoff_and_land.py", True, 90, lines=(r"Altitude: \d", r"Flight mode: TAKEOFF"), lands=True,
    ),
    Example(
        "upload_params.py", True, 60, lines=(r"Params uploaded!",),
        args=("udpin://0.0.0.0:14540", "{params_file}"), saved=(("MIS_TAKEOFF_ALT", 3.5), ("COM_DISARM_LAND", 3.0)),
    ),
]


def _id(e):
    return e.path.split("/")[-1].removesuffix(".py")


def pinned_sums():
    """{relative path: SHA-256} of the pinned upstream examples."""
    sums = {}
    for line in (PINNED / "SHA256SUMS").read_text().splitlines():
        if line.strip():
            digest, name = line.split(maxsplit=1)
            sums[name.lstrip("*")] = digest
    return sums


def examples_dir():
    """The upstream examples directory, every pinned file in it unmodified."""
    root = Path(SOURCE)
    for name, digest in pinned_sums().items():
        f = root / name
        assert f.is_file(), f"{f} is missing: not the pinned MAVSDK-Python examples"
        got = hashlib.sha256(f.read_bytes()).hexdigest()
        assert got == digest, f"{f} differs from the pinned upstream file (sha256 {got}, pinned {digest})"
    return root


class Netns:
    """A network and PID namespace of its own: loopback up, nothing else.
    `wrap` runs a command inside; `close` ends every process in it."""

    def __init__(self):
        if shutil.which("unshare") is None or shutil.which("nsenter") is None:
            pytest.skip("needs util-linux's unshare and nsenter for a network namespace per test")
        self.holder = subprocess.Popen(
            ["unshare", "--net", "--pid", "--fork", "--kill-child", "sh", "-c",
             "ip link set lo up && echo ready && exec sleep 3600"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        line = self.holder.stdout.readline().strip()
        if line != "ready":
            err = self.holder.stderr.read() if self.holder.wait(5) is not None else ""
            pytest.skip(f"cannot make a network namespace here (unshare --net --pid, as root): {err.strip()}")
        self.init = wrapped_pid(self.holder.pid)
        self.pidns = os.readlink(f"/proc/{self.init}/ns/pid")

    def wrap(self):
        return ["nsenter", "-t", str(self.init), "--net", "--pid", "--"]

    def members(self):
        """Host PIDs of the processes still in the namespace."""
        out = []
        for d in os.listdir("/proc"):
            if d.isdigit():
                try:
                    if os.readlink(f"/proc/{d}/ns/pid") == self.pidns:
                        out.append(int(d))
                except OSError:
                    pass
        return out

    def close(self):
        """Kill the namespace's init: the kernel then kills every process in
        it. Returns the PIDs still in it afterwards (none)."""
        try:
            os.kill(self.init, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.holder.wait(10)
        deadline = time.monotonic() + 5
        while (left := self.members()) and time.monotonic() < deadline:
            time.sleep(0.05)
        return left


class Lines:
    """A child's stdout read on a thread: every line kept, with the wall
    time it came at, waitable."""

    def __init__(self, stream, parse=None):
        self.items = []
        self.cv = threading.Condition()
        self.parse = parse
        threading.Thread(target=self._read, args=(stream,), daemon=True).start()

    def _read(self, stream):
        for line in stream:
            line = line.rstrip("\n")
            if self.parse:
                try:
                    line = self.parse(line)
                except ValueError:
                    continue
            with self.cv:
                self.items.append((time.monotonic(), line))
                self.cv.notify_all()

    def wait(self, pred, timeout):
        """The first item for which pred is true, waiting up to timeout s; None if none."""
        deadline = time.monotonic() + timeout
        with self.cv:
            while True:
                for t, x in self.items:
                    if pred(x):
                        return t, x
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self.cv.wait(left)

    def all(self):
        with self.cv:
            return list(self.items)


def raised(lines, quiet=3.0):
    """True once the script printed a traceback and then nothing for `quiet`
    s: it raised. MAVSDK-Python 3 then never exits (its non-daemon thread
    reading mavsdk_server's output keeps the interpreter waiting), so the
    tests stop waiting for an exit status."""
    items = lines.all()
    return (any(x.startswith("Traceback (most recent call last)") for _, x in items)
            and time.monotonic() - items[-1][0] > quiet)


def saved_param(state_dir, name):
    """The value of `name` in the vehicle's params.toml (None if absent)."""
    try:
        text = Path(state_dir, "params.toml").read_text()
    except OSError:
        return None
    for line in text.splitlines():
        key, _, value = line.partition("#")[0].partition("=")
        if key.strip() == name:
            return float(value.strip())
    return None


def text_of(lines):
    return "\n".join(x for _, x in lines.all())


def vehicle_state(probe):
    """(armed, landed state) as the GCS link last reported them."""
    armed, landed = None, None
    for _, ev in probe.all():
        armed = ev.get("armed", armed)
        landed = ev.get("landed", landed)
    return armed, landed


@pytest.mark.parametrize(
    "ex",
    [pytest.param(e, marks=pytest.mark.xfail(strict=True, reason=f"rotorpilot lacks {e.missing}"))
     if e.missing else e for e in EXAMPLES],
    ids=_id,
)
def test_example(ex, tmp_path):
    src = examples_dir()
    work = tmp_path / "examples"
    shutil.copytree(src, work)
    params_file = tmp_path / "params.params"
    params_file.write_text(PARAM_FILE)
    extra = ["--log-dir", str(tmp_path / "logs")] if ex.logs else []
    ns = Netns()
    vehicle = Vehicle(instance=0, speed=ex.speed, gcs_port=14550, extra=extra, wrap=ns.wrap())
    probe = script = None
    try:
        vehicle.start()
        probe_proc = subprocess.Popen(
            ns.wrap() + [sys.executable, str(HERE / "gcs_probe.py")],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True,
        )
        probe = Lines(probe_proc.stdout, json.loads)
        assert probe.wait(lambda ev: "ready" in ev, 10), "the GCS probe did not start"
        assert probe.wait(lambda ev: "armed" in ev, 10), "no HEARTBEAT from the vehicle on the GCS link"
        args = [a.format(params_file=params_file) for a in ex.args]
        env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONWARNINGS="ignore::FutureWarning")
        script = subprocess.Popen(
            ns.wrap() + [sys.executable, ex.path.split("/")[-1], *args],
            cwd=work / Path(ex.path).parent, env=env,
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        )
        out = Lines(script.stdout)
        t0 = time.monotonic()
        if ex.gcs_does:
            assert out.wait(lambda x: "Connected to drone" in x, ex.bound), f"{ex.path} did not connect"
            for what in ex.gcs_does:
                # a second first: the script subscribes after it prints that it is connected
                time.sleep(1)
                probe_proc.stdin.write(what + "\n")
                probe_proc.stdin.flush()
        if ex.ends:
            while (rc := script.poll()) is None:
                if time.monotonic() - t0 > ex.bound:
                    pytest.fail(f"{ex.path} did not end within {ex.bound} s\n{text_of(out)[-3000:]}")
                if raised(out):
                    pytest.fail(f"{ex.path} raised\n{text_of(out)[-3000:]}")
                time.sleep(0.2)
            time.sleep(0.2)  # the reader thread takes the last lines
            assert rc == 0, f"{ex.path} exited {rc}\n{text_of(out)[-3000:]}"
        for pattern in ex.lines:
            while not (got := out.wait(lambda x, p=pattern: re.search(p, x), 1.0)):
                if time.monotonic() - t0 > ex.bound or raised(out):
                    break
            assert got, f"{ex.path} printed no line matching {pattern!r}\n{text_of(out)[-3000:]}"
        if not ex.ends:
            for mode in ex.modes:
                left = max(0.5, ex.bound - (time.monotonic() - t0))
                assert probe.wait(lambda ev, m=mode: (ev.get("main"), ev.get("sub")) == m, left), \
                    f"the vehicle was not in PX4 mode {mode} within {ex.bound} s"
            # Ctrl-C, as its user ends it (the KeyboardInterrupt it does not
            # catch is its way out). Twice: MAVSDK-Python 3 reads
            # mavsdk_server's output on a non-daemon thread and kills the
            # server only at exit (atexit), so after the first Ctrl-C the
            # interpreter waits for that thread for ever, against PX4 SITL
            # too; the second interrupts the wait, and atexit kills the server.
            pid = wrapped_pid(script.pid)
            os.kill(pid, signal.SIGINT)
            try:
                rc = script.wait(3)
            except subprocess.TimeoutExpired:
                os.kill(pid, signal.SIGINT)
                try:
                    rc = script.wait(10)
                except subprocess.TimeoutExpired:
                    pytest.fail(f"{ex.path} did not end within 10 s of a second SIGINT")
            assert rc in (0, 1, 130, -signal.SIGINT), f"{ex.path} ended with {rc} on SIGINT"
        print(f"{ex.path}: done in {time.monotonic() - t0:.1f} s\n{text_of(out)[-1500:]}")
        if ex.at:
            line, target = ex.at
            when = out.wait(lambda x: line in x, 1)
            assert when, f"no {line!r} printed"
            neds = [(t, ev["ned"]) for t, ev in probe.all() if "ned" in ev]
            t_ned, ned = min(neds, key=lambda p: abs(p[0] - when[0]))
            off = sum((a - b) ** 2 for a, b in zip(ned, target)) ** 0.5
            assert off < 1.0, f"at {line!r} the vehicle is at NED {ned}, {off:.2f} m from the path's end {target}"
        if ex.logs:
            got = sorted(work.glob("log-*.ulog"))
            assert got, f"{ex.path} wrote no log-*.ulog"
            data = got[0].read_bytes()
            assert data.startswith(b"ULog\x01\x12\x35"), f"not a ULog: {data[:8]!r}"
            vehicle.stop()
            ulg = next((tmp_path / "logs").rglob("flight.ulg")).read_bytes()
            assert ulg[: len(data)] == data, f"the {len(data)} bytes downloaded are not the flight's ULog"
        if ex.lands:
            deadline = time.monotonic() + 60
            while vehicle_state(probe) != (False, 1) and time.monotonic() < deadline:
                time.sleep(0.2)
            assert vehicle_state(probe) == (False, 1), \
                f"the vehicle is not landed and disarmed: (armed, landed state) = {vehicle_state(probe)}"
        for name, value in ex.saved:
            deadline = time.monotonic() + 10
            while (held := saved_param(vehicle.state_dir, name)) != value and time.monotonic() < deadline:
                time.sleep(0.2)
            assert held == value, f"{name} is {held} in the vehicle's saved parameters, not {value}"
        flown = {(ev["main"], ev["sub"]) for _, ev in probe.all() if "main" in ev}
        for mode in ex.modes:
            assert mode in flown, f"the vehicle never flew in PX4 mode {mode}; it flew in {sorted(flown)}"
        for name, sysid in ex.gcs_msgs:
            assert probe.wait(lambda ev, n=name, s=sysid: ev.get("msg") == n and ev["src"][0] == s, 3), \
                f"{name} from system {sysid} never reached the GCS"
    finally:
        if script is not None and script.poll() is None:
            script.kill()
        if script is not None:
            print(f"{ex.path}'s output:\n{text_of(out)[-4000:]}")
        if probe is not None:
            print("the GCS link saw:", [ev for _, ev in probe.all() if "ned" not in ev and "msg" not in ev])
        vehicle.stop()
        print("rotorpilot's log:\n" + vehicle.logs()[-2000:])
        left = ns.close()
        vehicle.cleanup()
        assert not left, f"processes left in the test's namespace: {left}"
