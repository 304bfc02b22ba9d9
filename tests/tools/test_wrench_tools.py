"""tools/show_wrench.py and tools/inject_disturbance.py as a new user meets
them: on the ground the live estimate is held, and show_wrench says
so instead of printing zeros against a non-zero truth; it never prints a
truth it has not heard as 0.000; inject_disturbance checks every value first
and changes all or nothing. Against rotorpilot itself, and the printed lines
from known inputs.

Run by tools/test-all.sh with the pymavlink venv (pymavlink 2.4.50, pytest).
"""
import os
import re
import subprocess
import sys

os.environ.setdefault("MAVLINK20", "1")

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TOOLS = os.path.join(ROOT, "tools")
sys.path.insert(0, TOOLS)
sys.path.insert(0, os.path.join(ROOT, "tests", "clients"))

import inject_disturbance  # noqa: E402
import show_wrench  # noqa: E402
from harness import Vehicle  # noqa: E402

EST = {"EST_FORCE": (0.0, 0.0, 0.0), "EST_TORQUE": (0.0, 0.0, 0.0), "EST_MASS": 2.0, "time": 3.0}
TRUTH = {"SIM_FORCE": (1.0, 0.0, 0.0), "SIM_TORQUE": (0.0, 0.0, 0.2), "SIM_MASS": 2.5}


def test_on_the_ground_the_estimate_line_says_held():
    est, truth = show_wrench.lines({**EST, **TRUTH, "landed": show_wrench.ON_GROUND})
    assert "on the ground: estimator held" in est
    assert "0.000" not in est
    assert "1.000" in truth and "2.500" in truth
    # in the air (MAV_LANDED_STATE_IN_AIR = 2) the numbers are shown
    est, _ = show_wrench.lines({**EST, **TRUTH, "landed": 2})
    assert "held" not in est and "0.000" in est


def test_a_truth_not_heard_is_unknown_not_zero():
    est, truth = show_wrench.lines(dict(EST))
    assert "0.000" not in truth
    assert truth.count("unknown") == 3


def run_tool(name, *args, timeout=30):
    return subprocess.run([sys.executable, os.path.join(TOOLS, name), *args],
                          capture_output=True, text=True, timeout=timeout)


def test_show_wrench_on_a_resting_vehicle():
    with Vehicle(speed=5) as v:
        r = run_tool("show_wrench.py", "--connect", f"udpin:127.0.0.1:{v.gcs_port}", "--duration", "6",
                     "--print-hz", "4")
    assert r.returncode == 0, r.stderr
    rows = r.stdout.splitlines()[1:]
    est = [line for line in rows if " est " in line]
    truth = [line for line in rows if " truth " in line]
    assert est and truth, r.stdout
    assert all("on the ground: estimator held" in line for line in est), r.stdout
    # the default quad's true mass, from the first line on
    assert all(line.rstrip().endswith("2.000") for line in truth), r.stdout


def params(port):
    r = run_tool("inject_disturbance.py", "--connect", f"udpin:127.0.0.1:{port}")
    assert r.returncode == 0, r.stderr
    return {m.group(1): float(m.group(2)) for m in re.finditer(r"^\s+(\w+)\s+(-?[\d.]+)$", r.stdout, re.M)}


def test_inject_changes_all_or_nothing():
    with Vehicle(speed=5) as v:
        port = str(v.gcs_port)
        r = run_tool("inject_disturbance.py", "--connect", f"udpin:127.0.0.1:{port}", "--force", "500,1,1",
                     "--torque", "0,0,0.5")
        assert r.returncode == 2, r.stdout + r.stderr
        assert "nothing changed" in r.stderr and "SIM_FEXT_X = 500 N" in r.stderr and "[-50, 50] N" in r.stderr
        p = params(port)
        assert [p[n] for n in ("SIM_FEXT_X", "SIM_FEXT_Y", "SIM_FEXT_Z", "SIM_TEXT_Z")] == [0.0] * 4, p
        r = run_tool("inject_disturbance.py", "--connect", f"udpin:127.0.0.1:{port}", "--force", "1,2,0",
                     "--torque", "0,0,0.5")
        assert r.returncode == 0, r.stdout + r.stderr
        p = params(port)
        assert [p[n] for n in ("SIM_FEXT_X", "SIM_FEXT_Y", "SIM_FEXT_Z", "SIM_TEXT_Z")] == [1.0, 2.0, 0.0, 0.5], p


def test_the_ranges_are_the_parameter_tables():
    with open(os.path.join(ROOT, "src", "params", "table.rs")) as f:
        table = f.read()
    for name, (lo, hi, unit) in inject_disturbance.RANGES.items():
        m = re.search(rf"\b{name}: real\(\s*([-\d.]+),\s*([-\d.]+),\s*([-\d.]+),\s*\"([^\"]*)\"", table)
        assert m, name
        assert (float(m.group(2)), float(m.group(3)), m.group(4)) == (lo, hi, unit), name
