#!/usr/bin/env python3
"""Time N short pytest tests (arm, take off to 5 m, land; pymavlink
through the `rotorpilot_mavlink` fixture) on a fresh vehicle each, then on
one shared vehicle (`@pytest.mark.rotorpilot(reuse=True)`), in the same run
on the same machine, and print both wall times, the per-test setup and
teardown, and the saving.

    python3 tools/bench_reuse.py [--tests 20] [--speed 10] [--rounds 1]

Needs the rotorpilot package with its pytest plugin (`pip install .`, or
PYTHONPATH=python with ROTORPILOT_BIN set), pymavlink and pytest.
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

TESTS = '''
import pytest
from pymavlink import mavutil

from rotorpilot import wait_message

pytestmark = pytest.mark.rotorpilot(speed={speed}, params={{"MIS_TAKEOFF_ALT": 5.0}}{reuse})


def recv(m, kind, cond=None, timeout=30.0):
    msg = wait_message(m, kind, cond, timeout)
    assert msg is not None, f"no {{kind}}"
    return msg


@pytest.mark.parametrize("i", range({n}))
def test_short_flight(rotorpilot_mavlink, i):
    m = rotorpilot_mavlink
    m.arducopter_arm()
    assert recv(m, "COMMAND_ACK", lambda a: a.command == 400).result == 0
    m.mav.command_long_send(m.target_system, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 0)
    recv(m, "GLOBAL_POSITION_INT", lambda g: g.relative_alt > 4500)
    m.mav.command_long_send(m.target_system, 1, mavutil.mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, 0, 0, 0, 0, 0)
    recv(m, "EXTENDED_SYS_STATE", lambda e: e.landed_state == 1, 60)  # on the ground
'''

DURATION = re.compile(r"^([0-9.]+)s (setup|call|teardown)\s+\S+", re.M)


def run(n, speed, reuse, workdir):
    path = os.path.join(workdir, f"test_{'shared' if reuse else 'fresh'}.py")
    with open(path, "w") as f:
        f.write(TESTS.format(n=n, speed=speed, reuse=", reuse=True" if reuse else ""))
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--durations=0", "--durations-min=0",
           path]
    t0 = time.monotonic()
    r = subprocess.run(cmd, cwd=workdir, capture_output=True, text=True, timeout=1800)
    wall = time.monotonic() - t0
    if r.returncode != 0 or f"{n} passed" not in r.stdout:
        sys.exit(f"pytest failed:\n{r.stdout[-4000:]}\n{r.stderr[-2000:]}")
    phases = {"setup": 0.0, "call": 0.0, "teardown": 0.0}
    for secs, phase in DURATION.findall(r.stdout):
        phases[phase] += float(secs)
    return wall, phases


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tests", type=int, default=20)
    ap.add_argument("--speed", type=float, default=10.0)
    ap.add_argument("--rounds", type=int, default=1, help="alternate fresh and shared this many times")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        for _ in range(a.rounds):
            results = {}
            for reuse in (False, True):
                results[reuse] = run(a.tests, a.speed, reuse, d)
                wall, p = results[reuse]
                print(f"{'shared (reuse=True)' if reuse else 'fresh vehicle each'}: {a.tests} tests in "
                      f"{wall:.2f} s wall; per test setup {p['setup'] / a.tests:.3f} s, "
                      f"call {p['call'] / a.tests:.3f} s, teardown {p['teardown'] / a.tests:.3f} s", flush=True)
            saved = results[False][0] - results[True][0]
            print(f"saved {saved:.2f} s of {results[False][0]:.2f} s ({100 * saved / results[False][0]:.0f} %), "
                  f"{saved / a.tests:.3f} s per test (speed {a.speed:g})")


if __name__ == "__main__":
    main()
