#!/usr/bin/env python3
"""Measure rotorpilot's MAVLink link on loopback (the figures of docs/flying.md, "Link speed"):

1. COMMAND_ACK round trip, p50/p99/max over N commands, for a command the
   link answers itself (unknown id -> UNSUPPORTED) and one that goes through
   the autopilot task (DO_SET_MODE Hold -> ACCEPTED);
   and a PARAM_SET's echo (PARAM_SET MIS_TAKEOFF_ALT, alternating two
   valid values -> the PARAM_VALUE that answers it);
2. full parameter list download with pymavlink (request to last index);
3. CPU use of one idle real-time vehicle (disarmed on the ground, streaming
   to its default remotes), from /proc/PID/stat over a window.

It starts its own vehicle (the release binary) on free ports:
    cargo build --release && python3 tools/bench_link.py
Needs pymavlink. Linux only (CPU from /proc).
"""

import argparse
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pymavlink import mavutil

REPO = Path(__file__).resolve().parents[1]
mavlink = mavutil.mavlink


def free_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def start(binary, speed, gcs_remote, api_remote):
    gcs_bind, api_bind = free_port(), free_port()
    state = tempfile.mkdtemp(prefix="rotorpilot-bench-")
    args = [binary, "--instance", "0", "--speed", str(speed), "--state-dir", state, "--reset-params",
            "--gcs-bind", f"127.0.0.1:{gcs_bind}", "--api-bind", f"127.0.0.1:{api_bind}",
            "--gcs-remote", gcs_remote, "--api-remote", api_remote]
    proc = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    deadline = time.monotonic() + 15
    for line in proc.stdout:
        if "parameters:" in line or time.monotonic() > deadline:
            break
    return proc, gcs_bind


def stop(proc):
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(5)
    except subprocess.TimeoutExpired:
        proc.kill()


def percentiles(xs):
    xs = sorted(xs)
    q = lambda f: xs[min(len(xs) - 1, int(f * len(xs)))]  # noqa: E731
    return q(0.5), q(0.99), xs[-1]


def frames(data):
    """The MAVLink 2 frames of one datagram (the vehicle packs several into
    one): (message id, payload) each."""
    k = 0
    while k + 12 <= len(data) and data[k] == 0xFD:
        length = data[k + 1]
        msgid = data[k + 7] | (data[k + 8] << 8) | (data[k + 9] << 16)
        yield msgid, data[k + 10:k + 10 + length]
        k += 12 + length + (13 if data[k + 2] & 1 else 0)


def prove_listener(sock, mav, dest):
    """Send a ground station's HEARTBEAT first, as every GCS does: a peer
    that never sent one is served as an unproven source address (direct
    answers from a small shared budget, no streams), which a benchmark of
    thousands of round trips would exhaust."""
    hb = mavlink.MAVLink_heartbeat_message(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0, 3)
    sock.sendto(hb.pack(mav), dest)
    time.sleep(0.05)


def ack_rtt(gcs_bind, n, command, params):
    """Round trips [ms] of COMMAND_LONG -> COMMAND_ACK from a udpout-style socket."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(1.0)
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    mav.robust_parsing = True
    frame = mavlink.MAVLink_command_long_message(1, 1, command, 0, *params).pack(mav)
    dest = ("127.0.0.1", gcs_bind)
    prove_listener(sock, mav, dest)
    rtts = []
    # warm up, and let the vehicle learn us as a peer
    for _ in range(20):
        sock.sendto(frame, dest)
        time.sleep(0.002)
    time.sleep(0.2)
    while True:
        try:
            sock.recv(65536)
        except socket.timeout:
            break
        except BlockingIOError:
            break
        sock.settimeout(0.01)
    sock.settimeout(1.0)
    for _ in range(n):
        t0 = time.perf_counter_ns()
        sock.sendto(frame, dest)
        while True:
            data = sock.recv(65536)
            # COMMAND_ACK = 77: its command in payload bytes 0..2
            if any(m == 77 and len(p) >= 2 and p[0] | (p[1] << 8) == command for m, p in frames(data)):
                break
        rtts.append((time.perf_counter_ns() - t0) / 1e6)
    sock.close()
    return rtts


def param_set_rtt(gcs_bind, n, name="MIS_TAKEOFF_ALT", values=(2.5, 3.0)):
    """Round trips [ms] of PARAM_SET -> its echo (the PARAM_VALUE naming it
    with the value set), alternating `values`."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(1.0)
    mav = mavlink.MAVLink(None, srcSystem=255, srcComponent=190)
    sets = [mavlink.MAVLink_param_set_message(1, 1, name.encode(), v, mavlink.MAV_PARAM_TYPE_REAL32).pack(mav)
            for v in values]
    dest = ("127.0.0.1", gcs_bind)
    prove_listener(sock, mav, dest)
    want = name.encode().ljust(16, b"\0")
    rtts = []
    for k in range(n + 10):
        t0 = time.perf_counter_ns()
        sock.sendto(sets[k % 2], dest)
        while True:
            data = sock.recv(65536)
            # PARAM_VALUE = 22: its param_id in payload bytes 8..24
            if any(m == 22 and p[8:24].ljust(16, b"\0") == want for m, p in frames(data)):
                break
        if k >= 10:  # the first ones teach the vehicle its peer
            rtts.append((time.perf_counter_ns() - t0) / 1e6)
    sock.close()
    return rtts


def param_download(gcs_remote_port, repeats):
    m = mavutil.mavlink_connection(f"udpin:127.0.0.1:{gcs_remote_port}", source_system=255)
    assert m.wait_heartbeat(timeout=5) is not None
    times, count = [], None
    for _ in range(repeats):
        # drop the backlog so the timing starts clean
        while m.recv_match(blocking=False) is not None:
            pass
        t0 = time.perf_counter()
        m.mav.param_request_list_send(m.target_system, 0)
        seen = set()
        while True:
            p = m.recv_match(type="PARAM_VALUE", blocking=True, timeout=2)
            if p is None:
                raise SystemExit("parameter list stalled")
            count = p.param_count
            seen.add(p.param_index)
            if len(seen) == count:
                break
        times.append((time.perf_counter() - t0) * 1e3)
        time.sleep(0.05)
    m.close()
    return times, count


def cpu_percent(pid, seconds):
    def ticks():
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return int(fields[11]) + int(fields[12])  # utime + stime

    hz = os.sysconf("SC_CLK_TCK")
    t0, c0 = time.monotonic(), ticks()
    time.sleep(seconds)
    t1, c1 = time.monotonic(), ticks()
    return 100.0 * (c1 - c0) / hz / (t1 - t0)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    target = os.environ.get("CARGO_TARGET_DIR", str(REPO / "target"))
    ap.add_argument("--binary", default=os.environ.get("ROTORPILOT_BIN", str(Path(target) / "release" / "rotorpilot")))
    ap.add_argument("-n", type=int, default=2000, help="command round trips per case")
    ap.add_argument("--param-repeats", type=int, default=20)
    ap.add_argument("--cpu-seconds", type=float, default=20.0)
    a = ap.parse_args()

    # 1 and 2: one vehicle whose GCS link sends to our pymavlink port
    gcs_port = free_port()
    proc, gcs_bind = start(a.binary, 1.0, f"127.0.0.1:{gcs_port}", "none")
    try:
        time.sleep(1.0)
        rows = []
        for label, cmd, params in [
            ("unknown command -> UNSUPPORTED (link only)", 31000, [0] * 7),
            ("DO_SET_MODE Hold -> ACCEPTED (autopilot task)", 176, [1, 4, 3, 0, 0, 0, 0]),
        ]:
            p50, p99, mx = percentiles(ack_rtt(gcs_bind, a.n, cmd, params))
            rows.append((label, p50, p99, mx))
        p50, p99, mx = percentiles(param_set_rtt(gcs_bind, a.n // 4))
        rows.append(("PARAM_SET -> PARAM_VALUE echo (autopilot task)", p50, p99, mx))
        times, count = param_download(gcs_port, a.param_repeats)
    finally:
        stop(proc)

    # 3: an idle vehicle at real time with the default stream rates
    proc, _ = start(a.binary, 1.0, f"127.0.0.1:{free_port()}", f"127.0.0.1:{free_port()}")
    try:
        time.sleep(3.0)
        cpu = cpu_percent(proc.pid, a.cpu_seconds)
    finally:
        stop(proc)

    print(f"load average at the end: {os.getloadavg()[0]:.2f}")
    print(f"| round trip (loopback; n = {a.n}, PARAM_SET n = {a.n // 4}) | p50 ms | p99 ms | max ms |")
    print("|---|---|---|---|")
    for label, p50, p99, mx in rows:
        print(f"| {label} | {p50:.3f} | {p99:.3f} | {mx:.3f} |")
    print()
    med = statistics.median(times)
    print(f"full parameter list ({count} parameters) with pymavlink: median {med:.1f} ms, "
          f"max {max(times):.1f} ms over {len(times)} downloads")
    print(f"idle real-time vehicle (2 links streaming, 1 kHz physics): {cpu:.2f} % of one core "
          f"over {a.cpu_seconds:.0f} s")


if __name__ == "__main__":
    sys.exit(main())
