#!/usr/bin/env python3
"""The cost of `--log-dir`: simulation-thread CPU per step of a hovering
vehicle with and without logs, and the bytes each log file grows by per
simulated minute.

    python tools/bench_logs.py [--speeds 1 20] [--hover-s 60 600]

For each speed (with its simulated hover time) and with/without logs: start
the real binary ($ROTORPILOT_BIN), arm and take off to 3 m with pymavlink,
then over the hover read the simulation thread's user+system CPU from
/proc/PID/task/TID/stat (the thread named `rotorpilot-sim`; clock ticks),
the whole process's from /proc/PID/stat (the link tasks write the .tlogs),
and the simulated time from ATTITUDE.time_boot_ms. Linux only; needs the
pymavlink venv. The machine's other load shows in the figures.
"""

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "clients"))
from harness import Vehicle, wait_message  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
TICK = os.sysconf("SC_CLK_TCK")


def sim_thread_cpu_s(pid):
    for task in Path(f"/proc/{pid}/task").iterdir():
        stat = (task / "stat").read_text()
        name = stat[stat.index("(") + 1 : stat.rindex(")")]
        if name == "rotorpilot-sim":
            fields = stat[stat.rindex(")") + 2 :].split()
            return (int(fields[11]) + int(fields[12])) / TICK
    raise RuntimeError("no rotorpilot-sim thread")


def process_cpu_s(pid):
    stat = Path(f"/proc/{pid}/stat").read_text()
    fields = stat[stat.rindex(")") + 2 :].split()
    return (int(fields[11]) + int(fields[12])) / TICK


def wait(m, kind, cond=None, timeout=10.0):
    msg = wait_message(m, kind, cond, timeout)
    if msg is None:
        raise RuntimeError(f"no {kind}")
    return msg


def sim_s(m):
    while m.recv_match(blocking=False) is not None:
        pass
    return wait(m, "ATTITUDE").time_boot_ms / 1000.0


def run(speed, hover_s, logs):
    extra = []
    base = None
    if logs:
        base = tempfile.mkdtemp(prefix="rotorpilot-bench-logs-")
        extra = ["--log-dir", base]
    v = Vehicle(speed=speed, extra=extra).start()
    try:
        pid = v.proc.pid
        m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=255)
        m.wait_heartbeat(timeout=5)
        wait(m, "SYS_STATUS", lambda s: s.onboard_control_sensors_health & 0x10000000)
        m.mav.command_long_send(m.target_system, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0)
        wait(m, "COMMAND_ACK", lambda a: a.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM)
        m.mav.command_long_send(m.target_system, 1, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 0)
        wait(m, "EXTENDED_SYS_STATE", lambda e: e.landed_state == 2, 30)
        wait(m, "GLOBAL_POSITION_INT", lambda g: g.relative_alt > 2000, 60)
        t0, c0, p0 = sim_s(m), sim_thread_cpu_s(pid), process_cpu_s(pid)
        while sim_s(m) - t0 < hover_s:
            time.sleep(0.2)
        t1, c1, p1 = sim_s(m), sim_thread_cpu_s(pid), process_cpu_s(pid)
        steps = (t1 - t0) / 0.001
        total_sim = t1
    finally:
        v.stop()
        v.cleanup()
    sizes = {}
    if base:
        run_dir = next(Path(base).iterdir())
        sizes = {p.name: p.stat().st_size * 60.0 / total_sim for p in sorted(run_dir.iterdir())}
    return (c1 - c0) / steps * 1e6, (c1 - c0), t1 - t0, sizes, (p1 - p0) / steps * 1e6


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--speeds", type=float, nargs="+", default=[1.0, 20.0])
    ap.add_argument("--hover-s", type=float, nargs="+", default=[60.0, 600.0])
    a = ap.parse_args()
    for speed, hover in zip(a.speeds, a.hover_s):
        for logs in (False, True):
            us, cpu, sim, sizes, proc_us = run(speed, hover, logs)
            what = "with logs   " if logs else "without logs"
            print(
                f"x{speed:g} {what}: sim thread {us:.2f} us CPU/step ({cpu:.2f} s over {sim:.1f} s simulated); "
                f"whole process {proc_us:.2f} us/step"
            )
            for name, b in sizes.items():
                print(f"    {name}: {b / 1024:.0f} KiB per simulated minute")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
