"""Kinematic diff-drive simulator with noisy odometry and localisation.

Stands in for Stage and AMCL; owns the occupancy maps and the map tools.
"""
