"""The clients the plugin starts for a vehicle, and the net under them.

MAVSDK-Python's gRPC wrapper (`mavsdk-grpc`, imported as `mavsdk_grpc`; or
`mavsdk` 3.x, the same code under its old name) starts a `mavsdk_server`
process per `System` and reads its output on a non-daemon thread. Nothing
stops that server but `System._stop_mavsdk_server()`, the `System`'s garbage
collection or an atexit handler, and the handler runs only after the
interpreter has joined that thread, which ends only when the server does: a
failed test's traceback keeps its `System` alive, and pytest never exits
(under pytest-xdist the worker exits and the server is left running).

So the plugin starts `mavsdk_server` itself (`MavsdkServer`: its output goes
to a file, no thread reads it) and stops it at teardown, and every vehicle's
`stop()` kills any `mavsdk_server` still bound to, or started with, one of
the vehicle's ports (`kill_mavsdk_servers`), whoever started it. Linux: it
reads /proc; elsewhere the net finds nothing. Standard library only.
"""

import importlib
import os
import re
import signal
import socket
import subprocess
import sys
import time
import warnings


class ClientError(RuntimeError):
    """A client the plugin starts could not be started or did not connect."""


# --- MAVSDK-Python (gRPC) -----------------------------------------------------

def mavsdk_module(name=None):
    """The installed gRPC MAVSDK-Python module: `name` ("mavsdk_grpc" or
    "mavsdk") if given; else the one this process already imported (the two
    cannot both be imported: they register the same protobuf files); else
    `mavsdk_grpc` (`pip install mavsdk-grpc`) if installed, else `mavsdk`
    when it is the gRPC wrapper (3.x; 4.x under that name is the native
    binding, another API)."""
    tried = []
    if name:
        names = (name,)
    else:
        imported = [n for n in ("mavsdk_grpc", "mavsdk") if n in sys.modules]
        names = imported[:1] or ("mavsdk_grpc", "mavsdk")
    for name in names:
        try:
            with warnings.catch_warnings():
                # mavsdk 3.17.4 warns that the package is now mavsdk-grpc: the user chose it
                warnings.simplefilter("ignore", FutureWarning)
                mod = importlib.import_module(name)
        except ImportError as e:
            tried.append(f"{name}: {e}")
            continue
        system = getattr(mod, "System", None)
        if system is not None and hasattr(system, "_start_mavsdk_server") and hasattr(mod, "bin"):
            return mod
        tried.append(f"{name}: not the gRPC wrapper (no System with its own mavsdk_server)")
    raise ClientError("rotorpilot_mavsdk needs MAVSDK-Python's gRPC wrapper: "
                      "pip install \"mavsdk-grpc==4.0.5\" (or \"mavsdk==3.17.4\"); " + "; ".join(tried))


def mavsdk_server_exe(mod):
    """The `mavsdk_server` executable shipped inside `mod` (its `bin` package)."""
    exe = os.path.join(os.path.dirname(mod.bin.__file__), "mavsdk_server.exe" if os.name == "nt" else "mavsdk_server")
    if not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
        raise ClientError(f"{mod.__name__} ships no mavsdk_server executable for this platform ({exe})")
    return exe


class MavsdkServer:
    """One `mavsdk_server` on gRPC port `port`, connected to `system_address`
    (`udpin://127.0.0.1:P`), its output in `log_path`."""

    # mavsdk_server's log lines, v2 to v4
    _DISCOVERED = re.compile(r"New system on|System discovered|Discovered \d+ system")

    def __init__(self, exe, port, system_address, log_path, sysid=245, compid=190):
        self.exe = exe
        self.port = int(port)
        self.system_address = system_address
        self.log_path = log_path
        self.args = [exe, "-p", str(self.port), "--sysid", str(sysid), "--compid", str(compid), system_address]
        self.proc = None
        self._log = None

    def start(self):
        self._log = open(self.log_path, "wb")
        self.proc = subprocess.Popen(self.args, stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT)
        return self

    def log(self):
        try:
            with open(self.log_path, errors="replace") as f:
                return f.read()
        except OSError:
            return ""

    def wait_ready(self, timeout=10.0):
        """Return once the server accepts gRPC connections and has found the
        vehicle; raise ClientError (with its log) if it exits first or takes
        longer than `timeout` wall seconds."""
        deadline = time.monotonic() + timeout
        listening = discovered = False
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise ClientError(f"mavsdk_server exited with status {self.proc.returncode}:\n{self.log()[-4000:]}")
            if not discovered:
                discovered = bool(self._DISCOVERED.search(self.log()))
            if not listening:
                with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
                    s.settimeout(0.2)
                    listening = s.connect_ex(("127.0.0.1", self.port)) == 0
            if listening and discovered:
                return self
            time.sleep(0.02)
        raise ClientError(f"mavsdk_server on port {self.port} was not "
                          + ("connected to the vehicle" if listening else "listening")
                          + f" within {timeout} s:\n{self.log()[-4000:]}")

    def stop(self):
        """Kill it (it keeps no state) and wait; idempotent."""
        try:
            if self.proc is not None and self.proc.poll() is None:
                self.proc.kill()
                try:
                    self.proc.wait(5)
                except subprocess.TimeoutExpired:
                    pass
        finally:
            if self._log is not None:
                self._log.close()
                self._log = None


# --- the net: mavsdk_server processes on a vehicle's ports ---------------------

def _socket_inodes(ports):
    """Inodes of this network namespace's TCP/UDP sockets bound to one of `ports`."""
    inodes = set()
    for table in ("tcp", "tcp6", "udp", "udp6"):
        try:
            with open(f"/proc/net/{table}") as f:
                next(f, None)
                for line in f:
                    fields = line.split()
                    if len(fields) > 9 and int(fields[1].rsplit(":", 1)[1], 16) in ports:
                        inodes.add(fields[9])
        except (OSError, ValueError, IndexError):
            continue
    return inodes


def _uses_port(pid, args, ports, inodes):
    for i, a in enumerate(args):
        if a == "-p" and i + 1 < len(args) and args[i + 1].isdigit() and int(args[i + 1]) in ports:
            return True  # its gRPC port
        m = re.search(r":(\d+)$", a)
        if m and int(m.group(1)) in ports:
            return True  # its MAVLink connection (udpin://127.0.0.1:P)
    if inodes:
        try:
            for fd in os.listdir(f"/proc/{pid}/fd"):
                try:
                    link = os.readlink(f"/proc/{pid}/fd/{fd}")
                except OSError:
                    continue
                if link.startswith("socket:[") and link[8:-1] in inodes:
                    return True
        except OSError:
            pass
    return False


def mavsdk_servers_on(ports):
    """Pids of this user's live `mavsdk_server` processes started with, or
    bound to, one of `ports` (Linux /proc; elsewhere none)."""
    ports = {int(p) for p in ports if p}
    if not ports or not os.path.isdir("/proc/self"):
        return []
    inodes = _socket_inodes(ports)
    uid = os.getuid()
    found = []
    for name in os.listdir("/proc"):
        if not name.isdigit():
            continue
        try:
            if os.stat(f"/proc/{name}").st_uid != uid:
                continue
            with open(f"/proc/{name}/cmdline", "rb") as f:
                args = [a.decode(errors="replace") for a in f.read().split(b"\0") if a]
            with open(f"/proc/{name}/stat") as f:
                state = f.read().rsplit(")", 1)[1].split()[0]
        except (OSError, IndexError):
            continue
        if not args or state == "Z" or not os.path.basename(args[0]).startswith("mavsdk_server"):
            continue
        if _uses_port(name, args, ports, inodes):
            found.append(int(name))
    return found


def _gone(pid):
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] == "Z"
    except (OSError, IndexError):
        return True


def kill_mavsdk_servers(ports, timeout=3.0):
    """SIGKILL every `mavsdk_server` of `mavsdk_servers_on(ports)` and wait
    (up to `timeout` s) until each is gone; returns their pids."""
    pids = mavsdk_servers_on(ports)
    for pid in pids:
        try:
            os.kill(pid, signal.SIGKILL)
        except OSError:
            pass
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not all(_gone(p) for p in pids):
        time.sleep(0.02)
    return pids
