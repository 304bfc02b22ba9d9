"""A failing MAVSDK test never hangs pytest nor leaks a process.

Each case writes a small test file the way the docs show (a MAVSDK-Python
test that takes off and then asserts something false, with and without the
plugin's `rotorpilot_mavsdk` fixture; a pymavlink one with
`rotorpilot_mavlink`), runs it with `python -m pytest` in a subprocess
(plain and `-n 2`) under a timeout, and checks that the inner run exits 1 on
its own, and that no `mavsdk_server` or `rotorpilot` process it started is
left: every process started by the inner run inherits a marker in its
environment, and none carrying it may survive the run.

MAVSDK-Python's gRPC wrapper starts `mavsdk_server` with a non-daemon thread
reading its output; a failed test's traceback keeps the `System` alive, so
without the plugin stopping that server the interpreter's exit waits on the
thread forever (and under xdist the server outlives its worker).

Needs `pip install .`, mavsdk==3.17.4 (and mavsdk-grpc, when installed, is
tried too), pymavlink, pytest-xdist.
"""

import importlib.util
import os
import re
import signal
import subprocess
import sys
import textwrap
import time
import uuid

import pytest

INNER_TIMEOUT = 60  # wall seconds; each inner run takes 5-15 s: one that needs 60 has hung

MAVSDK_MODULES = [m for m in ("mavsdk", "mavsdk_grpc") if importlib.util.find_spec(m) is not None]

PRELUDE = '''
import asyncio

import pytest
from {mod} import System


async def first(stream, cond, timeout, what):
    async def scan():
        async for x in stream:
            if cond(x):
                return x
    try:
        return await asyncio.wait_for(scan(), timeout)
    except asyncio.TimeoutError:
        raise AssertionError(f"no {{what}} within {{timeout}} s") from None


async def take_off(drone):
    await first(drone.core.connection_state(), lambda c: c.is_connected, 20, "connection")
    await first(drone.telemetry.health(), lambda h: h.is_armable and h.is_home_position_ok, 10, "health")
    await drone.action.arm()
    await drone.action.takeoff()
    return await first(drone.telemetry.position(), lambda p: p.relative_altitude_m > 2.0, 30, "takeoff")
'''

# the docs' MAVSDK recipe before the fixture: System on the reserved port, no finally
DOCS_STYLE = '''

@pytest.mark.rotorpilot(speed=10)
def test_takeoff_then_wrong_assertion(rotorpilot_vehicle):
    async def fly():
        drone = System(port=rotorpilot_vehicle.mavsdk_server_port)
        await drone.connect(system_address=rotorpilot_vehicle.mavsdk_url)
        p = await take_off(drone)
        assert p.relative_altitude_m > 100, "climbed to 100 m"  # false: it fails here

    asyncio.run(asyncio.wait_for(fly(), 120))


@pytest.mark.rotorpilot(speed=10)
def test_takeoff_then_error(rotorpilot_vehicle):
    async def fly():
        drone = System(port=rotorpilot_vehicle.mavsdk_server_port)
        await drone.connect(system_address=rotorpilot_vehicle.mavsdk_url)
        await take_off(drone)
        raise RuntimeError("an error after takeoff")

    asyncio.run(asyncio.wait_for(fly(), 120))
'''

WITH_FIXTURE = '''

@pytest.mark.rotorpilot(speed=10)
def test_fixture_takeoff_then_wrong_assertion(rotorpilot_mavsdk):
    async def fly():
        drone = rotorpilot_mavsdk
        await drone.connect()
        p = await take_off(drone)
        assert p.relative_altitude_m > 100, "climbed to 100 m"

    asyncio.run(asyncio.wait_for(fly(), 120))


@pytest.mark.rotorpilot(speed=10)
def test_fixture_timeout(rotorpilot_mavsdk):
    async def fly():
        drone = rotorpilot_mavsdk
        await drone.connect()
        await take_off(drone)
        await asyncio.sleep(60)

    asyncio.run(asyncio.wait_for(fly(), 5))


@pytest.mark.rotorpilot(speed=10)
def test_fixture_mavlink_wrong_assertion(rotorpilot_mavlink):
    hb = rotorpilot_mavlink.recv_match(type="HEARTBEAT", blocking=True, timeout=5)
    assert hb is not None
    assert hb.base_mode & 128, "armed"  # false: nobody armed it
'''


def _marked(marker):
    """Pids of live (non-zombie) processes whose environment carries `marker`."""
    pids = []
    needle = marker.encode()
    for name in os.listdir("/proc"):
        if not name.isdigit() or int(name) == os.getpid():
            continue
        try:
            with open(f"/proc/{name}/environ", "rb") as f:
                env = f.read()
            with open(f"/proc/{name}/stat") as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if needle in env and state != "Z":
            pids.append(int(name))
    return pids


def _describe(pids):
    out = []
    for pid in pids:
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                out.append(f"{pid}: " + f.read().replace(b"\0", b" ").decode(errors="replace"))
        except OSError:
            pass
    return "\n".join(out)


def run_inner(tmp_path, source, *args):
    """Run `source` as a test file with `python -m pytest`: (exit status or
    None on a timeout, output, pids of its processes left alive). Anything
    it left is killed afterwards."""
    test = tmp_path / "test_inner.py"
    test.write_text(source)
    marker = f"ROTORPILOT_INNER_RUN={uuid.uuid4().hex}"
    env = dict(os.environ)
    env["ROTORPILOT_INNER_RUN"] = marker.split("=", 1)[1]
    env["PYTHONWARNINGS"] = "ignore::FutureWarning"
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
           "--rotorpilot-log-dir", str(tmp_path / "logs"), *args, str(test)]
    proc = subprocess.Popen(cmd, cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True, start_new_session=True)
    try:
        out, _ = proc.communicate(timeout=INNER_TIMEOUT)
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate()
        rc = None
    deadline = time.monotonic() + 3  # processes being killed at exit: a moment to go
    left = _marked(marker)
    while left and time.monotonic() < deadline:
        time.sleep(0.1)
        left = _marked(marker)
    described = _describe(left)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
    return rc, out, described


def check(rc, out, left, failed):
    assert rc is not None, f"the inner pytest hung (killed after {INNER_TIMEOUT} s):\n{out[-4000:]}"
    assert rc == 1, f"inner pytest exited {rc}:\n{out[-4000:]}"
    assert f"{failed} failed" in out, out[-4000:]
    assert not left, f"processes left running by the inner run:\n{left}\n--- its output ---\n{out[-3000:]}"


@pytest.mark.parametrize("xdist", [[], ["-n", "2"]], ids=["plain", "n2"])
@pytest.mark.parametrize("mod", MAVSDK_MODULES)
def test_docs_style_failing_mavsdk_test_neither_hangs_nor_leaks(tmp_path, mod, xdist):
    rc, out, left = run_inner(tmp_path, PRELUDE.format(mod=mod) + DOCS_STYLE, *xdist)
    check(rc, out, left, 2)


def _fixture_module():
    """The gRPC wrapper the fixture picks by itself: mavsdk_grpc when installed."""
    return "mavsdk_grpc" if "mavsdk_grpc" in MAVSDK_MODULES else "mavsdk"


@pytest.mark.parametrize("xdist", [[], ["-n", "2"]], ids=["plain", "n2"])
@pytest.mark.parametrize("mod", MAVSDK_MODULES)
def test_fixture_failing_tests_neither_hang_nor_leak(tmp_path, mod, xdist):
    rc, out, left = run_inner(tmp_path, PRELUDE.format(mod=mod) + WITH_FIXTURE, "--rotorpilot-mavsdk", mod, *xdist)
    check(rc, out, left, 3)
    # a System kept alive by a failure's traceback says nothing at exit
    # (its __del__ would import at interpreter shutdown and print an ImportError)
    assert "Exception ignored" not in out, out[-4000:]
    # the failure report names the MAVSDK server's log kept beside the record
    assert "mavsdk_server.log" in out, out[-4000:]


INTERRUPTED_DOCS_STYLE = '''

@pytest.mark.rotorpilot(speed=10)
def test_long_flight(rotorpilot_vehicle):
    async def fly():
        drone = System(port=rotorpilot_vehicle.mavsdk_server_port)
        await drone.connect(system_address=rotorpilot_vehicle.mavsdk_url)
        await take_off(drone)
        open(os.environ["INNER_FLAG"], "w").close()
        await asyncio.sleep(120)

    asyncio.run(fly())
'''

INTERRUPTED_FIXTURE = '''

@pytest.mark.rotorpilot(speed=10)
def test_long_flight(rotorpilot_mavsdk):
    async def fly():
        await rotorpilot_mavsdk.connect()
        await take_off(rotorpilot_mavsdk)
        open(os.environ["INNER_FLAG"], "w").close()
        await asyncio.sleep(120)

    asyncio.run(fly())
'''


@pytest.mark.parametrize("xdist", [[], ["-n", "2"]], ids=["plain", "n2"])
@pytest.mark.parametrize("body", [INTERRUPTED_DOCS_STYLE, INTERRUPTED_FIXTURE], ids=["docs_style", "fixture"])
def test_interrupted_run_leaves_nothing(tmp_path, body, xdist):
    """SIGINT (Ctrl-C) in the middle of a flight: pytest stops, tears down and
    exits 2. Plain, the signal goes to pytest alone (a CI runner stopping
    it); under xdist to the whole process group, as a terminal's Ctrl-C
    reaches the controller, its workers and what they started."""
    src = "import os\n" + PRELUDE.format(mod=_fixture_module()) + body
    test = tmp_path / "test_inner.py"
    test.write_text(src)
    marker = uuid.uuid4().hex
    flag = tmp_path / "flying"
    env = dict(os.environ, ROTORPILOT_INNER_RUN=marker, INNER_FLAG=str(flag), PYTHONWARNINGS="ignore::FutureWarning")
    proc = subprocess.Popen([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
                             "--rotorpilot-log-dir", str(tmp_path / "logs"), *xdist, str(test)],
                            cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not flag.exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
        assert flag.exists(), "the inner test never took off"
        if xdist:
            os.killpg(proc.pid, signal.SIGINT)
        else:
            proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=60)
        rc = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, _ = proc.communicate()
        rc = None
    time.sleep(0.5)
    left = _marked(f"ROTORPILOT_INNER_RUN={marker}")
    described = _describe(left)
    for pid in left:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
    assert rc is not None, f"the interrupted inner pytest hung:\n{out[-4000:]}"
    assert rc == 2, f"inner pytest exited {rc} (2: interrupted):\n{out[-4000:]}"
    assert not described, f"processes left running by the interrupted run:\n{described}\n{out[-3000:]}"
    if not xdist:
        # the flight cut short is kept and named, its record replayable
        kept = re.findall(r"flight record kept in (\S+) .*\(test_inner\.py::\S+, interrupted\)", out)
        assert kept, out[-4000:]
        assert os.path.isfile(os.path.join(kept[0], "flight.record")), os.listdir(kept[0])
