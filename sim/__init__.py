"""Reducer physics for the simulated bench: kinematics, Wang 2020, Hu 2020, Li 2023, encoders.

No ROS imports.
"""
