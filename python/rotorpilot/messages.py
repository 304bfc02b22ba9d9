"""Waiting for MAVLink messages on a pymavlink connection (duck-typed: any
object with pymavlink's `recv_match`), bounded in wall time.

Standard library only: pymavlink is the caller's.
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
