"""pymavlink as a virtual joystick (QGroundControl's, or a script's) against
the real rotorpilot binary: MANUAL_CONTROL streamed at 20 Hz, Position mode
(POSCTL) flown with the sticks — climb with throttle, fly forward with
pitch, seen in LOCAL_POSITION_NED — then the sticks stop and the vehicle
returns after 5 s in Hold (NAV_RCL_ACT default, COM_FAIL_ACT_T; AUTO.RTL in
the heartbeat). Manual modes are
refused without manual control, as PX4 refuses them. The vehicle runs at
5x: the manual-control loss timer (COM_RC_LOSS_T) then runs on the wall
clock, so the script needs no scaled parameter. Every wait is bounded.

Run with the pymavlink venv: `python -m pytest tests/clients/test_pymavlink_manual.py`.
"""

import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from harness import Vehicle, drain  # noqa: E402

from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
SPEED = 5.0
STICK_PERIOD_S = 0.05
# PX4 main modes
POSCTL, AUTO, STABILIZED = 3, 4, 7
RTL_SUB = 5


@pytest.fixture
def vehicle():
    with Vehicle(speed=SPEED) as v:
        yield v
        print("rotorpilot log (tail):\n" + v.logs())


def connect(v):
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=255)
    assert m.wait_heartbeat(timeout=5) is not None, "no heartbeat"
    return m


class Joystick:
    """Sticks in MANUAL_CONTROL units (x pitch, y roll, r yaw: -1000..1000;
    z throttle 0..1000, 500 centred), sent every STICK_PERIOD_S while `on`
    by whoever waits through `wait`."""

    def __init__(self, m):
        self.m = m
        self.x = self.y = self.r = 0
        self.z = 500
        self.on = False
        self.last = 0.0

    def send(self):
        self.m.mav.manual_control_send(self.m.target_system, self.x, self.y, self.z, self.r, 0)
        self.last = time.monotonic()

    def tick(self):
        if self.on and time.monotonic() - self.last >= STICK_PERIOD_S:
            self.send()

    def wait(self, types, cond=lambda msg: True, timeout=5.0):
        """The first message of `types` meeting `cond` within `timeout` s, sticks flowing meanwhile."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.tick()
            msg = self.m.recv_match(type=types, blocking=True, timeout=0.02)
            if msg is not None and cond(msg):
                return msg
        return None

    def command(self, cmd, *params, timeout=3.0):
        p = list(params) + [0.0] * (7 - len(params))
        drain(self.m)
        self.m.mav.command_long_send(self.m.target_system, self.m.target_component, cmd, 0, *p)
        ack = self.wait("COMMAND_ACK", lambda a: a.command == cmd, timeout)
        assert ack is not None, f"no COMMAND_ACK for {cmd}"
        return ack.result

    def set_mode(self, main, sub=0):
        return self.command(mavlink.MAV_CMD_DO_SET_MODE, 1, main, sub)


def main_sub(hb):
    return (hb.custom_mode >> 16) & 0xFF, (hb.custom_mode >> 24) & 0xFF


def test_position_mode_flown_with_a_virtual_joystick_then_lost(vehicle):
    m = connect(vehicle)
    js = Joystick(m)
    # no manual control yet: PX4 refuses the manual modes
    assert js.set_mode(POSCTL) == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    assert js.set_mode(STABILIZED) == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    assert js.wait("STATUSTEXT", lambda s: "no manual control" in s.text, 2.0) is not None
    # sticks centred and streaming: Position is accepted and shown, arming too
    js.on = True
    js.send()
    assert js.wait("SYS_STATUS", lambda s: s.onboard_control_sensors_health & 0x10000000, 10.0), "armable"
    assert js.set_mode(POSCTL) == mavlink.MAV_RESULT_ACCEPTED
    assert js.wait("HEARTBEAT", lambda h: h.get_srcComponent() == 1 and main_sub(h) == (POSCTL, 0), 3.0)
    assert js.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == mavlink.MAV_RESULT_ACCEPTED
    # throttle 0.6 of the way up climbs ((0.6 - 0.1) / 0.9 x 3 m/s)
    js.z = 800
    up = js.wait("LOCAL_POSITION_NED", lambda p: p.z < -5.0, 15.0)
    assert up is not None, "climbs with throttle"
    js.z = 500
    level = js.wait("LOCAL_POSITION_NED", lambda p: abs(p.vz) < 0.1, 10.0)
    assert level is not None, "centred throttle holds the altitude"
    # pitch forward 0.6: (0.6 - 0.1) / 0.9 x MPC_VEL_MANUAL (10 m/s) = 5.6 m/s along the heading (north)
    x0 = level.x
    js.x = 600
    fast = js.wait("LOCAL_POSITION_NED", lambda p: p.vx > 5.3, 10.0)
    assert fast is not None, "flies forward"
    assert abs(fast.vx - 50.0 / 9.0) < 0.3 and abs(fast.vy) < 0.3, (fast.vx, fast.vy)
    far = js.wait("LOCAL_POSITION_NED", lambda p: p.x > x0 + 20.0, 10.0)
    assert far is not None, "moves 20 m forward"
    assert abs(far.z - level.z) < 0.5, "keeps the altitude"
    # centred: stops
    js.x = 0
    assert js.wait("LOCAL_POSITION_NED", lambda p: abs(p.vx) < 0.1 and p.x > x0 + 20.0, 10.0) is not None
    # the sticks stop: after COM_RC_LOSS_T (0.5 s) the vehicle holds, and
    # returns (NAV_RCL_ACT 2) after PX4's COM_FAIL_ACT_T (5 s), both on the
    # wall clock above real time
    js.on = False
    text = js.wait("STATUSTEXT", lambda s: s.text == "Manual control lost", 3.0)
    assert text is not None and text.severity == mavlink.MAV_SEVERITY_CRITICAL
    hold = js.wait("STATUSTEXT", lambda s: s.text == "Failsafe: manual control lost, Return in 5 s", 3.0)
    assert hold is not None, "holds first"
    held = time.monotonic()
    rtl = js.wait("HEARTBEAT", lambda h: h.get_srcComponent() == 1 and main_sub(h) == (AUTO, RTL_SUB), 8.0)
    assert rtl is not None, "returns"
    assert held - js.last >= 0.45, "not before COM_RC_LOSS_T after the last sticks"
    assert time.monotonic() - held >= 4.9, "not before COM_FAIL_ACT_T"
    home_bound = js.wait("LOCAL_POSITION_NED", lambda p: p.vx < -1.0, 20.0)
    assert home_bound is not None, "flies back towards home"
    # a manual mode without manual control is refused again
    assert js.set_mode(POSCTL) == mavlink.MAV_RESULT_TEMPORARILY_REJECTED
