#!/usr/bin/env python3
"""Mission transfer speed over loopback with pymavlink: upload (MISSION_COUNT,
then MISSION_ITEM_INT as the vehicle asks) and download (MISSION_REQUEST_LIST,
then MISSION_REQUEST_INT one by one) of N waypoints, against a rotorpilot
vehicle the script starts itself. Prints one row per N (median of --runs)."""
import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tests", "clients"))
from harness import Vehicle  # noqa: E402


def item(seq, sysid):
    lat = int((47.397742 + 1e-6 * (seq % 1000)) * 1e7)
    lon = int((8.545594 + 1e-6 * (seq // 1000)) * 1e7)
    return mavlink.MAVLink_mission_item_int_message(
        sysid, 1, seq, 3, 16, 1 if seq == 0 else 0, 1, 0, 2, 0, float("nan"), lat, lon, 10.0, 0)


def upload(m, n, timeout=60):
    items = [item(k, m.target_system) for k in range(n)]
    t0 = time.perf_counter()
    m.mav.mission_count_send(m.target_system, 1, n, 0)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        msg = m.recv_match(type=["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"], blocking=True, timeout=1)
        if msg is None:
            continue
        if msg.get_type() == "MISSION_ACK":
            assert msg.type == 0, msg
            return time.perf_counter() - t0
        if msg.get_type() == "MISSION_REQUEST":
            m.mav.mission_ack_send(m.target_system, 1, mavlink.MAV_MISSION_UNSUPPORTED, 0)
            continue
        m.mav.send(items[msg.seq])
    raise TimeoutError("upload")


def download(m, n, timeout=60):
    t0 = time.perf_counter()
    m.mav.mission_request_list_send(m.target_system, 1, 0)
    c = m.recv_match(type="MISSION_COUNT", blocking=True, timeout=5)
    assert c is not None and c.count == n, c
    for k in range(n):
        m.mav.mission_request_int_send(m.target_system, 1, k, 0)
        got = m.recv_match(type="MISSION_ITEM_INT", blocking=True, timeout=2)
        assert got is not None and got.seq == k, got
    m.mav.mission_ack_send(m.target_system, 1, 0, 0)
    return time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--sizes", default="100,1000,10000")
    ap.add_argument("--runs", type=int, default=3)
    a = ap.parse_args()
    with Vehicle(speed=1) as v:
        m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=245, source_component=190)
        m.wait_heartbeat(timeout=10)
        print("| items | upload (median, min-max) | download (median, min-max) |")
        print("|---|---|---|")
        for n in [int(x) for x in a.sizes.split(",")]:
            up = [upload(m, n) for _ in range(a.runs)]
            down = [download(m, n) for _ in range(a.runs)]
            f = lambda xs: f"{statistics.median(xs)*1e3:.0f} ms ({min(xs)*1e3:.0f}-{max(xs)*1e3:.0f})"
            print(f"| {n} | {f(up)} | {f(down)} |")


if __name__ == "__main__":
    main()
