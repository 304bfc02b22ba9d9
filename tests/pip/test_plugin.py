"""The pytest plugin's own behaviour, through inner pytest sessions
(`pytester`, in a subprocess, as a user's run): a failing test keeps its
vehicle's directory and flight record and says where, a passing one leaves
nothing behind, a vehicle that cannot start fails the fixture with its
stderr, misspelled parameters are refused, and the marker's options reach
the vehicle (airframe, parameters, home, several vehicles with their own
system ids). Needs pymavlink.
"""

import os
import re
import subprocess
import sysconfig
from importlib import metadata
from pathlib import Path

import pytest
from pymavlink import mavutil

import rotorpilot
from rotorpilot import Vehicle, binary
from rotorpilot.pytest_plugin import replay_command


def plugin_args():
    """`-p rotorpilot.pytest_plugin` when the package is used from a checkout
    (not installed, so no pytest11 entry point loads it)."""
    try:
        metadata.distribution("rotorpilot")
        return []
    except metadata.PackageNotFoundError:
        return ["-p", "rotorpilot.pytest_plugin"]


def run_inner(pytester, source, *args):
    pytester.makepyfile(test_inner=source)
    # the inner run imports this rotorpilot package, installed or not
    package_root = os.path.dirname(os.path.dirname(rotorpilot.__file__))
    pytester._monkeypatch.setenv("PYTHONPATH", os.pathsep.join([package_root, str(pytester.path)]))
    # the inner run sees warnings as a user's run does: the test-all script
    # silences FutureWarning for its own client runs, not for this one
    pytester._monkeypatch.delenv("PYTHONWARNINGS", raising=False)
    return pytester.runpytest_subprocess("-p", "no:cacheprovider", *plugin_args(), *args, timeout=120)


FAILING = """
def test_fails(rotorpilot_vehicle):
    assert rotorpilot_vehicle.proc.poll() is None
    assert rotorpilot_vehicle.speed == 20
    assert False, "on purpose"

def test_passes(rotorpilot_vehicle):
    assert rotorpilot_vehicle.proc.poll() is None
"""


@pytest.mark.parametrize("xdist", [False, True], ids=["plain", "xdist"])
def test_a_failed_test_keeps_its_record_and_says_where(pytester, tmp_path, xdist):
    if xdist:
        pytest.importorskip("xdist")
    base = tmp_path / "vehicles"
    args = ["--rotorpilot-speed", "20", "--rotorpilot-log-dir", str(base)] + (["-n", "2"] if xdist else [])
    r = run_inner(pytester, FAILING, *args)
    out = r.stdout.str()
    r.assert_outcomes(passed=1, failed=1)
    kept = re.findall(r"rotorpilot: (?:flight record|logs) kept in (\S+)", out)
    assert kept, out
    where = kept[-1]
    assert os.path.isdir(where) and where.startswith(str(base)), out
    # exactly one vehicle directory is left: the passing test's was deleted
    assert len(os.listdir(base)) == 1, os.listdir(base)
    # the terminal summary names the failed test beside its directory, under xdist too
    summary = out.split("= rotorpilot =")[-1]
    assert re.search(rf"kept in {re.escape(where)} .*\(test_inner.py::test_fails\)", summary), out
    # the flight record is kept, named, and replays
    record = os.path.join(where, "flight.record")
    assert os.path.isfile(record), os.listdir(where)
    # with the executable that flew: by its path unless it is the one on PATH
    assert f"replay with `{replay_command(binary(), record)}`" in out, out
    # the other logs are named beside it
    assert f"other logs: {os.path.join(os.path.dirname(os.path.dirname(where)), 'rotorpilot.stderr')}" in out, out
    replay = subprocess.run([binary(), "replay", record], capture_output=True, text=True, timeout=120)
    assert replay.returncode == 0, replay.stdout + replay.stderr
    # its report page is written, titled with the test, and named in the failure's report and the summary
    page = os.path.join(where, "flight.html")
    assert os.path.isfile(page), os.listdir(where)
    assert "test_inner.py::test_fails" in open(page, encoding="utf-8").read()
    assert out.count(f"report page {page}") >= 2, out  # the failure's report section and the summary


FAILING_SHARED = """
import pytest

pytestmark = pytest.mark.rotorpilot(reuse=True)

def test_passes(rotorpilot_vehicle):
    assert rotorpilot_vehicle.proc.poll() is None

def test_fails(rotorpilot_vehicle):
    assert False, "on purpose"
"""


@pytest.mark.parametrize("xdist", [False, True], ids=["plain", "xdist"])
def test_a_failed_test_on_a_shared_vehicle_gets_the_report_page_it_is_told_of(pytester, tmp_path, xdist):
    """A shared vehicle (reuse=True) keeps running for the next tests, so
    its page is written when the session ends, from the whole record, and
    titled with the failed tests it served; the failure's report says so."""
    if xdist:
        pytest.importorskip("xdist")
    base = tmp_path / "vehicles"
    args = ["--rotorpilot-speed", "20", "--rotorpilot-log-dir", str(base)] + (["-n", "1"] if xdist else [])
    r = run_inner(pytester, FAILING_SHARED, *args)
    out = r.stdout.str()
    r.assert_outcomes(passed=1, failed=1)
    pages = re.findall(r"report page (\S+flight\.html) when the session ends", out)
    assert pages, out
    page = pages[-1]
    assert os.path.isfile(page), os.listdir(os.path.dirname(page))
    assert "test_inner.py::test_fails" in open(page, encoding="utf-8").read()
    assert f"report page {page}" in out.split("= rotorpilot =")[-1], out  # the summary names it too


def test_a_passing_run_leaves_nothing_and_keep_always_keeps(pytester, tmp_path):
    base = tmp_path / "vehicles"
    r = run_inner(pytester, "def test_ok(rotorpilot_vehicle):\n    pass\n", "--rotorpilot-log-dir", str(base))
    r.assert_outcomes(passed=1)
    assert os.listdir(base) == []
    assert "kept in" not in r.stdout.str()
    r = run_inner(pytester, "def test_ok(rotorpilot_vehicle):\n    pass\n", "--rotorpilot-log-dir", str(base),
                  "--rotorpilot-keep", "always")
    r.assert_outcomes(passed=1)
    assert len(os.listdir(base)) == 1


def test_a_vehicle_that_cannot_start_fails_the_fixture_with_its_stderr(pytester, tmp_path):
    r = run_inner(pytester, "def test_x(rotorpilot_vehicle):\n    pass\n", "--rotorpilot-airframe", "no-such-frame",
                  "--rotorpilot-log-dir", str(tmp_path))
    r.assert_outcomes(errors=1)
    out = r.stdout.str()
    assert "exited with status" in out and "before it was ready to arm" in out, out
    assert "no-such-frame" in out.split("--- stderr ---")[1], out


def test_a_misspelled_parameter_fails_the_fixture(pytester, tmp_path):
    src = ('import pytest\n@pytest.mark.rotorpilot(params={"MIS_TAKEOF_ALT": 5.0})\n'
           "def test_x(rotorpilot_vehicle):\n    pass\n")
    r = run_inner(pytester, src, "--rotorpilot-log-dir", str(tmp_path))
    r.assert_outcomes(errors=1)
    out = r.stdout.str()
    # said once in the error's message, not again from the
    # daemon's stderr below it nor in the traceback's argument lines (pytest's
    # own short summary repeats the whole message when CI is set; not counted)
    report = out.split("short test summary info")[0]
    said = [line for line in report.splitlines() if "unknown parameter MIS_TAKEOF_ALT" in line]
    assert len(said) == 1, out
    assert report.index("VehicleError: rotorpilot skipped parameters") < report.index(said[0]), out
    # the error, not the plugin's source, and no replay of a flight that never was
    assert "def start(" not in out and "opts = _options(" not in out, out
    assert "replay with" not in out, out


def test_a_vehicle_that_never_started_names_no_replay(pytester, tmp_path):
    """An unknown airframe in the marker: the vehicle never started, so no
    flight record exists, and the report names its directory but no replay;
    every replay command the run prints names a record that exists."""
    src = ('import pytest\n@pytest.mark.rotorpilot(airframe="quadx")\n'
           "def test_x(rotorpilot_vehicle):\n    pass\n")
    r = run_inner(pytester, src, "--rotorpilot-log-dir", str(tmp_path))
    r.assert_outcomes(errors=1)
    out = r.stdout.str()
    assert "unknown airframe `quadx`" in out, out
    assert re.search(r"rotorpilot: logs kept in \S+ \(no flight: the vehicle failed to start\)", out), out
    assert "replay with" not in out, out


def connect(v):
    m = mavutil.mavlink_connection(v.pymavlink_url, source_system=255)
    assert m.wait_heartbeat(timeout=5) is not None
    return m


def param(m, name):
    m.mav.param_request_read_send(m.target_system, 1, name.encode(), -1)
    p = m.recv_match(type="PARAM_VALUE", condition=f"PARAM_VALUE.param_id == '{name}'", blocking=True, timeout=5)
    assert p is not None, name
    return p.param_value


@pytest.mark.rotorpilot(airframe="octo", speed=5, params={"MIS_TAKEOFF_ALT": 7.5}, home=(45.5, 9.25, 120.0))
def test_marker_options_reach_the_vehicle(rotorpilot_vehicle):
    v = rotorpilot_vehicle
    m = connect(v)
    assert m.messages["HEARTBEAT"].type == mavutil.mavlink.MAV_TYPE_OCTOROTOR
    assert param(m, "MIS_TAKEOFF_ALT") == pytest.approx(7.5)
    home = m.recv_match(type="HOME_POSITION", blocking=True, timeout=5)
    assert home is not None
    # home is where the vehicle rests, as PX4 sets it: the ground at the
    # marker's 120 m AMSL plus the body's rest height (NED z on the ground),
    # both on the navigation filter, whose height on the ground moves by up
    # to 0.15 m after home is set (0.027 m seen here)
    rest = m.recv_match(type="LOCAL_POSITION_NED", blocking=True, timeout=5)
    assert rest is not None and -0.5 < rest.z < 0.0
    assert (home.latitude / 1e7, home.longitude / 1e7) == pytest.approx((45.5, 9.25), abs=2e-3)
    assert home.altitude / 1e3 == pytest.approx(120.0 - rest.z, abs=0.3)
    assert v.speed == 5 and v.ready_s is not None and v.ready_s < 0.5


def test_several_vehicles_in_one_test(rotorpilot_vehicles):
    a, b = rotorpilot_vehicles(speed=5), rotorpilot_vehicles(speed=5, airframe="hexa")
    assert (a.system_id, b.system_id) == (1, 2)
    assert len({a.client_port, b.client_port, a.api_port, b.api_port}) == 4
    assert {a.mavsdk_server_port, b.mavsdk_server_port} and a.mavsdk_server_port != b.mavsdk_server_port
    ma, mb = connect(a), connect(b)
    assert (ma.target_system, mb.target_system) == (1, 2)
    assert mb.messages["HEARTBEAT"].type == mavutil.mavlink.MAV_TYPE_HEXAROTOR


def test_vehicle_without_pytest():
    with Vehicle(speed=10, params={"MIS_TAKEOFF_ALT": 4.0}) as v:
        assert v.pymavlink_url == f"udpin:127.0.0.1:{v.client_port}"
        assert v.mavsdk_url == f"udpin://127.0.0.1:{v.client_port}"
        assert param(connect(v), "MIS_TAKEOFF_ALT") == pytest.approx(4.0)
        root = v.root
    assert v.returncode == 0 and not os.path.exists(root)


def test_the_installed_package_runs_its_own_executable():
    """After `pip install .`: the package's version is Cargo.toml's, and with
    no ROTORPILOT_BIN it runs the executable the wheel put beside Python."""
    try:
        metadata.distribution("rotorpilot")
    except metadata.PackageNotFoundError:
        pytest.skip("rotorpilot is used from a checkout, not installed")
    cargo = (Path(__file__).resolve().parents[2] / "Cargo.toml").read_text()
    version = re.search(r'^version = "([^"]+)"', cargo, re.M).group(1)
    assert rotorpilot.__version__ == version
    if not os.environ.get("ROTORPILOT_BIN"):
        assert binary() == os.path.join(sysconfig.get_path("scripts"), "rotorpilot")


MARKERS = """
import pytest
pytestmark = pytest.mark.rotorpilot(speed=10, airframe="hexa")

@pytest.mark.rotorpilot(params={"MIS_TAKEOFF_ALT": 6.0}, airframe="octo")
def test_merged(rotorpilot_vehicle):
    v = rotorpilot_vehicle
    # speed from the module's marker, params from the function's, airframe: the closest wins
    assert (v.speed, v.params, v.airframe) == (10.0, {"MIS_TAKEOFF_ALT": 6.0}, "octo")

def test_module_only(rotorpilot_vehicle):
    assert (rotorpilot_vehicle.speed, rotorpilot_vehicle.airframe) == (10.0, "hexa")

@pytest.mark.rotorpilot(speed=5)
def test_factory_first(rotorpilot_vehicles):
    v = rotorpilot_vehicles(speed=20)
    assert (v.speed, v.airframe) == (20.0, "hexa")
"""


def test_marker_options_merge_across_function_and_module(pytester, tmp_path):
    r = run_inner(pytester, MARKERS, "--rotorpilot-log-dir", str(tmp_path), "--rotorpilot-speed", "2")
    r.assert_outcomes(passed=3)


def test_keep_never_deletes_a_vehicle_that_failed_to_start(pytester, tmp_path):
    src = "def test_x(rotorpilot_vehicle):\n    pass\n"
    for keep, left in (("never", 0), ("failed", 1)):
        base = tmp_path / keep
        r = run_inner(pytester, src, "--rotorpilot-airframe", "no-such-frame", "--rotorpilot-log-dir", str(base),
                      "--rotorpilot-keep", keep)
        r.assert_outcomes(errors=1)
        assert len(os.listdir(base)) == left, (keep, os.listdir(base))
        out = r.stdout.str()
        if left:
            where = os.path.join(base, os.listdir(base)[0])
            assert f"kept in {where}" in out, out
        else:
            assert f"kept in {base}" not in out and "directory is deleted" in out, out


STOP_FAILS = """
import pytest
from rotorpilot import VehicleError

def test_x(rotorpilot_vehicles):
    a, b = rotorpilot_vehicles(speed=10), rotorpilot_vehicles(speed=10)
    real_stop = a.stop
    def stop(timeout=5.0):
        real_stop(timeout)
        raise VehicleError("a could not be stopped (on purpose)")
    a.stop = stop
    with open("pids", "w") as f:
        f.write(f"{a.proc.pid} {b.proc.pid}")
"""


def test_a_vehicle_that_cannot_be_stopped_does_not_stop_the_teardown(pytester, tmp_path):
    base = tmp_path / "v"
    r = run_inner(pytester, STOP_FAILS, "--rotorpilot-log-dir", str(base), "--rotorpilot-keep", "never")
    r.assert_outcomes(passed=1, errors=1)
    assert "a could not be stopped (on purpose)" in r.stdout.str()
    pids = [int(p) for p in (pytester.path / "pids").read_text().split()]
    for pid in pids:  # both were stopped (reaped), the second one after the first's stop raised
        assert not os.path.exists(f"/proc/{pid}") or "zombie" in open(f"/proc/{pid}/status").read().lower()
    assert os.listdir(base) == []


def test_mavsdk_3s_renaming_warning_is_not_shown(pytester, tmp_path):
    """mavsdk 3.17.4 warns on import that it is now mavsdk-grpc: a test
    module that imports it sees no FutureWarning in its run (the plugin
    filters that one warning and no other)."""
    try:
        metadata.distribution("mavsdk")
    except metadata.PackageNotFoundError:
        pytest.skip("mavsdk 3 is not installed")
    src = ("import warnings\nimport mavsdk\n\n"
           "def test_x():\n    warnings.warn('another', FutureWarning)\n")
    r = run_inner(pytester, src, "--rotorpilot-log-dir", str(tmp_path))
    r.assert_outcomes(passed=1)
    out = r.stdout.str()
    assert "renamed to 'mavsdk-grpc'" not in out, out
    assert "FutureWarning: another" in out, out


def test_mavsdks_resources_deprecation_is_not_shown(pytester, tmp_path):
    """Both MAVSDK packages' System call importlib.resources.path, which
    Python deprecates: that warning, from their module, is filtered; the
    same warning from the test's own code is not."""
    src = ("import warnings\n\n"
           "def test_x():\n"
           "    warnings.warn_explicit('path is deprecated. Use files() instead', DeprecationWarning,\n"
           "                           'system.py', 506, module='mavsdk_grpc.system')\n"
           "    warnings.warn_explicit('path is deprecated. Use files() instead', DeprecationWarning,\n"
           "                           'system.py', 506, module='mavsdk.system')\n"
           "    warnings.warn('path is deprecated: mine', DeprecationWarning)\n")
    r = run_inner(pytester, src, "--rotorpilot-log-dir", str(tmp_path))
    r.assert_outcomes(passed=1)
    out = r.stdout.str()
    assert "Use files() instead" not in out, out
    assert "path is deprecated: mine" in out, out
