"""ROS 2 nodes: thin adapters from parameters and messages to the planning and streaming cores."""
