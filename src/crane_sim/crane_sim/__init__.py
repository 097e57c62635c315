"""Double-pendulum crane simulator: numpy core (no ROS import) and a ROS 2 node."""
