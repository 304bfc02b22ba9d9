#!/usr/bin/env python3
"""Parameters through MAVSDK's Param plugin (no flight, no position needed).

Downloads the whole table with Param.get_all_params and prints it sorted by
name, then checks:
- names are unique, and PX4 and rotorpilot names are there, each with its type;
- defaults as the vehicle was started with --reset-params;
- a REAL32 and an INT32 set read back with get_param_float / get_param_int;
- Action.set_takeoff_altitude lands in MIS_TAKEOFF_ALT, and the reverse;
- an out-of-range value is refused and the old value kept;
- a second full download shows the new values.
"""

from mavsdk.param import ParamError

from common import bail, bring_up, launch

EXPECT_FLOAT = {"MIS_TAKEOFF_ALT": 2.5, "MPC_XY_CRUISE": 5.0, "SIM_MASS": None}
EXPECT_INT = {"SYS_FAILURE_EN": 0, "CTRL_TYPE": None}


def as_table(listing):
    floats = {p.name: p.value for p in listing.float_params}
    ints = {p.name: p.value for p in listing.int_params}
    return floats, ints


def require(ok, what):
    if not ok:
        bail(what)
    print(f"[param] ok: {what}")


async def main():
    uav = await bring_up(need_position=False)

    listing = await uav.param.get_all_params()
    floats, ints = as_table(listing)
    for name in sorted(floats.keys() | ints.keys()):
        kind, value = ("f", floats[name]) if name in floats else ("i", ints[name])
        print(f"  {name:<18} {kind} {value}")

    count = len(listing.float_params) + len(listing.int_params)
    require(len(floats) + len(ints) == count and not floats.keys() & ints.keys(), f"{count} unique names")
    for name, default in EXPECT_FLOAT.items():
        require(name in floats and (default is None or floats[name] == default), f"REAL32 {name} = {floats.get(name)}")
    for name, default in EXPECT_INT.items():
        require(name in ints and (default is None or ints[name] == default), f"INT32 {name} = {ints.get(name)}")

    await uav.param.set_param_float("MPC_XY_CRUISE", 7.25)
    require(await uav.param.get_param_float("MPC_XY_CRUISE") == 7.25, "MPC_XY_CRUISE set to 7.25 and read back")
    await uav.param.set_param_int("SYS_FAILURE_EN", 1)
    require(await uav.param.get_param_int("SYS_FAILURE_EN") == 1, "SYS_FAILURE_EN set to 1 and read back")

    await uav.action.set_takeoff_altitude(3.75)
    require(await uav.param.get_param_float("MIS_TAKEOFF_ALT") == 3.75, "set_takeoff_altitude(3.75) is MIS_TAKEOFF_ALT")
    await uav.param.set_param_float("MIS_TAKEOFF_ALT", 6.0)
    require(await uav.action.get_takeoff_altitude() == 6.0, "MIS_TAKEOFF_ALT 6.0 is get_takeoff_altitude")

    try:
        await uav.param.set_param_float("MIS_TAKEOFF_ALT", -1.0)
        refused = False
    except ParamError as err:
        print(f"[param] -1 m takeoff height refused: {err._result.result}")
        refused = True
    require(refused, "MIS_TAKEOFF_ALT = -1 refused (PX4's minimum is 0, it has no maximum)")
    require(await uav.param.get_param_float("MIS_TAKEOFF_ALT") == 6.0, "MIS_TAKEOFF_ALT still 6.0")

    floats, ints = as_table(await uav.param.get_all_params())
    require(
        (floats["MIS_TAKEOFF_ALT"], floats["MPC_XY_CRUISE"], ints["SYS_FAILURE_EN"]) == (6.0, 7.25, 1),
        "second download shows the new values",
    )


if __name__ == "__main__":
    launch(main)
