#!/usr/bin/env bash
# bench_rotorpy.sh: simulated steps per second of rotorpilot beside RotorPy
# 3.0.0 (the Python multirotor simulator of the cross-check, pinned in
# tests/rotorpy/requirements.txt), both at a 1 kHz step, measured in one run
# on one machine, and the ratio of the two.
#   rotorpilot  `rotorpilot simulate tools/scenarios/figure-eight-geometric.toml
#               --json`: the quad flying the 30 s figure-eight with the
#               geometric law, 30,000 steps. The time counted is the binary's
#               own `wall_time_s` (the flight's set-up and its stepping, timed
#               inside the process); the whole process, start-up included, is
#               timed as well and shown beside it.
#   RotorPy     `python tools/bench_rotorpy.py SECONDS`: RotorPy's own
#               Environment, Multirotor and SE3Control with its Hummingbird
#               parameters (the cross-check's airframe), following a circle of
#               radius 2 m at 0.5 rad/s (the figure-eight's half-width and
#               rate) at sim_rate 1000, for ROTORPY_SECONDS simulated seconds
#               (4 by default: it steps at about real time, so a 30 s flight
#               would take the whole budget); RotorPy's defaults for the rest
#               (no wind, noisy IMU and motion capture every step, the null
#               estimator, rotor aerodynamics, scipy's RK45 over each step).
#               The time counted is around `sim.run(...)` alone (its loop and
#               the packing of its results), not the imports or the set-up;
#               the whole Python process is timed as well.
# Steps per second = steps of a run / its counted time; the runs alternate
# (rotorpilot, RotorPy, rotorpilot, ...) so that a change in the machine's
# load falls on both; the figures are the medians of the runs and the ratio
# is rotorpilot's median over RotorPy's. The two steps do not do the same
# work (each simulator's sensors, controller and integrator are its own),
# so the ratio compares the simulators as shipped, not the same arithmetic.
# The load average before and after and the number of cores are printed with
# the table: wall times move with the load.
#
# RotorPy lives in the venv .venv/rotorpy (the cross-check's, made from
# tests/rotorpy/requirements.txt when missing, as tools/test-all.sh does);
# VENV=DIR uses DIR/rotorpy instead. ROTORPILOT_RUNS (5), ROTORPY_RUNS (3)
# and ROTORPY_SECONDS (4) change the runs.
set -euo pipefail
cd "$(dirname "$0")/.."

SCENARIO=tools/scenarios/figure-eight-geometric.toml
ROTORPILOT_RUNS="${ROTORPILOT_RUNS:-5}"
ROTORPY_RUNS="${ROTORPY_RUNS:-3}"
ROTORPY_SECONDS="${ROTORPY_SECONDS:-4}"
PY="${PYTHON:-python3}"
VENV="${VENV:-$PWD/.venv}"

# the RotorPy venv, made as tools/test-all.sh makes its client venvs; pip
# only installs what is missing
if [ ! -x "$VENV/rotorpy/bin/python" ]; then
    if ! "$PY" -m venv "$VENV/rotorpy" 2>/dev/null; then
        # Debian's python3 ships venv separately
        if command -v apt-get >/dev/null; then
            apt-get install -y -qq python3-venv >/dev/null 2>&1 || { apt-get update -qq && apt-get install -y -qq python3-venv; }
        fi
        rm -rf "${VENV:?}/rotorpy"
        "$PY" -m venv "$VENV/rotorpy"
    fi
fi
"$VENV/rotorpy/bin/python" -m pip install -q --disable-pip-version-check -r tests/rotorpy/requirements.txt
rpy="$VENV/rotorpy/bin/python"

cargo build --release --quiet --bin rotorpilot
bin="${CARGO_TARGET_DIR:-$PWD/target}/release/rotorpilot"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

rotorpilot_cmd="$bin simulate $SCENARIO --json"
rotorpy_cmd="$rpy tools/bench_rotorpy.py $ROTORPY_SECONDS"

# seconds since the epoch, microseconds (bash 5's EPOCHREALTIME)
[ -n "${EPOCHREALTIME:-}" ] || { echo "bench_rotorpy.sh: needs bash 5 or later (EPOCHREALTIME)" >&2; exit 2; }
now() { printf '%s' "$EPOCHREALTIME"; }

load_before=$(cut -d' ' -f1-3 /proc/loadavg)
: >"$tmp/runs"  # one line a run: TOOL STEPS COUNTED_S PROCESS_S
runs=$(( ROTORPILOT_RUNS > ROTORPY_RUNS ? ROTORPILOT_RUNS : ROTORPY_RUNS ))
for (( i = 1; i <= runs; i++ )); do
    if (( i <= ROTORPILOT_RUNS )); then
        t0=$(now)
        "$bin" simulate "$SCENARIO" --json >"$tmp/out.json"
        t1=$(now)
        read -r steps counted < <("$rpy" -c 'import json,sys; d=json.load(open(sys.argv[1])); print(d["steps"], d["wall_time_s"])' "$tmp/out.json")
        proc=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.6f", b - a }')
        echo "rotorpilot run $i: $steps steps, wall_time_s $counted s, process $proc s"
        echo "rotorpilot $steps $counted $proc" >>"$tmp/runs"
    fi
    if (( i <= ROTORPY_RUNS )); then
        t0=$(now)
        read -r steps counted < <("$rpy" tools/bench_rotorpy.py "$ROTORPY_SECONDS")
        t1=$(now)
        proc=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.6f", b - a }')
        echo "RotorPy    run $i: $steps steps, sim.run $counted s, process $proc s"
        echo "rotorpy $steps $counted $proc" >>"$tmp/runs"
    fi
done
load_after=$(cut -d' ' -f1-3 /proc/loadavg)

echo
"$rpy" - "$tmp/runs" "$ROTORPY_SECONDS" <<'EOF'
import statistics
import sys

runs = {"rotorpilot": [], "rotorpy": []}
for line in open(sys.argv[1]):
    tool, steps, counted, proc = line.split()
    runs[tool].append((int(steps), float(counted), float(proc)))


def medians(tool):
    r = runs[tool]
    return (statistics.median(s for s, _, _ in r),
            statistics.median(c for _, c, _ in r),
            statistics.median(s / c for s, c, _ in r),
            statistics.median(p for _, _, p in r),
            statistics.median(s / p for s, _, p in r))


ours, theirs = medians("rotorpilot"), medians("rotorpy")
print("| simulator | flight | runs | steps a run | median counted time [s] "
      "| median steps/s (counted) | median process time [s] | median steps/s (process) |")
print("|---|---|---|---|---|---|---|---|")
print(f"| rotorpilot | quad, geometric, figure-eight, 30 s | {len(runs['rotorpilot'])} "
      f"| {ours[0]:,.0f} | {ours[1]:.4f} (`wall_time_s`) | {ours[2]:,.0f} | {ours[3]:.4f} | {ours[4]:,.0f} |")
print(f"| RotorPy 3.0.0 | Hummingbird, SE3Control, circle, {sys.argv[2]} s | {len(runs['rotorpy'])} "
      f"| {theirs[0]:,.0f} | {theirs[1]:.3f} (`sim.run`) | {theirs[2]:,.0f} | {theirs[3]:.3f} | {theirs[4]:,.0f} |")
print()
print(f"ratio of the medians, rotorpilot / RotorPy steps/s (counted time): {ours[2] / theirs[2]:,.0f}x")
print(f"the same on whole-process time (start-up and imports included):     {ours[4] / theirs[4]:,.0f}x")
EOF
echo
echo "counted time: rotorpilot's own wall_time_s from its JSON (the flight's set-up and stepping, not"
echo "process start, reading the file or printing); RotorPy's time around sim.run (not the imports)."
echo "The load average is the kernel's running mean: \"before\" still carries any build just done above."
echo
echo "| machine | |"
echo "|---|---|"
echo "| nproc | $(nproc) |"
echo "| CPU | $(sed -n 's/^model name[[:space:]]*: //p' /proc/cpuinfo | head -n 1) |"
echo "| load average (1, 5, 15 min) before | $load_before |"
echo "| load average (1, 5, 15 min) after | $load_after |"
echo "| rotorpilot command | \`$rotorpilot_cmd\` |"
echo "| RotorPy command | \`$rotorpy_cmd\` |"
echo "| RotorPy | $("$rpy" -c 'import importlib.metadata as m; print(m.version("rotorpy"), "numpy", m.version("numpy"), "scipy", m.version("scipy"))'), Python $("$rpy" -c 'import platform; print(platform.python_version())') |"
