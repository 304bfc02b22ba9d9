"""MAVSDK-Python 3.x reads the wind as it would from PX4: its telemetry
plugin's `wind()` stream is fed by WIND_COV (mavsdk_server's
`TelemetryImpl::process_wind`), which the vehicle sends on the API link at
PX4's onboard rate (10 Hz) once the flight stack has an estimate. The world's
wind is set with MAVSDK's param plugin (SIM_WIND_SPD 5 m/s, SIM_WIND_DIR 270:
from the west; no turbulence). Every wait is bounded.

Run with the mavsdk<4 venv: `python -m pytest tests/clients/test_mavsdk3_wind.py`.
"""

import asyncio
import math
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE / "mavsdk_examples"))
from harness import Vehicle  # noqa: E402
from test_mavsdk3_failsafe import connect, take_off  # noqa: E402

import common  # noqa: E402


def test_mavsdk_telemetry_wind_reports_5_m_s_from_the_west():
    async def flight(vehicle):
        uav = await connect(vehicle)
        try:
            await fly(uav)
        finally:
            uav._stop_mavsdk_server()

    async def fly(uav):
        await take_off(uav, 5.0)
        for name, value in [("SIM_WIND_TURB", 0.0), ("SIM_WIND_DIR", 270.0), ("SIM_WIND_SPD", 5.0)]:
            await uav.param.set_param_float(name, value)
        await common.pause(uav, 10.0)
        w = await common.sample(uav.telemetry.wind(), "wind")
        speed = math.hypot(w.wind_x_ned_m_s, w.wind_y_ned_m_s)
        from_deg = math.degrees(math.atan2(-w.wind_y_ned_m_s, -w.wind_x_ned_m_s)) % 360.0
        print(f"telemetry.wind(): {w}; {speed:.3f} m/s from {from_deg:.1f} deg")
        assert abs(speed - 5.0) < 0.5, w
        assert abs((from_deg - 270.0 + 180.0) % 360.0 - 180.0) < 10.0, w
        assert w.wind_z_ned_m_s == 0.0
        pos = await common.sample(uav.telemetry.position(), "position")
        assert abs(w.wind_altitude_msl_m - pos.absolute_altitude_m) < 0.5, (w, pos)
        await uav.action.land()
        await common.touchdown(uav, 60)

    with Vehicle(speed=5.0) as v:
        asyncio.run(asyncio.wait_for(flight(v), 150))
