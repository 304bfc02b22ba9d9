#!/usr/bin/env python3
"""Write tests/fixtures/mavlink/command-frames.txt: MAVLink 2 frames of
COMMAND_LONG, COMMAND_INT and COMMAND_ACK as pymavlink (an encoder that
shares no code with rotorpilot) packs them, so that the Rust daemon tests'
codec (tests/common/daemon.rs: the frames the test client sends, the COMMAND_ACK
it decodes, and rotorpilot's own ACK encoder) is checked against bytes it did
not make: a layout bug mirrored in encoder and decoder cannot pass.

    .venv/pymavlink/bin/python tools/golden_frames.py

One frame a line: `name sysid compid seq fields... hex`, fields as the
message's constructor takes them (floats exact in f32). Every frame is parsed
back by pymavlink before it is written.
"""
import math
import pathlib
import struct

import pymavlink
from pymavlink.dialects.v20 import common as mavlink2

OUT = pathlib.Path(__file__).resolve().parent.parent / "tests/fixtures/mavlink/command-frames.txt"


def pack(sysid, compid, seq, msg):
    mav = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=compid)
    mav.seq = seq
    buf = bytes(msg.pack(mav))
    # pymavlink reads its own frame back (CRC, length, fields)
    parsed = mavlink2.MAVLink(None).parse_char(buf)
    assert parsed is not None and parsed.get_msgId() == msg.get_msgId(), buf.hex()
    return buf


def f(x):
    """A float as its f32 value, printed so that it reads back exactly."""
    v = struct.unpack("<f", struct.pack("<f", x))[0]
    return "nan" if math.isnan(v) else repr(v)


FRAMES = [
    # MAVSDK's arm: COMMAND_LONG 400, unused params NaN, from 245/190
    ("command_long", 245, 190, 7,
     dict(target_system=1, target_component=1, command=400, confirmation=0,
          param1=1.0, param2=math.nan, param3=math.nan, param4=math.nan,
          param5=math.nan, param6=math.nan, param7=math.nan)),
    # every field distinct, a retransmission (confirmation 3)
    ("command_long", 255, 0, 200,
     dict(target_system=1, target_component=1, command=31337, confirmation=3,
          param1=1.5, param2=-2.25, param3=3.0e-3, param4=-4.0e4,
          param5=47.397742, param6=8.545594, param7=488.125)),
    # trailing zeros truncated: target component 0, confirmation 0, p7 = 0
    ("command_long", 245, 190, 8,
     dict(target_system=1, target_component=0, command=22, confirmation=0,
          param1=0.0, param2=0.0, param3=0.0, param4=0.0,
          param5=0.0, param6=0.0, param7=0.0)),
    # MAVSDK 4's goto_location: DO_REPOSITION in GLOBAL_INT
    ("command_int", 245, 190, 9,
     dict(target_system=1, target_component=1, frame=5, command=192, current=0,
          autocontinue=0, param1=-1.0, param2=1.0, param3=0.0, param4=0.5,
          x=473977420 + 450, y=85455940 - 531, z=493.25)),
    # every field distinct, negative x, frame 6, current and autocontinue set
    ("command_int", 250, 25, 255,
     dict(target_system=7, target_component=191, frame=6, command=178, current=1,
          autocontinue=2, param1=0.125, param2=-7.5, param3=1.0e6, param4=-0.0625,
          x=-338651234, y=1512093456, z=-12.5)),
    # the vehicle's answers, from 1/1, extensions set
    ("command_ack", 1, 1, 42,
     dict(command=192, result=4, progress=255, result_param2=-7,
          target_system=245, target_component=190)),
    # ACCEPTED to 255/0: the trailing zeros truncated
    ("command_ack", 1, 1, 43,
     dict(command=400, result=0, progress=0, result_param2=0,
          target_system=255, target_component=0)),
    # IN_PROGRESS with progress and a large result_param2
    ("command_ack", 2, 1, 0,
     dict(command=246, result=5, progress=37, result_param2=0x12345678,
          target_system=245, target_component=190)),
]

CLASSES = {
    "command_long": mavlink2.MAVLink_command_long_message,
    "command_int": mavlink2.MAVLink_command_int_message,
    "command_ack": mavlink2.MAVLink_command_ack_message,
}


def main():
    lines = [
        f"# MAVLink 2 frames packed by pymavlink {pymavlink.__version__} (common dialect),",
        "# written by tools/golden_frames.py; do not edit by hand.",
        "# name sysid compid seq field=value... hex",
    ]
    for name, sysid, compid, seq, fields in FRAMES:
        buf = pack(sysid, compid, seq, CLASSES[name](**fields))
        values = " ".join(f"{k}={f(v) if isinstance(v, float) else v}" for k, v in fields.items())
        lines.append(f"{name} {sysid} {compid} {seq} {values} {buf.hex()}")
    OUT.parent.mkdir(parents=True, exist_ok=True)
    OUT.write_text("\n".join(lines) + "\n")
    print(f"wrote {len(FRAMES)} frames to {OUT}")


if __name__ == "__main__":
    main()
