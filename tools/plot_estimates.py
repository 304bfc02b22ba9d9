#!/usr/bin/env python3
"""Plot the momentum-based estimator's results like the origin report's
exercise 4: for each chosen order, the estimated wrench, the estimate against
the applied disturbance, and the estimation error; plus one figure comparing
the orders.

    rotorpilot simulate tools/scenarios/fsr-exercise4.toml --csv ex4.csv
    rotorpilot estimate ex4.csv --order 1,3,5,20 --poly butterworth,binomial
    python3 tools/plot_estimates.py ex4.csv ex4-estimates.csv --orders 1,5,20 --out figures/

The flight CSV supplies the applied disturbance (fext_*, text_z, true_mass_kg)
and the estimator's nominal mass is taken from --nominal-mass, by default from
the flight's sidecar FLIGHT.meta.json (`nominal_mass_kg`, docs/logs.md), else
1.5 kg (the report's fsr-quad) with a warning. Force in NED [N], torque in
FRD [N m]. Needs matplotlib.
"""
import argparse
import csv
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

G = 9.81


def read(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if len(rows) < 2:
        sys.exit(f"{path}: no data rows")
    header = rows[0]
    cols = {h: [] for h in header}
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            sys.exit(f"{path}:{line}: {len(row)} fields, the header has {len(header)}")
        for h, v in zip(header, row):
            cols[h].append(float(v))
    return cols


FALLBACK_NOMINAL_MASS_KG = 1.5


def nominal_mass(flight, given):
    """The estimator's nominal mass [kg]: `given`, else the flight's sidecar's, else the fallback (warned)."""
    if given is not None:
        return given
    meta = flight + ".meta.json"
    try:
        with open(meta) as f:
            return float(json.load(f)["nominal_mass_kg"])
    except FileNotFoundError:
        print(f"plot_estimates.py: warning: {flight} has no sidecar {meta}: assuming the nominal mass "
              f"{FALLBACK_NOMINAL_MASS_KG} kg (fsr-quad); give --nominal-mass KG", file=sys.stderr)
        return FALLBACK_NOMINAL_MASS_KG
    except (OSError, ValueError, KeyError, TypeError) as e:
        sys.exit(f"{meta}: cannot read nominal_mass_kg: {e}")


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("flight", help="flight CSV (truth columns)")
    p.add_argument("estimates", help="CSV written by `rotorpilot estimate`")
    p.add_argument("--orders", default="1,5,20", help="orders to draw, comma-separated")
    p.add_argument("--poly", default="butterworth", help="butterworth or binomial")
    p.add_argument("--nominal-mass", type=float,
                   help="estimator's nominal mass [kg] (default: the flight's sidecar FLIGHT.meta.json, else 1.5)")
    p.add_argument("--out", default=".", help="directory for the PNG files")
    a = p.parse_args()
    fl, es = read(a.flight), read(a.estimates)
    a.nominal_mass = nominal_mass(a.flight, a.nominal_mass)
    for n in ("time_s", "fext_n", "fext_e", "fext_d", "text_z", "true_mass_kg"):
        if n not in fl:
            sys.exit(f"{a.flight}:1: missing column `{n}`")
    if len(fl["time_s"]) != len(es["time_s"]):
        sys.exit(f"{a.estimates}: {len(es['time_s'])} rows, the flight has {len(fl['time_s'])}")
    t = es["time_s"]
    # what the estimator should converge to at hover: f_e + (m_true - m_nom) g e3 (NED)
    truth = {
        "fn": fl["fext_n"],
        "fe": fl["fext_e"],
        "fd": [f + (m - a.nominal_mass) * G for f, m in zip(fl["fext_d"], fl["true_mass_kg"])],
        "tz": fl["text_z"],
    }
    labels = {"fn": "f_N [N]", "fe": "f_E [N]", "fd": "f_D [N]", "tz": "tau_z [N m]"}
    os.makedirs(a.out, exist_ok=True)
    orders = [int(o) for o in a.orders.split(",")]
    written = []
    for r in orders:
        key = f"{a.poly}{r}"
        if f"{key}_fn" not in es:
            sys.exit(f"{a.estimates}:1: no column `{key}_fn`: run `rotorpilot estimate` with --order {r} --poly {a.poly}")
        for kind in ("wrench", "vs_truth", "error"):
            fig, axes = plt.subplots(4, 1, sharex=True, figsize=(8, 8))
            for ax, ch in zip(axes, ("fn", "fe", "fd", "tz")):
                est = es[f"{key}_{ch}"]
                if kind == "wrench":
                    ax.plot(t, est, label=f"estimate r={r}")
                elif kind == "vs_truth":
                    ax.plot(t, est, label=f"estimate r={r}")
                    ax.plot(t, truth[ch], "--", label="applied")
                else:
                    ax.plot(t, [e - g for e, g in zip(est, truth[ch])], label="estimate - applied")
                ax.set_ylabel(labels[ch])
                ax.grid(True, alpha=0.3)
                ax.legend(loc="lower right", fontsize="small")
            axes[-1].set_xlabel("time [s]")
            title = {"wrench": "estimated wrench", "vs_truth": "estimate vs applied disturbance",
                     "error": "estimation error"}[kind]
            fig.suptitle(f"{title} ({a.poly}, r = {r})")
            fig.tight_layout()
            out = os.path.join(a.out, f"estimate_{a.poly}_r{r}_{kind}.png")
            fig.savefig(out, dpi=110)
            plt.close(fig)
            written.append(out)
    fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 6))
    for r in orders:
        axes[0].plot(t, es[f"{a.poly}{r}_fn"], label=f"r={r}")
        axes[1].plot(t, es[f"{a.poly}{r}_mass_kg"], label=f"r={r}")
    axes[0].plot(t, truth["fn"], "k--", label="applied")
    axes[1].plot(t, fl["true_mass_kg"], "k--", label="true mass")
    axes[0].set_ylabel("f_N [N]")
    axes[1].set_ylabel("mass [kg]")
    axes[1].set_xlabel("time [s]")
    for ax in axes:
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    fig.suptitle(f"orders compared ({a.poly})")
    fig.tight_layout()
    out = os.path.join(a.out, f"estimate_{a.poly}_orders.png")
    fig.savefig(out, dpi=110)
    plt.close(fig)
    written.append(out)
    for w in written:
        print(w)


if __name__ == "__main__":
    main()
