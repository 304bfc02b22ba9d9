"""Reading MAVLink messages on a pymavlink connection (duck-typed: any object
with pymavlink's `recv_match`, and `mav` for sending), bounded in wall time:
wait for a message, read away the backlog, send a command and read its ACK.

Standard library only: pymavlink is the caller's. The repository's client
tests (tests/clients/harness.py) import these from the checkout.
"""

import time


def wait_message(m, types, cond=None, timeout=5.0, seen=None):
    """The first message whose type is `types` (a name or a list of names)
    and for which `cond(msg)` is true (no `cond`: any), read from `m` within
    `timeout` wall seconds; None when none came. Every STATUSTEXT read on the
    way is appended to `seen` as (severity, text) when `seen` is a list."""
    want = [types] if isinstance(types, str) else list(types)
    deadline = time.monotonic() + timeout
    while True:
        left = deadline - time.monotonic()
        if left <= 0:
            return None
        msg = m.recv_match(blocking=True, timeout=min(0.5, max(0.01, left)))
        if msg is None:
            continue
        kind = msg.get_type()
        if seen is not None and kind == "STATUSTEXT":
            seen.append((msg.severity, msg.text))
        if kind in want and (cond is None or cond(msg)):
            return msg


def drain(m, seen=None):
    """Read away the backlog (every STATUSTEXT in it appended to `seen` as
    (severity, text) when `seen` is a list). The GCS link streams ~270
    messages/s; a script that sleeps lets the socket buffer fill, and the
    kernel then drops new datagrams (an ACK among them) until it reads again,
    as with PX4 SITL."""
    while (msg := m.recv_match(blocking=False)) is not None:
        if seen is not None and msg.get_type() == "STATUSTEXT":
            seen.append((msg.severity, msg.text))


def command(m, cmd, *params, timeout=3.0):
    """Send COMMAND_LONG `cmd` (missing params 0) to the connection's target
    after reading away the backlog; the result of its COMMAND_ACK (an
    AssertionError when none came within `timeout` s)."""
    p = list(params) + [0.0] * (7 - len(params))
    drain(m)
    m.mav.command_long_send(m.target_system, m.target_component, cmd, 0, *p)
    ack = wait_message(m, "COMMAND_ACK", lambda a: a.command == cmd, timeout)
    assert ack is not None, f"no COMMAND_ACK for {cmd}"
    return ack.result
