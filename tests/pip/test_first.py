from pymavlink import mavutil


def test_takeoff(rotorpilot_vehicle):
    m = mavutil.mavlink_connection(rotorpilot_vehicle.pymavlink_url)
    m.wait_heartbeat(timeout=5)
    m.arducopter_arm()
    assert m.recv_match(type="HEARTBEAT", condition="HEARTBEAT.base_mode & 128", blocking=True, timeout=5)
    m.mav.command_long_send(m.target_system, 1, mavutil.mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 0)
    assert m.recv_match(type="GLOBAL_POSITION_INT", condition="GLOBAL_POSITION_INT.relative_alt > 2000", blocking=True, timeout=30)
