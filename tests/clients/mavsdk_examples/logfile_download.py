#!/usr/bin/env python3
"""MAVSDK-Python's logfile_download.py example, against rotorpilot: list the
vehicle's logs (LOG_REQUEST_LIST), download the oldest (LOG_REQUEST_DATA),
check it parses as a ULog (pyulog) and equals the file the vehicle wrote
(ROTORPILOT_LOG_FILE), ROTORPILOT_EXPECT_LOGS logs in all."""

import os
import tempfile

from pyulog import ULog

from common import bail, bring_up, launch

EXPECTED = os.environ["ROTORPILOT_LOG_FILE"]
EXPECT_LOGS = int(os.environ["ROTORPILOT_EXPECT_LOGS"])


async def run():
    uav = await bring_up(need_position=False)
    entries = await uav.log_files.get_entries()
    for e in entries:
        print(f"log {e.id}: {e.date} {e.size_bytes} bytes")
    if len(entries) != EXPECT_LOGS:
        bail(f"{len(entries)} logs listed, expected {EXPECT_LOGS}")
    entry = entries[0]
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, f"log-{entry.date.replace(':', '-')}.ulg")
        previous = -1
        async for progress in uav.log_files.download_log_file(entry, path):
            pct = round(progress.progress * 100)
            if pct // 25 != previous // 25:
                print(f"download {pct} %")
            previous = pct
        got = open(path, "rb").read()
        ulog = ULog(path)
    want = open(EXPECTED, "rb").read()
    if got != want:
        bail(f"log {entry.id}: {len(got)} bytes downloaded, {len(want)} on disk, not equal")
    topics = sorted({d.name for d in ulog.data_list})
    print(f"log {entry.id}: a ULog of {len(got)} bytes, topics {topics}")
    if "vehicle_local_position" not in topics:
        bail("the downloaded ULog has no vehicle_local_position")


if __name__ == "__main__":
    launch(run)
