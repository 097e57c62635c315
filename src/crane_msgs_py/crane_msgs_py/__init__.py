"""Conventions of the crane trajectory server on top of standard ROS 2 interfaces."""
