#!/usr/bin/env python3
"""Write the fuzz corpus, tests/fuzz/corpus/*.bin: one UDP datagram per file,
each what a real client sends a PX4 vehicle (a GCS heartbeat, MAVSDK's arm
and takeoff, a parameter set, a mission upload's messages, offboard
setpoints, FTP, timesync, ...), packed by pymavlink (an encoder that shares
no code with rotorpilot). tests/fuzz.rs mutates these seeds; a seed that
reaches a handler lets the mutants reach it too.

    .venv/pymavlink/bin/python tools/fuzz_corpus.py

(any Python with pymavlink==2.4.50). The files are checked in; rerun only to
add seeds.
"""
import math
import pathlib
import struct

from pymavlink.dialects.v10 import common as mavlink1
from pymavlink.dialects.v20 import common as mavlink2

OUT = pathlib.Path(__file__).resolve().parent.parent / "tests/fuzz/corpus"
NAN = math.nan
LAT, LON = 473977418, 85455939  # PX4 SITL home, degE7


def v2(*msgs, sysid=245, compid=190):
    mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    out = b""
    for m in msgs:
        out += bytes(m.pack(mav))
        mav.seq = (mav.seq + 1) % 256
    return out


def v1(*msgs):
    mav = mavlink1.MAVLink(None, srcSystem=255, srcComponent=0)
    return b"".join(bytes(m.pack(mav)) for m in msgs)


M = mavlink2


def cmd(command, *p, target=1):
    p = list(p) + [NAN] * (7 - len(p))
    return M.MAVLink_command_long_message(target, 1, command, 0, *p)


def cmd_int(command, frame, p1, p2, p3, p4, x, y, z):
    return M.MAVLink_command_int_message(1, 1, frame, command, 0, 0, p1, p2, p3, p4, x, y, z)


def item(seq, command, x, y, z, frame=3, mission_type=0, p1=0.0):
    return M.MAVLink_mission_item_int_message(1, 1, seq, frame, command, 0, 1, p1, 0.0, 0.0, NAN, x, y, z, mission_type)


def ftp(seq, opcode, data=b"", session=0, offset=0):
    """A FILE_TRANSFER_PROTOCOL request as MAVSDK's FTP plugin sends it."""
    head = bytes([seq & 0xFF, seq >> 8, session, opcode, len(data), 0, 0, 0]) + offset.to_bytes(4, "little")
    return M.MAVLink_file_transfer_protocol_message(0, 1, 1, list((head + data).ljust(251, b"\0")))


def log_list():
    return M.MAVLink_log_request_list_message(1, 1, 0, 0xFFFF)


# @PARAM/param.pck setting MIS_TAKEOFF_ALT to 3.0: header (magic, 1 entry,
# 27 bytes), then float, no common prefix, a 15-character name, the value
PCK = bytes.fromhex("1b6701001b00") + bytes([4, 14 << 4]) + b"MIS_TAKEOFF_ALT" + struct.pack("<f", 3.0)

SEEDS = {
    "heartbeat-gcs": v2(M.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)),
    "heartbeat-v1": v1(mavlink1.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)),
    "arm": v2(cmd(400, 1.0)),
    "arm-force": v2(cmd(400, 1.0, 21196.0)),
    "disarm": v2(cmd(400, 0.0)),
    "takeoff": v2(cmd(22, NAN, 0, 0, NAN, NAN, NAN, 500.0)),
    "land": v2(cmd(21)),
    "rtl": v2(cmd(20)),
    "set-mode-hold": v2(cmd(176, 1.0, 4.0, 3.0)),
    "set-mode-offboard": v2(cmd(176, 1.0, 6.0, 0.0)),
    "set-mode-msg": v2(M.MAVLink_set_mode_message(1, 1, (4 << 16) | (4 << 24))),
    "reposition": v2(cmd_int(192, 6, -1.0, 1.0, 0.0, NAN, LAT + 1000, LON + 1000, 10.0)),
    "reposition-global": v2(cmd_int(192, 0, -1.0, 1.0, 0.0, NAN, LAT, LON, 510.0)),
    "change-speed": v2(cmd(178, 1.0, 3.0, -1.0)),
    "mission-start": v2(cmd(300, 0.0, 0.0)),
    "request-message": v2(cmd(512, 148.0), cmd(512, 242.0), cmd(512, 245.0)),
    "message-interval": v2(cmd(511, 32.0, 1000.0), cmd(511, 33.0, -1.0), cmd(511, 0.0, 0.0)),
    "inject-failure": v2(cmd(420, 101.0, 1.0, 1.0), cmd(420, 7.0, 1.0, 0.0)),
    "reboot": v2(cmd(246, 1.0)),
    "calibration": v2(cmd(241, 1.0)),
    "unknown-command": v2(cmd(31337, 1.0)),
    "command-other-system": v2(cmd(400, 1.0, target=7)),
    "param-request-list": v2(M.MAVLink_param_request_list_message(1, 1)),
    "param-read-name": v2(M.MAVLink_param_request_read_message(1, 1, b"MIS_TAKEOFF_ALT", -1)),
    "param-read-index": v2(M.MAVLink_param_request_read_message(1, 1, b"", 3)),
    "param-set-real": v2(M.MAVLink_param_set_message(1, 1, b"MIS_TAKEOFF_ALT", 5.0, 9)),
    "param-set-int": v2(M.MAVLink_param_set_message(1, 1, b"CTRL_TYPE", 1.0, 6)),
    "param-set-unknown": v2(M.MAVLink_param_set_message(1, 1, b"NO_SUCH_PARAM", 1.0, 9)),
    "mission-count": v2(M.MAVLink_mission_count_message(1, 1, 3, 0)),
    "mission-items": v2(
        item(0, 22, LAT, LON, 10.0),
        item(1, 16, LAT + 2000, LON, 10.0),
        item(2, 21, LAT + 2000, LON, 0.0),
    ),
    "mission-upload": v2(
        M.MAVLink_mission_count_message(1, 1, 2, 0),
        item(0, 22, LAT, LON, 10.0),
        item(1, 16, LAT + 2000, LON + 2000, 10.0),
    ),
    "mission-item-float": v2(
        M.MAVLink_mission_item_message(1, 1, 0, 3, 16, 0, 1, 0, 0, 0, NAN, 47.3978, 8.5456, 10.0, 0)
    ),
    "fence-upload": v2(
        M.MAVLink_mission_count_message(1, 1, 1, 1),
        M.MAVLink_mission_item_int_message(1, 1, 0, 0, 5003, 0, 1, 30.0, 0, 0, 0, LAT, LON, 0.0, 1),
    ),
    "rally-upload": v2(M.MAVLink_mission_count_message(1, 1, 1, 2), item(0, 5100, LAT, LON, 20.0, mission_type=2)),
    "mission-request-list": v2(M.MAVLink_mission_request_list_message(1, 1, 0)),
    "mission-request-int": v2(M.MAVLink_mission_request_int_message(1, 1, 0, 0)),
    "mission-ack": v2(M.MAVLink_mission_ack_message(1, 1, 0, 0)),
    "mission-clear": v2(M.MAVLink_mission_clear_all_message(1, 1, 255)),
    "mission-set-current": v2(M.MAVLink_mission_set_current_message(1, 1, 1)),
    "offboard-local": v2(
        M.MAVLink_set_position_target_local_ned_message(0, 1, 1, 1, 0b0000111111111000, 1.0, 2.0, -5.0, 0, 0, 0, 0, 0, 0, 0, 0)
    ),
    "offboard-velocity": v2(
        M.MAVLink_set_position_target_local_ned_message(0, 1, 1, 1, 0b0000111111000111, 0, 0, 0, 1.0, 0, -0.5, 0, 0, 0, 0, 0)
    ),
    "offboard-global": v2(
        M.MAVLink_set_position_target_global_int_message(0, 1, 1, 6, 0b0000111111111000, LAT, LON, 10.0, 0, 0, 0, 0, 0, 0, 0, 0)
    ),
    "attitude-target": v2(M.MAVLink_set_attitude_target_message(0, 1, 1, 0b00000111, [1.0, 0.0, 0.0, 0.0], 0, 0, 0, 0.6)),
    "manual-control": v2(M.MAVLink_manual_control_message(1, 0, 0, 500, 0, 0)),
    "timesync": v2(M.MAVLink_timesync_message(0, 123456789)),
    "ping": v2(M.MAVLink_ping_message(1000, 1, 0, 0)),
    "ftp-list": v2(M.MAVLink_file_transfer_protocol_message(0, 1, 1, list(bytes([1, 0, 0, 3, 0, 1, 0, 0, 0, 0, 0, 0]) + b"/\x00" + bytes(237)))),
    "ftp-open": v2(M.MAVLink_file_transfer_protocol_message(0, 1, 1, list(bytes([2, 0, 0, 4, 0, 18, 0, 0, 0, 0, 0, 0]) + b"@PARAM/param.pck\x00\x00" + bytes(233)))),
    # MAVSDK's FTP plugin: a listing, a burst download, an upload to
    # @PARAM/param.pck, a CRC, a rename and a remove; QGroundControl's and
    # MAVSDK's log download (list, data, end, erase)
    "ftp-list-session": v2(ftp(1, 3, b"/"), ftp(2, 3, b"/", offset=3), ftp(3, 3, b"/log"), ftp(4, 3, b"/fs/microsd/log")),
    "ftp-burst-download": v2(ftp(5, 4, b"@PARAM/param.pck"), ftp(6, 15), ftp(7, 5, offset=239), ftp(8, 1)),
    "ftp-read-file": v2(ftp(9, 4, b"/params.toml"), ftp(10, 5), ftp(11, 5, offset=4096), ftp(12, 2)),
    "ftp-param-upload": v2(
        ftp(13, 6, b"@PARAM/param.pck"),
        ftp(14, 7, PCK[:10]),
        ftp(15, 7, PCK[10:], offset=10),
        ftp(16, 1),
    ),
    "ftp-write-ops": v2(
        ftp(17, 6, b"/a.txt"), ftp(18, 7, b"hello"), ftp(19, 1), ftp(20, 14, b"/a.txt"),
        ftp(21, 13, b"/a.txt\0/b.txt"), ftp(22, 12, b"/b.txt", offset=2), ftp(23, 9, b"/d"),
        ftp(24, 10, b"/d"), ftp(25, 8, b"/b.txt"), ftp(26, 11, b"/../escape"),
    ),
    "log-download": v2(
        log_list(),
        M.MAVLink_log_request_data_message(1, 1, 0, 0, 0xFFFFFFFF),
        M.MAVLink_log_request_end_message(1, 1),
    ),
    "log-erase": v2(log_list(), M.MAVLink_log_erase_message(1, 1), log_list()),
    "request-data-stream": v2(M.MAVLink_request_data_stream_message(1, 1, 0, 10, 1)),
    "setup-signing": v2(M.MAVLink_setup_signing_message(1, 1, bytes(range(32)), 1000)),
    "all-in-one": v2(
        M.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3),
        cmd(400, 1.0),
        cmd(22, NAN, 0, 0, NAN, NAN, NAN, 500.0),
        M.MAVLink_param_request_list_message(1, 1),
    ),
}


def main():
    OUT.mkdir(parents=True, exist_ok=True)
    for name, data in SEEDS.items():
        # pymavlink reads every frame back
        parser = mavlink2.MAVLink(None)
        assert parser.parse_buffer(data), name
        (OUT / f"{name}.bin").write_bytes(data)
    print(f"{len(SEEDS)} seeds in {OUT}")


if __name__ == "__main__":
    main()
