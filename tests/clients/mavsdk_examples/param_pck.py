#!/usr/bin/env python3
"""PX4's packed parameter file over MAVSDK's FTP plugin, as PX4's own
test_param_ftp uses it: download @PARAM/param.pck, decode it, compare every
entry with the PARAM_VALUE list (MAVSDK's param.get_all_params); then upload
a file that changes MIS_TAKEOFF_ALT and read the parameter back."""

import os
import struct
import tempfile

from common import bail, bring_up, launch


def decode(f):
    """(magic, num, total, {name: (type, raw value)}) of a param.pck."""
    magic, num, total = struct.unpack_from("<HHH", f, 0)
    i, prev, out = 6, "", {}
    while i < len(f):
        if f[i] == 0:
            i += 1
            continue
        kind, flags = f[i] & 0x0F, f[i] >> 4
        common, length = f[i + 1] & 0x0F, (f[i + 1] >> 4) + 1
        name = prev[:common] + f[i + 2 : i + 2 + length].decode()
        i += 2 + length
        out[name] = (kind, f[i : i + 4])
        i += 4 + (4 if flags & 1 else 0)
        prev = name
    return magic, num, total, out


def encode(entries):
    """An upload: [(name, 'f' or 'i', value)]."""
    body, prev = b"", ""
    for name, t, v in entries:
        common = 0
        while common < min(len(name), len(prev), 15) and name[common] == prev[common]:
            common += 1
        rest = name[common:].encode()
        body += bytes([4 if t == "f" else 3, common | ((len(rest) - 1) << 4)]) + rest + struct.pack("<" + t, v)
        prev = name
    return struct.pack("<HHH", 0x671B, len(entries), 6 + len(body)) + body


async def run():
    uav = await bring_up(need_position=False)
    with tempfile.TemporaryDirectory() as d:
        async for _ in uav.ftp.download("@PARAM/param.pck", d, True):
            pass
        f = open(os.path.join(d, "param.pck"), "rb").read()
    magic, num, total, packed = decode(f)
    every = await uav.param.get_all_params()
    listed = {p.name: ("i", p.value) for p in every.int_params}
    listed.update({p.name: ("f", p.value) for p in every.float_params})
    print(f"param.pck: {len(f)} bytes, magic {magic:#x}, {num} of {total} parameters; PARAM_VALUE list: {len(listed)}")
    if magic != 0x671B or num != total or set(packed) != set(listed):
        bail(f"param.pck names differ from the list: {sorted(set(packed) ^ set(listed))}")
    for name, (t, value) in listed.items():
        kind, raw = packed[name]
        got = struct.unpack("<i", raw)[0] if kind == 3 else struct.unpack("<f", raw)[0]
        if (kind == 3) != (t == "i") or (got != value and abs(got - value) > 1e-6 * max(1.0, abs(value))):
            bail(f"{name}: param.pck says {got} (type {kind}), PARAM_VALUE {value}")
    print("every parameter in param.pck equals its PARAM_VALUE")
    before = await uav.param.get_param_float("MIS_TAKEOFF_ALT")
    wanted = before + 1.5
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "param.pck")
        open(path, "wb").write(encode([("MIS_TAKEOFF_ALT", "f", wanted), ("NOT_A_PARAM", "i", 3)]))
        async for _ in uav.ftp.upload(path, "@PARAM"):
            pass
    after = await uav.param.get_param_float("MIS_TAKEOFF_ALT")
    print(f"MIS_TAKEOFF_ALT {before} -> upload {wanted} -> {after}")
    if abs(after - wanted) > 1e-5:
        bail(f"MIS_TAKEOFF_ALT is {after} after uploading {wanted}")


if __name__ == "__main__":
    launch(run)
