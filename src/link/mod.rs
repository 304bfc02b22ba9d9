//! MAVLink 2 over UDP as PX4 SITL does (being written).
