"""The crane's shared facts, pure Python: the actuated axes, the parameters and their checks, the jerk-limited
braking, the load's geometry and the drive's states (the planner and the simulator both read them)."""
