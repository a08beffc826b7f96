"""robot_rise: plan, filter and execute get-up motions for Dynamixel humanoids."""
