"""ROS 2 node of the simulator: a thin adapter over ``crane_sim.simulator`` and ``crane_sim.playout``."""
