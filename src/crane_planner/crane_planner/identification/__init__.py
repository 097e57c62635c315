"""Commissioning: estimate the crane's parameters from one recorded move. No ROS import.

``recording`` reads and checks the data (CSV, rosbag2, arrays); ``fit`` estimates
L1, L2, the mass ratio, the joint dampings and tau with their standard errors.
"""
from .fit import Identification, IdentificationError, identify
from .recording import Recording, read_bag, read_csv

__all__ = ['Identification', 'IdentificationError', 'Recording', 'identify', 'read_bag', 'read_csv']
