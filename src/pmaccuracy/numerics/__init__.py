"""Pure mathematics below the robot model: planar screws (twists, wrenches) as complex numbers."""
