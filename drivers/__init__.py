"""drivers: Dynamixel Protocol 2.0 side of robot_rise (bytes and ticks live only here)."""
