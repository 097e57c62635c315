"""The ROS runtime the nodes share: the node runner, QoS profiles, real-time scheduling, the DDS profile,
declared parameters, /diagnostics, and rclpy workarounds (action server and client, raw taking)."""
