"""Port reservation (rotorpilot.reserve_port): ports that parallel vehicles
(pytest -n auto, other runs) pick never collide, and lie outside the kernel's
ephemeral range, so no `bind(0)` (a daemon's own 127.0.0.1:0) can take them."""

import json
import os
import random
import subprocess
import sys

import pytest

import rotorpilot
from rotorpilot import reserve_port
from rotorpilot.vehicle import _ephemeral_range

HOLD_50 = """
import json, random, sys
from rotorpilot import reserve_port
rng = random.Random(int(sys.argv[1])) if len(sys.argv) > 1 else None
held = [reserve_port(rng=rng) for _ in range(50)]
print(json.dumps([r.port for r in held]), flush=True)
sys.stdin.read()  # hold them until the parent has seen both lists
"""


@pytest.mark.parametrize("seed", [None, 13], ids=["random", "same-candidates"])
def test_two_processes_reserving_50_ports_at_once_never_collide(seed):
    """With `seed`, all three processes try the very same ports in the same
    order: only the locks keep them apart."""
    env = dict(os.environ, PYTHONPATH=os.path.dirname(os.path.dirname(rotorpilot.__file__)))
    extra = [] if seed is None else [str(seed)]
    procs = [subprocess.Popen([sys.executable, "-c", HOLD_50, *extra], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              text=True, env=env) for _ in range(2)]
    try:
        # both hold 50 while this process reserves 50 more
        lists = [json.loads(p.stdout.readline()) for p in procs]
        rng = None if seed is None else random.Random(seed)
        mine = [reserve_port(rng=rng) for _ in range(50)]
        lists.append([r.port for r in mine])
    finally:
        for p in procs:
            p.communicate("", timeout=10)
    ports = [port for ls in lists for port in ls]
    assert len(ports) == 150 and len(set(ports)) == 150, sorted(ports)
    lo, hi = _ephemeral_range()
    assert not [p for p in ports if lo <= p <= hi], (lo, hi)
    for r in mine:
        r.release()


def test_a_released_port_can_be_reserved_again_and_a_held_one_cannot():
    import fcntl
    import tempfile

    r = reserve_port()
    lock = os.path.join(tempfile.gettempdir(), "rotorpilot-ports", f"{r.port}.lock")
    fd = os.open(lock, os.O_RDWR)
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            held = False
        except OSError:
            held = True
        assert held, f"{lock} is not locked while reserved"
        r.release()
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # free now: raises if not
    finally:
        os.close(fd)


def test_a_vehicle_holds_its_ports_until_stopped():
    v = rotorpilot.Vehicle(speed=10).start()
    try:
        assert all(r.held for r in v._ports)
        assert {r.port for r in v._ports} == {v.client_port, v.mavsdk_server_port}
    finally:
        v.stop()
        v.cleanup()
    assert not any(r.held for r in v._ports)
