"""Cranes sharing a runway: where each will be (``occupancy``), planning around the others in time
(``schedule``), and the guard on the live states (``guard``). Pure Python, no ROS import."""
