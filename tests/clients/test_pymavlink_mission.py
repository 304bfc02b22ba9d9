"""The mission protocol with pymavlink, as ground-station scripts use it
against PX4 SITL: the old MISSION_ITEM loop fed by `mavwp.MAVWPLoader`,
MISSION_START (`set_mode_auto`), the progress messages, DO_JUMP, uploads
through a lossy link, refusals, and two uploaders at once. Every wait is
bounded.

Run with the pymavlink venv: `python -m pytest tests/clients/test_pymavlink_mission.py`.
"""

import math
import random
import sys
import threading
import time
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import mission_link as ml  # noqa: E402  (first: it selects MAVLink 2 in pymavlink)
from harness import FILTER_HEIGHT_DRIFT_M, Vehicle  # noqa: E402
from harness import wait_message as wait  # noqa: E402
from mission_link import Client, Item, LossyRelay, mavlink  # noqa: E402

from pymavlink import mavutil, mavwp  # noqa: E402

SPEED = 5.0
FAST = 20.0
HOME = (47.397742, 8.545594)
WPL = HERE / "missions" / "loop-jump.waypoints"


def gcs(v, sysid=255):
    """A pymavlink GCS as scripts open one: udpin on the GCS port, the vehicle speaks first."""
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{v.gcs_port}", source_system=sysid)
    assert m.wait_heartbeat(timeout=5) is not None, "no heartbeat"
    return m


def square(n=4, north=0.0, alt=10.0):
    return ml.survey(n, HOME, north=north, alt=alt)


@pytest.fixture
def vehicle():
    with Vehicle(speed=SPEED) as v:
        yield v
        print("rotorpilot log (tail):\n" + v.logs())


@pytest.fixture(scope="module")
def shared_vehicle():
    """One vehicle for the refusal cases (each uploads its own mission first)."""
    with Vehicle(speed=SPEED) as v:
        yield v
        print("rotorpilot log (tail):\n" + v.logs())


def api_client(v, sysid=254):
    """A second client on the API link (udpout to it, saying hello first)."""
    return Client(f"udpout:127.0.0.1:{v.api_bind}", sysid=sysid, compid=190)


@pytest.fixture(scope="module")
def wpl_flight():
    """The classic pymavlink upload of tests/clients/missions/loop-jump.waypoints
    (CLEAR_ALL, COUNT, each MISSION_REQUEST answered with MAVWPLoader's
    MISSION_ITEM, targets 0/0), read back the same way and on the other link,
    then MISSION_START and the flight at 20x to the end, recorded: every
    MISSION_ITEM_REACHED with the vehicle's position at that moment, every
    MISSION_CURRENT, the modes."""
    with Vehicle(speed=FAST) as v:
        m = gcs(v)
        loader = mavwp.MAVWPLoader()
        assert loader.load(str(WPL)) == 6
        items = [ml.from_message(loader.wp(i)) for i in range(loader.count())]

        m.waypoint_clear_all_send()
        m.waypoint_count_send(loader.count())
        answered = []
        for _ in range(loader.count()):
            # recv_match drops what it is not waiting for (the clear's ACK among them)
            req = m.recv_match(type="MISSION_REQUEST", blocking=True, timeout=5)
            assert req is not None, f"no MISSION_REQUEST after the items {answered}"
            answered.append(req.seq)
            m.mav.send(loader.wp(req.seq))
        ack = m.recv_match(type="MISSION_ACK", blocking=True, timeout=5)
        assert answered == list(range(6)), "the float loop is served with MISSION_REQUEST, in order"
        assert ack is not None and ack.mission_type == 0
        assert ack.type == mavlink.MAV_MISSION_ACCEPTED

        # read back with MISSION_REQUEST (float), as the same old scripts do
        c = Client(f"udpout:127.0.0.1:{v.api_bind}", sysid=254)
        got = c.download(int_mode=False)
        assert ml.plan_difference(items, got, sent_int=False, got_int=False) is None, got
        # and as int items: the same plan
        assert ml.plan_difference(items, c.download(), sent_int=False, got_int=True) is None
        c.close()

        ok = wait(m, "SYS_STATUS", lambda s: s.onboard_control_sensors_health & 0x10000000, 10)
        assert ok is not None, "never armable"
        before = wait(m, "MISSION_CURRENT", timeout=3)
        m.set_mode_auto()  # MAV_CMD_MISSION_START p1 = 0
        a = wait(m, "COMMAND_ACK", lambda a: a.command == mavlink.MAV_CMD_MISSION_START, 3)
        assert a is not None and a.result == mavlink.MAV_RESULT_ACCEPTED

        reached, currents, modes = [], [], set()
        pos = None
        t0 = time.monotonic()
        done = False
        while time.monotonic() - t0 < 60 and not done:
            msg = m.recv_match(type=["MISSION_ITEM_REACHED", "MISSION_CURRENT", "HEARTBEAT", "GLOBAL_POSITION_INT"],
                               blocking=True, timeout=0.5)
            if msg is None:
                continue
            kind = msg.get_type()
            if kind == "GLOBAL_POSITION_INT":
                pos = msg
            elif kind == "MISSION_ITEM_REACHED":
                reached.append((msg.seq, pos))
            elif kind == "MISSION_CURRENT":
                currents.append(msg)
            elif msg.get_srcComponent() == 1:
                modes.add(m.flightmode)
                done = bool(currents) and currents[-1].mission_state == 5 and not msg.base_mode & 128
        took = time.monotonic() - t0
        # the last item reached is repeated once a second (PX4: up to 10 times)
        t1 = time.monotonic()
        while time.monotonic() - t1 < 2.5:
            msg = m.recv_match(type="MISSION_ITEM_REACHED", blocking=True, timeout=0.5)
            if msg is not None:
                reached.append((msg.seq, None))
        land = wait(m, "EXTENDED_SYS_STATE", timeout=2)
        rest = wait(m, "GLOBAL_POSITION_INT", timeout=2)
        yield dict(items=items, before=before, reached=reached, currents=currents, modes=modes, took=took,
                   landed_state=land.landed_state, rest=rest)


def changes(seqs):
    return [s for k, s in enumerate(seqs) if k == 0 or s != seqs[k - 1]]


def test_wpl_file_old_float_loop_mission_start_and_progress(wpl_flight):
    """Progress as clients see it: every item reached in order, the triangle
    1-2 three times (DO_JUMP to 1, 2 more times), the last one repeated;
    MISSION_CURRENT not started, active, then COMPLETE on the last item; in
    MISSION; landed at home and disarmed."""
    f = wpl_flight
    items = f["items"]
    seqs = [s for s, _ in f["reached"]]
    print(f"flown in {f['took']:.1f} s wall; reached (changes) {changes(seqs)}; {len(seqs)} messages")
    nav = [s for s in changes(seqs) if items[s].command != 177]
    assert nav == [0, 1, 2, 1, 2, 1, 2, 4, 5], nav
    repeats = len(seqs) - len(changes(seqs))
    assert 2 <= repeats <= 10, f"{repeats} repeats of the last item reached"
    assert (f["before"].total, f["before"].mission_state) == (6, 2), "6 items, not started"
    states = {c.mission_state for c in f["currents"]}
    assert 3 in states, "ACTIVE while flown"
    last = f["currents"][-1]
    assert (last.mission_state, last.seq, last.total) == (5, 5, 6), "COMPLETE at the end"
    assert "MISSION" in f["modes"]
    assert f["landed_state"] == mavlink.MAV_LANDED_STATE_ON_GROUND
    g = f["rest"]
    assert abs(g.relative_alt) < FILTER_HEIGHT_DRIFT_M * 1000, "on the ground"
    assert ml.distance_m(g.lat / 1e7, g.lon / 1e7, *HOME) < 2.0, "at home"


def test_do_jump_loops_are_flown(wpl_flight):
    """Each MISSION_ITEM_REACHED of a waypoint comes when the vehicle is there
    (within the item's 2 m acceptance radius, plus what the vehicle flies
    between two position reports at 20x), the repeats of the DO_JUMP loop too;
    and MISSION_CURRENT follows the item being flown to."""
    f = wpl_flight
    items = f["items"]
    far = []
    previous = None
    for seq, pos in f["reached"]:
        it = items[seq]
        # the same seq again is the re-send of the last item reached (every
        # second, as PX4), which goes on while the vehicle flies to the next:
        # only the first report of a reach says where the vehicle is
        repeat, previous = seq == previous, seq
        if repeat or pos is None or it.command not in (16, 21):
            continue
        d = ml.distance_m(pos.lat / 1e7, pos.lon / 1e7, it.x, it.y)
        if d > 6.0:
            far.append((seq, round(d, 1)))
    assert not far, f"items reported reached while the vehicle was elsewhere (seq, metres away): {far}"
    current = changes([c.seq for c in f["currents"] if c.mission_state == 3])
    assert [s for s in current if items[s].command != 177] == [0, 1, 2, 1, 2, 1, 2, 4, 5], current


def test_mission_start_without_a_mission_is_denied(vehicle):
    c = Client(f"udpout:127.0.0.1:{vehicle.gcs_bind}")
    assert c.upload(square()) == ml.ACCEPTED
    assert c.clear() == ml.ACCEPTED
    assert c.download() == []
    c.drain()
    c.mav.command_long_send(*c.target, mavlink.MAV_CMD_MISSION_START, 0, 0, 0, 0, 0, 0, 0, 0)
    a = c.recv("COMMAND_ACK", 3)
    assert a is not None and a.command == mavlink.MAV_CMD_MISSION_START
    assert a.result == mavlink.MAV_RESULT_DENIED
    hb = wait(c.m, "HEARTBEAT", lambda h: h.get_srcComponent() == 1, 3)
    assert not hb.base_mode & 128, "still disarmed"


def bad(items, k, **change):
    from dataclasses import replace

    out = list(items)
    out[k] = replace(out[k], **change)
    return out


@pytest.mark.parametrize(
    "name,expected",
    [
        ("latitude 91", mavlink.MAV_MISSION_INVALID_PARAM5_X),
        ("altitude NaN", mavlink.MAV_MISSION_INVALID_PARAM7),
        ("frame LOCAL_NED", mavlink.MAV_MISSION_UNSUPPORTED_FRAME),
        ("count 20001", mavlink.MAV_MISSION_NO_SPACE),
    ],
)
@pytest.mark.parametrize("kind", ["int", "float"])
def test_refused_uploads_leave_the_stored_mission(shared_vehicle, name, expected, kind):
    c = Client(f"udpout:127.0.0.1:{shared_vehicle.gcs_bind}")
    stored = square(5)
    assert c.upload(stored, answer=kind) == ml.ACCEPTED
    good = square(5, north=7.0)
    if name == "latitude 91":
        plan = bad(good, 2, x=91.0)
    elif name == "altitude NaN":
        plan = bad(good, 2, z=math.nan)
    elif name == "frame LOCAL_NED":
        plan = bad(good, 2, frame=mavlink.MAV_FRAME_LOCAL_NED)
    else:
        plan = good + [good[-1]] * (20001 - len(good))  # refused at MISSION_COUNT
    result = c.upload(plan, answer=kind, budget=5)
    assert result == expected, f"{name}: MISSION_ACK {result}, not {expected}"
    got = c.download()
    assert ml.plan_difference(stored, got, sent_int=kind == "int") is None, "the stored mission is unchanged"
    # and the link still takes a good upload afterwards
    assert c.upload(good, answer=kind) == ml.ACCEPTED
    assert ml.plan_difference(good, c.download(), sent_int=kind == "int") is None


def test_lossy_link_uploads_are_whole_or_nothing():
    """20 uploads of 12-item missions through a relay that drops 30 % of the
    datagrams each way (seeded), each with its own time budget (seeded, 0.3 to
    5.5 s: some end mid-transfer, some just before or after the last item):
    after each, the stored mission (read on the other link, without loss) is
    either the new one whole (always when the client got ACCEPTED) or the one
    before it whole, never a mix."""
    v = Vehicle(speed=SPEED)
    relay = LossyRelay(("127.0.0.1", v.gcs_bind), drop=0.3, seed=20).start()
    v.gcs_port = relay.vehicle_port
    budgets = random.Random(7).uniform
    with v:
        lossy = Client(f"udpout:127.0.0.1:{relay.client_port}", heartbeat_timeout=10)
        truth = api_client(v)
        previous = truth.download()
        assert previous == []
        outcomes = []
        t0 = time.monotonic()
        for k in range(20):
            mission = square(12, north=3.0 * (k + 1))
            budget = round(budgets(0.3, 5.5), 2)
            lossy.drain(linger=0.1)
            t = time.monotonic()
            result = lossy.upload(mission, budget=budget)
            took = time.monotonic() - t
            stored = truth.download(timeout=5)
            is_new = ml.plan_difference(mission, stored) is None
            is_old = ml.plan_difference(previous, stored) is None
            outcomes.append((budget, round(took, 2), result, "new" if is_new else "old" if is_old else "MIX"))
            assert is_new or is_old, f"attempt {k}: the stored mission is neither the new one nor the previous one"
            if result == ml.ACCEPTED:
                assert is_new, f"attempt {k}: ACCEPTED but the new mission is not stored"
            elif result is not None:
                assert is_old, f"attempt {k}: refused ({result}) but the mission changed"
            previous = stored
        took = time.monotonic() - t0
        relay.stop()
        print(f"{len(outcomes)} attempts in {took:.1f} s; relay (passed, dropped) {relay.counts}")
        for o in outcomes:
            print("  budget %5.2f s, took %5.2f s, ACK %s, stored: %s" % o)
        accepted = sum(1 for o in outcomes if o[2] == ml.ACCEPTED)
        unchanged = sum(1 for o in outcomes if o[3] == "old")
        assert accepted >= 3, "uploads with a long enough budget complete despite the loss"
        assert unchanged >= 3, "some uploads were cut short (the test exercises both outcomes)"
        for way in ("up", "down"):
            passed, dropped = relay.counts[way]
            assert 0.25 < dropped / (passed + dropped) < 0.35, way


@pytest.mark.parametrize("links", ["same link", "two links"])
def test_two_uploaders_at_once_one_wins(vehicle, links):
    """Two clients (system ids 255 and 254, from two ports) upload different
    missions at the same instant: one gets ACCEPTED, the other a MISSION_ACK
    error, and the stored mission is exactly the winner's."""
    a = Client(f"udpout:127.0.0.1:{vehicle.gcs_bind}", sysid=255)
    b_port = vehicle.gcs_bind if links == "same link" else vehicle.api_bind
    b = Client(f"udpout:127.0.0.1:{b_port}", sysid=254)
    # 200 items each: a transfer lasts long enough for the two to overlap
    missions = {a: square(200, north=0.0), b: square(200, north=50.0)}
    results, spans = {}, {}
    go = threading.Barrier(2)

    def run(c):
        c.drain()
        go.wait(2)
        t = time.monotonic()
        results[c] = c.upload(missions[c], budget=10)
        spans[c] = (t, time.monotonic())

    threads = [threading.Thread(target=run, args=(c,)) for c in (a, b)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(15)
    assert max(s[0] for s in spans.values()) < min(s[1] for s in spans.values()), "the uploads overlapped"
    print({c.sysid: r for c, r in results.items()})
    winners = [c for c, r in results.items() if r == ml.ACCEPTED]
    losers = [c for c, r in results.items() if r not in (ml.ACCEPTED, None)]
    assert len(winners) == 1 and len(losers) == 1, f"results {[(c.sysid, r) for c, r in results.items()]}"
    stored = a.download()
    assert ml.plan_difference(missions[winners[0]], stored) is None, "the stored mission is the winner's"
    # the loser tries again alone and succeeds
    assert losers[0].upload(missions[losers[0]]) == ml.ACCEPTED
    assert ml.plan_difference(missions[losers[0]], b.download()) is None


def test_fence_and_rally_are_kept_apart_from_the_mission(vehicle):
    """The three plan types are stored, read back and cleared each on its own."""
    c = Client(f"udpout:127.0.0.1:{vehicle.gcs_bind}")
    mission = square(4)
    fence = [Item(5001, 5, *ml.offset(*HOME, n, e), 0.0, 4.0) for n, e in ((-50, -50), (-50, 50), (50, 50), (50, -50))]
    rally = [Item(5100, 6, *ml.offset(*HOME, 30, -30), 12.0)]
    assert c.upload(mission) == ml.ACCEPTED
    assert c.upload(fence, mission_type=ml.FENCE) == ml.ACCEPTED
    assert c.upload(rally, mission_type=ml.RALLY) == ml.ACCEPTED
    assert ml.plan_difference(fence, c.download(ml.FENCE)) is None
    assert ml.plan_difference(rally, c.download(ml.RALLY)) is None
    assert c.clear(ml.FENCE) == ml.ACCEPTED
    assert c.download(ml.FENCE) == []
    assert ml.plan_difference(mission, c.download()) is None
    assert ml.plan_difference(rally, c.download(ml.RALLY)) is None
    assert c.clear(mavlink.MAV_MISSION_TYPE_ALL) == ml.ACCEPTED
    assert c.download() == [] and c.download(ml.RALLY) == []
