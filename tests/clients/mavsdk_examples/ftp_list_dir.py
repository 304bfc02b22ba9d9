#!/usr/bin/env python3
"""MAVSDK-Python's ftp_list_dir.py example, against rotorpilot: list the
vehicle's root as PX4 SITL serves it, then its log directory down to the
ULogs. Exits non-zero when a listing is not what PX4 SITL shows a client:
`/` must hold the `log` directory and the vehicle's parameter file, and
`log/` the flights `--log-dir` wrote (ROTORPILOT_EXPECT_LOGS of them)."""

import os

from common import bail, bring_up, launch

EXPECT_LOGS = int(os.environ.get("ROTORPILOT_EXPECT_LOGS", "0"))


async def run():
    uav = await bring_up(need_position=False)
    root = await uav.ftp.list_directory("/")
    print(f"/: dirs {root.dirs} files {root.files}")
    if "log" not in root.dirs:
        bail(f"no log directory at /: {root.dirs}")
    if not any(f.startswith("params.toml") for f in root.files):
        bail(f"no parameter file at /: {root.files}")
    if any("signing.key" in f for f in root.files):
        bail("the signing key is listed")
    logs = []
    days = await uav.ftp.list_directory("/log")
    print(f"/log: {days.dirs}")
    for day in days.dirs:
        listing = await uav.ftp.list_directory(f"/log/{day}")
        print(f"/log/{day}: {listing.files}")
        logs += [f"/log/{day}/{f}" for f in listing.files]
    if len(logs) != EXPECT_LOGS or not all(".ulg" in f for f in logs):
        bail(f"expected {EXPECT_LOGS} ULogs under /log, found {logs}")


if __name__ == "__main__":
    launch(run)
