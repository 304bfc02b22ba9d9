"""The MAVLink mission protocol from the client side, with pymavlink: what a
ground-station script does to upload, download and clear a plan, plus a
lossy UDP relay to put between a client and the vehicle. Used by the client
tests and by tools/bench_mission.py. Every wait is bounded.

Items travel as MISSION_ITEM (float degrees, what `mavwp.MAVWPLoader` makes)
or MISSION_ITEM_INT (degE7, what MAVSDK and MAVProxy send); `Item` holds
degrees as Python floats, and `same_plan` compares a plan sent one way with
one read back another way, allowing exactly for what each encoding rounds.
"""

import math
import os
import random
import select
import socket
import struct
import threading
import time
from dataclasses import dataclass, replace

# MISSION_COUNT, MISSION_ACK and MISSION_ITEM carry mission_type only in
# MAVLink 2; pymavlink picks the dialect module when mavutil is imported
os.environ["MAVLINK20"] = "1"
from pymavlink import mavutil  # noqa: E402

if not mavutil.mavlink20():
    mavutil.set_dialect(mavutil.current_dialect)
mavlink = mavutil.mavlink

MISSION, FENCE, RALLY = 0, 1, 2
# frames whose x/y are latitude/longitude (float: 0 3 10; int: 5 6 11)
GLOBAL_FRAMES = {0, 3, 10, 5, 6, 11}
ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
RESULT_NAMES = {v.name: k for k, v in mavlink.enums["MAV_MISSION_RESULT"].items()}
STATE_NAMES = {1: "NO_MISSION", 2: "NOT_STARTED", 3: "ACTIVE", 4: "PAUSED", 5: "COMPLETE"}


def f32(v):
    """`v` as a MAVLink float field carries it."""
    return struct.unpack("<f", struct.pack("<f", v))[0]


@dataclass(frozen=True)
class Item:
    """One mission item; x/y in degrees for global frames, raw otherwise."""

    command: int
    frame: int = 3
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    p3: float = 0.0
    p4: float = 0.0
    autocontinue: int = 1
    current: int = 0

    def is_global(self):
        return self.frame in GLOBAL_FRAMES


def waypoint(lat, lon, alt, hold=0.0, accept=1.0, yaw=math.nan, frame=3):
    return Item(16, frame, lat, lon, alt, hold, accept, 0.0, yaw)


def distance_m(lat_a, lon_a, lat_b, lon_b):
    """Horizontal distance between two nearby points (flat earth, as the vehicle)."""
    r = 6_371_000.0
    north = math.radians(lat_a - lat_b) * r
    east = math.radians(lon_a - lon_b) * r * math.cos(math.radians(0.5 * (lat_a + lat_b)))
    return math.hypot(north, east)


def offset(lat, lon, north_m, east_m):
    """The point `north_m`, `east_m` from lat/lon (flat earth, as the vehicle)."""
    r = 6_371_000.0
    return (lat + math.degrees(north_m / r), lon + math.degrees(east_m / (r * math.cos(math.radians(lat)))))


def survey(n, home, north=0.0, alt=10.0, side=30.0):
    """A mission of `n` items: a takeoff at `home`, then waypoints around a
    `side` m square `north` m north of it (each a little further east and at
    one of three altitudes, so that no two items are alike)."""
    items = [Item(22, 3, *home, alt, math.nan, math.nan, math.nan, math.nan)]
    for k in range(n - 1):
        corner = ((0, 0), (1, 0), (1, 1), (0, 1))[k % 4]
        lat, lon = offset(*home, north + side * corner[0], side * corner[1] + k * 0.37)
        items.append(waypoint(lat, lon, alt + k % 3, hold=0.0, accept=2.0))
    return items


def item_message(mav, it, seq, int_mode, mission_type=MISSION, target=(0, 0)):
    """The MISSION_ITEM(_INT) message for `it` at `seq` (not sent)."""
    current = 1 if seq == 0 else it.current
    if int_mode:
        x, y = (round(it.x * 1e7), round(it.y * 1e7)) if it.is_global() else (int(it.x), int(it.y))
        return mavlink.MAVLink_mission_item_int_message(
            *target, seq, it.frame, it.command, current, it.autocontinue,
            it.p1, it.p2, it.p3, it.p4, x, y, it.z, mission_type)
    return mavlink.MAVLink_mission_item_message(
        *target, seq, it.frame, it.command, current, it.autocontinue,
        it.p1, it.p2, it.p3, it.p4, it.x, it.y, it.z, mission_type)


def from_message(msg):
    """An `Item` from a MISSION_ITEM or MISSION_ITEM_INT."""
    x, y = msg.x, msg.y
    if msg.get_type() == "MISSION_ITEM_INT" and msg.frame in GLOBAL_FRAMES:
        x, y = x / 1e7, y / 1e7
    return Item(msg.command, msg.frame, x, y, msg.z, msg.param1, msg.param2, msg.param3, msg.param4,
                msg.autocontinue, msg.current)


def _ulp32(v):
    """The float32 step at |v|."""
    bits = struct.unpack("<i", struct.pack("<f", abs(v)))[0]
    return struct.unpack("<f", struct.pack("<i", bits + 1))[0] - abs(f32(v))


def _same_float(a, b):
    return (math.isnan(a) and math.isnan(b)) or f32(a) == f32(b)


def _same_xy(sent, got, is_global, sent_int, got_int):
    if not is_global:
        return abs(sent - got) <= _ulp32(sent)
    if sent_int and got_int:
        return round(got * 1e7) == round(sent * 1e7)
    if not sent_int and not got_int:
        return f32(got) == f32(sent)
    if got_int:
        # float degrees stored as degE7: rounded or truncated
        return abs(round(got * 1e7) - f32(sent) * 1e7) <= 1.0
    stored = round(sent * 1e7) / 1e7
    return abs(got - stored) <= _ulp32(stored)


def item_difference(sent, got, sent_int, got_int):
    """None if `got` (read back as int or as float items) is `sent` (sent as
    int or as float items), else what differs. Exact, except that latitude and
    longitude read back in the other encoding may differ by what that
    encoding rounds (one degE7 unit, or one float32 step)."""
    for f in ("command", "frame", "autocontinue"):
        if getattr(sent, f) != getattr(got, f):
            return f"{f} {getattr(sent, f)} != {getattr(got, f)}"
    for f in ("p1", "p2", "p3", "p4", "z"):
        if not _same_float(getattr(sent, f), getattr(got, f)):
            return f"{f} {getattr(sent, f)!r} != {getattr(got, f)!r}"
    for f in ("x", "y"):
        if not _same_xy(getattr(sent, f), getattr(got, f), sent.is_global(), sent_int, got_int):
            return f"{f} {getattr(sent, f)!r} (sent) != {getattr(got, f)!r}"
    return None


def plan_difference(sent, got, sent_int=True, got_int=True):
    """None if the plans are the same item for item, else the first difference."""
    if len(sent) != len(got):
        return f"{len(got)} items, not {len(sent)}"
    for i, (a, b) in enumerate(zip(sent, got)):
        d = item_difference(a, b, sent_int, got_int)
        if d:
            return f"item {i}: {d}"
    return None


class Client:
    """A pymavlink connection used as a mission client. `url` is any pymavlink
    connection string; a udpout client says hello first so the vehicle learns it."""

    def __init__(self, url, sysid=255, compid=190, hello=True, heartbeat_timeout=5.0):
        self.sysid, self.compid = sysid, compid
        self.m = mavutil.mavlink_connection(url, source_system=sysid, source_component=compid)
        self.mav = self.m.mav
        deadline = time.monotonic() + heartbeat_timeout
        hb = None
        while hb is None and time.monotonic() < deadline:
            if hello:
                self.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
            hb = self.m.recv_match(type="HEARTBEAT", blocking=True, timeout=0.3)
            if hb is not None and hb.get_srcComponent() != 1:
                hb = None
        if hb is None:
            raise TimeoutError(f"no vehicle heartbeat on {url}")
        self.target = (hb.get_srcSystem(), 1)

    def close(self):
        self.m.close()

    def drain(self, linger=0.0):
        """Read away what is queued, and what comes for `linger` more seconds
        (stale answers to a transfer given up: the streams never pause)."""
        end = time.monotonic() + linger
        while True:
            while self.m.recv_match(blocking=False) is not None:
                pass
            left = end - time.monotonic()
            if left <= 0:
                return
            self.m.recv_match(blocking=True, timeout=min(left, 0.05))

    def for_me(self, msg):
        return msg.target_system == self.sysid and msg.target_component in (self.compid, 0)

    def recv(self, types, timeout):
        """The next message of `types` aimed at this client, or None."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            msg = self.m.recv_match(type=types, blocking=True, timeout=min(left, 0.1))
            if msg is not None and (not hasattr(msg, "target_system") or self.for_me(msg)):
                return msg

    def ack(self, result=ACCEPTED, mission_type=MISSION):
        self.mav.mission_ack_send(*self.target, result, mission_type)

    def upload(self, items, mission_type=MISSION, budget=10.0, count_retry=0.5, item_retry=0.15, answer="int"):
        """Upload `items` and return the vehicle's MISSION_ACK result, or None
        when `budget` seconds ran out (then MISSION_ACK CANCELLED goes, three
        times). Every request is answered with MISSION_ITEM_INT (`answer`
        "int", as MAVSDK and MAVProxy), or MISSION_ITEM ("float", as
        MAVWPLoader), or in kind (None: MISSION_REQUEST with MISSION_ITEM,
        MISSION_REQUEST_INT with MISSION_ITEM_INT). Robust to loss: MISSION_COUNT goes again until the
        request for item 0 comes, an item goes again when no request for the
        next came within `item_retry`, and the last one again until the ACK
        comes. A request for another item before the one for item 0 is left
        alone: it belongs to a transfer this client gave up."""
        n = len(items)
        # a client that has not been reading has a full socket buffer, and the
        # kernel drops what comes next (the answer to the count among it)
        self.drain()
        self.mav.mission_count_send(*self.target, n, mission_type)
        deadline = time.monotonic() + budget
        sent_count = time.monotonic()
        started = False
        last = None  # (message, time sent)
        while time.monotonic() < deadline:
            msg = self.recv(["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"], 0.02)
            now = time.monotonic()
            if msg is None:
                if not started and now - sent_count > count_retry:
                    self.mav.mission_count_send(*self.target, n, mission_type)
                    sent_count = now
                elif last is not None and item_retry and now - last[1] > item_retry:
                    self.mav.send(last[0])
                    last = (last[0], now)
                continue
            if msg.mission_type != mission_type:
                continue
            if msg.get_type() == "MISSION_ACK":
                return msg.type
            if not started and msg.seq != 0:
                continue
            started = True
            if msg.seq >= n:
                continue
            int_mode = msg.get_type() == "MISSION_REQUEST_INT" if answer is None else answer == "int"
            reply = item_message(self.mav, items[msg.seq], msg.seq, int_mode, mission_type, self.target)
            self.mav.send(reply)
            last = (reply, now)
        for _ in range(3):
            self.ack(mavlink.MAV_MISSION_OPERATION_CANCELLED, mission_type)
        return None

    def download(self, mission_type=MISSION, int_mode=True, timeout=10.0, retry=0.3):
        """The vehicle's plan of `mission_type` as a list of `Item`, read one
        item at a time (MISSION_REQUEST_INT, or MISSION_REQUEST with
        `int_mode` False), with retries; raises TimeoutError after `timeout`."""
        self.drain()
        deadline = time.monotonic() + timeout
        count = None
        while count is None:
            if time.monotonic() > deadline:
                raise TimeoutError("no MISSION_COUNT")
            self.mav.mission_request_list_send(*self.target, mission_type)
            c = self.recv("MISSION_COUNT", retry)
            if c is not None and c.mission_type == mission_type:
                count = c.count
        items = []
        want = "MISSION_ITEM_INT" if int_mode else "MISSION_ITEM"
        send = self.mav.mission_request_int_send if int_mode else self.mav.mission_request_send
        while len(items) < count:
            seq = len(items)
            if time.monotonic() > deadline:
                raise TimeoutError(f"item {seq} of {count} did not come")
            send(*self.target, seq, mission_type)
            t_sent = time.monotonic()
            while time.monotonic() - t_sent < retry:
                it = self.recv([want, "MISSION_ACK"], retry)
                if it is None:
                    break
                if it.get_type() == "MISSION_ACK":
                    raise RuntimeError(f"download refused: MISSION_ACK {it.type}")
                if it.seq == seq and it.mission_type == mission_type:
                    items.append(from_message(it))
                    break
        self.ack(ACCEPTED, mission_type)
        return items

    def clear(self, mission_type=MISSION, timeout=3.0):
        """MISSION_CLEAR_ALL; the MISSION_ACK result, or None."""
        self.drain()
        self.mav.mission_clear_all_send(*self.target, mission_type)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            a = self.recv("MISSION_ACK", deadline - time.monotonic())
            if a is not None and a.mission_type == mission_type:
                return a.type
        return None


class LossyRelay:
    """A UDP relay on 127.0.0.1 between one client and a vehicle link that
    drops each datagram with probability `drop`, each way, from random
    generators with fixed seeds. The vehicle sends to `vehicle_port` (give it
    as the link's remote); the client talks to `client_port`."""

    def __init__(self, vehicle_addr, drop=0.3, seed=1):
        self.vehicle_addr = vehicle_addr
        self.drop = drop
        self.rng_up = random.Random(seed)
        self.rng_down = random.Random(seed + 1)
        self.to_vehicle = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.to_vehicle.bind(("127.0.0.1", 0))
        self.to_client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.to_client.bind(("127.0.0.1", 0))
        for s in (self.to_vehicle, self.to_client):
            s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 1 << 20)
        self.vehicle_port = self.to_vehicle.getsockname()[1]
        self.client_port = self.to_client.getsockname()[1]
        self.client = None
        self.counts = {"up": [0, 0], "down": [0, 0]}  # [passed, dropped]
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def start(self):
        self._thread.start()
        return self

    def _run(self):
        socks = [self.to_vehicle, self.to_client]
        while not self._stop.is_set():
            ready, _, _ = select.select(socks, [], [], 0.1)
            for s in ready:
                try:
                    data, addr = s.recvfrom(65536)
                except OSError:
                    continue
                if s is self.to_client:
                    self.client = addr
                    keep = self.rng_up.random() >= self.drop
                    self.counts["up"][0 if keep else 1] += 1
                    if keep:
                        self.to_vehicle.sendto(data, self.vehicle_addr)
                elif self.client is not None:
                    keep = self.rng_down.random() >= self.drop
                    self.counts["down"][0 if keep else 1] += 1
                    if keep:
                        self.to_client.sendto(data, self.client)

    def stop(self):
        self._stop.set()
        self._thread.join(2)
        self.to_vehicle.close()
        self.to_client.close()


def renumbered(items, **changes):
    """`items` with fields changed on every item (a helper for variants)."""
    return [replace(it, **changes) for it in items]
