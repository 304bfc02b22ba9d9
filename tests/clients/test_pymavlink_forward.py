"""Forwarding between the links, read by pymavlink against the real
rotorpilot binary as on PX4 SITL, whose MAVLink instances are started with
`-f`: a companion (pymavlink, system 42, component 191) on the API link and a
ground station (pymavlink, 255/190) on the GCS link.

- the companion's STATUSTEXT, DEBUG_VECT and NAMED_VALUE_FLOAT reach the GCS
  byte for byte: the companion's system and component id, its sequence
  number, its CRC;
- a COMMAND_LONG for the vehicle (1/1) is answered and not forwarded; one for
  the GCS's component (heard only on the GCS link) reaches the GCS; one for a
  component heard nowhere reaches no one;
- the companion's HEARTBEAT reaches the GCS while MAV_HB_FORW_EN is 1 (PX4's
  default), and not once the GCS sets it to 0.

Run with the pymavlink venv: `python -m pytest tests/clients/test_pymavlink_forward.py`.
"""

import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle, command, drain  # noqa: E402
from harness import wait_message as wait  # noqa: E402
from test_pymavlink import param_set  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
COMPANION = (42, 191)
GCS = (255, 190)


@pytest.fixture
def vehicle():
    with Vehicle(speed=1.0) as v:
        yield v
        print("rotorpilot log (tail):\n" + v.logs())


def link(port, ids, kind):
    """A pymavlink client on `port` with its own ids; it waits for the
    vehicle's heartbeat, then sends its own (so the link has heard it)."""
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{port}", source_system=ids[0], source_component=ids[1])
    assert m.wait_heartbeat(timeout=5) is not None, "no heartbeat from the vehicle"
    m.mav.heartbeat_send(kind, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE)
    return m


def send(m, msg):
    """Send `msg` from `m`; the bytes as they went out."""
    buf = msg.pack(m.mav)
    m.write(buf)
    return bytes(buf)


def heard(m, kind, src, cond=None, timeout=2.0):
    """The first `kind` message from `src` (system, component) within `timeout` s."""
    return wait(
        m, kind,
        lambda x: (x.get_srcSystem(), x.get_srcComponent()) == src and (cond is None or cond(x)),
        timeout,
    )


def test_a_companions_messages_reach_the_gcs_as_sent_and_commands_go_where_aimed(vehicle):
    gcs = link(vehicle.gcs_port, GCS, mavlink.MAV_TYPE_GCS)
    api = link(vehicle.api_port, COMPANION, mavlink.MAV_TYPE_ONBOARD_CONTROLLER)
    time.sleep(0.3)
    drain(gcs)
    # what MAVSDK's server_utility.send_status_text and a companion's
    # telemetry send: each reaches the GCS exactly as it left the companion
    sent = {
        "STATUSTEXT": send(api, api.mav.statustext_encode(mavlink.MAV_SEVERITY_INFO, b"Hello from the companion")),
        "DEBUG_VECT": send(api, api.mav.debug_vect_encode(b"FWD", 1234, 1.0, 2.0, 3.0)),
        "NAMED_VALUE_FLOAT": send(api, api.mav.named_value_float_encode(1234, b"FWD_NV", 4.5)),
    }
    for kind, buf in sent.items():
        got = heard(gcs, kind, COMPANION)
        assert got is not None, f"{kind} from {COMPANION} never reached the GCS link"
        assert bytes(got.get_msgbuf()) == buf, f"{kind}: not the bytes the companion sent"
    # a command for the vehicle: answered on the API link, not forwarded
    drain(gcs)
    assert command(api, mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION) == \
        mavlink.MAV_RESULT_ACCEPTED
    assert heard(gcs, "COMMAND_LONG", COMPANION, timeout=1.0) is None, "a command for 1/1 was forwarded"
    # a command for the GCS's component, heard only on the GCS link: passed there
    api.mav.command_long_send(*GCS, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0)
    got = heard(gcs, "COMMAND_LONG", COMPANION)
    assert got is not None, "a command for the GCS did not reach it"
    assert (got.target_system, got.target_component) == GCS
    assert wait(api, "COMMAND_ACK", lambda a: a.command == mavlink.MAV_CMD_REQUEST_MESSAGE, 0.5) is None, \
        "the vehicle answered a command aimed at the GCS"
    # a command for a component heard nowhere: dropped
    api.mav.command_long_send(77, 1, mavlink.MAV_CMD_REQUEST_MESSAGE, 0, 148, 0, 0, 0, 0, 0, 0)
    assert heard(gcs, "COMMAND_LONG", COMPANION, timeout=1.0) is None
    # and the other way: the GCS's text reaches the companion
    drain(api)
    buf = send(gcs, gcs.mav.statustext_encode(mavlink.MAV_SEVERITY_NOTICE, b"Hello from the GCS"))
    got = heard(api, "STATUSTEXT", GCS)
    assert got is not None and bytes(got.get_msgbuf()) == buf


def test_heartbeats_are_forwarded_until_mav_hb_forw_en_is_0(vehicle):
    gcs = link(vehicle.gcs_port, GCS, mavlink.MAV_TYPE_GCS)
    api = link(vehicle.api_port, COMPANION, mavlink.MAV_TYPE_ONBOARD_CONTROLLER)
    drain(gcs)
    api.mav.heartbeat_send(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    assert heard(gcs, "HEARTBEAT", COMPANION) is not None, \
        "the companion's HEARTBEAT did not reach the GCS (MAV_HB_FORW_EN is 1)"
    p = param_set(gcs, "MAV_HB_FORW_EN", 0, mavlink.MAV_PARAM_TYPE_INT32)
    assert p is not None and p.param_value == 0.0
    drain(gcs)
    api.mav.heartbeat_send(mavlink.MAV_TYPE_ONBOARD_CONTROLLER, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    assert heard(gcs, "HEARTBEAT", COMPANION, timeout=1.5) is None, "forwarded with MAV_HB_FORW_EN 0"
    # the other messages still go
    buf = send(api, api.mav.statustext_encode(mavlink.MAV_SEVERITY_INFO, b"still here"))
    got = heard(gcs, "STATUSTEXT", COMPANION)
    assert got is not None and bytes(got.get_msgbuf()) == buf
