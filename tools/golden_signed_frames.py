#!/usr/bin/env python3
"""Write tests/fixtures/mavlink/signed-frames.txt: MAVLink 2 frames signed by
pymavlink (an implementation that shares no code with rotorpilot or the Rust
`mavlink` crate), so that src/link/signing.rs's signature check and signer
are held against bytes they did not make.

    .venv/pymavlink/bin/python tools/golden_signed_frames.py

One frame a line: `name key_hex link_id timestamp frame_hex`. The key is
SHA-256 of a passphrase, as MAVProxy's `signing setup PASSPHRASE` makes it.
Every frame is parsed back and its signature checked by pymavlink first.
"""
import hashlib
import math
import pathlib

from pymavlink.dialects.v20 import common as mavlink2

OUT = pathlib.Path(__file__).resolve().parent.parent / "tests/fixtures/mavlink/signed-frames.txt"
KEY = hashlib.sha256(b"rotorpilot golden").digest()


def signed(name, sysid, compid, link_id, timestamp, msg):
    mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    mav.signing.secret_key = KEY
    mav.signing.sign_outgoing = True
    mav.signing.link_id = link_id
    mav.signing.timestamp = timestamp
    buf = bytes(msg.pack(mav))
    rx = mavlink2.MAVLink(None)
    rx.signing.secret_key = KEY
    rx.signing.timestamp = timestamp
    parsed = rx.parse_char(buf)
    assert parsed is not None and parsed._signed and parsed.get_msgId() == msg.get_msgId(), buf.hex()
    return f"{name} {KEY.hex()} {link_id} {timestamp} {buf.hex()}"


NAN = math.nan
LINES = [
    # arm from a GCS (255/190)
    signed("command_long_arm", 255, 190, 3, 373_000_000_000_01,
           mavlink2.MAVLink_command_long_message(1, 1, 400, 0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)),
    # telemetry as a vehicle sends it
    signed("attitude", 1, 1, 0, 373_000_000_000_02,
           mavlink2.MAVLink_attitude_message(123_456, 0.1, -0.2, 1.5, 0.01, -0.02, 0.03)),
    # a heartbeat from a GCS
    signed("heartbeat", 255, 190, 3, 373_000_000_000_03,
           mavlink2.MAVLink_heartbeat_message(6, 8, 0, 0, 4, 3)),
]

OUT.write_text("\n".join(LINES) + "\n")
print(f"wrote {len(LINES)} frames to {OUT}")
