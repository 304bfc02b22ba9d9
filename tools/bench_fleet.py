#!/usr/bin/env python3
"""Benchmarks of a fleet in one process, against the release
binary, printed as Markdown tables with the exact commands:

1. Real-time factor reached by `rotorpilot --count N` for N = 64 and 250
   (MAVLink system ids stop at 250 here: instances 0..249), with every
   vehicle's API link streaming PX4's default set to one listening UDP
   socket of this script (`--api-remote 127.0.0.1:PORT --gcs-remote none`;
   datagrams and bytes per second counted, kernel drops read from
   /proc/net/udp) and without links (`--api-remote none --gcs-remote none`:
   nothing streamed), at `--speed 1` (does it keep real time at 1 kHz?)
   and `--speed 1000` (the most it reaches: the simulation lets simulated
   time lag when it cannot keep up, so the reached factor is simulated time
   advanced / wall time). 256 and 1,024 vehicles are tried without links
   and reported as the daemon answers (refused while system ids stop at 250).
2. Memory: VmRSS of the process (/proc/PID/status) at 1, 64 and 250
   vehicles, and the slope per vehicle (least squares).
3. CPU of an idle fleet of 64 at --speed 1 (utime + stime from
   /proc/PID/stat over the window, in % of one core): with a listening
   client, streaming into the void (a closed port), and without links.
   The listener's own CPU (this script) is shown beside: on a 2-core
   machine it competes with the fleet.
4. Side by side: N separate `rotorpilot --instance k` processes versus one
   `rotorpilot --count N` (N = 8, 32, 64), all at --speed 1 streaming
   their API link to the listener: total CPU % and RSS, and whether each
   vehicle keeps real time (its own factor, from its ATTITUDE.time_boot_ms).

Simulated time is read off ATTITUDE.time_boot_ms per system id. Without
links one probe is needed: this script sends a ground station's HEARTBEAT
to the first vehicle's GCS port (18570+i), which then streams to it alone
(about 270 datagrams/s, one vehicle of the fleet); every vehicle is on one
clock, so its time is the fleet's.

5. The tracked goals (`--only goals`): `rotorpilot simulate
   tools/fleets/fleet-1024.toml --json --threads 1` and `--threads 2` (the
   real-time factor its summary gives, the speed-up from 1 to 2 threads, and
   the CPU seconds each run took: user + system of the child, which a busy
   machine does not inflate as it does wall time), and the daemon's 250
   vehicles streaming to the listener flat out (section 1's figure), on the
   daemon's navigation filter and, as the goals count them, on the ideal
   navigation solution (a `--fleet` file setting RP_NAV_SRC 0). With
   `--compare OTHER_BINARY` each configuration runs with both binaries in
   turn, side by side in one run.

Each configuration runs --repeat times (default 2), configurations
alternating, and the tables give medians and [min, max] ranges. The
machine's load average at each start is shown: other work on the machine
lowers the figures.

    cargo build --release
    .venv/pymavlink/bin/python tools/bench_fleet.py [--quick] [--only rt,mem,cpu,side,goals]
    .venv/pymavlink/bin/python tools/bench_fleet.py --only goals --compare OLD_BINARY

stdlib + pymavlink; Linux (/proc). Fleets of 64 start at instance 100
(ports 14680+, 18670+), away from PX4's instances 0..9 that client tests
use; a fleet of 250 needs instances 0..249, and waits while any of its ports
is taken.
"""

import argparse
import json
import os
import shlex
import shutil
import resource
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from pymavlink import mavutil

REPO = Path(__file__).resolve().parents[1]
mavlink = mavutil.mavlink
TICK = os.sysconf("SC_CLK_TCK")
ATTITUDE = mavlink.MAVLINK_MSG_ID_ATTITUDE
# the simulation's step rate [Hz]: vehicle-steps/s = vehicles x factor x STEP_HZ
STEP_HZ = 1000.0


def binary():
    if os.environ.get("ROTORPILOT_BIN"):
        return os.environ["ROTORPILOT_BIN"]
    target = os.environ.get("CARGO_TARGET_DIR", str(REPO / "target"))
    return str(Path(target) / "release" / "rotorpilot")


def load_avg():
    with open("/proc/loadavg") as f:
        return float(f.read().split()[0])


def cpu_s(pid):
    """utime + stime [s] of process `pid` (all its threads)."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def rss_mb(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    return float("nan")


def udp_drops(port):
    """Datagrams the kernel dropped for our socket on `port` (its receive buffer was full)."""
    want = f":{port:04X}"
    with open("/proc/net/udp") as f:
        for line in f.readlines()[1:]:
            cols = line.split()
            if cols[1].endswith(want):
                return int(cols[-1])
    return 0


def ports_free(ports):
    for p in ports:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            s.bind(("0.0.0.0", p))
        except OSError:
            return False
        finally:
            s.close()
    return True


class Listener:
    """One UDP socket on 127.0.0.1 that every vehicle streams to: counts
    datagrams and bytes, and keeps, per system id, the last ATTITUDE's
    time_boot_ms with the wall time it arrived (MAVLink 2 frames read by
    hand: header byte 5 the system id, bytes 7..9 the message id, the
    payload from byte 10; time_boot_ms is ATTITUDE's first field)."""

    def __init__(self):
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.sock.bind(("127.0.0.1", 0))
        self.port = self.sock.getsockname()[1]
        self.sock.settimeout(0.2)
        self.datagrams = 0
        self.bytes = 0
        self.clock = {}
        self.lock = threading.Lock()
        self.done = threading.Event()
        self.mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        buf = bytearray(2048)
        recv = self.sock.recvfrom_into
        clock = self.clock
        while not self.done.is_set():
            try:
                n, _ = recv(buf)
            except OSError:
                continue
            now = time.monotonic()
            self.datagrams += 1
            self.bytes += n
            k = 0
            while k + 12 <= n and buf[k] == 0xFD:
                length = buf[k + 1]
                if buf[k + 7] == ATTITUDE and buf[k + 8] == 0 and buf[k + 9] == 0:
                    t = int.from_bytes(buf[k + 10:k + 10 + min(4, length)], "little")
                    clock[buf[k + 5]] = (now, t)
                k += 12 + length + (13 if buf[k + 2] & 1 else 0)

    def probe(self, port):
        """A ground station's HEARTBEAT to 127.0.0.1:PORT (a vehicle's GCS
        link then streams to this socket)."""
        msg = self.mav.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        self.sock.sendto(msg.pack(self.mav), ("127.0.0.1", port))

    def snapshot(self):
        return self.datagrams, self.bytes, dict(self.clock)

    def close(self):
        self.done.set()
        self.thread.join(2)
        self.sock.close()


def factors(c0, c1):
    """Per system id: simulated time advanced / wall time between two clock snapshots."""
    out = {}
    for s, (w1, t1) in c1.items():
        if s in c0:
            w0, t0 = c0[s]
            if w1 - w0 > 1.0:
                out[s] = (t1 - t0) / 1000.0 / (w1 - w0)
    return out


class Run:
    """Processes started from `commands` (each an argv list), their banners
    read up to the "parameters:" line; stopped with SIGTERM."""

    def __init__(self, commands, tmp, start_timeout):
        self.procs = []
        self.logs = []
        self.error = None
        for k, argv in enumerate(commands):
            log = open(os.path.join(tmp, f"stderr-{k}.log"), "w+")
            p = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=log, text=True)
            self.procs.append(p)
            self.logs.append(log)
        deadline = time.monotonic() + start_timeout
        for p, log in zip(self.procs, self.logs):
            ok = self._banner(p, deadline)
            if not ok:
                log.flush()
                log.seek(0)
                lines = [x for x in log.read().splitlines() if x.strip()]
                # the daemon's own words ("error: invalid value '256' for
                # '--count <N>': ..."), not the hint clap prints after them
                said = [x for x in lines if x.startswith("error")] or lines[-1:]
                self.error = (said[0] if said else f"exit {p.poll()}")[:200]
                return

    @staticmethod
    def _banner(p, deadline):
        done = threading.Event()
        ready = threading.Event()

        def read():
            for line in p.stdout:
                if "parameters:" in line:
                    ready.set()
                    break
            done.set()
            # keep draining stdout: nothing more is expected, but never block the daemon
            for _ in p.stdout:
                pass

        threading.Thread(target=read, daemon=True).start()
        done.wait(max(0.1, deadline - time.monotonic()))
        # its banner's last line, and still running a moment later
        return ready.is_set() and p.poll() is None

    def cpu_s(self):
        return sum(cpu_s(p.pid) for p in self.procs)

    def rss_mb(self):
        return sum(rss_mb(p.pid) for p in self.procs)

    def lag_warnings(self):
        n = 0
        for log in self.logs:
            log.flush()
            log.seek(0)
            n += log.read().count("cannot keep up")
        return n

    def stop(self):
        for p in self.procs:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(30)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait(5)
        for log in self.logs:
            log.close()


def fleet_cmd(n, first, speed, links, state, listen_port, void_port, fleet_file=None):
    """The command line of one fleet (n > 1 or forced) or lone vehicle (n == 0: `--instance first` alone);
    with `fleet_file`, the fleet that file describes."""
    remote = {"listener": f"127.0.0.1:{listen_port}", "void": f"127.0.0.1:{void_port}", "none": "none"}[links]
    argv = [binary()]
    if fleet_file:
        argv += ["--fleet", fleet_file]
    else:
        if n:
            argv += ["--count", str(n)]
        argv += ["--instance", str(first)]
    argv += ["--speed", f"{speed:g}", "--state-dir", state, "--reset-params",
             "--reset-plans", "--api-remote", remote, "--gcs-remote", "none"]
    return argv


def ideal_fleet_file(n, first, directory):
    """A fleet file of `--count n --instance first`'s vehicles flying the ideal navigation
    solution (RP_NAV_SRC 0, as scenario and mission files fly) instead of the daemon's filter."""
    path = os.path.join(directory, "ideal.toml")
    with open(path, "w") as f:
        f.write(f"[[vehicle]]\ninstance = {first}\ncount = {n}\nspacing_m = [3.0, 0.0]\n"
                "params = { RP_NAV_SRC = 0 }\n")
    return path


def shown(argv, listen_port, void_port, state):
    """The command as a user would type it (temporary paths and ports named)."""
    s = shlex.join(argv[1:]).replace(state, "STATE")
    s = s.replace(f"127.0.0.1:{listen_port}", "127.0.0.1:LISTENER").replace(f"127.0.0.1:{void_port}", "127.0.0.1:CLOSED")
    return "rotorpilot " + s


def measure(config, window_s, warmup_s):
    """One run of `config` (dict: n, first, speed, links, lone): its figures."""
    n, first, speed, links, lone = (config[k] for k in ("n", "first", "speed", "links", "lone"))
    listener = Listener()
    void = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    void.bind(("127.0.0.1", 0))
    void_port = void.getsockname()[1]
    void.close()  # closed: datagrams sent there are dropped by the kernel (ICMP port unreachable)
    tmp = tempfile.mkdtemp(prefix="rotorpilot-bench-fleet-")
    if lone:
        commands = [fleet_cmd(0, first + k, speed, links, os.path.join(tmp, str(first + k)), listener.port, void_port)
                    for k in range(n)]
    else:
        fleet_file = ideal_fleet_file(n, first, tmp) if config.get("ideal") else None
        commands = [fleet_cmd(n, first, speed, links, tmp, listener.port, void_port, fleet_file)]
    config["command"] = shown(commands[0], listener.port, void_port, tmp) + (
        f"  # k = {first}..{first + n - 1}, one process each" if lone else "")
    if lone:
        config["command"] = config["command"].replace(f"--instance {first}", "--instance k").replace(
            os.path.join("STATE", str(first)), "STATE/k").replace("STATE/" + str(first), "STATE/k")
    ports = [18570 + first + k for k in range(min(n, 250))] + [14580 + first + k for k in range(min(n, 250))]
    waited = time.monotonic() + 120
    while not ports_free(ports) and time.monotonic() < waited:
        time.sleep(2)
    for attempt in range(4):
        result = {"load": load_avg()}
        run = Run(commands, tmp, 20 + n * 0.2)
        if not (run.error and "in use" in run.error):
            break
        # another process took one of the ports between our look and the bind: wait, try again
        run.stop()
        time.sleep(10)
    try:
        if run.error:
            result["error"] = run.error
            return result
        probe = 18570 + first

        def poke():
            if links != "listener":
                listener.probe(probe)

        t_end = time.monotonic() + warmup_s
        while time.monotonic() < t_end:
            poke()
            time.sleep(min(0.5, max(0.0, t_end - time.monotonic())))
        d0, b0, c0 = listener.snapshot()
        drops0 = udp_drops(listener.port)
        cpu0, w0, me0 = run.cpu_s(), time.monotonic(), sum(os.times()[:2])
        t_end = w0 + window_s
        while time.monotonic() < t_end:
            poke()
            time.sleep(min(0.5, max(0.0, t_end - time.monotonic())))
        cpu1, w1, me1 = run.cpu_s(), time.monotonic(), sum(os.times()[:2])
        d1, b1, c1 = listener.snapshot()
        wall = w1 - w0
        f = factors(c0, c1)
        result.update(
            cpu_pct=100.0 * (cpu1 - cpu0) / wall,
            client_pct=100.0 * (me1 - me0) / wall,
            rss_mb=run.rss_mb(),
            dgram_s=(d1 - d0) / wall,
            mb_s=(b1 - b0) / wall / 1e6,
            drops=udp_drops(listener.port) - drops0,
            heard=len(f),
            factor=statistics.median(f.values()) if f else float("nan"),
            min_factor=min(f.values()) if f else float("nan"),
            lag=run.lag_warnings(),
        )
        return result
    finally:
        run.stop()
        listener.close()
        shutil.rmtree(tmp, ignore_errors=True)


FLEET_1024 = REPO / "tools" / "fleets" / "fleet-1024.toml"


def headless(threads):
    """One `simulate fleet-1024.toml --json --threads N`: the real-time
    factor of its summary, its wall time and the CPU seconds it took."""
    load = load_avg()
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([binary(), "simulate", str(FLEET_1024), "--json", "--threads", str(threads)],
                         capture_output=True, text=True, check=True)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    d = json.loads(out.stdout)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return {"load": load, "factor": d["real_time_factor"], "wall": d["wall_time_s"], "cpu": cpu}


def goals(binaries, repeat, window, warmup):
    """Section 5: each binary's fleet-1024 factors and its 250-vehicle daemon rate, alternating."""
    rows = {b: {"h1": [], "h2": [], "daemon": [], "ideal": []} for b in binaries}
    daemon = {"n": 250, "first": 0, "speed": 1000.0, "links": "listener", "lone": False}
    for r in range(repeat):
        for b in binaries:
            os.environ["ROTORPILOT_BIN"] = b
            for t in (1, 2):
                res = headless(t)
                rows[b][f"h{t}"].append(res)
                print(f"# run {r + 1}: {b} simulate {FLEET_1024.name} --threads {t}\n#   -> {res}", file=sys.stderr, flush=True)
            res = measure(dict(daemon), window, warmup)
            rows[b]["daemon"].append(res)
            print(f"# run {r + 1}: {b} --count 250 --speed 1000 (API -> listener)\n#   -> {res}", file=sys.stderr, flush=True)
            res = measure(dict(daemon, ideal=True), window, warmup)
            rows[b]["ideal"].append(res)
            print(f"# run {r + 1}: {b} the same on the ideal navigation\n#   -> {res}", file=sys.stderr, flush=True)
    print("\n### Tracked goals (fleet-1024 headless; 250 vehicles in the daemon, API links to a listener, flat out)\n")
    cols = ["binary", "fleet-1024, 1 thread (x real time)", "2 threads", "speed-up 1 -> 2 (wall)",
            "CPU s, 1 thread", "CPU s, 2 threads", "daemon, 250 vehicles (x real time)",
            "the same, ideal navigation", "load avg"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for b in binaries:
        h1, h2, d = rows[b]["h1"], rows[b]["h2"], [x for x in rows[b]["daemon"] if "error" not in x]
        ideal = [x for x in rows[b]["ideal"] if "error" not in x]
        speedup = [x["wall"] / y["wall"] for x, y in zip(h1, h2)]
        loads = [x["load"] for x in h1 + h2] + [x["load"] for x in rows[b]["daemon"] + rows[b]["ideal"]]
        print("| " + " | ".join([
            b, fmt([x["factor"] for x in h1], 3), fmt([x["factor"] for x in h2], 3), fmt(speedup, 2),
            fmt([x["cpu"] for x in h1], 2), fmt([x["cpu"] for x in h2], 2), fmt([x["factor"] for x in d], 2),
            fmt([x["factor"] for x in ideal], 2), fmt(loads, 2),
        ]) + " |")
    print(f"\nCommands: `rotorpilot simulate tools/fleets/fleet-1024.toml --json --threads 1|2`; "
          f"`{shown(fleet_cmd(250, 0, 1000.0, 'listener', 'STATE', 1, 2), 1, 2, 'STATE')}`; the ideal navigation: "
          f"`{shown(fleet_cmd(250, 0, 1000.0, 'listener', 'STATE', 1, 2, 'IDEAL.toml'), 1, 2, 'STATE')}` with "
          "IDEAL.toml one [[vehicle]] entry of instance 0, count 250, params = { RP_NAV_SRC = 0 }")


def fmt(xs, digits):
    xs = [x for x in xs if x is not None and x == x]
    if not xs:
        return "–"
    m = statistics.median(xs)
    if len(xs) == 1:
        return f"{m:.{digits}f}"
    return f"{m:.{digits}f} [{min(xs):.{digits}f}, {max(xs):.{digits}f}]"


def table(rows, title):
    if not rows:
        return
    print(f"\n### {title}\n")
    cols = ["vehicles", "processes", "links", "--speed", "runs", "reached factor (median vehicle)",
            "slowest vehicle", "M vehicle-steps/s (1 kHz)", "CPU % of a core", "listener CPU %", "RSS MB", "datagrams/s", "MB/s", "kernel drops", "lag warnings",
            "load avg"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for c, rs in rows:
        ok = [r for r in rs if "error" not in r]
        errs = sorted({r["error"] for r in rs if "error" in r})
        if not ok:
            print(f"| {c['n']} | {c['n'] if c['lone'] else 1} | {c['links']} | {c['speed']:g} | {len(rs)} | "
                  f"refused: {errs[0] if errs else '?'} |" + " |" * (len(cols) - 6))
            continue
        g = lambda k: [r[k] for r in ok]  # noqa: E731
        heard = min(g("heard"))
        print("| " + " | ".join([
            str(c["n"]), str(c["n"] if c["lone"] else 1), c["links"], f"{c['speed']:g}", str(len(ok)),
            fmt(g("factor"), 3), fmt(g("min_factor"), 3) + ("" if c["links"] != "listener" else f" ({heard} heard)"),
            fmt([c["n"] * f * STEP_HZ / 1e6 for f in g("factor")], 3), fmt(g("cpu_pct"), 1), fmt(g("client_pct"), 1), fmt(g("rss_mb"), 1), fmt(g("dgram_s"), 0), fmt(g("mb_s"), 2),
            fmt(g("drops"), 0), fmt(g("lag"), 0), fmt(g("load"), 2),
        ]) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=2, help="runs of each configuration (alternating)")
    ap.add_argument("--window", type=float, default=10.0, help="measuring window [s] of wall time")
    ap.add_argument("--warmup", type=float, default=3.0, help="wall seconds after start before measuring")
    ap.add_argument("--only", default="rt,mem,cpu,side", help="sections: rt, mem, cpu, side, goals")
    ap.add_argument("--compare", metavar="BINARY", help="goals: also run this binary, side by side")
    ap.add_argument("--quick", action="store_true", help="one run, 4 s windows, smaller fleets (a smoke test)")
    a = ap.parse_args()
    if a.quick:
        a.repeat, a.window, a.warmup = 1, 4.0, 2.0
    only = set(a.only.split(","))
    if not os.path.exists(binary()):
        sys.exit(f"no binary at {binary()}: cargo build --release (or set ROTORPILOT_BIN)")

    def cfg(n, speed, links, lone=False, first=None, section=""):
        if first is None:
            first = 100 if n <= 100 else 0
        return {"n": n, "first": first, "speed": speed, "links": links, "lone": lone, "section": section}

    if "goals" in only:
        goals([binary()] + ([a.compare] if a.compare else []), a.repeat, a.window, a.warmup)
        only.discard("goals")
        if not only:
            return

    big = [8] if a.quick else [64, 250]
    configs = []
    if "rt" in only:
        for n in big:
            for links in ("listener", "none"):
                for speed in (1.0, 1000.0):
                    configs.append(cfg(n, speed, links, section="rt"))
        for n in ([] if a.quick else [256, 1024]):
            for speed in (1.0, 1000.0):
                configs.append(cfg(n, speed, "none", section="rt", first=0))
    if "mem" in only:
        configs.append(cfg(1, 1.0, "listener", section="mem"))
        if "rt" not in only:
            configs += [cfg(n, 1.0, "listener", section="mem") for n in big]
    if "cpu" in only:
        configs.append(cfg(64, 1.0, "void", section="cpu"))
        if "rt" not in only or a.quick:
            configs += [cfg(64, 1.0, links, section="cpu") for links in ("listener", "none")]
    if "side" in only:
        for n in ([8] if a.quick else [8, 32, 64]):
            for lone in (True, False):
                configs.append(cfg(n, 1.0, "listener", lone=lone, section="side"))

    results = [[] for _ in configs]
    print(f"# rotorpilot fleet benchmarks: {binary()}", flush=True)
    print(f"# {os.cpu_count()} cores; {a.repeat} run(s) of each configuration, alternating; windows of "
          f"{a.window:g} s after {a.warmup:g} s", flush=True)
    for r in range(a.repeat):
        for k, c in enumerate(configs):
            res = measure(c, a.window, a.warmup)
            results[k].append(res)
            print(f"# run {r + 1}: {c['command']}\n#   -> {res}", file=sys.stderr, flush=True)

    rows = list(zip(configs, results))
    table([x for x in rows if x[0]["section"] == "rt" or (x[0]["section"] == "mem" and x[0]["n"] > 1)],
          "Real-time factor reached (one process; system ids stop at 250: instances 0..249)")
    by_n = {}
    for c, rs in rows:
        if not c["lone"] and c["links"] == "listener" and c["speed"] == 1.0:
            by_n.setdefault(c["n"], []).extend(r["rss_mb"] for r in rs if "rss_mb" in r)
    mem = sorted((n, statistics.median(v)) for n, v in by_n.items() if v)
    if len(mem) >= 2:
        xs, ys = [m[0] for m in mem], [m[1] for m in mem]
        mx, my = statistics.mean(xs), statistics.mean(ys)
        slope = sum((x - mx) * (y - my) for x, y in mem) / sum((x - mx) ** 2 for x in xs)
        print("\n### Memory (VmRSS, one process, API link to a listener, --speed 1)\n")
        print("| vehicles | RSS MB (median [range]) |\n|---|---|")
        for x, _ in mem:
            print(f"| {x} | {fmt(by_n[x], 1)} |")
        print(f"\nslope: {slope * 1024:.0f} kB per vehicle (least squares over {xs}); "
              f"intercept {my - slope * mx:.1f} MB")
    table([x for x in rows if x[0]["speed"] == 1.0 and x[0]["section"] in ("rt", "cpu") and x[0]["n"] == 64],
          "CPU of an idle fleet (on the ground, disarmed) at --speed 1")
    table([x for x in rows if x[0]["section"] == "side"],
          "Side by side: N processes `--instance k` versus one `--count N` (--speed 1, API links to a listener)")
    print("\n### Commands\n")
    seen = set()
    for c, _ in rows:
        if c["command"] not in seen:
            seen.add(c["command"])
            print(f"    {c['command']}")
    print(f"\nLISTENER: this script's UDP socket (counts datagrams; reads ATTITUDE.time_boot_ms per system id); "
          f"CLOSED: a closed port (streams into the void). Without links, the listener sends a HEARTBEAT to the "
          f"first vehicle's GCS port 18570+i each 0.5 s and reads that vehicle's clock.")


if __name__ == "__main__":
    main()
