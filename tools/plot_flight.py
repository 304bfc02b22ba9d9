#!/usr/bin/env python3
"""Plot a rotorpilot flight (the CSV of `rotorpilot simulate --csv` or of a
daemon's `--log-csv`, or a kept flight's `flight.record`) as PNG figures like
the origin report's: the north/east path, position and velocity errors,
attitude (roll and pitch as flown, heading error: the log has no roll/pitch
setpoint), angular-velocity error, thrust and torques.

    rotorpilot simulate tools/scenarios/fsr-exercise5.toml --csv flight.csv
    python3 tools/plot_flight.py flight.csv --out figures/
    python3 tools/plot_flight.py logs/2026-12-02T03-27-51Z-i0/flight.record --out figures/

A flight record (the pytest plugin keeps one per failed test; it has no CSV)
is replayed first with `rotorpilot replay RECORD --csv` into a temporary
file: the executable is --rotorpilot, else $ROTORPILOT_BIN, else `rotorpilot`
on the PATH. Frames: NED world, FRD body; SI units. Needs matplotlib.
"""
import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_log(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if len(rows) < 2:
        sys.exit(f"{path}: no data rows")
    header = rows[0]
    cols = {name: [] for name in header}
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            sys.exit(f"{path}:{line}: {len(row)} fields, the header has {len(header)}")
        for name, value in zip(header, row):
            cols[name].append(float(value))
    return cols


def is_record(path):
    """A flight record's first line is its JSON header: {"header": {"format": "rotorpilot-flight-record", ...}}."""
    try:
        with open(path, "rb") as f:
            first = f.readline(1 << 20)
        return json.loads(first)["header"]["format"] == "rotorpilot-flight-record"
    except (OSError, ValueError, KeyError, TypeError):
        return False


def replayed_csv(record, exe, into):
    """`rotorpilot replay RECORD --csv` into the directory `into`: the CSV's path."""
    exe = exe or os.environ.get("ROTORPILOT_BIN") or shutil.which("rotorpilot")
    if not exe:
        sys.exit(f"{record}: a flight record is replayed to plot it: give --rotorpilot PATH, "
                 "set ROTORPILOT_BIN, or put rotorpilot on the PATH")
    out = os.path.join(into, "flight.csv")
    r = subprocess.run([exe, "replay", record, "--csv", out], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"{record}: rotorpilot replay failed (status {r.returncode}):\n{r.stderr.strip()}")
    return out


def need(cols, path, *names):
    for n in names:
        if n not in cols:
            sys.exit(f"{path}:1: missing column `{n}`")


def wrap(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def figure(title, t, series, ylabel, out):
    fig, axes = plt.subplots(len(series), 1, sharex=True, figsize=(8, 2.2 * len(series)))
    if len(series) == 1:
        axes = [axes]
    for ax, (label, ys) in zip(axes, series):
        for name, y in ys:
            ax.plot(t, y, label=name, linewidth=1)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("time [s]")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def path_figure(c, out):
    """The north/east path (NED world, seen from above: north up, east
    right), as flown and as referenced, with where it started and ended."""
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(c["ref_e"], c["ref_n"], label="reference", linewidth=1, linestyle="--")
    ax.plot(c["true_pos_e"], c["true_pos_n"], label="flown", linewidth=1)
    ax.plot(c["true_pos_e"][:1], c["true_pos_n"][:1], "o", label="start")
    ax.plot(c["true_pos_e"][-1:], c["true_pos_n"][-1:], "s", label="end")
    ax.set_xlabel("east [m]")
    ax.set_ylabel("north [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    ax.set_title("path, north/east (NED)")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("log", help="flight CSV (`rotorpilot simulate --csv`, `--log-csv`) or a flight.record")
    p.add_argument("--out", default=".", help="directory for the PNG files")
    p.add_argument("--rotorpilot", metavar="PATH", help="the rotorpilot executable that replays a flight record")
    a = p.parse_args()
    if is_record(a.log):
        with tempfile.TemporaryDirectory() as tmp:
            c = read_log(replayed_csv(a.log, a.rotorpilot, tmp))
    else:
        c = read_log(a.log)
    need(c, a.log, "time_s", "true_pos_n", "true_pos_e", "true_pos_d", "ref_n", "ref_e", "ref_d", "ref_yaw",
         "true_vel_n", "true_vel_e", "true_vel_d", "roll", "pitch", "yaw", "p_frd", "q_frd", "r_frd",
         "thrust_n", "tau_x", "tau_y", "tau_z")
    os.makedirs(a.out, exist_ok=True)
    t = c["time_s"]
    # finite-difference reference velocity (the log carries the reference position)
    def diff(y):
        return [0.0] + [(y[k] - y[k - 1]) / (t[k] - t[k - 1]) for k in range(1, len(y))]
    axes = ("n", "e", "d")
    e_p = [[c[f"true_pos_{x}"][k] - c[f"ref_{x}"][k] for k in range(len(t))] for x in axes]
    e_v = [[c[f"true_vel_{x}"][k] - v for k, v in enumerate(diff(c[f"ref_{x}"]))] for x in axes]
    out = [path_figure(c, os.path.join(a.out, "path_ne.png"))]
    out.append(figure("position error e_p = p - p_d", t,
                      [(f"e_{x} [m]", [(f"e_p,{x}", e_p[i])]) for i, x in enumerate(axes)],
                      "m", os.path.join(a.out, "position_error.png")))
    out.append(figure("velocity error e_v = v - v_d", t,
                      [(f"e_v,{x} [m/s]", [(f"e_v,{x}", e_v[i])]) for i, x in enumerate(axes)],
                      "m/s", os.path.join(a.out, "velocity_error.png")))
    yaw_err = [wrap(y - r) for y, r in zip(c["yaw"], c["ref_yaw"])]
    # roll and pitch as flown, not an error: the log has no roll/pitch setpoint (only ref_yaw)
    out.append(figure("attitude: roll and pitch as flown, heading error", t,
                      [("roll [rad]", [("roll", c["roll"])]), ("pitch [rad]", [("pitch", c["pitch"])]),
                       ("yaw - yaw_d [rad]", [("e_yaw", yaw_err)])],
                      "rad", os.path.join(a.out, "attitude.png")))
    yaw_rate_ref = diff([math.atan2(math.sin(y), math.cos(y)) for y in c["ref_yaw"]])
    out.append(figure("angular velocity (body FRD)", t,
                      [("p [rad/s]", [("p", c["p_frd"])]), ("q [rad/s]", [("q", c["q_frd"])]),
                       ("r [rad/s]", [("r", c["r_frd"]), ("yaw_d'", yaw_rate_ref)])],
                      "rad/s", os.path.join(a.out, "angular_velocity.png")))
    out.append(figure("thrust and body torques", t,
                      [("u_T [N]", [("u_T", c["thrust_n"])]), ("tau_x [N m]", [("tau_x", c["tau_x"])]),
                       ("tau_y [N m]", [("tau_y", c["tau_y"])]), ("tau_z [N m]", [("tau_z", c["tau_z"])])],
                      "N", os.path.join(a.out, "inputs.png")))
    for f in out:
        print(f)


if __name__ == "__main__":
    main()
