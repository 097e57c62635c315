"""The node set that several real-time ROS modules share (``conftest.py``'s ``cart_crane`` fixture).

Each node set started costs seconds (the processes, DDS discovery, the planner's solvers built and warmed up),
so the modules whose tests need the three nodes with the joint [cart] at their defaults share one: a module
switches at run time what it needs (the streamer's operator mode) and sets it back at its end. They run one
after the other in the order below (``conftest.py`` sorts them so): integration first (its tests were written
for the solver processes' background builds right after the start-up), faults last (it kills nodes and starts
new ones). test_feedback.py starts its own: with the sway feedback switched off after a correction, the sim's
cart is left off its hold (its plant follows the reference's acceleration, and keeps a velocity offset).
"""

#: The namespace of the shared node set.
CART_NAMESPACE = '/crane_cart'
#: The modules that share it, in the order they run.
CART_CRANE_MODULES = ('test_integration.py', 'test_motion_from_state.py', 'test_operator.py', 'test_faults.py')
#: The streamer's parameters besides its defaults: the camera noise its sway feedback expects in test_faults.py's
#: test with a noisy camera (read-only, so at start-up; it does nothing while the feedback is off, as it is in every
#: other test).
CART_STREAMER_PARAMS = {'feedback_noise': 1e-3}
