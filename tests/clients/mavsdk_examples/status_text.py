#!/usr/bin/env python3
"""A status text from a companion reaches the ground station: MAVSDK sends
"Hello world!" with ServerUtility.send_status_text, speaking as system 1 as
MAVSDK-Python's send_status_message.py example does, and the vehicle forwards
it from the API link to the GCS link, as PX4 SITL's MAVLink instances do
(started with -f). The test reads the GCS link.

Unlike the example, this script lets 2 s of the vehicle's time go by before it
exits: the example returns as soon as the text is queued, and its exit stops
mavsdk_server, sometimes before the text has left.
"""

from mavsdk.server_utility import StatusTextType

from common import bring_up, launch, pause


async def main():
    uav = await bring_up(need_position=False, sysid=1)
    await uav.server_utility.send_status_text(StatusTextType.INFO, "Hello world!")
    print("[text] sent")
    await pause(uav, 2.0)


if __name__ == "__main__":
    launch(main)
