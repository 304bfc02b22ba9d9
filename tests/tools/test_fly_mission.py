"""tools/fly_mission.py against a scripted vehicle that speaks the mission
protocol as PX4 does (float mode first, MISSION_REQUEST_INT after; a lost
request repeated; MISSION_CURRENT with mission_state; MISSION_ITEM_REACHED
repeated): the upload in both modes, the answers to refusals, disarms and
timeouts; and then against rotorpilot itself, both shipped files at 20x.

Run by tools/test-all.sh with the pymavlink venv (pymavlink 2.4.50, pytest).
"""
import os
import socket
import subprocess
import sys
import threading
import time

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil  # noqa: E402

mavlink = mavutil.mavlink
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCRIPT = os.path.join(ROOT, "tools", "fly_mission.py")
PLAN = os.path.join(ROOT, "tools", "missions", "home-square.plan")
WPL = os.path.join(ROOT, "tools", "missions", "five-waypoints.txt")


def free_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


class FakeVehicle(threading.Thread):
    """Vehicle 1/1 on udpout to the script's udpin port.

    refuse: {mission_type: MAV_MISSION_RESULT} answered after the first item;
    flight: "complete" (reach every item, land, disarm), "stall" (never
    finish), "disarm" (disarm half way).
    """

    def __init__(self, port, refuse=None, flight="complete"):
        super().__init__(daemon=True)
        self.m = mavutil.mavlink_connection(f"udpout:127.0.0.1:{port}", source_system=1, source_component=1)
        self.refuse = refuse or {}
        self.flight = flight
        self.stored = {0: [], 1: [], 2: []}
        self.modes_used = set()
        self.cleared = set()
        self.armed = False
        self.stop = threading.Event()
        self.upload = None  # (mission_type, count, items, next seq, int mode)
        self.requested_twice = False

    def heartbeat(self):
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | (mavlink.MAV_MODE_FLAG_SAFETY_ARMED if self.armed else 0)
        self.m.mav.heartbeat_send(mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_PX4, base, 4 << 16 | 3 << 24,
                                  mavlink.MAV_STATE_ACTIVE if self.armed else mavlink.MAV_STATE_STANDBY)

    def status(self):
        self.m.mav.sys_status_send(0, 0, 0x10000000, 0, 16000, 0, -1, 0, 0, 0, 0, 0, 0)

    def request(self, seq):
        kind, n, items, _, int_mode = self.upload
        self.upload = (kind, n, items, seq, int_mode)
        if int_mode:
            self.m.mav.mission_request_int_send(255, 190, seq, kind)
        else:
            self.m.mav.mission_request_send(255, 190, seq, kind)

    def on_message(self, msg):
        t = msg.get_type()
        if t == "MISSION_COUNT":
            # PX4 starts a link in float mode; this one switches to int after item 0
            self.upload = (msg.mission_type, msg.count, [], 0, False)
            self.request(0)
        elif t in ("MISSION_ITEM", "MISSION_ITEM_INT") and self.upload:
            kind, n, items, seq, int_mode = self.upload
            if msg.seq != seq or msg.mission_type != kind:
                return
            self.modes_used.add(t)
            items.append(msg)
            if kind in self.refuse:
                self.m.mav.mission_ack_send(255, 190, self.refuse[kind], kind)
                self.upload = None
                return
            if seq + 1 == n:
                self.stored[kind] = items
                self.m.mav.mission_ack_send(255, 190, mavlink.MAV_MISSION_ACCEPTED, kind)
                self.upload = None
                return
            self.upload = (kind, n, items, seq, True)
            if seq == 1 and not self.requested_twice:
                # a lost item: ask again for the next one, as a 250 ms re-request would
                self.requested_twice = True
                self.request(seq + 1)
            self.request(seq + 1)
        elif t == "MISSION_CLEAR_ALL":
            self.cleared.add(msg.mission_type)
            self.stored[msg.mission_type] = []
            self.m.mav.mission_ack_send(255, 190, mavlink.MAV_MISSION_ACCEPTED, msg.mission_type)
        elif t == "COMMAND_LONG":
            self.m.mav.command_ack_send(msg.command, mavlink.MAV_RESULT_ACCEPTED)
            if msg.command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
                self.armed = msg.param1 == 1
                self.heartbeat()
            elif msg.command == mavlink.MAV_CMD_MISSION_START:
                threading.Thread(target=self.fly, daemon=True).start()

    def fly(self):
        items = self.stored[0]
        n = len(items)
        for seq in range(n):
            self.m.mav.mission_current_send(seq, n, 3, 0)
            time.sleep(0.05)
            if self.flight == "disarm" and seq == n // 2:
                self.armed = False
                self.heartbeat()
                return
            self.m.mav.mission_item_reached_send(seq)
            self.m.mav.mission_item_reached_send(seq)  # PX4 repeats the last one
            self.m.mav.extended_sys_state_send(0, mavlink.MAV_LANDED_STATE_IN_AIR)
        if self.flight == "stall":
            return
        self.m.mav.mission_current_send(n - 1, n, 5, 0)
        self.m.mav.extended_sys_state_send(0, mavlink.MAV_LANDED_STATE_ON_GROUND)
        time.sleep(0.1)
        self.armed = False
        self.heartbeat()
        self.m.mav.mission_current_send(n - 1, n, 5, 0)

    def run(self):
        next_beat = 0.0
        while not self.stop.is_set():
            now = time.monotonic()
            if now >= next_beat:
                self.heartbeat()
                self.status()
                next_beat = now + 0.2
            msg = self.m.recv_match(blocking=True, timeout=0.05)
            if msg is not None and msg.get_srcSystem() == 255:
                self.on_message(msg)


def fly(path, *args, refuse=None, flight="complete", timeout=60):
    port = free_port()
    v = FakeVehicle(port, refuse=refuse, flight=flight)
    v.start()
    try:
        out = subprocess.run(
            [sys.executable, SCRIPT, path, "--connect", f"udpin:127.0.0.1:{port}", *args],
            capture_output=True, text=True, timeout=timeout,
        )
    finally:
        v.stop.set()
        v.join(timeout=2)
    return out, v


def test_a_plan_uploads_in_both_modes_flies_and_succeeds():
    out, v = fly(PLAN)
    assert out.returncode == 0, out.stdout + out.stderr
    assert "mission complete; landed and disarmed" in out.stdout
    assert "reached item 5" in out.stdout and out.stdout.count("reached item 5") == 1
    assert "current item 5 of 6, complete" in out.stdout
    assert v.modes_used == {"MISSION_ITEM", "MISSION_ITEM_INT"}
    mission, fence, rally = v.stored[0], v.stored[1], v.stored[2]
    assert [i.command for i in mission] == [22, 16, 16, 16, 16, 20]
    assert [i.command for i in fence] == [5001, 5001, 5001, 5001, 5004]
    assert [(i.command, i.frame) for i in rally] == [(5100, 3), (5100, 3)]
    # item 0 went as MISSION_ITEM (float degrees), the rest as MISSION_ITEM_INT (degE7)
    assert mission[0].get_type() == "MISSION_ITEM" and abs(mission[0].x - 47.397742) < 1e-5
    assert mission[2].get_type() == "MISSION_ITEM_INT" and (mission[2].x, mission[2].y) == (473981420, 85461940)
    assert mission[0].current == 1 and mission[1].current == 0
    assert mission[5].frame == 2 and (mission[5].x, mission[5].y) == (0, 0)
    assert fence[4].param1 == 15.0 and fence[0].param1 == 4.0


def test_a_wpl_file_replaces_only_the_mission():
    out, v = fly(WPL, "--upload-only")
    assert out.returncode == 0, out.stdout + out.stderr
    assert [i.command for i in v.stored[0]] == [22, 16, 16, 16, 16, 16, 20]
    assert v.cleared == set() and "geofence" not in out.stdout


def test_an_empty_plan_section_clears_it_on_the_vehicle(tmp_path):
    text = open(PLAN).read()
    start = text.index('"rallyPoints"')
    end = text.index('"version": 1\n}')
    p = tmp_path / "norally.plan"
    p.write_text(text[:start] + '"rallyPoints": {"points": [], "version": 2},\n    ' + text[end:])
    out, v = fly(str(p), "--upload-only")
    assert out.returncode == 0, out.stdout + out.stderr
    assert v.cleared == {2} and "rally points: cleared" in out.stdout


def test_a_refused_upload_names_the_plan_and_the_answer():
    out, _ = fly(PLAN, refuse={1: mavlink.MAV_MISSION_INVALID_PARAM1})
    assert out.returncode == 1
    assert "fly_mission: geofence: refused (after item 0 of 5 was sent): MAV_MISSION_INVALID_PARAM1\n" in out.stderr, \
        out.stderr


def test_a_disarm_before_the_end_fails():
    out, _ = fly(PLAN, flight="disarm")
    assert out.returncode == 1
    assert "disarmed before the mission completed" in out.stderr, out.stdout + out.stderr


def test_a_mission_that_never_ends_times_out():
    out, _ = fly(PLAN, "--timeout", "3", flight="stall")
    assert out.returncode == 2
    assert "fly_mission: timeout after 3 s: item 5 of 6, active; armed" in out.stderr, out.stdout + out.stderr


def test_bad_files_are_clear_failures(tmp_path):
    bad = tmp_path / "bad.plan"
    bad.write_text('{"version": 2}')
    out = subprocess.run([sys.executable, SCRIPT, str(bad)], capture_output=True, text=True, timeout=30)
    assert out.returncode == 1 and "bad.plan: version: .plan file version 2 is not supported" in out.stderr
    out = subprocess.run([sys.executable, SCRIPT, str(tmp_path / "none.txt")], capture_output=True, text=True,
                         timeout=30)
    assert out.returncode == 1 and "none.txt: cannot read" in out.stderr


def test_the_real_vehicle_flies_both_files_at_20x():
    """The script against rotorpilot itself (the release binary), at 20x:
    the .plan (mission, fence, rally; RTL to the rally point) and the WPL file
    fly to completion, and each item is reported reached."""
    sys.path.insert(0, os.path.join(ROOT, "tests", "clients"))
    from harness import Vehicle

    for path in (PLAN, WPL):
        with Vehicle(speed=20) as v:
            p = subprocess.run(
                [sys.executable, SCRIPT, "--connect", f"udpin:127.0.0.1:{v.gcs_port}", path, "--timeout", "120"],
                capture_output=True,
                text=True,
                timeout=240,
            )
            out = p.stdout + p.stderr
            assert p.returncode == 0, out + v.logs()
            assert "mission complete; landed and disarmed" in out, out
            assert "reached item 1" in out and "complete" in out, out


def test_a_plan_the_real_vehicle_refuses_quotes_the_vehicle(tmp_path):
    """rotorpilot refuses a mission whose item 3 is above RP_ALT_MAX_AMSL
    once all 7 items are sent: the script says so with the vehicle's own
    text, which names item 3, and blames no item of its own (it used to say
    "refused at item 6")."""
    sys.path.insert(0, os.path.join(ROOT, "tests", "clients"))
    from harness import Vehicle

    wpl = tmp_path / "high.txt"
    rows = ["QGC WPL 110"]
    for seq, z in enumerate([10, 10, 10, 12000, 10, 10, 10]):
        rows.append(f"{seq}\t0\t3\t16\t0\t0\t0\t0\t{47.3978 + seq * 1e-4:.7f}\t8.5456\t{z}\t1")
    wpl.write_text("\n".join(rows) + "\n")
    with Vehicle(speed=20) as v:
        p = subprocess.run(
            [sys.executable, SCRIPT, "--connect", f"udpin:127.0.0.1:{v.gcs_port}", str(wpl), "--upload-only"],
            capture_output=True, text=True, timeout=60,
        )
    assert p.returncode == 1, p.stdout + p.stderr
    assert p.stderr.startswith("fly_mission: mission: refused (after item 6 of 7 was sent): "
                               "MAV_MISSION_INVALID_PARAM7: the vehicle said \""), p.stderr
    assert "Plan rejected: item 3 at 12488 m > RP_ALT_MAX_AMSL" in p.stderr, p.stderr
