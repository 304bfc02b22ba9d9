"""A ground station that watches: listens where PX4 SITL's GCS link sends
(udpin 0.0.0.0:14550 by default), sends a GCS heartbeat each second, and
prints one JSON line per thing a test may check, until SIGTERM or SIGINT:

- `{"armed": bool, "main": int, "sub": int}` when the vehicle's (system 1 or
  `--sysid`) arming state or PX4 custom mode (main and sub mode) changes;
- `{"landed": n}` when its EXTENDED_SYS_STATE landed state changes;
- `{"text": str, "src": [sys, comp]}` for every STATUSTEXT, from anyone;
- `{"msg": NAME, "src": [sys, comp]}` the first time a message type comes
  from a source;
- `{"ned": [x, y, z]}` its LOCAL_POSITION_NED (metres, NED from its
  origin), twice a second.

A line `arm` or `disarm` on its stdin sends the vehicle
MAV_CMD_COMPONENT_ARM_DISARM, as a ground station's button does.

Used by test_mavsdk_python_examples.py, inside the test's network namespace,
so that an example script's effect on the vehicle (landed and disarmed, the
mode it flew in, what reached the GCS link) is judged from outside the script.
"""

import argparse
import json
import signal
import sys
import threading
import time

from pymavlink import mavutil


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--listen", default="udpin:0.0.0.0:14550")
    ap.add_argument("--sysid", type=int, default=1)
    args = ap.parse_args()
    stop = []
    signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
    signal.signal(signal.SIGINT, lambda *_: stop.append(1))
    m = mavutil.mavlink_connection(args.listen, source_system=255, source_component=190)

    def say(obj):
        sys.stdout.write(json.dumps(obj) + "\n")
        sys.stdout.flush()

    def commands():
        for line in sys.stdin:
            arm = {"arm": 1.0, "disarm": 0.0}.get(line.strip())
            if arm is not None:
                # MAV_CMD_COMPONENT_ARM_DISARM to the autopilot
                m.mav.command_long_send(args.sysid, 1, 400, 0, arm, 0, 0, 0, 0, 0, 0)

    threading.Thread(target=commands, daemon=True).start()
    seen = set()
    state = None
    landed = None
    next_hb = 0.0
    next_ned = 0.0
    say({"ready": True})
    while not stop:
        now = time.monotonic()
        if now >= next_hb:
            # MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID; udpin sends nothing before
            # the vehicle's first datagram tells it where the vehicle is
            m.mav.heartbeat_send(6, 8, 0, 0, 0)
            next_hb = now + 1.0
        msg = m.recv_match(blocking=True, timeout=0.2)
        if msg is None:
            continue
        kind = msg.get_type()
        if kind == "BAD_DATA":
            continue
        src = [msg.get_srcSystem(), msg.get_srcComponent()]
        if (kind, tuple(src)) not in seen:
            seen.add((kind, tuple(src)))
            say({"msg": kind, "src": src})
        if kind == "STATUSTEXT":
            say({"text": msg.text, "src": src})
        if src[0] != args.sysid or src[1] != 1:
            continue
        if kind == "HEARTBEAT":
            main_mode = (msg.custom_mode >> 16) & 0xFF
            sub_mode = (msg.custom_mode >> 24) & 0xFF
            now_state = (bool(msg.base_mode & 128), main_mode, sub_mode)
            if now_state != state:
                state = now_state
                say({"armed": state[0], "main": main_mode, "sub": sub_mode})
        elif kind == "LOCAL_POSITION_NED" and now >= next_ned:
            say({"ned": [round(msg.x, 3), round(msg.y, 3), round(msg.z, 3)]})
            next_ned = now + 0.5
        elif kind == "EXTENDED_SYS_STATE" and msg.landed_state != landed:
            landed = msg.landed_state
            say({"landed": landed})


if __name__ == "__main__":
    main()
