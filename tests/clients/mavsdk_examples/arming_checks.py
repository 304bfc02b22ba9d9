#!/usr/bin/env python3
"""The arming checks as a ground station reads them from PX4: MAVSDK's Events
plugin fetches the component metadata over MAVLink FTP, asks for the report
(MAV_CMD_RUN_PREARM_CHECKS) and decodes the EVENTs. On the ground, ready, in
Hold: the report says Hold can be armed, lists what the other modes lack
(a mission, the sticks, an offboard signal) and the vehicle's components.
Then the GPS receiver fails (INJECT_FAILURE, SYS_FAILURE_EN 1): the report
that follows says Hold cannot be armed for "No GPS fix", the GPS component has
an error, and arming is refused as the report said.
"""

from mavsdk.action import ActionError
from mavsdk.failure import FailureType, FailureUnit

from common import bail, bring_up, launch, next_matching


def problems(checks):
    return sorted(p.message for p in checks)


async def report(uav):
    """The first report: the plugin has it once the metadata is in and the
    vehicle answered the request for it."""
    return await next_matching(uav.events.health_and_arming_checks(), lambda r: True, 20, "arming-check report")


async def main():
    uav = await bring_up()
    ready = await report(uav)
    mode = ready.current_mode_intention
    print(f"[checks] {mode.mode_name}: can arm {mode.can_arm_or_run}, problems {problems(ready.all_problems)}")
    if mode.mode_name != "Hold" or not mode.can_arm_or_run or mode.problems:
        bail(f"ready on the ground: Hold armable with no problem, got {mode}")
    expected = ["No manual control input", "No offboard signal", "No valid mission"]
    if not set(expected) <= set(problems(ready.all_problems)):
        bail(f"the other modes' problems {expected} in {problems(ready.all_problems)}")
    components = {c.name: c for c in ready.health_components}
    for name in ["gps", "motors_escs", "battery"]:
        c = components.get(name)
        if c is None or not c.is_present or c.has_error:
            bail(f"component {name} present without error: {c}")
    mission = next(p for p in ready.all_problems if p.message == "No valid mission")
    if mission.health_component != "mission":
        bail(f"'No valid mission' concerns the mission, not {mission.health_component!r}")

    await uav.param.set_param_int("SYS_FAILURE_EN", 1)
    await uav.failure.inject(FailureUnit.SENSOR_GPS, FailureType.OFF, 0)
    lost = await next_matching(
        uav.events.health_and_arming_checks(),
        lambda r: not r.current_mode_intention.can_arm_or_run,
        20,
        "a report without GPS",
    )
    mode = lost.current_mode_intention
    print(f"[checks] {mode.mode_name}: can arm {mode.can_arm_or_run}, problems {problems(mode.problems)}")
    if "No GPS fix" not in problems(mode.problems):
        bail(f"Hold's problems name the GPS: {problems(mode.problems)}")
    gps = next(c for c in lost.health_components if c.name == "gps")
    if not gps.has_error:
        bail(f"the GPS component has an error: {gps}")
    try:
        await uav.action.arm()
        bail("armed without GPS")
    except ActionError as e:
        print(f"[checks] arming refused as the report said: {e}")


if __name__ == "__main__":
    launch(main)
