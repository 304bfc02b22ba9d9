#!/usr/bin/env python3
"""Show the estimated external wrench and mass of a running rotorpilot vehicle
live, beside the injected truth.

The vehicle streams (10 Hz by default, SET_MESSAGE_INTERVAL on ids 250/251):
  DEBUG_VECT EST_FORCE   estimated external force [N], world NED
  DEBUG_VECT EST_TORQUE  estimated external torque [N m], body FRD
  NAMED_VALUE_FLOAT EST_MASS  estimated real mass [kg]
and the truth it injects (SIM_FEXT_*, SIM_TEXT_*, SIM_MASS parameters) as
SIM_FORCE, SIM_TORQUE and SIM_MASS.

    python3 tools/show_wrench.py                       # GCS link of instance 0
    python3 tools/show_wrench.py --rate 20 --duration 30
    python3 tools/show_wrench.py --csv wrench.csv

Needs pymavlink (pip install pymavlink).
"""

import argparse
import sys
import time

from pymavlink import mavutil


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
    print(f"{'':>8} {'force N (NED)':>26} | {'torque N m (FRD)':>26} | {'mass kg':>7}")
    try:
        while a.duration is None or time.monotonic() - t0 < a.duration:
            msg = m.recv_match(type=["DEBUG_VECT", "NAMED_VALUE_FLOAT"], blocking=True, timeout=0.2)
            now = time.monotonic()
            if now - last_hb > 1.0:
                # stay a live peer when connected with udpout
                m.mav.heartbeat_send(mavutil.mavlink.MAV_TYPE_GCS, mavutil.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
                last_hb = now
            if msg is not None:
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
            if now >= next_print and all(k in latest for k in ("EST_FORCE", "EST_TORQUE", "EST_MASS")):
                next_print = now + 1.0 / a.print_hz
                f = latest.get("EST_FORCE", (0, 0, 0))
                tq = latest.get("EST_TORQUE", (0, 0, 0))
                sf = latest.get("SIM_FORCE", (0, 0, 0))
                st = latest.get("SIM_TORQUE", (0, 0, 0))
                print(f"t={latest['time']:7.1f}s est   [{f[0]:7.3f} {f[1]:7.3f} {f[2]:7.3f}] | "
                      f"[{tq[0]:7.3f} {tq[1]:7.3f} {tq[2]:7.3f}] | {latest.get('EST_MASS', 0):7.3f}")
                print(f"{'':>10} truth [{sf[0]:7.3f} {sf[1]:7.3f} {sf[2]:7.3f}] | "
                      f"[{st[0]:7.3f} {st[1]:7.3f} {st[2]:7.3f}] | {latest.get('SIM_MASS', 0):7.3f}")
    except KeyboardInterrupt:
        pass
    finally:
        if csv:
            csv.close()


if __name__ == "__main__":
    main()
