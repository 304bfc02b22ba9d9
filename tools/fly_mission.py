#!/usr/bin/env python3
"""Fly a mission file on a rotorpilot vehicle (or PX4 SITL) with plain
pymavlink, for users without MAVSDK: upload the mission (and the geofence and
rally points of a .plan), arm, start the mission, report progress, and wait
until the mission is complete and the vehicle has landed and disarmed.

Files, read as rotorpilot reads them (src/mission/file.rs):
  .plan                      QGroundControl JSON, as MAVSDK's
                             mission_raw.import_qgroundcontrol_mission reads it
  .txt, .waypoints, .mission QGC WPL 110 (MAVProxy `wp save`), every item
                             uploaded, seq 0 included

The upload is the classic MAVLink mission protocol: MISSION_COUNT, then each
MISSION_REQUEST answered with MISSION_ITEM (float degrees) and each
MISSION_REQUEST_INT with MISSION_ITEM_INT (degE7), until MISSION_ACK. A .plan
replaces all three plans on the vehicle (an empty list clears that plan, as
QGroundControl's upload does); a WPL file replaces the one plan it holds.

Examples (vehicle instance 0; this script as the GCS on udpin:0.0.0.0:14550):
    cargo run --release -- --speed 5 &
    python3 tools/fly_mission.py tools/missions/home-square.plan
    python3 tools/fly_mission.py tools/missions/five-waypoints.txt --timeout 600
    python3 tools/fly_mission.py tools/missions/home-square.plan --upload-only
    python3 tools/fly_mission.py tools/missions/five-waypoints.txt --list   # no vehicle needed

Exit status: 0 when the mission completed and the vehicle is down and
disarmed; 1 when the file, the upload, arming or the start failed, or the
vehicle disarmed without completing the mission; 2 on a timeout; 130 on
Ctrl-C. Needs pymavlink (pip install pymavlink==2.4.50) except for --list.
"""

import argparse
import json
import math
import os
import struct
import sys
import time

# MAVLink 2 from the first byte: mission_type (fence, rally) is an extension field.
os.environ.setdefault("MAVLINK20", "1")

MISSION, FENCE, RALLY = 0, 1, 2
TYPE_NAMES = {MISSION: "mission", FENCE: "geofence", RALLY: "rally points"}
LIST_NAMES = {MISSION: "mission", FENCE: "fence", RALLY: "rally"}
FRAME_MISSION = 2
GLOBAL_FRAMES = {0, 3, 5, 6, 10, 11}
POSITIONAL = {16, 17, 18, 19, 21, 22, 31, 5000, 5001, 5002, 5003, 5004, 5100}
MISSION_STATE = {0: "unknown", 1: "no mission", 2: "not started", 3: "active", 4: "paused", 5: "complete"}


class Failure(Exception):
    """A failure to report (exit 1)."""


class Timeout(Exception):
    """A deadline passed (exit 2)."""


# ----- reading the files ---------------------------------------------------------------------------


def f32(v):
    """v as the f32 a MAVLink float field carries (overflow to infinity, as Rust's `as f32`)."""
    try:
        return struct.unpack("<f", struct.pack("<f", v))[0]
    except OverflowError:
        return math.copysign(math.inf, v)


def round_half_away(v):
    """std::round / Rust's round: halves away from zero (Python's round() goes to even)."""
    return math.copysign(math.floor(abs(v) + 0.5), v)


def quantise_deg(v):
    """Degrees as MISSION_ITEM_INT carries them: round(v * 1e7) / 1e7 (kept when it cannot be sent)."""
    scaled = round_half_away(v * 1e7) if math.isfinite(v) else v
    if math.isfinite(scaled) and abs(scaled) <= 2**31 - 1:
        return int(scaled) / 1e7
    return v


def item(frame, command, autocontinue, params, x, y, z):
    return {
        "frame": frame,
        "command": command,
        "autocontinue": 1 if autocontinue else 0,
        "params": [f32(p) for p in params],
        "x": x,
        "y": y,
        "z": f32(z),
    }


def plan_fail(path, field, problem):
    raise Failure(f"{path}: {field}: {problem}")


def plan_number(path, field, v, null=None):
    if v is None and null is not None:
        return null
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        plan_fail(path, field, f"expected a number{' or null' if null is not None else ''}, found {json.dumps(v)}")
    return float(v)


def plan_simple(path, at, j):
    for key in ("command", "autoContinue", "frame", "params"):
        if key not in j:
            plan_fail(path, f"{at}.{key}", "missing")
    params = j["params"]
    if not isinstance(params, list) or len(params) != 7:
        plan_fail(path, f"{at}.params", "expected 7 params (p1 to p4, latitude / x, longitude / y, altitude / z)")
    command, frame = int(j["command"]), int(j["frame"])
    p = [None if v is None else plan_number(path, f"{at}.params[{k}]", v) for k, v in enumerate(params)]

    def coordinate(k, what):
        v = p[k]
        if v is None:
            if command in POSITIONAL and frame in GLOBAL_FRAMES:
                plan_fail(path, f"{at}.params[{k}]", f"null {what}: command {command} needs a position")
            return 0.0
        if frame == FRAME_MISSION:
            # MAVSDK: static_cast<int32_t>(asFloat()), cut towards zero
            v = f32(v)
            return float(max(-(2**31), min(2**31 - 1, math.trunc(v)))) if math.isfinite(v) else 0.0
        return quantise_deg(v) if frame in GLOBAL_FRAMES else v

    nan = math.nan
    return item(
        frame,
        command,
        bool(j["autoContinue"]),
        [nan if v is None else v for v in p[:4]],
        coordinate(4, "latitude"),
        coordinate(5, "longitude"),
        nan if p[6] is None else p[6],
    )


def check_version(path, section, obj, expected, what):
    v = obj.get("version") if isinstance(obj, dict) else None
    if v != expected:
        field = f"{section}.version" if section else "version"
        plan_fail(path, field, f"{what} version {json.dumps(v)} is not supported (version {expected} is, as in MAVSDK)")


def read_plan(path, text):
    """A QGroundControl .plan as MAVSDK imports it: {MISSION: [...], FENCE: [...], RALLY: [...]}."""
    try:
        root = json.loads(text)
    except ValueError as e:
        raise Failure(f"{path}: not JSON: {e}") from None
    if not isinstance(root, dict):
        plan_fail(path, "(top level)", "expected an object")
    check_version(path, "", root, 1, ".plan file")
    mission = root.get("mission")
    if not isinstance(mission, dict):
        plan_fail(path, "mission", "missing")
    check_version(path, "mission", mission, 2, "mission")
    out = {MISSION: [], FENCE: [], RALLY: []}
    for i, j in enumerate(mission.get("items", [])):
        at = f"mission.items[{i}]"
        kind = j.get("type") if isinstance(j, dict) else None
        if kind == "SimpleItem":
            out[MISSION].append(plan_simple(path, at, j))
        elif kind == "ComplexItem":
            if j.get("complexItemType") != "survey":
                plan_fail(path, f"{at}.complexItemType", f"complex item {json.dumps(j.get('complexItemType'))} is not supported (only \"survey\" version 5 is)")
            if j.get("version") != 5:
                plan_fail(path, f"{at}.version", f"survey version {json.dumps(j.get('version'))} is not supported (version 5 is)")
            subs = (j.get("TransectStyleComplexItem") or {}).get("Items") or []
            if not subs:
                plan_fail(path, f"{at}.TransectStyleComplexItem.Items", "no survey items")
            for k, s in enumerate(subs):
                out[MISSION].append(plan_simple(path, f"{at}.TransectStyleComplexItem.Items[{k}]", s))
        else:
            plan_fail(path, f"{at}.type", f"expected \"SimpleItem\" or \"ComplexItem\", found {json.dumps(kind)}")

    fence = root.get("geoFence")
    if fence is not None:
        check_version(path, "geoFence", fence, 2, "geoFence")
        for i, poly in enumerate(fence.get("polygons", [])):
            inclusion = poly.get("inclusion")
            command = 5001 if inclusion is None or inclusion else 5002
            vertices = poly.get("polygon", [])
            for k, v in enumerate(vertices):
                at = f"geoFence.polygons[{i}].polygon[{k}]"
                lat, lon = (plan_number(path, f"{at}[{n}]", v[n]) for n in (0, 1))
                out[FENCE].append(item(0, command, False, [len(vertices), 0, 0, 0], quantise_deg(lat), quantise_deg(lon), 0))
        for i, c in enumerate(fence.get("circles", [])):
            at = f"geoFence.circles[{i}]"
            if "inclusion" not in c:
                plan_fail(path, f"{at}.inclusion", "missing")
            centre = c["circle"]["center"]
            lat, lon = (plan_number(path, f"{at}.circle.center[{n}]", centre[n]) for n in (0, 1))
            radius = plan_number(path, f"{at}.circle.radius", c["circle"].get("radius"), null=math.nan)
            command = 5003 if c["inclusion"] else 5004
            out[FENCE].append(item(0, command, False, [radius, 0, 0, 0], quantise_deg(lat), quantise_deg(lon), 0))

    rally = root.get("rallyPoints")
    if rally is not None:
        check_version(path, "rallyPoints", rally, 2, "rallyPoints")
        for i, pt in enumerate(rally.get("points", [])):
            at = f"rallyPoints.points[{i}]"
            lat, lon = (plan_number(path, f"{at}[{n}]", pt[n]) for n in (0, 1))
            alt = plan_number(path, f"{at}[2]", pt[2], null=math.nan)
            out[RALLY].append(item(3, 5100, False, [0, 0, 0, 0], quantise_deg(lat), quantise_deg(lon), alt))
    return out


def read_wpl(path, text):
    """QGC WPL 110: {kind: [...]} for the one plan the file holds."""
    lines = text.splitlines()
    if not lines or lines[0].strip() != "QGC WPL 110":
        first = lines[0].strip() if lines else ""
        raise Failure(f"{path}:1: header: expected `QGC WPL 110`, found `{first[:40]}`")
    items = []
    for n, raw in enumerate(lines[1:], start=2):
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        f = line.split()
        if len(f) != 12:
            raise Failure(f"{path}:{n}: line: {len(f)} fields; an item has 12")
        try:
            seq, _current, frame, command = (int(v) for v in f[:4])
            p = [float(v) for v in f[4:8]]
            x, y, z = (float(v) for v in f[8:11])
            autocontinue = int(f[11])
        except ValueError as e:
            raise Failure(f"{path}:{n}: {e}") from None
        if seq != len(items):
            raise Failure(f"{path}:{n}: field 1 (seq): seq {seq} out of order: expected {len(items)}")
        if command == 0 and seq == 0:
            command = 16  # Mission Planner's home item, as MAVWPLoader reads it
        if frame in GLOBAL_FRAMES:
            x, y = quantise_deg(x), quantise_deg(y)
        items.append(item(frame, command, autocontinue == 1, p, x, y, z))
    commands = {i["command"] for i in items}
    if items and commands <= {5000, 5001, 5002, 5003, 5004}:
        return {FENCE: items}
    if items and commands == {5100}:
        return {RALLY: items}
    return {MISSION: items}


def read_mission_file(path):
    try:
        with open(path, encoding="utf-8-sig") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise Failure(f"{path}: cannot read: {e}") from None
    ext = os.path.splitext(path)[1].lower()
    if ext == ".plan" or (ext not in (".txt", ".waypoints", ".mission") and text.lstrip().startswith("{")):
        return read_plan(path, text)
    return read_wpl(path, text)


def print_items(plans):
    for kind in sorted(plans):
        for seq, it in enumerate(plans[kind]):
            params = " ".join(repr(p) for p in it["params"])
            print(
                f"{LIST_NAMES[kind]} {seq}: frame {it['frame']} command {it['command']} autocontinue {it['autocontinue']} "
                f"params {params} x {it['x']!r} y {it['y']!r} z {it['z']!r}"
            )


# ----- talking to the vehicle -----------------------------------------------------------------------


class Vehicle:
    def __init__(self, url, wait_s):
        from pymavlink import mavutil

        self.mavutil = mavutil
        self.mavlink = mavutil.mavlink
        self.m = mavutil.mavlink_connection(url, source_system=255, source_component=190)
        self.armed = False
        self.landed_state = None
        self.mode = None
        # every STATUSTEXT the vehicle sent, in order (a refusal quotes those it gave)
        self.texts = []
        # udpout links must talk first; on udpin this goes nowhere yet
        self.m.mav.heartbeat_send(self.mavlink.MAV_TYPE_GCS, self.mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
        deadline = time.monotonic() + wait_s
        while True:
            hb = self.recv(["HEARTBEAT"], deadline)
            if hb is None:
                raise Failure(f"no vehicle heard on {url} within {wait_s:.0f} s (is it running? right port?)")
            if hb.autopilot != self.mavlink.MAV_AUTOPILOT_INVALID and hb.type != self.mavlink.MAV_TYPE_GCS:
                self.sysid, self.compid = hb.get_srcSystem(), hb.get_srcComponent()
                break
        print(f"vehicle {self.sysid}/{self.compid} on {url}")

    def recv(self, types, deadline):
        """The next message of `types` from the vehicle (None at the deadline); keeps state and prints vehicle text."""
        want = set(types) | {"HEARTBEAT", "STATUSTEXT", "EXTENDED_SYS_STATE"}
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            msg = self.m.recv_match(type=list(want), blocking=True, timeout=min(left, 0.25))
            if msg is None:
                continue
            if hasattr(self, "sysid") and msg.get_srcSystem() != self.sysid:
                continue
            kind = msg.get_type()
            if kind == "HEARTBEAT" and hasattr(self, "sysid") and msg.get_srcComponent() == self.compid:
                self.armed = bool(msg.base_mode & self.mavlink.MAV_MODE_FLAG_SAFETY_ARMED)
                mode = self.mavutil.mode_string_v10(msg)
                if mode != self.mode and self.mode is not None:
                    print(f"  mode {mode}")
                self.mode = mode
            elif kind == "STATUSTEXT":
                print(f"  vehicle: {msg.text}")
                self.texts.append(msg.text)
            elif kind == "EXTENDED_SYS_STATE":
                self.landed_state = msg.landed_state
            if kind in types:
                return msg

    def result_name(self, enum, value):
        e = self.mavlink.enums.get(enum, {})
        return e[value].name if value in e else str(value)

    def command(self, cmd, params, what, timeout=5.0):
        """COMMAND_LONG, resent with a rising confirmation until COMMAND_ACK; fails unless ACCEPTED."""
        p = list(params) + [0.0] * (7 - len(params))
        for confirmation in range(3):
            self.m.mav.command_long_send(self.sysid, self.compid, cmd, confirmation, *p)
            deadline = time.monotonic() + timeout / 3
            while True:
                ack = self.recv(["COMMAND_ACK"], deadline)
                if ack is None:
                    break
                if ack.command != cmd:
                    continue
                if ack.result == self.mavlink.MAV_RESULT_IN_PROGRESS:
                    continue
                if ack.result != self.mavlink.MAV_RESULT_ACCEPTED:
                    raise Failure(f"{what} refused: {self.result_name('MAV_RESULT', ack.result)}")
                return
        raise Failure(f"{what}: no COMMAND_ACK in {timeout:.0f} s")

    def upload(self, kind, items):
        """Upload one plan; an empty one is cleared (MISSION_CLEAR_ALL)."""
        name = TYPE_NAMES[kind]
        mav = self.m.mav
        if not items:
            mav.mission_clear_all_send(self.sysid, self.compid, kind)
            self.wait_ack(kind, name, time.monotonic() + 5.0)
            print(f"{name}: cleared")
            return
        n = len(items)
        sent = set()
        highest = -1
        texts_before = len(self.texts)
        count_tries = 0
        last_heard = time.monotonic()
        mav.mission_count_send(self.sysid, self.compid, n, kind)
        while True:
            msg = self.recv(["MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK"], time.monotonic() + 0.25)
            now = time.monotonic()
            if msg is None:
                if not sent and now - last_heard > 1.5:
                    count_tries += 1
                    if count_tries > 4:
                        raise Failure(f"{name}: the vehicle never asked for an item (MISSION_COUNT sent 5 times)")
                    mav.mission_count_send(self.sysid, self.compid, n, kind)
                    last_heard = now
                elif sent and now - last_heard > 6.0:
                    raise Failure(f"{name}: the vehicle stopped asking after item {highest} of {n}")
                continue
            if getattr(msg, "mission_type", 0) != kind or msg.target_system not in (0, 255):
                continue
            last_heard = now
            if msg.get_type() == "MISSION_ACK":
                if msg.type != self.mavlink.MAV_MISSION_ACCEPTED:
                    self.refused(name, msg.type, texts_before, f"after item {highest} of {n} was sent")
                if highest != n - 1:
                    raise Failure(f"{name}: accepted before item {n - 1} was asked for (protocol error)")
                print(f"{name}: {n} items uploaded")
                return
            seq = msg.seq
            if seq >= n:
                raise Failure(f"{name}: the vehicle asked for item {seq} of {n}")
            it = items[seq]
            current = 1 if seq == 0 else 0
            if msg.get_type() == "MISSION_REQUEST_INT":
                # degE7 in global frames, the value cut to an integer otherwise (as MAVSDK and MAVProxy)
                scale = 1e7 if it["frame"] in GLOBAL_FRAMES else 1.0
                xi = int(round_half_away(it["x"] * scale)) if math.isfinite(it["x"]) else 0
                yi = int(round_half_away(it["y"] * scale)) if math.isfinite(it["y"]) else 0
                mav.mission_item_int_send(
                    self.sysid, self.compid, seq, it["frame"], it["command"], current, it["autocontinue"],
                    *it["params"], xi, yi, it["z"], kind,
                )
            else:
                mav.mission_item_send(
                    self.sysid, self.compid, seq, it["frame"], it["command"], current, it["autocontinue"],
                    *it["params"], it["x"], it["y"], it["z"], kind,
                )
            sent.add(seq)
            highest = max(highest, seq)

    def refused(self, name, result, texts_before, when):
        """Raise the refusal of a plan: the MAV_MISSION_RESULT, and the
        vehicle's own words when it gave any (PX4 and rotorpilot say which
        item and which limit, e.g. "Plan rejected: item 3 at 12488 m >
        RP_ALT_MAX_AMSL"): the ACK names no item, so neither does this but
        through the vehicle's text."""
        # the texts may trail the ACK on the wire (the link's and the flight
        # stack's come apart): listen half a second for them
        self.recv([], time.monotonic() + 0.5)
        said = "; ".join(self.texts[texts_before:])
        why = f"{self.result_name('MAV_MISSION_RESULT', result)}" + (f": the vehicle said \"{said}\"" if said else "")
        raise Failure(f"{name}: refused ({when}): {why}")

    def wait_ack(self, kind, name, deadline):
        while True:
            ack = self.recv(["MISSION_ACK"], deadline)
            if ack is None:
                raise Failure(f"{name}: no MISSION_ACK")
            if getattr(ack, "mission_type", 0) != kind:
                continue
            if ack.type != self.mavlink.MAV_MISSION_ACCEPTED:
                raise Failure(f"{name}: refused: {self.result_name('MAV_MISSION_RESULT', ack.type)}")
            return

    def wait_armable(self, wait_s):
        deadline = time.monotonic() + wait_s
        while True:
            s = self.recv(["SYS_STATUS"], deadline)
            if s is None:
                print("  (no pre-arm OK seen; trying to arm anyway)")
                return
            if s.onboard_control_sensors_health & self.mavlink.MAV_SYS_STATUS_PREARM_CHECK:
                return

    def wait_armed(self, wait_s):
        deadline = time.monotonic() + wait_s
        while not self.armed:
            if self.recv(["HEARTBEAT"], deadline) is None:
                raise Failure("arming was accepted, but the vehicle never reported itself armed")

    def fly(self, count, timeout):
        """Arm, start, report; return when the mission is complete and the vehicle is down and disarmed."""
        self.wait_armable(20.0)
        self.command(self.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [1], "arming")
        self.wait_armed(3.0)
        print("armed")
        # as pymavlink's set_mode_auto(): from the first item
        self.command(self.mavlink.MAV_CMD_MISSION_START, [0, 0], "mission start")
        print(f"mission started ({count} items)")
        deadline = time.monotonic() + timeout
        reached = set()
        last_reached = -1
        current = None
        complete = False
        disarmed_at = None
        down_since = None
        disarm_sent = False
        while True:
            msg = self.recv(["MISSION_CURRENT", "MISSION_ITEM_REACHED", "HEARTBEAT"], deadline)
            if msg is None:
                state = "armed" if self.armed else "disarmed"
                at = f"item {current[0]} of {current[1]}, {MISSION_STATE.get(current[2], current[2])}" if current else "no progress heard"
                raise Timeout(f"timeout after {timeout:.0f} s: {at}; {state}")
            kind = msg.get_type()
            if kind == "MISSION_ITEM_REACHED" and msg.seq not in reached:
                # PX4 repeats the last one for a while: each is printed once
                reached.add(msg.seq)
                last_reached = max(last_reached, msg.seq)
                print(f"  reached item {msg.seq}")
            elif kind == "MISSION_CURRENT":
                state = getattr(msg, "mission_state", 0)
                now = (msg.seq, getattr(msg, "total", count), state)
                if now != current:
                    print(f"  current item {msg.seq} of {now[1]}, {MISSION_STATE.get(state, state)}")
                    current = now
                if state == 5 or (state == 0 and last_reached >= count - 1):
                    # mission_state 0: a vehicle that does not fill it; MAVSDK's fallback
                    complete = True
            t = time.monotonic()
            if self.armed:
                disarmed_at = None
            elif disarmed_at is None:
                disarmed_at = t
                print("disarmed")
            on_ground = self.landed_state == self.mavlink.MAV_LANDED_STATE_ON_GROUND
            down_since = (down_since or t) if on_ground else None
            if complete and disarmed_at is not None and (on_ground or self.landed_state is None):
                return
            # MISSION_CURRENT comes at 1 Hz: a few seconds for the news after the disarm
            if disarmed_at is not None and not complete and t - disarmed_at > 3.0:
                raise Failure("the vehicle disarmed before the mission completed")
            # a vehicle that does not disarm by itself after landing (COM_DISARM_LAND < 0)
            if complete and self.armed and down_since is not None and t - down_since > 10.0 and not disarm_sent:
                print("  landed 10 s ago and still armed: disarming")
                disarm_sent = True
                self.command(self.mavlink.MAV_CMD_COMPONENT_ARM_DISARM, [0], "disarming")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("file", help="QGroundControl .plan, or QGC WPL 110 .txt/.waypoints/.mission")
    ap.add_argument("--connect", default="udpin:0.0.0.0:14550", help="pymavlink connection string (default udpin:0.0.0.0:14550, the GCS port)")
    ap.add_argument("--timeout", type=float, default=300.0, help="seconds from the mission start to landed and disarmed (default 300)")
    ap.add_argument("--upload-only", action="store_true", help="upload, then stop (no arming, no flight)")
    ap.add_argument("--list", action="store_true", help="print the items as they would be uploaded, then stop (no vehicle)")
    args = ap.parse_args()
    try:
        plans = read_mission_file(args.file)
        if args.list:
            print_items(plans)
            return 0
        count = len(plans.get(MISSION, []))
        if not args.upload_only and MISSION in plans and count == 0:
            raise Failure(f"{args.file}: no mission items to fly")
        v = Vehicle(args.connect, 15.0)
        for kind in sorted(plans):
            v.upload(kind, plans[kind])
        if args.upload_only:
            return 0
        if MISSION not in plans:
            raise Failure(f"{args.file}: holds no mission to fly (uploaded the {TYPE_NAMES[min(plans)]})")
        v.fly(count, args.timeout)
        print("mission complete; landed and disarmed")
        return 0
    except Failure as e:
        print(f"fly_mission: {e}", file=sys.stderr)
        return 1
    except Timeout as e:
        print(f"fly_mission: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("fly_mission: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
