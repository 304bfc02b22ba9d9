"""MAVLink 2 message signing against the real rotorpilot binary,
with pymavlink's signing (`setup_signing`) as the key holder, as MAVProxy's
`signing setup` does it: SETUP_SIGNING installs the key; then a signed client
flies (sets a parameter, arms, takes off, changes mode) while an unsigned
client on the same link can neither arm, disarm, set a parameter nor change
the mode, and is answered nothing (PX4 answers refused frames with
silence); a replayed signed frame is refused; the key file is 0600 and in no
PARAM list; after a restart on the same state directory the key is kept and
the vehicle's signing timestamps continue above the ones before.

Run with the pymavlink venv: `python -m pytest tests/clients/test_pymavlink_signing.py`.
"""

import hashlib
import os
import stat
import struct
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle, command, drain  # noqa: E402
from harness import wait_message as wait  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
KEY = hashlib.sha256(b"rotorpilot signing test").digest()
# PX4 custom mode: AUTO (4) / LAND (6)
LAND_CUSTOM_MODE = (4 << 16) | (6 << 24)


def signature_of(msg):
    """(link id, timestamp) of a signed message, from its bytes."""
    buf = bytes(msg.get_msgbuf())
    return buf[-13], int.from_bytes(buf[-12:-6], "little")


def signed_client(v, send_setup):
    """A GCS on the vehicle's GCS link that holds KEY (and, with
    `send_setup`, gives it to the vehicle first, unsigned, as MAVProxy's
    `signing setup` does)."""
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=255)
    hb = m.wait_heartbeat(timeout=5)
    assert hb is not None, "no heartbeat"
    if send_setup:
        now = int((time.time() - 1420070400) * 100_000)
        m.mav.setup_signing_send(v.sysid, 1, list(KEY), now)
    m.setup_signing(KEY, sign_outgoing=True)
    drain(m)
    # from now on pymavlink drops every unsigned or badly signed frame
    hb = wait(m, "HEARTBEAT", timeout=5.0)
    assert hb is not None and hb._signed, "the vehicle does not sign with the key"
    return m


def unsigned_client(v):
    """Another host on the GCS link without the key: it sends to the
    vehicle's GCS port from its own socket."""
    return mavutil.mavlink_connection(f"udpout:127.0.0.1:{v.gcs_bind}", source_system=254)


def param_value(m, name, timeout=3.0):
    drain(m)
    m.mav.param_request_read_send(m.target_system, m.target_component, name.encode(), -1)
    p = wait(m, "PARAM_VALUE", lambda p: p.param_id == name, timeout)
    assert p is not None, f"no PARAM_VALUE {name}"
    return p.param_value


def heartbeat(m):
    drain(m)
    hb = wait(m, "HEARTBEAT", timeout=3.0)
    assert hb is not None
    return hb


def armed(hb):
    return bool(hb.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED)


def mode(hb):
    return mavutil.interpret_px4_mode(hb.base_mode, hb.custom_mode)


def rel_alt(m):
    drain(m)
    g = wait(m, "GLOBAL_POSITION_INT", timeout=2.0)
    assert g is not None
    return g.relative_alt / 1000.0


def unsigned_attempts(u, sysid, disarm_in_flight=False):
    """What an unsigned host tries: arm (or force-disarm), set a parameter,
    change the mode to LAND (COMMAND_LONG and SET_MODE). Returns whatever it
    received in 1.5 s (it must be nothing)."""
    if disarm_in_flight:
        u.mav.command_long_send(sysid, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0, 21196, 0, 0, 0, 0, 0)
    else:
        u.mav.command_long_send(sysid, 1, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 21196, 0, 0, 0, 0, 0)
    u.mav.param_set_send(sysid, 1, b"MIS_TAKEOFF_ALT", 9.0, mavlink.MAV_PARAM_TYPE_REAL32)
    u.mav.command_long_send(sysid, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, 1, 4, 6, 0, 0, 0, 0)
    u.mav.set_mode_send(sysid, 1, LAND_CUSTOM_MODE)
    u.mav.param_request_list_send(sysid, 1)
    got = []
    deadline = time.monotonic() + 1.5
    while time.monotonic() < deadline:
        msg = u.recv_match(blocking=True, timeout=0.2)
        if msg is not None:
            got.append(msg.get_type())
    return got


def all_param_names(m, timeout=10.0):
    drain(m)
    m.mav.param_request_list_send(m.target_system, m.target_component)
    names, count = set(), None
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and (count is None or len(names) < count):
        p = wait(m, "PARAM_VALUE", timeout=1.0)
        if p is not None:
            names.add(p.param_id)
            count = p.param_count
    assert count is not None and len(names) == count, f"{len(names)} of {count} parameters"
    return names


def test_signed_client_flies_unsigned_refused_replay_refused_key_kept_across_restart():
    with Vehicle(speed=5.0) as v:
        m = signed_client(v, send_setup=True)
        key_file = Path(v.state_dir) / "signing.key"
        deadline = time.monotonic() + 3.0
        while not key_file.exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert key_file.exists(), "the key is not stored"
        assert stat.S_IMODE(os.stat(key_file).st_mode) == 0o600
        assert key_file.read_bytes()[:32] == KEY
        names = all_param_names(m)
        # PX4's own parameters (SDLOG_KEY, SDLOG_EXCH_KEY, UXRCE_DDS_KEY: log
        # encryption and DDS key indices, present in PX4 SITL too) hold no signing key
        px4_own = {"SDLOG_KEY", "SDLOG_EXCH_KEY", "UXRCE_DDS_KEY"}
        assert not any("SIGN" in n or ("KEY" in n and n not in px4_own) for n in names), sorted(names)

        # an unsigned host: nothing happens, nothing comes back
        u = unsigned_client(v)
        assert wait(m, "SYS_STATUS", lambda s: s.onboard_control_sensors_health & 0x10000000, 10.0), "armable"
        assert unsigned_attempts(u, v.sysid) == []
        hb = heartbeat(m)
        assert not armed(hb), "an unsigned arm armed the vehicle"
        assert mode(hb) != "LAND"
        assert param_value(m, "MIS_TAKEOFF_ALT") != 9.0

        # the signed client sets a parameter, arms, takes off
        drain(m)
        m.param_set_send("MIS_TAKEOFF_ALT", 3.0, mavlink.MAV_PARAM_TYPE_REAL32)
        assert wait(m, "PARAM_VALUE", lambda p: p.param_id == "MIS_TAKEOFF_ALT" and p.param_value == 3.0, 3.0)
        assert command(m, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0
        assert command(m, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == 0
        assert wait(m, "HEARTBEAT", lambda h: mode(h) == "LOITER", 20.0), "takeoff ends in LOITER"
        assert abs(rel_alt(m) - 3.0) < 0.5

        # in flight, unsigned: no disarm, no parameter, no LAND
        assert unsigned_attempts(u, v.sysid, disarm_in_flight=True) == []
        hb = heartbeat(m)
        assert armed(hb) and mode(hb) == "LOITER", mode(hb)
        assert param_value(m, "MIS_TAKEOFF_ALT") == 3.0
        assert abs(rel_alt(m) - 3.0) < 0.5

        # a signed PARAM_SET, captured and sent again after a newer one: refused
        captured = bytes(m.mav.param_set_encode(v.sysid, 1, b"MIS_TAKEOFF_ALT", 4.0,
                                                mavlink.MAV_PARAM_TYPE_REAL32).pack(m.mav))
        drain(m)
        m.write(captured)
        assert wait(m, "PARAM_VALUE", lambda p: p.param_id == "MIS_TAKEOFF_ALT" and p.param_value == 4.0, 3.0)
        # each set's echo is rebroadcast 5 ms later (as PX4): let it pass
        time.sleep(0.3)
        drain(m)
        m.param_set_send("MIS_TAKEOFF_ALT", 5.0, mavlink.MAV_PARAM_TYPE_REAL32)
        assert wait(m, "PARAM_VALUE", lambda p: p.param_id == "MIS_TAKEOFF_ALT" and p.param_value == 5.0, 3.0)
        time.sleep(0.3)
        drain(m)
        m.write(captured)
        assert wait(m, "PARAM_VALUE", lambda p: p.param_id == "MIS_TAKEOFF_ALT" and p.param_value == 4.0,
                    1.5) is None, "the replayed PARAM_SET was applied"
        assert param_value(m, "MIS_TAKEOFF_ALT") == 5.0

        # the signed client changes the mode: LAND
        m.mav.command_long_send(v.sysid, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, 1, 4, 6, 0, 0, 0, 0)
        assert wait(m, "HEARTBEAT", lambda h: mode(h) == "LAND", 5.0), "signed LAND"

        # the vehicle's signing timestamps on the GCS link (link id 0) before the restart
        drain(m)
        before = max(signature_of(h)[1] for h in [wait(m, "HEARTBEAT", timeout=3.0) for _ in range(3)])
        assert signature_of(wait(m, "HEARTBEAT", timeout=3.0))[0] == 0
        m.close()
        v.stop()
        stored = key_file.read_bytes()
        assert len(stored) == 40 and stored[:32] == KEY
        stored_ts = struct.unpack("<Q", stored[32:])[0]
        assert stored_ts >= before, "the timestamp stored at shutdown is below one already sent"

        v.start()
        m = signed_client(v, send_setup=False)
        first = signature_of(wait(m, "HEARTBEAT", timeout=5.0))[1]
        # it begins above the stored one by the store interval (10 s)
        assert first > stored_ts + 1_000_000 > before, (first, stored_ts, before)
        assert param_value(m, "MIS_TAKEOFF_ALT") == 5.0
        u = unsigned_client(v)
        assert unsigned_attempts(u, v.sysid) == []
        assert param_value(m, "MIS_TAKEOFF_ALT") == 5.0
        m.close()
        u.close()
