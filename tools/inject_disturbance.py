#!/usr/bin/env python3
"""Inject a disturbance into a running rotorpilot vehicle through its SIM_
parameters: an external force (world NED, N), an external torque (body FRD,
N m) and the true mass (kg). The estimator (EST_FORCE, EST_TORQUE, EST_MASS)
does not see these values; it has to find them. Watch it with show_wrench.py.

Examples (vehicle instance 0, this script as the GCS on udpin:0.0.0.0:14550):
    python3 tools/inject_disturbance.py --force 0.5,0.5,0 --torque 0,0,0.2 --mass 1.8
    python3 tools/inject_disturbance.py --clear
    python3 tools/inject_disturbance.py --connect udpout:127.0.0.1:18570 --force 0,1,0

Every value is checked against the parameter's range first (RANGES, the
vehicle's parameter table): one value out of range changes nothing. Should the
vehicle refuse one anyway, the values already set are put back: all or nothing.

The estimator is held while the vehicle rests on the ground (it restarts
there on purpose): take off first to see it find the disturbance.

Needs pymavlink (pip install pymavlink).
"""

import argparse
import struct
import sys
import time

from pymavlink import mavutil


# (min, max, unit) of each parameter this tool sets: src/params/table.rs (a test keeps them equal)
RANGES = {
    "SIM_FEXT_X": (-50.0, 50.0, "N"),
    "SIM_FEXT_Y": (-50.0, 50.0, "N"),
    "SIM_FEXT_Z": (-50.0, 50.0, "N"),
    "SIM_TEXT_X": (-10.0, 10.0, "N m"),
    "SIM_TEXT_Y": (-10.0, 10.0, "N m"),
    "SIM_TEXT_Z": (-10.0, 10.0, "N m"),
    "SIM_MASS": (0.05, 100.0, "kg"),
}


def out_of_range(changes):
    """The problems of `changes` [(name, value)] against RANGES, one line each (empty: all valid)."""
    problems = []
    for name, value in changes:
        lo, hi, unit = RANGES[name]
        if not (lo <= value <= hi):
            problems.append(f"{name} = {value:g} {unit} is outside its range [{lo:g}, {hi:g}] {unit}")
    return problems


def vec3(s):
    v = [float(x) for x in s.split(",")]
    if len(v) != 3:
        raise argparse.ArgumentTypeError("expected X,Y,Z")
    return v


def connect(url, timeout):
    m = mavutil.mavlink_connection(url, source_system=255, source_component=190)
    # udpout connections must talk first; on udpin this sends nothing yet
    m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    if m.wait_heartbeat(timeout=timeout) is None:
        sys.exit(f"no vehicle heard on {url} within {timeout} s")
    return m


def get(m, name, timeout=2.0):
    m.mav.param_request_read_send(m.target_system, 1, name.encode(), -1)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        p = m.recv_match(type=["PARAM_VALUE", "PARAM_ERROR"], blocking=True, timeout=0.2)
        if p is not None and p.param_id == name:
            return p
    return None


def set_real(m, name, value, timeout=2.0):
    """PARAM_SET as REAL32; returns the value the vehicle answers with."""
    m.mav.param_set_send(m.target_system, 1, name.encode(), value, mavutil.mavlink.MAV_PARAM_TYPE_REAL32)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        p = m.recv_match(type=["PARAM_VALUE", "PARAM_ERROR", "STATUSTEXT"], blocking=True, timeout=0.2)
        if p is None:
            continue
        if p.get_type() == "STATUSTEXT":
            print(f"  vehicle: {p.text}")
        elif p.param_id == name and p.get_type() == "PARAM_VALUE":
            return p.param_value
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--connect", default="udpin:0.0.0.0:14550", help="pymavlink connection (default %(default)s)")
    ap.add_argument("--force", type=vec3, metavar="FN,FE,FD", help="external force [N], world NED")
    ap.add_argument("--torque", type=vec3, metavar="TX,TY,TZ", help="external torque [N m], body FRD")
    ap.add_argument("--mass", type=float, help="true mass [kg]")
    ap.add_argument("--mass-factor", type=float, help="true mass as a factor of the nominal (MDL_MASS)")
    ap.add_argument("--clear", action="store_true", help="no force, no torque, nominal mass")
    ap.add_argument("--timeout", type=float, default=10.0)
    a = ap.parse_args()

    m = connect(a.connect, a.timeout)
    print(f"vehicle {m.target_system} on {a.connect}")
    changes = []
    if a.clear:
        a.force, a.torque = [0.0] * 3, [0.0] * 3
        nominal = get(m, "MDL_MASS")
        a.mass = nominal.param_value if nominal is not None else None
    if a.mass_factor is not None:
        nominal = get(m, "MDL_MASS")
        if nominal is None:
            sys.exit("cannot read MDL_MASS")
        a.mass = nominal.param_value * a.mass_factor
    if a.force:
        changes += list(zip(["SIM_FEXT_X", "SIM_FEXT_Y", "SIM_FEXT_Z"], a.force))
    if a.torque:
        changes += list(zip(["SIM_TEXT_X", "SIM_TEXT_Y", "SIM_TEXT_Z"], a.torque))
    if a.mass is not None:
        changes.append(("SIM_MASS", a.mass))
    if not changes:
        for name in ["SIM_FEXT_X", "SIM_FEXT_Y", "SIM_FEXT_Z", "SIM_TEXT_X", "SIM_TEXT_Y", "SIM_TEXT_Z",
                     "SIM_MASS", "MDL_MASS"]:
            p = get(m, name)
            print(f"  {name:<12} {p.param_value:10.4f}" if p is not None else f"  {name:<12} ?")
        return
    problems = out_of_range(changes)
    if problems:
        print("nothing changed:", file=sys.stderr)
        for p in problems:
            print(f"  {p}", file=sys.stderr)
        sys.exit(2)
    # the values before, to put back if the vehicle refuses one
    before = {}
    for name, _ in changes:
        p = get(m, name)
        if p is None:
            sys.exit(f"cannot read {name}: nothing changed")
        before[name] = p.param_value
    done = []
    for name, value in changes:
        got = set_real(m, name, float(value))
        ok = got is not None and abs(got - value) <= 1e-6 * max(1.0, abs(value))
        print(f"  {name:<12} {value:10.4f} -> {'?' if got is None else f'{got:.4f}'}{'' if ok else '  REFUSED'}")
        if not ok:
            for prev in reversed(done):
                set_real(m, prev, before[prev])
                print(f"  {prev:<12} put back to {before[prev]:.4f}")
            sys.exit(f"{name} refused: nothing changed")
        done.append(name)
    sys.exit(0)


if __name__ == "__main__":
    main()
