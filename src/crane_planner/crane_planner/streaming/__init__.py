"""The streaming core: sampling a plan at the stream's rate and the network impairment model. No ROS import."""
