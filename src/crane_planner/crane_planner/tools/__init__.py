"""Command-line tools: ``crane-plan``, ``crane-demo``, ``crane-record``.

Also the ROS harness they and the tests share, evaluation, figures, processes.

Only ``harness`` and ``demo`` may import ROS; the rest runs without it.
"""
