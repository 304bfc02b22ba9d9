#!/usr/bin/env python3
"""Show the estimated external wrench and mass of a running rotorpilot vehicle
live, beside the injected truth.

The vehicle streams (10 Hz by default, SET_MESSAGE_INTERVAL on ids 250/251):
  DEBUG_VECT EST_FORCE   estimated external force [N], world NED
  DEBUG_VECT EST_TORQUE  estimated external torque [N m], body FRD
  NAMED_VALUE_FLOAT EST_MASS  estimated real mass [kg]
and the truth it injects (SIM_FEXT_*, SIM_TEXT_*, SIM_MASS parameters) as
SIM_FORCE, SIM_TORQUE and SIM_MASS.

While the vehicle rests on the ground (EXTENDED_SYS_STATE landed_state
ON_GROUND) the estimator is held at zero on purpose (the ground's reaction
is not a disturbance): the line says "on the ground: estimator held" instead
of zeros. Take off to see the estimate. A value not yet heard prints as
"unknown".

    python3 tools/show_wrench.py                       # GCS link of instance 0
    python3 tools/show_wrench.py --rate 20 --duration 30
    python3 tools/show_wrench.py --csv wrench.csv

Needs pymavlink (pip install pymavlink).
"""

import argparse
import sys
import time

from pymavlink import mavutil


ESTIMATE = ("EST_FORCE", "EST_TORQUE", "EST_MASS")
TRUTH = ("SIM_FORCE", "SIM_TORQUE", "SIM_MASS")
# how long to wait for the truth and the landed state after the first estimate [s]
# (EXTENDED_SYS_STATE comes at 1 Hz)
WAIT_ALL_S = 2.5
ON_GROUND = 1  # MAV_LANDED_STATE_ON_GROUND


def vec(v):
    return "[" + " ".join(f"{x:7.3f}" for x in v) + "]" if v is not None else f"[{'unknown':^23}]"


def scalar(v):
    return f"{v:7.3f}" if v is not None else "unknown"


def lines(latest):
    """The two printed lines (estimate, truth) for the latest values: `latest`
    maps EST_*/SIM_* names to their values, "time" to the vehicle time [s] and
    "landed" to EXTENDED_SYS_STATE.landed_state (absent: not heard yet)."""
    t = latest.get("time")
    head = f"t={t:7.1f}s" if t is not None else f"{'t=?':>10}"
    if latest.get("landed") == ON_GROUND:
        est = f"{head} est   on the ground: estimator held (take off to estimate)"
    else:
        est = (f"{head} est   {vec(latest.get('EST_FORCE'))} | {vec(latest.get('EST_TORQUE'))} | "
               f"{scalar(latest.get('EST_MASS'))}")
    truth = (f"{'':>10} truth {vec(latest.get('SIM_FORCE'))} | {vec(latest.get('SIM_TORQUE'))} | "
             f"{scalar(latest.get('SIM_MASS'))}")
    return [est, truth]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--connect", default="udpin:0.0.0.0:14550", help="pymavlink connection (default %(default)s)")
    ap.add_argument("--rate", type=float, help="ask for this stream rate [Hz] (SET_MESSAGE_INTERVAL)")
    ap.add_argument("--print-hz", type=float, default=2.0, help="lines per second (default %(default)s)")
    ap.add_argument("--duration", type=float, help="stop after this many seconds")
    ap.add_argument("--csv", help="also write every sample to this CSV file")
    a = ap.parse_args()

    m = mavutil.mavlink_connection(a.connect, source_system=255, source_component=190)
    m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    if m.wait_heartbeat(timeout=10) is None:
        sys.exit(f"no vehicle heard on {a.connect}")
    if a.rate:
        for msg_id in (250, 251):
            m.mav.command_long_send(m.target_system, 1, 511, 0, msg_id, 1e6 / a.rate, 0, 0, 0, 0, 0)
    csv = open(a.csv, "w") if a.csv else None
    if csv:
        csv.write("wall_s,time_s,name,x,y,z\n")
    latest = {}
    t0 = time.monotonic()
    next_print = t0
    last_hb = t0
    first_estimate = None
    print(f"{'':>8} {'force N (NED)':>26} | {'torque N m (FRD)':>26} | {'mass kg':>7}", flush=True)
    try:
        while a.duration is None or time.monotonic() - t0 < a.duration:
            msg = m.recv_match(type=["DEBUG_VECT", "NAMED_VALUE_FLOAT", "EXTENDED_SYS_STATE"], blocking=True,
                               timeout=0.2)
            now = time.monotonic()
            if now - last_hb > 1.0:
                # stay a live peer when connected with udpout
                m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                last_hb = now
            if msg is not None and msg.get_type() == "EXTENDED_SYS_STATE":
                latest["landed"] = msg.landed_state
            elif msg is not None:
                if msg.get_type() == "DEBUG_VECT":
                    latest[msg.name] = (msg.x, msg.y, msg.z)
                    t = msg.time_usec / 1e6
                    row = (msg.x, msg.y, msg.z)
                else:
                    latest[msg.name] = msg.value
                    t = msg.time_boot_ms / 1e3
                    row = (msg.value, "", "")
                latest["time"] = t
                if csv:
                    csv.write(f"{now - t0:.3f},{t:.3f},{msg.name},{row[0]},{row[1]},{row[2]}\n")
            if first_estimate is None and all(k in latest for k in ESTIMATE):
                first_estimate = now
            # print once the truth and the landed state are heard too (or did not come in time)
            ready = first_estimate is not None and (
                all(k in latest for k in TRUTH + ("landed",)) or now - first_estimate > WAIT_ALL_S)
            if now >= next_print and ready:
                next_print = now + 1.0 / a.print_hz
                for line in lines(latest):
                    print(line, flush=True)
    except KeyboardInterrupt:
        pass
    finally:
        if csv:
            csv.close()


if __name__ == "__main__":
    main()
