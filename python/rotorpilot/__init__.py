"""rotorpilot: a software-in-the-loop multirotor that speaks MAVLink like PX4 SITL.

`pip install .` (from a checkout) puts the `rotorpilot` executable on the
PATH and installs this package: a pytest plugin (fixtures
`rotorpilot_vehicle`, `rotorpilot_vehicles`, and the clients
`rotorpilot_mavsdk` and `rotorpilot_mavlink`, marker `rotorpilot`, options
`--rotorpilot-*`; see `rotorpilot.pytest_plugin`; one vehicle for many tests,
reset between them: `rotorpilot.shared`) and `Vehicle`, which
starts one vehicle on free loopback ports and waits until it is ready to arm
(and, when it stops, kills any `mavsdk_server` left on its ports:
`rotorpilot.clients`).

Standard library only.
"""

from .messages import wait_message
from .vehicle import PortReservation, Vehicle, VehicleError, binary, free_tcp_port, free_udp_port, reserve_port

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("rotorpilot")  # Cargo.toml's version (maturin)
except PackageNotFoundError:  # used from a checkout, not installed
    __version__ = "0+checkout"

__all__ = ["Vehicle", "VehicleError", "binary", "free_tcp_port", "free_udp_port", "reserve_port",
           "PortReservation", "wait_message", "__version__"]
