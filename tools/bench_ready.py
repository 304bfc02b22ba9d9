#!/usr/bin/env python3
"""Start-to-ready time of a rotorpilot vehicle, as a client sees it.

For each run: start the daemon on free loopback ports (as the pytest fixture
does), listen where its API link sends (pymavlink `udpin`), and stop the
clock when both have arrived: a SYS_STATUS whose health word has every
present sensor bit and MAV_SYS_STATUS_PREARM_CHECK set, and a HOME_POSITION.
The clock starts just before the process is spawned, so the figure includes
exec, loading, binding and the first simulated steps. Also reported: the
daemon's own figure from its `rotorpilot: ready to arm (T s after start)` line.

    python3 tools/bench_ready.py                    # 20 runs at speed 1 and 20
    python3 tools/bench_ready.py --runs 50 --speeds 1,5,20 --bin target/release/rotorpilot

Needs pymavlink. The binary: --bin, else $ROTORPILOT_BIN, else the
installed one, else target/release/rotorpilot (see rotorpilot.binary).
"""

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "python"))
from pymavlink import mavutil  # noqa: E402

from rotorpilot import binary, free_udp_port  # noqa: E402
from rotorpilot.vehicle import READY_LINE  # noqa: E402

PREARM_CHECK = 0x1000_0000


def one_run(exe, speed, timeout=10.0):
    """(client-seen seconds, the daemon's own seconds) for one start."""
    port = free_udp_port()
    # bind before the daemon starts, so no early datagram is lost
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=255)
    with tempfile.TemporaryDirectory(prefix="rotorpilot-bench-") as d:
        args = [exe, "--speed", str(speed), "--api-bind", "127.0.0.1:0", "--api-remote", f"127.0.0.1:{port}",
                "--gcs-bind", "127.0.0.1:0", "--gcs-remote", "none", "--state-dir", d]
        t0 = time.monotonic()
        proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        try:
            healthy = home = False
            deadline = t0 + timeout
            while not (healthy and home):
                if time.monotonic() > deadline:
                    raise RuntimeError(f"not ready within {timeout} s (speed {speed})")
                msg = m.recv_match(type=["SYS_STATUS", "HOME_POSITION"], blocking=True, timeout=0.5)
                if msg is None:
                    continue
                if msg.get_type() == "HOME_POSITION":
                    home = True
                else:
                    present = msg.onboard_control_sensors_present
                    healthy = (msg.onboard_control_sensors_health & present) == present and bool(
                        msg.onboard_control_sensors_health & PREARM_CHECK)
            seen = time.monotonic() - t0
        finally:
            proc.terminate()
            out, _ = proc.communicate(timeout=10)
            m.close()
    own = READY_LINE.search(out or "")
    return seen, float(own.group(1)) if own else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=20)
    ap.add_argument("--speeds", default="1,20", help="comma-separated speed factors (default 1,20)")
    ap.add_argument("--bin", help="the rotorpilot executable")
    a = ap.parse_args()
    exe = binary(a.bin)
    print(f"{exe}: start to ready to arm (SYS_STATUS health + PREARM_CHECK and HOME_POSITION at the client), "
          f"{a.runs} runs each")
    print(f"{'speed':>6} {'median s':>9} {'max s':>7} {'min s':>7}   {'daemon median s':>15}")
    worst = 0.0
    for speed in (float(s) for s in a.speeds.split(",")):
        runs = [one_run(exe, speed) for _ in range(a.runs)]
        seen = [r[0] for r in runs]
        own = [r[1] for r in runs]
        worst = max(worst, max(seen))
        print(f"{speed:>6g} {statistics.median(seen):>9.3f} {max(seen):>7.3f} {min(seen):>7.3f}   "
              f"{statistics.median(own):>15.4f}")
    return 0 if worst < 0.5 else 1


if __name__ == "__main__":
    sys.exit(main())
