"""The net under the clients (`rotorpilot.clients`): a `mavsdk_server` on a
vehicle's port is found (by its arguments or by the socket it holds) and
killed, one on another port is left alone, and `Vehicle.stop()` kills those
on its own ports. Stand-ins named `mavsdk_server` (`exec -a`) play the
server, so this needs no MAVSDK.
"""

import os
import subprocess
import sys
import time

import pytest

from rotorpilot import Vehicle, reserve_port
from rotorpilot.clients import kill_mavsdk_servers, mavsdk_servers_on

pytestmark = pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="the net reads /proc (Linux)")


def fake_server(*args, bind=None):
    """A process whose argv[0] is .../mavsdk_server: sleeping, with `args`
    on its command line, and listening on TCP `bind` if given."""
    code = "import socket, sys, time\n"
    if bind is not None:
        code += f"s = socket.socket(); s.bind(('127.0.0.1', {bind})); s.listen()\n"
    code += "print('up', flush=True); time.sleep(60)\n"
    p = subprocess.Popen(["bash", "-c", 'exec -a /opt/fake/bin/mavsdk_server "$0" "$@"', sys.executable, "-c", code,
                          *args], stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "up"
    return p


def test_found_by_arguments_or_socket_and_only_on_those_ports():
    with reserve_port() as grpc, reserve_port() as mav, reserve_port() as bound, reserve_port() as other:
        by_port = fake_server("-p", str(grpc.port), "--sysid", "245")
        by_address = fake_server(f"udpin://127.0.0.1:{mav.port}")
        by_socket = fake_server(bind=bound.port)
        bystander = fake_server("-p", str(other.port), f"udpin://127.0.0.1:{other.port}")
        try:
            assert set(mavsdk_servers_on([grpc.port, mav.port, bound.port])) == {
                by_port.pid, by_address.pid, by_socket.pid}
            killed = kill_mavsdk_servers([grpc.port, mav.port, bound.port])
            assert set(killed) == {by_port.pid, by_address.pid, by_socket.pid}
            for p in (by_port, by_address, by_socket):
                assert p.wait(5) == -9
            assert bystander.poll() is None, "a mavsdk_server on another port was killed"
            assert mavsdk_servers_on([grpc.port, mav.port, bound.port]) == []
        finally:
            for p in (by_port, by_address, by_socket, bystander):
                p.kill()
                p.wait()


def test_vehicle_stop_kills_the_mavsdk_servers_on_its_ports():
    v = Vehicle(speed=10).start()
    try:
        a = fake_server("-p", str(v.mavsdk_server_port), v.mavsdk_url)
        b = fake_server(bind=v.mavsdk_server_port)
    finally:
        rc = v.stop()
    v.cleanup()
    assert rc == 0
    assert set(v.killed_clients) == {a.pid, b.pid}
    assert a.wait(5) == -9 and b.wait(5) == -9
    # a second stop(): its ports are released, so it looks for nobody on them
    t = time.monotonic()
    assert v.stop() == 0
    assert time.monotonic() - t < 1
    assert set(v.killed_clients) == {a.pid, b.pid}
