"""A fleet in one process (`rotorpilot --count N`) against real clients, as
a PX4 SITL user runs several instances: each vehicle on PX4's
ports for its instance, the whole fleet reporting to one ground station on
UDP 14550.

- A fleet of 4 on PX4's default ports: MAVSDK flies a mission on vehicle 2
  through its API port (udpin://0.0.0.0:14542, what a script for PX4 SITL
  instance 2 uses) while pymavlink arms, takes off and lands vehicle 3 on
  its API port 14543; a ground station on 14550 sees every vehicle, and
  vehicles 0 and 1 stay disarmed where they were spawned.
- A fleet of 32: one pymavlink socket on 14550 hears 32 heartbeats, system
  ids 1..32 each from its own GCS port 18570+i, and arms and takes off
  every vehicle, each command addressed by target_system and sent to that
  vehicle's address (as QGroundControl does); all 32 report in the air.

These tests need UDP 14550 and PX4's instance ports free (they fail saying
which port is taken); run them one file at a time. Run with the MAVSDK 3
venv (it holds MAVSDK and pymavlink):
`python -m pytest tests/clients/test_fleet.py`.
"""

import asyncio
import math
import socket
import sys
import threading
import time
from contextlib import closing
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "mavsdk_examples"))
from harness import FILTER_HEIGHT_DRIFT_M, Fleet, busy_udp_ports, free_tcp_port  # noqa: E402

import common  # noqa: E402  (mavsdk_examples/common.py: next_matching, sample)
from mavsdk import System  # noqa: E402
from mavsdk.mission import MissionItem, MissionPlan  # noqa: E402
from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
GCS_PORT = 14550
M_PER_DEG = common.M_PER_DEG_LAT
ARMED = mavlink.MAV_MODE_FLAG_SAFETY_ARMED
# SYS_STATUS health: PX4's pre-arm check bit (all checks pass)
PREARM_OK = 0x10000000
# a short RTL for the mission: climb to 10 m, not PX4 SITL's 30 m
SHORT_RTL = {"RTL_RETURN_ALT": 10.0, "RTL_DESCEND_ALT": 10.0}


def need_free(ports, why):
    busy = busy_udp_ports(ports)
    if busy:
        pytest.fail(f"UDP ports {busy} are taken by another process; {why}. Stop it (a ground station, "
                    f"PX4 SITL, another test run) and run this file alone.")


def gcs_socket():
    """A ground station's pymavlink socket on 0.0.0.0:14550, where PX4 SITL
    instances (and the fleet) send their GCS link."""
    need_free([GCS_PORT], "the fleet's vehicles report to a ground station on 14550")
    return mavutil.mavlink_connection(f"udpin:0.0.0.0:{GCS_PORT}", source_system=255, source_component=190)


# HEARTBEAT, SYS_STATUS, GLOBAL_POSITION_INT, COMMAND_ACK, STATUSTEXT
WANTED = {mavlink.MAVLINK_MSG_ID_HEARTBEAT, mavlink.MAVLINK_MSG_ID_SYS_STATUS,
          mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, mavlink.MAVLINK_MSG_ID_COMMAND_ACK,
          mavlink.MAVLINK_MSG_ID_STATUSTEXT}


class Board:
    """What a ground station on 14550 saw, per system id: where it speaks
    from, its last heartbeat, whether it was ever armed, the highest and
    lowest relative altitude and the horizontal positions it reported, its
    COMMAND_ACKs and STATUSTEXTs. `read` takes one datagram's messages."""

    def __init__(self, m):
        self.m = m
        # room for a few seconds of a fleet's stream while the script is busy
        m.port.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
        self.lock = threading.Lock()
        self.addr = {}
        self.heartbeats = {}
        self.last_heartbeat = {}
        self.ever_armed = set()
        self.armable = set()
        self.alt = {}
        self.rel_alt = {}
        self.positions = {}
        self.acks = []
        self.texts = []

    def read(self, timeout=0.2):
        """Read the datagrams waiting (up to `timeout` s for the first)."""
        self.m.port.settimeout(timeout)
        try:
            data, addr = self.m.port.recvfrom(65535)
        except OSError:
            return
        self.m.port.setblocking(False)
        while True:
            self.take(data, addr)
            try:
                data, addr = self.m.port.recvfrom(65535)
            except OSError:
                return

    def take(self, data, addr):
        # the GCS link streams ~270 messages/s per vehicle, most of them
        # attitude and position at 50 Hz, several frames to a datagram (as
        # PX4 packs them): decode only the frames read here (MAVLink 2: the
        # payload length in byte 1, the message id in bytes 7..9)
        msgs, k = [], 0
        while k + 12 <= len(data) and data[k] == 0xFD:
            end = k + 12 + data[k + 1] + (13 if data[k + 2] & 1 else 0)
            if data[k + 7] in WANTED and not data[k + 8] and not data[k + 9]:
                try:
                    msgs += self.m.mav.parse_buffer(data[k:end]) or []
                except mavlink.MAVError:
                    pass
            k = end
        now = time.monotonic()
        with self.lock:
            for msg in msgs:
                s, c = msg.get_srcSystem(), msg.get_srcComponent()
                kind = msg.get_type()
                if c != 1:
                    continue
                self.addr.setdefault(s, set()).add(addr)
                if kind == "HEARTBEAT":
                    self.heartbeats[s] = msg
                    self.last_heartbeat[s] = now
                    if msg.base_mode & ARMED:
                        self.ever_armed.add(s)
                elif kind == "SYS_STATUS" and msg.onboard_control_sensors_health & PREARM_OK:
                    self.armable.add(s)
                elif kind == "GLOBAL_POSITION_INT":
                    h = msg.relative_alt / 1000.0
                    lo, hi = self.alt.get(s, (h, h))
                    self.alt[s] = (min(lo, h), max(hi, h))
                    self.rel_alt[s] = h
                    self.positions.setdefault(s, []).append((msg.lat * 1e-7, msg.lon * 1e-7))
                elif kind == "COMMAND_ACK":
                    self.acks.append((s, msg.command, msg.result))
                elif kind == "STATUSTEXT":
                    self.texts.append((s, msg.text))

    def until(self, cond, timeout, what):
        """Read until `cond()` holds; fail saying `what` after `timeout` wall seconds."""
        deadline = time.monotonic() + timeout
        while not cond():
            if time.monotonic() > deadline:
                raise AssertionError(f"{what() if callable(what) else what} not within {timeout} s")
            self.read()

    def drift_m(self, s):
        """Largest horizontal distance [m] between system `s`'s reported positions."""
        pts = self.positions.get(s, [])
        if not pts:
            return math.inf
        lat0, lon0 = pts[0]
        return max(common.ground_gap_m(lat, lon, lat0, lon0) for lat, lon in pts)


def background(board, stop):
    """Read `board`'s socket on a thread until `stop` is set."""

    def run():
        while not stop.is_set():
            board.read()

    t = threading.Thread(target=run, daemon=True)
    t.start()
    return t


def at(home, north, east):
    """Latitude and longitude `north`, `east` metres from `home`."""
    lat = home.latitude_deg + north / M_PER_DEG
    return lat, home.longitude_deg + east / (M_PER_DEG * math.cos(math.radians(home.latitude_deg)))


def waypoint(lat, lon, alt, speed):
    nan = float("nan")
    return MissionItem(lat, lon, alt, speed, True, nan, nan, MissionItem.CameraAction.NONE, nan, 1.0, 2.0,
                       nan, nan, MissionItem.VehicleAction.NONE)


def fly_mission(api_port, wall_limit):
    """MAVSDK on `udpin://0.0.0.0:API_PORT`: upload two waypoints east of
    home with RTL after, arm, start; returns (home, mission
    progress seen, where it came to rest) once it is back on the ground and
    disarmed."""

    async def main():
        uav = System(port=free_tcp_port())
        await uav.connect(system_address=f"udpin://0.0.0.0:{api_port}")
        try:
            return await asyncio.wait_for(scenario(uav), wall_limit)
        finally:
            uav._stop_mavsdk_server()

    async def scenario(uav):
        await common.next_matching(uav.core.connection_state(), lambda c: c.is_connected, 20, "heartbeat")
        await common.next_matching(
            uav.telemetry.health(), lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable,
            20, "health")
        home = await common.sample(uav.telemetry.home(), "home", 10)
        # east, then south-east, at 8 m: away from the other vehicles' spawn
        # points (3 m apart, north of the origin)
        plan = MissionPlan([waypoint(*at(home, 0, 15), 8.0, 5.0), waypoint(*at(home, -10, 15), 8.0, 5.0)])
        await uav.mission.set_return_to_launch_after_mission(True)
        await uav.mission.upload_mission(plan)
        progress = []

        async def collect():
            async for p in uav.mission.mission_progress():
                progress.append((p.current, p.total))

        watcher = asyncio.ensure_future(collect())
        await uav.action.arm()
        await uav.mission.start_mission()
        await common.next_matching(uav.telemetry.in_air(), bool, 30, "liftoff")

        async def finished():
            while not await uav.mission.is_mission_finished():
                await asyncio.sleep(0.1)

        await asyncio.wait_for(finished(), 60)
        await common.next_matching(uav.telemetry.in_air(), lambda f: not f, 60, "touchdown")
        await common.next_matching(uav.telemetry.armed(), lambda a: not a, 20, "disarm")
        watcher.cancel()
        await asyncio.gather(watcher, return_exceptions=True)
        rest = await common.sample(uav.telemetry.position(), "position")
        return home, progress, rest

    return asyncio.run(main())


def command(m, target, cmd, *params, timeout=5.0):
    """COMMAND_LONG to (target, 1) on pymavlink connection `m`; its ACK's result."""
    p = list(params) + [0.0] * (7 - len(params))
    m.mav.command_long_send(target, 1, cmd, 0, *p)
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        a = m.recv_match(type="COMMAND_ACK", blocking=True, timeout=0.5)
        if a is not None and a.command == cmd:
            assert a.get_srcSystem() == target, f"ACK from system {a.get_srcSystem()}, not {target}"
            return a.result
    raise AssertionError(f"no COMMAND_ACK for {cmd} from system {target}")


def fly_up_and_down(api_port, sysid, result):
    """pymavlink on vehicle `sysid`'s API port (udpin:0.0.0.0:API_PORT): arm,
    take off, land; into `result` the highest relative altitude [m] and
    whether it ended disarmed on the ground (or the error)."""
    m = mavutil.mavlink_connection(f"udpin:0.0.0.0:{api_port}", source_system=254, source_component=191)
    try:
        hb = m.wait_heartbeat(timeout=10)
        assert hb is not None, f"no heartbeat on {api_port}"
        result["heartbeat_from"] = hb.get_srcSystem()
        ok = m.recv_match(type="SYS_STATUS", condition=f"SYS_STATUS.onboard_control_sensors_health & {PREARM_OK}",
                          blocking=True, timeout=20)
        assert ok is not None, "never armable"
        assert command(m, sysid, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1) == 0, "arm"
        # p7 below home: PX4 takes off to home + MIS_TAKEOFF_ALT
        assert command(m, sysid, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, float("nan"), float("nan"), float("nan"),
                       0) == 0, "takeoff"
        top, deadline = 0.0, time.monotonic() + 30
        while top < 2.0 and time.monotonic() < deadline:
            g = m.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=0.5)
            if g is not None and g.get_srcSystem() == sysid:
                top = max(top, g.relative_alt / 1000.0)
        result["top_m"] = top
        assert top >= 2.0, f"vehicle {sysid} did not climb: {top:.2f} m"
        assert command(m, sysid, mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, float("nan"), float("nan"), float("nan"),
                       float("nan")) == 0, "land"
        down = m.recv_match(type="HEARTBEAT", condition=f"not HEARTBEAT.base_mode & {ARMED}", blocking=True,
                            timeout=60)
        g = m.recv_match(type="GLOBAL_POSITION_INT", blocking=True, timeout=5)
        result["landed"] = down is not None and g is not None and g.relative_alt / 1000.0 < 0.5
    except Exception as e:  # noqa: BLE001 - reported by the test on the main thread
        result["error"] = repr(e)
    finally:
        m.close()


def test_fleet_of_4_mission_on_2_commands_on_3_others_stay_put():
    """`rotorpilot --count 4 --speed 5` on PX4's default ports: MAVSDK flies
    a mission on vehicle 2 (its API port 14542) while pymavlink flies vehicle
    3 up and down (its API port 14543); the ground station on 14550 hears all
    four, sees 2 and 3 fly, and 0 and 1 never arm, never leave the ground,
    never move, and keep reporting; nothing collides."""
    need_free([14540 + k for k in range(4)], "the fleet's API links send to PX4's 14540+i")
    stop = threading.Event()
    # vehicle 2 keeps the short RTL in its own state directory (ROOT/2)
    with closing(gcs_socket()) as gcs, Fleet(4, speed=5.0, params={2: SHORT_RTL}) as fleet:
        board = Board(gcs)
        reader = background(board, stop)
        try:
            board_until = time.monotonic() + 15
            while len(board.heartbeats) < 4 and time.monotonic() < board_until:
                time.sleep(0.05)
            with board.lock:
                assert sorted(board.heartbeats) == [1, 2, 3, 4], f"heartbeats on 14550 from {sorted(board.heartbeats)}"
            three = {}
            pilot = threading.Thread(target=fly_up_and_down, args=(14543, 4, three), daemon=True)
            pilot.start()
            home, progress, rest = fly_mission(14542, 150)
            pilot.join(90)
            assert not pilot.is_alive(), "pymavlink's flight of vehicle 3 did not end"
            # the others still report at the end
            end = time.monotonic()
            time.sleep(1.5)
        finally:
            stop.set()
            reader.join(5)
            fleet.stop(10)

    print(f"vehicle 2: progress {sorted(set(progress))}; vehicle 3: {three}")
    print(f"ever armed {sorted(board.ever_armed)}; altitude ranges {board.alt}; "
          f"drift {[round(board.drift_m(s), 3) for s in (1, 2)]} m")
    print(f"status texts {board.texts[-10:]}")
    assert "error" not in three, three.get("error")
    assert three["heartbeat_from"] == 4, "port 14543 is vehicle 3's (system id 4)"
    assert three["landed"], "vehicle 3 back on the ground, disarmed"
    # vehicle 2's mission: every item reached, back home (its own: 6 m north of vehicle 0's)
    assert progress and progress[-1] == (2, 2), progress
    assert common.ground_gap_m(rest.latitude_deg, rest.longitude_deg, home.latitude_deg, home.longitude_deg) < 1.5
    lat0, lon0 = board.positions[1][0]
    north = (home.latitude_deg - lat0) * M_PER_DEG
    assert north == pytest.approx(6.0, abs=0.3), "instance 2 spawns 3 m x 2 north of instance 0"
    # the ground station saw it all
    assert {3, 4} <= board.ever_armed, "vehicles 2 and 3 seen armed on 14550"
    assert board.alt[3][1] > 6.0 and board.alt[4][1] > 1.5, "vehicles 2 and 3 seen in the air on 14550"
    for s in (1, 2):
        assert s not in board.ever_armed, f"vehicle {s - 1} armed"
        lo, hi = board.alt[s]
        # on the ground the navigation filter's height moves with GNSS height
        assert hi - lo < FILTER_HEIGHT_DRIFT_M and hi < 0.5, f"vehicle {s - 1} left the ground: {board.alt[s]} m"
        assert board.drift_m(s) < 0.2, f"vehicle {s - 1} moved {board.drift_m(s):.2f} m"
        assert board.last_heartbeat[s] > end - 1.5, f"vehicle {s - 1} went quiet"
        assert len(board.positions[s]) > 100, f"vehicle {s - 1}: few positions on 14550"
    for s, addrs in board.addr.items():
        assert addrs == {("127.0.0.1", 18570 + s - 1)}, f"system {s} speaks from {addrs}"
    assert not [t for t in board.texts if "Collision" in t[1]], board.texts


def send_to(board, sysid, msg):
    """Send `msg` (built with the socket's MAVLink encoder) to vehicle `sysid`'s
    GCS address, learned from its heartbeat."""
    mav = board.m.mav
    (addr,) = board.addr[sysid]
    board.m.port.sendto(msg.pack(mav), addr)
    mav.seq = (mav.seq + 1) % 256


def command_all(board, ids, cmd, *params, timeout=20.0):
    """COMMAND_LONG `cmd` to each of `ids` (target_system = its id), resent
    every second to those not yet answered; the results by id."""
    p = list(params) + [0.0] * (7 - len(params))
    mav = board.m.mav
    got = {}
    deadline = time.monotonic() + timeout
    seen = len(board.acks)
    while set(got) != set(ids) and time.monotonic() < deadline:
        for s in ids:
            if s not in got:
                send_to(board, s, mav.command_long_encode(s, 1, cmd, 0, *p))
        until = time.monotonic() + 1.0
        while set(got) != set(ids) and time.monotonic() < until:
            board.read(0.1)
            for s, c, r in board.acks[seen:]:
                if c == cmd and s in ids:
                    got[s] = r
            seen = len(board.acks)
    return got


def test_fleet_of_32_every_heartbeat_own_id_all_take_off_from_one_script():
    """`rotorpilot --count 32 --speed 10`: on one pymavlink socket on
    14550, 32 heartbeats with system ids 1..32, system i+1 from port 18570+i;
    one script arms and takes off each (commands by target_system, to the
    address its heartbeat came from); every vehicle acknowledges its own
    commands and reports armed and above 1.5 m. The API links stay quiet
    (`--api-remote none`): PX4's 14540..14549 are left to whoever uses them."""
    n = 32
    ids = list(range(1, n + 1))
    with closing(gcs_socket()) as gcs, Fleet(n, speed=10.0, api_remote="none") as fleet:
        board = Board(gcs)
        try:
            board.until(lambda: len(board.heartbeats) >= n, 20,
                        lambda: f"{n} heartbeats (heard {sorted(board.heartbeats)})")
            # 2 s more: a stray system id would show up
            t = time.monotonic() + 2
            while time.monotonic() < t:
                board.read()
            assert sorted(board.heartbeats) == ids, f"system ids heard: {sorted(board.heartbeats)}"
            for s in ids:
                assert board.addr[s] == {("127.0.0.1", 18570 + s - 1)}, f"system {s} speaks from {board.addr[s]}"
                hb = board.heartbeats[s]
                assert hb.type == mavlink.MAV_TYPE_QUADROTOR and hb.autopilot == mavlink.MAV_AUTOPILOT_PX4
            assert not board.ever_armed, f"armed before any command: {board.ever_armed}"

            # a ground station's heartbeat to each, as QGroundControl sends
            for s in ids:
                send_to(board, s, board.m.mav.heartbeat_encode(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID,
                                                               0, 0, 0))
            board.until(lambda: board.armable >= set(ids), 30, "every vehicle armable")
            armed = command_all(board, ids, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
            assert armed == {s: 0 for s in ids}, f"arm results {armed}"
            nan = float("nan")
            took = command_all(board, ids, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, nan, nan, nan, 0)
            assert took == {s: 0 for s in ids}, f"takeoff results {took}"

            def airborne():
                with board.lock:
                    return [s for s in ids if board.rel_alt.get(s, 0.0) > 1.5
                            and board.heartbeats[s].base_mode & ARMED]

            try:
                board.until(lambda: len(airborne()) == n, 60, "every vehicle in the air")
            finally:
                print(f"in the air: {len(airborne())} of {n}; altitudes "
                      f"{ {s: round(board.rel_alt.get(s, 0.0), 2) for s in ids} }")
        finally:
            fleet.stop(15)
    assert sorted(airborne()) == ids
    assert not [t for t in board.texts if "Collision" in t[1]], board.texts
