#!/usr/bin/env python3
"""Measure flight records and replay:

1. `flight`: fly a ~5-minute (simulated) flight at --speed 20 with --log-dir
   and --log-csv (takeoff, a minute of streamed offboard velocity setpoints,
   eight repositions around a 40 m square, land), stop it with SIGTERM, then
   time `rotorpilot replay` on its record with and without --csv (best of 3)
   and check the replayed CSV against the live flight.csv byte for byte.
2. `cost`: the simulation thread's CPU time per step of a vehicle hovering
   at speed 1 for HOVER seconds, without logs, with --log-dir, and with
   --log-dir --log-csv (on-CPU time of the `rotorpilot-sim` thread from
   /proc/PID/task/TID/schedstat, ns).

    cargo build --release && python3 tools/bench_replay.py flight
    python3 tools/bench_replay.py cost --hover 20 --rounds 2
Needs pymavlink. Linux only (/proc).
"""

import argparse
import atexit
import glob
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pymavlink import mavutil

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "python"))
from rotorpilot import binary, free_udp_port  # noqa: E402


class Vehicle:
    """A rotorpilot on instance `inst`, its GCS link sending to a pymavlink client."""

    def __init__(self, inst, speed, extra):
        self.dir = tempfile.mkdtemp(prefix="rotorpilot-bench-")
        gcs = free_udp_port()  # reserved for this process (rotorpilot.reserve_port)
        args = [binary(), "--instance", str(inst), "--speed", str(speed), "--state-dir", self.dir + "/st",
                "--gcs-remote", f"127.0.0.1:{gcs}", "--api-remote", "none"] + extra
        self.p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        atexit.register(lambda: self.p.poll() is None and self.p.kill())
        for line in self.p.stdout:
            if "parameters:" in line:
                break
        self.m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{gcs}", source_system=255)
        self.m.wait_heartbeat(timeout=10)
        self.speed = speed

    def hb(self):
        self.m.mav.heartbeat_send(6, 8, 0, 0, 0)

    def cmd(self, c, *ps):
        ps = list(ps) + [0] * (7 - len(ps))
        for _ in range(3):
            self.m.mav.command_long_send(self.m.target_system, 1, c, 0, *ps)
            while True:
                a = self.m.recv_match(type="COMMAND_ACK", blocking=True, timeout=3)
                if a is None:
                    break
                if a.command == c:
                    return a.result
        raise RuntimeError(f"no COMMAND_ACK for {c}")

    def wait(self, sim_s):
        end = time.monotonic() + sim_s / self.speed
        while time.monotonic() < end:
            self.hb()
            time.sleep(0.05)

    def take_off(self):
        self.hb()
        time.sleep(0.5)
        assert self.cmd(400, 1) == 0, "arm"
        assert self.cmd(22) == 0, "takeoff"

    def stop(self):
        self.p.send_signal(signal.SIGTERM)
        self.p.wait(10)

    def sim_cpu_s(self):
        for t in glob.glob(f"/proc/{self.p.pid}/task/*"):
            if open(t + "/comm").read().strip() == "rotorpilot-sim":
                return int(open(t + "/schedstat").read().split()[0]) / 1e9
        raise RuntimeError("no rotorpilot-sim thread")


def flight(args):
    logs = tempfile.mkdtemp(prefix="rotorpilot-bench-logs-")
    v = Vehicle(args.instance, 20.0, ["--log-dir", logs, "--log-csv"])
    v.take_off()
    v.wait(15)
    t0 = time.monotonic()
    offboard = False
    while (time.monotonic() - t0) * v.speed < 60:
        a = (time.monotonic() - t0) * v.speed * 0.2
        # velocity and yaw rate in LOCAL_NED: a 3 m/s circle
        v.m.mav.set_position_target_local_ned_send(0, v.m.target_system, 1, 1, 0b0000_0101_1100_0111, 0, 0, 0,
                                                   3 * math.cos(a), 3 * math.sin(a), 0, 0, 0, 0, 0, 0.2)
        if not offboard and (time.monotonic() - t0) * v.speed > 1:
            assert v.cmd(176, 1, 6, 0) == 0, "offboard mode"
            offboard = True
        v.hb()
        time.sleep(0.02)
    lat0, lon0 = 47.397742, 8.545594
    for n, e in [(40, 0), (40, 40), (0, 40), (0, 0)] * 2:
        lat = int((lat0 + n / 111111.0) * 1e7)
        lon = int((lon0 + e / (111111.0 * math.cos(math.radians(lat0)))) * 1e7)
        v.m.mav.command_int_send(v.m.target_system, 1, 0, 192, 0, 0, -1, 1, 0, float("nan"), lat, lon, 500.0)
        v.wait(25)
    v.cmd(21)
    v.wait(30)
    v.stop()
    run = glob.glob(logs + "/*")[0]
    record = os.path.join(run, "flight.record")
    for csv in (False, True):
        best = None
        for _ in range(3):
            out = [binary(), "replay", record, "--json"] + (["--csv", run + "/replay.csv"] if csv else [])
            t = time.monotonic()
            r = subprocess.run(out, capture_output=True, text=True, check=True)
            wall = time.monotonic() - t
            best = wall if best is None else min(best, wall)
        import json
        s = json.loads(r.stdout)
        print(f"replay{' --csv' if csv else ''}: {s['steps']} steps ({s['sim_time_s']:.1f} s simulated), "
              f"{s['inputs']} inputs: best {best:.3f} s wall for the whole command "
              f"({s['steps'] / best:.0f} steps/s)")
    same = Path(run, "replay.csv").read_bytes() == Path(run, "flight.csv").read_bytes()
    print(f"replayed CSV == live flight.csv: {same} ({os.path.getsize(run + '/flight.csv')} bytes); "
          f"record {os.path.getsize(record)} bytes")
    shutil.rmtree(logs, ignore_errors=True)
    shutil.rmtree(v.dir, ignore_errors=True)
    return 0 if same else 1


def cost(args):
    for _ in range(args.rounds):
        for mode, extra in [("no logs", []), ("--log-dir", ["--log-dir", "L"]),
                            ("--log-dir --log-csv", ["--log-dir", "L", "--log-csv"])]:
            d = tempfile.mkdtemp(prefix="rotorpilot-bench-")
            extra = [x if x != "L" else d for x in extra]
            v = Vehicle(args.instance, 1.0, extra)
            v.take_off()
            v.wait(5)  # climb
            c0, t0 = v.sim_cpu_s(), time.monotonic()
            v.wait(args.hover)
            c1, t1 = v.sim_cpu_s(), time.monotonic()
            v.stop()
            steps = (t1 - t0) / 0.001
            print(f"{mode:>20}: simulation thread {c1 - c0:.3f} s on CPU over {t1 - t0:.1f} s hovering "
                  f"= {(c1 - c0) / steps * 1e6:.2f} us/step")
            shutil.rmtree(d, ignore_errors=True)
            shutil.rmtree(v.dir, ignore_errors=True)
    return 0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="what", required=True)
    f = sub.add_parser("flight")
    f.add_argument("--instance", type=int, default=43)
    c = sub.add_parser("cost")
    c.add_argument("--instance", type=int, default=44)
    c.add_argument("--hover", type=float, default=20.0)
    c.add_argument("--rounds", type=int, default=1)
    a = ap.parse_args()
    return flight(a) if a.what == "flight" else cost(a)


if __name__ == "__main__":
    sys.exit(main())
