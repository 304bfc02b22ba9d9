"""Start and stop one rotorpilot vehicle (the `rotorpilot` daemon) for a test.

A vehicle gets its own reserved loopback ports (`reserve_port`), a temporary state directory (its
`params.toml` is written before start, so parameters are in force from the
first step, and in the flight record) and a log directory; `start()` returns
once the daemon prints `rotorpilot: ready to arm`, which it does when its
SYS_STATUS health word is complete (home set, prearm checks pass).

The daemon is started as

    rotorpilot --airframe A --speed S [--home LAT,LON,ALT] --instance N
        --api-bind 127.0.0.1:0 --api-remote 127.0.0.1:P
        --gcs-bind 127.0.0.1:0 --gcs-remote none
        --state-dir DIR/state --log-dir DIR/logs

and its stdout banner tells the ports it bound and its run's log directory:

    rotorpilot: quad at 47.3977420, 8.5455940, 488.0 m AMSL; instance 0, system id 1; speed x1
      GCS  link: udp 127.0.0.1:51925 -> (whoever talks)
      API  link: udp 127.0.0.1:59595 -> 127.0.0.1:40123
      plans: DIR/state/missions.json (mission 0 items, fence 0, rally 0)
      logs: DIR/logs/2026-12-02T03-17-05Z-i0
      parameters: DIR/state/params.toml
    rotorpilot: ready to arm (0.004 s after start)

The API link sends to port P, where the client listens (`udpin`), as MAVSDK
and pymavlink listen on 14540 for PX4 SITL. Every wait is bounded.
"""

import os
import random
import re
import shutil
import socket
import subprocess
import sys
import sysconfig
import tempfile
import threading
from pathlib import Path

from .clients import kill_mavsdk_servers

try:
    import fcntl
except ImportError:  # Windows: the ephemeral-range guard alone
    fcntl = None

EXE = "rotorpilot.exe" if os.name == "nt" else "rotorpilot"


class VehicleError(RuntimeError):
    """The daemon could not be found, exited early or never got ready."""


def binary(explicit=None):
    """The `rotorpilot` executable: `explicit` (e.g. `--rotorpilot-bin`),
    else $ROTORPILOT_BIN, else the one `pip install` put beside this
    interpreter (found even when the venv is not activated), else the one on
    PATH, else a checkout's own build ($CARGO_TARGET_DIR or target/, release)
    when this package is used from a checkout without installing."""
    tried = []
    for label, cand in (("--rotorpilot-bin", explicit), ("$ROTORPILOT_BIN", os.environ.get("ROTORPILOT_BIN"))):
        if cand:
            if os.path.isfile(cand) and os.access(cand, os.X_OK):
                return str(cand)
            raise VehicleError(f"{label} is {cand}, which is not an executable file")
    scripts = sysconfig.get_path("scripts")
    for cand in ([os.path.join(scripts, EXE)] if scripts else []) + [shutil.which("rotorpilot")]:
        if cand and os.path.isfile(cand) and os.access(cand, os.X_OK):
            return cand
        tried.append(str(cand))
    checkout = Path(__file__).resolve().parents[2]
    if (checkout / "Cargo.toml").is_file():
        target = Path(os.environ.get("CARGO_TARGET_DIR") or checkout / "target")
        cand = target / "release" / EXE
        if cand.is_file():
            return str(cand)
        tried.append(str(cand))
    raise VehicleError(
        "no rotorpilot executable: `pip install` rotorpilot, or set ROTORPILOT_BIN "
        "(or --rotorpilot-bin) to a built one (cargo build --release); tried " + ", ".join(tried)
    )


# --- port reservation -------------------------------------------------------
# A port picked by bind-and-close is bound again later by someone else (the
# client's `udpin`, mavsdk_server's gRPC). Two guards keep it ours meanwhile:
# it lies outside the kernel's ephemeral range (so no `bind(0)` anywhere,
# a daemon's `127.0.0.1:0` included, gets it), and an exclusive flock on
# $TMPDIR/rotorpilot-ports/P.lock, held until `release()` (or the process's
# exit), keeps every other reserving process (pytest-xdist workers, other
# runs) off it.

_PORT_LO, _PORT_HI = 20000, 65535  # candidates: above the usual fixed services
_FALLBACK = (20000, 32767)  # below Linux's default ephemeral range 32768..60999


def _ephemeral_range():
    """The kernel's ephemeral (automatic `bind(0)`) port range, inclusive;
    Linux's default when /proc does not say (other systems)."""
    try:
        with open("/proc/sys/net/ipv4/ip_local_port_range") as f:
            lo, hi = (int(x) for x in f.read().split())
        return lo, hi
    except (OSError, ValueError):
        return 32768, 60999


def _candidate_ranges():
    """Port ranges (inclusive) in _PORT_LO.._PORT_HI outside the ephemeral range."""
    lo, hi = _ephemeral_range()
    ranges = [(a, b) for a, b in ((_PORT_LO, min(lo - 1, _PORT_HI)), (max(hi + 1, _PORT_LO), _PORT_HI)) if b - a >= 100]
    return ranges or [_FALLBACK]


def _bindable(port):
    """Whether 127.0.0.1:port is free for both UDP and TCP right now."""
    for kind in (socket.SOCK_DGRAM, socket.SOCK_STREAM):
        with socket.socket(socket.AF_INET, kind) as s:
            try:
                s.bind(("127.0.0.1", port))
            except OSError:
                return False
    return True


class PortReservation:
    """A loopback port held for this process: `port`, `release()`; also a
    context manager. Free for UDP and TCP when reserved."""

    def __init__(self, port, lock_fd):
        self.port = port
        self._fd = lock_fd

    def release(self):
        if self._fd is not None:
            os.close(self._fd)  # closing drops the flock
            self._fd = None

    @property
    def held(self):
        return self._fd is not None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()

    def __int__(self):
        return self.port

    def __repr__(self):
        return f"<PortReservation {self.port}{'' if self.held else ' released'}>"


def _lock_dir():
    d = os.path.join(tempfile.gettempdir(), "rotorpilot-ports")
    os.makedirs(d, exist_ok=True)
    try:
        os.chmod(d, 0o1777)  # shared by every user's runs, like /tmp
    except OSError:
        pass
    return d


def reserve_port(attempts=500, rng=None):
    """Reserve a loopback port outside the kernel's ephemeral range: its lock
    file `$TMPDIR/rotorpilot-ports/P.lock` is held (exclusive, non-blocking
    flock) by the returned `PortReservation` until `release()`, and the port
    was free for UDP and TCP once locked. Ports are tried at random (`rng`:
    a `random.Random`, default the system's)."""
    ranges = _candidate_ranges()
    weights = [b - a + 1 for a, b in ranges]
    d = _lock_dir()
    rng = rng or random.SystemRandom()
    for _ in range(attempts):
        a, b = rng.choices(ranges, weights)[0]
        port = rng.randint(a, b)
        try:
            fd = os.open(os.path.join(d, f"{port}.lock"), os.O_RDWR | os.O_CREAT, 0o666)
        except OSError:  # e.g. another user's lock file
            continue
        if fcntl is not None:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:  # another process (or reservation) holds it
                os.close(fd)
                continue
        if not _bindable(port):
            os.close(fd)
            continue
        return PortReservation(port, fd)
    raise VehicleError(f"no free loopback port outside the ephemeral range {_ephemeral_range()} "
                       f"after {attempts} tries")


_HELD = []  # reservations of free_udp_port/free_tcp_port: kept until exit


def free_udp_port():
    """A reserved loopback port for a UDP listener (see `reserve_port`),
    held until this process exits."""
    r = reserve_port()
    _HELD.append(r)
    return r.port


def free_tcp_port():
    """A reserved loopback port for a TCP listener, e.g. mavsdk_server's gRPC
    (see `reserve_port`), held until this process exits."""
    return free_udp_port()


_LINK = re.compile(r"^\s+(\S+)\s+link: udp (\S+):(\d+) -> ")
_LOGS = re.compile(r"^\s+logs: (.+)$")
# the daemon's ready line; group 1: its own start-to-ready seconds
READY_LINE = re.compile(r"^rotorpilot: ready to arm \(([0-9.]+) s after start\)", re.M)


def _toml_value(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise VehicleError(f"parameter {name}: {value!r} is not a number")
    return repr(int(value)) if isinstance(value, int) else repr(float(value))


class Vehicle:
    """One rotorpilot daemon on free loopback ports.

    Attributes once started (see the module doc):
      `pymavlink_url` ("udpin:127.0.0.1:P") for `mavutil.mavlink_connection`,
      `mavsdk_url` ("udpin://127.0.0.1:P") for MAVSDK 3's `System.connect(system_address=...)`
      and MAVSDK 4's `Mavsdk.add_any_connection`, `mavsdk_server_port` (a free
      TCP port for MAVSDK 3's `System(port=...)`: its default 50051 clashes
      between parallel tests), `client_port` (P), `api_port` and `gcs_port`
      (the daemon's bound API and GCS ports: `udpout:127.0.0.1:G` reaches the
      GCS link), `system_id`, `speed`, `airframe`, `home`, `params`,
      `state_dir`, `log_dir` (this run's directory: `flight.record`, logs),
      `record` (`log_dir/flight.record`), `root` (the temporary directory
      holding both), `ready_s` (the daemon's own start-to-ready time), `proc`.
    """

    def __init__(
        self,
        airframe="quad",
        speed=1.0,
        params=None,
        home=None,
        instance=0,
        bin=None,
        root=None,
        extra_args=(),
    ):
        self.airframe = airframe
        self.speed = float(speed)
        self.params = dict(params or {})
        # checked now, written to params.toml at start (read before the first step)
        self._param_lines = [f"{name} = {_toml_value(name, value)}\n" for name, value in self.params.items()]
        self.home = tuple(home) if home is not None else None
        if self.home is not None and len(self.home) != 3:
            raise VehicleError(f"home must be (lat_deg, lon_deg, alt_amsl_m), got {home!r}")
        self.instance = int(instance)
        self.system_id = self.instance + 1
        self.bin = binary(bin)
        self.extra_args = list(extra_args)
        self._root_parent = root
        self.root = None
        self.proc = None
        self.banner = []
        self.api_port = self.gcs_port = self.client_port = self.mavsdk_server_port = None
        self.log_dir = None
        self.ready_s = None
        self.returncode = None
        self._ports = []
        self.killed_clients = []  # pids of mavsdk_servers stop() had to kill
        # whether a failed start() leaves `root` for a post-mortem (the
        # pytest plugin clears it for --rotorpilot-keep never)
        self.keep_failed = True

    # --- connection strings -------------------------------------------------
    @property
    def pymavlink_url(self):
        return f"udpin:127.0.0.1:{self.client_port}"

    @property
    def mavsdk_url(self):
        return f"udpin://127.0.0.1:{self.client_port}"

    @property
    def record(self):
        return os.path.join(self.log_dir, "flight.record") if self.log_dir else None

    @property
    def state_dir(self):
        return os.path.join(self.root, "state") if self.root else None

    @property
    def stderr_path(self):
        return os.path.join(self.root, "rotorpilot.stderr") if self.root else None

    def wall(self, sim_seconds):
        """Wall seconds for `sim_seconds` of simulated time at this speed."""
        return sim_seconds / self.speed

    # --- life cycle ---------------------------------------------------------
    def start(self, timeout=20.0):
        """Start the daemon and return once it is ready to arm; raise
        VehicleError with its stderr if it exits first or takes longer than
        `timeout` wall seconds."""
        __tracebackhide__ = True  # under pytest: the error, not this method's source
        if self._root_parent:
            os.makedirs(self._root_parent, exist_ok=True)
        self.root = tempfile.mkdtemp(prefix="rotorpilot-", dir=self._root_parent)
        os.makedirs(self.state_dir)
        if self.params:
            with open(os.path.join(self.state_dir, "params.toml"), "w") as f:
                f.write("# set by the rotorpilot test fixture before start\n")
                f.writelines(self._param_lines)
        # both held until stop(): nobody else reserves them meanwhile
        self._ports = [reserve_port(), reserve_port()]
        self.client_port, self.mavsdk_server_port = (r.port for r in self._ports)
        args = [
            self.bin,
            "--airframe", str(self.airframe),
            "--speed", repr(self.speed),
            "--instance", str(self.instance),
            "--api-bind", "127.0.0.1:0",
            "--api-remote", f"127.0.0.1:{self.client_port}",
            "--gcs-bind", "127.0.0.1:0",
            "--gcs-remote", "none",
            "--state-dir", self.state_dir,
            "--log-dir", os.path.join(self.root, "logs"),
        ]
        if self.home is not None:
            args += ["--home", ",".join(repr(float(x)) for x in self.home)]
        args += self.extra_args
        self._stderr = open(self.stderr_path, "w")
        self.proc = subprocess.Popen(
            args, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=self._stderr, text=True, bufsize=1
        )
        ready = threading.Event()
        threading.Thread(target=self._read_stdout, args=(ready,), daemon=True).start()
        # the reader sets `ready` at the ready line, or at end of output (exit)
        if not ready.wait(timeout):
            self._fail(f"rotorpilot was not ready to arm within {timeout} s")
        if self.ready_s is None:
            try:
                rc = self.proc.wait(2)
                self._fail(f"rotorpilot exited with status {rc} before it was ready to arm")
            except subprocess.TimeoutExpired:
                self._fail("rotorpilot closed its output before it was ready to arm")
        if self.api_port is None:
            self._fail("rotorpilot's banner names no API link")
        warnings = [w for w in self.stderr().splitlines() if "params.toml:" in w]
        if warnings:
            self._fail("rotorpilot skipped parameters:\n" + "\n".join(warnings))
        return self

    def _read_stdout(self, ready):
        for line in self.proc.stdout:
            line = line.rstrip("\n")
            self.banner.append(line)
            m = _LINK.match(line)
            if m:
                port = int(m.group(3))
                if m.group(1) == "API":
                    self.api_port = port
                elif m.group(1) == "GCS":
                    self.gcs_port = port
            m = _LOGS.match(line)
            if m:
                self.log_dir = m.group(1)
            m = READY_LINE.match(line)
            if m:
                self.ready_s = float(m.group(1))
                ready.set()
        ready.set()

    def stderr(self):
        try:
            with open(self.stderr_path) as f:
                return f.read()
        except (OSError, TypeError):
            return ""

    def _fail(self, why):
        # pytest shows a frame's arguments in its traceback: this frame's
        # `why` would repeat the message its E lines give, so it is hidden
        __tracebackhide__ = True
        try:
            self.stop()
        except VehicleError as e:
            why += f" ({e})"
        # each line once: a line `why` already quotes is not repeated from stderr
        said = set(why.splitlines())
        tail = "\n".join(line for line in self.stderr()[-6000:].splitlines() if line not in said)
        out = "\n".join(self.banner[-20:])
        raise VehicleError(
            f"{why}\ncommand: {' '.join(self.proc.args if self.proc else [])}\n"
            f"--- stdout ---\n{out}\n--- stderr ---\n{tail}\n"
            + (f"(kept in {self.root})" if self.keep_failed else "(its directory is deleted: keep policy never)")
        )

    def stop(self, timeout=5.0):
        """SIGTERM and wait (then SIGKILL); the daemon saves its state and
        closes its logs on SIGTERM. Returns its exit status; raises
        VehicleError if it outlives SIGKILL too. Releases its ports either way.

        First it kills any `mavsdk_server` still bound to, or started with,
        one of this vehicle's client ports (`client_port`,
        `mavsdk_server_port`): a MAVSDK `System` a failed test never closed
        would otherwise outlive the test, and keep Python from exiting."""
        try:
            if any(r.held for r in self._ports):  # still ours
                self.killed_clients += kill_mavsdk_servers([self.client_port, self.mavsdk_server_port])
            if self.proc is not None and self.proc.returncode is None:
                if self.proc.poll() is None:
                    self.proc.terminate()  # SIGTERM
                    try:
                        self.proc.wait(timeout)
                    except subprocess.TimeoutExpired:
                        self.proc.kill()
                        try:
                            self.proc.wait(5)
                        except subprocess.TimeoutExpired:
                            raise VehicleError(f"rotorpilot (pid {self.proc.pid}) did not exit "
                                               f"{timeout} s after SIGTERM nor 5 s after SIGKILL") from None
            if self.proc is not None:
                self.returncode = self.proc.returncode
            return self.returncode
        finally:
            for r in self._ports:
                r.release()
            if getattr(self, "_stderr", None):
                self._stderr.close()
                self._stderr = None

    def cleanup(self):
        """Delete the temporary state and log directories."""
        if self.root:
            shutil.rmtree(self.root, ignore_errors=True)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()
        if exc[0] is None:
            self.cleanup()
        else:
            print(f"rotorpilot: logs kept in {self.log_dir or self.root}", file=sys.stderr)

    def __repr__(self):
        return (
            f"<rotorpilot.Vehicle {self.airframe} x{self.speed} sysid {self.system_id} "
            f"client {self.client_port if self.proc else '-'} logs {self.log_dir}>"
        )
