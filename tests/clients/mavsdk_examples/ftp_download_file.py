#!/usr/bin/env python3
"""MAVSDK-Python's ftp_download_file.py example, against rotorpilot: find
the oldest flight log under /log, download it by FTP (burst reads), and
compare it byte for byte with the file the vehicle wrote
(ROTORPILOT_LOG_FILE), then check its CRC32 with the vehicle's."""

import os
import tempfile
import zlib

from common import bail, bring_up, launch

EXPECTED = os.environ["ROTORPILOT_LOG_FILE"]


def crc32part(data):
    """PX4's crc32part from 0: zlib's CRC-32 without its inversions."""
    return zlib.crc32(data, 0xFFFFFFFF) ^ 0xFFFFFFFF


async def run():
    uav = await bring_up(need_position=False)
    days = await uav.ftp.list_directory("/log")
    first_day = sorted(days.dirs)[0]
    files = await uav.ftp.list_directory(f"/log/{first_day}")
    name = sorted(f.split("\t")[0] for f in files.files)[0]
    remote = f"/log/{first_day}/{name}"
    with tempfile.TemporaryDirectory() as local:
        last = -1
        async for p in uav.ftp.download(remote, local, True):
            pct = p.bytes_transferred * 100 // max(p.total_bytes, 1)
            if pct // 25 != last // 25:
                print(f"{remote}: {p.bytes_transferred}/{p.total_bytes}")
            last = pct
        got = open(os.path.join(local, name), "rb").read()
    want = open(EXPECTED, "rb").read()
    if got != want:
        bail(f"{remote}: {len(got)} bytes downloaded, {len(want)} on disk, not equal")
    print(f"{remote}: {len(got)} bytes, equal to the file on disk")
    # MAVSDK sums the local file with PX4's crc32part (not zlib's CRC-32:
    # no inversion in or out) and compares it with the vehicle's CalcFileCRC32
    if not await uav.ftp.are_files_identical(EXPECTED, remote):
        bail("CalcFileCRC32 does not match the file")
    print(f"CRC32 matches: {crc32part(want):#010x} (PX4's crc32part, the vehicle's answer)")


if __name__ == "__main__":
    launch(run)
