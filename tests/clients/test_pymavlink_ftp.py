"""MAVLink FTP and log download by hand with pymavlink against the
rotorpilot binary: what a careless or hostile client sends gets PX4's NAK
and no crash (a path out of the state directory, the signing key, an
unknown session, a second session, a write past the size cap, unknown
opcodes, a flood of garbage), with no --log-dir the log list is PX4's
answer for no logs (one LOG_ENTRY, num_logs 0), and the flight being
logged is listed with the size it has on disk, and that much downloads.

Run in the pymavlink venv: `python -m pytest tests/clients/test_pymavlink_ftp.py`.
"""

import random
import struct
import sys
import tempfile
import time
from pathlib import Path

from pymavlink import mavutil

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from harness import Vehicle  # noqa: E402

ACK, NAK = 128, 129
LIST, OPEN_RO, READ, CREATE, WRITE, REMOVE, TERMINATE, RESET = 3, 4, 5, 6, 7, 8, 1, 2
FAIL_ERRNO, INVALID_SESSION, NO_SESSIONS, EOF, UNKNOWN, PROTECTED, NOT_FOUND = 2, 4, 5, 6, 7, 9, 10
EFBIG = 27


class Ftp:
    def __init__(self, v):
        self.m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.api_port}", source_system=245)
        assert self.m.wait_heartbeat(timeout=10) is not None
        self.sysid = v.sysid
        self.seq = 0

    def ask(self, opcode, path=b"", session=0, offset=0, data=None, tries=3):
        """(opcode, data) of the answer; the request is resent after a
        second without one, as MAVSDK and mavftp do (an answer the vehicle's
        budget held back under a flood is then sent again)."""
        self.seq += 1
        body = data if data is not None else path
        payload = struct.pack("<HBBBBBBI", self.seq, session, opcode, len(body), 0, 0, 0, offset) + body
        payload = list(payload.ljust(251, b"\0"))
        for _ in range(tries):
            self.m.mav.file_transfer_protocol_send(0, self.sysid, 1, payload)
            while True:
                r = self.m.recv_match(type="FILE_TRANSFER_PROTOCOL", blocking=True, timeout=1)
                if r is None:
                    break
                p = bytes(r.payload)
                seq, _, op, size, req = struct.unpack_from("<HBBBB", p)
                if seq == (self.seq + 1) & 0xFFFF and req == opcode:
                    return op, p[12 : 12 + size]
        raise AssertionError(f"no answer to opcode {opcode} in {tries} tries")


def test_bad_requests_get_px4s_naks_and_the_vehicle_goes_on():
    with Vehicle() as v:
        f = Ftp(v)
        op, data = f.ask(LIST, b"/")
        assert op == ACK and b"Dlog\0" in data and b"Fparams.toml\t" in data
        assert b"signing" not in data and b"lock" not in data
        assert f.ask(LIST, b"/", offset=50) == (NAK, bytes([EOF]))
        # out of the state directory, by .. and by absolute paths
        for path in [b"/../../../etc/passwd", b"../params.toml", b"/log/../../x", b"/signing.key"]:
            assert f.ask(OPEN_RO, path) == (NAK, bytes([PROTECTED])), path
        assert f.ask(OPEN_RO, b"/etc/passwd") == (NAK, bytes([NOT_FOUND]))
        assert f.ask(CREATE, b"/params.toml") == (NAK, bytes([PROTECTED]))
        # sessions
        assert f.ask(READ, session=3) == (NAK, bytes([INVALID_SESSION]))
        assert f.ask(READ, session=0) == (NAK, bytes([INVALID_SESSION]))
        op, size = f.ask(OPEN_RO, b"/params.toml")
        assert op == ACK and len(size) == 4
        assert f.ask(OPEN_RO, b"/params.toml") == (NAK, bytes([NO_SESSIONS]))
        assert f.ask(TERMINATE, session=0)[0] == ACK
        # a write past the size cap (1 MiB a file)
        assert f.ask(CREATE, b"/scratch.bin")[0] == ACK
        assert f.ask(WRITE, offset=0, data=b"x" * 200) == (ACK, struct.pack("<I", 200))
        assert f.ask(WRITE, offset=1 << 20, data=b"x") == (NAK, bytes([FAIL_ERRNO, EFBIG]))
        assert f.ask(RESET)[0] == ACK
        assert f.ask(REMOVE, b"/scratch.bin")[0] == ACK
        # unknown opcodes and a flood of garbage
        for opcode in [16, 77, 127, 200, 255]:
            assert f.ask(opcode) == (NAK, bytes([UNKNOWN])), opcode
        rng = random.Random(7)
        for _ in range(2000):
            f.m.mav.file_transfer_protocol_send(0, v.sysid, 1, [rng.randrange(256) for _ in range(251)])
        f.m.recv_match(type="FILE_TRANSFER_PROTOCOL", blocking=True, timeout=1)
        assert f.ask(RESET, tries=10)[0] == ACK
        assert f.ask(LIST, b"/", tries=10)[0] == ACK
        assert v.proc.poll() is None, "the vehicle still runs"


def test_no_logs_is_one_entry_saying_none():
    with Vehicle() as v:
        m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.api_port}", source_system=245)
        assert m.wait_heartbeat(timeout=10) is not None
        m.mav.log_request_list_send(v.sysid, 1, 0, 0xFFFF)
        e = m.recv_match(type="LOG_ENTRY", blocking=True, timeout=3)
        assert e is not None, "no LOG_ENTRY"
        assert (e.num_logs, e.id, e.last_log_num, e.size) == (0, 0, 0, 0)
        # data for a log that does not exist: nothing, as PX4
        m.mav.log_request_data_send(v.sysid, 1, 0, 0, 90)
        assert m.recv_match(type="LOG_DATA", blocking=True, timeout=1) is None


def test_the_log_being_written_is_listed_with_its_size_on_disk_and_downloads():
    """PX4's logger writes continuously: the running flight's ULog is listed
    with the bytes already on disk (not 0 while a buffer holds them), and a
    download of that size is those bytes, a ULog from its header on."""
    with tempfile.TemporaryDirectory() as logs, Vehicle(speed=1.0, extra=("--log-dir", logs)) as v:
        m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.api_port}", source_system=245)
        assert m.wait_heartbeat(timeout=10) is not None
        # at 1x the flight logs some 17 kB/s: 2.5 s is far less than a
        # write buffer holds, so only a writer that flushes has it on disk
        time.sleep(2.5)
        while m.recv_match(blocking=False) is not None:
            pass  # the telemetry of those seconds, read before the answer
        m.mav.log_request_list_send(v.sysid, 1, 0, 0xFFFF)
        entries = []
        while (e := m.recv_match(type="LOG_ENTRY", blocking=True, timeout=2)) is not None:
            entries.append(e)
            if len(entries) == e.num_logs:
                break
        assert entries and entries[0].num_logs == 1, f"{entries}"
        e = entries[0]
        assert e.size > 0, "the running flight's log is listed with size 0"
        m.mav.log_request_data_send(v.sysid, 1, e.id, 0, e.size)
        got = {}
        deadline = time.monotonic() + 20
        while sum(len(b) for b in got.values()) < e.size and time.monotonic() < deadline:
            d = m.recv_match(type="LOG_DATA", blocking=True, timeout=1)
            if d is not None and d.id == e.id:
                got[d.ofs] = bytes(d.data[: d.count])
        data = b"".join(got[k] for k in sorted(got))
        assert len(data) == e.size, f"downloaded {len(data)} of {e.size} bytes"
        assert data.startswith(b"ULog\x01\x12\x35"), data[:8]
        ulg = next(Path(logs).rglob("*.ulg")).read_bytes()
        assert ulg[: e.size] == data, "the download is not the file's bytes"
