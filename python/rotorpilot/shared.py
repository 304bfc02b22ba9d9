"""One vehicle for many tests: the reset between two tests, and the pool of
shared vehicles the pytest plugin hands out (marker option `reuse=True`).

`reset(vehicle)` brings a running vehicle back to the state it started in,
with what any PX4 client could send over its GCS link (pymavlink, to
`udpout:127.0.0.1:<gcs_port>`, so the API port a test's client may still
hold stays untouched):

1. COMMAND_LONG COMPONENT_ARM_DISARM p1 = 0, p2 = 21196 (forced disarm, in
   flight too: PX4 refuses to reboot an armed vehicle);
2. PARAM_SET, back to its start value, of every parameter set since the
   vehicle started (its start values and the sets are the daemon's flight
   record: the header's `params`, and every `set_param` line accepted);
3. MISSION_CLEAR_ALL for each plan type (mission 0, fence 1, rally 2);
4. COMMAND_LONG PREFLIGHT_REBOOT_SHUTDOWN p1 = 1: the vehicle restarts from
   those parameters, disarmed, on the ground at home, with a new flight
   stack, a full battery and no injected failure;
5. MAV_CMD_REQUEST_MESSAGE SYS_STATUS until its health word is complete (all
   sensors healthy, prearm checks pass): ready to arm, as the daemon's
   `ready to arm` line after a start.

What a reset does not restart: the simulated clock keeps counting (as it
does across a reboot: `time_boot_ms`, the CSV's `time_s`, the record's
steps); the process, its links (a stream rate a client set with
SET_MESSAGE_INTERVAL, signing keys) and its log files (one flight record
for every test the vehicle served, a `reboot` line where each test began).
A test flown after a reset is the flight a fresh vehicle flies, in every
column of the flight CSV but `time_s` (docs/testing.md, "One vehicle for
many tests"; `tests/pip/test_reuse.py` proves it).

Needs pymavlink (imported on first use).
"""

import json
import struct
import time

from .clients import kill_mavsdk_servers
from .messages import drain, wait_message
from .vehicle import Vehicle, VehicleError

# MAVLink numbers (common.xml)
_ARM_DISARM = 400
_FORCE = 21196
_REBOOT = 246
_REQUEST_MESSAGE = 512
_SYS_STATUS_ID = 1
_PREARM_CHECK = 0x10000000  # MAV_SYS_STATUS_PREARM_CHECK
_ACCEPTED = 0
_PARAM_INT32, _PARAM_REAL32 = 6, 9
_PLAN_TYPES = (0, 1, 2)  # MAV_MISSION_TYPE_MISSION, FENCE, RALLY


def _record_lines(record):
    with open(record) as f:
        return [json.loads(line) for line in f if line.endswith("\n")]


def _f32(x):
    return struct.unpack("<f", struct.pack("<f", float(x)))[0]


def _stored(outcome):
    """The value of a set_param line's outcome `Ok(Real32(4.0))` /
    `Ok(Int32(5))`, as the header spells values; None for a refusal."""
    if not outcome.startswith("Ok(") or not outcome.endswith("))"):
        return None
    kind, _, number = outcome[3:-2].partition("(")
    if kind == "Int32":
        return {"Int32": int(number)}
    if kind == "Real32":
        return {"Real32": _f32(number)}
    return None


def _same(a, b):
    (ka, va), = a.items()
    (kb, vb), = b.items()
    return ka == kb and (va == vb if ka == "Int32" else _f32(va) == _f32(vb))


def changed_params(record):
    """{name: start value} of every parameter whose value now differs from
    the one it started with, from the flight record `record` (the header's
    `params`, then every accepted `set_param` line in order). Values as the
    record spells them: `{"Int32": n}` or `{"Real32": x}`."""
    lines = _record_lines(record)
    if not lines or "header" not in lines[0]:
        raise VehicleError(f"{record}: no flight record header")
    start = lines[0]["header"]["params"]
    now = {}
    for line in lines[1:]:
        s = line.get("set_param")
        if s is not None:
            v = _stored(line.get("outcome", ""))
            if v is not None:
                now[s["name"]] = v
    return {n: start[n] for n, v in now.items() if n in start and not _same(v, start[n])}


def last_reboot_step(record):
    """The step of the record's last `reboot` line (None when none)."""
    steps = [line["step"] for line in _record_lines(record) if "reboot" in line]
    return steps[-1] if steps else None


def _param_wire(value):
    """(param_value, param_type) as PARAM_SET carries it: INT32 bytewise."""
    (kind, x), = value.items()
    if kind == "Int32":
        return struct.unpack("<f", struct.pack("<i", int(x)))[0], _PARAM_INT32
    return float(x), _PARAM_REAL32


def _command(m, cmd, *params, timeout):
    p = list(params) + [0.0] * (7 - len(params))
    drain(m)
    m.mav.command_long_send(m.target_system, 1, cmd, 0, *p)
    ack = wait_message(m, "COMMAND_ACK", lambda a: a.command == cmd, timeout)
    if ack is None:
        raise VehicleError(f"reset: no COMMAND_ACK for command {cmd} within {timeout} s")
    return ack.result


def _set_param(m, name, value, timeout):
    wire, kind = _param_wire(value)
    drain(m)
    m.mav.param_set_send(m.target_system, 1, name.encode(), wire, kind)
    got = wait_message(m, ["PARAM_VALUE", "PARAM_ERROR"], lambda p: p.param_id == name, timeout)
    if got is None or got.get_type() != "PARAM_VALUE" or struct.pack("<f", got.param_value) != struct.pack("<f", wire):
        raise VehicleError(f"reset: PARAM_SET {name} back to {value} was not stored ({got})")


def _clear_plan(m, kind, timeout):
    drain(m)
    m.mav.mission_clear_all_send(m.target_system, 1, kind)
    ack = wait_message(m, "MISSION_ACK", lambda a: a.mission_type == kind, timeout)
    if ack is None or ack.type != _ACCEPTED:
        raise VehicleError(f"reset: MISSION_CLEAR_ALL of plan type {kind} answered {ack}")


def _ready(status):
    h, enabled = status.onboard_control_sensors_health, status.onboard_control_sensors_enabled
    return bool(h & _PREARM_CHECK) and (h & enabled) == enabled


def reset(vehicle: Vehicle, timeout=10.0):
    """Bring `vehicle` (running) back to its start state (module doc); return
    the step of the flight record's `reboot` line where the next flight
    starts. Raises VehicleError saying which step failed."""
    try:
        from pymavlink import mavutil
    except ImportError as e:  # not a VehicleError: the pool must not fall back to a fresh vehicle each test
        raise ImportError("resetting a shared vehicle (reuse=True) needs pymavlink: pip install pymavlink") from e

    if vehicle.proc is None or vehicle.proc.poll() is not None:
        raise VehicleError("reset: the vehicle is not running")
    changed = changed_params(vehicle.record)
    m = mavutil.mavlink_connection(f"udpout:127.0.0.1:{vehicle.gcs_port}", source_system=255, source_component=190)
    try:
        m.target_system = vehicle.system_id
        result = _command(m, _ARM_DISARM, 0, _FORCE, timeout=timeout)
        if result != _ACCEPTED:
            raise VehicleError(f"reset: forced disarm answered {result}")
        for name, value in changed.items():
            _set_param(m, name, value, timeout)
        for kind in _PLAN_TYPES:
            _clear_plan(m, kind, timeout)
        result = _command(m, _REBOOT, 1, timeout=timeout)
        if result != _ACCEPTED:
            raise VehicleError(f"reset: reboot answered {result}")
        deadline = time.monotonic() + timeout
        while True:
            if _command(m, _REQUEST_MESSAGE, _SYS_STATUS_ID, timeout=timeout) == _ACCEPTED:
                s = wait_message(m, "SYS_STATUS", None, 1.0)
                if s is not None and _ready(s):
                    break
            if time.monotonic() > deadline:
                raise VehicleError(f"reset: not ready to arm {timeout} s after the reboot")
            time.sleep(0.01)
    finally:
        m.close()
    return last_reboot_step(vehicle.record)


class _Entry:
    """A shared vehicle and what the pool knows of it."""

    def __init__(self, key, vehicle):
        self.key = key
        self.vehicle = vehicle
        self.in_use = False
        self.served = 0  # tests it was handed to
        self.failed = False  # a test it served failed: its directory is kept
        self.failed_tests = []  # the node ids of the tests it served that failed
        self.start_step = 0  # where the current test's flight starts in its record
        self.why = None  # why the pool dropped it


class VehiclePool:
    """Running vehicles shared by the tests of one pytest process (one xdist
    worker), keyed by their options: `acquire` hands out one not in use
    (reset if it served a test before; a new one if none is free or the
    reset fails), `release` takes it back, `close` stops them all."""

    def __init__(self, start, reset_timeout=10.0):
        self._start = start  # options -> a started Vehicle
        self._entries = []
        self._reset_timeout = reset_timeout
        self.dropped = []  # entries whose reset failed or whose daemon died: stopped, directory kept

    def acquire(self, key, opts):
        for e in list(self._entries):
            if e.key == key and not e.in_use:
                try:
                    e.start_step = reset(e.vehicle, self._reset_timeout)
                except (VehicleError, OSError) as err:
                    self._drop(e, f"reset failed: {err}")
                    continue
                break
        else:
            e = _Entry(key, self._start(opts))
            self._entries.append(e)
        e.in_use = True
        e.served += 1
        return e

    def release(self, e, failed, test=None):
        """Back into the pool after a test (`failed`: it failed; `test`: its
        node id, kept for the report page when it failed). Kills any
        `mavsdk_server` the test left on the vehicle's ports; drops the
        vehicle if its daemon exited (a problem to report unless it exited
        with status 0: a client's shutdown). Returns the problem, or None."""
        e.in_use = False
        e.failed = e.failed or failed
        if failed and test:
            e.failed_tests.append(test)
        v = e.vehicle
        kill_mavsdk_servers([v.client_port, v.mavsdk_server_port])
        rc = v.proc.poll()
        if rc is None:
            return None
        self._drop(e, f"exited with status {rc}", failed=rc != 0)
        if rc == 0:  # a client shut it down: the next test gets a new one
            return None
        return f"rotorpilot (system id {v.system_id}) exited with status {rc} during the test:\n" + v.stderr()[-4000:]

    def _drop(self, e, why, failed=True):
        self._entries.remove(e)
        e.failed = e.failed or failed
        e.why = why
        try:
            e.vehicle.stop()
        finally:
            self.dropped.append(e)

    def close(self, keep, on_kept=None):
        """Stop every vehicle; delete the directories as `keep` says
        (`--rotorpilot-keep`: "failed" keeps those a failed test used,
        "always" all, "never" none) and call `on_kept(entry)` for each one
        kept, stopped (its flight record complete). Returns the errors of
        vehicles that could not be stopped."""
        errors = []
        for e in self._entries:
            try:
                e.vehicle.stop()
            except VehicleError as err:
                errors.append(err)
                e.failed = True
        for e in self._entries + self.dropped:
            if keep == "never" or (keep == "failed" and not e.failed):
                e.vehicle.cleanup()
            elif on_kept is not None:
                on_kept(e)
        self._entries = []
        return errors
