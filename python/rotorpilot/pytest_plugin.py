"""pytest plugin: a rotorpilot vehicle per test, ready to arm, on free ports.

Loaded by the `pytest11` entry point whenever rotorpilot is installed (from a
checkout without installing: `pytest -p rotorpilot.pytest_plugin` with
`python/` on PYTHONPATH and ROTORPILOT_BIN set).

Fixtures
  rotorpilot_vehicle   a started `rotorpilot.Vehicle`, ready to arm
  rotorpilot_vehicles  a factory: `rotorpilot_vehicles(**options)` starts one
                       more (system ids 1, 2, ... unless `instance=` is given)
  rotorpilot_mavsdk    a MAVSDK-Python (gRPC) `System` for rotorpilot_vehicle:
                       its mavsdk_server started by the fixture, on the
                       vehicle's `mavsdk_server_port`, connected to the
                       vehicle, and killed at teardown whatever the test did;
                       `await drone.connect()` attaches it in the test's loop
  rotorpilot_mavlink   a pymavlink connection to rotorpilot_vehicle, heartbeat
                       received; closed at teardown

Options, first found wins: the factory's keyword arguments, the marker
`@pytest.mark.rotorpilot(airframe="octo", speed=10, params={...},
home=(lat, lon, alt), reuse=True)` (each option separately, from the closest marker: function,
class, module), the
command line (`--rotorpilot-airframe`, `--rotorpilot-speed`), the defaults
(quad, speed 1, PX4's default parameters and SITL home).

With `reuse=True` the tests with the same options share one running vehicle
per pytest process (per xdist worker), reset between them over its GCS link
(`rotorpilot.shared`: parameters back to their start values, plans cleared,
disarmed and rebooted at home, failures gone) and stopped at the session's
end; a test's clients are still its own.

Teardown stops the clients, then each vehicle (SIGTERM, wait); a
`mavsdk_server` still bound to, or started with, one of a vehicle's client
ports is killed first, whoever started it (`rotorpilot.clients`), so a
failed MAVSDK test neither hangs pytest's exit nor leaves a process behind.
When the test failed (setup or call), its directory with the flight record
(`flight.record`; replay with `rotorpilot replay`), the other logs and the
flight's report page (`flight.html`, written by `rotorpilot report` at
teardown, a shared vehicle's when the session ends: one HTML file that
opens offline) is kept and named in the
failure's report section and in the terminal summary;
otherwise it is deleted (`--rotorpilot-keep always|failed|never`; a vehicle
that failed to start too). Every vehicle's ports are reserved (outside the kernel's ephemeral
range, under a lock file held until it stops: `rotorpilot.reserve_port`), so
`pytest -n auto` (pytest-xdist) runs tests in parallel.
"""

import os
import shlex
import shutil
import subprocess

import pytest

from . import clients
from .shared import VehiclePool
from .vehicle import Vehicle, VehicleError, binary

OPTIONS = ("airframe", "speed", "params", "home", "instance", "extra_args", "reuse")
_VEHICLES = pytest.StashKey()
_SHARED = pytest.StashKey()  # the shared vehicles (reuse=True) a test was handed: pool entries
_PROPERTY = "rotorpilot_logs"
_PROPERTY_NO_FLIGHT = "rotorpilot_logs_no_flight"  # a vehicle that failed to start: nothing to replay
# every vehicle the plugin started in this process: pytest_unconfigure stops
# any still running (a teardown that never ran: an interrupted session)
_STARTED = []
# Ctrl-C (pytest_keyboard_interrupt): the teardowns that follow keep their
# vehicles' directories (the flights cut short), named at the end
_INTERRUPTED = []
_KEPT_INTERRUPTED = []  # (directory, node id)
# the logs a kept directory holds beside its flight record, named in the report
_OTHER_LOGS = ("rotorpilot.stderr", "mavsdk_server.log")


def pytest_addoption(parser):
    g = parser.getgroup("rotorpilot", "rotorpilot vehicles (fixture rotorpilot_vehicle)")
    g.addoption("--rotorpilot-bin", metavar="PATH",
                help="the rotorpilot executable (default: $ROTORPILOT_BIN, else the installed one)")
    g.addoption("--rotorpilot-speed", type=float, metavar="FACTOR",
                help="simulation speed factor for tests whose marker sets none (default 1)")
    g.addoption("--rotorpilot-airframe", metavar="NAME",
                help="airframe for tests whose marker sets none (default quad)")
    g.addoption("--rotorpilot-log-dir", metavar="DIR",
                help="make each vehicle's directory (state, logs, flight record) below DIR "
                     "(default: the system temp dir); point CI's artifact upload here")
    g.addoption("--rotorpilot-keep", choices=("failed", "always", "never"), default="failed",
                help="keep a vehicle's directory after the test: when it failed (default), always, never")
    g.addoption("--rotorpilot-mavsdk", choices=("mavsdk_grpc", "mavsdk"), metavar="MODULE",
                help="the MAVSDK-Python module of the rotorpilot_mavsdk fixture: mavsdk_grpc "
                     "(pip install mavsdk-grpc) or mavsdk (3.x) (default: the one the tests imported, "
                     "else mavsdk_grpc if installed)")
    g.addoption("--rotorpilot-ready-timeout", type=float, default=20.0, metavar="SECONDS",
                help="wall seconds to wait for a vehicle to be ready to arm, and for the "
                     "rotorpilot_mavsdk/rotorpilot_mavlink clients to connect (default 20)")


# mavsdk 3.17.4, the last gRPC wrapper under that name, warns on import that
# the package is now mavsdk-grpc: a name change, not a test's problem, which
# the user's `import mavsdk` would print in every run's warnings summary
MAVSDK_RENAMED = "ignore:The 'mavsdk' package has been renamed to 'mavsdk-grpc':FutureWarning"
# and both packages' System, when it starts its own mavsdk_server, call
# importlib.resources.path, which Python deprecates: theirs to change
MAVSDK_RESOURCES = r"ignore:path is deprecated:DeprecationWarning:mavsdk(_grpc)?\.system"


def pytest_configure(config):
    config.addinivalue_line(
        "markers",
        "rotorpilot(airframe='quad', speed=1, params={}, home=(lat, lon, alt), reuse=False): "
        "options of the rotorpilot_vehicle fixture (reuse=True: one vehicle for the tests with "
        "the same options, reset between them)",
    )
    config.addinivalue_line("filterwarnings", MAVSDK_RENAMED)
    config.addinivalue_line("filterwarnings", MAVSDK_RESOURCES)


def pytest_keyboard_interrupt(excinfo):
    """Ctrl-C: the flights torn down after it were cut short, which is when
    their records are wanted; keep them (unless `--rotorpilot-keep never`)."""
    _INTERRUPTED.append(True)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    """Keep each phase's report on the item (`item.rep_setup`, `rep_call`)
    for the fixture's teardown, and name the kept logs in a failure's report."""
    outcome = yield
    rep = outcome.get_result()
    setattr(item, "rep_" + rep.when, rep)
    if rep.failed and rep.when in ("setup", "call"):
        keep = item.config.getoption("rotorpilot_keep") != "never"
        lines = [_kept_line(v) for v in item.stash.get(_VEHICLES, []) if v.root] + _shared_kept_lines(item)
        if keep and lines:
            rep.sections.append(("rotorpilot", "\n".join(lines)))


def _kept_line(vehicle, shared=False):
    """Where a vehicle's directory is kept and the other logs in it; the
    replay command only when there is a flight to replay (a vehicle that
    never started, or never got ready to arm, flew none)."""
    where = vehicle.log_dir or vehicle.root
    record = os.path.join(where, "flight.record")
    if getattr(vehicle, "start_failed", False) or not os.path.isfile(record):
        return f"rotorpilot: logs kept in {where} (no flight: the vehicle failed to start)" + _other_logs(
            vehicle.root)
    line = f"rotorpilot: flight record kept in {where} — replay with `{replay_command(vehicle.bin, record)}`"
    if vehicle.log_dir:
        # written from the record once the vehicle stops: at the fixture's
        # teardown, or for a shared one when the session ends
        when = " when the session ends (the vehicle serves other tests until then)" if shared else ""
        line += f"\nrotorpilot: report page {_page(vehicle)}{when} (open it in a browser)"
    return line + _other_logs(vehicle.root)


def replay_command(exe, record):
    """`rotorpilot replay RECORD`, naming the executable by its path when
    the `rotorpilot` on PATH is another one (ROTORPILOT_BIN, a checkout's
    build, an unactivated venv): the command replays with the binary that flew."""
    on_path = shutil.which("rotorpilot")
    same = on_path is not None and os.path.realpath(on_path) == os.path.realpath(exe)
    return f"{'rotorpilot' if same else shlex.quote(exe)} replay {shlex.quote(record)}"


def _other_logs(root):
    """The daemon's stderr and the mavsdk_server's log kept in `root`, as a
    report line (empty when there are none)."""
    logs = [os.path.join(root, name) for name in _OTHER_LOGS if root and os.path.isfile(os.path.join(root, name))]
    return f"\nrotorpilot:   other logs: {', '.join(logs)}" if logs else ""


def _page(vehicle):
    return os.path.join(vehicle.log_dir, "flight.html")


def _write_page(vehicle, nodeid):
    """`rotorpilot report` of a stopped vehicle's record into its log
    directory, titled with the test's node id; a failure is written beside
    it (`flight.html.error`) and never fails the test."""
    if not vehicle.log_dir or not os.path.exists(vehicle.record):
        return
    try:
        r = subprocess.run([vehicle.bin, "report", vehicle.record, "-o", _page(vehicle), "--test", nodeid],
                           capture_output=True, text=True, timeout=300)
        why = None if r.returncode == 0 else r.stderr
    except (OSError, subprocess.TimeoutExpired) as e:
        why = str(e)
    if why:
        with open(_page(vehicle) + ".error", "w", encoding="utf-8") as f:
            f.write(why)


def _failed(item):
    return any(getattr(item, "rep_" + w, None) is not None and getattr(item, "rep_" + w).failed
               for w in ("setup", "call"))


def _options(request, given):
    """Per option, first found wins: the factory's keywords, then each
    `rotorpilot` marker from the closest (function) to the farthest (class,
    module), then the command line."""
    unknown = set(given) - set(OPTIONS)
    if unknown:
        raise TypeError(f"rotorpilot_vehicles: unknown option(s) {sorted(unknown)}; known: {OPTIONS}")
    opts = dict(given)
    for marker in request.node.iter_markers("rotorpilot"):  # closest first
        if marker.args:
            raise TypeError("@pytest.mark.rotorpilot takes keyword arguments only, e.g. speed=10")
        unknown = set(marker.kwargs) - set(OPTIONS)
        if unknown:
            raise TypeError(f"@pytest.mark.rotorpilot: unknown option(s) {sorted(unknown)}; known: {OPTIONS}")
        for name, value in marker.kwargs.items():
            opts.setdefault(name, value)
    cfg = request.config
    if "speed" not in opts and cfg.getoption("rotorpilot_speed") is not None:
        opts["speed"] = cfg.getoption("rotorpilot_speed")
    if "airframe" not in opts and cfg.getoption("rotorpilot_airframe"):
        opts["airframe"] = cfg.getoption("rotorpilot_airframe")
    return opts


@pytest.fixture
def rotorpilot_vehicles(request):
    """Factory: `rotorpilot_vehicles(airframe=..., speed=..., params=..., home=...,
    instance=...)` starts a vehicle and returns it ready to arm; all are
    stopped (and their logs kept or deleted) after the test."""
    cfg = request.config
    vehicles = request.node.stash.setdefault(_VEHICLES, [])

    def start(**given):
        __tracebackhide__ = True  # a vehicle that cannot start: its error, not this plugin's source
        opts = _options(request, given)
        if opts.pop("reuse", False):
            return _shared_vehicle(request, opts)
        opts.setdefault("instance", len(vehicles))
        v = Vehicle(bin=cfg.getoption("rotorpilot_bin"), root=cfg.getoption("rotorpilot_log_dir"), **opts)
        v.keep_failed = cfg.getoption("rotorpilot_keep") != "never"
        _STARTED.append(v)
        try:
            v.start(timeout=cfg.getoption("rotorpilot_ready_timeout"))
        except BaseException:
            # raises VehicleError with its stderr; the teardown below keeps
            # its directory (the test failed) or deletes it, as for the others
            v.start_failed = True
            vehicles.append(v)
            raise
        vehicles.append(v)
        return v

    yield start

    keep_mode = cfg.getoption("rotorpilot_keep")
    problems = _release_shared(request)
    first_error = None
    for v in vehicles:  # stop every one, even when one of them cannot be stopped
        if v.proc is None:
            continue
        early = v.proc.poll()
        try:
            rc = v.stop()
        except Exception as e:  # noqa: BLE001 - raised after the others are stopped and cleaned
            first_error = first_error or e
            continue
        if getattr(v, "start_failed", False):
            continue  # its start() already raised with its stderr
        if early is not None and early != 0:
            problems.append(f"rotorpilot (system id {v.system_id}) exited with status {early} during the test:\n"
                            + v.stderr()[-4000:])
        elif rc != 0:
            problems.append(f"rotorpilot (system id {v.system_id}) did not stop cleanly (status {rc}):\n"
                            + v.stderr()[-4000:])
    failed = (_failed(request.node) or problems or first_error or _INTERRUPTED
              or any(getattr(v, "start_failed", False) for v in vehicles))
    keep = keep_mode == "always" or (keep_mode == "failed" and failed)
    for v in vehicles:
        if not v.root:
            continue
        if keep:
            _write_page(v, request.node.nodeid)
            flew = not getattr(v, "start_failed", False)
            request.node.user_properties.append((_PROPERTY if flew else _PROPERTY_NO_FLIGHT, v.log_dir or v.root))
            if _INTERRUPTED:
                # no report will carry it: the summary names it from here
                _KEPT_INTERRUPTED.append((v.log_dir or v.root, request.node.nodeid))
        else:
            v.cleanup()
    if first_error is not None:
        raise first_error
    if problems:
        raise VehicleError("\n\n".join(problems))


# --- one vehicle for many tests (marker option reuse=True) ----------------------

@pytest.fixture(scope="session")
def _rotorpilot_pool(request):
    """The shared vehicles of this pytest process (each xdist worker has its
    own), stopped at the session's end; their directories deleted unless a
    test they served failed (`--rotorpilot-keep`)."""
    cfg = request.config

    def start(opts):
        v = Vehicle(bin=cfg.getoption("rotorpilot_bin"), root=cfg.getoption("rotorpilot_log_dir"), **opts)
        v.keep_failed = cfg.getoption("rotorpilot_keep") != "never"
        _STARTED.append(v)
        try:
            v.start(timeout=cfg.getoption("rotorpilot_ready_timeout"))  # VehicleError: it stopped itself
        except BaseException:
            if not v.keep_failed:
                v.cleanup()
            raise
        return v

    pool = VehiclePool(start, reset_timeout=cfg.getoption("rotorpilot_ready_timeout"))
    yield pool
    # a kept vehicle's page, titled with the failed tests it served
    errors = pool.close(cfg.getoption("rotorpilot_keep"),
                        on_kept=lambda e: _write_page(e.vehicle, ", ".join(e.failed_tests) or "shared vehicle"))
    if errors:
        raise errors[0]


def _shared_vehicle(request, opts):
    """A running vehicle with options `opts` from the pool, reset to its start
    state if it served a test before (`rotorpilot.shared`)."""
    pool = request.getfixturevalue("_rotorpilot_pool")
    shared = request.node.stash.setdefault(_SHARED, [])
    opts.setdefault("instance", len(shared))
    key = repr(sorted(opts.items()))
    try:
        entry = pool.acquire(key, opts)
    except VehicleError:
        for e in pool.dropped:  # a vehicle that failed to start or reset: say where its logs are
            request.node.user_properties.append((_PROPERTY, e.vehicle.log_dir or e.vehicle.root))
        raise
    shared.append(entry)
    return entry.vehicle


def _release_shared(request):
    """Hand the test's shared vehicles back to the pool; name their records
    when the test failed. Returns the problems to raise (a daemon that died)."""
    entries = request.node.stash.get(_SHARED, [])
    if not entries:
        return []
    pool = request.getfixturevalue("_rotorpilot_pool")
    failed = _failed(request.node)
    keep_mode = request.config.getoption("rotorpilot_keep")
    problems = []
    for e in entries:
        problem = pool.release(e, failed, request.node.nodeid)
        if problem:
            problems.append(problem)
        if keep_mode == "always" or (keep_mode == "failed" and (failed or problem)):
            request.node.user_properties.append((_PROPERTY, e.vehicle.log_dir or e.vehicle.root))
    return problems


def _shared_kept_lines(item):
    """The failure report's lines for the shared vehicles of `item`: the
    record and the step where this test's flight starts in it."""
    lines = []
    for e in item.stash.get(_SHARED, []):
        if e.vehicle.root:
            line = _kept_line(e.vehicle, shared=True)
            if e.served > 1:
                line += f" (a shared vehicle: this test's flight starts at step {e.start_step}, its reset's reboot)"
            lines.append(line)
    return lines


@pytest.fixture
def rotorpilot_vehicle(rotorpilot_vehicles):
    """A started rotorpilot vehicle, ready to arm (`rotorpilot.Vehicle`):
    `pymavlink_url`, `mavsdk_url`, `mavsdk_server_port`, `system_id`, `speed`,
    `state_dir`, `log_dir`, `record`, `proc`. Options from the `rotorpilot`
    marker and the `--rotorpilot-*` command-line options."""
    __tracebackhide__ = True
    return rotorpilot_vehicles()


@pytest.fixture
def rotorpilot_mavsdk(rotorpilot_vehicle, request):
    """A MAVSDK-Python `System` (gRPC wrapper: the one the test imported, else
    `mavsdk_grpc`, else `mavsdk` 3.x; `--rotorpilot-mavsdk` chooses) for
    `rotorpilot_vehicle`. The fixture starts its `mavsdk_server` on
    the vehicle's `mavsdk_server_port`, connected to `mavsdk_url`, waits
    until the server has found the vehicle, and kills the server at teardown,
    whatever the test did; the server's output is `mavsdk_server.log` in the
    vehicle's directory. gRPC channels belong to an event loop, so the test
    attaches the `System` in its own: `await drone.connect()`."""
    v = rotorpilot_vehicle
    mod = clients.mavsdk_module(request.config.getoption("rotorpilot_mavsdk"))
    server = clients.MavsdkServer(clients.mavsdk_server_exe(mod), v.mavsdk_server_port, v.mavsdk_url,
                                  os.path.join(v.root, "mavsdk_server.log"))
    try:
        server.start()
        server.wait_ready(request.config.getoption("rotorpilot_ready_timeout"))
        yield _quiet_system(mod)(mavsdk_server_address="127.0.0.1", port=v.mavsdk_server_port)
    finally:
        server.stop()


def _quiet_system(mod):
    """`mod.System` without its `__del__`: the fixture owns the server and
    kills it at teardown, and a System kept alive by a failed test's
    traceback would otherwise run `__del__` at interpreter exit, where its
    `import subprocess` fails with an ImportError printed after the summary."""
    return type("System", (mod.System,), {"__del__": lambda self: None, "__module__": mod.System.__module__})


@pytest.fixture
def rotorpilot_mavlink(rotorpilot_vehicle, request):
    """A pymavlink connection (`mavutil.mavlink_connection(pymavlink_url,
    source_system=255)`) to `rotorpilot_vehicle`, its first heartbeat
    received (`target_system` set); closed at teardown."""
    from pymavlink import mavutil

    timeout = request.config.getoption("rotorpilot_ready_timeout")
    m = mavutil.mavlink_connection(rotorpilot_vehicle.pymavlink_url, source_system=255)
    try:
        _request_heartbeat(m, rotorpilot_vehicle)
        if m.wait_heartbeat(timeout=timeout) is None:
            raise clients.ClientError(f"no heartbeat from the vehicle on {rotorpilot_vehicle.pymavlink_url} "
                                      f"within {timeout} s")
        yield m
    finally:
        m.close()


def _request_heartbeat(m, vehicle):
    """Ask the vehicle's API link, from the client's own port, for a
    HEARTBEAT now (MAV_CMD_REQUEST_MESSAGE 0): the stream sends one a second,
    and a client bound after the vehicle started (or after a shared
    vehicle's reset) would otherwise wait up to a second for it."""
    request = m.mav.command_long_encode(vehicle.system_id, 1, 512, 0, 0, 0, 0, 0, 0, 0, 0)
    m.port.sendto(request.pack(m.mav), ("127.0.0.1", vehicle.api_port))  # from the udpin socket, before it heard anyone


def pytest_unconfigure(config):
    """Stop any vehicle (and the mavsdk_servers on its ports) whose teardown
    did not run, so no process outlives the session."""
    while _STARTED:
        v = _STARTED.pop()
        if v.proc is not None and v.proc.returncode is None:
            try:
                v.stop()
            except Exception:  # noqa: BLE001 - the session is ending; stop the others
                pass


def pytest_terminal_summary(terminalreporter):
    """Name every kept vehicle directory (on the xdist controller too: the
    paths travel in the reports' user_properties)."""
    kept, no_flight = {}, set()
    for reports in terminalreporter.stats.values():
        for rep in reports:
            for name, value in getattr(rep, "user_properties", ()) or ():
                if name in (_PROPERTY, _PROPERTY_NO_FLIGHT):
                    kept.setdefault(value, getattr(rep, "nodeid", ""))
                if name == _PROPERTY_NO_FLIGHT:
                    no_flight.add(value)
    for where, nodeid in _KEPT_INTERRUPTED:
        kept.setdefault(where, f"{nodeid}, interrupted")
    if not kept:
        return
    try:
        exe = binary(terminalreporter.config.getoption("rotorpilot_bin"))
    except VehicleError:
        exe = "rotorpilot"
    terminalreporter.section("rotorpilot")
    for where, nodeid in kept.items():
        record = os.path.join(where, "flight.record")
        page = os.path.join(where, "flight.html")
        if os.path.exists(record) and where not in no_flight:
            terminalreporter.write_line(
                f"rotorpilot: flight record kept in {where} — replay with `{replay_command(exe, record)}` ({nodeid})")
            if os.path.exists(page):
                terminalreporter.write_line(f"rotorpilot:   report page {page}")
        else:
            terminalreporter.write_line(f"rotorpilot: logs kept in {where} ({nodeid})")
