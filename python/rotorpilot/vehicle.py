"""Start and stop one rotorpilot vehicle (the `rotorpilot` daemon) for a test.

A vehicle gets its own free loopback ports, a temporary state directory (its
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
import re
import shutil
import socket
import subprocess
import sys
import sysconfig
import tempfile
import threading
from pathlib import Path

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


def free_udp_port():
    """A UDP port on 127.0.0.1 that was free a moment ago (the kernel's pick)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def free_tcp_port():
    """A TCP port on 127.0.0.1 that was free a moment ago (for mavsdk_server's gRPC)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


_LINK = re.compile(r"^\s+(\S+)\s+link: udp (\S+):(\d+) -> ")
_LOGS = re.compile(r"^\s+logs: (.+)$")
_READY = re.compile(r"^rotorpilot: ready to arm \(([0-9.]+) s after start\)")


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
        if self._root_parent:
            os.makedirs(self._root_parent, exist_ok=True)
        self.root = tempfile.mkdtemp(prefix="rotorpilot-", dir=self._root_parent)
        os.makedirs(self.state_dir)
        if self.params:
            with open(os.path.join(self.state_dir, "params.toml"), "w") as f:
                f.write("# set by the rotorpilot test fixture before start\n")
                f.writelines(self._param_lines)
        self.client_port = free_udp_port()
        self.mavsdk_server_port = free_tcp_port()
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
            m = _READY.match(line)
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
        self.stop()
        tail = self.stderr()[-6000:]
        out = "\n".join(self.banner[-20:])
        raise VehicleError(
            f"{why}\ncommand: {' '.join(self.proc.args if self.proc else [])}\n"
            f"--- stdout ---\n{out}\n--- stderr ---\n{tail}\n(kept in {self.root})"
        )

    def stop(self, timeout=5.0):
        """SIGTERM and wait (then SIGKILL); the daemon saves its state and
        closes its logs on SIGTERM. Returns its exit status."""
        if self.proc is not None and self.proc.returncode is None:
            if self.proc.poll() is None:
                self.proc.terminate()  # SIGTERM
                try:
                    self.proc.wait(timeout)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait(5)
        if self.proc is not None:
            self.returncode = self.proc.returncode
        if getattr(self, "_stderr", None):
            self._stderr.close()
            self._stderr = None
        return self.returncode

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
